//! Reading a finished solve back: its input, loaded as the solve loaded it, and its flow.
//!
//! A solve records in its manifest what it read and how ([`SolveRecord`]: the input as named
//! and the [`LoadOptions`]). A later command (`advect`, `analyze`, Python) resolves those paths
//! against the solve's working directory and checks that the files outside the run still hold
//! what the solve read ([`SolveInput::of_run`]; an edited manifest cannot make it read
//! elsewhere), loads the input again and reads `flow_intrinsic.npy` ([`read_flow`]).

use super::RunManifest;
use crate::format::{read_npy_float, IoError};
use crate::load::{load_sequence, LoadOptions, LoadedSequence};
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What a solve read, as its manifest records it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolveRecord {
    /// The input as the solve named it (relative to its working directory); `None` when the
    /// run holds its input itself (a flow computed from arrays: [`super::write_run_input`]).
    pub input: Option<PathBuf>,
    /// How it was loaded (`--intensity` as named, like `input`).
    pub load: LoadOptions,
}

/// A finished solve's input, resolved: where it is now and how to load it.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveInput {
    pub input: PathBuf,
    pub load: LoadOptions,
}

impl SolveInput {
    /// The input of the solve whose output is `run`, from the record in its manifest.
    pub fn of_run(run: &Path) -> Result<Self, IoError> {
        let manifest = RunManifest::read_run(run)?;
        let Some(record) = manifest.solve.clone() else {
            let why = "its manifest records no solve: not the output of `meshflow solve`, \
                       or written by an earlier version (solve again)";
            return Err(IoError::format(run, why));
        };
        Self::resolve(run, &manifest, record)
    }

    /// `record` of the run `run` (whose manifest is `manifest`): relative paths against the
    /// solve's working directory, and the files outside the run checked against what the run
    /// recorded of them ([`RunManifest::check_inputs`]).
    pub fn resolve(
        run: &Path,
        manifest: &RunManifest,
        record: SolveRecord,
    ) -> Result<Self, IoError> {
        let mut load = record.load;
        let input = match record.input {
            None => {
                load.intensity = None;
                run.to_path_buf()
            }
            Some(input) => {
                load.intensity = load.intensity.map(|file| manifest.resolve(&file));
                manifest.resolve(&input)
            }
        };
        let resolved = Self { input, load };
        let external = resolved.external_inputs(run);
        if !external.is_empty() {
            manifest.check_inputs(run, &external)?;
        }
        Ok(resolved)
    }

    /// The files outside `run` that its solve read.
    pub fn external_inputs(&self, run: &Path) -> Vec<&Path> {
        std::iter::once(self.input.as_path())
            .chain(self.load.intensity.as_deref())
            .filter(|path| *path != run)
            .collect()
    }

    /// The input loaded again, as the solve loaded it.
    pub fn load(&self) -> Result<LoadedSequence, crate::Error> {
        load_sequence(&self.input, &self.load)
    }
}

/// `flow_intrinsic.npy` of the run `run` whose input is `loaded`: `flow[s][i]`, slab `s` at
/// mesh vertex `i`, in vertex frames.
pub fn read_flow(run: &Path, loaded: &LoadedSequence) -> Result<Vec<Vec<Vector2<f64>>>, IoError> {
    let file = run.join("flow_intrinsic.npy");
    let array = read_npy_float(&file)?;
    let map = &loaded.vertex_map;
    let (s, v) = (loaded.sequence.n_slabs(), map.n_file_vertices());
    if array.shape != [s as u64, v as u64, 2] {
        return Err(IoError::format(
            &file,
            format!(
                "shape {:?}, expected ({s}, {v}, 2) for the run's input (was it changed since?)",
                array.shape
            ),
        ));
    }
    if let Some(at) = array.data.iter().position(|v| !v.is_finite()) {
        let (slab, vertex) = (at / (2 * v), at / 2 % v);
        let why = format!(
            "slab {slab}, vertex {vertex} holds {}: not a flow",
            array.data[at]
        );
        return Err(IoError::format(&file, why));
    }
    Ok((0..s)
        .map(|slab| {
            (0..map.n_mesh_vertices())
                .map(|m| {
                    let row = 2 * (slab * v + map.representative(m));
                    Vector2::new(array.data[row], array.data[row + 1])
                })
                .collect()
        })
        .collect())
}
