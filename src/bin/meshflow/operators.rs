//! `meshflow operators`: the finite-element operators of one mesh, for SciPy/MATLAB.

use crate::progress::during;
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem;
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{read_mesh, write_matrix_market, write_npy, Overwrite, StagedDir};
use meshflow::mesh::Mesh;
use meshflow::Error;
use std::path::Path;

pub fn write_operators(mesh_path: &Path, out: &Path, overwrite: Overwrite) -> Result<(), Error> {
    let mut staged = StagedDir::create(out, overwrite)?;
    staged.record_command(crate::command_line());
    let obj = during(format!("reading {}", mesh_path.display()), || {
        read_mesh(mesh_path)
    })?;
    let in_file = |e: Error| e.in_file(mesh_path);
    let mesh = Mesh::new(obj.positions.len(), obj.faces).map_err(|e| in_file(e.into()))?;
    let geometry =
        IntrinsicGeometry::from_positions(&mesh, &obj.positions).map_err(|e| in_file(e.into()))?;
    let connection = Connection::new(&mesh, &geometry);
    let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &obj.positions)
        .map_err(|e| in_file(e.into()))?;
    let matrices = during("assembling the operators", || {
        fem::exported_operators(&mesh, &geometry, &connection)
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
    staged.commit()?;
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
