//! Writing a computed flow: NPY arrays and a JSON summary.

use super::{write_atomically, write_npy, IoError};
use crate::flow::{FlowParams, FlowResult, MeshSequence};
use std::io::Write;
use std::path::Path;

/// Writes `dir/flow.npy` (S, V, 3: R^3 vectors on frame s; embedded sequences only),
/// `dir/flow_intrinsic.npy` (S, V, 2: vertex-frame components) and `dir/summary.json`
/// (energy and its terms, residual, iterations, solver, sizes, parameters, timings), each
/// atomically. `input` is recorded in the summary.
pub fn write_flow_outputs(
    dir: &Path,
    input: &str,
    sequence: &MeshSequence,
    params: &FlowParams,
    result: &FlowResult,
) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(|e| IoError::file(dir, e))?;
    let (s, v) = (
        result.intrinsic.len() as u64,
        sequence.mesh().n_vertices() as u64,
    );
    let intrinsic: Vec<f64> = result
        .intrinsic
        .iter()
        .flatten()
        .flat_map(|u| [u.x, u.y])
        .collect();
    write_npy(&dir.join("flow_intrinsic.npy"), &[s, v, 2], &intrinsic)?;
    if let Some(vectors) = &result.vectors {
        let values: Vec<f64> = vectors
            .iter()
            .flatten()
            .flat_map(|u| [u.x, u.y, u.z])
            .collect();
        write_npy(&dir.join("flow.npy"), &[s, v, 3], &values)?;
    }
    let summary = summary_json(input, sequence, params, result);
    write_atomically(&dir.join("summary.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &summary).map_err(std::io::Error::other)?;
        writeln!(w)
    })
}

/// The summary written next to the flow.
pub fn summary_json(
    input: &str,
    sequence: &MeshSequence,
    params: &FlowParams,
    result: &FlowResult,
) -> serde_json::Value {
    let speeds: Vec<f64> = result
        .intrinsic
        .iter()
        .flatten()
        .map(|u| u.norm())
        .collect();
    serde_json::json!({
        "input": input,
        "energy": result.energy,
        "energy_terms": result.energy_terms,
        "energy_at_zero": result.energy_at_zero,
        "relative_residual": result.relative_residual,
        "iterations": result.iterations,
        "solver": result.method,
        "factor_entries": result.factor_entries,
        "frames": sequence.n_frames(),
        "slabs": sequence.n_slabs(),
        "vertices": sequence.mesh().n_vertices(),
        "faces": sequence.mesh().n_faces(),
        "times": sequence.times(),
        "max_speed": speeds.iter().cloned().fold(0.0, f64::max),
        "params": params_json(params),
        "seconds": result.timings,
    })
}

/// Parameters with `alpha = ∞` written as the string "inf" (JSON has no infinity).
fn params_json(params: &FlowParams) -> serde_json::Value {
    let mut value = serde_json::to_value(params).expect("parameters serialize");
    if !params.alpha.is_finite() {
        value["alpha"] = serde_json::Value::from("inf");
    }
    value
}
