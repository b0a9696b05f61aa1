//! Property tests: validation of arbitrary index and position arrays never panics. Whatever
//! the arrays, building the mesh, its geometry, a sequence (directly or through the NPY
//! reader, which also welds, with and without repair) and solving the flow returns `Ok` or a
//! typed error; so does reading arbitrary OBJ-like text. Repairing any face list gives a mesh.

use meshflow::flow::{compute_flow, FlowParams, MeshSequence};
use meshflow::geometry::IntrinsicGeometry;
use meshflow::io::{load_sequence, write_npy, LoadOptions};
use meshflow::mesh::{repair, ConnectivityError, Mesh};
use meshflow::shapes::grid;
use nalgebra::Vector3;
use proptest::prelude::*;

/// Coordinates mixing ordinary values, repeats (coincident vertices) and specials.
fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => (-2i32..=2).prop_map(f64::from),
        4 => -1.0..1.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(1e300),
        1 => Just(-0.0),
        1 => Just(f64::MIN_POSITIVE / 4.0),
    ]
}

fn position() -> impl Strategy<Value = Vector3<f64>> {
    [coordinate(), coordinate(), coordinate()].prop_map(Vector3::from)
}

/// Any small index/position arrays: indices may be out of range, repeated, inconsistent.
fn arbitrary_arrays() -> impl Strategy<Value = (Vec<[u32; 3]>, Vec<Vec<Vector3<f64>>>)> {
    (0usize..10, 1usize..4).prop_flat_map(|(n, frames)| {
        (
            prop::collection::vec([0u32..12, 0u32..12, 0u32..12], 0..16),
            prop::collection::vec(prop::collection::vec(position(), n), frames),
        )
    })
}

/// A 3×3 grid with random edits: faces dropped or flipped, vertices moved onto others.
fn edited_grid() -> impl Strategy<Value = (Vec<[u32; 3]>, Vec<Vec<Vector3<f64>>>)> {
    let surface = grid(3, 3, 1.0, 1.0);
    let n_faces = surface.faces.len();
    let n = surface.positions.len();
    (
        prop::collection::vec(0u8..8, n_faces),
        prop::collection::vec((0..n, 0..n), 0..3),
        prop::collection::vec(-0.3..0.3f64, n),
    )
        .prop_map(move |(edits, collapses, heights)| {
            let faces = surface
                .faces
                .iter()
                .zip(&edits)
                .filter(|(_, &e)| e != 0)
                .map(|(&[a, b, c], &e)| if e == 1 { [a, c, b] } else { [a, b, c] })
                .collect();
            let mut frame: Vec<Vector3<f64>> = surface.positions.clone();
            for (p, h) in frame.iter_mut().zip(&heights) {
                p.z = *h;
            }
            for &(from, onto) in &collapses {
                frame[from] = frame[onto];
            }
            let moved = frame.iter().map(|p| p * 1.01).collect();
            (faces, vec![frame, moved])
        })
}

/// Runs every stage the arrays get through; panics are the only failure.
fn validate_everything(faces: &[[u32; 3]], frames: &[Vec<Vector3<f64>>]) {
    let n = frames[0].len();
    let intensities: Vec<Vec<f64>> = frames
        .iter()
        .map(|p| p.iter().map(|x| x.x.sin()).collect())
        .collect();
    if let Ok(mesh) = Mesh::new(n, faces.to_vec()) {
        let _ = IntrinsicGeometry::from_positions(&mesh, &frames[0]);
        if let Ok(sequence) = MeshSequence::new(mesh, frames.to_vec(), intensities.clone(), None) {
            let params = FlowParams {
                max_iterations: 200,
                ..FlowParams::default()
            };
            let _ = compute_flow(&sequence, &params);
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let k = frames.len() as u64;
    let positions: Vec<f64> = frames
        .iter()
        .flatten()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    let indices: Vec<i64> = faces.iter().flatten().map(|&i| i64::from(i)).collect();
    write_npy(
        &dir.path().join("positions.npy"),
        &[k, n as u64, 3],
        &positions,
    )
    .unwrap();
    write_npy(
        &dir.path().join("faces.npy"),
        &[faces.len() as u64, 3],
        &indices,
    )
    .unwrap();
    let grey: Vec<f64> = intensities.concat();
    write_npy(&dir.path().join("intensity.npy"), &[k, n as u64], &grey).unwrap();
    let _ = load_sequence(dir.path(), &Default::default());
    let repairing = LoadOptions {
        repair: true,
        ..LoadOptions::default()
    };
    let _ = load_sequence(dir.path(), &repairing);
}

/// Any triangles over `n` vertices: repeated, duplicated, non-manifold, inconsistent.
fn face_soup() -> impl Strategy<Value = (usize, Vec<[u32; 3]>)> {
    (3u32..12).prop_flat_map(|n| {
        (
            Just(n as usize),
            prop::collection::vec([0..n, 0..n, 0..n], 0..40),
        )
    })
}

/// OBJ-like text: statements with random numbers and references, some malformed.
fn obj_text() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        Just("1".to_string()),
        Just("-1".to_string()),
        Just("0".to_string()),
        Just("2/1".to_string()),
        Just("3//2".to_string()),
        Just("-2/-1/1".to_string()),
        Just("nan".to_string()),
        Just("1e999".to_string()),
        Just("/".to_string()),
        Just("x".to_string()),
        (-5i64..9).prop_map(|i| i.to_string()),
        (-1.0..1.0f64).prop_map(|x| x.to_string()),
    ];
    let keyword = prop::sample::select(vec!["v", "vt", "f", "usemtl", "mtllib", "#", "g", ""]);
    let line = (keyword, prop::collection::vec(token, 0..8))
        .prop_map(|(k, tokens)| format!("{k} {}", tokens.join(" ")));
    prop::collection::vec(line, 0..24).prop_map(|lines| lines.join("\n"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn arbitrary_obj_text_never_panics(text in obj_text()) {
        let dir = tempfile::tempdir().unwrap();
        for k in 0..2 {
            std::fs::write(dir.path().join(format!("frame_{k}.obj")), &text).unwrap();
        }
        let _ = load_sequence(dir.path(), &Default::default());
    }

    #[test]
    fn arbitrary_arrays_never_panic((faces, frames) in arbitrary_arrays()) {
        validate_everything(&faces, &frames);
    }

    #[test]
    fn edited_grids_never_panic((faces, frames) in edited_grid()) {
        validate_everything(&faces, &frames);
    }

    #[test]
    fn repaired_face_soups_are_oriented_manifolds((n, faces) in face_soup()) {
        let repaired = repair(n, &faces);
        match Mesh::new(repaired.vertex_origin.len(), repaired.faces.clone()) {
            Ok(_) => {}
            Err(ConnectivityError::NoFaces) => prop_assert!(repaired.faces.is_empty()),
            Err(e) => prop_assert!(false, "{e} for {faces:?}"),
        }
        // Every face is an input face (perhaps flipped) over split copies of its vertices.
        for (face, &origin) in repaired.faces.iter().zip(&repaired.face_origin) {
            let mut back = face.map(|v| repaired.vertex_origin[v as usize]);
            let mut input = faces[origin as usize];
            back.sort_unstable();
            input.sort_unstable();
            prop_assert_eq!(back, input);
        }
    }
}
