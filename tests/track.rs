//! Normal-motion tracking (`meshflow::track`): exact cases on small meshes.

use meshflow::shapes::{grid, icosphere, Surface};
use meshflow::track::{track, FrameSurface, Relaxation, TrackError, TrackFrame, TrackOptions};

/// The paper's normal motion, without the relaxation that follows it by default.
fn normal_motion() -> TrackOptions {
    TrackOptions {
        relaxation: Relaxation::None,
        ..Default::default()
    }
}
use nalgebra::{Rotation3, Vector3};

/// `surface` with its positions mapped by `f` and grey value `grey(x)` at each vertex.
fn frame(
    surface: &Surface,
    f: impl Fn(&Vector3<f64>) -> Vector3<f64>,
    grey: impl Fn(&Vector3<f64>) -> f64,
) -> TrackFrame {
    let positions: Vec<_> = surface.positions.iter().map(f).collect();
    TrackFrame {
        intensity: positions.iter().map(grey).collect(),
        positions,
        faces: surface.faces.clone(),
    }
}

fn linear_grey(x: &Vector3<f64>) -> f64 {
    0.3 + 0.2 * x.x - 0.1 * x.y + 0.05 * x.z
}

/// A sphere scaled radially, each frame meshed differently: vertices move along their normals
/// (within a degree of radial on an icosphere), land on the next frame's surface, and carry
/// that frame's grey values.
#[test]
fn a_radially_scaled_sphere_is_tracked_along_the_normals_onto_each_surface() {
    let coarse = icosphere(2);
    let fine = icosphere(4);
    let turn = Rotation3::from_euler_angles(0.3, 0.2, 0.1);
    let frames = vec![
        frame(&coarse, |x| *x, linear_grey),
        frame(&fine, |x| 1.1 * x, linear_grey),
        frame(&fine, |x| 1.25 * (turn * x), linear_grey),
    ];
    let tracked = track(&frames, None, &normal_motion()).unwrap();
    let sequence = &tracked.sequence;
    for k in 1..3 {
        let surface = FrameSurface::new(
            k,
            &frames[k].positions,
            &frames[k].faces,
            &frames[k].intensity,
        )
        .unwrap();
        let before = sequence.positions(k - 1).unwrap();
        let after = sequence.positions(k).unwrap();
        for (i, (x0, x1)) in before.iter().zip(after).enumerate() {
            let on_surface = (surface.closest_point(x1).position - x1).norm();
            assert!(
                on_surface <= 1e-9 * 2.5,
                "frame {k}, vertex {i}: {on_surface:e} off"
            );
            let angle = (x1 - x0).angle(x0).to_degrees();
            assert!(angle < 1.0, "frame {k}, vertex {i}: {angle}° from radial");
            let grey = sequence.intensities(k)[i];
            assert!(
                (grey - linear_grey(x1)).abs() < 1e-12,
                "grey {grey} at vertex {i}"
            );
        }
        let report = &tracked.report.frames[k];
        assert_eq!((report.misses, report.flipped_triangles), (0, 0));
        // Facets of the finer target lie inside the sphere by at most 1 − cos(edge / 2).
        let radius = [1.0, 1.1, 1.25][k];
        let facet = 0.01 * radius;
        for x in after {
            assert!((x.norm() - radius).abs() < facet, "|x| = {}", x.norm());
        }
    }
    let area_change = tracked.report.frames[2].worst_area_change;
    assert!(
        (area_change - (1.25f64.powi(2) - 1.0)).abs() < 0.05,
        "{area_change}"
    );
}

#[test]
fn identical_frames_give_zero_motion() {
    let sphere = icosphere(3);
    let frames = vec![frame(&sphere, |x| *x, linear_grey); 3];
    let tracked = track(&frames, None, &TrackOptions::default()).unwrap();
    for report in &tracked.report.frames {
        assert!(
            report.max_step < 1e-14,
            "frame {}: {}",
            report.frame,
            report.max_step
        );
    }
    // Relaxation against an identical frame stays put, up to the round-off of its solves.
    for (x, y) in tracked
        .sequence
        .positions(2)
        .unwrap()
        .iter()
        .zip(&sphere.positions)
    {
        assert!((x - y).norm() < 1e-14, "{x:?} moved from {y:?}");
    }
}

/// A plane moving along its normal, remeshed (finer, shifted in its plane, larger): every
/// vertex, boundary ones included, moves by exactly the offset.
#[test]
fn a_plane_moving_along_its_normal_moves_every_vertex_by_the_offset() {
    let patch = grid(6, 5, 1.0, 1.0);
    let larger = grid(13, 11, 2.0, 2.0);
    let offset = Vector3::new(0.0, 0.0, 0.3);
    let frames = vec![
        frame(&patch, |x| *x, linear_grey),
        frame(
            &larger,
            |x| x + offset - Vector3::new(0.47, 0.53, 0.0),
            linear_grey,
        ),
    ];
    let options = TrackOptions {
        max_step: Some(0.5),
        ..normal_motion()
    };
    let tracked = track(&frames, None, &options).unwrap();
    let (before, after) = (
        tracked.sequence.positions(0).unwrap(),
        tracked.sequence.positions(1).unwrap(),
    );
    for (x0, x1) in before.iter().zip(after) {
        assert!((x1 - x0 - offset).norm() < 1e-12, "moved by {:?}", x1 - x0);
    }
    let report = &tracked.report.frames[1];
    assert!((report.mean_step - 0.3).abs() < 1e-12);
    assert!(report.worst_edge_change < 1e-12 && report.worst_area_change < 1e-12);
}

#[test]
fn a_surface_beyond_the_step_bound_is_an_error_naming_frame_and_vertex() {
    let patch = grid(4, 4, 1.0, 1.0);
    let frames = vec![
        frame(&patch, |x| *x, linear_grey),
        frame(&patch, |x| x + Vector3::new(0.0, 0.0, 0.5), linear_grey),
    ];
    let options = TrackOptions {
        max_step: Some(0.2),
        ..Default::default()
    };
    let error = track(&frames, None, &options).err().expect("too far");
    // The whole patch moved as one: the error also says that it looks like a drift.
    let TrackError::AfterWarning { warning, source } = &error else {
        panic!("{error}");
    };
    assert!(warning.contains("frame 1 looks misaligned"), "{warning}");
    assert!(
        matches!(
            **source,
            TrackError::TooFar {
                frame: 1,
                vertex: 0,
                ..
            }
        ),
        "{error}"
    );
    assert!(error.to_string().contains("--max-step"), "{error}");
    let lenient = TrackOptions {
        keep_going: true,
        ..options
    };
    let tracked = track(&frames, None, &lenient).unwrap();
    assert_eq!(
        tracked.report.frames[1].beyond_max_step,
        patch.positions.len()
    );
}

#[test]
fn bad_frames_are_errors_naming_the_frame() {
    let patch = grid(3, 3, 1.0, 1.0);
    let good = frame(&patch, |x| *x, linear_grey);
    let mut nan = good.clone();
    nan.positions[4].y = f64::NAN;
    let empty = TrackFrame {
        faces: Vec::new(),
        ..good.clone()
    };
    let mut out_of_range = good.clone();
    out_of_range.faces[2][1] = 99;
    let cases: [(TrackFrame, &str); 3] = [
        (nan, "frame 1: vertex 4 has a non-finite coordinate"),
        (empty, "frame 1 has no triangles"),
        (out_of_range, "frame 1: face 2 uses vertex 99"),
    ];
    for (bad, message) in cases {
        let error = track(&[good.clone(), bad], None, &TrackOptions::default())
            .err()
            .expect("an error");
        assert!(error.to_string().starts_with(message), "{error}");
    }
    assert!(matches!(
        track(&[], None, &TrackOptions::default()),
        Err(TrackError::NoFrames)
    ));
}

/// The flow of a sequence meshed differently in every frame, tracked, is close to the flow of
/// the same scene with true correspondence (mean angular error against `ω ẑ × x`).
#[test]
fn the_flow_of_a_tracked_remeshed_sphere_is_close_to_the_flow_with_correspondence() {
    use meshflow::accuracy::compare_result;
    use meshflow::flow::{compute_flow, FlowParams};
    use meshflow::synth::{remeshed_pulsating_sphere, turning_flow};
    let scene = remeshed_pulsating_sphere(3, 4, 0.1, 0.5).unwrap();
    let params = FlowParams::default();
    let fixed = compute_flow(&scene.fixed.sequence, &params).unwrap();
    let fixed_error = compare_result(&scene.fixed.sequence, &fixed, &scene.fixed.flow)
        .unwrap()
        .mean_angular_degrees;
    let tracked = track(
        &scene.frames,
        Some(scene.times.clone()),
        &TrackOptions::default(),
    )
    .unwrap();
    let sequence = &tracked.sequence;
    let truth: Vec<_> = (0..sequence.n_slabs())
        .map(|s| turning_flow(scene.omega, sequence.positions(s).unwrap()))
        .collect();
    let result = compute_flow(sequence, &params).unwrap();
    let tracked_error = compare_result(sequence, &result, &truth)
        .unwrap()
        .mean_angular_degrees;
    println!("fixed {fixed_error:.3}°, tracked {tracked_error:.3}°");
    assert!(fixed_error < 5.0, "{fixed_error}");
    assert!(
        tracked_error < 1.25 * fixed_error,
        "{tracked_error} vs {fixed_error}"
    );
}

#[test]
fn a_latitude_longitude_sphere_is_a_closed_outward_oriented_mesh() {
    let sphere = meshflow::shapes::uv_sphere(6, 10);
    let mesh = sphere.mesh().unwrap();
    assert_eq!(
        (mesh.n_vertices(), mesh.n_faces()),
        (2 + 5 * 10, 2 * 6 * 10 - 2 * 10)
    );
    assert_eq!(mesh.euler_characteristic(), 2);
    for face in &sphere.faces {
        let [a, b, c] = face.map(|v| sphere.positions[v as usize]);
        assert!(
            (b - a).cross(&(c - a)).dot(&(a + b + c)) > 0.0,
            "{face:?} points inwards"
        );
    }
}

/// Frame 0 a unit patch in z = 0; frame 1 a large plane through (0.5, 0.5, 0.2) tilted by
/// `tilt` degrees about the y-axis.
fn patch_and_tilted_plane(tilt: f64) -> Vec<TrackFrame> {
    let patch = grid(2, 2, 1.0, 1.0);
    let turn = Rotation3::from_axis_angle(&Vector3::y_axis(), tilt.to_radians());
    let centre = Vector3::new(0.5, 0.5, 0.2);
    let plane = frame(
        &grid(1, 1, 40.0, 40.0),
        |x| centre + turn * (x - Vector3::new(20.0, 20.0, 0.0)),
        linear_grey,
    );
    vec![frame(&patch, |x| *x, linear_grey), plane]
}

/// A surface steeper than `acos(1 / FAR_HIT_RATIO)` ≈ 70.5° against the normal is hit farther
/// than `FAR_HIT_RATIO` times its closest distance: the closest point wins (as for a line that
/// passed the nearby surface by and met another sheet). Less steep, the line's hit stands.
#[test]
fn a_hit_far_beyond_the_closest_distance_gives_way_to_the_closest_point() {
    let options = TrackOptions {
        max_step: Some(10.0),
        ..normal_motion()
    };
    for (tilt, misses) in [(60.0, 0), (80.0, 9)] {
        let frames = patch_and_tilted_plane(tilt);
        let tracked = track(&frames, None, &options).unwrap();
        let report = &tracked.report.frames[1];
        assert_eq!(report.misses, misses, "tilt {tilt}°");
        let normal =
            Rotation3::from_axis_angle(&Vector3::y_axis(), f64::to_radians(tilt)) * Vector3::z();
        for (x0, x1) in frames[0]
            .positions
            .iter()
            .zip(tracked.sequence.positions(1).unwrap())
        {
            let on_plane = (x1 - Vector3::new(0.5, 0.5, 0.2)).dot(&normal);
            assert!(on_plane.abs() < 1e-12, "tilt {tilt}°: {x1:?} off the plane");
            let step = x1 - x0;
            let along = match misses {
                0 => step.cross(&Vector3::z()).norm(),
                _ => step.cross(&normal).norm(),
            };
            assert!(
                along < 1e-9,
                "tilt {tilt}°: step {step:?} not along the right normal"
            );
        }
    }
}

/// An ellipsoid (radii 1, 0.8, 0.6: no rotation leaves it in place), remeshed, turned by 20°
/// and moved between frames: rigid alignment finds the motion, and the tracked mesh, on the
/// aligned frame, stays where it was. Without alignment the drift is reported.
#[test]
fn rigid_alignment_recovers_a_turned_and_moved_remeshed_ellipsoid() {
    use meshflow::track::Alignment;
    let radii = Vector3::new(1.0, 0.8, 0.6);
    let axis = nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8));
    let turn = Rotation3::from_axis_angle(&axis, 20f64.to_radians());
    let shift = Vector3::new(0.15, -0.1, 0.05);
    let frames = vec![
        frame(&icosphere(3), |x| x.component_mul(&radii), linear_grey),
        frame(
            &icosphere(4),
            |x| turn * x.component_mul(&radii) + shift,
            linear_grey,
        ),
    ];
    let options = TrackOptions {
        alignment: Alignment::Rigid,
        ..Default::default()
    };
    let tracked = track(&frames, None, &options).unwrap();
    let alignment = tracked.report.frames[1].alignment.clone().unwrap();
    assert!(alignment.applied);
    assert!(
        (alignment.rotation_degrees - 20.0).abs() < 0.2,
        "{alignment:?}"
    );
    assert!(alignment.median_distance_after < 2e-3, "{alignment:?}");
    // The finer frame's facets lie within 1e-3 of the coarse one's vertices.
    let (before, after) = (
        tracked.sequence.positions(0).unwrap(),
        tracked.sequence.positions(1).unwrap(),
    );
    let largest = before
        .iter()
        .zip(after)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(largest < 5e-3, "tracked vertices moved by up to {largest}");
    assert!(
        tracked.report.warnings.is_empty(),
        "{:?}",
        tracked.report.warnings
    );

    let unaligned = track(
        &frames,
        None,
        &TrackOptions {
            keep_going: true,
            ..Default::default()
        },
    );
    let warnings = match unaligned {
        Ok(t) => t.report.warnings,
        Err(e) => vec![e.to_string()],
    };
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("frame 1 looks misaligned") && w.contains("--align rigid")),
        "{warnings:?}"
    );
}

/// A strong bump (curvature radius 0.13 at its top) moving onto a plane 0.6 below its top:
/// normal lines from the top cross before they reach the plane, so normal motion alone folds
/// the mesh, and the folds are smoothed out on the plane; the relaxation keeps every triangle
/// the right way up from the start.
#[test]
fn relaxation_prevents_the_fold_of_normal_steps_beyond_the_radius_of_curvature() {
    let bump = |x: &Vector3<f64>| {
        let r2 = (x.x - 0.5).powi(2) + (x.y - 0.5).powi(2);
        Vector3::new(x.x, x.y, 0.3 * (-r2 / (2.0 * 0.2f64.powi(2))).exp())
    };
    let patch = grid(24, 24, 1.0, 1.0);
    let plane = grid(30, 30, 3.0, 3.0);
    let frames = vec![
        frame(&patch, bump, linear_grey),
        frame(&plane, |x| x - Vector3::new(1.0, 1.0, 0.3), linear_grey),
    ];
    let normal_only = TrackOptions {
        max_step: Some(2.0),
        ..normal_motion()
    };
    let normal = track(&frames, None, &normal_only).unwrap();
    let report = &normal.report.frames[1];
    assert!(report.repaired_folds > 10, "{report:?}");
    assert_eq!(report.flipped_triangles, 0);
    let relaxed = TrackOptions {
        max_step: Some(2.0),
        ..Default::default()
    };
    let tracked = track(&frames, None, &relaxed).unwrap();
    let report = &tracked.report.frames[1];
    assert_eq!((report.flipped_triangles, report.repaired_folds), (0, 0));
    assert_eq!(tracked.report.trimmed_vertices, 0);
    for x in [&normal, &tracked]
        .map(|t| t.sequence.positions(1).unwrap())
        .concat()
    {
        assert!((x.z + 0.3).abs() < 1e-12, "{x:?} off the plane");
    }
    // Flattening the bump stretches the patch by its arc length, not more.
    assert!(report.edge_log_ratio_max < 0.7, "{report:?}");
}

/// A reference simplified to a chosen size: the count within 5 %, a closed manifold sphere,
/// on frame 0's surface, and triangles far from degenerate.
#[test]
fn a_reference_of_a_chosen_size_is_a_clean_mesh_on_frame_0() {
    use meshflow::mesh::Mesh;
    use meshflow::track::simplified_reference;
    let sphere = icosphere(4);
    for target in [300, 1000] {
        let reference = simplified_reference(&sphere.positions, &sphere.faces, target);
        let n = reference.positions.len();
        assert!(
            n.abs_diff(target) * 20 <= target,
            "{n} vertices for {target}"
        );
        let mesh = Mesh::new(n, reference.faces.clone()).unwrap();
        assert!(mesh.is_closed() && mesh.euler_characteristic() == 2);
        let zeros = vec![0.0; sphere.positions.len()];
        let surface = FrameSurface::new(0, &sphere.positions, &sphere.faces, &zeros).unwrap();
        for x in &reference.positions {
            assert!((surface.closest_point(x).position - x).norm() < 1e-12);
        }
        let smallest = reference
            .faces
            .iter()
            .map(|f| {
                let x = f.map(|v| reference.positions[v as usize]);
                (0..3)
                    .map(|c| {
                        (x[(c + 1) % 3] - x[c])
                            .angle(&(x[(c + 2) % 3] - x[c]))
                            .to_degrees()
                    })
                    .fold(180.0, f64::min)
            })
            .fold(180.0, f64::min);
        assert!(smallest > 20.0, "{target}: smallest angle {smallest}°");
    }
    let whole = simplified_reference(&sphere.positions, &sphere.faces, 10_000);
    assert_eq!(whole.positions, sphere.positions, "no refinement");
}

/// A patch whose next frame ends short of it (the field of view shrank): the reference is
/// trimmed to what both frames cover, the trimming is reported, and every tracked vertex is
/// on each frame's surface.
#[test]
fn a_reference_beyond_a_frame_boundary_is_trimmed_to_the_covered_part() {
    let patch = grid(20, 20, 1.0, 1.0);
    let smaller = grid(14, 14, 0.7, 0.7);
    let frames = vec![
        frame(&patch, |x| *x, linear_grey),
        frame(&smaller, |x| x + Vector3::new(0.0, 0.0, 0.05), linear_grey),
    ];
    let mut trims = Vec::new();
    let tracked = meshflow::track::track_with_progress(
        &frames,
        None,
        &TrackOptions::default(),
        &mut |event| {
            if let meshflow::track::TrackEvent::Trimmed {
                frame, remaining, ..
            } = event
            {
                trims.push((frame, remaining));
            }
        },
    )
    .unwrap();
    let n = tracked.sequence.mesh().n_vertices();
    assert!(
        !trims.is_empty() && trims.iter().all(|&(frame, _)| frame == 1),
        "{trims:?}"
    );
    assert_eq!(trims.last().unwrap().1, n);
    assert_eq!(tracked.report.trimmed_vertices, 21 * 21 - n);
    assert!((n as f64) > 0.3 * 21.0 * 21.0, "only {n} vertices left");
    for x in tracked.sequence.positions(1).unwrap() {
        assert!(
            x.x <= 0.7 + 1e-12 && x.y <= 0.7 + 1e-12 && (x.z - 0.05).abs() < 1e-12,
            "{x:?}"
        );
    }
    assert!(
        tracked.report.warnings[0].contains("frame 1 does not cover"),
        "{:?}",
        tracked.report.warnings
    );
    let kept = TrackOptions {
        keep_uncovered: true,
        keep_going: true,
        ..Default::default()
    };
    let untrimmed = track(&frames, None, &kept);
    assert!(untrimmed.map_or(true, |t| t.sequence.mesh().n_vertices() == 21 * 21));
}

/// The material's velocity is the mesh's own motion plus the flow relative to it: a grid
/// sliding along x at 0.2 per unit time carrying a flow (0, 0.1, 0) moves at (0.2, 0.1, 0).
#[test]
fn tissue_velocity_is_the_mesh_motion_plus_the_flow() {
    use meshflow::flow::MeshSequence;
    let patch = grid(3, 3, 1.0, 1.0);
    let positions: Vec<Vec<Vector3<f64>>> = (0..3)
        .map(|k| {
            patch
                .positions
                .iter()
                .map(|x| x + Vector3::new(0.1 * k as f64, 0.0, 0.0))
                .collect()
        })
        .collect();
    let grey = vec![vec![0.0; patch.positions.len()]; 3];
    let sequence = MeshSequence::new(
        patch.mesh().unwrap(),
        positions,
        grey,
        Some(vec![0.0, 0.5, 1.5]),
    )
    .unwrap();
    let flow = vec![vec![Vector3::new(0.0, 0.1, 0.0); patch.positions.len()]; 2];
    let velocity = meshflow::flow::tissue_velocity(&sequence, &flow);
    for (s, expected) in [
        (0, Vector3::new(0.2, 0.1, 0.0)),
        (1, Vector3::new(0.1, 0.1, 0.0)),
    ] {
        for v in &velocity[s] {
            assert!((v - expected).norm() < 1e-14, "slab {s}: {v:?}");
        }
    }
}

/// Frames tracked as they come ([`meshflow::track::track_as_they_come`]: each dropped once
/// tracked) give exactly what tracking the whole slice gives, for a closed surface with
/// uncovered vertices kept.
#[test]
fn frames_tracked_as_they_come_equal_the_whole_run() {
    let coarse = icosphere(2);
    let fine = icosphere(4);
    let turn = Rotation3::from_euler_angles(0.3, 0.2, 0.1);
    let frames = vec![
        frame(&fine, |x| *x, linear_grey),
        frame(&coarse, |x| 1.1 * x, linear_grey),
        frame(&fine, |x| 1.25 * (turn * x), linear_grey),
        frame(&coarse, |x| 1.2 * (turn * turn * x), linear_grey),
    ];
    let options = TrackOptions {
        keep_uncovered: true,
        reference_vertices: Some(300),
        ..Default::default()
    };
    let whole = track(&frames, None, &options).unwrap();
    let mut rest = frames[1..].iter().cloned();
    let mut events = 0;
    let streamed = meshflow::track::track_as_they_come(
        frames[0].clone(),
        &mut rest,
        None,
        &options,
        &mut |_| events += 1,
    )
    .unwrap();
    assert_eq!(events, 4);
    for k in 0..4 {
        assert_eq!(
            whole.sequence.positions(k),
            streamed.sequence.positions(k),
            "frame {k}"
        );
    }
    assert_eq!(
        whole.report.reference_vertices,
        streamed.report.reference_vertices
    );
}
