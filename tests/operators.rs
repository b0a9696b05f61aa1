//! Finite-element operators: closed forms, flat-mesh reductions, sums, symmetry, definiteness.

mod common;

use common::{dense, eigenvalues, generalized_eigen};
use meshflow::connection::{vertex_frames_in_r3, Connection};
use meshflow::fem::{
    connection_laplacian, cotan_laplacian, face_gradient_operator, scalar_mass, vector_mass,
    MassKind,
};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::mesh::Mesh;
use meshflow::shapes::{icosphere, torus, Surface};
use nalgebra::{DMatrix, DVector, Matrix3x2, Vector2, Vector3};

struct Setup {
    mesh: Mesh,
    positions: Vec<Vector3<f64>>,
    geometry: IntrinsicGeometry,
    connection: Connection,
}

fn setup(surface: Surface) -> Setup {
    let mesh = surface.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &surface.positions).unwrap();
    let connection = Connection::new(&mesh, &geometry);
    Setup {
        mesh,
        positions: surface.positions,
        geometry,
        connection,
    }
}

/// A flat 6×5 grid with boundary whose interior vertices are moved off the lattice.
fn jittered_flat_patch() -> Setup {
    setup(common::jittered_grid(6, 5, 1.2, 1.0, 0.06))
}

fn single_triangle(c: Vector3<f64>) -> Setup {
    setup(Surface {
        positions: vec![Vector3::zeros(), Vector3::new(1.0, 0.0, 0.0), c],
        faces: vec![[0, 1, 2]],
    })
}

fn assert_close(a: &DMatrix<f64>, b: &DMatrix<f64>, tolerance: f64) {
    assert!((a - b).amax() <= tolerance, "\n{a}\nvs\n{b}");
}

#[test]
fn scalar_operators_match_closed_forms() {
    let right = single_triangle(Vector3::new(0.0, 1.0, 0.0));
    let l = dense(&cotan_laplacian(&right.mesh, &right.geometry));
    let expected =
        DMatrix::from_row_slice(3, 3, &[1.0, -0.5, -0.5, -0.5, 0.5, 0.0, -0.5, 0.0, 0.5]);
    assert_close(&l, &expected, 1e-15);
    let m = dense(&scalar_mass(
        &right.mesh,
        &right.geometry,
        MassKind::Consistent,
    ));
    let pattern = DMatrix::from_row_slice(3, 3, &[2.0, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 2.0]);
    assert_close(&m, &(&pattern / 24.0), 1e-16);
    let lumped = dense(&scalar_mass(&right.mesh, &right.geometry, MassKind::Lumped));
    assert_close(&lumped, &(DMatrix::identity(3, 3) / 6.0), 1e-16);

    let equilateral = single_triangle(Vector3::new(0.5, 3f64.sqrt() / 2.0, 0.0));
    let l = dense(&cotan_laplacian(&equilateral.mesh, &equilateral.geometry));
    let w = 1.0 / (2.0 * 3f64.sqrt());
    let expected = DMatrix::from_fn(3, 3, |i, j| if i == j { 2.0 * w } else { -w });
    assert_close(&l, &expected, 1e-15);
    let m = dense(&scalar_mass(
        &equilateral.mesh,
        &equilateral.geometry,
        MassKind::Consistent,
    ));
    assert_close(&m, &(&pattern * (3f64.sqrt() / 4.0 / 12.0)), 1e-16);
}

#[test]
fn flat_connection_laplacian_is_the_cotan_laplacian_doubled() {
    let s = jittered_flat_patch();
    let k = dense(&connection_laplacian(&s.mesh, &s.geometry, &s.connection));
    let m = dense(&vector_mass(
        &s.mesh,
        &s.geometry,
        &s.connection,
        MassKind::Consistent,
    ));
    let l = dense(&cotan_laplacian(&s.mesh, &s.geometry));
    let ms = dense(&scalar_mass(&s.mesh, &s.geometry, MassKind::Consistent));
    let doubled = |values: Vec<f64>| values.iter().flat_map(|&v| [v, v]).collect::<Vec<_>>();
    for (kv, lv) in eigenvalues(&k).iter().zip(doubled(eigenvalues(&l))) {
        assert!((kv - lv).abs() < 1e-12, "standard spectrum: {kv} vs {lv}");
    }
    let (k_general, _) = generalized_eigen(&k, &m);
    let (l_general, _) = generalized_eigen(&l, &ms);
    for (kv, lv) in k_general.iter().zip(doubled(l_general)) {
        assert!(
            (kv - lv).abs() < 1e-9 * (1.0 + lv),
            "generalized spectrum: {kv} vs {lv}"
        );
    }
}

/// The field equal to the constant R^3 vector `c` (in the plane), in vertex-frame components.
fn constant_field(frames: &[Matrix3x2<f64>], c: Vector3<f64>) -> DVector<f64> {
    DVector::from_iterator(
        2 * frames.len(),
        frames.iter().flat_map(|p| {
            let u = p.transpose() * c;
            [u.x, u.y]
        }),
    )
}

#[test]
fn constant_fields_on_a_flat_mesh_are_in_the_kernel_and_have_unit_mass_density() {
    let s = jittered_flat_patch();
    let frames = vertex_frames_in_r3(&s.mesh, &s.geometry, &s.connection, &s.positions).unwrap();
    for p in &frames {
        // In-plane orthonormal frames: the push-forward is an isometry on a flat mesh.
        assert!((p.transpose() * p - nalgebra::Matrix2::identity()).amax() < 1e-13);
        assert!(p.row(2).amax() < 1e-15);
    }
    let k = connection_laplacian(&s.mesh, &s.geometry, &s.connection);
    let m = vector_mass(&s.mesh, &s.geometry, &s.connection, MassKind::Consistent);
    let area = s.geometry.total_area();
    assert!((area - 1.2).abs() < 1e-13);
    for c in [Vector3::x(), Vector3::new(0.6, -0.8, 0.0)] {
        let u =
            DMatrix::from_column_slice(2 * frames.len(), 1, constant_field(&frames, c).as_slice());
        let ku = common::mul(&k, &u);
        assert!(ku.amax() < 1e-13, "K·constant = {}", ku.amax());
        let mass = (u.transpose() * common::mul(&m, &u))[(0, 0)];
        assert!((mass - area).abs() < 1e-13, "∫|u|² = {mass}, area {area}");
    }
}

#[test]
fn masses_sum_to_area_and_operators_are_symmetric_and_definite() {
    let s = setup(icosphere(1));
    let area = s.geometry.total_area();
    for kind in [MassKind::Consistent, MassKind::Lumped] {
        let m = dense(&scalar_mass(&s.mesh, &s.geometry, kind));
        assert!((m.sum() - area).abs() < 1e-13 * area);
        let mv = dense(&vector_mass(&s.mesh, &s.geometry, &s.connection, kind));
        assert!(
            (mv.trace()
                - if kind == MassKind::Lumped {
                    2.0 * area
                } else {
                    area
                })
            .abs()
                < 1e-12
        );
        assert!(
            eigenvalues(&mv)[0] > 0.0,
            "vector mass is positive definite"
        );
        assert_eq!(
            common::asymmetry(&vector_mass(&s.mesh, &s.geometry, &s.connection, kind)),
            0.0
        );
    }
    let k = connection_laplacian(&s.mesh, &s.geometry, &s.connection);
    assert!(common::asymmetry(&k) < 1e-15);
    assert!(
        eigenvalues(&dense(&k))[0] > 1e-3,
        "no parallel field on the sphere"
    );
    let l = cotan_laplacian(&s.mesh, &s.geometry);
    assert!(common::asymmetry(&l) < 1e-15);
    let row_sums = dense(&l) * DVector::repeat(s.mesh.n_vertices(), 1.0);
    assert!(row_sums.amax() < 1e-14);
}

#[test]
fn face_gradient_of_a_linear_function_is_exact() {
    let s = jittered_flat_patch();
    let g = face_gradient_operator(&s.mesh, &s.geometry);
    assert_eq!(
        (g.nrows(), g.ncols()),
        (2 * s.mesh.n_faces(), s.mesh.n_vertices())
    );
    let exact = Vector3::new(0.7, -1.3, 0.0);
    let f = DMatrix::from_iterator(
        s.mesh.n_vertices(),
        1,
        s.positions.iter().map(|p| exact.dot(p) + 0.2),
    );
    let gf = common::mul(&g, &f);
    for (t, face) in s.mesh.faces().iter().enumerate() {
        // Map the face-frame gradient to R^3 with F_T = E3 · E2⁻¹.
        let [a, b, c] = face.map(|v| s.positions[v as usize]);
        let f_t = Matrix3x2::from_columns(&[b - a, c - a])
            * s.geometry
                .triangle(t)
                .layout_edge_matrix()
                .try_inverse()
                .unwrap();
        let grad = f_t * Vector2::new(gf[(2 * t, 0)], gf[(2 * t + 1, 0)]);
        assert!((grad - exact).norm() < 1e-12, "face {t}: {grad} vs {exact}");
    }
}

#[test]
fn edge_transport_preserves_vectors_on_a_flat_mesh() {
    let s = jittered_flat_patch();
    let frames = vertex_frames_in_r3(&s.mesh, &s.geometry, &s.connection, &s.positions).unwrap();
    let u = Vector2::new(0.3, -1.7);
    for h in 0..s.mesh.n_halfedges() {
        let [i, j] = s.mesh.halfedge_vertices(h);
        let moved = s.connection.transport(&s.mesh, &s.geometry, h, u);
        let before = frames[i as usize] * u;
        let after = frames[j as usize] * moved;
        assert!(
            (before - after).norm() < 1e-13,
            "halfedge {h}: {before} → {after}"
        );
    }
}

#[test]
fn curved_frames_are_nearly_tangent_and_converge() {
    // Frames of the sphere lie in the tangent plane up to O(h).
    let worst_normal_component = |level| {
        let s = setup(icosphere(level));
        let frames =
            vertex_frames_in_r3(&s.mesh, &s.geometry, &s.connection, &s.positions).unwrap();
        frames
            .iter()
            .zip(&s.positions)
            .map(|(p, n)| (n.transpose() * p).amax())
            .fold(0.0, f64::max)
    };
    let worst: Vec<f64> = (2..=4).map(worst_normal_component).collect();
    println!("largest normal component of a frame vector, levels 2-4: {worst:?}");
    assert!(
        worst.windows(2).all(|w| w[1] < 0.7 * w[0]) && worst[2] < 4e-3,
        "{worst:?}"
    );
}

#[test]
fn intrinsic_flat_torus_has_two_parallel_fields() {
    // The paper's "naive" surface: periodic grid, spacing 1, diagonals √2; no embedding.
    let (n_major, n_minor) = (8, 6);
    let mesh = torus(2.0, 1.0, n_major, n_minor).mesh().unwrap();
    let steps = |a: u32, b: u32, n: usize, m: usize| {
        let d = |x: usize, y: usize, period: usize| {
            let step = (x + period - y) % period;
            step.min(period - step) as f64
        };
        let (a, b) = (a as usize, b as usize);
        (d(a / m, b / m, n), d(a % m, b % m, m))
    };
    let lengths = mesh
        .edges()
        .iter()
        .map(|&[a, b]| {
            let (di, dj) = steps(a, b, n_major, n_minor);
            (di * di + dj * dj).sqrt()
        })
        .collect();
    let geometry = IntrinsicGeometry::new(&mesh, lengths).unwrap();
    assert!(geometry
        .angle_defects(&mesh)
        .iter()
        .all(|d| d.abs() < 1e-14));
    let connection = Connection::new(&mesh, &geometry);
    let k = eigenvalues(&dense(&connection_laplacian(&mesh, &geometry, &connection)));
    assert!(k[0].abs() < 1e-12 && k[1].abs() < 1e-12, "{:?}", &k[..3]);
    assert!(k[2] > 0.1);
    let l = eigenvalues(&dense(&cotan_laplacian(&mesh, &geometry)));
    for (i, lv) in l.iter().enumerate() {
        assert!((k[2 * i] - lv).abs() < 1e-12 && (k[2 * i + 1] - lv).abs() < 1e-12);
    }
}
