//! `meshflow operators`: the finite-element operators of one mesh, for SciPy/MATLAB.
//!
//! The mesh is built as `solve` builds it (welded, unused vertices dropped, oriented, repaired
//! with `--repair`), without grey values; matrices and `frames.npy` are over its vertices, and
//! `vertex_map.npy` relates them to the file's when the two numberings differ.

use crate::progress::during;
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem;
use meshflow::format::{write_matrix_market, write_npy};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::load::{load_mesh, LoadOptions};
use meshflow::run::{Overwrite, StagedDir};
use meshflow::Error;
use std::path::Path;

pub fn write_operators(
    mesh_path: &Path,
    out: &Path,
    options: &LoadOptions,
    overwrite: Overwrite,
) -> Result<(), Error> {
    let mut staged = StagedDir::create_apart_from(&[mesh_path], out, overwrite)?;
    staged.record_command(crate::command_line());
    let loaded = during(format!("reading {}", mesh_path.display()), || {
        load_mesh(mesh_path, options)
    })?;
    crate::print_warnings(&loaded.warnings);
    let (mesh, positions) = (&loaded.mesh, &loaded.positions);
    let in_file = |e: Error| e.in_file(mesh_path);
    let geometry =
        IntrinsicGeometry::from_positions(mesh, positions).map_err(|e| in_file(e.into()))?;
    let connection = Connection::new(mesh, &geometry);
    let frames = vertex_frames_in_r3(mesh, &geometry, &connection, positions)
        .map_err(|e| in_file(e.into()))?;
    let matrices = during("assembling the operators", || {
        fem::exported_operators(mesh, &geometry, &connection)
    });
    let dir = staged.path();
    let writing = during(format!("writing {}", out.display()), || {
        matrices
            .iter()
            .try_for_each(|(name, matrix)| {
                write_matrix_market(&dir.join(format!("{name}.mtx")), matrix)
            })
            .map_err(|e| staged.in_target(e))
    });
    writing?;
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
        &dir.join("frames.npy"),
        &[mesh.n_vertices() as u64, 2, 3],
        &frame_values,
    )
    .map_err(|e| staged.in_target(e))?;
    let map = &loaded.vertex_map;
    if !map.is_identity() {
        let table = map.to_npy();
        write_npy(&dir.join("vertex_map.npy"), &[table.len() as u64], &table)
            .map_err(|e| staged.in_target(e))?;
    }
    staged.commit()?;
    stdout_line!(
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
