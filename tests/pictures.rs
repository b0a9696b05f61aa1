//! `meshflow solve --png` and `meshflow render DIR`: which pictures, what is on them, and that
//! both ways of drawing give the same pixels.

mod common;

use common::{meshflow, meshflow_ok, shipped};
use std::path::Path;

const SLABS: usize = 5;

/// Solves the shipped sample with its ground truth and `--png` into `dir`.
fn solve_with_pictures(dir: &Path, extra: &[&str]) {
    let input = shipped("rotating_sphere");
    let truth = shipped("rotating_sphere/ground_truth.npy");
    let mut args = vec![
        "solve",
        &input,
        "--out",
        dir.to_str().unwrap(),
        "--ground-truth",
        &truth,
        "--png",
    ];
    args.extend_from_slice(extra);
    meshflow_ok(&args);
}

fn picture(path: &Path) -> image::RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

fn picture_names() -> Vec<String> {
    ["grey", "flow", "arrows", "angular_error"]
        .iter()
        .flat_map(|kind| (0..SLABS).map(move |s| format!("{kind}_{s:04}.png")))
        .collect()
}

#[test]
fn solve_png_draws_every_slab_at_the_requested_size() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("run");
    solve_with_pictures(&dir, &["--size", "320x240"]);
    for name in picture_names() {
        let image = picture(&dir.join(&name));
        assert_eq!(image.dimensions(), (320, 240), "{name}");
        // The sphere fills the middle: the centre is not background white.
        assert_ne!(image.get_pixel(160, 120).0, [255; 3], "{name}");
        assert_eq!(image.get_pixel(2, 120).0, [255; 3], "{name}: left edge");
    }
}

#[test]
fn render_draws_the_same_pixels_as_solve_png() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("run");
    solve_with_pictures(&dir, &["--view", "20,10", "--size", "300x200"]);
    let rendered = out.path().join("rendered");
    let run = meshflow_ok(&[
        "render",
        dir.to_str().unwrap(),
        "--out",
        rendered.to_str().unwrap(),
        "--view",
        "20,10",
        "--size",
        "300x200",
    ]);
    assert!(String::from_utf8_lossy(&run.stdout).contains("5 slabs -> 20 pictures"));
    for name in picture_names() {
        // The VTU files hold the flow bit for bit, so camera, scale and pixels agree exactly.
        assert!(
            picture(&dir.join(&name)) == picture(&rendered.join(&name)),
            "{name} differs"
        );
    }
}

#[test]
fn flow_scale_sets_the_saturation_of_the_flow_colours() {
    let out = tempfile::tempdir().unwrap();
    let (small, large) = (out.path().join("small"), out.path().join("large"));
    solve_with_pictures(&small, &["--flow-scale", "0.005", "--size", "320x240"]);
    solve_with_pictures(&large, &["--flow-scale", "5", "--size", "320x240"]);
    // The texture turns about +z, seen from above the equator: on the sphere the flow is
    // horizontal on the screen. With a scale 1000× the speeds the surface is near-white; with
    // a scale below the speeds it is saturated (far from white).
    let whiteness = |image: &image::RgbImage| {
        let [r, g, b] = image.get_pixel(160, 120).0.map(f64::from);
        r.min(g).min(b) / r.max(g).max(b)
    };
    let (faint, strong) = (
        picture(&large.join("flow_0002.png")),
        picture(&small.join("flow_0002.png")),
    );
    assert!(whiteness(&faint) > 0.95, "{:?}", faint.get_pixel(160, 120));
    assert!(whiteness(&strong) < 0.5, "{:?}", strong.get_pixel(160, 120));
}

#[test]
fn render_errors_name_the_file() {
    let out = tempfile::tempdir().unwrap();
    let missing = out.path().join("nothing");
    let run = meshflow(&["render", missing.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1));
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("nothing/flow.pvd"), "{stderr}");

    // A slab file without the flow array.
    let dir = out.path().join("run");
    let input = shipped("rotating_sphere");
    meshflow_ok(&["solve", &input, "--out", dir.to_str().unwrap()]);
    let vtu = dir.join("flow_0003.vtu");
    let text = std::fs::read_to_string(&vtu).unwrap();
    std::fs::write(&vtu, text.replace("Name=\"flow\"", "Name=\"velocity\"")).unwrap();
    let run = meshflow(&["render", dir.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1));
    assert!(
        stderr.contains("flow_0003.vtu") && stderr.contains("'flow'"),
        "{stderr}"
    );
    // Nothing was drawn: all files are read before any picture.
    assert!(!dir.join("grey_0000.png").exists());

    for (args, expected) in [
        (vec!["--size", "10x10"], "--size"),
        (vec!["--view", "north"], "--view"),
        (vec!["--flow-scale", "0"], "--flow-scale"),
    ] {
        let mut all = vec!["render", dir.to_str().unwrap()];
        all.extend(args);
        let run = meshflow(&all);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(expected), "{stderr}");
    }
}
