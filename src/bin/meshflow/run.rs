//! Reading a finished `meshflow solve` run: the sequence as its command read it, and its flow
//! (the library's [`SolveInput`] and [`read_flow`], with progress).

use crate::progress::during;
use crate::{Cli, Command};
use clap::Parser;
use meshflow::format::IoError;
use meshflow::load::LoadedSequence;
use meshflow::run::{
    read_flow, Overwrite, RecordBase, RunManifest, SolveInput, SolveRecord, StagedDir,
};
use meshflow::Error;
use nalgebra::Vector2;
use std::path::Path;

/// A run's input as loaded again, and its flow per mesh vertex.
pub struct FinishedRun {
    pub input: SolveInput,
    pub loaded: LoadedSequence,
    /// `flow[s][i]`: slab `s` at mesh vertex `i`, vertex frames.
    pub flow: Vec<Vec<Vector2<f64>>>,
}

impl FinishedRun {
    /// Reads `run` whose solve read `input` ([`solve_input`], which checked it): that input
    /// and `flow_intrinsic.npy`.
    pub fn read(run: &Path, input: SolveInput) -> Result<Self, Error> {
        let loaded = during(format!("reading {}", input.input.display()), || {
            input.load()
        })?;
        let flow = read_flow(run, &loaded)?;
        Ok(FinishedRun {
            input,
            loaded,
            flow,
        })
    }
}

/// The output directory of a command that reads `run` and its solve's input again (`advect`,
/// `analyze`): refused, before anything is read, when it is or holds one of them or lies
/// inside one.
pub fn stage_output(
    run: &Path,
    input: &SolveInput,
    extra_inputs: &[&Path],
    out: &Path,
    overwrite: Overwrite,
) -> Result<StagedDir, Error> {
    let inputs: Vec<&Path> = std::iter::once(run)
        .chain(input.external_inputs(run))
        .chain(extra_inputs.iter().copied())
        .collect();
    let mut staged = StagedDir::create_apart_from(&inputs, out, overwrite)?;
    staged.record_command(crate::command_line());
    // The surface the output lies on, as the run's own record says it (relative to `out`),
    // so that readers of `out` alone (napari) find it; its files outside `out` fingerprinted.
    let surface: Vec<&Path> = std::iter::once(input.input.as_path())
        .chain(input.load.intensity.as_deref())
        .collect();
    staged.record_inputs(&surface)?;
    staged.record_solve(SolveRecord::new(
        Some(&input.input),
        input.load.clone(),
        out,
    ));
    Ok(staged)
}

/// The input of the solve that made `run`, from its manifest: the record a solve writes, or
/// for a run of an earlier version, its command line. Its external inputs are checked against
/// what the run recorded of them (an edited manifest cannot make a later command read
/// elsewhere, and a changed input is named).
pub fn solve_input(run: &Path) -> Result<SolveInput, Error> {
    let manifest = RunManifest::read_run(run)?;
    let record = match manifest.solve.clone() {
        Some(record) => record,
        None => recorded_command(run, &manifest)?,
    };
    Ok(SolveInput::resolve(run, &manifest, record)?)
}

/// What the first command of an earlier version's manifest read, parsed as the CLI parses it.
fn recorded_command(run: &Path, manifest: &RunManifest) -> Result<SolveRecord, Error> {
    let not_a_run = |why: &str| Error::from(IoError::format(run, why.to_string()));
    let command = manifest
        .commands
        .first()
        .ok_or_else(|| not_a_run("its manifest lists no command"))?;
    match Cli::try_parse_from(command).map(|cli| cli.command) {
        // As the user named them, from the working directory that the manifest names.
        Ok(Command::Solve(args)) => Ok(SolveRecord {
            input: (args.input != args.out).then(|| args.input.clone()),
            load: args.load_options(),
            relative_to: RecordBase::WorkingDirectory,
        }),
        _ => Err(not_a_run("not the output of `meshflow solve`")),
    }
}
