//! Reading a finished `meshflow solve` run: the sequence as its command read it, and its flow.

use crate::progress::during;
use crate::{Cli, Command, SolveArgs};
use clap::Parser;
use meshflow::format::{read_npy_float, IoError};
use meshflow::load::{load_sequence, LoadedSequence};
use meshflow::run::{Overwrite, RunManifest, StagedDir};
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
    /// Reads `run` made by the solve `args` ([`solve_command`], which checked its inputs):
    /// that command's input and `flow_intrinsic.npy`.
    pub fn read(run: &Path, args: Box<SolveArgs>) -> Result<Self, Error> {
        let loaded = during(format!("reading {}", args.input.display()), || {
            load_sequence(&args.input, &args.load_options())
        })?;
        let flow = read_flow(run, &loaded)?;
        Ok(FinishedRun { args, loaded, flow })
    }
}

/// The files outside `run` that its solve read, as the solve named them.
pub fn external_inputs<'a>(run: &Path, args: &'a SolveArgs) -> Vec<&'a Path> {
    std::iter::once(args.input.as_path())
        .chain(args.intensity.as_deref())
        .filter(|path| *path != run)
        .collect()
}

/// The output directory of a command that reads `run` and its solve's input again (`advect`,
/// `analyze`): refused, before anything is read, when it is or holds one of them or lies
/// inside one.
pub fn stage_output(
    run: &Path,
    args: &SolveArgs,
    extra_inputs: &[&Path],
    out: &Path,
    overwrite: Overwrite,
) -> Result<StagedDir, Error> {
    let inputs: Vec<&Path> = std::iter::once(run)
        .chain(external_inputs(run, args))
        .chain(extra_inputs.iter().copied())
        .collect();
    let mut staged = StagedDir::create_apart_from(&inputs, out, overwrite)?;
    staged.record_command(crate::command_line());
    Ok(staged)
}

/// The `solve` arguments that made `run`, from its manifest, with its external inputs checked
/// against what the run recorded of them (an edited manifest cannot make a later command read
/// elsewhere, and a changed input is named).
pub fn solve_command(run: &Path) -> Result<Box<crate::SolveArgs>, Error> {
    let not_a_run = |why: &str| Error::from(IoError::format(run, why.to_string()));
    let manifest = RunManifest::read_run(run)?;
    let command = manifest
        .commands
        .first()
        .ok_or_else(|| not_a_run("its manifest lists no command"))?;
    let args = match Cli::try_parse_from(command).map(|cli| cli.command) {
        // Its paths as the solve meant them, wherever `advect` runs from.
        // A flow computed from arrays holds its input itself (`meshflow::run::write_run_input`).
        Ok(Command::Solve(mut args)) if args.input == args.out => {
            args.input = run.to_path_buf();
            args.intensity = None;
            args
        }
        Ok(Command::Solve(mut args)) => {
            args.input = manifest.resolve(&args.input);
            args.intensity = args.intensity.map(|file| manifest.resolve(&file));
            args
        }
        _ => return Err(not_a_run("not the output of `meshflow solve`")),
    };
    let external = external_inputs(run, &args);
    if !external.is_empty() {
        manifest.check_inputs(run, &external)?;
    }
    Ok(args)
}

/// `flow_intrinsic.npy` of the run, per mesh vertex.
fn read_flow(
    run: &Path,
    loaded: &meshflow::load::LoadedSequence,
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
    if let Some(at) = array.data.iter().position(|v| !v.is_finite()) {
        let (slab, vertex) = (at / (2 * v), at / 2 % v);
        return Err(IoError::format(
            &file,
            format!(
                "slab {slab}, vertex {vertex} holds {}: not a flow",
                array.data[at]
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
