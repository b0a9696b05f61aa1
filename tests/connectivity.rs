//! Connectivity: tables, fans and boundary on good meshes; a typed error for every bad one.

use meshflow::mesh::{ConnectivityError, Mesh};
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
    let err = Mesh::new(11, faces).unwrap_err();
    assert!(
        matches!(err, ConnectivityError::NonManifoldVertex { vertex: 0, .. }),
        "{err:?}"
    );
}

#[test]
fn rejects_isolated_vertex() {
    let err = Mesh::new(4, vec![[0, 1, 2]]).unwrap_err();
    assert_eq!(err, ConnectivityError::IsolatedVertex { vertex: 3 });
}
