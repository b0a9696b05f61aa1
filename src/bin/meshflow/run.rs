//! Reading a finished `meshflow solve` run: the sequence as its command read it, and its flow.

use crate::progress::during;
use crate::{Cli, Command, SolveArgs};
use clap::Parser;
use meshflow::io::{load_sequence, read_npy_float, IoError, LoadedSequence, RunManifest};
use meshflow::Error;
use nalgebra::Vector2;
use std::path::Path;

/// A run's solve arguments, its input as loaded again, and its flow per mesh vertex.
pub struct FinishedRun {
    pub args: Box<SolveArgs>,
    pub loaded: LoadedSequence,
    /// `flow[s][i]`: slab `s` at mesh vertex `i`, vertex frames.
    pub flow: Vec<Vec<Vector2<f64>>>,
}

impl FinishedRun {
    /// Reads `run`: its manifest's solve command, that command's input, `flow_intrinsic.npy`.
    pub fn read(run: &Path) -> Result<Self, Error> {
        let args = solve_command(run)?;
        let loaded = during(format!("reading {}", args.input.display()), || {
            load_sequence(&args.input, &args.load_options())
        })?;
        let flow = read_flow(run, &loaded)?;
        Ok(FinishedRun { args, loaded, flow })
    }
}

/// The `solve` arguments that made `run`, from its manifest.
fn solve_command(run: &Path) -> Result<Box<crate::SolveArgs>, Error> {
    let not_a_run = |why: &str| Error::from(IoError::format(run, why.to_string()));
    let manifest = RunManifest::read(run)
        .ok_or_else(|| not_a_run("not a meshflow output (no meshflow_run.json)"))?;
    let command = manifest
        .commands
        .first()
        .ok_or_else(|| not_a_run("its manifest lists no command"))?;
    match Cli::try_parse_from(command).map(|cli| cli.command) {
        // Its paths as the solve meant them, wherever `advect` runs from.
        // A flow computed from arrays holds its input itself (`meshflow::io::write_run_input`).
        Ok(Command::Solve(mut args)) if args.input == args.out => {
            args.input = run.to_path_buf();
            Ok(args)
        }
        Ok(Command::Solve(mut args)) => {
            args.input = manifest.resolve(&args.input);
            args.intensity = args.intensity.map(|file| manifest.resolve(&file));
            Ok(args)
        }
        _ => Err(not_a_run("not the output of `meshflow solve`")),
    }
}

/// `flow_intrinsic.npy` of the run, per mesh vertex.
fn read_flow(
    run: &Path,
    loaded: &meshflow::io::LoadedSequence,
) -> Result<Vec<Vec<Vector2<f64>>>, Error> {
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
        )
        .into());
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
