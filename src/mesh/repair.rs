//! Making a face list an oriented manifold: consistent orientation ([`orient`]) and repair of
//! non-manifold edges and vertices ([`repair`]), from connectivity alone (no positions).
//!
//! An edge with exactly two faces is *manifold*; the faces of a component are the faces
//! connected through manifold edges.
//!
//! # Orientation
//!
//! Flipping a face reverses it, `[a, b, c] → [a, c, b]`. Per component, a breadth-first search
//! from its lowest-numbered face flips each face reached so that it traverses the manifold edge
//! it was reached through opposite to its neighbour. If that flipped more than half of the
//! component's faces, the flips are inverted: the orientation of the majority of the faces is
//! kept (on a tie, the lowest face's). A manifold edge whose two faces still traverse it in the
//! same direction is an *orientation conflict*: the component is not orientable (a Möbius
//! strip). [`orient`] reports it as an error, [`repair`] cuts the edge.
//!
//! # Repair
//!
//! 1. Faces with a repeated vertex are removed, and faces with the same three vertices as an
//!    earlier face (in any order).
//! 2. The faces are oriented as above. Edges with three or more faces and orientation conflicts
//!    are *cut*; every other manifold edge *joins* its two faces.
//! 3. The corners at each vertex are grouped into *pieces*: corners connected through joined
//!    edges around the vertex. A vertex with several pieces (several fans, or faces across a
//!    cut edge) is split: every piece becomes a vertex of its own.
//!
//! The result is an oriented manifold that [`Mesh::new`](super::Mesh::new) accepts (when a face
//! is left). Around a vertex, a piece is a chain of consistently oriented corners: a cycle, or a
//! path whose two free edges it traverses in opposite directions. So two faces that share both
//! pieces of a cut edge are the two ends of such paths and meet there consistently, and no
//! three faces can share them.
//!
//! Numbering: new vertices follow the original vertices' order; the pieces of one vertex are
//! numbered in the order of their first face. A vertex that no face uses gets no new vertex.
//! Faces keep their order.

use super::validate::{check_repeated_vertices, edge_of_key, halfedge_vertices, halfedges_by_edge};
use super::{ConnectivityError, NO_HALFEDGE};
use std::collections::{HashSet, VecDeque};

/// What [`repair`] changed; all zero for an oriented manifold without unused vertices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RepairReport {
    /// Faces removed because they name a vertex twice.
    pub degenerate_faces: usize,
    /// Faces removed because an earlier face has the same three vertices.
    pub duplicate_faces: usize,
    /// Faces flipped to agree with their neighbours.
    pub flipped_faces: usize,
    /// Edges with three or more faces (cut).
    pub non_manifold_edges: usize,
    /// Orientation conflicts (cut): the surface was not orientable.
    pub orientation_cuts: usize,
    /// Vertices split into several.
    pub split_vertices: usize,
    /// Vertices the splits added.
    pub added_vertices: usize,
}

impl RepairReport {
    /// Whether the repair changed anything beyond orientation.
    pub fn is_empty(&self) -> bool {
        *self
            == Self {
                flipped_faces: self.flipped_faces,
                ..Self::default()
            }
    }
}

/// A repaired face list (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Repaired {
    /// Oriented manifold faces over the new vertices.
    pub faces: Vec<[u32; 3]>,
    /// `vertex_origin[v]`: the original vertex of new vertex `v`.
    pub vertex_origin: Vec<u32>,
    /// `face_origin[f]`: the index of new face `f` in the input.
    pub face_origin: Vec<u32>,
    pub report: RepairReport,
}

/// Flips faces so that every manifold edge is traversed in opposite directions, keeping the
/// majority orientation of each component (see the module docs), and returns how many faces
/// were flipped. Fails, changing nothing, on a face with a repeated vertex, an edge with three
/// or more faces, or a non-orientable component.
pub fn orient(faces: &mut [[u32; 3]]) -> Result<usize, ConnectivityError> {
    check_repeated_vertices(faces)?;
    let keyed = halfedges_by_edge(faces);
    if let Some(run) = keyed.chunk_by(|a, b| a.0 == b.0).find(|run| run.len() > 2) {
        return Err(ConnectivityError::NonManifoldEdge {
            vertices: edge_of_key(run[0].0),
            n_faces: run.len(),
            faces: [run[0].1 as usize / 3, run[1].1 as usize / 3],
        });
    }
    let orientation = Orientation::of(faces, &keyed);
    if let Some(&[a, b]) = orientation.conflicts.first() {
        return Err(ConnectivityError::NonOrientable {
            vertices: {
                let [i, j] = halfedge_vertices(faces, a as usize);
                [i.min(j), i.max(j)]
            },
            faces: [a as usize / 3, b as usize / 3],
        });
    }
    Ok(orientation.apply(faces))
}

/// Repairs `faces` over `n_vertices` vertices into an oriented manifold (see the module docs).
/// Indices must be below `n_vertices`.
pub fn repair(n_vertices: usize, faces: &[[u32; 3]]) -> Repaired {
    let mut report = RepairReport::default();
    let mut seen = HashSet::with_capacity(faces.len());
    let mut face_origin = Vec::with_capacity(faces.len());
    for (f, face) in faces.iter().enumerate() {
        let [a, b, c] = *face;
        if a == b || b == c || a == c {
            report.degenerate_faces += 1;
            continue;
        }
        let mut sorted = *face;
        sorted.sort_unstable();
        if !seen.insert(sorted) {
            report.duplicate_faces += 1;
            continue;
        }
        face_origin.push(f as u32);
    }
    let mut kept: Vec<[u32; 3]> = face_origin.iter().map(|&f| faces[f as usize]).collect();
    report.flipped_faces = Orientation::of(&kept, &halfedges_by_edge(&kept)).apply(&mut kept);

    // Corners (index 3f + c, the corner where halfedge 3f + c starts) joined across edges.
    let mut pieces = UnionFind::new(3 * kept.len());
    for run in halfedges_by_edge(&kept).chunk_by(|a, b| a.0 == b.0) {
        match *run {
            [(_, a), (_, b)] => {
                let (a, b) = (a as usize, b as usize);
                if halfedge_vertices(&kept, a)[0] == halfedge_vertices(&kept, b)[0] {
                    report.orientation_cuts += 1;
                    continue;
                }
                // a runs i → j and b runs j → i: their tails are at i and j, their heads at
                // j and i.
                pieces.union(a, next_in_face(b));
                pieces.union(b, next_in_face(a));
            }
            [_] => {}
            _ => report.non_manifold_edges += 1,
        }
    }

    let (vertex_origin, corner_vertex) = number_pieces(n_vertices, &kept, &mut pieces);
    let mut split = vec![0u32; n_vertices];
    for &v in &vertex_origin {
        split[v as usize] += 1;
    }
    report.split_vertices = split.iter().filter(|&&n| n > 1).count();
    report.added_vertices = split.iter().map(|&n| n.saturating_sub(1) as usize).sum();
    let faces = (0..kept.len())
        .map(|f| [0, 1, 2].map(|c| corner_vertex[3 * f + c]))
        .collect();
    Repaired {
        faces,
        vertex_origin,
        face_origin,
        report,
    }
}

/// The halfedge after `h` in its face: it starts where `h` ends.
fn next_in_face(h: usize) -> usize {
    3 * (h / 3) + (h % 3 + 1) % 3
}

/// New vertices: per original vertex in order, one per piece in the order of its first corner.
/// Returns the original vertex of each new one and the new vertex of each corner.
fn number_pieces(
    n_vertices: usize,
    faces: &[[u32; 3]],
    pieces: &mut UnionFind,
) -> (Vec<u32>, Vec<u32>) {
    // Corners grouped by vertex (a counting sort), in corner order within each vertex.
    let mut offsets = vec![0usize; n_vertices + 1];
    for &v in faces.iter().flatten() {
        offsets[v as usize + 1] += 1;
    }
    for i in 0..n_vertices {
        offsets[i + 1] += offsets[i];
    }
    let mut by_vertex = vec![0u32; 3 * faces.len()];
    let mut fill = offsets.clone();
    for (corner, &v) in faces.iter().flatten().enumerate() {
        by_vertex[fill[v as usize]] = corner as u32;
        fill[v as usize] += 1;
    }
    let mut vertex_origin = Vec::new();
    let mut corner_vertex = vec![0u32; 3 * faces.len()];
    let mut piece_vertex = vec![NO_HALFEDGE; 3 * faces.len()];
    for v in 0..n_vertices {
        for &corner in &by_vertex[offsets[v]..offsets[v + 1]] {
            let root = pieces.find(corner as usize);
            if piece_vertex[root] == NO_HALFEDGE {
                piece_vertex[root] = vertex_origin.len() as u32;
                vertex_origin.push(v as u32);
            }
            corner_vertex[corner as usize] = piece_vertex[root];
        }
    }
    (vertex_origin, corner_vertex)
}

/// Per-face flips from the breadth-first orientation, and the conflicts left.
struct Orientation {
    flip: Vec<bool>,
    /// The two halfedges of each manifold edge whose faces disagree after the flips.
    conflicts: Vec<[u32; 2]>,
}

impl Orientation {
    /// Orients the faces through their manifold edges (`keyed`: [`halfedges_by_edge`]).
    fn of(faces: &[[u32; 3]], keyed: &[(u64, u32)]) -> Self {
        // partner[h]: the other halfedge of h's manifold edge, and whether both run the same
        // way (then exactly one of the two faces must flip).
        let mut partner = vec![(NO_HALFEDGE, false); 3 * faces.len()];
        let mut manifold = Vec::new();
        for run in keyed.chunk_by(|a, b| a.0 == b.0) {
            if let [(_, a), (_, b)] = *run {
                let same = halfedge_vertices(faces, a as usize)[0]
                    == halfedge_vertices(faces, b as usize)[0];
                partner[a as usize] = (b, same);
                partner[b as usize] = (a, same);
                manifold.push([a, b]);
            }
        }
        let mut flip = vec![false; faces.len()];
        let mut visited = vec![false; faces.len()];
        let mut queue = VecDeque::new();
        let mut component = Vec::new();
        for root in 0..faces.len() {
            if visited[root] {
                continue;
            }
            visited[root] = true;
            queue.push_back(root);
            component.clear();
            while let Some(f) = queue.pop_front() {
                component.push(f);
                for &(other, same) in &partner[3 * f..3 * f + 3] {
                    let g = other as usize / 3;
                    if other != NO_HALFEDGE && !visited[g] {
                        visited[g] = true;
                        flip[g] = flip[f] ^ same;
                        queue.push_back(g);
                    }
                }
            }
            let flipped = component.iter().filter(|&&f| flip[f]).count();
            if 2 * flipped > component.len() {
                component.iter().for_each(|&f| flip[f] = !flip[f]);
            }
        }
        let conflicts = manifold
            .into_iter()
            .filter(|&[a, _]| {
                let (b, same) = partner[a as usize];
                flip[a as usize / 3] ^ flip[b as usize / 3] != same
            })
            .collect();
        Self { flip, conflicts }
    }

    /// Flips the faces and returns how many.
    fn apply(&self, faces: &mut [[u32; 3]]) -> usize {
        let mut count = 0;
        for (face, _) in faces.iter_mut().zip(&self.flip).filter(|(_, &f)| f) {
            face.swap(1, 2);
            count += 1;
        }
        count
    }
}

/// Disjoint sets of `0..n` with path halving.
pub(crate) struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    pub(crate) fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
        }
    }

    pub(crate) fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] as usize != x {
            let grandparent = self.parent[self.parent[x] as usize];
            self.parent[x] = grandparent;
            x = grandparent as usize;
        }
        x
    }

    /// Joins the sets of `a` and `b`; the smaller root stays the root.
    pub(crate) fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        let (low, high) = (a.min(b), a.max(b));
        self.parent[high] = low as u32;
    }
}
