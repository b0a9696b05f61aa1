//! `meshflow track` as a user runs it: the image options (`--intensity-attribute`,
//! `--intensity`, `--channels`), the hints and warnings about images, and the report of a run
//! that fails part-way.

mod common;

use common::{meshflow, meshflow_error, meshflow_ok, write_npy};
use meshflow::io::ply::{write_ply, PlyEncoding};
use meshflow::io::{read_npy, write_obj};
use meshflow::shapes::{icosphere, uv_sphere, Surface};
use nalgebra::{Rotation3, Vector3};
use std::path::Path;

fn signal(x: &Vector3<f64>) -> f64 {
    0.4 + 0.2 * x.x - 0.15 * x.y + 0.1 * x.z
}

/// A sphere growing from radius 1 by 5 % per frame, meshed differently in every frame.
fn frames() -> Vec<Surface> {
    let turned = Rotation3::from_euler_angles(0.3, 0.2, 0.1);
    let meshes = [icosphere(3), uv_sphere(16, 32), icosphere(3)];
    (meshes.into_iter().enumerate())
        .map(|(k, mut mesh)| {
            for p in mesh.positions.iter_mut() {
                *p = 1.05f64.powi(k as i32) * if k == 2 { turned * *p } else { *p };
            }
            mesh
        })
        .collect()
}

/// PLY frames with an integer `label` and a fractional `signal` and no colours.
fn write_ply_frames(dir: &Path) -> Vec<Surface> {
    let frames = frames();
    for (k, f) in frames.iter().enumerate() {
        let label: Vec<f64> = (0..f.positions.len()).map(|i| (i % 7) as f64).collect();
        let values: Vec<f64> = f.positions.iter().map(signal).collect();
        let properties: [(&str, &[f64]); 2] = [("label", &label), ("signal", &values)];
        let path = dir.join(format!("t{k}.ply"));
        write_ply(
            &path,
            &f.positions,
            &f.faces,
            None,
            &properties,
            PlyEncoding::Ascii,
        )
        .unwrap();
    }
    frames
}

/// OBJ frames without colours in `dir/frames`.
fn write_obj_frames(dir: &Path, frames: &[Surface]) -> std::path::PathBuf {
    let input = dir.join("frames");
    std::fs::create_dir(&input).unwrap();
    for (k, f) in frames.iter().enumerate() {
        let path = input.join(format!("t{k}.obj"));
        write_obj(&path, &f.positions, &f.faces, None).unwrap();
    }
    input
}

fn stderr(run: &std::process::Output) -> String {
    String::from_utf8_lossy(&run.stderr).into_owned()
}

/// Without an image option, the hint names the fractional property, not the integer label,
/// and only options of `track`; with `--intensity-attribute signal` the tracked image is the
/// signal where the tracked vertices are (exact: it is linear); with `--intensity DIR` of
/// three channels per frame, `intensity.npy` holds the three channels.
#[test]
fn track_takes_the_image_from_a_ply_property_or_per_frame_arrays() {
    let work = tempfile::tempdir().unwrap();
    let input = work.path().join("frames");
    std::fs::create_dir(&input).unwrap();
    let frames = write_ply_frames(&input);
    let input = input.to_str().unwrap();

    let refused = work.path().join("refused");
    let run = meshflow(&["track", input, "--out", refused.to_str().unwrap()]);
    let message = stderr(&run);
    assert_eq!(run.status.code(), Some(1), "{message}");
    assert_eq!(message.lines().count(), 1, "{message}");
    assert!(
        message.contains("use --intensity-attribute signal (or --intensity FILE.npy)"),
        "{message}"
    );
    assert!(!refused.exists());

    let out = work.path().join("tracked");
    meshflow_ok(&[
        "track",
        input,
        "--out",
        out.to_str().unwrap(),
        "--intensity-attribute",
        "signal",
    ]);
    let positions = read_npy(&out.join("positions.npy")).unwrap();
    let image = read_npy(&out.join("intensity.npy")).unwrap();
    let v = frames[0].positions.len();
    assert_eq!(
        (positions.shape.clone(), image.shape.clone()),
        (vec![3, v as u64, 3], vec![3, v as u64])
    );
    for (x, grey) in positions.data.chunks_exact(3).zip(&image.data) {
        let x = Vector3::new(x[0], x[1], x[2]);
        assert!((grey - signal(&x)).abs() < 1e-12, "{grey} at {x:?}");
    }

    let arrays = work.path().join("image");
    std::fs::create_dir(&arrays).unwrap();
    for (k, f) in frames.iter().enumerate() {
        let values: Vec<f64> = f
            .positions
            .iter()
            .flat_map(|x| [signal(x), 2.0 * signal(x), 1.0])
            .collect();
        write_npy(
            &arrays.join(format!("frame_{k}.npy")),
            &[f.positions.len() as u64, 3],
            &values,
        );
    }
    let colour = work.path().join("colour");
    meshflow_ok(&[
        "track",
        input,
        "--out",
        colour.to_str().unwrap(),
        "--intensity",
        arrays.to_str().unwrap(),
    ]);
    let image = read_npy(&colour.join("intensity.npy")).unwrap();
    assert_eq!(image.shape, vec![3, v as u64, 3]);
    for c in image.data.chunks_exact(3) {
        assert!(
            (c[1] - 2.0 * c[0]).abs() < 1e-12 && (c[2] - 1.0).abs() < 1e-12,
            "{c:?}"
        );
    }

    // One array cannot hold frames of different sizes: the error names the file and says why.
    let one = work.path().join("one.npy");
    write_npy(&one, &[3, v as u64], &vec![0.5; 3 * v]);
    let run = meshflow(&[
        "track",
        input,
        "--out",
        work.path().join("x").to_str().unwrap(),
        "--intensity",
        one.to_str().unwrap(),
    ]);
    let message = stderr(&run);
    assert_eq!(run.status.code(), Some(1), "{message}");
    assert!(
        message.contains("one.npy") && message.contains("one .npy per frame"),
        "{message}"
    );
}

/// Frames without an image track, with a warning that says what `solve` will need.
#[test]
fn frames_without_an_image_are_tracked_with_a_warning_for_solve() {
    let work = tempfile::tempdir().unwrap();
    let input = write_obj_frames(work.path(), &frames());
    let out = work.path().join("tracked");
    let run = meshflow_ok(&[
        "track",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let message = stderr(&run);
    assert!(
        message.contains("intensity.npy not written")
            && message.contains("`meshflow solve` on the result will need --intensity"),
        "{message}"
    );
    assert!(!out.join("intensity.npy").exists() && out.join("positions.npy").exists());
}

/// A run that fails at frame 2 has printed the reports of frames 0 and 1 with track.json's
/// names, and the error says where the fault is; nothing is written.
#[test]
fn a_failed_run_shows_the_frames_done_and_where_the_fault_is() {
    let work = tempfile::tempdir().unwrap();
    let mut frames = frames();
    for p in frames[2].positions.iter_mut() {
        *p *= 2.0;
    }
    let input = write_obj_frames(work.path(), &frames);
    let out = work.path().join("tracked");
    let run = meshflow(&[
        "track",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--max-step",
        "0.3",
    ]);
    let (stdout, message) = (String::from_utf8_lossy(&run.stdout), stderr(&run));
    assert_eq!(run.status.code(), Some(1), "{message}");
    for k in 0..2 {
        let line = stdout
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("frame   {k}:")));
        let line = line.unwrap_or_else(|| panic!("no line for frame {k} in {stdout}"));
        for name in [
            "mean_step",
            "edge_log_ratio_p99",
            "flipped_triangles",
            "max_off_surface",
            "worst_edge_change",
        ] {
            assert!(line.contains(name), "{line}");
        }
    }
    assert!(!stdout.contains("frame   2:"), "{stdout}");
    assert_eq!(message.lines().count(), 1, "{message}");
    assert!(
        message.contains("frame 2: vertex")
            && message.contains("(at (")
            && message.contains("inside"),
        "{message}"
    );
    assert!(!out.exists());
}

/// Simplification only removes vertices: asking for more than the mesh has is an error that
/// says so, not a silent run at the mesh's own size under a header that promises the number.
#[test]
fn a_reference_larger_than_the_mesh_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let frames = frames();
    let input = write_obj_frames(dir.path(), &frames);
    let out = dir.path().join("out");
    let (input, out_text) = (input.to_str().unwrap(), out.to_str().unwrap());
    let asked = ["--reference-vertices", "100000000", "--quiet"];
    let has = frames[0].positions.len();
    meshflow_error(
        &[&["track", input, "--out", out_text][..], &asked].concat(),
        &format!("--reference-vertices 100000000 asks for more than the {has} vertices"),
    );
    assert!(!out.exists());
}
