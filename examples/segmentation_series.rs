//! A surface segmented anew at every time point, tracked into one moving mesh: the guide's
//! "Real segmentations" table, reproducible on any such series.
//!
//! ```text
//! cargo run --release --example segmentation_series -- FRAMES_DIR [REFERENCE_VERTICES]
//! ```
//!
//! `FRAMES_DIR` holds one `.obj` or `.ply` per time point, in natural order (the guide uses the
//! Drosophila midgut of `nikolas-claussen/blender-tissue-cartography`,
//! `nbs/Tutorials/midgut_example/meshes`, Apache-2.0). The frames are tracked from a reference
//! of `REFERENCE_VERTICES` (default 5000; 0: frame 0's own mesh) with the default relaxation and
//! by normal motion alone (`--keep-going`, to see how far it folds). Prints per frame the
//! 99th percentile and the largest `|log(l / l_previous)|` over the edges, flipped triangles,
//! misses and the largest distance off the frame's surface, and the time of each run; draws
//! the input and the tracked mesh at the first, middle and last frame, every vertex a
//! pseudo-random grey so that the triangulations show, into `out/segmentation_series/`.

use meshflow::format::frame_files;

use meshflow::load::{read_mesh, FrameFormat};
use meshflow::render::{mosaic_picture, write_png, Camera, Surface, View};
use meshflow::track::{track, Relaxation, TrackFrame, TrackOptions, Tracked};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(
        args.next()
            .ok_or("usage: segmentation_series FRAMES_DIR [REFERENCE_VERTICES]")?,
    );
    let vertices: usize = args.next().map_or(Ok(5000), |a| a.parse())?;
    let files = frame_files(&dir, |p| FrameFormat::of(p).is_some(), "mesh frames")?;
    let frames = files
        .iter()
        .map(|file| {
            let mesh = read_mesh(file)?;
            Ok(TrackFrame {
                intensity: vec![0.0; mesh.positions.len()],
                positions: mesh.positions,
                faces: mesh.faces,
            })
        })
        .collect::<Result<Vec<_>, meshflow::format::IoError>>()?;
    let sizes: Vec<usize> = frames.iter().map(|f| f.positions.len()).collect();
    println!(
        "{}: {} frames of {}–{} vertices; reference: {}",
        dir.display(),
        frames.len(),
        sizes.iter().min().unwrap_or(&0),
        sizes.iter().max().unwrap_or(&0),
        match vertices {
            0 => "frame 0's own mesh".to_string(),
            n => format!("{n} vertices"),
        }
    );
    let mut relaxed = None;
    for relaxation in [Relaxation::default(), Relaxation::None] {
        let options = TrackOptions {
            reference_vertices: (vertices > 0).then_some(vertices),
            relaxation,
            keep_going: relaxation == Relaxation::None,
            ..Default::default()
        };
        let start = Instant::now();
        let tracked = track(&frames, None, &options)?;
        let seconds = start.elapsed().as_secs_f64();
        print_table(&tracked, relaxation, seconds);
        if relaxation != Relaxation::None {
            relaxed = Some(tracked);
        }
    }
    if let Some(tracked) = relaxed {
        draw(&frames, &tracked, Path::new("out/segmentation_series"))?;
    }
    Ok(())
}

fn print_table(tracked: &Tracked, relaxation: Relaxation, seconds: f64) {
    let frames = &tracked.report.frames;
    println!(
        "\n{relaxation:?}: {seconds:.2} s on {} threads, {} vertices",
        rayon::current_num_threads(),
        tracked.sequence.mesh().n_vertices()
    );
    println!(
        "{:>6} {:>10} {:>10} {:>8} {:>7} {:>12}",
        "frame", "p99 |log|", "max |log|", "flipped", "misses", "off surface"
    );
    for f in frames {
        println!(
            "{:>6} {:>10.3} {:>10.3} {:>8} {:>7} {:>12.1e}",
            f.frame,
            f.edge_log_ratio_p99,
            f.edge_log_ratio_max,
            f.flipped_triangles,
            f.misses,
            f.max_off_surface
        );
    }
    let worst =
        |g: fn(&meshflow::track::FrameReport) -> f64| frames.iter().map(g).fold(0.0, f64::max);
    println!(
        "worst per frame: p99 {:.3}, largest {:.3}; flipped triangles in all {}; farthest off a surface {:.1e}",
        worst(|f| f.edge_log_ratio_p99),
        worst(|f| f.edge_log_ratio_max),
        frames.iter().map(|f| f.flipped_triangles).sum::<usize>(),
        worst(|f| f.max_off_surface)
    );
}

/// The input (top) and the tracked mesh (bottom) at the first, middle and last frames.
fn draw(
    frames: &[TrackFrame],
    tracked: &Tracked,
    dir: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    std::fs::create_dir_all(dir)?;
    let last = frames.len() - 1;
    let shown = [0, last / 2, last];
    let size = 300;
    let mut sheet = image::RgbImage::new(3 * size, 2 * size);
    let camera = Camera::framing(&frames[0].positions, View::new(-60.0, 30.0), size, size);
    let faces = tracked.sequence.mesh().faces();
    for (column, &k) in shown.iter().enumerate() {
        let moved = tracked.sequence.positions(k).ok_or("tracked in R^3")?;
        let rows = [
            ("input", &frames[k].positions[..], &frames[k].faces[..]),
            ("tracked", moved, faces),
        ];
        for (row, (name, positions, faces)) in rows.into_iter().enumerate() {
            let label = format!("{name} {k}: {} faces", faces.len());
            let picture = mosaic_picture(&camera, Surface { positions, faces }, label)?;
            image::imageops::replace(
                &mut sheet,
                &picture,
                (size * column as u32) as i64,
                (size * row as u32) as i64,
            );
        }
    }
    let file = dir.join("meshes.png");
    write_png(&file, &sheet)?;
    println!("\npicture: {}", file.display());
    Ok(())
}
