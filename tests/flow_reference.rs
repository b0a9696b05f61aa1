//! On a static flat mesh the connection is trivial, and the flow must equal an independent
//! componentwise P1 Horn–Schunck / Weickert–Schnörr solution written here with global x/y
//! components, hat-function gradients and dense linear algebra. Covers lumped and consistent
//! time coupling, Neumann and Dirichlet boundaries, non-uniform frame times and α = ∞, and
//! relative weights resolved with the data's scales computed here independently.

mod common;

use meshflow::flow::{
    compute_flow, Boundary, FlowParams, MeshSequence, SolverChoice, TimeCoupling, Weight,
};
use meshflow::shapes::Surface;
use nalgebra::{DMatrix, DVector, Matrix2, Vector2, Vector3};
use std::collections::BTreeSet;

fn image(p: &Vector3<f64>, t: f64) -> f64 {
    (3.0 * p.x + 0.8 * t).sin() * (2.0 * p.y - 0.5 * t).cos() + 0.5 * p.x * p.y + 0.1 * t * p.x
}

struct Case {
    surface: Surface,
    times: Vec<f64>,
    params: FlowParams,
}

/// Hat-function gradients of a planar triangle in global x/y and its area.
fn hat_gradients(p: [Vector3<f64>; 3]) -> ([Vector2<f64>; 3], f64) {
    let e = Matrix2::new(
        p[1].x - p[0].x,
        p[2].x - p[0].x,
        p[1].y - p[0].y,
        p[2].y - p[0].y,
    );
    let area = 0.5 * e.determinant();
    // ∇φ_b, ∇φ_c are the rows of E⁻¹; ∇φ_a = −∇φ_b − ∇φ_c.
    let inv = e.try_inverse().unwrap();
    let (gb, gc) = (
        Vector2::new(inv[(0, 0)], inv[(0, 1)]),
        Vector2::new(inv[(1, 0)], inv[(1, 1)]),
    );
    ([-gb - gc, gb, gc], area)
}

/// The reference minimizer: unknown `(s, i, k)` is component `k` (x or y) at vertex `i` in slab `s`.
fn reference_flow(case: &Case) -> Vec<Vec<Vector2<f64>>> {
    let (v, n_slabs) = (case.surface.positions.len(), case.times.len() - 1);
    let index = |s: usize, i: u32, k: usize| s * 2 * v + 2 * i as usize + k;
    let mut h = DMatrix::zeros(2 * v * n_slabs, 2 * v * n_slabs);
    let mut rhs = DVector::zeros(2 * v * n_slabs);
    let (alpha, beta, gamma) = reference_weights(case);
    let dt: Vec<f64> = case.times.windows(2).map(|w| w[1] - w[0]).collect();
    for face in &case.surface.faces {
        let p = face.map(|i| case.surface.positions[i as usize]);
        let (grads, area) = hat_gradients(p);
        let mass = |a: usize, b: usize| area / 12.0 * if a == b { 2.0 } else { 1.0 };
        let lumped = |a: usize, b: usize| if a == b { area / 3.0 } else { 0.0 };
        for s in 0..n_slabs {
            let (t0, t1) = (case.times[s], case.times[s + 1]);
            let mid = |a: usize| 0.5 * (image(&p[a], t0) + image(&p[a], t1));
            let rate = |a: usize| (image(&p[a], t1) - image(&p[a], t0)) / dt[s];
            let g: Vector2<f64> = (0..3).map(|a| grads[a] * mid(a)).sum();
            for a in 0..3 {
                for b in 0..3 {
                    for k in 0..2 {
                        rhs[index(s, face[a], k)] -= dt[s] * mass(a, b) * rate(b) * g[k];
                        let diffusion =
                            dt[s] * (beta * mass(a, b) + gamma * area * grads[a].dot(&grads[b]));
                        h[(index(s, face[a], k), index(s, face[b], k))] += diffusion;
                        for l in 0..2 {
                            h[(index(s, face[a], k), index(s, face[b], l))] +=
                                dt[s] * mass(a, b) * g[k] * g[l];
                        }
                    }
                }
            }
            if s + 1 < n_slabs && alpha.is_finite() {
                let c = gamma / (alpha * alpha * 0.5 * (dt[s] + dt[s + 1]));
                for a in 0..3 {
                    for b in 0..3 {
                        let w = c * match case.params.time_coupling {
                            TimeCoupling::Lumped => lumped(a, b),
                            TimeCoupling::Consistent => mass(a, b),
                        };
                        for k in 0..2 {
                            for (sa, sb, sign) in [
                                (s, s, 1.0),
                                (s + 1, s + 1, 1.0),
                                (s, s + 1, -1.0),
                                (s + 1, s, -1.0),
                            ] {
                                h[(index(sa, face[a], k), index(sb, face[b], k))] += sign * w;
                            }
                        }
                    }
                }
            }
        }
    }
    if case.params.boundary == Boundary::Dirichlet {
        let mesh = case.surface.mesh().unwrap();
        for s in 0..n_slabs {
            for i in (0..v).filter(|&i| mesh.is_boundary_vertex(i)) {
                for k in 0..2 {
                    let d = index(s, i as u32, k);
                    h.row_mut(d).fill(0.0);
                    h.column_mut(d).fill(0.0);
                    h[(d, d)] = 1.0;
                    rhs[d] = 0.0;
                }
            }
        }
    }
    let u = h
        .cholesky()
        .expect("reference system is positive definite")
        .solve(&rhs);
    (0..n_slabs)
        .map(|s| {
            (0..v)
                .map(|i| Vector2::new(u[index(s, i as u32, 0)], u[index(s, i as u32, 1)]))
                .collect()
        })
        .collect()
}

/// `(α, β, γ)` as numbers: values as given; relative weights from `S² = ∫∫|∇I|⁴ / ∫∫|∇I|²`
/// (P1 gradients of the mid-slab image), the mean edge length `h̄` and the mean frame spacing.
fn reference_weights(case: &Case) -> (f64, f64, f64) {
    let (mut second, mut fourth) = (0.0, 0.0);
    for window in case.times.windows(2) {
        let (t0, t1) = (window[0], window[1]);
        for face in &case.surface.faces {
            let p = face.map(|i| case.surface.positions[i as usize]);
            let (grads, area) = hat_gradients(p);
            let g: Vector2<f64> = (0..3)
                .map(|a| grads[a] * 0.5 * (image(&p[a], t0) + image(&p[a], t1)))
                .sum();
            second += (t1 - t0) * area * g.norm_squared();
            fourth += (t1 - t0) * area * g.norm_squared().powi(2);
        }
    }
    let s = (fourth / second).sqrt();
    let edges: BTreeSet<(u32, u32)> = case
        .surface
        .faces
        .iter()
        .flat_map(|f| (0..3).map(|c| (f[c].min(f[(c + 1) % 3]), f[c].max(f[(c + 1) % 3]))))
        .collect();
    let x = &case.surface.positions;
    let h = edges
        .iter()
        .map(|&(i, j)| (x[j as usize] - x[i as usize]).norm())
        .sum::<f64>()
        / edges.len() as f64;
    let frame_spacing =
        (case.times[case.times.len() - 1] - case.times[0]) / (case.times.len() - 1) as f64;
    let gamma = match case.params.gamma {
        Weight::Value(g) => g,
        Weight::Relative(spread) => (spread * h * s).powi(2),
    };
    let alpha = match case.params.alpha {
        Weight::Value(a) => a,
        Weight::Relative(n) => gamma.sqrt() / (s * n * frame_spacing),
    };
    let beta = match case.params.beta {
        Weight::Value(b) => b,
        Weight::Relative(b) => b * s * s,
    };
    (alpha, beta, gamma)
}

fn assert_matches_reference(case: Case) {
    let frames = case.times.len();
    let intensities = case
        .times
        .iter()
        .map(|&t| case.surface.positions.iter().map(|p| image(p, t)).collect())
        .collect();
    let sequence = MeshSequence::new(
        case.surface.mesh().unwrap(),
        vec![case.surface.positions.clone(); frames],
        intensities,
        Some(case.times.clone()),
    )
    .unwrap();
    let flow = compute_flow(&sequence, &case.params).unwrap();
    let expected = reference_flow(&case);
    let scale = expected
        .iter()
        .flatten()
        .map(|u| u.norm())
        .fold(0.0, f64::max);
    assert!(scale > 1e-2, "the test image moves");
    for (computed, expected) in flow.vectors.unwrap().iter().zip(&expected) {
        for (u, e) in computed.iter().zip(expected) {
            assert!(u.z.abs() < 1e-14, "flat mesh, flat flow");
            let difference = (u.xy() - e).norm();
            assert!(difference < 1e-9 * scale, "flow {u} vs reference {e}");
        }
    }
}

fn flat_patch() -> Surface {
    common::jittered_grid(6, 5, 1.2, 1.0, 0.05)
}

#[test]
fn lumped_neumann_uniform_times() {
    assert_matches_reference(Case {
        surface: flat_patch(),
        times: vec![0.0, 1.0, 2.0, 3.0],
        params: FlowParams::paper(1.0, 0.0, 0.05),
    });
}

#[test]
fn consistent_dirichlet_non_uniform_times() {
    assert_matches_reference(Case {
        surface: flat_patch(),
        times: vec![0.0, 0.5, 1.7, 2.0],
        params: FlowParams {
            boundary: Boundary::Dirichlet,
            time_coupling: TimeCoupling::Consistent,
            ..FlowParams::paper(0.7, 0.0, 0.2)
        },
    });
}

#[test]
fn lumped_dirichlet_with_beta_and_iterative_solver() {
    assert_matches_reference(Case {
        surface: flat_patch(),
        times: vec![0.0, 0.3, 0.6, 1.4, 1.5],
        params: FlowParams {
            boundary: Boundary::Dirichlet,
            solver: SolverChoice::PcgSlabGaussSeidel,
            tolerance: 1e-12,
            ..FlowParams::paper(2.0, 0.3, 0.1)
        },
    });
}

#[test]
fn frame_by_frame_flow_without_time_coupling() {
    assert_matches_reference(Case {
        surface: flat_patch(),
        times: vec![0.0, 1.0, 2.5],
        params: FlowParams::paper(f64::INFINITY, 0.01, 0.1),
    });
}

#[test]
fn relative_weights_resolve_with_the_data_scales() {
    // The defaults (spread 0.5 edge lengths, time scale 1 frame) and a relative speed penalty,
    // with non-uniform frame times so that the mean frame spacing matters.
    assert_matches_reference(Case {
        surface: flat_patch(),
        times: vec![0.0, 0.4, 1.5, 2.1],
        params: FlowParams {
            beta: Weight::Relative(0.02),
            ..FlowParams::default()
        },
    });
}
