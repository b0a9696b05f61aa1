//! `meshflow advect RUN --out DIR`: trajectories of the mesh vertices along a finished run's
//! flow (`meshflow::flow::advect`), and the sequence reparametrized by them.

use crate::progress::during;
use crate::run::FinishedRun;
use meshflow::flow::{advect as carry, closest_seeds, vertex_seeds, MeshSequence, Trajectories};
use meshflow::format::{read_npy_float, write_npy, write_npy_sequence, write_npy_vectors, IoError};
use meshflow::geometry::SurfacePoint;
use meshflow::render::colormap::finite_range;
use meshflow::render::{
    trajectory_picture, write_png, Camera, PictureStyle, Surface, UpChoice, View,
};
use meshflow::run::{Overwrite, StagedDir};
use meshflow::Error;
use nalgebra::Vector3;
use std::path::Path;

pub fn advect(
    run: &Path,
    out: &Path,
    seeds_file: Option<&Path>,
    overwrite: Overwrite,
) -> Result<(), Error> {
    let input = crate::run::solve_input(run)?;
    let staged = crate::run::stage_output(
        run,
        &input,
        &seeds_file.into_iter().collect::<Vec<_>>(),
        out,
        overwrite,
    )?;
    let FinishedRun {
        input,
        loaded,
        flow,
    } = FinishedRun::read(run, input)?;
    let sequence = &loaded.sequence;
    let seeds = match seeds_file {
        Some(file) => located_seeds(file, sequence)?,
        None => vertex_seeds(sequence),
    };
    let trajectories = during("following the seeds", || carry(sequence, &flow, &seeds))?;
    let grey = trajectories.intensities(sequence);
    let positions = trajectories.positions(sequence).ok_or_else(|| {
        IoError::format(
            &input.input,
            "an intrinsic sequence has no positions to follow",
        )
    })?;
    let target = |e| staged.error_in_target(e);
    write_paths(&staged, &positions, &trajectories).map_err(target)?;
    if seeds_file.is_none() {
        // The mesh riding on the flow: an NPY sequence `solve` reads.
        let (faces, times) = (sequence.mesh().faces(), sequence.times());
        write_npy_sequence(staged.path(), &positions, faces, Some(&grey), times)
            .map_err(|e| target(e.into()))?;
        let up = UpChoice::of_sequence(&loaded);
        stdout_line!("{}", crate::pictures::up_axis_line(&up, None));
        let view = up.view();
        draw_paths(&staged, sequence, &trajectories, view).map_err(target)?;
    }
    staged.commit()?;
    report(
        sequence,
        &grey,
        &trajectories,
        run,
        out,
        seeds_file.is_none(),
    );
    Ok(())
}

/// The points of an (N, 3) `.npy`, each at its closest point of frame 0's surface.
fn located_seeds(file: &Path, sequence: &MeshSequence) -> Result<Vec<SurfacePoint>, Error> {
    let array = read_npy_float(file)?;
    if !matches!(array.shape[..], [_, 3]) {
        let shape = format!("shape {:?}, expected (points, 3)", array.shape);
        return Err(IoError::format(file, shape).into());
    }
    let points: Vec<Vector3<f64>> = (array.data.chunks_exact(3))
        .map(|p| Vector3::new(p[0], p[1], p[2]))
        .collect();
    closest_seeds(sequence, &points).map_err(|e| e.in_file(file))
}

/// `trajectories.npy` (K, N, 3: `positions`), `trajectory_faces.npy` (K, N),
/// `trajectory_barycentric.npy` (K, N, 3).
fn write_paths(
    staged: &StagedDir,
    positions: &[Vec<Vector3<f64>>],
    trajectories: &Trajectories,
) -> Result<(), Error> {
    let dir = staged.path();
    write_npy_vectors(&dir.join("trajectories.npy"), positions)?;
    let (k, n) = (positions.len() as u64, positions[0].len() as u64);
    let points = || trajectories.points.iter().flatten();
    let faces: Vec<i64> = points().map(|p| p.face as i64).collect();
    write_npy(&dir.join("trajectory_faces.npy"), &[k, n], &faces)?;
    let barycentric: Vec<f64> = points().flat_map(|p| p.barycentric).collect();
    write_npy(
        &dir.join("trajectory_barycentric.npy"),
        &[k, n, 3],
        &barycentric,
    )?;
    Ok(())
}

/// `trajectories.png`: the last frame in grey with every path (mapped onto it) over it.
fn draw_paths(
    staged: &StagedDir,
    sequence: &MeshSequence,
    trajectories: &Trajectories,
    view: View,
) -> Result<(), Error> {
    let last = sequence.n_frames() - 1;
    let Some(positions) = sequence.positions(last) else {
        return Ok(());
    };
    let mesh = sequence.mesh();
    let n = trajectories.points[0].len();
    let paths: Vec<Vec<_>> = (0..n)
        .map(|i| {
            trajectories
                .points
                .iter()
                .map(|frame| frame[i].position(mesh, positions))
                .collect()
        })
        .collect();
    let image = sequence.intensities(last);
    let (low, high) = finite_range(image).unwrap_or((0.0, 1.0));
    let range = (low, high.max(low + f64::EPSILON));
    let camera = Camera::framing(positions, view, 960, 720);
    let surface = Surface {
        positions,
        faces: mesh.faces(),
    };
    let style = PictureStyle {
        label: Some(format!("paths of frames 0-{last} on frame {last}")),
        ..Default::default()
    };
    let picture = trajectory_picture(&camera, surface, image, range, &paths, &style)?;
    write_png(&staged.path().join("trajectories.png"), &picture)?;
    Ok(())
}

/// Per frame, the mean change of the image the moving vertices see, next to that of the
/// vertices at rest.
fn report(
    sequence: &MeshSequence,
    grey: &[Vec<f64>],
    trajectories: &Trajectories,
    run: &Path,
    out: &Path,
    vertex_seeds: bool,
) {
    let stuck = trajectories.reached_boundary.iter().filter(|&&b| b).count();
    stdout_line!(
        "{}: {} points followed through {} frames ({stuck} reached the boundary) -> {}",
        run.display(),
        grey[0].len(),
        grey.len(),
        out.display()
    );
    let mean_change = |a: &[f64], b: &[f64]| {
        a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>() / a.len() as f64
    };
    for k in (1..grey.len()).filter(|_| vertex_seeds) {
        stdout_line!(
            "  frame {k:3}: mean image change along the trajectories {:.3e} (at rest {:.3e})",
            mean_change(&grey[k], &grey[0]),
            mean_change(sequence.intensities(k), sequence.intensities(0)),
        );
    }
}
