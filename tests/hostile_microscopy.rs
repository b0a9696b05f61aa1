//! Hostile and mistaken input to the microscopy readers and commands (`sample`, `surface`,
//! `match`): each ends in one clear error naming the file and position, never a panic, an
//! output over an input, or memory beyond the limit.

mod common;
mod hostile_support;

use common::{cells, meshflow, meshflow_ok, surface, write_npy, write_points};
use hostile_support::{small_tiff, tiff_bytes, Page};
use meshflow::accuracy::match_tracks;
use meshflow::surface::{fit_surface, read_points, FitOptions, Resolution};
use meshflow::volume::{
    read_volumes, sample_shell, Reduce, Shell, Volume, VolumeOptions, VoxelSizeSource,
};
use nalgebra::Vector3;
use std::path::Path;

/// The memory limit of this test binary: every test sets the same, so that they may run in
/// parallel.
const LIMIT: u64 = 512 << 20;

fn limited() {
    meshflow::limits::set_memory_limit(LIMIT);
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The message of a library error, checked to be one line naming every one of `names`.
fn naming(error: impl std::fmt::Display, names: &[&str]) -> String {
    let message = error.to_string();
    assert!(!message.contains('\n'), "{message:?} is not one line");
    for name in names {
        assert!(message.contains(name), "{message:?} does not name {name:?}");
    }
    message
}

/// A failing command: non-zero exit and one `meshflow: error` line naming `names`.
fn fails(args: &[&str], names: &[&str]) -> String {
    let run = meshflow(args);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(!run.status.success(), "{args:?} succeeded: {stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
    assert_eq!(errors.len(), 1, "{args:?}: {stderr}");
    naming(errors[0], names)
}

/// A (2, 24, 24, 24) volume around the origin of the surface's sphere, voxel 1.
fn volumes(dir: &Path) -> std::path::PathBuf {
    let file = dir.join("volumes.npy");
    write_npy(&file, &[2, 24, 24, 24], &vec![1.0f32; 2 * 24 * 24 * 24]);
    file
}

const ORIGIN: &str = "--origin=-11.5,-11.5,-11.5";

#[test]
fn outputs_over_inputs_are_refused_and_intensity_may_be_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let (points, seq) = surface(dir.path());
    let vols = volumes(dir.path());
    let volume_bytes = std::fs::read(&vols).unwrap();
    let positions = seq.join("positions.npy");
    let position_bytes = std::fs::read(&positions).unwrap();
    let sample = |out: &Path| -> Vec<String> {
        let args = [
            "sample",
            path(&vols),
            path(&seq),
            ORIGIN,
            "--out",
            path(out),
        ];
        args.iter().map(|s| s.to_string()).collect()
    };
    let run = |args: Vec<String>, names: &[&str]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails(&args, names)
    };
    run(sample(&vols), &["volumes.npy", "is the input"]);
    run(sample(&positions), &["positions.npy"]);
    assert_eq!(std::fs::read(&vols).unwrap(), volume_bytes);
    assert_eq!(std::fs::read(&positions).unwrap(), position_bytes);
    // The default output, twice: an earlier intensity.npy is replaced.
    for _ in 0..2 {
        meshflow_ok(&["sample", path(&vols), path(&seq), ORIGIN]);
    }
    assert!(seq.join("intensity.npy").is_file());
    // ...but not through a link to another file of the sequence.
    #[cfg(unix)]
    {
        std::fs::remove_file(seq.join("intensity.npy")).unwrap();
        std::os::unix::fs::symlink(&positions, seq.join("intensity.npy")).unwrap();
        fails(
            &["sample", path(&vols), path(&seq), ORIGIN],
            &["intensity.npy", "positions.npy"],
        );
        assert_eq!(std::fs::read(&positions).unwrap(), position_bytes);
    }
    let tracks = dir.path().join("tracks.npy");
    meshflow_ok(&["match", path(&points), "--out", path(&tracks)]);
    let track_bytes = std::fs::read(&tracks).unwrap();
    fails(
        &["match", path(&tracks), "--out", path(&tracks)],
        &["tracks.npy", "is the input"],
    );
    assert_eq!(std::fs::read(&tracks).unwrap(), track_bytes);
    fails(&["surface", path(&seq), "--out", path(&seq)], &["seq"]);
}

#[test]
fn zero_length_shapes_are_errors_naming_the_file() {
    limited();
    let dir = tempfile::tempdir().unwrap();
    for (name, shape) in [
        ("z0.npy", vec![0u64, 4, 4]),
        ("k0.npy", vec![0, 2, 2, 2]),
        ("x0.npy", vec![2, 2, 2, 0]),
    ] {
        let file = dir.path().join(name);
        write_npy::<f32>(&file, &shape, &[]);
        let error = read_volumes(&file, &VolumeOptions::default()).unwrap_err();
        naming(error, &[name, "no voxels"]);
    }
    for (name, shape) in [
        ("n0.npy", vec![0u64, 3]),
        ("k0.npy", vec![0, 5, 3]),
        ("frames0.npy", vec![2, 0, 3]),
        ("three0.npy", vec![3, 0]),
    ] {
        let file = dir.path().join(name);
        write_npy::<f64>(&file, &shape, &[]);
        naming(read_points(&file).unwrap_err(), &[name]);
    }
}

#[test]
fn tiffs_declaring_more_than_the_limit_are_refused_before_decoding() {
    limited();
    let dir = tempfile::tempdir().unwrap();
    // 64 pages of 8192² sharing one small deflate strip: 4.3 GB declared by a few kB.
    let page = Page {
        compression: 8,
        strip_bytes: 64,
        ..Page::bytes(8192, 8192)
    };
    let bomb = dir.path().join("bomb.tif");
    std::fs::write(&bomb, tiff_bytes(&vec![page; 64], &[0x78; 64])).unwrap();
    let error = read_volumes(&bomb, &VolumeOptions::default()).unwrap_err();
    naming(
        error,
        &[
            "bomb.tif",
            "1 volume frame of 64 × 8192 × 8192 voxels",
            "--memory-limit",
        ],
    );
    let error = meshflow::volume::count_volume_frames(&bomb).unwrap_err();
    naming(error, &["bomb.tif", "--memory-limit"]);
}

#[test]
fn tiff_errors_name_the_file_and_page_and_unsupported_samples_plainly() {
    limited();
    let dir = tempfile::tempdir().unwrap();
    let mut pages = vec![Page::bytes(4, 4); 3];
    pages[2].strip_offset = 1 << 30; // beyond the file
    let truncated = dir.path().join("truncated.tif");
    std::fs::write(&truncated, tiff_bytes(&pages, &[7; 16])).unwrap();
    let error = read_volumes(&truncated, &VolumeOptions::default()).unwrap_err();
    naming(error, &["truncated.tif", "page 2"]);

    let one_bit = Page {
        bits: 1,
        strip_bytes: 2,
        ..Page::bytes(16, 1)
    };
    let bits = dir.path().join("bits.tif");
    std::fs::write(&bits, tiff_bytes(&[one_bit], &[0xff, 0])).unwrap();
    let error = read_volumes(&bits, &VolumeOptions::default()).unwrap_err();
    naming(
        error,
        &["bits.tif", "page 0", "1-bit samples are not supported"],
    );

    let mut sizes = vec![Page::bytes(4, 4); 2];
    sizes[1].width = 5;
    let mixed = dir.path().join("mixed.tif");
    std::fs::write(&mixed, tiff_bytes(&sizes, &[1; 20])).unwrap();
    naming(
        read_volumes(&mixed, &VolumeOptions::default()).unwrap_err(),
        &["mixed.tif", "page 1", "5 × 4"],
    );

    let good = dir.path().join("good.tif");
    std::fs::write(&good, small_tiff(3, 5, 4)).unwrap();
    let read = read_volumes(&good, &VolumeOptions::default()).unwrap();
    assert_eq!(read.volumes[0].shape(), [3, 4, 5]);
    assert_eq!(read.volumes[0].values()[7], 7.0);
}

#[test]
fn the_frame_count_is_checked_before_any_volume_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let (_, seq) = surface(dir.path());
    // Three frames declared, the data cut short: the frame count is the error.
    let lying = dir.path().join("three.npy");
    let bytes = hostile_support::npy_bytes(&[3, 4, 4, 4], &[1.0; 10]);
    std::fs::write(&lying, bytes).unwrap();
    fails(
        &["sample", path(&lying), path(&seq), "--voxel-size", "1,1,1"],
        &["three.npy", "3 volume frames for 2 surface frames"],
    );
}

/// The Gaussian along one mirrored axis, summed tap by tap: the definition.
fn mirrored_gaussian(line: &[f64], s: f64) -> Vec<f64> {
    let n = line.len() as i64;
    let period = 2 * (n - 1);
    let radius = (3.0 * s).ceil() as i64;
    let weight = |m: i64| (-(m * m) as f64 / (2.0 * s * s)).exp();
    let total: f64 = (-radius..=radius).map(weight).sum();
    (0..n)
        .map(|i| {
            (-radius..=radius)
                .map(|m| {
                    let r = (i + m).rem_euclid(period);
                    let at = if r < n { r } else { period - r };
                    weight(m) * line[at as usize] / total
                })
                .sum()
        })
        .collect()
}

#[test]
fn wide_gaussians_fold_onto_the_volume_and_the_widest_average_it() {
    limited();
    let values: Vec<f32> = (0..3 * 4 * 5).map(|v| ((v * 7) % 11) as f32).collect();
    let volume = Volume::new(
        [3, 4, 5],
        values.clone(),
        Vector3::repeat(1.0),
        Vector3::zeros(),
    )
    .unwrap();
    // σ = 1.5 voxels: 11 taps, longer than the x period (8), the y period (6) and z's (4).
    let smoothed = volume.smoothed(1.5).unwrap();
    let mut expected: Vec<f64> = values.iter().map(|&v| v as f64).collect();
    for (length, stride) in [(5usize, 1usize), (4, 5), (3, 20)] {
        for start in (0..60).filter(|s| (s / stride) % length == 0) {
            let line: Vec<f64> = (0..length).map(|n| expected[start + n * stride]).collect();
            for (n, v) in mirrored_gaussian(&line, 1.5).into_iter().enumerate() {
                expected[start + n * stride] = v;
            }
        }
    }
    for (got, want) in smoothed.values().iter().zip(&expected) {
        assert!((*got as f64 - want).abs() < 1e-4, "{got} vs {want}");
    }
    // Wider than every axis: the mean, at once (σ = 1e9 used to allocate 6e9 taps).
    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / 60.0;
    for sigma in [1e4, 1e9] {
        let started = std::time::Instant::now();
        let flat = volume.smoothed(sigma).unwrap();
        assert!(started.elapsed().as_secs_f64() < 5.0);
        assert!(flat
            .values()
            .iter()
            .all(|&v| (v as f64 - mean).abs() < 1e-4));
    }
}

#[test]
fn shell_layers_are_checked_against_the_memory_limit() {
    limited();
    let volume = Volume::new(
        [2, 2, 2],
        vec![1.0; 8],
        Vector3::repeat(1.0),
        Vector3::zeros(),
    )
    .unwrap();
    let shell = Shell {
        inside: 1.0,
        outside: 1.0,
        layers: 1_000_000_000,
    };
    let x = vec![Vector3::repeat(0.5); 3];
    let n = vec![Vector3::z(); 3];
    let error = sample_shell(&volume, &x, &n, &shell, Reduce::Max).unwrap_err();
    naming(
        error,
        &["--layers 1000000000", "3 vertices", "--memory-limit"],
    );
    let ok = Shell { layers: 3, ..shell };
    let mean = sample_shell(
        &volume,
        &x,
        &n,
        &Shell {
            inside: 0.4,
            outside: 0.4,
            ..ok
        },
        Reduce::Mean,
    );
    assert_eq!(mean.unwrap().values, vec![1.0; 3]);
    fails(&["sample", "v.npy", "seq", "--layers", "3"], &["--shell"]);
}

fn imagej_tiff(file: &Path, spacing: &str, resolution: (u32, u32)) {
    use tiff::encoder::{colortype::Gray8, Rational, TiffEncoder};
    use tiff::tags::Tag;
    let mut encoder = TiffEncoder::new(std::fs::File::create(file).unwrap()).unwrap();
    let mut image = encoder.new_image::<Gray8>(3, 2).unwrap();
    let description = format!("ImageJ=1.54f\nimages=1\nunit=micron\nspacing={spacing}\n");
    let tags = image.encoder();
    tags.write_tag(Tag::ImageDescription, description.as_str())
        .unwrap();
    let (n, d) = resolution;
    tags.write_tag(Tag::XResolution, Rational { n, d }).unwrap();
    tags.write_tag(Tag::YResolution, Rational { n: 2, d: 1 })
        .unwrap();
    image.write_data(&[1u8; 6]).unwrap();
}

#[test]
fn invalid_voxel_size_metadata_is_named_and_yields_to_a_given_size() {
    limited();
    let dir = tempfile::tempdir().unwrap();
    let given = VolumeOptions {
        voxel_size: Some(Vector3::new(1.0, 1.0, 3.0)),
        ..VolumeOptions::default()
    };
    let cases = [
        ("0", (2, 1), "spacing=0"),
        ("-2", (2, 1), "spacing=-2"),
        ("NaN", (2, 1), "spacing=NaN"),
        ("2.0 um", (2, 1), "spacing=2.0 um"),
        ("1e-320", (2, 1), "spacing=1e-320"),
        ("2", (0, 0), "XResolution 0/0"),
    ];
    for (n, (spacing, resolution, named)) in cases.into_iter().enumerate() {
        let file = dir.path().join(format!("bad_{n}.tif"));
        imagej_tiff(&file, spacing, resolution);
        let error = read_volumes(&file, &VolumeOptions::default()).unwrap_err();
        naming(
            error,
            &[&format!("bad_{n}.tif"), named, "invalid", "--voxel-size"],
        );
        let read = read_volumes(&file, &given).unwrap();
        assert_eq!(read.volumes[0].voxel_size(), Vector3::new(1.0, 1.0, 3.0));
        match read.voxel_size_source {
            VoxelSizeSource::GivenOverInvalid(why) => assert!(why.contains(named), "{why}"),
            other => panic!("{other:?}"),
        }
    }
    let good = dir.path().join("good.tif");
    imagej_tiff(&good, "2.5", (4, 1));
    let read = read_volumes(&good, &VolumeOptions::default()).unwrap();
    assert_eq!(read.volumes[0].voxel_size(), Vector3::new(0.25, 0.5, 2.5));
    let subnormal = VolumeOptions {
        voxel_size: Some(Vector3::new(1.0, 1e-320, 1.0)),
        ..VolumeOptions::default()
    };
    naming(
        read_volumes(&good, &subnormal).unwrap_err(),
        &["good.tif", "voxel size"],
    );
}

#[test]
fn float64_voxels_beyond_single_precision_are_named_by_position() {
    limited();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("huge.npy");
    let mut values = vec![0.0f64; 2 * 3 * 4 * 5];
    values[60 + 2 * 20 + 5 + 3] = 1e300; // frame 1, z 2, y 1, x 3
    write_npy(&file, &[2, 3, 4, 5], &values);
    let error = read_volumes(&file, &VolumeOptions::default()).unwrap_err();
    naming(
        error,
        &[
            "huge.npy",
            "frame 1, voxel (z 2, y 1, x 3)",
            "1e300",
            "single precision",
        ],
    );
    values[63] = f64::INFINITY;
    write_npy(&file, &[2, 3, 4, 5], &values);
    let error = read_volumes(&file, &VolumeOptions::default()).unwrap_err();
    naming(error, &["huge.npy", "inf"]);
}

#[test]
fn csv_points_bad_lines_and_non_finite_values_name_the_line() {
    limited();
    let dir = tempfile::tempdir().unwrap();
    let csv = |name: &str, text: &str| {
        let file = dir.path().join(name);
        std::fs::write(&file, text).unwrap();
        read_points(&file)
    };
    let error = csv("first.csv", "1.0,2.0,abc\n1,2,3\n").unwrap_err();
    naming(error, &["first.csv", "line 1", "'abc' is not a number"]);
    let error = csv("nan.csv", "x,y,z\n1,2,3\n# note\nnan,0,0\n").unwrap_err();
    naming(
        error,
        &["nan.csv", "line 4", "'nan' is not a finite number"],
    );
    let error = csv("short.csv", "x,y,z\n1,2\n").unwrap_err();
    naming(error, &["short.csv", "line 2", "2 fields"]);
    let read = csv("good.csv", "# cells\nx, y, z\n1,2,3\n4 5 6\n").unwrap();
    assert_eq!(
        read,
        vec![vec![
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(4.0, 5.0, 6.0)
        ]]
    );
    let npy = dir.path().join("row.npy");
    write_npy(&npy, &[2, 3], &[0.0, 0.0, 0.0, 1.0, f64::NAN, 2.0]);
    naming(read_points(&npy).unwrap_err(), &["row.npy", "row 1"]);
}

#[test]
fn badly_scaled_points_name_the_frame() {
    limited();
    let options = FitOptions {
        resolution: Resolution::Vertices(200),
        ..FitOptions::default()
    };
    let frames: Vec<Vec<Vector3<f64>>> = (0..2)
        .map(|k| cells(k, 100).iter().map(|p| p * 1e100).collect())
        .collect();
    let error = fit_surface(&frames, &options).unwrap_err();
    naming(error, &["frame 0", "too large", "rescale"]);
    let tiny: Vec<Vec<Vector3<f64>>> = (0..2)
        .map(|k| cells(k, 100).iter().map(|p| p * 1e-60).collect())
        .collect();
    naming(
        fit_surface(&tiny, &options).unwrap_err(),
        &["frame 0", "too small"],
    );
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("cells.npy");
    write_points(&points, &[cells(0, 300), cells(1, 300)]);
    let out = dir.path().join("out");
    let over = [
        "surface",
        path(&points),
        "--out",
        path(&out),
        "--memory-limit",
        "40K",
    ];
    fails(&over, &["fitting", "300 points", "--memory-limit"]);
}

#[test]
fn surface_times_are_finite_increasing_and_one_per_frame() {
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("cells.npy");
    write_points(&points, &[cells(0, 100), cells(1, 100)]);
    let out = dir.path().join("out");
    let surface = |times: &str, names: &[&str]| {
        let args = [
            "surface",
            path(&points),
            "--out",
            path(&out),
            "--times",
            times,
        ];
        fails(&args, names);
        assert!(!out.exists());
    };
    surface("0,nan", &["--times", "time 1 is NaN"]);
    surface("0,inf", &["--times", "inf"]);
    surface("1,0", &["--times", "time 1 (0)", "increase"]);
    surface("0,0", &["--times", "increase"]);
    surface("0,1,2", &["--times", "3 times", "2 frames"]);
}

#[test]
fn a_new_surface_replaces_the_image_sampled_on_the_old_one() {
    let dir = tempfile::tempdir().unwrap();
    let (points, seq) = surface(dir.path());
    let vols = volumes(dir.path());
    meshflow_ok(&["sample", path(&vols), path(&seq), ORIGIN]);
    let manifest = std::fs::read_to_string(seq.join("meshflow_run.json")).unwrap();
    assert!(manifest.contains("intensity.npy"), "{manifest}");
    for force in [false, true] {
        if force {
            meshflow_ok(&["sample", path(&vols), path(&seq), ORIGIN]);
        }
        let mut args = vec![
            "surface",
            path(&points),
            "--out",
            path(&seq),
            "--vertices",
            "400",
        ];
        if force {
            args.push("--force");
        }
        meshflow_ok(&args);
        assert!(!seq.join("intensity.npy").exists(), "force {force}");
        assert!(seq.join("positions.npy").is_file());
    }
}

#[test]
fn match_checks_its_distance_and_its_output_size() {
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("cells.npy");
    write_points(&points, &[cells(0, 50), cells(1, 50)]);
    let out = dir.path().join("tracks.npy");
    for bad in ["nan", "-1", "0", "inf"] {
        let args = [
            "match",
            path(&points),
            "--out",
            path(&out),
            "--max-distance",
            bad,
        ];
        fails(&args, &["--max-distance", "positive"]);
    }
    let small = [
        "match",
        path(&points),
        "--out",
        path(&out),
        "--memory-limit",
        "4K",
    ];
    fails(
        &small,
        &["cells.npy", "2 frames × 50 tracks", "--memory-limit"],
    );
    assert!(!out.exists());
}

/// Mutual nearest neighbours by brute force: the definition the k-d tree must reproduce.
fn brute_match(a: &[Vector3<f64>], b: &[Vector3<f64>], bound: f64) -> Vec<(usize, usize)> {
    let nearest = |x: &Vector3<f64>, set: &[Vector3<f64>]| {
        (0..set.len())
            .map(|i| ((set[i] - x).norm(), i))
            .filter(|(d, _)| *d <= bound)
            .min_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)))
            .map(|(_, i)| i)
    };
    (0..a.len())
        .filter_map(|i| {
            let j = nearest(&a[i], b)?;
            (nearest(&b[j], a) == Some(i)).then_some((i, j))
        })
        .collect()
}

#[test]
fn matching_agrees_with_brute_force_at_any_distance() {
    let mut seed = 12345u64;
    let mut random = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    // Rounded coordinates: many ties and equal coordinates along the split axes.
    let mut cloud = |n: usize| -> Vec<Vector3<f64>> {
        (0..n)
            .map(|_| Vector3::new(random(), random(), random()).map(|c| (c * 8.0).round()))
            .collect()
    };
    for bound in [0.5, 1.0, 3.0, 1e9] {
        let (a, b) = (cloud(300), cloud(280));
        let tracks = match_tracks(&[a.clone(), b.clone()], Some(bound)).unwrap();
        let six = |p: Vector3<f64>, q: Vector3<f64>| [p.x, p.y, p.z, q.x, q.y, q.z];
        let mut want: Vec<[f64; 6]> = (brute_match(&a, &b, bound).into_iter())
            .map(|(i, j)| six(a[i], b[j]))
            .collect();
        let mut got: Vec<[f64; 6]> = (0..tracks.n_tracks())
            .filter_map(|t| Some(six(tracks.position(0, t)?, tracks.position(1, t)?)))
            .collect();
        want.sort_by(|p, q| p.partial_cmp(q).unwrap());
        got.sort_by(|p, q| p.partial_cmp(q).unwrap());
        assert_eq!(got, want, "bound {bound}");
    }
}

/// A recording larger than the memory limit streams through `sample` where one frame fits
/// (counting its frames holds nothing; reading them all at once would take 5 × 3.5 MB).
#[test]
fn sample_streams_a_recording_larger_than_the_memory_limit() {
    let dir = tempfile::tempdir().unwrap();
    let (_, seq) = surface(dir.path());
    // Two frames of 96³ float32 (3.5 MB each) about the sphere, voxel 0.25.
    let n = 96u64;
    let file = dir.path().join("recording.npy");
    write_npy(&file, &[2, n, n, n], &vec![5.0f32; 2 * 96 * 96 * 96]);
    let out = dir.path().join("intensity.npy");
    let args = [
        "sample",
        path(&file),
        path(&seq),
        "--voxel-size",
        "0.25,0.25,0.25",
        "--origin=-11.875,-11.875,-11.875",
        "--out",
        path(&out),
        "--memory-limit",
        "16M",
    ];
    meshflow_ok(&args);
    let sampled = meshflow::format::read_npy(&out).unwrap();
    assert!(sampled.data.iter().all(|&v| (v - 5.0).abs() < 1e-6));
    // A frame that does not fit is refused before anything is read.
    let mut small = args;
    small[small.len() - 1] = "8M";
    fails(
        &small,
        &[
            "recording.npy",
            "1 volume frame of 96 × 96 × 96 voxels",
            "--memory-limit",
        ],
    );
}

/// `sample` writes the image and its no-data mask together: where the mask cannot be written
/// (a directory stands at its path), the image already there is left as it was, not replaced
/// beside an old mask.
#[test]
fn the_image_and_its_mask_are_replaced_together_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let (_, seq) = surface(dir.path());
    // A speckled recording, so that smoothing changes what is sampled.
    let vols = dir.path().join("speckled.npy");
    let speckle: Vec<f32> = (0..2 * 24 * 24 * 24)
        .map(|i| ((i * 7919) % 101) as f32)
        .collect();
    write_npy(&vols, &[2, 24, 24, 24], &speckle);
    let out = dir.path().join("image.npy");
    let sample = |smooth: &str| {
        let args = [
            "sample",
            path(&vols),
            path(&seq),
            ORIGIN,
            "--smooth",
            smooth,
            "--out",
            path(&out),
        ];
        args.map(String::from)
    };
    let run = |args: [String; 8]| meshflow(&args.each_ref().map(String::as_str));
    assert!(run(sample("0")).status.success());
    let before = std::fs::read(&out).unwrap();
    let unchanged = |smooth: &str| {
        let other = dir.path().join(format!("other_{smooth}.npy"));
        let mut args = sample(smooth);
        args[7] = path(&other).to_string();
        assert!(run(args).status.success());
        std::fs::read(other).unwrap() == before
    };
    assert!(!unchanged("1"), "smoothing changes the image");
    let mask = dir.path().join("image_no_data.npy");
    std::fs::remove_file(&mask).unwrap();
    std::fs::create_dir(&mask).unwrap();
    std::fs::write(mask.join("keep"), b"x").unwrap();
    let again = sample("1");
    fails(
        &again.each_ref().map(String::as_str),
        &["image_no_data.npy", "Is a directory"],
    );
    assert_eq!(
        std::fs::read(&out).unwrap(),
        before,
        "the image was replaced alone"
    );
    let partial = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".partial")
        })
        .count();
    assert_eq!(partial, 0, "temporary files are removed");
}
