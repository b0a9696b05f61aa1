//! `meshflow solve --png` and `meshflow render DIR`: which pictures, what is on them, and that
//! both ways of drawing give the same pixels.

mod common;

use common::{listing, meshflow, meshflow_error, meshflow_ok, shipped};
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

/// Pictures go into the run or beside it, never inside it, and the slab files a `flow.pvd`
/// lists must lie in the run: an edited collection cannot make `render` read elsewhere.
#[test]
fn render_stays_apart_from_other_files() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("run");
    meshflow_ok(&[
        "solve",
        &shipped("rotating_sphere"),
        "--out",
        dir.to_str().unwrap(),
    ]);
    let (run, inside) = (dir.to_str().unwrap(), dir.join("pictures"));
    let render_inside = ["render", run, "--out", inside.to_str().unwrap()];
    meshflow_error(&render_inside, "lies inside the input directory");
    assert!(!inside.exists());
    let pvd = dir.join("flow.pvd");
    let text = std::fs::read_to_string(&pvd).unwrap();
    let outside = out.path().join("flow_0000.vtu");
    std::fs::copy(dir.join("flow_0000.vtu"), &outside).unwrap();
    let relisted = text.replace("\"flow_0000.vtu\"", "\"../flow_0000.vtu\"");
    std::fs::write(&pvd, relisted).unwrap();
    let refused = "flow.pvd: DataSet file \"../flow_0000.vtu\": leads out";
    meshflow_error(&["render", run], refused);
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

    // A run solved with --format npy: render says why it has nothing to read and what to do.
    let npy_only = out.path().join("npy_only");
    let input = shipped("rotating_sphere");
    meshflow_ok(&[
        "solve",
        &input,
        "--out",
        npy_only.to_str().unwrap(),
        "--format",
        "npy",
    ]);
    let run = meshflow(&["render", npy_only.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1));
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("no ParaView files") && stderr.contains("--png"),
        "{stderr}"
    );

    // A slab file without the flow array.
    let dir = out.path().join("run");
    let input = shipped("rotating_sphere");
    meshflow_ok(&["solve", &input, "--out", dir.to_str().unwrap()]);
    let vtu = dir.join("flow_0003.vtu");
    let text = std::fs::read_to_string(&vtu).unwrap();
    std::fs::write(&vtu, text.replace("Name=\"flow\"", "Name=\"motion\"")).unwrap();
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

/// The picture names of `slabs` (with the angular error).
fn pictures_of(slabs: &[usize]) -> Vec<String> {
    ["grey", "flow", "arrows", "angular_error"]
        .iter()
        .flat_map(|kind| slabs.iter().map(move |s| format!("{kind}_{s:04}.png")))
        .collect()
}

#[test]
fn render_into_the_run_replaces_only_its_pictures() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("run");
    let run = dir.to_str().unwrap();
    solve_with_pictures(&dir, &["--size", "64x48", "--slabs", "0,2-3"]);
    let data: Vec<String> = listing(&dir)
        .into_iter()
        .filter(|n| !n.ends_with(".png"))
        .collect();
    let with = |slabs: &[usize]| {
        let mut names = data.clone();
        names.extend(pictures_of(slabs));
        names.sort();
        names
    };
    assert_eq!(listing(&dir), with(&[0, 2, 3]));
    let flow = std::fs::read(dir.join("flow.npy")).unwrap();

    let drawn = meshflow_ok(&["render", run, "--size", "64x48", "--slabs", "1,last"]);
    assert!(String::from_utf8_lossy(&drawn.stdout).contains("2 of 5 slabs -> 8 pictures"));
    assert_eq!(listing(&dir), with(&[1, 4]));
    assert_eq!(std::fs::read(dir.join("flow.npy")).unwrap(), flow);
    let manifest = meshflow::io::RunManifest::read(&dir).unwrap();
    assert_eq!(manifest.commands.len(), 2);
    assert_eq!(manifest.commands[1][..2], ["meshflow", "render"]);
    assert_eq!(listing(out.path()), ["run"]);

    // Elsewhere: an output of its own, replaced by the next render there.
    let other = out.path().join("other");
    let elsewhere = [
        "render",
        run,
        "--size",
        "64x48",
        "--out",
        other.to_str().unwrap(),
    ];
    meshflow_ok(&[&elsewhere[..], &["--slabs", "0"]].concat());
    meshflow_ok(&[&elsewhere[..], &["--slabs", "2"]].concat());
    let mut expected = pictures_of(&[2]);
    expected.push("meshflow_run.json".into());
    expected.sort();
    assert_eq!(listing(&other), expected);
    assert_eq!(listing(&dir), with(&[1, 4]));
}

#[test]
fn slab_lists_are_parsed_and_checked_against_the_slab_count() {
    use meshflow::render::SlabSelection;
    let chosen = |text: &str, n: usize| text.parse::<SlabSelection>().unwrap().resolve(n);
    assert_eq!(
        chosen("0,5,10-12,last", 20).unwrap(),
        [0, 5, 10, 11, 12, 19]
    );
    assert_eq!(chosen(" 3 , 1-2 ,2", 5).unwrap(), [1, 2, 3]);
    assert_eq!(chosen("last-last", 5).unwrap(), [4]);
    assert_eq!(chosen("2-last", 5).unwrap(), [2, 3, 4]);
    assert_eq!(chosen("all", 3).unwrap(), [0, 1, 2]);
    assert_eq!(SlabSelection::all().resolve(2).unwrap(), [0, 1]);
    for (text, n, message) in [
        (
            "0,7",
            5,
            r#"slab list "0,7": "7" names slab 7, but there are 5 slabs (0-4)"#,
        ),
        (
            "2-9",
            5,
            r#"slab list "2-9": "2-9" names slab 9, but there are 5 slabs (0-4)"#,
        ),
        (
            "6-last",
            5,
            r#"slab list "6-last": "6-last" runs backwards (slab 6 to 4)"#,
        ),
        ("0", 0, r#"slab list "0": there are no slabs"#),
    ] {
        assert_eq!(chosen(text, n).unwrap_err().to_string(), message);
    }
    for (text, message) in [
        ("1,,2", r#"slab list "1,,2": an item is empty"#),
        ("3-1", r#"slab list "3-1": "3-1" runs backwards"#),
        (
            "-1",
            r#"slab list "-1": "-1" is not a slab number, a range FIRST-LAST, 'last' or 'all'"#,
        ),
        (
            "first",
            r#"slab list "first": "first" is not a slab number"#,
        ),
    ] {
        let error = text.parse::<SlabSelection>().unwrap_err().to_string();
        assert!(error.starts_with(message), "{error}");
    }

    // On the command line: syntax errors are usage errors, slabs beyond the last are found
    // before the solve; --slabs needs --png.
    let out = tempfile::tempdir().unwrap();
    let target = out.path().join("run");
    let input = shipped("rotating_sphere");
    let solve = |slabs: &str, png: bool| {
        let mut args = vec!["solve", &input, "--out", target.to_str().unwrap()];
        args.extend(["--slabs", slabs]);
        if png {
            args.push("--png");
        }
        meshflow(&args)
    };
    for (slabs, png, code, message) in [
        (
            "0,9",
            true,
            1,
            r#"slab list "0,9": "9" names slab 9, but there are 5 slabs (0-4)"#,
        ),
        ("x", true, 2, r#"invalid value 'x' for '--slabs <LIST>'"#),
        (
            "0",
            false,
            2,
            "--slabs chooses the pictures of --png; add --png",
        ),
    ] {
        let run = solve(slabs, png);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(code), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(message), "{stderr}");
        assert!(!target.exists());
    }
}

/// Rows and columns spanned by the drawn surface: pixels that are not background white,
/// leaving out the label in the top-left corner (rows < 20 and columns < 120).
fn extent(image: &image::RgbImage) -> (u32, u32) {
    let drawn: Vec<(u32, u32)> = image
        .enumerate_pixels()
        .filter(|(x, y, p)| p.0 != [255; 3] && !(*y < 20 && *x < 120))
        .map(|(x, y, _)| (x, y))
        .collect();
    let span = |coordinate: fn(&(u32, u32)) -> u32| {
        let values = drawn.iter().map(coordinate);
        values.clone().max().unwrap() - values.min().unwrap() + 1
    };
    (span(|p| p.0), span(|p| p.1))
}

/// Three frames of a cigar (the level-3 icosphere stretched 5 times along axis `long`, 1 = y
/// or 2 = z) rising slowly along its length, with grey stripes turning about it.
struct Cigar {
    faces: Vec<[u32; 3]>,
    positions: Vec<Vec<nalgebra::Vector3<f64>>>,
    colours: Vec<Vec<[f64; 3]>>,
}

fn cigar(long: usize) -> Cigar {
    let sphere = meshflow::shapes::icosphere(3);
    let (across, around) = ((long + 1) % 3, (long + 2) % 3);
    let mut stretch = nalgebra::Vector3::repeat(0.3);
    stretch[long] = 1.5;
    let positions = (0..3)
        .map(|k| {
            let mut lift = nalgebra::Vector3::zeros();
            lift[long] = 0.02 * k as f64;
            let stretched = sphere.positions.iter().map(|p| p.component_mul(&stretch));
            stretched.map(|p| p + lift).collect()
        })
        .collect();
    let colours = (0..3)
        .map(|k| {
            let stripe = |p: &nalgebra::Vector3<f64>| {
                0.5 + 0.4 * (4.0 * p[across].atan2(p[around]) + 0.1 * k as f64).sin()
            };
            sphere.positions.iter().map(|p| [stripe(p); 3]).collect()
        })
        .collect();
    Cigar {
        faces: sphere.faces,
        positions,
        colours,
    }
}

const ONE_SMALL_SLAB: [&str; 6] = ["--size", "300x300", "--slabs", "0", "--beta", "0.01"];

/// `solve INPUT --out RUN --png` on slab 0 at 300 × 300, with `extra` arguments; its stdout.
fn solve_one_slab(input: &Path, run: &Path, extra: &[&str]) -> String {
    let args = [
        "solve",
        input.to_str().unwrap(),
        "--out",
        run.to_str().unwrap(),
        "--png",
    ];
    let output = meshflow_ok(&[&args[..], &ONE_SMALL_SLAB, extra].concat());
    String::from_utf8_lossy(&output.stdout).into_owned()
}

fn summary_up(run: &Path) -> String {
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    summary["view"]["up"].as_str().unwrap().to_string()
}

#[test]
fn gltf_input_is_drawn_upright() {
    use meshflow::io::gltf_write::{write_glb_animation, AnimationFrame};
    // Along +y, the glTF up axis.
    let cigar = cigar(1);
    let frames: Vec<AnimationFrame> = (0..3)
        .map(|k| AnimationFrame {
            time: k as f64,
            positions: &cigar.positions[k],
            colors: &cigar.colours[k],
        })
        .collect();
    let out = tempfile::tempdir().unwrap();
    let file = out.path().join("cigar.glb");
    write_glb_animation(&file, &cigar.faces, &frames).unwrap();
    let run = out.path().join("run");
    let said = solve_one_slab(&file, &run, &[]);
    assert!(
        said.contains("view: up axis y (the glTF convention; --up z to change)"),
        "{said}"
    );
    assert_eq!(summary_up(&run), "y");
    let upright = picture(&run.join("grey_0000.png"));
    let (width, height) = extent(&upright);
    assert!(height > 3 * width, "{width} x {height}: not upright");

    // render uses the solve's view: the same pixels; --up z lays it down.
    let render = ["render", run.to_str().unwrap()];
    let size = &ONE_SMALL_SLAB[..4];
    meshflow_ok(&[&render[..], size].concat());
    assert!(picture(&run.join("grey_0000.png")) == upright);
    meshflow_ok(&[&render[..], size, &["--up", "z"]].concat());
    let (width, height) = extent(&picture(&run.join("grey_0000.png")));
    assert!(height < width, "{width} x {height}: not lying");
}

/// OBJ frames do not say which way is up: a cigar stands on its length whether that is y or
/// z (a rod), says why, and an explicit `--up` wins.
#[test]
fn obj_input_stands_on_the_axis_its_shape_suggests() {
    for (long, up, other) in [(1, "y", "z"), (2, "z", "y")] {
        let cigar = cigar(long);
        let out = tempfile::tempdir().unwrap();
        let frames = out.path().join("frames");
        std::fs::create_dir(&frames).unwrap();
        for k in 0..3 {
            let file = frames.join(format!("frame_{k}.obj"));
            let colours = Some(cigar.colours[k].as_slice());
            meshflow::io::write_obj(&file, &cigar.positions[k], &cigar.faces, colours).unwrap();
        }
        let run = out.path().join("run");
        let said = solve_one_slab(&frames, &run, &[]);
        let line = format!("view: up axis {up} (chosen from the data: a rod, spreads 0.");
        assert!(said.contains(&line), "{said}");
        let reason = format!(" : 1, its axis 0° from {up}; --up {other} to change)");
        assert!(said.contains(&reason), "{said}");
        assert_eq!(summary_up(&run), up);
        let (width, height) = extent(&picture(&run.join("grey_0000.png")));
        assert!(height > 3 * width, "{up}: {width} x {height}: not upright");

        // A run whose summary has no view (an older one): render chooses from slab 0 alike.
        let summary = run.join("summary.json");
        let mut recorded: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
        recorded.as_object_mut().unwrap().remove("view");
        std::fs::write(&summary, recorded.to_string()).unwrap();
        let rendered =
            meshflow_ok(&[&["render", run.to_str().unwrap()], &ONE_SMALL_SLAB[..4]].concat());
        let said = String::from_utf8_lossy(&rendered.stdout);
        assert!(said.contains(&line), "{said}");
        let (width, height) = extent(&picture(&run.join("grey_0000.png")));
        assert!(
            height > 3 * width,
            "render, {up}: {width} x {height}: not upright"
        );

        let given = out.path().join("given");
        let said = solve_one_slab(&frames, &given, &["--up", other]);
        assert!(
            said.contains(&format!("view: up axis {other} (--up)")),
            "{said}"
        );
        assert_eq!(summary_up(&given), other);
        let (width, height) = extent(&picture(&given.join("grey_0000.png")));
        assert!(
            height < width,
            "--up {other}: {width} x {height}: not lying"
        );
    }
}

/// `--slabs` chooses which pictures to draw, not how they look: one camera and one flow scale
/// for the whole run, so slab 3 drawn alone is the same picture as slab 3 drawn with all.
#[test]
fn a_slab_drawn_alone_is_the_picture_drawn_with_all() {
    let work = tempfile::tempdir().unwrap();
    let run = work.path().join("run");
    meshflow_ok(&[
        "solve",
        &shipped("rotating_sphere"),
        "--out",
        run.to_str().unwrap(),
    ]);
    let (all, alone) = (work.path().join("all"), work.path().join("alone"));
    meshflow_ok(&[
        "render",
        run.to_str().unwrap(),
        "--out",
        all.to_str().unwrap(),
    ]);
    meshflow_ok(&[
        "render",
        run.to_str().unwrap(),
        "--out",
        alone.to_str().unwrap(),
        "--slabs",
        "3",
    ]);
    for name in ["grey_0003.png", "flow_0003.png", "arrows_0003.png"] {
        let a = std::fs::read(all.join(name)).unwrap();
        let b = std::fs::read(alone.join(name)).unwrap();
        assert!(a == b, "{name} differs when drawn alone");
    }
    assert!(!alone.join("flow_0002.png").exists());
}
