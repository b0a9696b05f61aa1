//! What a flow tells (`meshflow::analysis`): divergence and curl converge to their analytic
//! values on the sphere and the torus (first order per face, second order in the weak vertex
//! form), the Hodge parts are orthogonal, add up to the field and find the parts of a mixture,
//! the harmonic space is 2-dimensional on a torus and empty on a sphere, and the strain rate is
//! zero for rigid motions, `2ṙ/r` for a growing sphere and the analytic rates for a stretch.

use meshflow::analysis::{analyze_flow, face_frames, hodge, SlabAnalysis};
use meshflow::flow::MeshSequence;
use meshflow::shapes::{icosphere, torus, Surface};
use nalgebra::{Rotation3, Vector2, Vector3};

/// A sequence of `frames` (positions per frame) on `surface`'s faces, grey values 0.
fn sequence(surface: &Surface, frames: Vec<Vec<Vector3<f64>>>, times: Vec<f64>) -> MeshSequence {
    let grey = vec![vec![0.0; surface.positions.len()]; frames.len()];
    MeshSequence::new(surface.mesh().unwrap(), frames, grey, Some(times)).unwrap()
}

/// The surface standing still for two frames, a unit of time apart.
fn still(surface: &Surface) -> MeshSequence {
    sequence(surface, vec![surface.positions.clone(); 2], vec![0.0, 1.0])
}

/// The tangent field `field(x)` (in R³, projected onto each vertex frame) of slab 0.
fn vertex_field(
    sequence: &MeshSequence,
    field: impl Fn(&Vector3<f64>) -> Vector3<f64>,
) -> Vec<Vector2<f64>> {
    let frames = sequence.slab_frames(0).unwrap().unwrap();
    let positions = sequence.positions(0).unwrap();
    frames
        .iter()
        .zip(positions)
        .map(|(p, x)| p.transpose() * field(x))
        .collect()
}

fn analysis(sequence: &MeshSequence, u: Vec<Vector2<f64>>) -> SlabAnalysis {
    analyze_flow(sequence, &[u]).unwrap().remove(0)
}

/// Area-weighted relative L² error of `computed` against `exact` at points with `weights`.
fn relative_error(computed: &[f64], exact: &[f64], weights: &[f64]) -> f64 {
    let (mut error, mut norm) = (0.0, 0.0);
    for ((c, e), w) in computed.iter().zip(exact).zip(weights) {
        error += w * (c - e).powi(2);
        norm += w * e * e;
    }
    (error / norm).sqrt()
}

fn face_areas(sequence: &MeshSequence) -> Vec<f64> {
    let geometry = sequence.slab_geometry(0).unwrap();
    geometry.triangles().iter().map(|t| t.area).collect()
}

fn centroids(surface: &Surface) -> Vec<Vector3<f64>> {
    surface
        .faces
        .iter()
        .map(|f| {
            f.iter()
                .map(|&i| surface.positions[i as usize])
                .sum::<Vector3<f64>>()
                / 3.0
        })
        .collect()
}

/// Convergence orders between consecutive refinements (the edge length halves each time).
fn orders(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect()
}

/// `Y = xy` on the unit sphere (degree 2: `ΔY = −6Y`) and its surface gradient.
fn y2(x: &Vector3<f64>) -> f64 {
    x.x * x.y
}

fn grad_y2(x: &Vector3<f64>) -> Vector3<f64> {
    let n = x.normalize();
    let g = Vector3::new(x.y, x.x, 0.0);
    g - n * n.dot(&g)
}

/// `J v = n × v` on the outward-oriented sphere.
fn turned(x: &Vector3<f64>, v: Vector3<f64>) -> Vector3<f64> {
    x.normalize().cross(&v)
}

struct SphereErrors {
    vertex_median: f64,
    face_div: f64,
    face_curl: f64,
    vertex_div: f64,
    vertex_curl: f64,
}

/// Errors of div and curl of `∇Y` (`rotated`: of `J∇Y`) on the level-`level` icosphere.
fn sphere_errors(level: u32, rotated: bool) -> SphereErrors {
    let surface = icosphere(level);
    let sequence = still(&surface);
    let field = |x: &Vector3<f64>| match rotated {
        false => grad_y2(x),
        true => turned(x, grad_y2(x)),
    };
    let a = analysis(&sequence, vertex_field(&sequence, field));
    let areas = face_areas(&sequence);
    let faces: Vec<f64> = centroids(&surface)
        .iter()
        .map(|c| -6.0 * y2(&c.normalize()))
        .collect();
    let vertices: Vec<f64> = surface.positions.iter().map(|x| -6.0 * y2(x)).collect();
    let ones = vec![1.0; vertices.len()];
    let rms = |values: &[f64], weights: &[f64]| {
        (values
            .iter()
            .zip(weights)
            .map(|(v, w)| w * v * v)
            .sum::<f64>()
            / weights.iter().sum::<f64>())
        .sqrt()
    };
    let scale = rms(&vertices, &ones);
    let (div_face, curl_face, div_vertex, curl_vertex) = match rotated {
        false => (
            &a.face_divergence,
            &a.face_curl,
            &a.vertex_divergence,
            &a.vertex_curl,
        ),
        true => (
            &a.face_curl,
            &a.face_divergence,
            &a.vertex_curl,
            &a.vertex_divergence,
        ),
    };
    let mut pointwise: Vec<f64> = div_vertex
        .iter()
        .zip(&vertices)
        .map(|(c, e)| (c - e).abs() / scale)
        .collect();
    pointwise.sort_by(f64::total_cmp);
    SphereErrors {
        vertex_median: pointwise[pointwise.len() / 2],
        face_div: relative_error(div_face, &faces, &areas),
        face_curl: rms(curl_face, &areas) / scale,
        vertex_div: relative_error(div_vertex, &vertices, &ones),
        vertex_curl: rms(curl_vertex, &ones) / scale,
    }
}

/// `u = ∇Y` (and `J∇Y`) for `Y = xy` on icospheres of 162 to 40,962 vertices: divergence (and
/// curl) → `−6Y` at first order per face and second order at the vertices (the median vertex;
/// in L² the order is 1.5, from first-order errors along the icosahedron's seams, where the
/// subdivision meets irregularly), the other → 0.
#[test]
fn divergence_and_curl_converge_on_the_sphere() {
    for rotated in [false, true] {
        let errors: Vec<SphereErrors> = (2..=6).map(|l| sphere_errors(l, rotated)).collect();
        let pick = |f: fn(&SphereErrors) -> f64| errors.iter().map(f).collect::<Vec<f64>>();
        let (face, vertex) = (pick(|e| e.face_div), pick(|e| e.vertex_div));
        let median = pick(|e| e.vertex_median);
        let (face_zero, vertex_zero) = (pick(|e| e.face_curl), pick(|e| e.vertex_curl));
        println!(
            "J∇Y: {rotated}; face {face:.3?} orders {:.2?}",
            orders(&face)
        );
        println!("  vertex L² {vertex:.3?} orders {:.2?}", orders(&vertex));
        println!(
            "  vertex median {median:.3?} orders {:.2?}",
            orders(&median)
        );
        println!(
            "  zero part: face {face_zero:.3?} orders {:.2?}",
            orders(&face_zero)
        );
        println!(
            "  zero part: vertex {vertex_zero:.3?} orders {:.2?}",
            orders(&vertex_zero)
        );
        assert!(orders(&face).iter().all(|&p| p > 1.0), "{face:?}");
        assert!(
            orders(&face_zero).iter().all(|&p| p > 0.95),
            "{face_zero:?}"
        );
        assert!(orders(&vertex)[2..].iter().all(|&p| p > 1.5), "{vertex:?}");
        assert!(orders(&median)[2..].iter().all(|&p| p > 1.9), "{median:?}");
        assert!(
            orders(&vertex_zero)[2..].iter().all(|&p| p > 1.4),
            "{vertex_zero:?}"
        );
        assert!(vertex[4] < 2e-3 && face[4] < 3e-3, "{vertex:?} {face:?}");
    }
}

/// The torus `((R + r cos v) cos u, (R + r cos v) sin u, r sin v)` with `R = 2`, `r = 1`:
/// the angles of a point, and the outward normal.
fn torus_angles(x: &Vector3<f64>) -> (f64, f64) {
    let rho = x.x.hypot(x.y);
    (x.y.atan2(x.x), x.z.atan2(rho - 2.0))
}

fn torus_normal(x: &Vector3<f64>) -> Vector3<f64> {
    let (u, v) = torus_angles(x);
    Vector3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin())
}

/// `f = sin v` on the torus: its surface gradient `(cos v / r²) x_v` and `Δf = −sin v (r cos v +
/// ρ) / (r² ρ)`, `ρ = R + r cos v`.
fn torus_gradient(x: &Vector3<f64>) -> Vector3<f64> {
    let (u, v) = torus_angles(x);
    Vector3::new(-v.sin() * u.cos(), -v.sin() * u.sin(), v.cos()) * v.cos()
}

fn torus_laplacian(x: &Vector3<f64>) -> f64 {
    let (_, v) = torus_angles(x);
    let rho = 2.0 + v.cos();
    -v.sin() * (v.cos() + rho) / rho
}

/// `+1` when the faces of `surface` turn counter-clockwise about `outward`, else `−1`: the
/// sign of `J` in R³.
fn orientation(surface: &Surface, outward: impl Fn(&Vector3<f64>) -> Vector3<f64>) -> f64 {
    let [a, b, c] = surface.faces[0].map(|i| surface.positions[i as usize]);
    (b - a).cross(&(c - a)).dot(&outward(&a)).signum()
}

/// On regular torus grids (no seams) the weak vertex form converges at second order in L²,
/// the face values at first order; for `J∇f` divergence and curl trade places.
#[test]
fn divergence_and_curl_converge_on_the_torus() {
    let (mut face, mut vertex, mut zero) = (vec![], vec![], vec![]);
    let mut rotated_vertex = vec![];
    for n in [12, 24, 48, 96] {
        let surface = torus(2.0, 1.0, 2 * n, n);
        let sign = orientation(&surface, torus_normal);
        let sequence = still(&surface);
        let rotated = |x: &Vector3<f64>| torus_normal(x).cross(&torus_gradient(x)) * sign;
        let a = analysis(&sequence, vertex_field(&sequence, torus_gradient));
        let b = analysis(&sequence, vertex_field(&sequence, rotated));
        let areas = face_areas(&sequence);
        // Face values against the Laplacian at the centroid's closest torus point.
        let exact_faces: Vec<f64> = centroids(&surface).iter().map(torus_laplacian).collect();
        let exact_vertices: Vec<f64> = surface.positions.iter().map(torus_laplacian).collect();
        let ones = vec![1.0; exact_vertices.len()];
        face.push(relative_error(&a.face_divergence, &exact_faces, &areas));
        vertex.push(relative_error(&a.vertex_divergence, &exact_vertices, &ones));
        rotated_vertex.push(relative_error(&b.vertex_curl, &exact_vertices, &ones));
        let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        let size = rms(&exact_vertices);
        let rms = |x: &[f64]| rms(x) / size;
        zero.push(rms(&a.vertex_curl).max(rms(&b.vertex_divergence)));
    }
    println!("torus: face {face:.3?} orders {:.2?}", orders(&face));
    println!("  vertex {vertex:.3?} orders {:.2?}", orders(&vertex));
    println!(
        "  J∇f: vertex curl {rotated_vertex:.3?} orders {:.2?}",
        orders(&rotated_vertex)
    );
    println!("  zero parts {zero:.3?} orders {:.2?}", orders(&zero));
    assert!(orders(&face).iter().all(|&p| p > 0.9), "{face:?}");
    assert!(orders(&vertex).iter().all(|&p| p > 1.9), "{vertex:?}");
    assert!(
        orders(&rotated_vertex).iter().all(|&p| p > 1.9),
        "{rotated_vertex:?}"
    );
    assert!(orders(&zero).iter().all(|&p| p > 1.85), "{zero:?}");
}

/// A seeded pseudo-random tangent field (vertex frames), for the algebraic checks.
fn random_field(n: usize, seed: u64) -> Vec<Vector2<f64>> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..n).map(|_| Vector2::new(next(), next())).collect()
}

/// The three parts are L²-orthogonal to round-off and add up to the field exactly, on a
/// sphere, a torus and a patch with boundary (where `ψ = 0` on the boundary edges).
#[test]
fn hodge_parts_are_orthogonal_and_add_up() {
    let surfaces = [
        ("sphere", icosphere(3)),
        ("torus", torus(2.0, 1.0, 24, 12)),
        ("patch", meshflow::shapes::grid(9, 7, 3.0, 2.0)),
    ];
    for (name, surface) in surfaces {
        let sequence = still(&surface);
        let geometry = sequence.slab_geometry(0).unwrap();
        let a = analysis(&sequence, random_field(surface.positions.len(), 7));
        let h = &a.hodge;
        let dot = |x: &[Vector2<f64>], y: &[Vector2<f64>]| hodge::inner_product(&geometry, x, y);
        let norm = dot(&h.field, &h.field);
        let products = [
            dot(&h.exact, &h.coexact),
            dot(&h.exact, &h.harmonic),
            dot(&h.coexact, &h.harmonic),
        ];
        println!("{name}: |U|² {norm:.3e}, cross products {products:.3?}");
        assert!(
            products.iter().all(|p| p.abs() < 1e-12 * norm),
            "{name}: {products:?}"
        );
        for f in 0..h.field.len() {
            let sum = h.exact[f] + h.coexact[f] + h.harmonic[f];
            assert!((sum - h.field[f]).norm() <= 1e-15 * h.field[f].norm().max(1.0));
        }
        let energies = a.totals.exact_energy + a.totals.coexact_energy + a.totals.harmonic_energy;
        assert!(
            (energies - a.totals.energy).abs() < 1e-11 * norm,
            "{name}: Pythagoras"
        );
        let mesh = sequence.mesh();
        for h_edge in (0..mesh.n_halfedges()).filter(|&e| mesh.is_boundary_halfedge(e)) {
            assert_eq!(
                h.stream[mesh.halfedge_edge(h_edge)],
                0.0,
                "{name}: ψ on the boundary"
            );
        }
    }
}

/// The harmonic part vanishes on the sphere (genus 0) and spans exactly two dimensions on the
/// torus (genus 1): fields decomposed one after another leave harmonic parts of rank 2.
#[test]
fn harmonic_space_has_the_dimension_of_the_topology() {
    let sphere = icosphere(3);
    let sequence = still(&sphere);
    let a = analysis(&sequence, random_field(sphere.positions.len(), 3));
    let size = a.totals.energy;
    println!(
        "sphere: harmonic energy {:.2e} of {size:.2e}",
        a.totals.harmonic_energy
    );
    assert!(
        a.totals.harmonic_energy < 1e-24 * size.max(1.0),
        "{}",
        a.totals.harmonic_energy
    );

    let ring = torus(2.0, 1.0, 24, 12);
    let sequence = still(&ring);
    let geometry = sequence.slab_geometry(0).unwrap();
    let columns: Vec<nalgebra::DVector<f64>> = (0..6)
        .map(|seed| {
            let a = analysis(&sequence, random_field(ring.positions.len(), seed));
            let weighted = a
                .hodge
                .harmonic
                .iter()
                .zip(geometry.triangles())
                .flat_map(|(h, t)| [h.x * t.area.sqrt(), h.y * t.area.sqrt()]);
            nalgebra::DVector::from_iterator(2 * ring.faces.len(), weighted)
        })
        .collect();
    let singular = nalgebra::DMatrix::from_columns(&columns).singular_values();
    let mut values: Vec<f64> = singular.iter().copied().collect();
    values.sort_by(|a, b| b.total_cmp(a));
    println!("torus: harmonic singular values {values:.3?}");
    assert!(values[1] > 1e-2 * values[0], "{values:?}");
    assert!(values[2] < 1e-10 * values[0], "{values:?}");
}

/// A mixture `∇Y₁ + J∇Y₂` on the sphere decomposes back into its parts, at first order.
#[test]
fn a_mixture_decomposes_into_its_parts() {
    let y1_gradient = grad_y2;
    let y2_gradient = |x: &Vector3<f64>| {
        // Y₂ = x z.
        let n = x.normalize();
        let g = Vector3::new(x.z, 0.0, x.x);
        g - n * n.dot(&g)
    };
    let mut errors = vec![];
    for level in 2..=5 {
        let surface = icosphere(level);
        let sequence = still(&surface);
        let mixture = |x: &Vector3<f64>| y1_gradient(x) + turned(x, y2_gradient(x));
        let a = analysis(&sequence, vertex_field(&sequence, mixture));
        let maps = face_frames(&sequence, 0).unwrap().unwrap();
        let areas = face_areas(&sequence);
        let error = |part: &[Vector2<f64>], truth: &dyn Fn(&Vector3<f64>) -> Vector3<f64>| {
            let (mut e, mut n) = (0.0, 0.0);
            for ((m, p), (c, w)) in maps
                .iter()
                .zip(part)
                .zip(centroids(&surface).iter().zip(&areas))
            {
                let t = truth(&c.normalize());
                e += w * (m * p - t).norm_squared();
                n += w * t.norm_squared();
            }
            (e / n).sqrt()
        };
        let exact = error(&a.hodge.exact, &y1_gradient);
        let coexact = error(&a.hodge.coexact, &|x| turned(x, y2_gradient(x)));
        errors.push(exact.max(coexact));
        let harmonic = a.totals.harmonic_energy / a.totals.energy;
        assert!(harmonic < 1e-20, "level {level}: {harmonic}");
    }
    println!(
        "mixture: part errors {errors:.3?} orders {:.2?}",
        orders(&errors)
    );
    assert!(orders(&errors).iter().all(|&p| p > 0.9), "{errors:?}");
    assert!(errors[3] < 0.02, "{errors:?}");
}

/// A texture turning rigidly on a still sphere (the Killing field `ω × x`) has no strain rate:
/// the face values go to zero at first order.
#[test]
fn a_rigid_rotation_of_the_texture_has_no_strain_rate() {
    let omega = Vector3::new(0.3, -0.2, 1.0);
    let mut largest = vec![];
    for level in 2..=5 {
        let surface = icosphere(level);
        let sequence = still(&surface);
        let a = analysis(&sequence, vertex_field(&sequence, |x| omega.cross(x)));
        let worst = a.strain.iter().map(|d| d.tensor.norm()).fold(0.0, f64::max);
        largest.push(worst / omega.norm());
    }
    println!(
        "Killing field: largest |D| / |ω| {largest:.3?} orders {:.2?}",
        orders(&largest)
    );
    assert!(orders(&largest).iter().all(|&p| p > 0.9), "{largest:?}");
    assert!(largest[3] < 0.02, "{largest:?}");
}

/// A sphere growing from radius 1 to 1.1 in half a unit of time, carrying its texture (flow
/// zero): areal rate `2ṙ/r̄` on every face (`r̄` the slab's mean radius), no shear.
#[test]
fn a_growing_sphere_has_areal_rate_two_rdot_over_r() {
    let surface = icosphere(3);
    let (r0, r1, dt) = (1.0, 1.1, 0.5);
    let frames = [r0, r1]
        .map(|r| surface.positions.iter().map(|x| x * r).collect())
        .to_vec();
    let sequence = sequence(&surface, frames, vec![0.0, dt]);
    let a = analysis(&sequence, vec![Vector2::zeros(); surface.positions.len()]);
    let expected = 2.0 * ((r1 - r0) / dt) / (0.5 * (r0 + r1));
    for d in &a.strain {
        assert!(
            (d.areal - expected).abs() < 1e-12 * expected,
            "{} vs {expected}",
            d.areal
        );
        assert!(d.shear < 1e-12 * expected, "{}", d.shear);
    }
    assert!((a.totals.mean_areal_rate - expected).abs() < 1e-12 * expected);
}

/// A sphere stretched along z (`x ↦ diag(1, 1, 1 + εt) x`, flow zero): the rate of deformation
/// is the tangential part of `diag(0, 0, ε)`, with principal rates `ε (1 − n_z²)` along the
/// meridian and 0 along the parallel.
#[test]
fn a_stretched_sphere_has_the_analytic_principal_rates() {
    let surface = icosphere(4);
    let epsilon = 1e-3;
    let stretched: Vec<Vector3<f64>> = (surface.positions.iter())
        .map(|x| Vector3::new(x.x, x.y, x.z * (1.0 + epsilon)))
        .collect();
    let sequence = sequence(
        &surface,
        vec![surface.positions.clone(), stretched],
        vec![0.0, 1.0],
    );
    let a = analysis(&sequence, vec![Vector2::zeros(); surface.positions.len()]);
    let maps = face_frames(&sequence, 0).unwrap().unwrap();
    let mut worst: f64 = 0.0;
    for ((d, c), m) in a.strain.iter().zip(centroids(&surface)).zip(&maps) {
        let n = c.normalize();
        let expected = epsilon * (1.0 - n.z * n.z);
        worst = worst
            .max((d.principal[0] - expected).abs())
            .max(d.principal[1].abs())
            .max((d.areal - expected).abs());
        // The stretching direction is the meridian, where the two rates differ.
        if expected > 0.2 * epsilon {
            let meridian = (Vector3::z() - n * n.z).normalize();
            let direction = (m * d.directions[0]).normalize();
            assert!(
                direction.dot(&meridian).abs() > 0.99,
                "{direction} vs {meridian}"
            );
        }
    }
    println!(
        "stretched sphere: worst principal-rate error {:.2e} of ε",
        worst / epsilon
    );
    assert!(worst < 0.03 * epsilon, "{worst}");
}

/// Moving the whole sequence rigidly (rotation and translation) changes no analysed number.
#[test]
fn the_analysis_is_invariant_under_rigid_motions() {
    let surface = icosphere(3);
    let frames: Vec<Vec<Vector3<f64>>> = (0..3)
        .map(|k| {
            let t = k as f64;
            (surface.positions.iter())
                .map(|x| Vector3::new(x.x * (1.0 + 0.1 * t * x.z), x.y, x.z * (1.0 + 0.05 * t)))
                .collect()
        })
        .collect();
    let motion = Rotation3::from_euler_angles(0.3, -1.1, 2.0);
    let shift = Vector3::new(5.0, -2.0, 0.5);
    let moved: Vec<Vec<Vector3<f64>>> = (frames.iter())
        .map(|f| f.iter().map(|x| motion * x + shift).collect())
        .collect();
    let times = vec![0.0, 0.5, 1.25];
    let (plain, turned) = (
        sequence(&surface, frames, times.clone()),
        sequence(&surface, moved, times),
    );
    let flows: Vec<Vec<Vector2<f64>>> = (0..2)
        .map(|s| random_field(surface.positions.len(), s))
        .collect();
    let (a, b) = (
        analyze_flow(&plain, &flows).unwrap(),
        analyze_flow(&turned, &flows).unwrap(),
    );
    let close = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(p, q)| (p - q).abs() < 1e-9);
    for (x, y) in a.iter().zip(&b) {
        assert!(close(&x.face_divergence, &y.face_divergence));
        assert!(close(&x.vertex_curl, &y.vertex_curl));
        let areal = |s: &SlabAnalysis| s.strain.iter().map(|d| d.areal).collect::<Vec<_>>();
        let shear = |s: &SlabAnalysis| s.strain.iter().map(|d| d.shear).collect::<Vec<_>>();
        assert!(close(&areal(x), &areal(y)) && close(&shear(x), &shear(y)));
        assert!(close(&x.hodge.potential, &y.hodge.potential));
        assert!((x.totals.harmonic_energy - y.totals.harmonic_energy).abs() < 1e-9);
    }
}

/// A 12 × 10 grid with the faces of the cells `holes` removed: one boundary loop more per hole.
fn holed_patch(holes: &[(usize, usize)]) -> Surface {
    let mut patch = meshflow::shapes::grid(12, 10, 3.0, 2.5);
    // grid lists cell (i, j)'s two faces at 2 (i · 10 + j).
    let removed: Vec<usize> = holes.iter().map(|&(i, j)| 2 * (i * 10 + j)).collect();
    patch.faces = (patch.faces.iter().enumerate())
        .filter(|(f, _)| !removed.contains(&(f - f % 2)))
        .map(|(_, face)| *face)
        .collect();
    patch
}

/// The tree–cotree generators number dim H¹ (`2g` closed, `2g + b − 1` with boundary), their
/// forms are closed (every face's signed sum is 0) and not exact (each carries harmonic
/// energy: the Gram matrix of their harmonic parts is positive definite, else the
/// decomposition would fail below).
#[test]
fn tree_cotree_generators_span_the_first_cohomology() {
    use meshflow::mesh::{halfedge_sign, Mesh, TreeCotree};
    let sphere = icosphere(2);
    let ring = torus(2.0, 1.0, 12, 8);
    let n = ring.positions.len() as u32;
    // A torus and a sphere as one mesh: two components.
    let mut both = ring.faces.clone();
    both.extend(sphere.faces.iter().map(|f| f.map(|v| v + n)));
    let two = Mesh::new(ring.positions.len() + sphere.positions.len(), both).unwrap();
    let cases = [
        ("sphere", sphere.mesh().unwrap(), 0),
        ("torus", ring.mesh().unwrap(), 2),
        ("torus + sphere", two, 2),
        ("disk", holed_patch(&[]).mesh().unwrap(), 0),
        ("annulus", holed_patch(&[(5, 5)]).mesh().unwrap(), 1),
        (
            "three holes",
            holed_patch(&[(2, 2), (5, 7), (9, 4)]).mesh().unwrap(),
            3,
        ),
    ];
    for (name, mesh, dimension) in cases {
        let tree_cotree = TreeCotree::new(&mesh);
        assert_eq!(tree_cotree.n_generators(), dimension, "{name}");
        for form in tree_cotree.closed_forms(&mesh) {
            assert!(form.iter().any(|&w| w != 0.0), "{name}");
            for f in 0..mesh.n_faces() {
                let sum: f64 = (3 * f..3 * f + 3)
                    .map(|h| halfedge_sign(&mesh, h) * form[mesh.halfedge_edge(h)])
                    .sum();
                assert_eq!(sum, 0.0, "{name}: face {f}");
            }
        }
    }
}

/// The co-exact potential integrated from `U − ∇φ − h` equals the Crouzeix–Raviart solve's
/// (Polthier & Preuss' direct route), on a torus (two generators), a patch with three holes and
/// a sphere.
#[test]
fn integrated_and_solved_stream_functions_agree() {
    let surfaces = [
        ("torus", torus(2.0, 1.0, 24, 12)),
        ("three holes", holed_patch(&[(2, 2), (5, 7), (9, 4)])),
        ("sphere", icosphere(3)),
    ];
    for (name, surface) in surfaces {
        let sequence = still(&surface);
        let mesh = sequence.mesh();
        let geometry = sequence.slab_geometry(0).unwrap();
        let field = random_field(mesh.n_faces(), 11);
        let integrated = hodge::HodgeSolver::new(mesh)
            .decompose(mesh, &geometry, field.clone())
            .unwrap();
        let solved = hodge::HodgeSolver::with_generator_limit(mesh, 0)
            .decompose(mesh, &geometry, field)
            .unwrap();
        let size = hodge::inner_product(&geometry, &solved.field, &solved.field).sqrt();
        for (part, a, b) in [
            ("exact", &integrated.exact, &solved.exact),
            ("co-exact", &integrated.coexact, &solved.coexact),
            ("harmonic", &integrated.harmonic, &solved.harmonic),
        ] {
            let d: Vec<Vector2<f64>> = a.iter().zip(b).map(|(a, b)| a - b).collect();
            let difference = hodge::inner_product(&geometry, &d, &d).sqrt();
            println!(
                "{name}: {part} parts differ by {:.1e} of |U|",
                difference / size
            );
            assert!(difference < 1e-9 * size, "{name}: {part}");
        }
        let scale = solved.stream.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let worst = (integrated.stream.iter().zip(&solved.stream))
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(worst < 1e-9 * scale, "{name}: ψ differs by {worst:.1e}");
    }
}
