//! A microscopist's first day (issue 41): wrong units refused with the numbers that tell why,
//! vertices without data flagged from `sample` through `solve`, every tracked cell's error
//! written, and the messages a newcomer meets on the way.

mod common;

use common::{meshflow, meshflow_error, meshflow_ok, shipped, surface, write_npy};
use meshflow::format::{read_npy, read_npy_image};
use meshflow::mesh::Mesh;
use meshflow::volume::{
    sample_sequence, Misplacement, PlacementReport, SampleOptions, Volume, VolumeError,
};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// (2, 24, 24, 24) volumes of voxel 1 (a textured pattern), to be placed about the sphere by
/// `--origin=-11.5,-11.5,-11.5`.
fn volumes(dir: &Path) -> PathBuf {
    let file = dir.join("volumes.npy");
    let values: Vec<f32> = (0..2 * 24 * 24 * 24)
        .map(|n| 1.0 + ((n % 24) as f32 * 0.7).sin() * ((n / 24 % 24) as f32 * 0.5).cos())
        .collect();
    write_npy(&file, &[2, 24, 24, 24], &values);
    file
}

const ORIGIN: &str = "--origin=-11.5,-11.5,-11.5";

/// One frame's message, the report's numbers in it and the hint the sizes give.
#[test]
fn a_surface_mostly_outside_its_volume_is_refused_with_the_reason() {
    let mesh = Mesh::new(3, vec![[0, 1, 2]]).unwrap();
    let volume = |voxel: f64| {
        Volume::new(
            [4, 4, 4],
            vec![1.0; 64],
            Vector3::repeat(voxel),
            Vector3::zeros(),
        )
        .unwrap()
    };
    // A triangle 2000 µm across on a volume of 3 × 1 µm… given in mm: 1000 times apart.
    let x = vec![vec![
        Vector3::new(1000.0, 1000.0, 1.0),
        Vector3::new(3000.0, 1000.0, 1.0),
        Vector3::new(1000.0, 3000.0, 1.0),
    ]];
    let error = sample_sequence(&[volume(1.0)], &mesh, &x, &SampleOptions::default()).unwrap_err();
    let VolumeError::Misplaced(report) = &error else {
        panic!("{error}")
    };
    let PlacementReport {
        frame,
        misplacement,
        vertices,
        ..
    } = **report;
    assert_eq!(frame, 0);
    assert_eq!(vertices, 3);
    assert_eq!(misplacement, Misplacement::MostlyOutside { outside: 3 });
    let message = error.to_string();
    for named in [
        "frame 0: 3 of 3 vertices (100 %)",
        "x 0…3, y 0…3, z 0…3",
        "voxel size 1 × 1 × 1",
        "origin 0, 0, 0",
        "the surface x 1000…3000",
        "about 1000 times larger",
        "different units",
        "--allow-outside",
    ] {
        assert!(message.contains(named), "{message:?} lacks {named:?}");
    }
    // The same sizes, but beside the volume: the origin is the suspect, not the units.
    let beside: Vec<Vector3<f64>> = x[0]
        .iter()
        .map(|p| p / 1000.0 + Vector3::x() * 10.0)
        .collect();
    let message = sample_sequence(&[volume(1.0)], &mesh, &[beside], &SampleOptions::default())
        .unwrap_err()
        .to_string();
    assert!(message.contains("check --voxel-size"), "{message}");
    assert!(!message.contains("different units"), "{message}");
    // Allowed: sampled, every vertex without data.
    let allowed = SampleOptions {
        allow_outside: true,
        ..SampleOptions::default()
    };
    let sampled = sample_sequence(&[volume(1.0)], &mesh, &x, &allowed).unwrap();
    assert_eq!(sampled.no_data, vec![vec![true; 3]]);
    assert_eq!(sampled.values, vec![vec![0.0; 3]]);
    // Half outside is not more than half: sampled.
    let half = vec![vec![
        Vector3::new(1.0, 1.0, 1.0),
        Vector3::new(2.0, 1.0, 1.0),
        Vector3::new(9.0, 1.0, 1.0),
    ]];
    let two_of_three = sample_sequence(&[volume(1.0)], &mesh, &half, &SampleOptions::default());
    assert!(two_of_three.is_ok());
    // The voxel size in nm for a surface in µm: inside the huge box, but within one voxel.
    let tiny = vec![vec![
        Vector3::new(1.0, 1.0, 1.0),
        Vector3::new(2.0, 1.0, 1.0),
        Vector3::new(1.0, 2.0, 1.0),
    ]];
    let error =
        sample_sequence(&[volume(1000.0)], &mesh, &tiny, &SampleOptions::default()).unwrap_err();
    let message = error.to_string();
    assert!(
        message.contains("the surface spans 0.001 voxels, too few to sample"),
        "{message}"
    );
    assert!(message.contains("about 1000 times smaller"), "{message}");
    assert!(sample_sequence(&[volume(1000.0)], &mesh, &tiny, &allowed).is_ok());
}

#[test]
fn sample_refuses_wrong_units_and_flags_what_it_cannot_see() {
    let dir = tempfile::tempdir().unwrap();
    let (_, seq) = surface(dir.path());
    let vols = volumes(dir.path());
    // The voxel size in mm for a surface in µm.
    let message = meshflow_error(
        &[
            "sample",
            path(&vols),
            path(&seq),
            ORIGIN,
            "--voxel-size",
            "0.001,0.001,0.001",
        ],
        "lie outside the recording",
    );
    for named in [
        "voxel size 0.001 × 0.001 × 0.001",
        "about 1000 times larger",
        "--allow-outside",
    ] {
        assert!(message.contains(named), "{message}");
    }
    assert!(!seq.join("intensity.npy").exists(), "nothing is written");
    // No voxel size and no origin: the sphere about 0 lies mostly outside the box from 0,
    // after the warning that the voxel size was taken as 1 × 1 × 1.
    let run = meshflow(&["sample", path(&vols), path(&seq)]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert_eq!(lines.len(), 2, "{stderr}");
    assert!(
        lines[0].contains("warning") && lines[0].contains("taking 1 × 1 × 1"),
        "{stderr}"
    );
    assert!(lines[1].contains("lie outside"), "{stderr}");
    assert!(lines[1].contains("x 0…23, y 0…23, z 0…23"), "{stderr}");
    assert!(lines[1].contains("the surface x -10…10"), "{stderr}");
    assert!(lines[1].contains("check --voxel-size"), "{stderr}");
    // Placed so that the sphere pokes out of the volume on +x: sampled, and the vertices
    // outside flagged in no_data.npy beside the image.
    meshflow_ok(&[
        "sample",
        path(&vols),
        path(&seq),
        "--origin=-11.5,-11.5,-11.5",
        "--shell",
        "0,0",
        "--layers",
        "1",
        "--voxel-size",
        "0.9,1,1",
    ]);
    let no_data = read_npy_image(&seq.join("no_data.npy")).unwrap();
    let positions = read_npy(&seq.join("positions.npy")).unwrap();
    let n = positions.shape[1] as usize;
    assert_eq!(no_data.shape, vec![2, n as u64]);
    let xs: Vec<f64> = positions.data.iter().step_by(3).copied().collect();
    for (k, row) in no_data.data.chunks(n).enumerate() {
        for (i, &flag) in row.iter().enumerate() {
            let x = xs[k * n + i];
            // The volume's last x voxel centre: −11.5 + 23 · 0.9 = 9.2.
            assert_eq!(flag > 0.0, x > 9.2, "frame {k} vertex {i} at x = {x}");
        }
    }
    let flagged = no_data.data.iter().filter(|&&f| f > 0.0).count();
    assert!(flagged > 0, "the sphere reaches x = 10 > 9.2");
    // The solve flags a slab's vertex where either frame has no data.
    let run = dir.path().join("run");
    meshflow_ok(&[
        "solve",
        path(&seq),
        "--out",
        path(&run),
        "--png",
        "--format",
        "npy,vtu",
    ]);
    let slab = read_npy_image(&run.join("no_data.npy")).unwrap();
    assert_eq!(slab.shape, vec![1, n as u64]);
    for i in 0..n {
        let either = no_data.data[i] > 0.0 || no_data.data[n + i] > 0.0;
        assert_eq!(slab.data[i] > 0.0, either, "vertex {i}");
    }
    let vtu = meshflow::format::vtk::read_vtu(&run.join("flow_0000.vtu")).unwrap();
    let flags = vtu.point_array("no_data").expect("no_data in the VTU");
    assert_eq!(flags.values, slab.data);
    assert!(run.join("grey_0000.png").is_file());
}

/// `track_errors.csv` and `.vtu`: one row per cell scored, the row's numbers consistent with
/// each other and with summary.json.
#[test]
fn every_scored_cell_has_its_row() {
    let dir = tempfile::tempdir().unwrap();
    let (points, seq) = surface(dir.path());
    let vols = volumes(dir.path());
    meshflow_ok(&["sample", path(&vols), path(&seq), ORIGIN]);
    let tracks = dir.path().join("tracks.npy");
    meshflow_ok(&["match", path(&points), "--out", path(&tracks)]);
    let run = dir.path().join("run");
    meshflow_ok(&[
        "solve",
        path(&seq),
        "--out",
        path(&run),
        "--ground-truth-tracks",
        path(&tracks),
        "--png",
    ]);
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("summary.json")).unwrap()).unwrap();
    let scored = summary["ground_truth_tracks"]["points"].as_u64().unwrap() as usize;
    assert!(scored > 200, "{scored} of 300 cells");
    let csv = std::fs::read_to_string(run.join("track_errors.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), 15);
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|f| f.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), scored);
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (t, f, e) = (column("true_x"), column("flow_x"), column("endpoint_error"));
    let mut mean = 0.0;
    for row in &rows {
        let difference = (0..3)
            .map(|c| (row[f + c] - row[t + c]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            (difference - row[e]).abs() < 1e-9 * (1.0 + row[e]),
            "{row:?}"
        );
        mean += row[e] / rows.len() as f64;
    }
    let reported = summary["ground_truth_tracks"]["mean_endpoint"]
        .as_f64()
        .unwrap();
    assert!(
        (mean - reported).abs() < 1e-9 * reported.max(1e-12),
        "{mean} vs {reported}"
    );
    let vtu = std::fs::read_to_string(run.join("track_errors.vtu")).unwrap();
    assert!(vtu.contains(&format!(
        "NumberOfPoints=\"{scored}\" NumberOfCells=\"{scored}\""
    )));
    assert!(run.join("track_errors_0000.png").is_file());
}

#[test]
fn messages_a_newcomer_meets() {
    let dir = tempfile::tempdir().unwrap();
    let (_, seq) = surface(dir.path());
    let vols = volumes(dir.path());
    // The arguments swapped.
    let swapped = meshflow_error(&["sample", path(&seq), path(&vols)], "swap them");
    assert!(
        swapped.contains("meshflow sample VOLUMES SEQUENCE"),
        "{swapped}"
    );
    // --out a directory: refused before any volume is read.
    let message = meshflow_error(
        &[
            "sample",
            path(&vols),
            path(&seq),
            ORIGIN,
            "--out",
            path(dir.path()),
        ],
        "a directory",
    );
    assert!(message.contains("--out names the .npy file"), "{message}");
    // An unquoted glob, expanded by the shell into many volume files.
    for name in ["a.npy", "b.npy"] {
        std::fs::copy(&vols, dir.path().join(name)).unwrap();
    }
    let a = dir.path().join("a.npy");
    let b = dir.path().join("b.npy");
    let run = meshflow(&["sample", path(&a), path(&b), path(&seq)]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("quote it"), "{stderr}");
    // Compressed frames.
    let gz = dir.path().join("gz");
    std::fs::create_dir(&gz).unwrap();
    for k in 0..2 {
        std::fs::write(gz.join(format!("frame_{k}.obj.gz")), b"\x1f\x8b").unwrap();
    }
    let message = meshflow_error(
        &["solve", path(&gz), "--out", path(&dir.path().join("o"))],
        "compressed",
    );
    assert!(
        message.contains("2 compressed mesh frames (frame_0.obj.gz"),
        "{message}"
    );
    assert!(message.contains("decompress"), "{message}");
    // --times of the wrong length names --times.
    let sphere = shipped("rotating_sphere");
    let message = meshflow_error(
        &[
            "solve",
            &sphere,
            "--out",
            path(&dir.path().join("t")),
            "--times",
            "0,1,2",
        ],
        "--times",
    );
    assert!(message.contains("frame times"), "{message}");
    // One slab: "1 slab", and no α = ∞.
    let two = dir.path().join("two");
    std::fs::create_dir(&two).unwrap();
    for k in 0..2 {
        let name = format!("frame_{k}.obj");
        std::fs::copy(Path::new(&sphere).join(&name), two.join(&name)).unwrap();
    }
    let run = meshflow_ok(&["solve", path(&two), "--out", path(&dir.path().join("one"))]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("-> 1 slab;"), "{stdout}");
    assert!(stdout.contains("α unused (one slab"), "{stdout}");
    assert!(!stdout.contains('∞'), "{stdout}");
    // analyze has no flow scale to set.
    let help = meshflow_ok(&["analyze", "--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(!help.contains("--flow-scale"), "{help}");
    assert!(help.contains("--tissue-scale"), "{help}");
}

/// `analyze --tissue-scale`'s smoothing on the unit sphere: the field `z` (degree 1, Laplacian
/// eigenvalue 2) is damped by four implicit heat steps to `t = L²/2`, `(1 + 2t/4)⁻⁴`, a
/// constant stays, and the area-weighted mean is kept.
#[test]
fn smoothing_over_a_length_damps_by_the_heat_kernel() {
    use meshflow::flow::{smoothed_over_length, MeshSequence};
    let sphere = meshflow::shapes::icosphere(4);
    let mesh = Mesh::new(sphere.positions.len(), sphere.faces.clone()).unwrap();
    let frames = vec![sphere.positions.clone(), sphere.positions.clone()];
    let z: Vec<f64> = sphere.positions.iter().map(|p| p.z).collect();
    let sequence = MeshSequence::new(mesh, frames, vec![z.clone(), z.clone()], None).unwrap();
    let length = 0.5;
    let ones = vec![1.0; z.len()];
    let smoothed = smoothed_over_length(&sequence, 0, &[&z, &ones], length).unwrap();
    let t = 0.5 * length * length;
    let expected = (1.0 + 2.0 * t / 4.0_f64).powi(-4);
    let factor: f64 = smoothed[0].iter().zip(&z).map(|(s, z)| s * z).sum::<f64>()
        / z.iter().map(|z| z * z).sum::<f64>();
    assert!(
        (factor - expected).abs() < 0.01 * expected,
        "{factor} vs {expected}"
    );
    assert!(smoothed[1].iter().all(|&c| (c - 1.0).abs() < 1e-12));
    let unchanged = smoothed_over_length(&sequence, 1, &[&z], 0.0).unwrap();
    assert_eq!(unchanged[0], z);
}

/// A voxel size from ImageJ metadata prints as the file says it (`1.6774`), not as the
/// nearest float64 of `1 / (10000 / 16774)` (`1.6773999999999998`).
#[test]
fn voxel_sizes_from_metadata_print_their_digits() {
    use meshflow::volume::{read_volumes, VolumeOptions, VoxelSizeSource};
    use tiff::encoder::{colortype::Gray8, Rational, TiffEncoder};
    use tiff::tags::Tag;
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("stack.tif");
    let mut encoder = TiffEncoder::new(std::fs::File::create(&file).unwrap()).unwrap();
    let mut image = encoder.new_image::<Gray8>(3, 2).unwrap();
    let description = "ImageJ=1.54f\nimages=1\nunit=micron\nspacing=7.1847\n";
    let tags = image.encoder();
    tags.write_tag(Tag::ImageDescription, description).unwrap();
    let per_micron = Rational { n: 10000, d: 16774 };
    tags.write_tag(Tag::XResolution, per_micron).unwrap();
    tags.write_tag(Tag::YResolution, Rational { n: 10000, d: 16774 })
        .unwrap();
    image.write_data(&[1u8; 6]).unwrap();
    let read = read_volumes(&file, &VolumeOptions::default()).unwrap();
    assert!((read.volumes[0].voxel_size().x - 1.6774).abs() < 1e-12);
    let VoxelSizeSource::File(said) = read.voxel_size_source else {
        panic!("{:?}", read.voxel_size_source)
    };
    assert!(said.ends_with(": 1.6774 × 1.6774 × 7.1847"), "{said}");
}

/// Every section of the user guide is in its table of contents.
#[test]
fn the_guide_lists_every_section() {
    let guide =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/guide.md")).unwrap();
    let contents: String = guide
        .lines()
        .skip_while(|l| !l.starts_with("- ["))
        .take_while(|l| l.starts_with("- ["))
        .collect();
    let mut in_code = false;
    for line in guide.lines() {
        in_code ^= line.starts_with("```");
        let Some(title) = line.strip_prefix("## ").filter(|_| !in_code) else {
            continue;
        };
        assert!(
            contents.contains(&format!("[{title}](#")),
            "{title} is not in the contents"
        );
    }
    // The MPI section names the flags Open MPI needs as root and with more ranks than cores.
    let cluster = guide.split("### Running on a cluster").nth(1).unwrap();
    for flag in ["--allow-run-as-root", "--oversubscribe"] {
        assert!(cluster.contains(flag), "the cluster section lacks {flag}");
    }
}

/// A NaN in a CSV of cell centres names the file and its line.
#[test]
fn nan_in_a_csv_names_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let cells = dir.path().join("cells");
    std::fs::create_dir(&cells).unwrap();
    for k in 0..2 {
        let rows: String = common::cells(k, 50)
            .iter()
            .enumerate()
            .map(|(i, p)| match (k, i) {
                (1, 7) => "1.0,NaN,2.0\n".to_string(),
                _ => format!("{},{},{}\n", p.x, p.y, p.z),
            })
            .collect();
        std::fs::write(
            cells.join(format!("frame_{k}.csv")),
            format!("x,y,z\n{rows}"),
        )
        .unwrap();
    }
    let out = dir.path().join("surf");
    let message = meshflow_error(
        &["surface", path(&cells), "--out", path(&out)],
        "frame_1.csv",
    );
    assert!(message.contains("line 9"), "{message}");
    assert!(
        message.contains("'NaN' is not a finite number"),
        "{message}"
    );
}
