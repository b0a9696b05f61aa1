//! Experiment I of Bauer, Grasmair & Kirisits (2015), with a synthetic video in place of the
//! Hamburg taxi sequence: a ring torus whose major circle stretches into an ellipse while its tube
//! grows ripples ([`meshflow::synth::paper_torus`]), 255 × 190 periodic grid, 20 frames,
//! α = γ = 1, β = 0.
//!
//! The same images are also solved on the flat torus — the periodic pixel grid with spacing 1,
//! the "naive" model that ignores the surface — and both flows are pulled back to pixels per
//! frame ([`Chart`]) and compared by their angular difference, as in the paper's Figs. 3–6.
//!
//! Writes into `out/paper_torus/`: `torus_SSSS.vtu` + `torus.pvd` (both flows and their
//! difference on the moving torus); for the first, middle and last slab the parameter-domain
//! pictures `image_`, `flow_surface_`, `flow_flat_`, `angular_difference_SSSS.png` and the 3D
//! pictures `grey_`, `flow_`, `arrows_SSSS.png`; prints a table and the run times.
//!
//! `cargo run --release --example paper_torus [-- N1 N2 FRAMES]`

mod common;

use common::{solve_in_chart, ChartGrid, Comparison};
use meshflow::chart::Chart;
use meshflow::flow::{FlowParams, MeshSequence};
use meshflow::render::View;
use meshflow::synth::paper_torus;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), meshflow::Error> {
    let (n1, n2, frames) = grid_size_from_args();
    let out = Path::new("out/paper_torus");
    std::fs::create_dir_all(out).map_err(|e| meshflow::format::IoError::file(out, e))?;
    let params = FlowParams::paper(1.0, 0.0, 1.0);
    println!(
        "paper torus: {n1} × {n2} grid, {frames} frames, α = γ = 1, β = 0, {} threads",
        rayon::current_num_threads()
    );
    let start = Instant::now();
    let surface = paper_torus(n1, n2, frames)?;
    let chart = Chart::periodic_grid(n1, n2);
    let flat = flat_torus(&surface, &chart)?;
    let generated = start.elapsed().as_secs_f64();

    let comparison = Comparison::new(
        ["surface", "flat"],
        [
            solve_in_chart(&surface, &chart, &params, "moving torus")?,
            solve_in_chart(&flat, &chart, &params, "flat torus")?,
        ],
    );
    let solved = start.elapsed().as_secs_f64();
    comparison.print_table();

    let grid = ChartGrid {
        rows: n2,
        cols: n1,
        column_major: true,
        pixel_size: 3,
    };
    let view = View::new(-70.0, 40.0);
    comparison.write_outputs(out, "torus", &surface, grid, view)?;
    let total = start.elapsed().as_secs_f64();

    println!();
    for (name, flow) in comparison.names.iter().zip(&comparison.flows) {
        println!("{name:>8} flow        {:7.2} s", flow.result.timings.total);
    }
    println!("generate sequences  {generated:7.2} s");
    println!("outputs and PNGs    {:7.2} s", total - solved);
    println!("end to end          {total:7.2} s");
    println!("written to          {}", out.display());
    Ok(())
}

fn grid_size_from_args() -> (usize, usize, usize) {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("N1 N2 FRAMES are whole numbers"))
        .collect();
    match args[..] {
        [n1, n2, frames] => (n1, n2, frames),
        [] => (255, 190, 20),
        _ => panic!("usage: paper_torus [N1 N2 FRAMES]"),
    }
}

/// The naive model: the same images on the flat periodic pixel grid (spacing 1), a sequence of
/// edge lengths with no embedding.
fn flat_torus(surface: &MeshSequence, chart: &Chart) -> Result<MeshSequence, meshflow::Error> {
    let mesh = surface.mesh();
    let lengths = chart.flat_edge_lengths(mesh)?;
    let intensities = (0..surface.n_frames())
        .map(|k| surface.intensities(k).to_vec())
        .collect();
    Ok(MeshSequence::from_edge_lengths(
        mesh.clone(),
        vec![lengths; surface.n_frames()],
        intensities,
        Some(surface.times().to_vec()),
    )?)
}
