//! The solve over time windows held by separate ranks (`meshflow::flow::distributed`), with
//! threads standing in for the ranks: for 1 to 4 ranks the solution equals the single
//! process's (`pcg-slab-gauss-seidel`, the same odd–even preconditioner) to 1e-10 and takes the
//! same number of iterations, with lumped and consistent coupling and Dirichlet boundaries.
//! Each rank assembles only its window, from its frames, with the scales summed over ranks.

use meshflow::flow::distributed::{solve_window, TimeRanks};
use meshflow::flow::window::{flow_over_ranks, TimeWindow, WindowSlabs};
use meshflow::flow::{FlowParams, FlowProblem, FlowResult, MeshSequence, ScaleSums, SolverChoice};
use meshflow::flow::{Scale, Warping};
use nalgebra::Vector3;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Barrier, Mutex};

mod common;

/// What the threads share for sums: a barrier and one slot per rank.
struct Shared {
    barrier: Barrier,
    sums: Mutex<Vec<Vec<f64>>>,
}

/// A rank played by a thread: sums through `Shared`, messages through one channel per
/// ordered pair of ranks (unbounded: sends never block, unlike MPI's, so the tests of message
/// order are the `mpirun` ones in `tests/mpi.rs`).
struct ThreadRank {
    rank: usize,
    size: usize,
    shared: Arc<Shared>,
    to: Vec<Sender<Vec<f64>>>,
    from: Vec<Receiver<Vec<f64>>>,
}

/// `size` ranks wired to each other.
fn thread_ranks(size: usize) -> Vec<ThreadRank> {
    let shared = Arc::new(Shared {
        barrier: Barrier::new(size),
        sums: Mutex::new(vec![Vec::new(); size]),
    });
    let mut senders: Vec<Vec<Sender<Vec<f64>>>> = (0..size).map(|_| Vec::new()).collect();
    let mut receivers: Vec<Vec<Receiver<Vec<f64>>>> = (0..size).map(|_| Vec::new()).collect();
    for to_all in senders.iter_mut() {
        for inbox in receivers.iter_mut() {
            let (sender, receiver) = channel();
            to_all.push(sender);
            inbox.push(receiver);
        }
    }
    (senders.into_iter().zip(receivers).enumerate())
        .map(|(rank, (to, from))| ThreadRank {
            rank,
            size,
            shared: shared.clone(),
            to,
            from,
        })
        .collect()
}

impl TimeRanks for ThreadRank {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn sum(&self, values: &mut [f64]) {
        self.shared.sums.lock().unwrap()[self.rank] = values.to_vec();
        self.shared.barrier.wait();
        let all = self.shared.sums.lock().unwrap().clone();
        self.shared.barrier.wait();
        for (k, v) in values.iter_mut().enumerate() {
            *v = all.iter().map(|rank| rank[k]).sum();
        }
    }

    fn send(&self, to: usize, values: &[f64]) {
        self.to[to].send(values.to_vec()).unwrap();
    }

    fn receive(&self, from: usize) -> Vec<f64> {
        self.from[from].recv().unwrap()
    }
}

/// Rank `rank` of `size`: its window's slabs `[a, b)` from its frames alone, the scales summed
/// over ranks, the solve; returns its unknowns and the iterations.
fn rank_solve(
    sequence: &MeshSequence,
    params: &FlowParams,
    rank: ThreadRank,
    window: TimeWindow,
) -> (Vec<f64>, usize) {
    let frames = window.frames();
    let local = sequence.frames(frames.clone()).unwrap();
    let slabs = WindowSlabs::new(&local, frames.start, window, params).unwrap();
    let mut sums = slabs.scale_sums(&local).to_array();
    rank.sum(&mut sums);
    let scales = ScaleSums::from_array(sums).scales();
    let system = slabs.assemble(&local, params, &scales).unwrap();
    let solution = solve_window(&system, &rank, params, None, &|_| {}).unwrap();
    (solution.u, solution.iterations)
}

/// Solves with `solver` in one process and over 1 to 8 ranks (at most one per slab): the same
/// solution to 1e-10 and the same iterations (±1, the dot products summed in another order).
fn check(name: &str, sequence: &MeshSequence, params: &FlowParams, solver: SolverChoice) {
    let params = FlowParams {
        solver,
        tolerance: 1e-12,
        direct_limit: 0,
        ..params.clone()
    };
    let single = FlowProblem::new(sequence, &params)
        .unwrap()
        .solve(&|_| {})
        .unwrap();
    let expected: Vec<f64> = (single.intrinsic.iter().flatten())
        .flat_map(|v| [v.x, v.y])
        .collect();
    let n_slabs = sequence.n_slabs();
    for size in 1..=n_slabs.min(8) {
        let results: Vec<(Vec<f64>, usize)> = std::thread::scope(|scope| {
            let handles: Vec<_> = (thread_ranks(size).into_iter())
                .map(|me| {
                    let window = TimeWindow::of_rank(me.rank, size, n_slabs);
                    let params = &params;
                    scope.spawn(move || rank_solve(sequence, params, me, window))
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let u: Vec<f64> = results.iter().flat_map(|(u, _)| u.clone()).collect();
        let norm = expected.iter().map(|x| x * x).sum::<f64>().sqrt();
        let difference = (u.iter().zip(&expected))
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt()
            / norm;
        let iterations: Vec<usize> = results.iter().map(|(_, i)| *i).collect();
        println!(
            "{name}, {solver:?}, {size} ranks: iterations {iterations:?} (one process {}, {}), \
             difference {difference:.1e}",
            single.iterations, single.method
        );
        assert!(difference < 1e-10, "{name}, {size} ranks: {difference:e}");
        assert!(iterations.iter().all(|&i| i == iterations[0]), "{name}");
        assert!(
            iterations[0].abs_diff(single.iterations) <= 1,
            "{name}, {size} ranks"
        );
    }
}

#[test]
fn ranks_sweep_as_one_process_does() {
    for (name, sequence, params) in common::window_cases() {
        check(&name, &sequence, &params, SolverChoice::PcgSlabGaussSeidel);
    }
}

/// The coarse levels pair slabs across windows and gather onto fewer ranks; the V-cycle is
/// the single process's, so are the iterations.
#[test]
fn ranks_run_the_multigrid_in_time_as_one_process_does() {
    for (name, sequence, params) in common::window_cases() {
        check(&name, &sequence, &params, SolverChoice::PcgTimeMultigrid);
    }
}

/// The whole computation over ranks (`flow_over_ranks`: windows, scales, solve, energy, flow in
/// R^3 gathered on rank 0) gives the single process's `FlowResult`: flow, vectors, energy terms
/// and weights to 1e-10 relative, with 1 to 4 ranks.
#[test]
fn ranks_compute_the_single_process_flow_result() {
    for (name, sequence, params) in common::window_cases() {
        check_flow_over_ranks(&name, &sequence, &params);
    }
}

/// Coarse-to-fine warping over ranks: each rank warps its own slabs between the collective
/// solves, and the result (with the warped residual) is the single process's.
#[test]
fn ranks_warp_coarse_to_fine_as_one_process_does() {
    let warping = Warping {
        levels: 2,
        warps: 2,
    };
    for (name, sequence, params) in common::window_cases() {
        let params = FlowParams { warping, ..params };
        check_flow_over_ranks(&format!("{name}, warping"), &sequence, &params);
    }
}

/// Robust smoothness over ranks: each rank reweights its own slabs, the robust energy is
/// summed over ranks, so the reweightings stop where one process's do.
#[test]
fn ranks_reweight_robust_smoothness_as_one_process_does() {
    let (name, sequence, params) = common::window_cases().remove(0);
    let params = FlowParams {
        robust_smoothness: Some(Scale::Value(0.05)),
        ..params
    };
    check_flow_over_ranks(&format!("{name}, robust"), &sequence, &params);
    let params = FlowParams {
        warping: Warping {
            levels: 2,
            warps: 1,
        },
        ..params
    };
    check_flow_over_ranks(&format!("{name}, robust, warping"), &sequence, &params);
}

/// The anisotropic regularizer over ranks, with robust smoothness and warping, and image- and
/// flow-driven: each rank computes its own (warped) slabs' tensors, and the reweighting reads
/// them.
#[test]
fn ranks_solve_anisotropic_robust_warped_as_one_process_does() {
    let (name, sequence, params) = common::window_cases().remove(0);
    let params = FlowParams {
        anisotropy: Some(meshflow::flow::Anisotropy::new(0.3)),
        robust_smoothness: Some(Scale::Value(0.05)),
        warping: Warping {
            levels: 2,
            warps: 1,
        },
        ..params
    };
    check_flow_over_ranks(
        &format!("{name}, anisotropic, robust, warping"),
        &sequence,
        &params,
    );
    // Image- and flow-driven, with the tensor's weight in time: each rank lags its own
    // slabs' tensors, and the links to a neighbour's slab read that slab's structure.
    let params = FlowParams {
        anisotropy: Some(meshflow::flow::Anisotropy {
            in_time: true,
            ..meshflow::flow::Anisotropy::new(0.3)
        }),
        flow_driven: meshflow::flow::FlowDriven::Anisotropic,
        warping: Warping::NONE,
        ..params
    };
    check_flow_over_ranks(
        &format!("{name}, image- and flow-driven"),
        &sequence,
        &params,
    );
}

/// `flow_over_ranks` on 1 to 4 thread ranks against `FlowProblem::solve` with the multigrid in
/// time at tolerance 1e-12: the flow, its vectors and warped residual, the energy terms and the
/// weights to 1e-10 relative, the same iterations and reweightings.
fn check_flow_over_ranks(name: &str, sequence: &MeshSequence, params: &FlowParams) {
    let params = FlowParams {
        solver: SolverChoice::PcgTimeMultigrid,
        tolerance: 1e-12,
        ..params.clone()
    };
    let single = FlowProblem::new(sequence, &params)
        .unwrap()
        .solve(&|_| {})
        .unwrap();
    for size in 1..=sequence.n_slabs().min(4) {
        let results: Vec<Option<FlowResult>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (thread_ranks(size).into_iter())
                .map(|me| {
                    let window = TimeWindow::of_rank(me.rank, size, sequence.n_slabs());
                    let frames = sequence.frames(window.frames()).unwrap();
                    let params = &params;
                    scope.spawn(move || {
                        flow_over_ranks(&frames, &window, &me, params, &|_| {}).unwrap()
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert!(results[1..].iter().all(Option::is_none), "{name}");
        let result = results[0].as_ref().unwrap();
        let flat = |r: &FlowResult| -> Vec<f64> {
            let vectors = r.vectors.iter().flatten().flatten();
            (r.intrinsic.iter().flatten().flat_map(|v| [v.x, v.y]))
                .chain(vectors.flat_map(|v| [v.x, v.y, v.z]))
                .collect()
        };
        let (got, want) = (flat(result), flat(&single));
        assert_eq!(got.len(), want.len(), "{name}");
        let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let difference = (got.iter().zip(&want)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let (e, f) = (result.energy_terms, single.energy_terms);
        let energies = [
            (e.data, f.data),
            (e.speed, f.speed),
            (e.spatial, f.spatial),
            (e.temporal, f.temporal),
            (result.energy_at_zero, single.energy_at_zero),
            (result.weights.alpha, single.weights.alpha),
            (result.weights.gamma, single.weights.gamma),
        ];
        println!(
            "{name}, {size} ranks: flow differs by {:.1e}, energy {:.6e} vs {:.6e}, {} iterations in all",
            difference / scale,
            result.energy,
            single.energy,
            result.iterations_in_all(),
        );
        assert!(difference <= 1e-10 * scale, "{name}, {size} ranks");
        for (a, b) in energies {
            assert!(
                (a - b).abs() <= 1e-10 * b.abs().max(1e-300),
                "{name}: {a} vs {b}"
            );
        }
        assert_eq!(result.iterations, single.iterations, "{name}");
        assert_eq!(result.reweightings, single.reweightings, "{name}");
        assert_eq!(
            result.timings.steps.len(),
            single.timings.steps.len(),
            "{name}"
        );
        match (&result.warped_residual, &single.warped_residual) {
            (Some(got), Some(want)) => {
                let (got, want) = (got.concat(), want.concat());
                assert_eq!(got.len(), want.len(), "{name}");
                let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                let difference =
                    (got.iter().zip(&want)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                assert!(
                    difference <= 1e-10 * scale,
                    "{name}: residual {difference:e}"
                );
            }
            (None, None) => {}
            _ => panic!("{name}: warped residual on one side only"),
        }
    }
}

/// How [`write_grid_sequence`] stores the frames.
#[derive(Clone, Copy, Debug)]
enum GridFormat {
    /// `frame_K.obj` with a grey value per vertex.
    Obj,
    /// An NPY directory: positions, faces, grey values, times.
    Npy,
    /// One glTF animation `grid.glb` (morph targets, grey vertex colours).
    Glb,
}

/// Frames `0..6` of a 6 × 5 grid whose middle column is stored twice (a texture seam: the
/// faces right of it use the copies), written in `format` into `dir`; the path to read. With
/// `tear_in_last`, the copies leave the originals in the last frame only. The image moves
/// across the grid (`image_moves`) or is fixed to it.
fn write_grid_sequence(
    dir: &std::path::Path,
    tear_in_last: bool,
    image_moves: bool,
    format: GridFormat,
) -> std::path::PathBuf {
    let (nx, ny, seam) = (6usize, 5usize, 3usize);
    let index = |i: usize, j: usize| (j * nx + i) as u32;
    let copy = |j: usize| (nx * ny + j) as u32;
    let mut faces = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            // Faces right of the seam (i ≥ seam) take its copies.
            let corner = |ci: usize, cj: usize| match ci == seam && i >= seam {
                true => copy(cj),
                false => index(ci, cj),
            };
            faces.push([corner(i, j), corner(i + 1, j), corner(i + 1, j + 1)]);
            faces.push([corner(i, j), corner(i + 1, j + 1), corner(i, j + 1)]);
        }
    }
    let (mut frames, mut all_colors) = (Vec::new(), Vec::new());
    for k in 0..6 {
        let t = k as f64;
        let mut positions: Vec<Vector3<f64>> = (0..ny)
            .flat_map(|j| (0..nx).map(move |i| (i, j)))
            .map(|(i, j)| Vector3::new(i as f64, j as f64, 0.1 * t * (i as f64 * 0.7).sin()))
            .collect();
        let tear = if tear_in_last && k == 5 { 0.5 } else { 0.0 };
        let copies: Vec<_> = (0..ny)
            .map(|j| positions[index(seam, j) as usize] + Vector3::z() * tear)
            .collect();
        positions.extend(copies);
        let shift = if image_moves { 0.3 * t } else { 0.0 };
        let colors: Vec<[f64; 3]> = (positions.iter())
            .map(|p| [((p.x - shift) * 1.3).sin() * 0.4 + 0.5 + 0.05 * p.y; 3])
            .collect();
        frames.push(positions);
        all_colors.push(colors);
    }
    let times = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
    match format {
        GridFormat::Obj => {
            for (k, (positions, colors)) in frames.iter().zip(&all_colors).enumerate() {
                let file = dir.join(format!("frame_{k}.obj"));
                meshflow::io::write_obj(&file, positions, &faces, Some(colors)).unwrap();
            }
            dir.to_path_buf()
        }
        GridFormat::Npy => {
            let greys: Vec<Vec<f64>> = (all_colors.iter())
                .map(|colors| colors.iter().map(|c| c[0]).collect())
                .collect();
            meshflow::io::write_npy_sequence(dir, &frames, &faces, Some(&greys), &times).unwrap();
            dir.to_path_buf()
        }
        GridFormat::Glb => {
            let path = dir.join("grid.glb");
            let animation: Vec<_> = (frames.iter().zip(&all_colors).zip(times))
                .map(
                    |((positions, colors), time)| meshflow::io::gltf_write::AnimationFrame {
                        time,
                        positions,
                        colors,
                    },
                )
                .collect();
            meshflow::io::gltf_write::write_glb_animation(&path, &faces, &animation).unwrap();
            path
        }
    }
}

/// Ranks that read only their windows' frames and frame 0 (OBJ frame files, those rows of NPY
/// arrays, a glTF animation evaluated at those frames) weld as one reader of all frames does, by summing their verdicts on frame 0's coincident pairs: the seam is welded
/// when its copies follow the originals in every frame, and left apart when they leave them
/// in the last frame only, even on ranks whose windows end before it. Positions, image and
/// times are the whole sequence's frames of the window.
#[test]
fn ranks_read_their_windows_and_weld_alike() {
    let formats = [GridFormat::Obj, GridFormat::Npy, GridFormat::Glb];
    for (tear_in_last, format) in formats.iter().flat_map(|&f| [(false, f), (true, f)]) {
        let dir = tempfile::tempdir().unwrap();
        let input = write_grid_sequence(dir.path(), tear_in_last, true, format);
        let options = meshflow::io::LoadOptions::default();
        let whole = meshflow::io::load_sequence(&input, &options).unwrap();
        let welded = whole.vertex_map.n_welded();
        assert_eq!(welded > 0, !tear_in_last, "{format:?}: {welded} welded");
        for size in 1..=3 {
            let loaded: Vec<_> = std::thread::scope(|scope| {
                let handles: Vec<_> = (thread_ranks(size).into_iter())
                    .map(|me| {
                        let window = TimeWindow::of_rank(me.rank, size, 5);
                        let frames = (me.rank > 0).then(|| window.frames());
                        let (path, options) = (&input, &options);
                        scope.spawn(move || {
                            let sum = |v: &mut [f64]| me.sum(v);
                            let loaded = meshflow::io::load_frames(path, options, frames, &sum);
                            (window, loaded.unwrap().sequence)
                        })
                    })
                    .collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            });
            for (rank, (window, sequence)) in loaded.iter().enumerate().skip(1) {
                let expected = whole.sequence.frames(window.frames()).unwrap();
                let name = format!("{format:?}, tear {tear_in_last}, {size} ranks, rank {rank}");
                assert_eq!(sequence.mesh().faces(), expected.mesh().faces(), "{name}");
                assert_eq!(sequence.times(), expected.times(), "{name}");
                for k in 0..sequence.n_frames() {
                    assert_eq!(sequence.positions(k), expected.positions(k), "{name}");
                    assert_eq!(sequence.channels(k), expected.channels(k), "{name}");
                }
            }
        }
        // Alone, a reader of frames 1..4 would weld the torn seam: the sum is what decides.
        let alone = meshflow::io::load_frames(&input, &options, Some(1..4), &|_| {}).unwrap();
        assert!(
            alone.vertex_map.n_welded() > 0,
            "{format:?}, tear {tear_in_last}"
        );
    }
}

/// Ranks that each read only their window and hold only their own slabs write, through rank 0
/// (`io::write_flow_over_ranks`, the slabs streamed to it one by one), byte for byte the files
/// one process writes from the whole result: NPY arrays in the files' numbering (a welded
/// seam), VTU and PVD, and `summary.json` with all frame times, the largest speed and the
/// static-image warning that only a reader of all frames can give. Three channels, with
/// warping (a warped residual per slab).
#[test]
fn ranks_stream_the_files_one_process_writes() {
    use meshflow::io::{Channels, LoadOptions, OutputFormat, Overwrite, Scores, StagedDir};
    let formats = [OutputFormat::Npy, OutputFormat::Vtu];
    let view = meshflow::render::View::default();
    for image_moves in [true, false] {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("input");
        std::fs::create_dir(&input).unwrap();
        write_grid_sequence(&input, false, image_moves, GridFormat::Obj);
        let options = LoadOptions {
            channels: Channels::Rgb,
            ..Default::default()
        };
        let whole = meshflow::io::load_sequence(&input, &options).unwrap();
        assert!(whole.vertex_map.n_welded() > 0);
        let static_warnings = whole.warnings.len();
        assert_eq!(static_warnings, usize::from(!image_moves));
        let params = FlowParams {
            warping: Warping {
                levels: 2,
                warps: 1,
            },
            ..FlowParams::default()
        };
        let result = FlowProblem::new(&whole.sequence, &params)
            .unwrap()
            .solve(&|_| {})
            .unwrap();
        let single = dir.path().join("single");
        let out = StagedDir::create(&single, Overwrite::EarlierRun).unwrap();
        let scores = Scores::default();
        meshflow::io::write_flow_outputs(&out, &whole, &params, &result, &formats, scores, &view)
            .unwrap();
        out.commit().unwrap();
        for size in 1..=3 {
            let streamed = dir.path().join(format!("ranks_{size}"));
            std::thread::scope(|scope| {
                for me in thread_ranks(size) {
                    let window = TimeWindow::of_rank(me.rank, size, 5);
                    let own = own_slabs(&result, &window);
                    let (input, options, params, streamed) = (&input, &options, &params, &streamed);
                    scope.spawn(move || {
                        let frames = Some(window.frames());
                        let sum = |v: &mut [f64]| me.sum(v);
                        let loaded =
                            meshflow::io::load_frames(input, options, frames, &sum).unwrap();
                        if me.rank > 0 {
                            return meshflow::io::send_own_slabs(&loaded, &window, &me, &own);
                        }
                        let out = StagedDir::create(streamed, Overwrite::EarlierRun).unwrap();
                        let written = meshflow::io::write_flow_over_ranks(
                            &out, &loaded, &window, &me, params, &own, &formats, &view,
                        )
                        .unwrap();
                        assert_eq!(written.n_frames, 6);
                        // Rank 0 alone read all frames, and its reader warned.
                        assert_eq!(written.static_image.is_some(), !image_moves && size > 1);
                        out.commit().unwrap();
                    });
                }
            });
            let names = |d: &std::path::Path| {
                let mut names: Vec<_> = (std::fs::read_dir(d).unwrap())
                    .map(|e| e.unwrap().file_name())
                    .collect();
                names.sort();
                names
            };
            assert_eq!(names(&streamed), names(&single), "{size} ranks");
            assert!(names(&single).len() >= 10, "{:?}", names(&single));
            for name in names(&single) {
                let read = |d: &std::path::Path| std::fs::read(d.join(&name)).unwrap();
                let same = read(&streamed) == read(&single);
                assert!(
                    same,
                    "{size} ranks, image moves {image_moves}: {name:?} differs"
                );
            }
        }
    }
}

/// A glTF animation needs every frame at once: streaming it is refused with the file named.
#[test]
fn streaming_refuses_a_gltf_animation() {
    use meshflow::io::{OutputFormat, Overwrite, StagedDir};
    let dir = tempfile::tempdir().unwrap();
    let input = write_grid_sequence(dir.path(), false, true, GridFormat::Obj);
    let loaded = meshflow::io::load_sequence(&input, &Default::default()).unwrap();
    let params = FlowParams::default();
    let result = FlowProblem::new(&loaded.sequence, &params)
        .unwrap()
        .solve(&|_| {})
        .unwrap();
    let out = StagedDir::create(&dir.path().join("out"), Overwrite::EarlierRun).unwrap();
    let me = thread_ranks(1).remove(0);
    let window = TimeWindow::of_rank(0, 1, 5);
    let formats = [OutputFormat::Npy, OutputFormat::Glb];
    let view = meshflow::render::View::default();
    let error = meshflow::io::write_flow_over_ranks(
        &out, &loaded, &window, &me, &params, &result, &formats, &view,
    )
    .unwrap_err()
    .to_string();
    assert!(
        error.contains("flow.glb") && error.contains("all frames"),
        "{error}"
    );
}

/// `result` cut to the slabs of `window`, as the rank holding them computes it.
fn own_slabs(result: &FlowResult, window: &TimeWindow) -> FlowResult {
    let slabs = window.slabs.clone();
    FlowResult {
        intrinsic: result.intrinsic[slabs.clone()].to_vec(),
        vectors: (result.vectors.as_ref()).map(|v| v[slabs.clone()].to_vec()),
        warped_residual: (result.warped_residual.as_ref()).map(|r| r[slabs].to_vec()),
        ..result.clone()
    }
}

/// With `β = 0` a field the image cannot see makes the minimizer not unique: ranks refuse it as
/// one process does ([`FlowError::Singular`], the same message, on every rank), each checking
/// its own slabs and summing what couples them. A flat grid whose image varies along x only in
/// frames 3 and 4: slab 3 alone is blind to `u = ŷ` (frame by frame, the error names it, on
/// whichever rank holds it); coupled in time, the steady field `ŷ` is still seen by the other
/// slabs (unique), and with the image striped in every frame it is not.
#[test]
fn ranks_refuse_a_flow_the_image_cannot_determine_as_one_process_does() {
    use meshflow::flow::{FlowError, Weight};
    let grid = meshflow::shapes::grid(6, 5, 1.0, 1.0);
    let image = |striped: fn(usize) -> bool| {
        common::still_sequence(&grid, 6, move |p, k| {
            let stripes = (4.0 * p.x - 0.2 * k as f64).sin();
            match striped(k) {
                true => stripes,
                false => stripes + 0.3 * (3.0 * p.y).sin(),
            }
        })
    };
    let in_slab_3 = image(|k| matches!(k, 3 | 4));
    let everywhere = image(|_| true);
    for (sequence, alpha, singular) in [
        (&in_slab_3, f64::INFINITY, true),
        (&in_slab_3, 1.0, false),
        (&everywhere, 1.0, true),
    ] {
        let params = FlowParams {
            alpha: Weight::Value(alpha),
            solver: SolverChoice::PcgTimeMultigrid,
            ..FlowParams::default()
        };
        let single = FlowProblem::new(sequence, &params).map(|_| ());
        assert_eq!(single.is_err(), singular, "α {alpha}: {single:?}");
        for size in 1..=3 {
            let results: Vec<Result<(), String>> = std::thread::scope(|scope| {
                let handles: Vec<_> = (thread_ranks(size).into_iter())
                    .map(|me| {
                        let window = TimeWindow::of_rank(me.rank, size, 5);
                        let frames = sequence.frames(window.frames()).unwrap();
                        let params = &params;
                        scope.spawn(move || {
                            flow_over_ranks(&frames, &window, &me, params, &|_| {})
                                .map(|_| ())
                                .map_err(|e| {
                                    assert!(matches!(e, FlowError::Singular { .. }), "{e}");
                                    e.to_string()
                                })
                        })
                    })
                    .collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            });
            let expected = single.as_ref().map_err(ToString::to_string).cloned();
            for result in results {
                assert_eq!(result, expected, "α {alpha}, {size} ranks");
            }
        }
    }
    let frame_by_frame = FlowParams {
        alpha: Weight::Value(f64::INFINITY),
        ..FlowParams::default()
    };
    let message = FlowProblem::new(&in_slab_3, &frame_by_frame)
        .err()
        .unwrap()
        .to_string();
    assert!(message.contains("slab 3 "), "{message}");
}
