//! Checks that scanned meshes load and give sound operators: one Markdown table row per mesh.
//!
//! `cargo run --release --example scan_checks -- MESH...` (`.obj`, `.ply`, `.gltf`, `.glb`)
//!
//! Each mesh is loaded as `meshflow operators` loads it (`io::load_mesh`: welding at the
//! default tolerance, unused vertices dropped, orientation); if that is refused for what only
//! repair fixes, it is loaded again with `--repair` and the row says so. Columns:
//!
//! - `V`, `F`, `χ` (Euler characteristic V − E + F of the mesh), `parts` (connected
//!   components), `boundary` (boundary vertices);
//! - `loader`: what loading changed (welded copies, dropped vertices, touching pairs kept
//!   apart, flipped faces, repairs);
//! - `K ⪰ 0`: the connection Laplacian K (2V×2V) is positive semi-definite, checked by a sparse
//!   Cholesky factorization of `K + δM` with `δ = 1e-10 · tr K / tr M`. `tr K / tr M` is the
//!   mean generalized eigenvalue of `(K, M)`, so the shift is far below every eigenvalue that
//!   matters, but it makes the exact kernel (parallel fields, e.g. on a torus) factorizable;
//!   the factorization fails if `(K, M)` has an eigenvalue below `−δ`;
//! - `M ≻ 0`: the consistent vector mass M is positive definite (its Cholesky factorization
//!   succeeds);
//! - `|L·1|`: `max_i |(L 1)_i| / max_i L_ii` for the cotan Laplacian L; constants are in its
//!   kernel, so this is round-off (`< 1e-12` passes);
//! - `frames`: `max_i |P_iᵀ P_i − I|` for the vertex frames in R^3 (`frames.npy`,
//!   `docs/discretization.md` §8); they are orthonormal, so this is round-off (`< 1e-12`
//!   passes).
//!
//! The process exits with status 1 if any mesh fails a check or does not load.

use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::Triplet;
use faer::Side;
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem::{self, MassKind, SparseMatrix};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::load::{load_mesh, LoadOptions, LoadWarning, LoadedMesh};
use meshflow::mesh::Mesh;
use meshflow::Error;
use std::path::Path;
use std::process::ExitCode;

fn main() -> ExitCode {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        eprintln!("usage: scan_checks MESH...");
        return ExitCode::from(2);
    }
    println!("| mesh | V | F | χ | parts | boundary | loader | K ⪰ 0 | M ≻ 0 | \\|L·1\\| | frames \\|PᵀP − I\\| |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut all_pass = true;
    for path in &paths {
        let name = Path::new(path)
            .file_name()
            .map_or(path.clone(), |n| n.to_string_lossy().into_owned());
        match check(Path::new(path)) {
            Ok(row) => {
                all_pass &= row.passes();
                println!("| {name} | {} |", row.cells().join(" | "));
            }
            Err(error) => {
                all_pass = false;
                println!("| {name} | does not load: {error} ||||||||||");
            }
        }
    }
    match all_pass {
        true => ExitCode::SUCCESS,
        false => ExitCode::FAILURE,
    }
}

/// What one mesh gave.
struct Row {
    mesh: Mesh,
    loader: String,
    k_semidefinite: bool,
    m_definite: bool,
    constants: f64,
    frames: f64,
}

impl Row {
    fn passes(&self) -> bool {
        self.k_semidefinite && self.m_definite && self.constants < 1e-12 && self.frames < 1e-12
    }

    fn cells(&self) -> Vec<String> {
        let mesh = &self.mesh;
        let boundary = (0..mesh.n_vertices())
            .filter(|&i| mesh.is_boundary_vertex(i))
            .count();
        let verdict = |ok: bool| if ok { "pass" } else { "FAIL" }.to_string();
        vec![
            mesh.n_vertices().to_string(),
            mesh.n_faces().to_string(),
            mesh.euler_characteristic().to_string(),
            mesh.connected_components().len().to_string(),
            boundary.to_string(),
            self.loader.clone(),
            verdict(self.k_semidefinite),
            verdict(self.m_definite),
            format!("{:.1e}", self.constants),
            format!("{:.1e}", self.frames),
        ]
    }
}

fn check(path: &Path) -> Result<Row, Error> {
    let (loaded, repaired) = match load_mesh(path, &LoadOptions::default()) {
        Ok(loaded) => (loaded, false),
        Err(error) if error.to_string().contains("--repair") => {
            let options = LoadOptions {
                repair: true,
                ..LoadOptions::default()
            };
            (load_mesh(path, &options)?, true)
        }
        Err(error) => return Err(error),
    };
    let loader = describe_loading(&loaded, repaired);
    let LoadedMesh {
        mesh, positions, ..
    } = loaded;
    let geometry = IntrinsicGeometry::from_positions(&mesh, &positions)?;
    let connection = Connection::new(&mesh, &geometry);
    let k = fem::connection_laplacian(&mesh, &geometry, &connection);
    let m = fem::vector_mass(&mesh, &geometry, &connection, MassKind::Consistent);
    let shift = 1e-10 * trace(&k) / trace(&m);
    let l = fem::cotan_laplacian(&mesh, &geometry);
    let constants = row_sums(&l)
        .into_iter()
        .fold(0.0, |a: f64, s| a.max(s.abs()))
        / diagonal(&l).into_iter().fold(0.0, f64::max);
    let frames = vertex_frames_in_r3(&mesh, &geometry, &connection, &positions)?
        .iter()
        .map(|p| (p.transpose() * p - nalgebra::Matrix2::identity()).amax())
        .fold(0.0, f64::max);
    Ok(Row {
        frames,
        k_semidefinite: cholesky_succeeds(&sum(&k, 1.0, &m, shift)),
        m_definite: cholesky_succeeds(&m),
        constants,
        loader,
        mesh,
    })
}

/// The loader's changes, from the vertex map and the warnings.
fn describe_loading(loaded: &LoadedMesh, repaired: bool) -> String {
    let map = &loaded.vertex_map;
    let mut said = Vec::new();
    if map.n_welded() > 0 {
        said.push(format!("welded {}", map.n_welded()));
    }
    for warning in &loaded.warnings {
        said.push(match warning {
            LoadWarning::UnusedVertices { count, .. } => format!("dropped {count} unused"),
            LoadWarning::TouchingVertices { count, .. } => {
                format!("kept {count} touching pairs apart")
            }
            LoadWarning::FlippedFaces { count, .. } => format!("flipped {count} faces"),
            LoadWarning::Repaired { report, .. } => {
                let mut parts = Vec::new();
                let removed = report.degenerate_faces + report.duplicate_faces;
                let cut = report.non_manifold_edges + report.orientation_cuts;
                if removed > 0 {
                    parts.push(format!("removed {removed} faces"));
                }
                if cut > 0 {
                    parts.push(format!("cut {cut} edges"));
                }
                if report.split_vertices > 0 {
                    parts.push(format!(
                        "split {} vertices into {}",
                        report.split_vertices,
                        report.split_vertices + report.added_vertices
                    ));
                }
                format!("--repair: {}", parts.join(", "))
            }
            other => other.to_string(),
        });
    }
    if repaired && !said.iter().any(|s| s.starts_with("--repair")) {
        said.push("--repair".into());
    }
    match said.is_empty() {
        true => "as written".into(),
        false => said.join("; "),
    }
}

fn diagonal(a: &SparseMatrix) -> Vec<f64> {
    let mut d = vec![0.0; a.nrows()];
    for entry in a.triplet_iter().filter(|t| t.row == t.col) {
        d[entry.row] += entry.val;
    }
    d
}

fn trace(a: &SparseMatrix) -> f64 {
    diagonal(a).iter().sum()
}

fn row_sums(a: &SparseMatrix) -> Vec<f64> {
    let mut sums = vec![0.0; a.nrows()];
    for entry in a.triplet_iter() {
        sums[entry.row] += entry.val;
    }
    sums
}

/// `x A + y B`.
fn sum(a: &SparseMatrix, x: f64, b: &SparseMatrix, y: f64) -> SparseMatrix {
    let scaled = |m: &SparseMatrix, s: f64| {
        m.triplet_iter()
            .map(move |t| Triplet::new(t.row, t.col, s * t.val))
            .collect::<Vec<_>>()
    };
    let triplets = [scaled(a, x), scaled(b, y)].concat();
    SparseMatrix::try_new_from_triplets(a.nrows(), a.ncols(), &triplets).expect("same shape")
}

fn cholesky_succeeds(a: &SparseMatrix) -> bool {
    SymbolicLlt::try_new(a.symbolic(), Side::Lower)
        .is_ok_and(|symbolic| Llt::try_new_with_symbolic(symbolic, a.as_ref(), Side::Lower).is_ok())
}
