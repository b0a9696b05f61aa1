//! `meshflow analyze RUN --out DIR`: what a finished run's flow tells (`meshflow::analysis`):
//! divergence, curl, Helmholtz–Hodge parts and the tissue's strain rate, as NPY, ParaView and
//! `analysis.json`, with a table per slab on stdout.

use crate::progress::during;
use crate::run::FinishedRun;
use meshflow::analysis::{analyze_flow, SlabAnalysis};
use meshflow::io::{write_analysis_outputs, Overwrite, StagedDir};
use meshflow::Error;
use std::path::Path;

pub fn analyze(run: &Path, out: &Path, overwrite: Overwrite) -> Result<(), Error> {
    let mut staged = StagedDir::create(out, overwrite)?;
    staged.record_command(crate::command_line());
    let FinishedRun { loaded, flow, .. } = FinishedRun::read(run)?;
    let start = std::time::Instant::now();
    let slabs = during("analysing the flow", || {
        analyze_flow(&loaded.sequence, &flow)
    })?;
    let seconds = start.elapsed().as_secs_f64();
    during(format!("writing {}", out.display()), || {
        write_analysis_outputs(staged.path(), &loaded, &slabs, run)
    })
    .map_err(|e| staged.in_target(e))?;
    staged.commit()?;
    println!(
        "{}: {} slabs x {} faces analysed in {seconds:.2} s -> {}",
        run.display(),
        slabs.len(),
        loaded.sequence.mesh().n_faces(),
        out.display()
    );
    print_table(&loaded.sequence.times()[..slabs.len()], &slabs);
    Ok(())
}

/// Per slab: the means over the surface and the shares of the Hodge parts in `∫|U|²`.
fn print_table(times: &[f64], slabs: &[SlabAnalysis]) {
    println!(
        "{:>5} {:>10} {:>10} {:>10} {:>11} {:>11} {:>11} {:>10}  Hodge exact / co-exact / harmonic",
        "slab", "time", "area", "speed", "divergence", "curl", "areal rate", "shear"
    );
    for (a, t) in slabs.iter().zip(times) {
        let totals = &a.totals;
        let share = |part: f64| 100.0 * part / totals.energy.max(f64::MIN_POSITIVE);
        println!(
            "{:>5} {:>10.4} {:>10.4e} {:>10.3e} {:>11.3e} {:>11.3e} {:>11.3e} {:>10.3e}  {:.1} % / {:.1} % / {:.1} %",
            a.slab,
            t,
            totals.area,
            totals.mean_speed,
            totals.mean_divergence,
            totals.mean_curl,
            totals.mean_areal_rate,
            totals.mean_shear_rate,
            share(totals.exact_energy),
            share(totals.coexact_energy),
            share(totals.harmonic_energy),
        );
    }
}
