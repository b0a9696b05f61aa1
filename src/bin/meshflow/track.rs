//! `meshflow track`: frames with their own triangulations → one fixed-connectivity sequence
//! (NPY directory that `solve` reads), by normal motion (`meshflow::track`).

use crate::progress::during;
use meshflow::io::{
    load_mesh, load_sequence, read_mesh, read_times_file, write_atomically, write_npy_sequence,
    LoadOptions, Overwrite, SequenceSource, StagedDir,
};
use meshflow::shapes::Surface;
use meshflow::track::{track, FrameReport, TrackFrame, TrackOptions, Tracked};
use meshflow::Error;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// What `track` needs from the command line.
pub struct TrackRequest<'a> {
    pub input: &'a Path,
    pub out: &'a Path,
    pub reference: Option<&'a Path>,
    pub options: TrackOptions,
    pub times: Option<Vec<f64>>,
    pub load: LoadOptions,
    pub overwrite: Overwrite,
}

pub fn run(request: TrackRequest) -> Result<(), Error> {
    let mut staged = StagedDir::create(request.out, request.overwrite)?;
    staged.record_command(crate::command_line());
    let input = during(format!("reading {}", request.input.display()), || {
        read_frames(request.input, &request.load)
    })?;
    let has_grey = input.frames.iter().any(|f| f.intensity.is_some());
    let frames: Vec<TrackFrame> = input
        .frames
        .into_iter()
        .map(|f| TrackFrame {
            intensity: f
                .intensity
                .unwrap_or_else(|| vec![0.0; f.frame.positions.len()]),
            ..f.frame
        })
        .collect();
    let reference_file = request.reference.unwrap_or(&input.first_file);
    let reference = load_mesh(reference_file, &request.load)?;
    crate::print_warnings(&reference.warnings);
    let options = TrackOptions {
        reference: Some(Surface {
            faces: reference.mesh.faces().to_vec(),
            positions: reference.positions,
        }),
        ..request.options
    };
    let times = request.times.or(input.times);
    let tracked = during(format!("tracking {} frames", frames.len()), || {
        track(&frames, times, &options)
    })?;
    write_outputs(&staged, &tracked, has_grey).map_err(|e| staged.error_in_target(e))?;
    staged.commit()?;
    print_report(&tracked, request.input, request.out);
    if !has_grey {
        eprintln!("meshflow: warning: the frames have no grey values: intensity.npy not written");
    }
    Ok(())
}

/// A frame as read, with its grey values if it has any.
struct ReadFrame {
    frame: TrackFrame,
    intensity: Option<Vec<f64>>,
}

/// What `track` reads: the frames (each file its own mesh), times from a `times.txt` or the
/// glTF animation, and the file whose mesh is the default reference.
struct InputFrames {
    frames: Vec<ReadFrame>,
    times: Option<Vec<f64>>,
    first_file: PathBuf,
}

fn read_frames(input: &Path, load: &LoadOptions) -> Result<InputFrames, Error> {
    let source = SequenceSource::detect(input)?;
    match &source {
        SequenceSource::Frames { files, .. } => {
            let frames = files
                .par_iter()
                .map(|file| {
                    let mesh = read_mesh(file)?;
                    Ok(ReadFrame {
                        frame: TrackFrame {
                            positions: mesh.positions,
                            faces: mesh.faces,
                            intensity: Vec::new(),
                        },
                        intensity: mesh.image.map(|v| v.to_grey()),
                    })
                })
                .collect::<Result<Vec<_>, Error>>()?;
            let times_file = source.times_file().expect("frames are files");
            let times = read_times_file(&times_file)?;
            Ok(InputFrames {
                frames,
                times,
                first_file: files[0].clone(),
            })
        }
        // One connectivity already: tracking re-parametrizes it by normal motion.
        SequenceSource::GltfAnimation(file) | SequenceSource::Npy(file) => {
            let loaded = load_sequence(input, load)?;
            let sequence = &loaded.sequence;
            let frames = (0..sequence.n_frames())
                .map(|k| ReadFrame {
                    frame: TrackFrame {
                        positions: sequence.positions(k).expect("read from files").to_vec(),
                        faces: sequence.mesh().faces().to_vec(),
                        intensity: Vec::new(),
                    },
                    intensity: Some(sequence.intensities(k).to_vec()),
                })
                .collect();
            Ok(InputFrames {
                frames,
                times: Some(sequence.times().to_vec()),
                first_file: file.clone(),
            })
        }
        SequenceSource::Arrays => unreachable!("detect() finds files"),
    }
}

/// positions.npy, faces.npy, intensity.npy, times.txt and track.json.
fn write_outputs(staged: &StagedDir, tracked: &Tracked, has_grey: bool) -> Result<(), Error> {
    let dir = staged.path();
    let sequence = &tracked.sequence;
    let frames = 0..sequence.n_frames();
    let positions: Vec<_> = frames
        .clone()
        .map(|f| sequence.positions(f).expect("tracked in R^3").to_vec())
        .collect();
    let grey: Vec<_> = frames.map(|f| sequence.intensities(f).to_vec()).collect();
    let faces = sequence.mesh().faces();
    let intensities = has_grey.then_some(&grey[..]);
    write_npy_sequence(dir, &positions, faces, intensities, sequence.times())?;
    let report = serde_json::to_string_pretty(&tracked.report).expect("a report serializes");
    write_atomically(&dir.join("track.json"), |w| {
        use std::io::Write;
        writeln!(w, "{report}")
    })?;
    Ok(())
}

fn print_report(tracked: &Tracked, input: &Path, out: &Path) {
    let mesh = tracked.sequence.mesh();
    println!(
        "{}: {} frames tracked by normal motion on {} vertices, {} faces (step bound {:.3e}) -> {}",
        input.display(),
        tracked.sequence.n_frames(),
        mesh.n_vertices(),
        mesh.n_faces(),
        tracked.report.max_step_bound,
        out.display()
    );
    for report in &tracked.report.frames {
        println!("  {}", describe(report));
    }
}

fn describe(r: &FrameReport) -> String {
    format!(
        "frame {:3}: step mean {:.3e} max {:.3e}; misses {} (closest point {}, beyond bound {}); \
         worst edge change {:.1} %, area change {:.1} %; flipped triangles {}",
        r.frame,
        r.mean_step,
        r.max_step,
        r.misses,
        r.fallbacks,
        r.beyond_max_step,
        100.0 * r.worst_edge_change,
        100.0 * r.worst_area_change,
        r.flipped_triangles
    )
}
