//! Helpers shared by the integration tests: dense views of sparse operators and eigen solvers
//! that are independent of the code under test (nalgebra dense, faer sparse Cholesky), and
//! running the `meshflow` binary on the shipped meshes.
#![allow(dead_code)]

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::{Mat, Side};
use meshflow::fem::SparseMatrix;
use meshflow::flow::FlowResult;
use meshflow::shapes::{grid, Surface};
use nalgebra::{DMatrix, Rotation3, Vector3};
use std::path::Path;
use std::process::{Command, Output};

/// Runs the `meshflow` binary with `args`; its stderr without the plain progress lines
/// (`meshflow: [  1.2 s] …`) that it writes when stderr is a pipe, leaving warnings and errors.
pub fn meshflow(args: &[&str]) -> Output {
    let mut run = meshflow_with_progress(args);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    run.stderr = stderr
        .lines()
        .filter(|line| !is_progress_line(line))
        .flat_map(|line| [line, "\n"])
        .collect::<String>()
        .into_bytes();
    run
}

/// Whether `line` of stderr is a plain progress line.
pub fn is_progress_line(line: &str) -> bool {
    line.starts_with("meshflow: [")
}

/// Runs the `meshflow` binary with `args`, its stderr as written.
pub fn meshflow_with_progress(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_meshflow"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs the binary and asserts that it succeeded.
pub fn meshflow_ok(args: &[&str]) -> Output {
    let run = meshflow(args);
    assert!(
        run.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    run
}

/// Runs the binary and asserts that it failed with exit code 1 and one line on stderr that
/// contains `expected`; returns that line.
/// Runs `meshflow solve INPUT --out OUT EXTRA… --force`, which must succeed: its stdout and
/// OUT's summary.json.
pub fn solve_and_summary(input: &str, out: &Path, extra: &[&str]) -> (String, serde_json::Value) {
    let out_dir = out.to_str().unwrap();
    let args = [&["solve", input, "--out", out_dir, "--force"][..], extra].concat();
    let run = meshflow_ok(&args);
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let summary = serde_json::from_str(&summary).unwrap();
    (String::from_utf8_lossy(&run.stdout).into_owned(), summary)
}

pub fn meshflow_error(args: &[&str], expected: &str) -> String {
    let run = meshflow(args);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert_eq!(run.status.code(), Some(1), "{args:?}: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
    assert!(
        stderr.contains(expected),
        "{args:?}: expected {expected:?}, got {stderr}"
    );
    stderr
}

/// The names of the entries of `dir`, sorted.
pub fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The path of a file or directory under `meshes/`.
pub fn shipped(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("meshes")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

pub fn dense(a: &SparseMatrix) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(a.nrows(), a.ncols());
    for_each_entry(a, |i, j, v| out[(i, j)] += v);
    out
}

pub fn for_each_entry(a: &SparseMatrix, mut f: impl FnMut(usize, usize, f64)) {
    let (symbolic, values) = a.parts();
    let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
    for j in 0..a.ncols() {
        for k in col_ptr[j]..col_ptr[j + 1] {
            f(row_idx[k], j, values[k]);
        }
    }
}

/// `A X` for a sparse `A` and dense `X`.
pub fn mul(a: &SparseMatrix, x: &DMatrix<f64>) -> DMatrix<f64> {
    let mut y = DMatrix::zeros(a.nrows(), x.ncols());
    for_each_entry(a, |i, j, v| {
        for c in 0..x.ncols() {
            y[(i, c)] += v * x[(j, c)];
        }
    });
    y
}

/// Largest entry of |A − Aᵀ|.
pub fn asymmetry(a: &SparseMatrix) -> f64 {
    let d = dense(a);
    (&d - d.transpose()).amax()
}

/// Largest |a_k − b_k| over the stored values, relative to the largest |a_k| (same pattern).
pub fn relative_value_difference(a: &SparseMatrix, b: &SparseMatrix) -> f64 {
    let (sa, va) = a.parts();
    let (sb, vb) = b.parts();
    assert_eq!(sa.col_ptr(), sb.col_ptr());
    assert_eq!(sa.row_idx(), sb.row_idx());
    let scale = va.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    va.iter()
        .zip(vb)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// Eigenvalues (ascending) and B-orthonormal eigenvectors of the dense pencil (A, B), B SPD.
pub fn generalized_eigen(a: &DMatrix<f64>, b: &DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let l = b.clone().cholesky().expect("B is positive definite").l();
    let l_inv = l.try_inverse().unwrap();
    let c = &l_inv * a * l_inv.transpose();
    let c = (&c + c.transpose()) * 0.5;
    let eigen = c.symmetric_eigen();
    let mut order: Vec<usize> = (0..eigen.eigenvalues.len()).collect();
    order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
    let values = order.iter().map(|&i| eigen.eigenvalues[i]).collect();
    let vectors = l_inv.transpose() * eigen.eigenvectors.select_columns(&order);
    (values, vectors)
}

pub fn eigenvalues(a: &DMatrix<f64>) -> Vec<f64> {
    let mut v: Vec<f64> = a.clone().symmetric_eigenvalues().iter().copied().collect();
    v.sort_by(f64::total_cmp);
    v
}

/// The `count` smallest eigenvalues of the sparse pencil (K, M), K and M SPD, by subspace
/// iteration on `K⁻¹M` with a block of `block > count` vectors and Rayleigh–Ritz projection.
pub fn lowest_generalized_eigenvalues(
    k: &SparseMatrix,
    m: &SparseMatrix,
    count: usize,
    block: usize,
) -> Vec<f64> {
    let n = k.nrows();
    let symbolic = SymbolicLlt::try_new(k.symbolic(), Side::Lower).unwrap();
    let llt = Llt::try_new_with_symbolic(symbolic, k.as_ref(), Side::Lower)
        .expect("K is positive definite");
    let mut seed = 12345u64;
    let mut x = DMatrix::from_fn(n, block, |_, _| {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    });
    let mut previous = vec![f64::INFINITY; count];
    for _ in 0..200 {
        let mx = mul(m, &x);
        let mut rhs = Mat::from_fn(n, block, |i, j| mx[(i, j)]);
        llt.solve_in_place(rhs.as_mut());
        let y = DMatrix::from_fn(n, block, |i, j| rhs[(i, j)]);
        let ky = y.transpose() * mul(k, &y);
        let my = y.transpose() * mul(m, &y);
        let (values, z) = generalized_eigen(&ky, &my);
        x = y * z;
        let change = values
            .iter()
            .zip(&previous)
            .map(|(a, b)| ((a - b) / a).abs())
            .fold(0.0, f64::max);
        previous = values[..count].to_vec();
        if change < 1e-13 {
            break;
        }
    }
    previous
}

/// The rotation part of [`rigid_motion`].
pub fn rigid_rotation() -> Rotation3<f64> {
    Rotation3::from_euler_angles(0.3, -1.1, 2.4)
}

/// A fixed rotation and translation applied to every position.
pub fn rigid_motion(positions: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let shift = Vector3::new(1.5, -40.0, 7.25);
    positions
        .iter()
        .map(|p| rigid_rotation() * p + shift)
        .collect()
}

/// Deterministic pseudo-random numbers in [-1, 1).
pub fn noise(count: usize, mut seed: u64) -> Vec<f64> {
    (0..count)
        .map(|_| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            2.0 * ((seed >> 11) as f64 / (1u64 << 53) as f64) - 1.0
        })
        .collect()
}

/// A flat `nx × ny` grid over `width × height` whose interior vertices are moved off the lattice
/// by up to `amplitude` in x and y (the boundary stays straight).
pub fn jittered_grid(nx: usize, ny: usize, width: f64, height: f64, amplitude: f64) -> Surface {
    let mut surface = grid(nx, ny, width, height);
    let jitter = noise(2 * surface.positions.len(), 7);
    for (i, p) in surface.positions.iter_mut().enumerate() {
        let on_boundary =
            p.x == 0.0 || p.y == 0.0 || (p.x - width).abs() < 1e-12 || (p.y - height).abs() < 1e-12;
        if !on_boundary {
            p.x += amplitude * jitter[2 * i];
            p.y += amplitude * jitter[2 * i + 1];
        }
    }
    surface
}

/// The flow's intrinsic components, slab-major.
pub fn flat_u(flow: &FlowResult) -> Vec<f64> {
    flow.intrinsic
        .iter()
        .flatten()
        .flat_map(|u| [u.x, u.y])
        .collect()
}

/// The same minimizer: intrinsic flows within 1e-9 of the largest component, energies within
/// 1e-10 relative.
pub fn assert_same_intrinsic_flow(a: &FlowResult, b: &FlowResult) {
    let (ua, ub) = (flat_u(a), flat_u(b));
    let scale = ua.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let difference = ua
        .iter()
        .zip(&ub)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(
        difference < 1e-9 * scale,
        "intrinsic flows differ by {difference:e} (scale {scale:e})"
    );
    assert!((a.energy - b.energy).abs() < 1e-10 * a.energy);
}

/// Writes `values` as a `.npy` file of `shape` (C order) in their own dtype (float64 for `f64`).
pub fn write_npy<T: npyz::AutoSerialize + Copy>(path: &Path, shape: &[u64], values: &[T]) {
    use npyz::WriterBuilder;
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut writer = npyz::WriteOptions::<T>::new()
        .default_dtype()
        .shape(shape)
        .writer(&mut file)
        .begin_nd()
        .unwrap();
    writer.extend(values.iter().copied()).unwrap();
    writer.finish().unwrap();
}

/// `surface` standing still for `frames` frames (times 0, 1, …) with the grey value
/// `image(p, k)` at the vertex at `p` in frame `k`.
pub fn still_sequence(
    surface: &Surface,
    frames: usize,
    image: impl Fn(&Vector3<f64>, usize) -> f64,
) -> meshflow::flow::MeshSequence {
    let intensities = (0..frames)
        .map(|k| surface.positions.iter().map(|p| image(p, k)).collect())
        .collect();
    let positions = vec![surface.positions.clone(); frames];
    meshflow::flow::MeshSequence::new(surface.mesh().unwrap(), positions, intensities, None)
        .unwrap()
}

/// Time-window test cases: a deforming sphere (8 slabs) with lumped and consistent coupling,
/// and a 7 × 6 grid (5 slabs) with a moving pattern, Dirichlet boundary and default weights.
pub fn window_cases() -> Vec<(
    String,
    meshflow::flow::MeshSequence,
    meshflow::flow::FlowParams,
)> {
    use meshflow::flow::{Boundary, FlowParams, TimeCoupling};
    let sphere = meshflow::synth::deforming_sphere(2, 9, 1.0, 0.05, 0.3)
        .unwrap()
        .sequence;
    let mut cases: Vec<_> = [TimeCoupling::Lumped, TimeCoupling::Consistent]
        .into_iter()
        .map(|coupling| {
            let params = FlowParams {
                time_coupling: coupling,
                ..FlowParams::paper(0.5, 0.0, 0.1)
            };
            (format!("sphere, {coupling:?}"), sphere.clone(), params)
        })
        .collect();
    let grid = still_sequence(&grid(7, 6, 1.0, 1.0), 6, |p, k| {
        (5.0 * p.x - 0.2 * k as f64).sin() * (3.0 * p.y).cos()
    });
    let params = FlowParams {
        boundary: Boundary::Dirichlet,
        ..FlowParams::default()
    };
    cases.push(("grid, Dirichlet, default weights".into(), grid, params));
    cases
}

/// Points on a sphere of radius 10 about the origin (a golden spiral), turned by 0.02 rad about
/// z per frame `k`.
pub fn cells(k: usize, n: usize) -> Vec<Vector3<f64>> {
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let phi = i as f64 * 2.399_963 + 0.02 * k as f64;
            let r = (1.0 - z * z).sqrt();
            10.0 * Vector3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Point frames as one (K, N, 3) float64 `.npy`.
pub fn write_points(file: &Path, frames: &[Vec<Vector3<f64>>]) {
    let n = frames[0].len() as u64;
    let values: Vec<f64> = frames
        .iter()
        .flatten()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    write_npy(file, &[frames.len() as u64, n, 3], &values);
}

/// Two frames of 300 [`cells`] in `DIR/cells.npy` (a (2, 300, 3) tracks file) and the surface
/// through them, `DIR/seq` (`meshflow surface … --vertices 300`).
pub fn surface(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let points = dir.join("cells.npy");
    write_points(&points, &[cells(0, 300), cells(1, 300)]);
    let seq = dir.join("seq");
    let name = |p: &Path| p.to_str().unwrap().to_string();
    meshflow_ok(&[
        "surface",
        &name(&points),
        "--out",
        &name(&seq),
        "--vertices",
        "300",
    ]);
    (points, seq)
}

/// `n³` unit voxels with `value(p)` at the voxel centres `p = (i, j, k)`, plus uniform noise of
/// standard deviation `noise` from a fixed hash (repeatable).
pub fn noisy_volume(
    n: usize,
    value: impl Fn(Vector3<f64>) -> f64,
    noise: f64,
) -> meshflow::volume::Volume {
    let mut values = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = Vector3::new(i as f64, j as f64, k as f64);
                let hash = ((i * 73_856_093) ^ (j * 19_349_663) ^ (k * 83_492_791)) % 1000;
                let uniform = hash as f64 / 1000.0 - 0.5; // variance 1/12
                values.push((value(p) + noise * 12f64.sqrt() * uniform) as f32);
            }
        }
    }
    meshflow::volume::Volume::new([n; 3], values, Vector3::repeat(1.0), Vector3::zeros()).unwrap()
}

/// `frames` (each `shape` = (Z, Y, X), C order) as an NGFF 0.5 OME-Zarr image (Zarr v3,
/// uncompressed little-endian float32, one chunk per frame, unit voxels, no translation).
pub fn write_ome_zarr_f32(image: &Path, shape: [usize; 3], frames: &[&[f32]]) {
    let [z, y, x] = shape;
    let axes: Vec<serde_json::Value> =
        std::iter::once(serde_json::json!({"name": "t", "type": "time"}))
            .chain(
                "zyx"
                    .chars()
                    .map(|n| serde_json::json!({"name": n.to_string(), "type": "space"})),
            )
            .collect();
    let group = serde_json::json!({"zarr_format": 3, "node_type": "group", "attributes": {"ome": {
        "version": "0.5", "multiscales": [{"version": "0.5", "axes": axes, "datasets": [{"path": "s0",
        "coordinateTransformations": [{"type": "scale", "scale": [1.0, 1.0, 1.0, 1.0]}]}]}]}}});
    let array = serde_json::json!({"zarr_format": 3, "node_type": "array",
        "shape": [frames.len(), z, y, x], "data_type": "float32",
        "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": [1, z, y, x]}},
        "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
        "fill_value": 0.0, "codecs": [{"name": "bytes", "configuration": {"endian": "little"}}]});
    std::fs::create_dir_all(image.join("s0")).unwrap();
    std::fs::write(image.join("zarr.json"), group.to_string()).unwrap();
    std::fs::write(image.join("s0/zarr.json"), array.to_string()).unwrap();
    for (t, values) in frames.iter().enumerate() {
        let chunk = image.join(format!("s0/c/{t}/0/0/0"));
        std::fs::create_dir_all(chunk.parent().unwrap()).unwrap();
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(chunk, bytes).unwrap();
    }
}
