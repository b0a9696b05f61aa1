//! Large-input benchmark: writes a 1,002,001-vertex OBJ frame (a 1000×1000 grid over a wavy
//! height field, two million triangles, grey vertex colours), then times reading it
//! (`read_obj`), validating its connectivity (`Mesh::new`) and its geometry
//! (`IntrinsicGeometry::from_positions`), and loading a two-frame sequence of it end to end
//! (`load_sequence`: parallel reads, checks, welding, validation).
//!
//! `cargo run --release --example bench_io [-- N]` (an N×N grid; default 1000)

use meshflow::format::{read_obj, write_obj};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::load::load_sequence;
use meshflow::mesh::Mesh;
use meshflow::shapes::grid;
use std::time::Instant;

fn main() -> Result<(), meshflow::Error> {
    let n: usize = std::env::args()
        .nth(1)
        .map_or(1000, |a| a.parse().expect("a whole number"));
    let dir = std::env::temp_dir().join(format!("meshflow-bench-io-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let mut surface = grid(n, n, 1.0, 1.0);
    for p in &mut surface.positions {
        p.z = 0.05 * (12.0 * p.x).sin() * (9.0 * p.y).cos();
    }
    let colors: Vec<[f64; 3]> = surface
        .positions
        .iter()
        .map(|p| [0.5 + 0.5 * (40.0 * p.x).sin() * (30.0 * p.y).sin(); 3])
        .collect();
    for k in 0..2 {
        let positions: Vec<_> = surface
            .positions
            .iter()
            .map(|p| p + nalgebra::Vector3::new(0.0, 0.0, 0.01 * k as f64))
            .collect();
        let path = dir.join(format!("frame_{k}.obj"));
        write_obj(&path, &positions, &surface.faces, Some(&colors))?;
    }
    let frame = dir.join("frame_0.obj");
    let bytes = std::fs::metadata(&frame).map_or(0, |m| m.len());
    println!(
        "{}: {} vertices, {} faces, {:.0} MB",
        frame.display(),
        surface.positions.len(),
        surface.faces.len(),
        bytes as f64 / 1e6
    );

    let start = Instant::now();
    let obj = read_obj(&frame)?;
    let read = start.elapsed().as_secs_f64();
    let mesh = Mesh::new(obj.positions.len(), obj.faces.clone())?;
    let connectivity = start.elapsed().as_secs_f64() - read;
    IntrinsicGeometry::from_positions(&mesh, &obj.positions)?;
    let geometry = start.elapsed().as_secs_f64() - read - connectivity;
    println!("read_obj {read:.2} s, connectivity {connectivity:.2} s, geometry {geometry:.2} s");

    let start = Instant::now();
    let loaded = load_sequence(&dir, &Default::default())?;
    println!(
        "load_sequence of 2 frames: {:.2} s ({} vertices, {} welded)",
        start.elapsed().as_secs_f64(),
        loaded.sequence.mesh().n_vertices(),
        loaded.vertex_map.n_welded()
    );
    std::fs::remove_dir_all(&dir).expect("cleanup");
    Ok(())
}
