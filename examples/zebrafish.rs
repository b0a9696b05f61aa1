//! The paper's Experiment II on real data: a confocal recording of a zebrafish embryo, whose
//! endodermal cells crawl on the yolk, from the microscope's volumes and the cells' centres to
//! the flow on the tissue, scored at the cells themselves.
//!
//! The data is public but GPL-3 (`lukaslang/ofish`, folder `data/cxcr4aMO2_290112`; data
//! courtesy of P. Aanstad) and stays outside this repository. Convert its MATLAB files once,
//! then run:
//!
//! ```text
//! python3 examples/zebrafish/convert_ofish.py PATH/TO/ofish/data/cxcr4aMO2_290112 DATA
//! cargo run --release --example zebrafish -- DATA [--vertices N]
//! ```
//!
//! With `ZF_PAIRS_ONLY=1` in the environment it leaves out the sequence 140–142 (the slowest
//! case) and runs the pairs only.
//!
//! For each case (frames 114 → 116, 120 → 122, 140 → 141, 140 → 142 and the sequence
//! 140–142: every volume of the folder) it fits a surface through the cells' centres
//! (`meshflow::surface`, a height over a sphere fitted to the first frame), carries the
//! volumes onto it with the default sampling (`meshflow::volume`: a Gaussian of two voxels,
//! the maximum along the vertex normal over a shell), solves with several settings and scores
//! each flow at the cells matched between frames by mutual nearest neighbours
//! (`meshflow::accuracy::tracks`), beside two baselines: the zero flow and each cell moved as
//! the mean of its 8 nearest neighbours. Its last row is the recommended flow on a surface
//! fitted to the volumes' bright voxels alone (`meshflow::surface::foreground_points`), which
//! needs no cell centres: they only score it. It prints one table row per setting with the time of
//! each step, and draws the recommended flow of 140 → 141 into `out/zebrafish/`: the projected
//! image, the flow's colours and its arrows with the cells' own displacements in red, and its
//! divergence and curl smoothed over the tissue scale (`divergence_tissue.png`,
//! `curl_tissue.png`, as `meshflow analyze --png --tissue-scale 20` draws them), with how much
//! of each is at that scale. Errors end it with one line.

use meshflow::accuracy::{match_tracks, score_result, TrackPoint, TrackScores};
use meshflow::analysis::analyze_flow;
use meshflow::flow::{compute_flow, FlowParams, FlowResult, MeshSequence, Regularizer, Warping};
use meshflow::flow::{smoothed_over_length, Anisotropy, Scale, Weight};
use meshflow::render::colormap::symmetric_range;
use meshflow::render::{flow_picture, grey_picture, signed_picture, tracks_picture, write_png};
use meshflow::render::{Camera, PictureStyle, Surface, UpChoice};
use meshflow::surface::voxels::voxel_spacing;
use meshflow::surface::{fit_surface, fit_surface_weighted, foreground_points, read_points};
use meshflow::surface::{FitOptions, IsosurfaceOptions, Resolution};
use meshflow::volume::{read_volumes, sample_sequence, SampleOptions, Volume, VolumeOptions};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Voxel size of the recording, x, y, z in micrometres.
const VOXEL: [f64; 3] = [1.6774, 1.6774, 7.1847];

/// Errors end the example with one line, as the CLI's do.
fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("zebrafish: {error}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let (data, vertices) = arguments()?;
    let cases = cases_found(&data)?;
    let out = Path::new("out/zebrafish");
    std::fs::create_dir_all(out)?;
    let cells = read_cells(&data, &cases)?;
    let volumes = read_volume_frames(&data, &cases)?;
    println!(
        "zebrafish endoderm (lukaslang/ofish, cxcr4aMO2_290112): cells matched by mutual nearest \
         neighbours; endpoint errors (EPE) of the tangential displacement in µm over each pair \
         of frames; surfaces of about {vertices} vertices"
    );
    let pairs_only = std::env::var("ZF_PAIRS_ONLY").is_ok_and(|v| v == "1");
    for case in cases.iter().filter(|c| !pairs_only || c.frames.len() == 2) {
        run_case(case, &cells, &volumes, vertices, out)?;
    }
    Ok(())
}

/// Frames of a case (numbers of the recording), and whether its pictures are drawn.
struct Case {
    frames: &'static [usize],
    draw: bool,
}

const CASES: [Case; 5] = [
    Case {
        frames: &[114, 116],
        draw: false,
    },
    Case {
        frames: &[120, 122],
        draw: false,
    },
    Case {
        frames: &[140, 141],
        draw: true,
    },
    Case {
        frames: &[140, 142],
        draw: false,
    },
    Case {
        frames: &[140, 141, 142],
        draw: false,
    },
];

fn arguments() -> Result<(PathBuf, usize), String> {
    let usage = "usage: cargo run --release --example zebrafish -- DATA [--vertices N]  (DATA: \
                 written by examples/zebrafish/convert_ofish.py)";
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (data, vertices) = match &args[..] {
        [data] => (data, 65_000),
        [data, flag, n] if flag == "--vertices" => (data, n.parse().map_err(|_| usage)?),
        _ => return Err(usage.into()),
    };
    let data = PathBuf::from(data);
    if data.join("thresholdedcenters.mat").exists() {
        return Err(format!(
            "{} holds the MATLAB files: convert them first with \
             python3 examples/zebrafish/convert_ofish.py {} DATA",
            data.display(),
            data.display()
        ));
    }
    Ok((data, vertices))
}

fn volume_file(data: &Path, frame: usize) -> PathBuf {
    data.join(format!("volumes/frame_{frame}.npy"))
}

/// The cases whose volumes the converter wrote (it converts the pairs it finds), naming the
/// others; an error when there is none.
fn cases_found(data: &Path) -> Result<Vec<&'static Case>, String> {
    let (found, missing): (Vec<&Case>, Vec<&Case>) =
        (CASES.iter()).partition(|c| c.frames.iter().all(|&k| volume_file(data, k).is_file()));
    let names = |cases: &[&Case]| -> String {
        let name = |c: &&Case| c.frames.iter().map(usize::to_string).collect::<Vec<_>>();
        cases
            .iter()
            .map(|c| name(c).join("→"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if found.is_empty() {
        return Err(format!(
            "no volumes of any case in {} (expected volumes/frame_K.npy for {}): convert the \
             recording first with python3 examples/zebrafish/convert_ofish.py",
            data.join("volumes").display(),
            names(&missing)
        ));
    }
    if !missing.is_empty() {
        println!("skipped (volumes not converted): {}", names(&missing));
    }
    Ok(found)
}

/// The frames of `cases`, each once.
fn case_frames(cases: &[&Case]) -> Vec<usize> {
    let mut frames: Vec<usize> = cases
        .iter()
        .flat_map(|c| c.frames.iter().copied())
        .collect();
    frames.sort_unstable();
    frames.dedup();
    frames
}

/// The cell centres of one frame (µm).
type Cells = Vec<Vector3<f64>>;

/// Cell centres of the cases' frames, by frame number.
fn read_cells(data: &Path, cases: &[&Case]) -> Result<Vec<(usize, Cells)>, meshflow::Error> {
    case_frames(cases)
        .into_iter()
        .map(|k| {
            let file = data.join(format!("cells/frame_{k}.npy"));
            Ok((k, read_points(&file)?.remove(0)))
        })
        .collect()
}

/// Volumes of the cases' frames, by frame number.
fn read_volume_frames(
    data: &Path,
    cases: &[&Case],
) -> Result<Vec<(usize, Volume)>, meshflow::Error> {
    let options = VolumeOptions {
        voxel_size: Some(Vector3::from(VOXEL)),
        ..VolumeOptions::default()
    };
    case_frames(cases)
        .into_iter()
        .map(|k| {
            let file = volume_file(data, k);
            Ok((k, read_volumes(&file, &options)?.volumes.remove(0)))
        })
        .collect()
}

/// One row of the table: a flow (or a baseline) scored at the cells.
struct Row {
    name: String,
    scores: TrackScores,
    seconds: f64,
}

fn run_case(
    case: &Case,
    cells: &[(usize, Cells)],
    volumes: &[(usize, Volume)],
    vertices: usize,
    out: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let pick = |k: usize| cells.iter().find(|(f, _)| *f == k).expect("read").1.clone();
    let frames: Vec<Vec<Vector3<f64>>> = case.frames.iter().map(|&k| pick(k)).collect();
    let start = Instant::now();
    let fitted = fit_surface(
        &frames,
        &FitOptions {
            resolution: Resolution::Vertices(vertices),
            ..FitOptions::default()
        },
    )?;
    let fit_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let case_volumes: Vec<Volume> = case
        .frames
        .iter()
        .map(|&k| {
            volumes
                .iter()
                .find(|(f, _)| *f == k)
                .expect("read")
                .1
                .clone()
        })
        .collect();
    let mesh = meshflow::mesh::Mesh::new(fitted.positions[0].len(), fitted.faces.clone())?;
    let sampled = sample_sequence(
        &case_volumes,
        &mesh,
        &fitted.positions,
        &SampleOptions::default(),
    )?;
    let sample_seconds = start.elapsed().as_secs_f64();
    let times: Vec<f64> = case
        .frames
        .iter()
        .map(|&k| (k - case.frames[0]) as f64)
        .collect();
    let sequence = MeshSequence::new(
        mesh,
        fitted.positions.clone(),
        sampled.values.clone(),
        Some(times),
    )?;
    let tracks = match_tracks(&frames, None)?;
    let label = case
        .frames
        .iter()
        .map(|k| k.to_string())
        .collect::<Vec<_>>()
        .join(" → ");
    println!(
        "\n{label}: surface {} vertices, mean edge {:.2} µm ({fit_seconds:.2} s); volumes \
         sampled, {} of {} vertex frames outside the recording ({sample_seconds:.2} s); {} cells \
         tracked over {:?} pairs",
        sequence.mesh().n_vertices(),
        sequence.slab_geometry(0)?.mean_edge_length(),
        sampled.outside.iter().sum::<usize>(),
        sequence.mesh().n_vertices() * sequence.n_frames(),
        tracks.n_tracks(),
        tracks.pairs_per_slab(),
    );
    let mut rows = Vec::new();
    let zero = vec![vec![Vector3::zeros(); sequence.mesh().n_vertices()]; sequence.n_slabs()];
    let zero_scores = meshflow::accuracy::score_tracks(&sequence, &zero, &tracks)?;
    rows.push(Row {
        name: "each cell moved as its 8 neighbours".into(),
        scores: neighbour_baseline(&zero_scores)?,
        seconds: 0.0,
    });
    let mut recommended = None;
    for (name, params) in settings(case.frames.len()) {
        let start = Instant::now();
        let flow = compute_flow(&sequence, &params)?;
        let seconds = start.elapsed().as_secs_f64();
        let scores = score_result(&sequence, &flow, &tracks)?;
        if name.starts_with("recommended:") {
            recommended = Some((flow, scores.clone()));
        }
        rows.push(Row {
            name: name.into(),
            scores,
            seconds,
        });
    }
    rows.push(from_volumes_alone(
        &case_volumes,
        sequence.times(),
        vertices,
        &tracks,
    )?);
    print_table(&rows, &zero_scores);
    if let (true, Some((flow, scores))) = (case.draw, recommended) {
        draw(&sequence, &flow, &scores, out)?;
    }
    Ok(())
}

/// The recommendation: the strain regularizer, frame by frame.
fn recommended() -> FlowParams {
    FlowParams {
        regularizer: Regularizer::Strain { dirichlet: 0.0 },
        alpha: Weight::Relative(0.0),
        ..FlowParams::default()
    }
}

/// The recommended flow on a surface fitted to the volumes' bright voxels instead of the cells'
/// centres (`meshflow surface VOLUMES --voxel-size …`), scored at the same cells: the
/// recording alone, the cells only judging. Its ratio is to its own zero flow.
fn from_volumes_alone(
    volumes: &[Volume],
    times: &[f64],
    vertices: usize,
    tracks: &meshflow::accuracy::Tracks,
) -> Result<Row, Box<dyn std::error::Error>> {
    let start = Instant::now();
    let found = (volumes.iter())
        .map(|v| foreground_points(v, &IsosurfaceOptions::default()))
        .collect::<Result<Vec<_>, _>>()?;
    let frames: Vec<Vec<Vector3<f64>>> = found.iter().map(|f| f.points.clone()).collect();
    let weights: Vec<Vec<f64>> = found.iter().map(|f| f.weights.clone()).collect();
    let options = FitOptions {
        resolution: Resolution::Vertices(vertices),
        ..FitOptions::default()
    };
    let length = voxel_spacing(&volumes[0]);
    let fitted = fit_surface_weighted(&frames, &weights, length, &options)?;
    let mesh = meshflow::mesh::Mesh::new(fitted.positions[0].len(), fitted.faces.clone())?;
    let sampled = sample_sequence(volumes, &mesh, &fitted.positions, &SampleOptions::default())?;
    let sequence = MeshSequence::new(mesh, fitted.positions, sampled.values, Some(times.to_vec()))?;
    let flow = compute_flow(&sequence, &recommended())?;
    Ok(Row {
        name: "recommended, on the surface from the volumes alone".into(),
        scores: score_result(&sequence, &flow, tracks)?,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The settings compared: the defaults, the strain regularizer, coarse-to-fine warping, the
/// recommendation (strain, frame by frame), the recommendation with warping, and the
/// image-driven anisotropic regularizer (`λ` auto, `meshflow::flow::anisotropy`) on the
/// recommendation, alone, with warping and with robust smoothness (`ε` auto: image- and
/// flow-driven). Over
/// three frames the defaults coupled in time (also with the anisotropic regularizer, and with
/// its weight in time) and frame by frame stand for the first ones: a coupled solve of
/// 3 × 94k vertices takes about 50 s (365 PCG iterations), and warping would repeat it per
/// level and warp. Over two frames the anisotropic regularizer on the defaults
/// (covariant), alone and image- and flow-driven, joins them.
fn settings(n_frames: usize) -> Vec<(&'static str, FlowParams)> {
    let recommended = recommended();
    let with_warping = FlowParams {
        warping: Warping::LARGE_MOTION,
        ..recommended.clone()
    };
    let anisotropic = FlowParams {
        anisotropy: Some(Anisotropy::with(Scale::Auto)),
        ..recommended.clone()
    };
    let anisotropic_robust = FlowParams {
        robust_smoothness: Some(Scale::Auto),
        ..anisotropic.clone()
    };
    let first = if n_frames > 2 {
        vec![
            ("defaults (coupled in time)", FlowParams::default()),
            (
                "--anisotropic auto (coupled in time)",
                FlowParams {
                    anisotropy: Some(Anisotropy::with(Scale::Auto)),
                    ..FlowParams::default()
                },
            ),
            (
                "--anisotropic auto --anisotropic-in-time",
                FlowParams {
                    anisotropy: Some(Anisotropy {
                        in_time: true,
                        ..Anisotropy::with(Scale::Auto)
                    }),
                    ..FlowParams::default()
                },
            ),
            (
                "--time-scale 0 (frame by frame)",
                FlowParams {
                    alpha: Weight::Relative(0.0),
                    ..FlowParams::default()
                },
            ),
        ]
    } else {
        vec![
            ("defaults", FlowParams::default()),
            (
                "--large-motion",
                FlowParams {
                    warping: Warping::LARGE_MOTION,
                    ..FlowParams::default()
                },
            ),
            (
                "--anisotropic auto",
                FlowParams {
                    anisotropy: Some(Anisotropy::with(Scale::Auto)),
                    ..FlowParams::default()
                },
            ),
            (
                "--anisotropic auto --robust-smoothness auto",
                FlowParams {
                    anisotropy: Some(Anisotropy::with(Scale::Auto)),
                    robust_smoothness: Some(Scale::Auto),
                    ..FlowParams::default()
                },
            ),
        ]
    };
    first
        .into_iter()
        .chain([
            (
                "recommended: --regularizer strain --time-scale 0",
                recommended,
            ),
            (
                "--large-motion --regularizer strain --time-scale 0",
                with_warping,
            ),
            ("recommended + --anisotropic auto", anisotropic.clone()),
            (
                "--large-motion + recommended + --anisotropic auto",
                FlowParams {
                    warping: Warping::LARGE_MOTION,
                    ..anisotropic
                },
            ),
            (
                "recommended + --anisotropic auto --robust-smoothness auto",
                anisotropic_robust,
            ),
        ])
        .collect()
}

/// The baseline that moves every cell as the mean true displacement of its 8 nearest
/// neighbours in the same slab (itself left out): what smoothing the truth alone achieves.
fn neighbour_baseline(zero: &TrackScores) -> Result<TrackScores, Box<dyn std::error::Error>> {
    let mut points: Vec<TrackPoint> = zero.points.clone();
    for p in points.iter_mut() {
        let mut others: Vec<&TrackPoint> = zero
            .points
            .iter()
            .filter(|q| q.slab == p.slab && q.track != p.track)
            .collect();
        others.sort_by(|a, b| {
            let d = |q: &TrackPoint| (q.position - p.position).norm();
            d(a).total_cmp(&d(b))
        });
        let mean: Vector3<f64> = others.iter().take(8).map(|q| q.truth).sum::<Vector3<f64>>() / 8.0;
        p.computed = mean;
    }
    Ok(TrackScores::from_points(points, zero.slabs.len()))
}

fn print_table(rows: &[Row], zero: &TrackScores) {
    println!(
        "  {:<62} {:>7} {:>15} {:>9} {:>17} {:>7} {:>8}",
        "flow", "points", "EPE mean/median", "÷ zero", "direction mean/med", "speed", "seconds"
    );
    let z = &zero.overall;
    println!(
        "  {:<62} {:>7} {:>7.2} / {:<5.2} {:>9} {:>17} {:>7} {:>8}",
        "zero flow", z.points, z.zero_mean_endpoint, z.zero_median_endpoint, "1", "—", "0", ""
    );
    for row in rows {
        let s = &row.scores.overall;
        println!(
            "  {:<62} {:>7} {:>7.2} / {:<5.2} {:>9.3} {:>17} {:>7.2} {:>8.2}",
            row.name,
            s.points,
            s.mean_endpoint,
            s.median_endpoint,
            s.endpoint_ratio(),
            format!(
                "{:.1}° / {:.1}°",
                s.mean_direction_degrees, s.median_direction_degrees
            ),
            s.median_speed_ratio,
            row.seconds
        );
    }
}

/// The projected image, the flow's colours, and its arrows with the cells' displacements.
fn draw(
    sequence: &MeshSequence,
    flow: &FlowResult,
    scores: &TrackScores,
    out: &Path,
) -> Result<(), meshflow::Error> {
    let positions = sequence.positions(0).expect("embedded");
    let vectors = &flow.vectors.as_ref().expect("embedded")[0];
    let faces = sequence.mesh().faces();
    let surface = Surface { positions, faces };
    // The cap from outside, along its axis, as the CLI's pictures see it.
    let view = UpChoice::from_shape(positions, faces).view();
    let camera = Camera::framing(positions, view, 1200, 1000);
    let style = PictureStyle {
        arrow_spacing: 22.0,
        ..PictureStyle::default()
    };
    let grey = sequence.intensities(0);
    let range = (0.0, 0.6);
    let scale = robust_max(vectors.iter().map(|u| u.norm()));
    let labelled = |text: &str| PictureStyle {
        label: Some(text.into()),
        ..style.clone()
    };
    write_png(
        &out.join("image.png"),
        &grey_picture(
            &camera,
            surface,
            grey,
            range,
            &labelled("frame 140, projected"),
        )?,
    )?;
    write_png(
        &out.join("flow.png"),
        &flow_picture(
            &camera,
            surface,
            vectors,
            scale,
            &labelled("flow 140 -> 141"),
        )?,
    )?;
    let cells: Vec<Vector3<f64>> = scores.points.iter().map(|p| p.position).collect();
    let moves: Vec<Vector3<f64>> = scores.points.iter().map(|p| p.truth).collect();
    let picture = tracks_picture(
        &camera,
        surface,
        (grey, range),
        vectors,
        scale,
        (&cells, &moves),
        &labelled("flow (black) and cells (red), 140 -> 141"),
    )?;
    write_png(&out.join("arrows.png"), &picture)?;
    draw_tissue_scale(sequence, flow, &camera, &labelled, out)?;
    println!(
        "  pictures: {}/{{image,flow,arrows,divergence_tissue,curl_tissue}}.png",
        out.display()
    );
    Ok(())
}

/// The tissue scale of the analysis pictures: two cells across.
const TISSUE_SCALE: f64 = 20.0;

/// Divergence and curl of slab 0 smoothed over [`TISSUE_SCALE`] along the surface, drawn, and
/// the share of each field's mean square (over the vertices) that the smoothing keeps: what is
/// tissue-scale pattern rather than per-nucleus detail.
fn draw_tissue_scale(
    sequence: &MeshSequence,
    flow: &FlowResult,
    camera: &Camera,
    labelled: &dyn Fn(&str) -> PictureStyle,
    out: &Path,
) -> Result<(), meshflow::Error> {
    let analysis = analyze_flow(sequence, &flow.intrinsic[..1])?;
    let positions = sequence.positions(0).expect("embedded");
    let surface = Surface {
        positions,
        faces: sequence.mesh().faces(),
    };
    let mean_square = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64;
    for (name, values) in [
        ("divergence", &analysis[0].vertex_divergence),
        ("curl", &analysis[0].vertex_curl),
    ] {
        let smoothed = smoothed_over_length(sequence, 0, &[values], TISSUE_SCALE)?.remove(0);
        let label = format!("{name} 140 -> 141, smoothed over {TISSUE_SCALE} µm");
        let picture = signed_picture(
            camera,
            surface,
            &smoothed,
            symmetric_range(&smoothed),
            &labelled(&label),
        )?;
        write_png(&out.join(format!("{name}_tissue.png")), &picture)?;
        println!(
            "  {name}: rms {:.3} per frame, {:.3} over {TISSUE_SCALE} µm: {:.0} % of its mean square at the tissue scale",
            mean_square(values).sqrt(),
            mean_square(&smoothed).sqrt(),
            100.0 * mean_square(&smoothed) / mean_square(values)
        );
    }
    Ok(())
}

/// The 98th percentile: a flow scale that a few outliers do not set.
fn robust_max(values: impl Iterator<Item = f64>) -> f64 {
    let mut sorted: Vec<f64> = values.collect();
    sorted.sort_by(f64::total_cmp);
    sorted[(0.98 * (sorted.len() - 1) as f64) as usize].max(f64::MIN_POSITIVE)
}
