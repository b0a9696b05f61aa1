//! Connectivity: tables, fans and boundary on good meshes; a typed error for every bad one;
//! orientation and repair of face lists that are not oriented manifolds.

use meshflow::mesh::{orient, repair, ConnectivityError, Mesh, RepairReport};
use meshflow::shapes::{grid, icosphere, torus};

#[test]
fn closed_meshes_have_euler_characteristic_and_full_fans() {
    let sphere = icosphere(2).mesh().unwrap();
    assert_eq!(
        (sphere.n_vertices(), sphere.n_edges(), sphere.n_faces()),
        (162, 480, 320)
    );
    assert_eq!(sphere.euler_characteristic(), 2);
    assert!(sphere.is_closed());
    let ring = torus(2.0, 1.0, 12, 8).mesh().unwrap();
    assert_eq!(ring.euler_characteristic(), 0);
    assert!(ring.is_closed());
    for mesh in [&sphere, &ring] {
        for h in 0..mesh.n_halfedges() {
            let t = mesh.twin(h).unwrap();
            assert_eq!(mesh.twin(t), Some(h));
            let [i, j] = mesh.halfedge_vertices(h);
            assert_eq!(mesh.halfedge_vertices(t), [j, i]);
            assert_eq!(mesh.halfedge_edge(h), mesh.halfedge_edge(t));
        }
    }
}

/// Consecutive corners of a fan share an edge: the second edge of one is the first of the next.
fn assert_fans_are_counter_clockwise(mesh: &Mesh) {
    for i in 0..mesh.n_vertices() {
        let fan = mesh.vertex_fan(i);
        for pair in fan.windows(2) {
            let [_, k] = mesh.halfedge_vertices(pair[1].first_halfedge());
            let [came_from, to] = mesh.halfedge_vertices(pair[0].incoming_halfedge());
            assert_eq!(to as usize, i);
            assert_eq!(
                came_from, k,
                "vertex {i}: fan is not ordered counter-clockwise"
            );
        }
    }
}

#[test]
fn fans_are_ordered_and_boundary_fans_start_at_the_boundary() {
    let sphere = icosphere(1).mesh().unwrap();
    assert_fans_are_counter_clockwise(&sphere);
    let patch = grid(4, 3, 1.0, 1.0).mesh().unwrap();
    assert_fans_are_counter_clockwise(&patch);
    let boundary: Vec<usize> = (0..patch.n_vertices())
        .filter(|&i| patch.is_boundary_vertex(i))
        .collect();
    assert_eq!(boundary.len(), 2 * (4 + 3));
    for &i in &boundary {
        let fan = patch.vertex_fan(i);
        assert!(patch.is_boundary_halfedge(fan[0].first_halfedge()));
        assert!(patch.is_boundary_halfedge(fan[fan.len() - 1].incoming_halfedge()));
    }
    // Interior grid vertex (1, 1): four axis neighbours and two along the cell diagonals.
    assert_eq!(patch.vertex_fan(6).len(), 6);
}

#[test]
fn rejects_empty_face_list() {
    assert_eq!(
        Mesh::new(3, vec![]).unwrap_err(),
        ConnectivityError::NoFaces
    );
}

#[test]
fn rejects_out_of_range_index() {
    let err = Mesh::new(3, vec![[0, 1, 2], [0, 2, 3]]).unwrap_err();
    assert_eq!(
        err,
        ConnectivityError::IndexOutOfRange {
            face: 1,
            index: 3,
            n_vertices: 3
        }
    );
    assert!(err.to_string().contains("face 1"));
}

#[test]
fn rejects_repeated_vertex_in_a_face() {
    let err = Mesh::new(4, vec![[0, 1, 2], [3, 1, 3]]).unwrap_err();
    assert_eq!(
        err,
        ConnectivityError::RepeatedVertex { face: 1, vertex: 3 }
    );
}

#[test]
fn rejects_edge_with_three_faces() {
    let err = Mesh::new(5, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]).unwrap_err();
    assert!(
        matches!(
            err,
            ConnectivityError::NonManifoldEdge {
                vertices: [0, 1],
                n_faces: 3,
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn rejects_inconsistent_orientation() {
    let mut faces = grid(2, 2, 1.0, 1.0).faces;
    faces[3].swap(1, 2);
    let err = Mesh::new(9, faces).unwrap_err();
    assert!(
        matches!(err, ConnectivityError::InconsistentOrientation { .. }),
        "{err:?}"
    );
}

#[test]
fn rejects_bowtie_vertex_with_two_boundary_fans() {
    // Two triangles touching only at vertex 0.
    let err = Mesh::new(5, vec![[0, 1, 2], [0, 3, 4]]).unwrap_err();
    assert_eq!(
        err,
        ConnectivityError::NonManifoldVertex {
            vertex: 0,
            n_fans: 2
        }
    );
    assert_eq!(
        err.describe(|v| format!("file vertex {}", v + 10)),
        "file vertex 10 has 2 separate fans of faces (non-manifold vertex)"
    );
}

#[test]
fn rejects_vertex_joining_two_closed_fans() {
    // Two octahedra sharing their pole 0: the other pole is o + 5, the equator o + 1..o + 4.
    let octahedron = |o: u32| -> Vec<[u32; 3]> {
        let ring = [o + 1, o + 2, o + 3, o + 4];
        (0..4)
            .flat_map(|k| {
                let (a, b) = (ring[k], ring[(k + 1) % 4]);
                [[0, a, b], [o + 5, b, a]]
            })
            .collect()
    };
    assert!(Mesh::new(6, octahedron(0)).unwrap().is_closed());
    let mut faces = octahedron(0);
    faces.extend(octahedron(5));
    let err = Mesh::new(11, faces.clone()).unwrap_err();
    assert_eq!(
        err,
        ConnectivityError::NonManifoldVertex {
            vertex: 0,
            n_fans: 2
        }
    );
    // Three octahedra on one pole: three closed fans, counted.
    faces.extend(octahedron(10));
    let err = Mesh::new(16, faces).unwrap_err();
    assert_eq!(
        err,
        ConnectivityError::NonManifoldVertex {
            vertex: 0,
            n_fans: 3
        }
    );
}

#[test]
fn rejects_isolated_vertex() {
    let err = Mesh::new(4, vec![[0, 1, 2]]).unwrap_err();
    assert_eq!(err, ConnectivityError::IsolatedVertex { vertex: 3 });
}

/// A Möbius strip of `n` quads (two triangles each): top vertices `0..n`, bottom `n..2n`, the
/// last quad glued to the first with a half twist.
fn moebius_strip(n: u32) -> Vec<[u32; 3]> {
    (0..n)
        .flat_map(|i| {
            let (t0, b0) = (i, n + i);
            let (t1, b1) = match i + 1 {
                j if j < n => (j, n + j),
                _ => (n, 0), // the twist: top meets bottom
            };
            [[t0, b0, b1], [t0, b1, t1]]
        })
        .collect()
}

#[test]
fn orient_flips_the_minority_of_each_component() {
    let square = grid(2, 2, 1.0, 1.0).faces; // 8 faces over vertices 0..9
    let flipped = |[a, b, c]: [u32; 3]| [a, c, b];
    // Component A: face 3 flipped; component B (vertices 9..18): all but faces 0 and 5 flipped.
    let mut faces: Vec<[u32; 3]> = square.clone();
    faces[3] = flipped(faces[3]);
    let b_faces: Vec<[u32; 3]> = square.iter().map(|f| f.map(|v| v + 9)).collect();
    faces.extend(
        b_faces
            .iter()
            .enumerate()
            .map(|(k, &f)| if k == 0 || k == 5 { f } else { flipped(f) }),
    );
    let mut oriented = faces.clone();
    assert_eq!(orient(&mut oriented), Ok(3));
    let mut expected = square.clone();
    expected.extend(b_faces.iter().map(|&f| flipped(f)));
    assert_eq!(oriented, expected);
    assert!(Mesh::new(18, oriented.clone()).is_ok());
    // An oriented mesh is left alone.
    assert_eq!(orient(&mut oriented), Ok(0));
    assert_eq!(oriented, expected);
}

#[test]
fn orient_refuses_what_only_repair_can_fix() {
    let mut strip = moebius_strip(5);
    let before = strip.clone();
    let err = orient(&mut strip).unwrap_err();
    assert!(
        matches!(err, ConnectivityError::NonOrientable { .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("not orientable"), "{err}");
    assert_eq!(strip, before, "nothing flipped on failure");
    let mut fin = vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]];
    assert!(matches!(
        orient(&mut fin),
        Err(ConnectivityError::NonManifoldEdge { n_faces: 3, .. })
    ));
    assert_eq!(
        orient(&mut [[0, 1, 1]]),
        Err(ConnectivityError::RepeatedVertex { face: 0, vertex: 1 })
    );
}

#[test]
fn repair_leaves_an_oriented_manifold_as_it_is() {
    let sphere = icosphere(1);
    let repaired = repair(sphere.positions.len(), &sphere.faces);
    assert_eq!(repaired.faces, sphere.faces);
    assert_eq!(repaired.report, RepairReport::default());
    assert!(repaired.report.is_empty());
    let identity: Vec<u32> = (0..sphere.positions.len() as u32).collect();
    assert_eq!(repaired.vertex_origin, identity);
}

#[test]
fn repair_splits_a_bowtie_vertex_and_drops_unused_vertices() {
    // Vertex 5 is unused; vertex 0 joins two triangles at a point.
    let repaired = repair(6, &[[0, 1, 2], [0, 3, 4]]);
    assert_eq!(repaired.faces, vec![[0, 2, 3], [1, 4, 5]]);
    assert_eq!(repaired.vertex_origin, vec![0, 0, 1, 2, 3, 4]);
    assert_eq!(repaired.face_origin, vec![0, 1]);
    assert_eq!(
        repaired.report,
        RepairReport {
            split_vertices: 1,
            added_vertices: 1,
            ..RepairReport::default()
        }
    );
}

#[test]
fn repair_cuts_an_edge_shared_by_two_closed_surfaces() {
    // Two tetrahedra sharing edge (0, 1): it has four faces.
    let tetrahedron = |[a, b, c, d]: [u32; 4]| vec![[a, b, c], [a, d, b], [a, c, d], [b, d, c]];
    let mut faces = tetrahedron([0, 1, 2, 3]);
    faces.extend(tetrahedron([0, 1, 4, 5]));
    assert!(matches!(
        Mesh::new(6, faces.clone()),
        Err(ConnectivityError::NonManifoldEdge { n_faces: 4, .. })
    ));
    let repaired = repair(6, &faces);
    // Vertices 0 and 1 split, each tetrahedron keeping its own copy of the edge.
    assert_eq!(repaired.vertex_origin, vec![0, 0, 1, 1, 2, 3, 4, 5]);
    assert_eq!(
        repaired.faces,
        vec![
            [0, 2, 4],
            [0, 5, 2],
            [0, 4, 5],
            [2, 5, 4],
            [1, 3, 6],
            [1, 7, 3],
            [1, 6, 7],
            [3, 7, 6]
        ]
    );
    assert_eq!(
        repaired.report,
        RepairReport {
            non_manifold_edges: 1,
            split_vertices: 2,
            added_vertices: 2,
            ..RepairReport::default()
        }
    );
    let mesh = Mesh::new(8, repaired.faces).unwrap();
    assert!(mesh.is_closed());
    assert_eq!(mesh.euler_characteristic(), 4, "two spheres");
}

#[test]
fn repair_removes_degenerate_and_duplicate_faces_and_orients() {
    let mut faces = grid(2, 1, 1.0, 1.0).faces; // 4 faces over 6 vertices
    faces[1].swap(1, 2); // a flipped face: the other three win
    faces.insert(2, [4, 4, 1]);
    faces.push([faces[0][2], faces[0][1], faces[0][0]]); // face 0 again, reversed
    let repaired = repair(6, &faces);
    assert_eq!(repaired.face_origin, vec![0, 1, 3, 4]);
    assert_eq!(repaired.faces, grid(2, 1, 1.0, 1.0).faces);
    assert_eq!(
        repaired.report,
        RepairReport {
            degenerate_faces: 1,
            duplicate_faces: 1,
            flipped_faces: 1,
            ..RepairReport::default()
        }
    );
}

#[test]
fn repair_cuts_a_moebius_strip_open() {
    let strip = moebius_strip(5);
    let repaired = repair(10, &strip);
    assert_eq!(repaired.report.orientation_cuts, 1);
    assert_eq!(repaired.report.split_vertices, 2, "the cut edge's ends");
    assert_eq!(repaired.faces.len(), 10);
    let mesh = Mesh::new(repaired.vertex_origin.len(), repaired.faces).unwrap();
    assert_eq!(mesh.euler_characteristic(), 1, "a disc");
    assert_eq!(mesh.n_vertices(), 12);
}

#[test]
fn connected_components_list_the_vertices_of_each_piece() {
    // A square (two faces) and, apart from it, a triangle listed first.
    let mesh = Mesh::new(7, vec![[4, 5, 6], [0, 1, 2], [0, 2, 3]]).unwrap();
    assert_eq!(
        mesh.connected_components(),
        vec![vec![0, 1, 2, 3], vec![4, 5, 6]]
    );
}
