//! File formats: exact round trips, and clear errors (with line numbers) for broken files.

mod common;

use common::listing;
use meshflow::connection::Connection;
use meshflow::fem::connection_laplacian;
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{
    read_matrix_market, read_npy, read_obj, write_atomically, write_matrix_market, write_npy,
    write_obj, IoError, Overwrite, RunManifest, StagedDir, RUN_MANIFEST,
};
use meshflow::shapes::icosphere;
use nalgebra::Vector3;
use std::path::Path;

fn write_file(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

#[test]
fn obj_round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = icosphere(2);
    let jitter = common::noise(sphere.positions.len(), 3);
    let positions: Vec<Vector3<f64>> = sphere
        .positions
        .iter()
        .zip(&jitter)
        .map(|(p, j)| p * (1.0 + 1e-3 * j) + Vector3::repeat(1e-17))
        .collect();
    let colors: Vec<[f64; 3]> = jitter.iter().map(|&j| [j, j / 3.0, 1.7]).collect();
    let path = dir.path().join("sphere.obj");
    write_obj(&path, &positions, &sphere.faces, Some(&colors)).unwrap();
    let back = read_obj(&path).unwrap();
    assert_eq!(back.positions, positions);
    assert_eq!(back.faces, sphere.faces);
    assert_eq!(back.colors.unwrap(), colors);
}

#[test]
fn obj_reader_handles_polygons_references_and_keeps_vertex_order() {
    let dir = tempfile::tempdir().unwrap();
    let text = "# a quad and a triangle, vertices listed out of face order\n\
                v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n\
                o square\ng part\nusemtl none\ns off\n\
                f 4/1/1 1/1/1 2/1/1 3/1/1\nv 2 0.5 0\nf -4//1 -1//1 -3//1\n";
    let mesh = read_obj(&write_file(dir.path(), "quad.obj", text)).unwrap();
    assert_eq!(mesh.positions.len(), 5);
    assert_eq!(mesh.positions[3], Vector3::new(0.0, 1.0, 0.0));
    assert_eq!(mesh.faces, vec![[3, 0, 1], [3, 1, 2], [1, 4, 2]]);
    assert!(mesh.colors.is_none());
}

fn obj_error(text: &str) -> IoError {
    let dir = tempfile::tempdir().unwrap();
    read_obj(&write_file(dir.path(), "bad.obj", text)).unwrap_err()
}

#[test]
fn broken_obj_files_name_the_line() {
    let cases = [
        ("v 0 0 0\nv 1 0 zero\n", 2, "'zero' is not a number"),
        ("v 0 0 0\nv 1 0\n", 2, "needs 3, 4, 6 or 7 numbers"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
            4,
            "at least 3 vertices",
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 9\n",
            5,
            "vertex 9 does not exist",
        ),
        ("v 0 0 0\nv 1 0 0\nf 1 2 -7\n", 3, "out of range"),
    ];
    for (text, line, message) in cases {
        match obj_error(text) {
            IoError::Parse {
                line: l,
                message: m,
                ..
            } => {
                assert_eq!(l, line, "{text:?}");
                assert!(m.contains(message), "{m:?} should mention {message:?}");
            }
            other => panic!("{text:?}: unexpected {other:?}"),
        }
    }
    let partial = obj_error("v 0 0 0 1 1 1\nv 1 0 0\nv 0 1 0 0.5 0.5 0.5\nf 1 2 3\n");
    assert!(
        partial.to_string().contains("2 of 3 vertices have colours"),
        "{partial}"
    );
    let missing = read_obj(Path::new("/nonexistent/frame.obj")).unwrap_err();
    assert!(
        matches!(missing, IoError::File { .. })
            && missing.to_string().contains("/nonexistent/frame.obj")
    );
}

#[test]
fn npy_round_trip_and_validation() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.npy");
    let data: Vec<f64> = (0..24).map(|i| i as f64 * 0.1 - 1e-300).collect();
    write_npy(&path, &[2, 3, 4], &data).unwrap();
    let back = read_npy(&path).unwrap();
    assert_eq!((back.shape, back.data), (vec![2, 3, 4], data.clone()));
    assert!(write_npy(&dir.path().join("b.npy"), &[5, 5], &data).is_err());
    assert!(!dir.path().join("b.npy").exists());

    // Truncated: drop the last value.
    let bytes = std::fs::read(&path).unwrap();
    let cut = write_file(dir.path(), "cut.npy", &bytes[..bytes.len() - 8]);
    assert!(read_npy(&cut)
        .unwrap_err()
        .to_string()
        .contains("does not fit"));
    // Wrong dtype: the same header claiming int32 (same length, so the layout stays valid).
    let mut relabelled = bytes.clone();
    let at = relabelled.windows(3).position(|w| w == b"<f8").unwrap();
    relabelled[at..at + 3].copy_from_slice(b"<i4");
    let wrong = write_file(dir.path(), "int.npy", &relabelled);
    let message = read_npy(&wrong).unwrap_err().to_string();
    assert!(message.contains("expected float64"), "{message}");
    let garbage = write_file(dir.path(), "garbage.npy", b"definitely not numpy");
    assert!(read_npy(&garbage)
        .unwrap_err()
        .to_string()
        .contains("not a valid .npy"));
}

/// Rows of the first axis read alone (`read_npy_float_rows`, `read_npy_image_rows`: what a rank
/// reads of a long recording) equal those rows of the whole array, for float32, float64, uint8
/// and uint16; the file's row count comes with them, and no row at all reads only the header.
/// A truncated file is refused before any row is read.
#[test]
fn npy_rows_are_those_of_the_whole_array() {
    use meshflow::io::{read_npy_float, read_npy_float_rows, read_npy_image, read_npy_image_rows};
    let dir = tempfile::tempdir().unwrap();
    let shape = [5u64, 4, 3];
    let keep = |k: usize| matches!(k, 0 | 2 | 3);
    let rows_of = |whole: &[f64]| -> Vec<f64> {
        (whole.chunks(12).enumerate())
            .filter(|(k, _)| keep(*k))
            .flat_map(|(_, row)| row.to_vec())
            .collect()
    };
    let f32s: Vec<f32> = (0..60).map(|i| i as f32 * 0.37 - 3.0).collect();
    let f64s: Vec<f64> = (0..60).map(|i| (i as f64).sin()).collect();
    let u8s: Vec<u8> = (0..60).map(|i| (i * 7 % 256) as u8).collect();
    let u16s: Vec<u16> = (0..60).map(|i| (i * 1031 % 65536) as u16).collect();
    let files = [("f32", 0), ("f64", 1), ("u8", 2), ("u16", 3)].map(|(name, kind)| {
        let path = dir.path().join(format!("{name}.npy"));
        match kind {
            0 => common::write_npy(&path, &shape, &f32s),
            1 => common::write_npy(&path, &shape, &f64s),
            2 => common::write_npy(&path, &shape, &u8s),
            _ => common::write_npy(&path, &shape, &u16s),
        }
        path
    });
    for (k, path) in files.iter().enumerate() {
        let whole = read_npy_image(path).unwrap();
        let (rows, n_rows) = read_npy_image_rows(path, &keep).unwrap();
        assert_eq!(n_rows, 5);
        assert_eq!(rows.shape, vec![3, 4, 3], "{path:?}");
        assert_eq!(rows.data, rows_of(&whole.data), "{path:?}");
        if k < 2 {
            let whole = read_npy_float(path).unwrap();
            let (rows, _) = read_npy_float_rows(path, &keep).unwrap();
            assert_eq!(rows.data, rows_of(&whole.data), "{path:?}");
        }
        let (none, n_rows) = read_npy_image_rows(path, &|_| false).unwrap();
        assert_eq!((none.shape, none.data.len(), n_rows), (vec![0, 4, 3], 0, 5));
    }
    assert_eq!(
        read_npy_image(&files[0]).unwrap().data[5],
        f64::from(f32s[5])
    );
    let bytes = std::fs::read(&files[1]).unwrap();
    let cut = write_file(dir.path(), "cut.npy", &bytes[..bytes.len() - 8]);
    let message = read_npy_float_rows(&cut, &|k| k == 0)
        .unwrap_err()
        .to_string();
    assert!(message.contains("does not fit"), "{message}");
}

#[test]
fn matrix_market_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = icosphere(1);
    let mesh = sphere.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &sphere.positions).unwrap();
    let k = connection_laplacian(&mesh, &geometry, &Connection::new(&mesh, &geometry));
    let path = dir.path().join("k.mtx");
    write_matrix_market(&path, &k).unwrap();
    let back = read_matrix_market(&path).unwrap();
    assert_eq!(common::relative_value_difference(&k, &back), 0.0);
}

#[test]
fn failed_atomic_write_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("out.bin");
    std::fs::write(&target, b"old").unwrap();
    let err = write_atomically(&target, |w| {
        use std::io::Write;
        w.write_all(b"half of the new conte")?;
        Err(std::io::Error::other("disk on fire"))
    })
    .unwrap_err();
    assert!(err.to_string().contains("disk on fire"));
    assert_eq!(std::fs::read(&target).unwrap(), b"old");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temporary file is left"
    );
}

#[test]
fn ground_truth_is_float32_or_float64_and_lands_on_mesh_vertices() {
    use meshflow::io::{read_ground_truth, VertexMap};
    let dir = tempfile::tempdir().unwrap();
    // File vertex 3 is a welded copy of 0, file vertex 4 was dropped.
    let welding =
        VertexMap::from_mesh_vertices(&[Some(0), Some(1), Some(2), Some(0), None]).unwrap();
    // (slabs 2, file vertices 5, 3); row 3 repeats row 0 in each slab, row 4 is NaN (ignored).
    let row = |s: usize, i: usize| match i {
        4 => [f64::NAN; 3],
        _ => {
            let i = if i == 3 { 0 } else { i };
            [0.1, 0.2, 0.3].map(|c| c * (1 + i + 10 * s) as f64)
        }
    };
    let rows: Vec<f64> = (0..2)
        .flat_map(|s| (0..5).flat_map(move |i| row(s, i)))
        .collect();

    let single: Vec<f32> = rows.iter().map(|&v| v as f32).collect();
    let path = dir.path().join("truth32.npy");
    write_npy(&path, &[2, 5, 3], &single).unwrap();
    let truth = read_ground_truth(&path, &welding, 2).unwrap();
    assert_eq!(truth.len(), 2);
    for (s, slab) in truth.iter().enumerate() {
        let expected: Vec<Vector3<f64>> = (0..3)
            .map(|w| Vector3::from(row(s, w).map(|c| f64::from(c as f32))))
            .collect();
        assert_eq!(slab, &expected, "slab {s}");
    }
    // float32 data fails read_npy (float64 only), as before.
    assert!(read_npy(&path)
        .unwrap_err()
        .to_string()
        .contains("expected float64"));

    // Copies may differ by round-off (1e-12 of the slab's largest speed), not by 1e-8.
    let path = dir.path().join("truth64.npy");
    let largest = Vector3::from(row(1, 2)).norm();
    for (offset, accepted) in [(1e-12 * largest, true), (1e-8 * largest, false)] {
        let mut shifted = rows.clone();
        shifted[3 * (5 + 3)] += offset; // slab 1, file vertex 3, x
        write_npy(&path, &[2, 5, 3], &shifted).unwrap();
        let result = read_ground_truth(&path, &welding, 2);
        assert_eq!(result.is_ok(), accepted, "{offset}: {result:?}");
        if let Err(error) = result {
            let message = error.to_string();
            assert!(
                message.contains("truth64.npy")
                    && message.contains("slab 1: file vertices 0 and 3"),
                "{message}"
            );
        }
    }
    // Three slabs expected: the shape is named.
    write_npy(&path, &[2, 5, 3], &rows).unwrap();
    let message = read_ground_truth(&path, &welding, 3)
        .unwrap_err()
        .to_string();
    assert!(message.contains("expected (3, 5, 3)"), "{message}");
    // A NaN at a kept vertex is refused.
    let mut broken = rows.clone();
    broken[3 * 2] = f64::NAN; // slab 0, file vertex 2
    write_npy(&path, &[2, 5, 3], &broken).unwrap();
    let message = read_ground_truth(&path, &welding, 2)
        .unwrap_err()
        .to_string();
    assert!(message.contains("slab 0, vertex 2"), "{message}");
}

/// Stages `files` (name, contents) for `target` with `overwrite`, recording `command`, and
/// commits.
fn staged_run(
    target: &Path,
    overwrite: Overwrite,
    command: &str,
    files: &[(&str, &str)],
) -> Result<(), IoError> {
    let mut staged = StagedDir::create(target, overwrite)?;
    staged.record_command(["meshflow", command]);
    for (name, contents) in files {
        std::fs::write(staged.path().join(name), contents).unwrap();
    }
    staged.commit()
}

#[test]
fn an_output_directory_holds_exactly_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let first = [
        ("flow.npy", "1"),
        ("flow_0000.vtu", "1"),
        ("flow_0001.vtu", "1"),
    ];
    staged_run(&out, Overwrite::EarlierRun, "first", &first).unwrap();
    assert_eq!(
        listing(&out),
        ["flow.npy", "flow_0000.vtu", "flow_0001.vtu", RUN_MANIFEST]
    );
    // The rerun replaces the whole directory: the stale slab files are gone.
    staged_run(&out, Overwrite::EarlierRun, "second", &[("flow.npy", "2")]).unwrap();
    assert_eq!(listing(&out), ["flow.npy", RUN_MANIFEST]);
    assert_eq!(std::fs::read_to_string(out.join("flow.npy")).unwrap(), "2");
    let manifest = RunManifest::read(&out).unwrap();
    assert_eq!(manifest.files, ["flow.npy"]);
    assert_eq!(manifest.commands, [["meshflow", "second"]]);
    assert_eq!(listing(dir.path()), ["out"], "no staging or backup left");

    // An empty directory is fine.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    staged_run(&empty, Overwrite::EarlierRun, "x", &[("a.npy", "a")]).unwrap();
    assert_eq!(listing(&empty), ["a.npy", RUN_MANIFEST]);

    // A failed run (dropped before its commit) leaves the earlier output as it was.
    let mut failed = StagedDir::new(&out).unwrap();
    failed.record_command(["meshflow", "failed"]);
    std::fs::write(failed.path().join("flow.npy"), "half").unwrap();
    drop(failed);
    assert_eq!(listing(&out), ["flow.npy", RUN_MANIFEST]);
    assert_eq!(std::fs::read_to_string(out.join("flow.npy")).unwrap(), "2");
    assert_eq!(listing(dir.path()), ["empty", "out"]);
}

#[test]
fn directories_meshflow_did_not_write_are_refused_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mine");
    std::fs::create_dir(&out).unwrap();
    for name in ["notes.txt", "a", "b", "c"] {
        std::fs::write(out.join(name), "mine").unwrap();
    }
    let error = StagedDir::new(&out).unwrap_err().to_string();
    assert_eq!(
        error,
        format!(
            "{}: is not empty and not a meshflow output (a, b, c, 1 more); choose another \
             output directory, empty it, or add --force to write into it (its other files stay)",
            out.display()
        )
    );
    assert_eq!(
        listing(dir.path()),
        ["mine"],
        "refused before staging anything"
    );

    // Forced: the new files join the others.
    staged_run(&out, Overwrite::Force, "forced", &[("flow.npy", "1")]).unwrap();
    assert_eq!(
        listing(&out),
        ["a", "b", "c", "flow.npy", RUN_MANIFEST, "notes.txt"]
    );
    // Still not wholly meshflow's: refused again; forced again, the earlier run's files go.
    let error = StagedDir::new(&out).unwrap_err().to_string();
    assert!(error.contains("holds files that meshflow did not write (a, b, c, 1 more)"));
    staged_run(&out, Overwrite::Force, "again", &[("other.npy", "2")]).unwrap();
    assert_eq!(
        listing(&out),
        ["a", "b", "c", RUN_MANIFEST, "notes.txt", "other.npy"]
    );
    assert_eq!(RunManifest::read(&out).unwrap().files, ["other.npy"]);
    assert_eq!(std::fs::read_to_string(out.join("a")).unwrap(), "mine");

    // A file of the manifest's name that is no manifest does not make a run.
    let fake = dir.path().join("fake");
    std::fs::create_dir(&fake).unwrap();
    std::fs::write(fake.join(RUN_MANIFEST), "{}").unwrap();
    let error = StagedDir::new(&fake).unwrap_err().to_string();
    assert!(
        error.contains(&format!("not a meshflow output ({RUN_MANIFEST})")),
        "{error}"
    );
    // Nor is a file a directory.
    std::fs::write(dir.path().join("file"), "x").unwrap();
    let error = StagedDir::new(&dir.path().join("file")).unwrap_err();
    assert!(error.to_string().contains("is a file"), "{error}");
}

#[test]
fn an_update_keeps_the_chosen_files_of_the_earlier_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let solved = [
        ("flow.npy", "flow"),
        ("grey_0000.png", "old"),
        ("grey_0001.png", "old"),
    ];
    staged_run(&out, Overwrite::EarlierRun, "solve", &solved).unwrap();
    let mut update =
        StagedDir::update(&out, Overwrite::EarlierRun, |name| !name.ends_with(".png")).unwrap();
    update.record_command(["meshflow", "render"]);
    std::fs::write(update.path().join("grey_0001.png"), "new").unwrap();
    update.commit().unwrap();
    assert_eq!(listing(&out), ["flow.npy", "grey_0001.png", RUN_MANIFEST]);
    assert_eq!(
        std::fs::read_to_string(out.join("flow.npy")).unwrap(),
        "flow"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("grey_0001.png")).unwrap(),
        "new"
    );
    let manifest = RunManifest::read(&out).unwrap();
    assert_eq!(manifest.files, ["flow.npy", "grey_0001.png"]);
    assert_eq!(
        manifest.commands,
        [["meshflow", "solve"], ["meshflow", "render"]]
    );
    assert_eq!(listing(dir.path()), ["run"]);
}

#[cfg(unix)]
#[test]
fn an_output_behind_a_symbolic_link_is_replaced_where_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let real = dir.path().join("real");
    let link = dir.path().join("link");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    std::fs::create_dir(&real).unwrap();
    staged_run(&link, Overwrite::EarlierRun, "first", &[("a.npy", "1")]).unwrap();
    staged_run(&link, Overwrite::EarlierRun, "second", &[("b.npy", "2")]).unwrap();
    assert!(link.is_symlink());
    assert_eq!(listing(&real), ["b.npy", RUN_MANIFEST]);
}
