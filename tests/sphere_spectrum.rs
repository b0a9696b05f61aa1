//! The connection Laplacian on the unit sphere against the continuous Bochner Laplacian, whose
//! eigenvalues on tangent fields are l(l+1) − 1 = 1, 5, 11, … with multiplicity 2(2l+1).

mod common;

use meshflow::connection::Connection;
use meshflow::fem::{connection_laplacian, vector_mass, MassKind};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::shapes::icosphere;

const CLUSTERS: [(f64, usize); 3] = [(1.0, 6), (5.0, 10), (11.0, 14)];

/// Lowest 30 generalized eigenvalues of (K, M) on the icosphere of the given level.
fn sphere_eigenvalues(level: u32) -> Vec<f64> {
    let sphere = icosphere(level);
    let mesh = sphere.mesh().unwrap();
    let geometry = IntrinsicGeometry::from_positions(&mesh, &sphere.positions).unwrap();
    let connection = Connection::new(&mesh, &geometry);
    let k = connection_laplacian(&mesh, &geometry, &connection);
    let m = vector_mass(&mesh, &geometry, &connection, MassKind::Consistent);
    common::lowest_generalized_eigenvalues(&k, &m, 30, 48)
}

/// Largest relative error within each cluster of exact eigenvalue and multiplicity.
fn cluster_errors(eigenvalues: &[f64]) -> Vec<f64> {
    let mut start = 0;
    CLUSTERS
        .iter()
        .map(|&(exact, multiplicity)| {
            let cluster = &eigenvalues[start..start + multiplicity];
            start += multiplicity;
            cluster
                .iter()
                .map(|v| (v - exact).abs() / exact)
                .fold(0.0, f64::max)
        })
        .collect()
}

#[test]
fn eigenvalues_converge_quadratically_to_bochner_spectrum() {
    let errors: Vec<Vec<f64>> = (2..=4)
        .map(|level| cluster_errors(&sphere_eigenvalues(level)))
        .collect();
    for (level, e) in (2..=4).zip(&errors) {
        println!(
            "level {level}: relative errors of λ = 1, 5, 11: {:.3e} {:.3e} {:.3e}",
            e[0], e[1], e[2]
        );
    }
    // Halving h divides the error by about 4 (O(h²)) for every cluster.
    for pair in errors.windows(2) {
        for (coarse, fine) in pair[0].iter().zip(&pair[1]) {
            let ratio = coarse / fine;
            assert!(
                (3.3..4.8).contains(&ratio),
                "error ratio {ratio} under refinement is not ≈ 4"
            );
        }
    }
    // About 0.1 % for λ = 1 at 2562 vertices.
    assert!(
        errors[2][0] < 2e-3,
        "λ = 1 error {} at 2562 vertices",
        errors[2][0]
    );
}

#[test]
fn clusters_have_the_continuous_multiplicities() {
    let eigenvalues = sphere_eigenvalues(3);
    // Each cluster is tight around its exact value and well separated from the next one.
    let mut start = 0;
    for &(exact, multiplicity) in &CLUSTERS {
        let cluster = &eigenvalues[start..start + multiplicity];
        assert!(
            cluster.iter().all(|v| (v - exact).abs() < 0.02 * exact),
            "cluster {exact}: {cluster:?}"
        );
        start += multiplicity;
    }
    assert!(
        eigenvalues[0] > 0.9,
        "no covariantly constant field on the sphere: K is definite"
    );
}
