//! In the spirit of Experiment II of Bauer, Grasmair & Kirisits (2015): bright cells crawling
//! over a surface that is the graph `x3 = h(t, x1, x2)` of a rising dome with a running wave
//! ([`meshflow::synth::graph_surface`]), 101 × 101 grid over the unit square, 16 frames,
//! Dirichlet boundary, α = 10, β = 0, γ = 0.001.
//!
//! The same images are also solved on the flat square (the planar model that ignores the
//! height), both flows are pulled back to grid units per frame ([`Chart::grid`]) and compared
//! by their angular difference: they differ where the dome is steep.
//!
//! Writes into `out/graph_surface/`: `graph_SSSS.vtu` + `graph.pvd`; for the first, middle and
//! last slab `image_`, `flow_surface_`, `flow_planar_`, `angular_difference_SSSS.png` (parameter
//! domain) and `grey_`, `flow_`, `arrows_SSSS.png` (3D); prints a table and the run times.
//!
//! `cargo run --release --example graph_surface [-- N FRAMES]`

mod common;

use common::{solve_in_chart, ChartGrid, Comparison};
use meshflow::chart::Chart;
use meshflow::flow::{Boundary, FlowParams, MeshSequence};
use meshflow::render::View;
use meshflow::synth::graph_surface;
use nalgebra::Vector3;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), meshflow::Error> {
    let (n, frames) = size_from_args();
    let out = Path::new("out/graph_surface");
    std::fs::create_dir_all(out).map_err(|e| meshflow::format::IoError::file(out, e))?;
    let params = FlowParams {
        boundary: Boundary::Dirichlet,
        ..FlowParams::paper(10.0, 0.0, 1e-3)
    };
    println!(
        "graph surface: {} × {} grid, {frames} frames, α = 10, β = 0, γ = 0.001, Dirichlet",
        n + 1,
        n + 1
    );
    let start = Instant::now();
    let surface = graph_surface(n, frames)?;
    let planar = flattened(&surface)?;
    let chart = Chart::grid(n, n);
    let comparison = Comparison::new(
        ["surface", "planar"],
        [
            solve_in_chart(&surface, &chart, &params, "graph surface")?,
            solve_in_chart(&planar, &chart, &params, "planar")?,
        ],
    );
    let solved = start.elapsed().as_secs_f64();
    comparison.print_table();

    let grid = ChartGrid {
        rows: n + 1,
        cols: n + 1,
        column_major: false,
        pixel_size: 4,
    };
    let view = View::new(-60.0, 45.0);
    comparison.write_outputs(out, "graph", &surface, grid, view)?;
    let total = start.elapsed().as_secs_f64();
    println!();
    println!("solves              {solved:7.2} s");
    println!("outputs and PNGs    {:7.2} s", total - solved);
    println!("written to          {}", out.display());
    Ok(())
}

fn size_from_args() -> (usize, usize) {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("N FRAMES are whole numbers"))
        .collect();
    match args[..] {
        [n, frames] => (n, frames),
        [] => (100, 16),
        _ => panic!("usage: graph_surface [N FRAMES]"),
    }
}

/// The planar model: every frame's heights set to zero, same images.
fn flattened(surface: &MeshSequence) -> Result<MeshSequence, meshflow::Error> {
    let frames = (0..surface.n_frames())
        .map(|k| {
            surface
                .positions(k)
                .expect("embedded")
                .iter()
                .map(|p| Vector3::new(p.x, p.y, 0.0))
                .collect()
        })
        .collect();
    let intensities = (0..surface.n_frames())
        .map(|k| surface.intensities(k).to_vec())
        .collect();
    Ok(MeshSequence::new(
        surface.mesh().clone(),
        frames,
        intensities,
        Some(surface.times().to_vec()),
    )?)
}
