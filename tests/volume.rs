//! Volumes (`meshflow::volume`): trilinear interpolation is exact on linear functions, the
//! Gaussian keeps constants and mass and has variance σ², NPY and TIFF stacks (u8, u16, f32,
//! anisotropic ImageJ spacing) read back voxel for voxel, sampling along normals reads a
//! distance field at the right offsets, and bad input is an error naming the file.

mod common;

use common::write_npy;
use meshflow::connection::vertex_normals;
use meshflow::synth::rotating_sphere;
use meshflow::volume::{
    read_volumes, sample_sequence, sample_shell, Reduce, SampleOptions, Shell, Volume,
    VolumeOptions, VoxelSizeSource,
};
use nalgebra::Vector3;
use std::path::Path;

const VOXEL: [f64; 3] = [0.5, 0.75, 2.0];
const ORIGIN: [f64; 3] = [-3.0, 1.0, 2.5];

/// A volume of `shape` (z, y, x) whose voxel at `x(k, j, i)` holds `f(x)`.
fn volume_of(shape: [usize; 3], f: impl Fn(Vector3<f64>) -> f64) -> Volume {
    let (voxel, origin) = (Vector3::from(VOXEL), Vector3::from(ORIGIN));
    let mut values = Vec::with_capacity(shape.iter().product());
    for k in 0..shape[0] {
        for j in 0..shape[1] {
            for i in 0..shape[2] {
                let x = origin + Vector3::new(i as f64, j as f64, k as f64).component_mul(&voxel);
                values.push(f(x) as f32);
            }
        }
    }
    Volume::new(shape, values, voxel, origin).unwrap()
}

fn linear(x: Vector3<f64>) -> f64 {
    0.3 * x.x - 0.2 * x.y + 0.1 * x.z + 1.0
}

#[test]
fn trilinear_interpolation_is_exact_for_linear_functions_and_none_outside() {
    let volume = volume_of([6, 7, 8], linear);
    let origin = Vector3::from(ORIGIN);
    let extent = Vector3::new(7.0 * VOXEL[0], 6.0 * VOXEL[1], 5.0 * VOXEL[2]);
    for n in 0..200 {
        let t = Vector3::new(
            (n as f64 * 0.618_034).fract(),
            (n as f64 * 0.414_214).fract(),
            (n as f64 * 0.732_051).fract(),
        );
        let p = origin + t.component_mul(&extent);
        let value = volume.sample(&p).expect("inside");
        assert!((value - linear(p)).abs() < 1e-5, "at {p:?}: {value}");
    }
    // The box of voxel centres is closed: its far corner is inside, a hair beyond is not.
    assert!(volume.sample(&(origin + extent)).is_some());
    assert!(volume.sample(&(origin + extent * (1.0 + 1e-9))).is_none());
    assert!(volume
        .sample(&(origin - Vector3::new(0.0, 0.0, 1e-9)))
        .is_none());
}

#[test]
fn the_gaussian_keeps_constants_and_mass_and_has_variance_sigma_squared() {
    let constant = volume_of([5, 6, 7], |_| 2.5).smoothed(1.3).unwrap();
    assert!(constant.values().iter().all(|&v| (v - 2.5).abs() < 1e-5));

    // A unit impulse at the centre of a volume larger than 3σ on every side.
    let shape = [21, 41, 61];
    let centre = [10usize, 20, 30];
    let mut values = vec![0f32; shape.iter().product()];
    values[(centre[0] * shape[1] + centre[1]) * shape[2] + centre[2]] = 1.0;
    let voxel = Vector3::from(VOXEL);
    let impulse = Volume::new(shape, values, voxel, Vector3::zeros()).unwrap();
    let sigma = 3.0;
    let smoothed = impulse.smoothed(sigma).unwrap();
    let (mut mass, mut second) = (0.0, Vector3::<f64>::zeros());
    for k in 0..shape[0] {
        for j in 0..shape[1] {
            for i in 0..shape[2] {
                let v = smoothed.values()[(k * shape[1] + j) * shape[2] + i] as f64;
                let d = Vector3::new(
                    i as f64 - centre[2] as f64,
                    j as f64 - centre[1] as f64,
                    k as f64 - centre[0] as f64,
                )
                .component_mul(&voxel);
                mass += v;
                second += d.component_mul(&d) * v;
            }
        }
    }
    assert!((mass - 1.0).abs() < 1e-5, "mass {mass}");
    // Truncation at 3σ and sampling (σ/d = 1.5 voxels in z) change the variance by under 3 %.
    for axis in 0..3 {
        let variance = second[axis] / mass;
        assert!(
            (variance / (sigma * sigma) - 1.0).abs() < 0.03,
            "axis {axis}: variance {variance}, σ² {}",
            sigma * sigma
        );
    }
    assert!(impulse.smoothed(-1.0).is_err());
    assert_eq!(impulse.smoothed(0.0).unwrap(), impulse);
}

/// `(z, y, x)` test pattern with distinct integer values in every voxel (u8 holds them).
fn pattern(shape: [usize; 3], k: usize, j: usize, i: usize) -> f64 {
    ((k * shape[1] + j) * shape[2] + i) as f64 + 3.0
}

fn pattern_values(frames: usize, shape: [usize; 3]) -> Vec<f64> {
    let per_frame: usize = shape.iter().product();
    (0..frames * per_frame)
        .map(|n| {
            let (k, rest) = (
                (n % per_frame) / (shape[1] * shape[2]),
                n % (shape[1] * shape[2]),
            );
            pattern(shape, k, rest / shape[2], rest % shape[2]) + (n / per_frame) as f64
        })
        .collect()
}

fn assert_pattern(volume: &Volume, shape: [usize; 3], frame: usize) {
    assert_eq!(volume.shape(), shape);
    for k in 0..shape[0] {
        for j in 0..shape[1] {
            for i in 0..shape[2] {
                let got = volume.values()[(k * shape[1] + j) * shape[2] + i] as f64;
                assert_eq!(
                    got,
                    pattern(shape, k, j, i) + frame as f64,
                    "voxel {k} {j} {i}"
                );
            }
        }
    }
}

#[test]
fn npy_volumes_read_as_one_or_many_frames() {
    let dir = tempfile::tempdir().unwrap();
    let shape = [3, 4, 5];
    let four = dir.path().join("four.npy");
    write_npy(&four, &[2, 3, 4, 5], &pattern_values(2, shape));
    let options = VolumeOptions {
        voxel_size: Some(Vector3::from(VOXEL)),
        origin: Vector3::from(ORIGIN),
        ..VolumeOptions::default()
    };
    let frames = read_volumes(&four, &options).unwrap();
    assert_eq!(frames.volumes.len(), 2);
    assert_eq!(frames.voxel_size_source, VoxelSizeSource::Given);
    for (k, volume) in frames.volumes.iter().enumerate() {
        assert_pattern(volume, shape, k);
        assert_eq!(volume.voxel_size(), Vector3::from(VOXEL));
        assert_eq!(volume.origin(), Vector3::from(ORIGIN));
    }
    // A directory of one-frame files, in natural order (frame_10 after frame_2).
    let frames_dir = dir.path().join("frames");
    std::fs::create_dir(&frames_dir).unwrap();
    let per_frame = pattern_values(11, shape);
    for k in [0, 1, 2, 10] {
        let values = &per_frame[k * 60..][..60];
        write_npy(
            &frames_dir.join(format!("frame_{k}.npy")),
            &[3, 4, 5],
            values,
        );
    }
    let read = read_volumes(&frames_dir, &VolumeOptions::default()).unwrap();
    assert_eq!(read.voxel_size_source, VoxelSizeSource::Default);
    for (volume, k) in read.volumes.iter().zip([0, 1, 2, 10]) {
        assert_pattern(volume, shape, k);
    }
}

/// A multi-page grey TIFF written with the `tiff` crate, with ImageJ's voxel size metadata.
fn write_tiff<C: tiff::encoder::colortype::ColorType>(
    path: &Path,
    shape: [usize; 3],
    pixel: impl Fn(f64) -> C::Inner,
    voxel: Option<[f64; 3]>,
) where
    [C::Inner]: tiff::encoder::TiffValue,
{
    use tiff::encoder::{Rational, TiffEncoder};
    use tiff::tags::Tag;
    let mut encoder = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    for k in 0..shape[0] {
        let page: Vec<C::Inner> = (0..shape[1] * shape[2])
            .map(|n| pixel(pattern(shape, k, n / shape[2], n % shape[2])))
            .collect();
        let mut image = encoder
            .new_image::<C>(shape[2] as u32, shape[1] as u32)
            .unwrap();
        if let Some([x, y, z]) = voxel {
            let description = format!(
                "ImageJ=1.54f\nimages={}\nslices={}\nunit=micron\nspacing={z}\n",
                shape[0], shape[0]
            );
            let encoder = image.encoder();
            encoder
                .write_tag(Tag::ImageDescription, description.as_str())
                .unwrap();
            // Pixels per micron, as ImageJ writes them: 1/d as a rational.
            let per_unit = |d: f64| Rational {
                n: (1e6 / d).round() as u32,
                d: 1_000_000,
            };
            encoder.write_tag(Tag::XResolution, per_unit(x)).unwrap();
            encoder.write_tag(Tag::YResolution, per_unit(y)).unwrap();
        }
        image.write_data(&page).unwrap();
    }
}

#[test]
fn tiff_stacks_read_back_with_their_sample_type_and_imagej_voxel_size() {
    use tiff::encoder::colortype::{Gray16, Gray32Float, Gray8};
    let dir = tempfile::tempdir().unwrap();
    let shape = [4, 5, 6];
    let anisotropic = [0.5, 0.5, 2.0];
    let u8_file = dir.path().join("u8.tif");
    let u16_file = dir.path().join("u16.tiff");
    let f32_file = dir.path().join("f32.tif");
    write_tiff::<Gray8>(&u8_file, shape, |v| v as u8, Some(anisotropic));
    write_tiff::<Gray16>(&u16_file, shape, |v| v as u16, Some(anisotropic));
    write_tiff::<Gray32Float>(&f32_file, shape, |v| v as f32, None);
    for file in [&u8_file, &u16_file, &f32_file] {
        let read = read_volumes(file, &VolumeOptions::default()).unwrap();
        assert_eq!(read.volumes.len(), 1);
        assert_pattern(&read.volumes[0], shape, 0);
        let voxel = read.volumes[0].voxel_size();
        match file == &f32_file {
            true => {
                assert_eq!(read.voxel_size_source, VoxelSizeSource::Default);
                assert_eq!(voxel, Vector3::repeat(1.0));
            }
            false => {
                assert!(matches!(read.voxel_size_source, VoxelSizeSource::File(_)));
                assert!(
                    (voxel - Vector3::from(anisotropic)).norm() < 1e-9,
                    "{voxel:?}"
                );
            }
        }
    }
    // The caller's voxel size wins over the file's.
    let given = VolumeOptions {
        voxel_size: Some(Vector3::new(1.0, 2.0, 3.0)),
        ..VolumeOptions::default()
    };
    let read = read_volumes(&u16_file, &given).unwrap();
    assert_eq!(read.volumes[0].voxel_size(), Vector3::new(1.0, 2.0, 3.0));
}

/// The error's message, which must name `file`.
fn error_naming(path: &Path, options: &VolumeOptions, file: &str) -> String {
    let message = read_volumes(path, options).unwrap_err().to_string();
    assert!(message.contains(file), "{message:?} does not name {file}");
    assert!(!message.contains('\n'), "{message:?} is not one line");
    message
}

#[test]
fn bad_volumes_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat.npy");
    write_npy(&flat, &[4, 5], &[0.0; 20]);
    let message = error_naming(&flat, &VolumeOptions::default(), "flat.npy");
    assert!(message.contains("(Z, Y, X)"), "{message}");

    let nan = dir.path().join("nan.npy");
    let mut values = vec![0.0; 24];
    values[13] = f64::NAN;
    write_npy(&nan, &[2, 3, 4], &values);
    let message = error_naming(&nan, &VolumeOptions::default(), "nan.npy");
    assert!(message.contains("z 1, y 0, x 1"), "{message}");

    let mixed = dir.path().join("mixed");
    std::fs::create_dir(&mixed).unwrap();
    write_npy(&mixed.join("a_1.npy"), &[2, 3, 4], &[0.0; 24]);
    write_npy(&mixed.join("a_2.npy"), &[2, 4, 3], &[0.0; 24]);
    let message = error_naming(&mixed, &VolumeOptions::default(), "a_2.npy");
    assert!(message.contains("frame 1"), "{message}");

    let broken = dir.path().join("broken.tif");
    std::fs::write(&broken, b"II*\0 this is not a tiff").unwrap();
    error_naming(&broken, &VolumeOptions::default(), "broken.tif");

    let zero = VolumeOptions {
        voxel_size: Some(Vector3::new(1.0, 0.0, 1.0)),
        ..VolumeOptions::default()
    };
    let message = error_naming(&nan, &zero, "nan.npy");
    assert!(message.contains("voxel size"), "{message}");

    let missing = dir.path().join("missing.npy");
    error_naming(&missing, &VolumeOptions::default(), "missing.npy");
}

/// `|x − c|`: distance from the centre of the volume box below.
fn distance_field() -> (Volume, Vector3<f64>) {
    let voxel = Vector3::new(0.05, 0.05, 0.1);
    let shape = [41, 81, 81];
    let centre = Vector3::new(2.0, 2.0, 2.0);
    let mut values = Vec::new();
    for k in 0..shape[0] {
        for j in 0..shape[1] {
            for i in 0..shape[2] {
                let x = Vector3::new(i as f64, j as f64, k as f64).component_mul(&voxel);
                values.push((x - centre).norm() as f32);
            }
        }
    }
    (
        Volume::new(shape, values, voxel, Vector3::zeros()).unwrap(),
        centre,
    )
}

#[test]
fn sampling_along_outward_normals_reads_a_distance_field_at_the_shell_offsets() {
    let (volume, centre) = distance_field();
    let sphere = rotating_sphere(3, 2, 1.0, 0.0).unwrap().sequence;
    let x: Vec<Vector3<f64>> = sphere
        .positions(0)
        .unwrap()
        .iter()
        .map(|p| centre + p)
        .collect();
    let normals = vertex_normals(sphere.mesh(), &x);
    let shell = Shell {
        inside: 0.3,
        outside: 0.5,
        layers: 5,
    };
    // Icosphere vertices are on the unit sphere, normals nearly radial: the distance along
    // the normal at offset o is 1 + o up to the interpolation error of |x| (h²/R ≈ 2.5e-3).
    let expect = |reduce: Reduce, value: f64| {
        let sampled = sample_shell(&volume, &x, &normals, &shell, reduce).unwrap();
        assert_eq!(sampled.outside, 0);
        for (i, v) in sampled.values.iter().enumerate() {
            assert!(
                (v - value).abs() < 4e-3,
                "{reduce:?} at vertex {i}: {v}, not {value}"
            );
        }
    };
    expect(Reduce::Max, 1.5);
    expect(Reduce::Layer(0), 0.7);
    expect(Reduce::Layer(2), 1.1);
    expect(Reduce::Mean, 1.1);
    // Leaving the box: a shell reaching 1.2 beyond a unit sphere centred 2 from the faces
    // leaves it at the faces' nearest vertices only; z's half-height is 2, too.
    let far = Shell {
        inside: 0.0,
        outside: 1.2,
        layers: 3,
    };
    let sampled = sample_shell(&volume, &x, &normals, &far, Reduce::Max).unwrap();
    let leaving = x
        .iter()
        .zip(&normals)
        .filter(|(p, n)| {
            let q = *p + *n * 1.2;
            q.iter().any(|c| !(0.0..=4.0).contains(c))
        })
        .count();
    assert!(leaving > 0);
    assert_eq!(sampled.outside, leaving);
    let bad = Shell { layers: 0, ..shell };
    assert!(sample_shell(&volume, &x, &normals, &bad, Reduce::Max).is_err());
    assert!(sample_shell(&volume, &x, &normals, &shell, Reduce::Layer(5)).is_err());
}

#[test]
fn a_sequence_is_smoothed_by_default_by_two_of_the_smallest_voxel_sides() {
    let (volume, centre) = distance_field();
    let sphere = rotating_sphere(2, 2, 1.0, 0.0).unwrap().sequence;
    let positions: Vec<Vec<Vector3<f64>>> = (0..2)
        .map(|k| {
            let scale = 1.0 + 0.1 * k as f64;
            let x = sphere.positions(k).unwrap();
            x.iter().map(|p| centre + p * scale).collect()
        })
        .collect();
    let volumes = vec![volume.clone(), volume];
    let options = SampleOptions {
        shell: Some(Shell {
            inside: 0.0,
            outside: 0.0,
            layers: 1,
        }),
        ..SampleOptions::default()
    };
    let sampled = sample_sequence(&volumes, sphere.mesh(), &positions, &options).unwrap();
    assert_eq!(sampled.smoothing, 0.1);
    // Smoothing |x − c| by a Gaussian adds σ²/|x − c| (its Laplacian 2/r, times σ²/2).
    for (k, frame) in sampled.values.iter().enumerate() {
        let r = 1.0 + 0.1 * k as f64;
        let expected = r + 0.01 / r;
        for v in frame {
            assert!(
                (v - expected).abs() < 4e-3,
                "frame {k}: {v}, not {expected}"
            );
        }
    }
    let unsmoothed = SampleOptions {
        smoothing: Some(0.0),
        ..options
    };
    let sampled = sample_sequence(&volumes, sphere.mesh(), &positions, &unsmoothed).unwrap();
    assert_eq!(sampled.smoothing, 0.0);
    assert!(sample_sequence(&volumes[..1], sphere.mesh(), &positions, &options).is_err());
}
