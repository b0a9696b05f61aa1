//! Folds of a triangle mesh in R³ and their smoothing out.
//!
//! A fold is where triangles cross over their neighbours: two triangles of an edge that face
//! opposite ways ([`folded_edges`]), or a triangle whose normal turned over against an earlier
//! state of the mesh (tracking's flip). Both are local tangles, left where vertices moved by
//! different amounts (to the middle of a layer of nuclei, to the next frame's surface), and
//! both are undone where they are by umbrella smoothing: each vertex of the fold, and a few
//! rings around it, moves halfway to the mean of its neighbours, then onto the surface it must
//! stay on ([`smooth_out`]), round after round until nothing is folded.

use crate::mesh::{Mesh, VertexNeighbours};
use nalgebra::Vector3;
use rayon::prelude::*;

/// The vertices of the edges of `mesh` at `positions` whose two triangles face opposite ways
/// (a dihedral angle beyond 90° from flat), two per edge.
pub fn folded_edges(mesh: &Mesh, positions: &[Vector3<f64>]) -> Vec<usize> {
    (folded_halfedges(mesh, positions).into_iter())
        .flat_map(|h| mesh.halfedge_vertices(h).map(|v| v as usize))
        .collect()
}

/// The edges of [`folded_edges`], each as the lesser of its two halfedges, in increasing order.
pub fn folded_halfedges(mesh: &Mesh, positions: &[Vector3<f64>]) -> Vec<usize> {
    let normal = |f: usize| {
        let [a, b, c] = mesh.faces()[f].map(|v| positions[v as usize]);
        (b - a).cross(&(c - a))
    };
    (0..mesh.n_halfedges())
        .filter(|&h| {
            (mesh.twin(h)).is_some_and(|t| t > h && normal(h / 3).dot(&normal(t / 3)) < 0.0)
        })
        .collect()
}

/// Smooths out the folds that `folded` finds (the vertices at fault) at `positions`: those
/// vertices and `rings` rings around them move halfway to the mean of their neighbours, then
/// to `project(vertex, position)` (onto the surface they must stay on; boundary vertices do
/// not move), a round at a time, for at most `rounds` rounds. Returns how many rounds it took
/// (`rounds + 1` where folds are left).
pub fn smooth_out(
    mesh: &Mesh,
    neighbours: &VertexNeighbours,
    positions: &mut [Vector3<f64>],
    rounds: usize,
    rings: usize,
    folded: impl Fn(&[Vector3<f64>]) -> Vec<usize>,
    project: impl Fn(usize, Vector3<f64>) -> Vector3<f64> + Sync,
) -> usize {
    for round in 0..rounds {
        let at_fault = folded(positions);
        if at_fault.is_empty() {
            return round;
        }
        let mut region = vec![false; positions.len()];
        at_fault.into_iter().for_each(|v| region[v] = true);
        for _ in 0..rings {
            let grown: Vec<usize> = (0..region.len())
                .filter(|&v| region[v])
                .flat_map(|v| neighbours.of(v).iter().map(|&n| n as usize))
                .collect();
            grown.into_iter().for_each(|v| region[v] = true);
        }
        let from = &*positions;
        let moved: Vec<(usize, Vector3<f64>)> = (0..region.len())
            .into_par_iter()
            .filter(|&v| region[v] && !mesh.is_boundary_vertex(v))
            .filter(|&v| !neighbours.of(v).is_empty())
            .map(|v| {
                let around = neighbours.of(v);
                let sum: Vector3<f64> = around.iter().map(|&n| from[n as usize]).sum();
                let mean = sum / around.len() as f64;
                (v, project(v, from[v] + 0.5 * (mean - from[v])))
            })
            .collect();
        moved.into_iter().for_each(|(v, x)| positions[v] = x);
    }
    match folded(positions).is_empty() {
        true => rounds,
        false => rounds + 1,
    }
}

/// The rings [`smooth_out_widening`] moves around each fold, tried in turn while folds are
/// left: a fold its own rings cannot undo (a vertex that took a far closest point, a sliver
/// between two creases) gets a wider region.
pub const WIDENING_RINGS: [usize; 3] = [2, 4, 8];

/// [`smooth_out`] with [`WIDENING_RINGS`], `rounds` rounds each; whether no fold is left.
pub fn smooth_out_widening(
    mesh: &Mesh,
    neighbours: &VertexNeighbours,
    positions: &mut [Vector3<f64>],
    rounds: usize,
    folded: impl Fn(&[Vector3<f64>]) -> Vec<usize>,
    project: impl Fn(usize, Vector3<f64>) -> Vector3<f64> + Sync,
) -> bool {
    WIDENING_RINGS.iter().any(|&rings| {
        smooth_out(
            mesh, neighbours, positions, rounds, rings, &folded, &project,
        ) <= rounds
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vertex_pushed_through_its_ring_is_pulled_back() {
        let sphere = crate::shapes::icosphere(2);
        let mesh = sphere.mesh().unwrap();
        let neighbours = VertexNeighbours::open(&mesh);
        let mut positions = sphere.positions.clone();
        assert!(folded_edges(&mesh, &positions).is_empty());
        // Vertex 0 pushed through the sphere: its fan turns inside out.
        positions[0] *= -0.2;
        assert!(!folded_edges(&mesh, &positions).is_empty());
        let onto_sphere = |_: usize, x: Vector3<f64>| x.normalize();
        let rounds = smooth_out(
            &mesh,
            &neighbours,
            &mut positions,
            50,
            2,
            |x| folded_edges(&mesh, x),
            onto_sphere,
        );
        assert!(rounds <= 50, "{rounds}");
        assert!(folded_edges(&mesh, &positions).is_empty());
        assert!(positions.iter().all(|x| (x.norm() - 1.0).abs() < 1e-12));
    }
}
