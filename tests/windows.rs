//! Time windows (`meshflow::flow::window`): the slabs `[a, b)` assembled from the frames
//! `a − 1 … b + 1` alone, with the scales summed over all windows, equal the same slabs of the
//! whole problem — blocks, links to the slabs beyond, right-hand side and energy constant —
//! for every split into 1 to 4 windows, both time couplings and Dirichlet boundaries. This is
//! what each rank of a solve distributed over time assembles (`docs/scaling.md`).

use meshflow::flow::window::{TimeWindow, WindowSlabs};
use meshflow::flow::{
    FlowParams, FlowProblem, LinkMatrix, MeshSequence, ScaleSums, SpaceTimeSystem, SystemWindow,
};

mod common;

fn pseudo_random(n: usize, seed: f64) -> Vec<f64> {
    (0..n).map(|i| (seed * (i as f64 + 1.0)).sin()).collect()
}

fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
    let norm = b
        .iter()
        .map(|x| x * x)
        .sum::<f64>()
        .sqrt()
        .max(f64::MIN_POSITIVE);
    let diff = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt();
    diff / norm
}

/// `A x` of a window system, and `X x` of a boundary link, compared as operators.
fn product(system: &SpaceTimeSystem, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    system.apply(x, &mut y);
    y
}

/// `(X x, Xᵀ x)` of a boundary link.
fn link_product(link: &LinkMatrix, system: &SpaceTimeSystem, x: &[f64]) -> Vec<f64> {
    let (mut y, mut z) = (vec![0.0; x.len()], vec![0.0; x.len()]);
    link.mul(system.pattern(), x, &mut y);
    link.transpose_mul(system.pattern(), x, &mut z);
    [y, z].concat()
}

fn assert_same_window(name: &str, window: &SystemWindow, whole: &SystemWindow) {
    let (w, s) = (&window.system, &whole.system);
    assert_eq!(w.n_slabs(), s.n_slabs(), "{name}");
    assert_eq!(window.slabs, whole.slabs, "{name}");
    assert_eq!(window.n_slabs_in_all, whole.n_slabs_in_all, "{name}");
    let x = pseudo_random(s.dimension(), 0.37);
    let differences = [
        relative_difference(&product(w, &x), &product(s, &x)),
        relative_difference(w.rhs(), s.rhs()),
        (w.constant() - s.constant()).abs() / s.constant().abs().max(1e-300),
    ];
    assert!(
        differences.iter().all(|d| *d < 1e-12),
        "{name}: {differences:?}"
    );
    let n = s.slab_dimension();
    for (mine, theirs) in [
        (&window.link_before, &whole.link_before),
        (&window.link_after, &whole.link_after),
    ] {
        match (mine, theirs) {
            (None, None) => {}
            (Some(a), Some(b)) => {
                let x = pseudo_random(n, 0.11);
                let d = relative_difference(&link_product(a, s, &x), &link_product(b, s, &x));
                assert!(d < 1e-12, "{name}: boundary link differs by {d:.1e}");
            }
            _ => panic!("{name}: a boundary link is missing"),
        }
    }
}

fn check_windows(name: &str, sequence: &MeshSequence, params: &FlowParams) {
    let whole = FlowProblem::new(sequence, params).unwrap();
    let n_slabs = sequence.n_slabs();
    for parts in 1..=4 {
        let windows: Vec<_> = (0..parts)
            .map(|r| TimeWindow::of_rank(r, parts, n_slabs))
            .collect();
        let built: Vec<(MeshSequence, WindowSlabs)> = (windows.iter())
            .map(|window| {
                let frames = window.frames();
                let local = sequence.frames(frames.clone()).unwrap();
                let slabs = WindowSlabs::new(&local, frames.start, window.clone(), params).unwrap();
                (local, slabs)
            })
            .collect();
        let sums = (built.iter())
            .map(|(local, slabs)| slabs.scale_sums(local))
            .fold(ScaleSums::default(), |all, window| all + window);
        let scales = sums.scales();
        let expected = whole.scales();
        for (got, want) in [
            (scales.gradient, expected.gradient),
            (scales.edge_length, expected.edge_length),
            (scales.frame_spacing, expected.frame_spacing),
        ] {
            assert!(
                (got - want).abs() <= 1e-13 * want.abs(),
                "{name}, {parts} windows: scales"
            );
        }
        for (window, (local, slabs)) in windows.iter().zip(&built) {
            let assembled = slabs.assemble(local, params, &scales).unwrap();
            let label = format!("{name}, {parts} windows, slabs {:?}", window.slabs);
            let expected = whole.system().window(window.slabs.clone());
            assert_same_window(&label, &assembled, &expected);
        }
    }
}

#[test]
fn windows_assemble_the_slabs_of_the_whole_problem() {
    for (name, sequence, params) in common::window_cases() {
        check_windows(&name, &sequence, &params);
    }
}

/// The anisotropic regularizer's tensors come from each slab's own images: a window's are the
/// whole problem's.
#[test]
fn windows_assemble_the_anisotropic_slabs_of_the_whole_problem() {
    let (name, sequence, params) = common::window_cases().remove(0);
    let params = FlowParams {
        anisotropy: Some(meshflow::flow::Anisotropy::new(0.3)),
        ..params
    };
    check_windows(&format!("{name}, anisotropic"), &sequence, &params);
}

/// A window's frames reach one slab beyond each end, clipped at the sequence's ends.
#[test]
fn window_frames_reach_one_slab_beyond_each_end() {
    let frames = |slabs| {
        TimeWindow {
            slabs,
            n_slabs_in_all: 9,
        }
        .frames()
    };
    assert_eq!(frames(0..3), 0..5);
    assert_eq!(frames(3..6), 2..8);
    assert_eq!(frames(6..9), 5..10);
    assert_eq!(frames(0..9), 0..10);
    assert_eq!(TimeWindow::of_rank(2, 3, 9).slabs, 6..9);
}
