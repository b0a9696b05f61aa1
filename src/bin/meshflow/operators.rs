//! `meshflow operators`: the finite-element operators of one mesh, for SciPy/MATLAB.

use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem;
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{read_mesh, write_matrix_market, write_npy, IoError};
use meshflow::mesh::Mesh;
use meshflow::Error;
use std::path::Path;

pub fn write_operators(mesh_path: &Path, out: &Path) -> Result<(), Error> {
    let obj = read_mesh(mesh_path)?;
    let in_file = |e: Error| e.in_file(mesh_path);
    let mesh = Mesh::new(obj.positions.len(), obj.faces).map_err(|e| in_file(e.into()))?;
    let geometry =
        IntrinsicGeometry::from_positions(&mesh, &obj.positions).map_err(|e| in_file(e.into()))?;
    let connection = Connection::new(&mesh, &geometry);
    let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &obj.positions)
        .map_err(|e| in_file(e.into()))?;
    let matrices = fem::exported_operators(&mesh, &geometry, &connection);
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
    println!(
        "{}: {} vertices, {} faces, {} boundary vertices, Euler characteristic {} -> {}",
        mesh_path.display(),
        mesh.n_vertices(),
        mesh.n_faces(),
        (0..mesh.n_vertices())
            .filter(|&i| mesh.is_boundary_vertex(i))
            .count(),
        mesh.euler_characteristic(),
        out.display()
    );
    Ok(())
}
