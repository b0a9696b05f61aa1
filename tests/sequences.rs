//! Reading sequences in every format gives the same numbers, and what `meshflow solve` writes
//! reads back: OBJ → solve → VTU (through vtkio), NPY and PLY input equal OBJ input to the
//! last bit, textures are sampled where they should be, seams are welded.

use meshflow::io::ply::{write_ply, PlyEncoding};
use meshflow::io::Channels;
use meshflow::io::{
    load_sequence, read_npy, read_obj, write_npy, write_obj, LoadOptions, VertexValues,
};
use meshflow::render::UpAxis;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use std::process::Command;

fn shipped_sphere() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rotating_sphere")
}

/// Runs `meshflow solve INPUT --out OUT --gamma 0.01 --quiet` with `extra` arguments (stderr:
/// only warnings and errors).
fn run_solve(input: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_meshflow"))
        .args([
            "solve",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .args(["--gamma", "0.01", "--quiet"])
        .args(extra)
        .output()
        .unwrap()
}

/// [`run_solve`], which must succeed; its standard output.
fn solve(input: &Path, out: &Path, extra: &[&str]) -> String {
    let run = run_solve(input, out, extra);
    let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    stdout
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

/// The shipped OBJ frames as NPY arrays and as binary PLY files.
fn convert_shipped(npy_dir: &Path, ply_dir: &Path) {
    std::fs::create_dir_all(npy_dir).unwrap();
    std::fs::create_dir_all(ply_dir).unwrap();
    let frames: Vec<_> = (0..6)
        .map(|k| read_obj(&shipped_sphere().join(format!("frame_{k}.obj"))).unwrap())
        .collect();
    let (k, v) = (frames.len() as u64, frames[0].positions.len() as u64);
    let positions: Vec<f64> = frames
        .iter()
        .flat_map(|f| f.positions.iter().flat_map(|p| [p.x, p.y, p.z]))
        .collect();
    let grey: Vec<f64> = frames
        .iter()
        .flat_map(|f| f.colors.as_ref().unwrap().iter().map(|c| c[0]))
        .collect();
    let faces: Vec<i32> = frames[0]
        .faces
        .iter()
        .flatten()
        .map(|&i| i as i32)
        .collect();
    write_npy(&npy_dir.join("positions.npy"), &[k, v, 3], &positions).unwrap();
    write_npy(
        &npy_dir.join("faces.npy"),
        &[frames[0].faces.len() as u64, 3],
        &faces,
    )
    .unwrap();
    write_npy(&npy_dir.join("intensity.npy"), &[k, v], &grey).unwrap();
    for (i, frame) in frames.iter().enumerate() {
        let grey: Vec<f64> = frame
            .colors
            .as_ref()
            .unwrap()
            .iter()
            .map(|c| c[0])
            .collect();
        write_ply(
            &ply_dir.join(format!("frame_{i}.ply")),
            &frame.positions,
            &frame.faces,
            None,
            &[("quality", &grey)],
            PlyEncoding::BinaryLittleEndian,
        )
        .unwrap();
    }
}

#[test]
fn npy_and_ply_input_equal_obj_input_to_the_last_bit() {
    let dir = tempfile::tempdir().unwrap();
    let (npy, ply) = (dir.path().join("npy"), dir.path().join("ply"));
    convert_shipped(&npy, &ply);
    let obj = load_sequence(&shipped_sphere(), &Default::default()).unwrap();
    let from_npy = load_sequence(&npy, &Default::default()).unwrap();
    let ply_options = LoadOptions {
        intensity_attribute: Some("quality".into()),
        ..Default::default()
    };
    let from_ply = load_sequence(&ply, &ply_options).unwrap();
    for other in [&from_npy, &from_ply] {
        let (a, b) = (&obj.sequence, &other.sequence);
        assert_eq!(a.mesh().faces(), b.mesh().faces());
        assert_eq!(a.times(), b.times());
        for k in 0..a.n_frames() {
            assert_eq!(a.positions(k), b.positions(k));
            assert_eq!(bits(a.intensities(k)), bits(b.intensities(k)));
        }
    }
    // And so do the flows the binary writes.
    let outputs: Vec<Vec<u64>> = [
        (shipped_sphere(), vec![]),
        (npy, vec![]),
        (ply, vec!["--intensity-attribute", "quality"]),
    ]
    .iter()
    .enumerate()
    .map(|(i, (input, extra))| {
        let out = dir.path().join(format!("out{i}"));
        solve(input, &out, extra);
        bits(&read_npy(&out.join("flow.npy")).unwrap().data)
    })
    .collect();
    assert_eq!(outputs[0], outputs[1]);
    assert_eq!(outputs[0], outputs[2]);
}

#[test]
fn solve_output_reads_back_through_vtkio() {
    use vtkio::model::{Attribute, DataSet, IOBuffer, Piece};
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    solve(&shipped_sphere(), &out, &[]);
    let sequence = load_sequence(&shipped_sphere(), &Default::default())
        .unwrap()
        .sequence;
    let flow = read_npy(&out.join("flow.npy")).unwrap();
    let intrinsic = read_npy(&out.join("flow_intrinsic.npy")).unwrap();
    let v = sequence.mesh().n_vertices();
    let pvd = std::fs::read_to_string(out.join("flow.pvd")).unwrap();
    for s in 0..sequence.n_slabs() {
        let name = format!("flow_{s:04}.vtu");
        assert!(
            pvd.contains(&format!("timestep=\"{}\" part=\"0\" file=\"{name}\"", s)),
            "{pvd}"
        );
        let vtk = vtkio::Vtk::import(out.join(&name)).unwrap();
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!("{name} is not an unstructured grid")
        };
        let Piece::Inline(piece) = &pieces[0] else {
            panic!("{name}: piece not inline")
        };
        let IOBuffer::F64(points) = &piece.points else {
            panic!("{name}: points not Float64")
        };
        let expected: Vec<f64> = sequence
            .positions(s)
            .unwrap()
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .collect();
        assert_eq!(bits(points), bits(&expected), "{name} points = frame {s}");
        let array = |wanted: &str| -> Vec<f64> {
            piece
                .data
                .point
                .iter()
                .find_map(|a| match a {
                    Attribute::DataArray(d) if d.name == wanted => match &d.data {
                        IOBuffer::F64(values) => Some(values.clone()),
                        _ => None,
                    },
                    _ => None,
                })
                .unwrap_or_else(|| panic!("{name} has no Float64 array {wanted}"))
        };
        let slab_flow = &flow.data[s * v * 3..(s + 1) * v * 3];
        assert_eq!(bits(&array("flow")), bits(slab_flow));
        assert_eq!(
            bits(&array("flow_intrinsic")),
            bits(&intrinsic.data[s * v * 2..(s + 1) * v * 2])
        );
        let speeds: Vec<f64> = slab_flow
            .chunks(3)
            .map(|u| Vector3::new(u[0], u[1], u[2]).norm())
            .collect();
        assert_eq!(bits(&array("speed")), bits(&speeds));
        assert_eq!(bits(&array("intensity")), bits(sequence.intensities(s)));
    }
}

#[test]
fn times_file_glob_and_existing_output_directory() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    for k in [0, 1, 2, 10] {
        let source = read_obj(&shipped_sphere().join(format!("frame_{}", k.min(3)) + ".obj"));
        let source = source.unwrap();
        let path = frames.join(format!("frame_{k}.obj"));
        write_obj(
            &path,
            &source.positions,
            &source.faces,
            source.colors.as_deref(),
        )
        .unwrap();
    }
    std::fs::write(frames.join("times.txt"), "# seconds\n0, 0.5\n0.75 2.5\n").unwrap();
    let from_dir = load_sequence(&frames, &Default::default()).unwrap();
    assert_eq!(from_dir.sequence.times(), [0.0, 0.5, 0.75, 2.5]);
    let names: Vec<String> = from_dir
        .frame_files
        .iter()
        .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        ["frame_0.obj", "frame_1.obj", "frame_2.obj", "frame_10.obj"]
    );

    // The glob takes 3 of the 4 frames, so the directory's times.txt no longer fits.
    let pattern = frames.join("frame_?.obj");
    let error = load_sequence(&pattern, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("times.txt") && error.contains("expected 3 frame times, got 4"),
        "{error}"
    );
    let options = LoadOptions {
        times: Some(vec![0.0, 1.0, 2.0]),
        ..Default::default()
    };
    let from_glob = load_sequence(&pattern, &options).unwrap();
    assert_eq!(from_glob.sequence.n_frames(), 3);
    assert_eq!(
        from_glob.sequence.positions(2),
        from_dir.sequence.positions(2)
    );

    // --times wins over times.txt; an existing output directory that meshflow did not write
    // is refused, and with --force it keeps its other files.
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    std::fs::write(out.join("flow.npy"), "stale").unwrap();
    let refused = run_solve(&frames, &out, &[]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        refused.status.code() == Some(1) && stderr.contains("flow.npy, notes.txt"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("flow.npy")).unwrap(),
        "stale"
    );
    solve(
        &frames,
        &out,
        &["--times", "0,1,2,3", "--format", "npy", "--force"],
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["times"], serde_json::json!([0.0, 1.0, 2.0, 3.0]));
    assert_eq!(read_npy(&out.join("flow.npy")).unwrap().shape, [3, 642, 3]);
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    assert!(!out.join("flow_0000.vtu").exists() && !out.join("flow.glb").exists());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 2, "{leftovers:?}");
}

/// A unit square split into two triangles per cell of an `n × n` grid, stored the way
/// single-index exporters do: every face has its own three vertices (all split), with texture
/// coordinates equal to (x, y).
fn split_textured_square(n: usize, shift: f64) -> (String, usize) {
    let surface = meshflow::shapes::grid(n, n, 1.0, 1.0);
    let mut text = String::from("mtllib square.mtl\nusemtl checker\n");
    for (f, face) in surface.faces.iter().enumerate() {
        for &v in face {
            let p: Vector3<f64> = surface.positions[v as usize];
            text += &format!("v {} {} {}\nvt {} {}\n", p.x, p.y, shift * p.x, p.x, p.y);
        }
        let b = 3 * f + 1;
        text += &format!("f {b}/{b} {}/{} {}/{}\n", b + 1, b + 1, b + 2, b + 2);
    }
    (text, surface.positions.len())
}

#[test]
fn textured_obj_frames_are_sampled_bilinearly_and_welded() {
    let dir = tempfile::tempdir().unwrap();
    // A 4×2 RGB texture; grey = Rec. 709 luma of each texel.
    let texels: [[u8; 3]; 8] = [
        [0, 0, 0],
        [255, 255, 255],
        [255, 0, 0],
        [0, 255, 0],
        [0, 0, 255],
        [128, 128, 128],
        [10, 200, 30],
        [255, 255, 0],
    ];
    let mut image = image::RgbImage::new(4, 2);
    for (i, t) in texels.iter().enumerate() {
        image.put_pixel(i as u32 % 4, i as u32 / 4, image::Rgb(*t));
    }
    image.save(dir.path().join("checker.png")).unwrap();
    std::fs::write(
        dir.path().join("square.mtl"),
        "newmtl checker\nKd 1 1 1\nmap_Kd -s 1 1 1 checker.png\n",
    )
    .unwrap();
    let n = 4;
    let mut n_vertices = 0;
    for k in 0..2 {
        let (text, v) = split_textured_square(n, 0.1 * k as f64);
        n_vertices = v;
        std::fs::write(dir.path().join(format!("frame_{k}.obj")), text).unwrap();
    }
    let loaded = load_sequence(dir.path(), &Default::default()).unwrap();
    let sequence = &loaded.sequence;
    assert_eq!(sequence.mesh().n_vertices(), n_vertices);
    assert_eq!(loaded.vertex_map.n_welded(), 3 * 2 * n * n - n_vertices);
    assert!(
        sequence.mesh().euler_characteristic() == 1,
        "one disc, not loose triangles"
    );

    let luma = |t: [u8; 3]| {
        let [r, g, b] = t.map(|c| c as f64 / 255.0);
        0.2126 * r + 0.7152 * g + 0.0722 * b
    };
    // Bilinear sampling by hand at (u, 1 − v), texel centres at ((x + ½)/4, (y + ½)/2), repeat.
    let sample = |u: f64, v: f64, value: &dyn Fn([u8; 3]) -> f64| {
        let (x, y) = (u * 4.0 - 0.5, (1.0 - v) * 2.0 - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: f64, j: f64| {
            let (i, j) = ((i as i64).rem_euclid(4), (j as i64).rem_euclid(2));
            value(texels[(j * 4 + i) as usize])
        };
        (at(x0, y0) * (1.0 - fx) + at(x0 + 1.0, y0) * fx) * (1.0 - fy)
            + (at(x0, y0 + 1.0) * (1.0 - fx) + at(x0 + 1.0, y0 + 1.0) * fx) * fy
    };
    // By default the three colour channels, each sampled bilinearly.
    assert_eq!(sequence.n_channels(), 3);
    for k in 0..2 {
        let positions = sequence.positions(k).unwrap();
        for (c, channel) in sequence.channels(k).iter().enumerate() {
            let value = |t: [u8; 3]| t[c] as f64 / 255.0;
            for (p, &got) in positions.iter().zip(channel) {
                assert!(
                    (got - sample(p.x, p.y, &value)).abs() < 1e-6,
                    "at {p:?}: {got}"
                );
            }
        }
    }
    // `--channels luma`: the luma of the colours (sampling is linear, so either order).
    let options = LoadOptions {
        channels: Channels::Luma,
        ..Default::default()
    };
    let luma_sequence = load_sequence(dir.path(), &options).unwrap().sequence;
    assert_eq!(luma_sequence.n_channels(), 1);
    for k in 0..2 {
        let positions = luma_sequence.positions(k).unwrap();
        for (p, &got) in positions.iter().zip(luma_sequence.intensities(k)) {
            assert!(
                (got - sample(p.x, p.y, &luma)).abs() < 1e-6,
                "at {p:?}: {got}"
            );
        }
    }
    // Unwelded, the split copies stay apart and every triangle is its own component.
    let options = LoadOptions {
        weld: false,
        ..Default::default()
    };
    let split = load_sequence(dir.path(), &options).unwrap();
    assert_eq!(split.sequence.mesh().n_vertices(), 3 * 2 * n * n);
}

/// Material libraries go through tobj for their `newmtl` and `map_Kd` statements only: colour
/// statements it would reject or panic on do not matter, `map_Kd` options are skipped (the
/// image name may have spaces), and a broken library is an error naming the OBJ file, the
/// library and its line.
#[test]
fn material_libraries_are_read_leniently_and_their_errors_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let image = image::RgbImage::from_pixel(2, 2, image::Rgb([51, 102, 204]));
    image.save(dir.path().join("wood grain.png")).unwrap();
    for k in 0..2 {
        let (text, _) = split_textured_square(2, 0.1 * k as f64);
        std::fs::write(dir.path().join(format!("frame_{k}.obj")), text).unwrap();
    }
    let load_with = |library: &str| {
        std::fs::write(dir.path().join("square.mtl"), library).unwrap();
        load_sequence(dir.path(), &Default::default())
    };
    let loaded = load_with(
        "# by hand\nnewmtl checker\nKd 0.8\nd -halo 0.5\nKa spectral paint.rfl\n\
         map_Kd -s 1 1 1 -clamp on wood grain.png\n",
    )
    .unwrap();
    for (channel, expected) in loaded.sequence.channels(0).iter().zip([0.2, 0.4, 0.8]) {
        assert!(
            channel.iter().all(|c| (c - expected).abs() < 1e-6),
            "{channel:?}"
        );
    }
    let broken = [
        (
            "map_Kd wood grain.png\nnewmtl checker\n",
            "square.mtl, line 1: map_Kd before any newmtl",
        ),
        (
            "newmtl checker\n\nmap_Kd\n",
            "square.mtl, line 3: 'map_Kd': material parse error",
        ),
        (
            "# none\nnewmtl\n",
            "square.mtl, line 2: 'newmtl': invalid object name",
        ),
        (
            "newmtl checker\nmap_Kd -s 1 1 1 -clamp on\n",
            "square.mtl: material 'checker': map_Kd '-s 1 1 1 -clamp on' names no image",
        ),
    ];
    for (library, expected) in broken {
        let error = load_with(library).unwrap_err().to_string();
        assert!(
            error.contains(".obj: material library square.mtl: "),
            "{error}"
        );
        assert!(error.contains(expected), "{error}");
    }
}

/// A rotating, textured sphere whose numbers are exact in float32 (positions on a 1/1024 grid,
/// grey values on a 1/256 grid), so glTF storage loses nothing.
/// Faces, positions per frame, grey values per frame.
type FrameArrays = (Vec<[u32; 3]>, Vec<Vec<Vector3<f64>>>, Vec<Vec<f64>>);

fn dyadic_sphere_frames() -> FrameArrays {
    let sphere = meshflow::shapes::icosphere(2);
    let round = |x: f64, grid: f64| (x * grid).round() / grid;
    let frames: Vec<Vec<Vector3<f64>>> = (0..4)
        .map(|k| {
            let rotation =
                nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), 0.05 * k as f64);
            sphere
                .positions
                .iter()
                .map(|p| (rotation * p).map(|c| round(c, 1024.0)))
                .collect()
        })
        .collect();
    let greys = frames
        .iter()
        .map(|f| {
            f.iter()
                .map(|p| round(0.5 + 0.4 * (5.0 * p.x).sin() * (3.0 * p.y).cos(), 256.0))
                .collect()
        })
        .collect();
    (sphere.faces, frames, greys)
}

#[test]
fn gltf_animation_and_gltf_frames_give_the_numbers_of_the_obj_frames() {
    use meshflow::io::gltf_write::{write_glb_animation, AnimationFrame};
    let dir = tempfile::tempdir().unwrap();
    let (faces, frames, greys) = dyadic_sphere_frames();
    let times = [0.0, 0.25, 0.5, 1.0];
    let colors: Vec<Vec<[f64; 3]>> = greys
        .iter()
        .map(|g| g.iter().map(|&v| [v; 3]).collect())
        .collect();
    let (obj_dir, glb_dir) = (dir.path().join("obj"), dir.path().join("glb"));
    std::fs::create_dir_all(&obj_dir).unwrap();
    std::fs::create_dir_all(&glb_dir).unwrap();
    let animation: Vec<AnimationFrame> = (0..4)
        .map(|k| AnimationFrame {
            time: times[k],
            positions: &frames[k],
            colors: &colors[k],
        })
        .collect();
    for (k, frame) in animation.iter().enumerate() {
        write_obj(
            &obj_dir.join(format!("f{k}.obj")),
            &frames[k],
            &faces,
            Some(&colors[k]),
        )
        .unwrap();
        write_glb_animation(
            &glb_dir.join(format!("f{k}.glb")),
            &faces,
            std::slice::from_ref(frame),
        )
        .unwrap();
    }
    std::fs::write(obj_dir.join("times.txt"), "0 0.25 0.5 1\n").unwrap();
    std::fs::write(glb_dir.join("times.txt"), "0 0.25 0.5 1\n").unwrap();
    let animation_file = dir.path().join("sphere.glb");
    write_glb_animation(&animation_file, &faces, &animation).unwrap();

    let obj = load_sequence(&obj_dir, &Default::default()).unwrap();
    for input in [&animation_file, &glb_dir] {
        let gltf = load_sequence(input, &Default::default()).unwrap();
        let (a, b) = (&obj.sequence, &gltf.sequence);
        assert_eq!(a.mesh().faces(), b.mesh().faces());
        assert_eq!(bits(a.times()), bits(b.times()), "{input:?}");
        for k in 0..4 {
            assert_eq!(a.positions(k), b.positions(k), "{input:?} frame {k}");
            assert_eq!(
                bits(a.intensities(k)),
                bits(b.intensities(k)),
                "{input:?} frame {k}"
            );
        }
    }
    let flows: Vec<Vec<u64>> = [&obj_dir, &animation_file]
        .iter()
        .enumerate()
        .map(|(i, input)| {
            let out = dir.path().join(format!("out{i}"));
            solve(input, &out, &["--format", "npy"]);
            bits(&read_npy(&out.join("flow.npy")).unwrap().data)
        })
        .collect();
    assert_eq!(flows[0], flows[1]);
}

#[test]
fn flow_glb_replays_the_frames_coloured_by_the_flow() {
    let dir = tempfile::tempdir().unwrap();
    // OBJ frames (+z up), then that output's own flow.glb as input (glTF: +y up).
    let from_obj = dir.path().join("obj");
    check_flow_glb(&shipped_sphere(), &from_obj, UpAxis::Z);
    check_flow_glb(
        &from_obj.join("flow.glb"),
        &dir.path().join("glb"),
        UpAxis::Y,
    );
}

/// Solves `input` into `out` and checks that `flow.glb` replays the frames coloured as the
/// default view about `up` shows the flow, and that `summary.json` records that view.
fn check_flow_glb(input: &Path, out: &Path, up: UpAxis) {
    use meshflow::io::gltf_read::read_gltf_animation;
    use meshflow::render::color_wheel::robust_max;
    use meshflow::render::{screen_flow_colors, Camera, View};
    solve(input, out, &["--format", "glb,npy"]);
    let sequence = load_sequence(input, &Default::default()).unwrap().sequence;
    let replay = read_gltf_animation(&out.join("flow.glb"), &Default::default()).unwrap();
    assert_eq!(replay.times.as_deref(), Some(sequence.times()));
    assert_eq!(replay.faces, sequence.mesh().faces());
    for k in 0..sequence.n_frames() {
        for (p, q) in replay.positions[k]
            .iter()
            .zip(sequence.positions(k).unwrap())
        {
            assert!(
                (p - q).norm() <= 2e-7 * q.norm(),
                "frame {k}: {p:?} vs {q:?}"
            );
        }
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let view = View::default().with_up(up);
    assert_eq!(summary["view"]["up"], up.name());
    assert_eq!(
        serde_json::from_value::<View>(summary["view"].clone()).unwrap(),
        view
    );
    // The colours are those of flow_SSSS.png: the colour wheel of the screen directions seen
    // from that view of all frames, scaled by the robust maximum R^3 speed.
    let flow = read_npy(&out.join("flow.npy")).unwrap();
    let vectors: Vec<nalgebra::Vector3<f64>> = flow
        .data
        .chunks(3)
        .map(|u| nalgebra::Vector3::new(u[0], u[1], u[2]))
        .collect();
    let speeds: Vec<f64> = vectors.iter().map(|u| u.norm()).collect();
    let all_positions: Vec<_> = (0..sequence.n_frames())
        .flat_map(|k| sequence.positions(k).unwrap().to_vec())
        .collect();
    let camera = Camera::framing(&all_positions, view, 960, 720);
    let colors = screen_flow_colors(
        &camera,
        &vectors[..sequence.mesh().n_vertices()],
        robust_max(&speeds),
    );
    let grey = replay.images.unwrap()[0].to_grey();
    for (g, c) in grey.iter().zip(&colors) {
        assert!((g - meshflow::io::grey_value(*c)).abs() < 1e-6);
    }
    assert!(
        colors.iter().any(|c| c != &[1.0; 3]),
        "the flow is not all zero"
    );
}

/// Writes OBJ frames of the dyadic sphere into `dir` with the grey values `greys(k)` of frame
/// `k` and the positions of frame `positions(k)`.
fn write_sphere_frames(
    dir: &Path,
    positions: impl Fn(usize) -> usize,
    greys: impl Fn(usize) -> Vec<f64>,
) {
    let (faces, frames, _) = dyadic_sphere_frames();
    for k in 0..frames.len() {
        let colours: Vec<[f64; 3]> = greys(k).iter().map(|&g| [g; 3]).collect();
        let path = dir.join(format!("frame_{k}.obj"));
        write_obj(&path, &frames[positions(k)], &faces, Some(&colours)).unwrap();
    }
}

#[test]
fn an_image_that_moves_with_the_surface_is_reported() {
    use meshflow::io::{LoadWarning, STATIC_IMAGE_TOLERANCE};
    let (_, _, greys) = dyadic_sphere_frames();
    let range = greys[0].iter().fold(f64::NEG_INFINITY, |m, &g| m.max(g))
        - greys[0].iter().fold(f64::INFINITY, |m, &g| m.min(g));
    let root = tempfile::tempdir().unwrap();
    let warnings = |name: &str, moving: bool, change: f64| {
        let dir = root.path().join(name);
        std::fs::create_dir(&dir).unwrap();
        // Frame k's grey values: frame 0's, vertex 7 changed by k · change.
        let grey = |k: usize| {
            let mut grey = greys[0].clone();
            grey[7] += k as f64 * change;
            grey
        };
        write_sphere_frames(&dir, |k| if moving { k } else { 0 }, grey);
        let loaded = load_sequence(&dir, &Default::default()).unwrap();
        (dir, loaded.warnings)
    };
    // Frame 3 differs by 3 · 0.3 of the tolerance: still the same image.
    let (glued, found) = warnings("glued", true, 0.3 * STATIC_IMAGE_TOLERANCE * range);
    assert_eq!(
        found,
        vec![LoadWarning::StaticImage {
            file: glued.clone(),
            frames: 4
        }]
    );
    assert!(found[0].to_string().contains("the flow is zero"));
    let (_, found) = warnings("changing", true, 2.0 * STATIC_IMAGE_TOLERANCE * range);
    assert_eq!(found, vec![]);
    // Nothing moves at all: nothing to report.
    let (_, found) = warnings("still", false, 0.0);
    assert_eq!(found, vec![]);
    // The CLI prints it as a warning line.
    let run = run_solve(&glued, &root.path().join("out"), &["--format", "npy"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert_eq!(
        stderr.trim(),
        format!(
            "meshflow: warning: {}: the grey values are the same in all 4 frames while the \
             surface moves: the image moves with the surface (e.g. a texture fixed to the mesh), \
             so the flow is zero",
            glued.display()
        )
    );
}

/// The shipped frames with what scans have: an unused file vertex 0, face 0 flipped, and a
/// triangle hanging at original vertex 5 by that vertex alone (file vertices 643, 644), which
/// makes vertex 5 non-manifold.
fn scan_like_frames(dir: &Path) {
    for k in 0..6 {
        let name = format!("frame_{k}.obj");
        let obj = read_obj(&shipped_sphere().join(&name)).unwrap();
        let mut positions = vec![Vector3::new(9.0, 9.0, 9.0)];
        positions.extend(&obj.positions);
        let tip = obj.positions[5];
        positions.extend([tip * 1.2, tip * 1.2 + Vector3::new(0.0, 0.0, 0.1)]);
        let mut colors = vec![[0.5; 3]];
        colors.extend(obj.colors.unwrap());
        colors.extend([[0.25; 3], [0.75; 3]]);
        let mut faces: Vec<[u32; 3]> = obj.faces.iter().map(|f| f.map(|v| v + 1)).collect();
        faces[0].swap(1, 2);
        faces.push([6, 643, 644]);
        write_obj(&dir.join(name), &positions, &faces, Some(&colors)).unwrap();
    }
}

#[test]
fn scan_defects_are_dropped_flipped_and_repaired_and_outputs_keep_file_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("scan");
    std::fs::create_dir_all(&input).unwrap();
    scan_like_frames(&input);
    let message = load_sequence(&input, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("frame_0.obj: file vertex 6 has 2 separate fans of faces")
            && message.contains("use --repair"),
        "{message}"
    );
    let options = LoadOptions {
        repair: true,
        ..LoadOptions::default()
    };
    let loaded = load_sequence(&input, &options).unwrap();
    // 645 file vertices: 0 dropped; 1..=642 the sphere (mesh 0..642); vertex 6 split into
    // mesh 5 (its first face, on the sphere) and mesh 6 (the hanging triangle's corner).
    let map = loaded.vertex_map.to_npy();
    assert_eq!(map.len(), 645);
    assert_eq!(map[..8], [-1, 0, 1, 2, 3, 4, 5, 7]);
    assert_eq!(map[642..], [642, 643, 644]);
    assert_eq!(loaded.sequence.mesh().n_vertices(), 645);
    assert_eq!(loaded.vertex_map.representative(6), 6);
    let messages: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(messages.len(), 3, "{messages:?}");
    assert!(messages[0].ends_with("dropped 1 vertex that no face uses (e.g. file vertex 0); outputs keep the file's numbering"));
    assert!(messages[1].ends_with("flipped 1 face to orient them like their neighbours"));
    assert!(messages[2].ends_with("repaired: split 1 non-manifold vertex into 2"));

    // The binary writes NPY rows per file vertex: NaN for the dropped one, the split vertex
    // its first piece's value.
    let out = dir.path().join("out");
    solve(&input, &out, &["--repair"]);
    let flow = read_npy(&out.join("flow.npy")).unwrap();
    assert_eq!(flow.shape, vec![5, 645, 3]);
    for (s, slab) in flow.data.chunks(645 * 3).enumerate() {
        assert!(slab[..3].iter().all(|x| x.is_nan()));
        // Every other row is its mesh vertex's flow, as the VTU (on mesh vertices) has it.
        let vtu = meshflow::io::vtk::read_vtu(&out.join(format!("flow_{s:04}.vtu"))).unwrap();
        let mesh_flow = &vtu.point_array("flow").unwrap().values;
        assert_eq!(mesh_flow.len(), 645 * 3);
        for (i, &m) in map.iter().enumerate().skip(1) {
            let m = m as usize;
            assert_eq!(
                slab[3 * i..3 * i + 3],
                mesh_flow[3 * m..3 * m + 3],
                "row {i}"
            );
        }
    }
    let table = std::fs::read(out.join("vertex_map.npy")).unwrap();
    let table = npyz::NpyFile::new(&table[..]).unwrap();
    assert_eq!(table.shape(), &[645]);
    assert_eq!(table.into_vec::<i64>().unwrap(), map);
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["dropped_vertices"], 1);
    assert_eq!(summary["warnings"].as_array().unwrap().len(), 3);
}

#[test]
fn float32_arrays_are_accepted_and_a_ply_without_colours_names_its_properties() {
    let dir = tempfile::tempdir().unwrap();
    let (npy, ply) = (dir.path().join("npy"), dir.path().join("ply"));
    convert_shipped(&npy, &ply);
    let double = load_sequence(&npy, &LoadOptions::default()).unwrap();
    for name in ["positions.npy", "intensity.npy"] {
        let array = read_npy(&npy.join(name)).unwrap();
        let single: Vec<f32> = array.data.iter().map(|&x| x as f32).collect();
        write_npy(&npy.join(name), &array.shape, &single).unwrap();
    }
    let single = load_sequence(&npy, &LoadOptions::default()).unwrap();
    let (a, b) = (&double.sequence, &single.sequence);
    for k in 0..a.n_frames() {
        let widened = |x: f64| f64::from(x as f32);
        let expected: Vec<f64> = a.intensities(k).iter().map(|&x| widened(x)).collect();
        assert_eq!(bits(b.intensities(k)), bits(&expected));
        let expected: Vec<Vector3<f64>> = a
            .positions(k)
            .unwrap()
            .iter()
            .map(|p| p.map(widened))
            .collect();
        assert_eq!(b.positions(k).unwrap(), expected.as_slice());
    }
    // --intensity in float32 too.
    let options = LoadOptions {
        intensity: Some(npy.join("intensity.npy")),
        ..LoadOptions::default()
    };
    let from_option = load_sequence(&shipped_sphere(), &options).unwrap();
    assert_eq!(
        bits(from_option.sequence.intensities(2)),
        bits(b.intensities(2))
    );

    let message = load_sequence(&ply, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("frame_0.ply: no grey values: no vertex colours, but scalar vertex properties quality; use --intensity-attribute quality"),
        "{message}"
    );
}

/// Every row with its first entry appended (a seam copy of vertex 0).
fn with_copy<T: Clone>(rows: &[Vec<T>]) -> Vec<Vec<T>> {
    rows.iter()
        .map(|r| [r.clone(), vec![r[0].clone()]].concat())
        .collect()
}

/// Arrays in memory go through the loaders' steps: the shipped sequence's own arrays give its
/// sequence back to the last bit, a seam copy is welded (and mapped), and errors name the
/// arrays, the frame and the vertex.
#[test]
fn arrays_are_built_like_files() {
    use meshflow::io::sequence_from_arrays;
    let loaded = load_sequence(&shipped_sphere(), &LoadOptions::default()).unwrap();
    let sequence = &loaded.sequence;
    let frames = 0..sequence.n_frames();
    let positions: Vec<Vec<Vector3<f64>>> = frames
        .clone()
        .map(|k| sequence.positions(k).unwrap().to_vec())
        .collect();
    let grey: Vec<Vec<f64>> = frames.map(|k| sequence.intensities(k).to_vec()).collect();
    let faces = sequence.mesh().faces().to_vec();
    let times = Some(sequence.times().to_vec());
    let from_arrays = |faces, positions, grey: Vec<Vec<f64>>| {
        sequence_from_arrays(
            faces,
            positions,
            grey.into_iter().map(VertexValues::Grey).collect(),
            times.clone(),
            &LoadOptions::default(),
        )
    };
    let again = from_arrays(faces.clone(), positions.clone(), grey.clone()).unwrap();
    assert_eq!(again.sequence.mesh().faces(), sequence.mesh().faces());
    for k in 0..sequence.n_frames() {
        assert_eq!(again.sequence.positions(k), sequence.positions(k));
        assert_eq!(again.sequence.intensities(k), sequence.intensities(k));
    }
    assert_eq!(again.source.describe(), "arrays in memory");

    // Vertex 0 copied as vertex V and used by one face in its place: welded back.
    let n = positions[0].len();
    let mut seam_faces = faces.clone();
    let face = seam_faces.iter().position(|f| f.contains(&0)).unwrap();
    seam_faces[face]
        .iter_mut()
        .filter(|v| **v == 0)
        .for_each(|v| *v = n as u32);
    let welded = from_arrays(seam_faces, with_copy(&positions), with_copy(&grey)).unwrap();
    assert_eq!(welded.vertex_map.mesh_vertex(n), Some(0));
    assert_eq!(welded.sequence.mesh().n_vertices(), n);

    let mut bad = grey.clone();
    bad[2][7] = f64::NAN;
    let error = from_arrays(faces.clone(), positions.clone(), bad).unwrap_err();
    assert!(
        error
            .to_string()
            .starts_with("arrays: frame 2: intensity at vertex 7 is NaN"),
        "{error}"
    );
    let mut short = positions.clone();
    short[3].pop();
    let error = from_arrays(faces, short, grey).unwrap_err().to_string();
    assert_eq!(error, "arrays: frame 3 has 641 vertices, frame 0 has 642");
}
