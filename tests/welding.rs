//! Welding: seam copies are joined (within the tolerance, in every frame); a surface that
//! touches itself, at a point or along a line, keeps its touching vertices apart.

use meshflow::io::{load_mesh, load_sequence, write_npy, write_obj, LoadOptions, LoadWarning};
use meshflow::io::{LoadedMesh, VertexMap};
use meshflow::shapes::grid;
use nalgebra::Vector3;
use std::path::Path;

/// A 3 × 2 grid of cells (12 vertices) whose faces right of column 1 use copies 12..15 of the
/// column's vertices 1, 5, 9 (moved by `offset`): a seam, as exporters write one.
fn seam_grid(offset: f64) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let surface = grid(3, 2, 3.0, 2.0);
    let mut positions = surface.positions.clone();
    let column = [1u32, 5, 9];
    positions.extend(column.map(|v| positions[v as usize] + Vector3::new(offset, 0.0, 0.0)));
    let faces = surface
        .faces
        .iter()
        .map(|face| {
            // Cells right of the seam have a vertex with x > 1.
            let right = face.iter().any(|&v| surface.positions[v as usize].x > 1.0);
            face.map(|v| match column.iter().position(|&c| c == v) {
                Some(k) if right => 12 + k as u32,
                _ => v,
            })
        })
        .collect();
    (positions, faces)
}

fn load_obj(
    dir: &Path,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    options: &LoadOptions,
) -> LoadedMesh {
    let path = dir.join("mesh.obj");
    write_obj(&path, positions, faces, None).unwrap();
    load_mesh(&path, options).unwrap()
}

fn map_of(loaded: &LoadedMesh) -> Vec<i64> {
    loaded.vertex_map.to_npy()
}

#[test]
fn seam_copies_are_welded_within_the_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let plain = grid(3, 2, 3.0, 2.0);
    // Copies 1e-12 apart (the diagonal is √13): welded at the default tolerance 1e-9.
    let (positions, faces) = seam_grid(1e-12);
    let loaded = load_obj(dir.path(), &positions, &faces, &LoadOptions::default());
    assert_eq!(
        loaded.mesh.faces(),
        plain.faces.as_slice(),
        "the grid itself"
    );
    assert_eq!(
        map_of(&loaded),
        vec![0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 1, 5, 9]
    );
    assert_eq!(loaded.vertex_map.n_welded(), 3);
    assert_eq!(
        loaded.positions, plain.positions,
        "the first copy's positions"
    );
    assert_eq!(loaded.mesh.euler_characteristic(), 1);
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);

    // Bitwise welding (tolerance 0) keeps them apart: the seam cuts the grid in two.
    let bitwise = LoadOptions {
        weld_tolerance: 0.0,
        ..LoadOptions::default()
    };
    let cut = load_obj(dir.path(), &positions, &faces, &bitwise);
    assert!(cut.vertex_map.is_identity());
    assert_eq!(cut.mesh.n_vertices(), 15);
    assert_eq!(cut.mesh.euler_characteristic(), 2);
    let boundary = |m: &LoadedMesh| {
        (0..m.mesh.n_vertices())
            .filter(|&i| m.mesh.is_boundary_vertex(i))
            .count()
    };
    assert_eq!((boundary(&loaded), boundary(&cut)), (10, 14));
    // Exact copies weld bitwise too.
    let (positions, faces) = seam_grid(0.0);
    let exact = load_obj(dir.path(), &positions, &faces, &bitwise);
    assert_eq!(exact.mesh.faces(), plain.faces.as_slice());
    let unwelded = LoadOptions {
        weld: false,
        ..LoadOptions::default()
    };
    let kept = load_obj(dir.path(), &positions, &faces, &unwelded);
    assert_eq!(kept.mesh.n_vertices(), 15);
}

/// An octahedron of radius 1 around `centre`, its vertices numbered from `first`:
/// `first + 0..6` = `+x, −x, +y, −y, +z, −z`.
fn octahedron(centre: Vector3<f64>, first: u32) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let axes = [
        Vector3::x(),
        -Vector3::x(),
        Vector3::y(),
        -Vector3::y(),
        Vector3::z(),
        -Vector3::z(),
    ];
    let positions = axes.iter().map(|a| centre + a).collect();
    let faces = [
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ]
    .iter()
    .map(|f: &[u32; 3]| f.map(|v| v + first))
    .collect();
    (positions, faces)
}

/// Positions of both, faces of the first, faces of the second.
type TwoSurfaces = (Vec<Vector3<f64>>, Vec<[u32; 3]>, Vec<[u32; 3]>);

fn two_octahedra(a: Vector3<f64>, b: Vector3<f64>) -> TwoSurfaces {
    let (mut positions, faces_a) = octahedron(a, 0);
    let (positions_b, faces_b) = octahedron(b, 6);
    positions.extend(positions_b);
    (positions, faces_a, faces_b)
}

#[test]
fn a_surface_touching_itself_at_a_point_stays_apart() {
    let dir = tempfile::tempdir().unwrap();
    // A's +x (vertex 0) and B's −x (vertex 7) meet at (1, 0, 0); nothing else coincides.
    let (mut positions, mut faces, faces_b) =
        two_octahedra(Vector3::zeros(), Vector3::new(2.0, 0.0, 0.0));
    faces.extend(faces_b.iter().copied());
    let loaded = load_obj(dir.path(), &positions, &faces, &LoadOptions::default());
    assert!(loaded.vertex_map.is_identity());
    assert_eq!(loaded.mesh.euler_characteristic(), 4, "two spheres");
    let touching = LoadWarning::TouchingVertices {
        file: dir.path().join("mesh.obj"),
        count: 1,
        first: [0, 7],
    };
    assert_eq!(loaded.warnings, vec![touching]);

    // A pinched sphere with a seam through the pinch: A's +x is also split along a seam (its
    // faces 3 and 7 use copy 12). The seam copy is welded, the touching vertex is not.
    positions.push(positions[0]);
    for f in [3, 7] {
        faces[f] = faces[f].map(|v| if v == 0 { 12 } else { v });
    }
    let loaded = load_obj(dir.path(), &positions, &faces, &LoadOptions::default());
    let mut expected: Vec<i64> = (0..12).collect();
    expected.push(0);
    assert_eq!(map_of(&loaded), expected);
    assert_eq!(loaded.mesh.euler_characteristic(), 4);
    assert!(loaded.mesh.is_closed());
    assert!(matches!(
        loaded.warnings[..],
        [LoadWarning::TouchingVertices {
            count: 2,
            first: [0, 7],
            ..
        }]
    ));
}

#[test]
fn sheets_touching_along_a_line_stay_apart() {
    let dir = tempfile::tempdir().unwrap();
    // B is A mirrored across the plane x + y = 1: A's edge from +x to +y (vertices 0, 2) is
    // B's (6, 8). Welding them would put four faces on that edge.
    let (positions, mut faces, faces_b) = two_octahedra(Vector3::zeros(), Vector3::zeros());
    let normal = Vector3::new(1.0, 1.0, 0.0);
    let mirrored: Vec<Vector3<f64>> = positions
        .iter()
        .enumerate()
        .map(|(i, &p)| match i {
            0..6 => p,
            _ => p - (normal.dot(&p) - 1.0) * normal,
        })
        .collect();
    assert_eq!((mirrored[6], mirrored[8]), (mirrored[0], mirrored[2]));
    faces.extend(faces_b);
    let loaded = load_obj(dir.path(), &mirrored, &faces, &LoadOptions::default());
    assert!(loaded.vertex_map.is_identity());
    assert_eq!(loaded.mesh.euler_characteristic(), 4);
    assert!(matches!(
        loaded.warnings[..],
        [LoadWarning::TouchingVertices {
            count: 2,
            first: [0, 6],
            ..
        }]
    ));
}

/// Writes an NPY sequence of `frames` over `faces`, grey value = x.
fn npy_sequence(dir: &Path, frames: &[Vec<Vector3<f64>>], faces: &[[u32; 3]]) {
    let (k, n) = (frames.len() as u64, frames[0].len() as u64);
    let coordinates: Vec<f64> = frames
        .iter()
        .flatten()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    write_npy(&dir.join("positions.npy"), &[k, n, 3], &coordinates).unwrap();
    let indices: Vec<i64> = faces.iter().flatten().map(|&v| i64::from(v)).collect();
    write_npy(&dir.join("faces.npy"), &[faces.len() as u64, 3], &indices).unwrap();
    let grey: Vec<f64> = frames.iter().flatten().map(|p| p.x).collect();
    write_npy(&dir.join("intensity.npy"), &[k, n], &grey).unwrap();
}

#[test]
fn copies_weld_only_when_they_coincide_in_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let (positions, faces) = seam_grid(0.0);
    let lifted: Vec<Vector3<f64>> = positions
        .iter()
        .map(|p| p + Vector3::new(0.0, 0.0, 0.1 * p.x))
        .collect();
    npy_sequence(dir.path(), &[positions.clone(), lifted.clone()], &faces);
    let welded = load_sequence(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(welded.sequence.mesh().n_vertices(), 12);
    assert_eq!(welded.vertex_map.n_welded(), 3);

    // In frame 1 copy 14 (of vertex 9) moves away: the copies of 1 and 5 still weld.
    let mut torn = lifted;
    torn[14].z += 0.5;
    npy_sequence(dir.path(), &[positions, torn], &faces);
    let loaded = load_sequence(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(
        loaded.vertex_map.to_npy(),
        vec![0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 1, 5, 12]
    );
    assert_eq!(loaded.sequence.mesh().n_vertices(), 13);
}

#[test]
fn vertex_map_moves_values_between_numberings() {
    // File vertices 0..5: 3 is a copy of 1, 4 is dropped.
    let map = VertexMap::from_mesh_vertices(&[Some(0), Some(1), Some(2), Some(1), None]).unwrap();
    assert_eq!((map.n_file_vertices(), map.n_mesh_vertices()), (5, 3));
    assert_eq!((map.n_welded(), map.n_dropped()), (1, 1));
    assert_eq!(map.representative(1), 1);
    assert_eq!(
        map.mean_values(&[1.0, 2.0, 3.0, 4.0, 99.0]),
        vec![1.0, 3.0, 3.0]
    );
    let rows = map.file_rows(&[10.0, 20.0, 30.0], f64::NAN);
    assert_eq!(rows[..4], [10.0, 20.0, 30.0, 20.0]);
    assert!(rows[4].is_nan());
    assert_eq!(map.to_npy(), vec![0, 1, 2, 1, -1]);
    assert!(!map.is_identity());
    assert!(VertexMap::identity(3).is_identity());
    // Mesh vertex 1 has no file vertex: not a map.
    assert!(VertexMap::from_mesh_vertices(&[Some(0), Some(2)]).is_none());
}

#[test]
fn tolerances_that_join_neighbours_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let surface = grid(20, 20, 1.0, 1.0);
    let path = dir.path().join("mesh.obj");
    write_obj(&path, &surface.positions, &surface.faces, None).unwrap();
    let message = |tolerance: f64| {
        let options = LoadOptions {
            weld_tolerance: tolerance,
            ..LoadOptions::default()
        };
        load_mesh(&path, &options)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    // Grid spacing 0.05 is 0.035 of the diagonal: at 0.2, every vertex has dozens of partners.
    let refused = message(0.2).unwrap_err();
    assert!(
        refused.contains("mesh.obj: --weld-tolerance 0.2 makes more than 7056 pairs"),
        "{refused}"
    );
    // At 0.02 nothing is close: the grid loads as it is.
    assert_eq!(message(0.02), Ok(()));
    for bad in [-1.0, f64::NAN, f64::INFINITY, 1.5, 1e300] {
        let refused = message(bad).unwrap_err();
        assert!(
            refused.contains(&format!("must be a number from 0 to 1 (relative to frame 0's bounding-box diagonal), got {bad:e}")),
            "{refused}"
        );
    }
}

/// A grey-value file for welded frames may have a row per file vertex (15 here) or per mesh
/// vertex (12: what `load_sequence` returns); both give the same image, and any other length
/// is refused with both counts named.
#[test]
fn intensity_files_may_follow_the_files_or_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let (positions, faces) = seam_grid(0.0);
    for k in 0..2 {
        let frame: Vec<Vector3<f64>> = positions
            .iter()
            .map(|p| p + Vector3::new(0.0, 0.0, 0.1 * k as f64 * p.x))
            .collect();
        write_obj(&dir.path().join(format!("f{k}.obj")), &frame, &faces, None).unwrap();
    }
    let grey = |p: &Vector3<f64>, k: usize| p.x + 0.3 * p.y + 0.1 * k as f64;
    let file_rows: Vec<f64> = (0..2)
        .flat_map(|k| positions.iter().map(move |p| grey(p, k)))
        .collect();
    let mesh_rows: Vec<f64> = (0..2)
        .flat_map(|k| positions[..12].iter().map(move |p| grey(p, k)))
        .collect();
    let load = |rows: &[f64], n: u64| {
        let file = dir.path().join(format!("grey_{n}.npy"));
        write_npy(&file, &[2, n], rows).unwrap();
        let options = LoadOptions {
            intensity: Some(file),
            ..LoadOptions::default()
        };
        load_sequence(dir.path(), &options)
    };
    let by_file = load(&file_rows, 15).unwrap();
    let by_mesh = load(&mesh_rows, 12).unwrap();
    assert_eq!(by_file.sequence.mesh().n_vertices(), 12);
    for k in 0..2 {
        assert_eq!(
            by_file.sequence.intensities(k),
            by_mesh.sequence.intensities(k)
        );
    }
    let error = load(&file_rows[..26], 13).unwrap_err().to_string();
    assert!(
        error.contains("grey_13.npy")
            && error.contains("expected (2, 15) = (frames, vertices in the files) or (2, 12)")
            && error.contains("as load_sequence returns them"),
        "{error}"
    );
    // NaN in the grey-value file is reported in that file, at the vertex of its numbering.
    let mut broken = mesh_rows.clone();
    broken[12 + 7] = f64::NAN;
    let error = load(&broken, 12).unwrap_err().to_string();
    assert!(
        error.contains("grey_12.npy") && error.contains("frame 1") && error.contains("vertex 7"),
        "{error}"
    );
}
