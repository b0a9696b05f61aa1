//! `meshflow operators`: the finite-element operators of one mesh, for SciPy/MATLAB.
//!
//! The mesh is built as `solve` builds it (welded, unused vertices dropped, oriented, repaired
//! with `--repair`), without grey values; matrices and `frames.npy` are over its vertices, and
//! `vertex_map.npy` relates them to the file's when the two numberings differ.

use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem;
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{load_mesh, write_matrix_market, write_npy, IoError, LoadOptions};
use meshflow::Error;
use std::path::Path;

pub fn write_operators(mesh_path: &Path, out: &Path, options: &LoadOptions) -> Result<(), Error> {
    let loaded = load_mesh(mesh_path, options)?;
    crate::print_warnings(&loaded.warnings);
    let (mesh, positions) = (&loaded.mesh, &loaded.positions);
    let in_file = |e: Error| e.in_file(mesh_path);
    let geometry =
        IntrinsicGeometry::from_positions(mesh, positions).map_err(|e| in_file(e.into()))?;
    let connection = Connection::new(mesh, &geometry);
    let frames = vertex_frames_in_r3(mesh, &geometry, &connection, positions)
        .map_err(|e| in_file(e.into()))?;
    let matrices = fem::exported_operators(mesh, &geometry, &connection);
    std::fs::create_dir_all(out).map_err(|e| IoError::File {
        path: out.to_path_buf(),
        source: e,
    })?;
    for (name, matrix) in &matrices {
        write_matrix_market(&out.join(format!("{name}.mtx")), matrix)?;
    }
    // frames.npy[i][k] = R^3 image of basis vector k of vertex i's frame.
    let frame_values: Vec<f64> = frames
        .iter()
        .flat_map(|p| {
            [p.column(0), p.column(1)]
                .into_iter()
                .flat_map(|c| [c[0], c[1], c[2]])
        })
        .collect();
    write_npy(
        &out.join("frames.npy"),
        &[mesh.n_vertices() as u64, 2, 3],
        &frame_values,
    )?;
    let map = &loaded.vertex_map;
    if !map.is_identity() {
        let table = map.to_npy();
        write_npy(&out.join("vertex_map.npy"), &[table.len() as u64], &table)?;
    }
    println!(
        "{}: {} vertices{}, {} faces, {} boundary vertices, Euler characteristic {} -> {}",
        mesh_path.display(),
        mesh.n_vertices(),
        crate::welded_note(map.n_welded()),
        mesh.n_faces(),
        (0..mesh.n_vertices())
            .filter(|&i| mesh.is_boundary_vertex(i))
            .count(),
        mesh.euler_characteristic(),
        out.display()
    );
    Ok(())
}
