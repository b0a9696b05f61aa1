//! Welding: joining the file vertices that an exporter split along texture or normal seams,
//! without gluing a surface to itself where it only touches.
//!
//! Exporters that store one index per corner (glTF always, OBJ and PLY often) duplicate a vertex
//! wherever its texture coordinates or normals jump; left alone, every seam is a boundary. A
//! surface may also touch itself (two sheets meeting at a point, tori crossing), and merging
//! the vertices that meet there would make the mesh non-manifold. The rule, over the vertices
//! that faces use (the others are never welded):
//!
//! 1. **Coincident**: vertices `a ≠ b` are coincident when `|p_a − p_b| ≤ tolerance · d` in
//!    every frame, `d` the bounding-box diagonal of the used vertices in frame 0; with
//!    tolerance 0, when their positions are bitwise equal in every frame (`−0 = +0`). Two
//!    vertices of one face are never coincident. A tolerance that makes neighbours coincide
//!    (more than [`MAX_PAIRS_PER_VERTEX`] close pairs per vertex) is refused.
//! 2. **Seam evidence**: coincident `a, b` are joined when they end *coincident edges*: an edge
//!    `(a, c)` of one face and `(b, d)` of another with `c, d` coincident or equal. Joined
//!    vertices, transitively, make one welded vertex. A point where a surface touches itself has
//!    no coincident edges, so its vertices stay apart.
//! 3. **Manifold check**: a welded vertex is undone (its file vertices kept apart) when, welded,
//!    it has a face with two of its file vertices, more fans than the most any of its file
//!    vertices has, or an edge with more than two faces and more than any of the file edges
//!    welded into it (two sheets touching along a line). Undoing one may break the fans of its
//!    neighbours, which are checked again, until nothing changes.
//!
//! So welding never makes a vertex or an edge less manifold than the file had it. Welded
//! vertices are numbered in the order of their first file vertex.

use super::UnionFind;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The outcome of [`weld`].
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Weld {
    /// `welded[i]`: the welded vertex of file vertex `i`.
    pub welded: Vec<u32>,
    /// How many welded vertices there are.
    pub n_vertices: usize,
    /// Coincident pairs left apart (a surface touching itself), and the first of them.
    pub apart: usize,
    pub first_apart: Option<[u32; 2]>,
}

impl Weld {
    /// Every file vertex its own.
    pub fn none(n: usize) -> Self {
        Self {
            welded: (0..n as u32).collect(),
            n_vertices: n,
            apart: 0,
            first_apart: None,
        }
    }
}

/// A tolerance so large that it makes neighbours coincide, not just copies: more close pairs
/// than [`MAX_PAIRS_PER_VERTEX`] per used vertex (welding would take quadratic time).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct TooManyPairs {
    pub limit: usize,
}

/// Seam copies make a few close pairs per vertex (a pole copied once per triangle a few
/// dozen); neighbours within the tolerance make many more.
const MAX_PAIRS_PER_VERTEX: usize = 16;

/// Adds up, over every process that reads some frames of one sequence, a count per candidate
/// pair: how the processes of a solve over time windows agree on one weld (`weld`). In one
/// process, nothing to add: `&|_| {}`.
pub type SumOverReaders<'a> = &'a dyn Fn(&mut [f64]);

/// Welds the file vertices of `faces` by the module's rule; `frames` holds one position per
/// file vertex each, frame 0 first, `tolerance` is relative to frame 0's bounding-box
/// diagonal. Indices must be in range.
///
/// Processes that read different frames (each frame 0 and its own) weld alike when each passes
/// `sum` over all of them: the candidate pairs come from frame 0 alone, the same everywhere,
/// and a pair is coincident when no process finds it apart in one of its frames.
pub(crate) fn weld(
    faces: &[[u32; 3]],
    frames: &[&[Vector3<f64>]],
    tolerance: f64,
    sum: SumOverReaders,
) -> Result<Weld, TooManyPairs> {
    let n = frames.first().map_or(0, |f| f.len());
    let mut used = vec![false; n];
    faces
        .iter()
        .flatten()
        .for_each(|&v| used[v as usize] = true);
    let close = close_pairs(&used, frames, tolerance, sum)?;
    if close.is_empty() {
        return Ok(Weld::none(n));
    }
    // Most meshes have no close pairs: the face tables are built only when some are.
    let surface = Surface::new(n, faces);
    let pairs: Vec<[u32; 2]> = close
        .into_iter()
        .filter(|&[a, b]| !surface.share_a_face(a, b))
        .collect();
    let candidates = Adjacency::from_pairs(n, &pairs);
    let mut joined = UnionFind::new(n);
    for face in faces {
        for k in 0..3 {
            let (a, c) = (face[k], face[(k + 1) % 3]);
            for (a, c) in [(a, c), (c, a)] {
                for &b in candidates.of(a) {
                    let ends = candidates.of(c).iter().chain(std::iter::once(&c));
                    for &d in ends.filter(|&&d| surface.has_edge(b, d)) {
                        joined.union(a as usize, b as usize);
                        joined.union(c as usize, d as usize);
                    }
                }
            }
        }
    }
    let mut classes = Classes::new(n, &mut joined);
    classes.undo_non_manifold(&surface);
    // A class's root is its lowest file vertex, so it is numbered first.
    let mut welded = vec![u32::MAX; n];
    let mut n_vertices = 0;
    for i in 0..n {
        let root = classes.class[i] as usize;
        if welded[root] == u32::MAX {
            welded[root] = n_vertices;
            n_vertices += 1;
        }
        welded[i] = welded[root];
    }
    let apart: Vec<[u32; 2]> = pairs
        .into_iter()
        .filter(|&[a, b]| welded[a as usize] != welded[b as usize])
        .collect();
    Ok(Weld {
        welded,
        n_vertices: n_vertices as usize,
        apart: apart.len(),
        first_apart: apart.into_iter().min(),
    })
}

/// The faces of each file vertex and the file's edges.
struct Surface<'a> {
    faces: &'a [[u32; 3]],
    vertex_faces: Adjacency,
    edges: HashSet<u64>,
}

impl<'a> Surface<'a> {
    fn new(n: usize, faces: &'a [[u32; 3]]) -> Self {
        let incidences: Vec<[u32; 2]> = faces
            .iter()
            .enumerate()
            .flat_map(|(f, face)| face.map(|v| [v, f as u32]))
            .collect();
        let edges = faces
            .iter()
            .flat_map(|&[a, b, c]| [edge_key(a, b), edge_key(b, c), edge_key(c, a)])
            .collect();
        Self {
            faces,
            vertex_faces: Adjacency::from_directed(n, &incidences),
            edges,
        }
    }

    fn has_edge(&self, a: u32, b: u32) -> bool {
        self.edges.contains(&edge_key(a, b))
    }

    fn share_a_face(&self, a: u32, b: u32) -> bool {
        self.vertex_faces
            .of(a)
            .iter()
            .any(|&f| self.faces[f as usize].contains(&b))
    }

    /// The other two vertices of each face of `v`, with the face.
    fn corners(&self, v: u32) -> impl Iterator<Item = (u32, [u32; 2])> + '_ {
        self.vertex_faces.of(v).iter().map(move |&f| {
            let face = self.faces[f as usize];
            let k = face
                .iter()
                .position(|&x| x == v)
                .expect("v is in its faces");
            (f, [face[(k + 1) % 3], face[(k + 2) % 3]])
        })
    }
}

fn edge_key(a: u32, b: u32) -> u64 {
    (u64::from(a.min(b)) << 32) | u64::from(a.max(b))
}

/// Neighbour lists of `0..n` in one array.
struct Adjacency {
    offsets: Vec<usize>,
    targets: Vec<u32>,
}

impl Adjacency {
    /// From `[from, to]` pairs, each listed under `from` in input order.
    fn from_directed(n: usize, pairs: &[[u32; 2]]) -> Self {
        let mut offsets = vec![0usize; n + 1];
        for &[from, _] in pairs {
            offsets[from as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut targets = vec![0u32; pairs.len()];
        let mut fill = offsets.clone();
        for &[from, to] in pairs {
            targets[fill[from as usize]] = to;
            fill[from as usize] += 1;
        }
        Self { offsets, targets }
    }

    /// Both directions of each pair.
    fn from_pairs(n: usize, pairs: &[[u32; 2]]) -> Self {
        let both: Vec<[u32; 2]> = pairs.iter().flat_map(|&[a, b]| [[a, b], [b, a]]).collect();
        Self::from_directed(n, &both)
    }

    fn of(&self, v: u32) -> &[u32] {
        &self.targets[self.offsets[v as usize]..self.offsets[v as usize + 1]]
    }
}

/// Pairs `[a, b]`, `a < b`, of used vertices close in every frame of every reader (rule 1
/// without the face condition): candidates found through a grid on frame 0 (`frames[0]`),
/// kept when `sum` finds no reader's frame where they are apart ([`weld`]).
fn close_pairs(
    used: &[bool],
    frames: &[&[Vector3<f64>]],
    tolerance: f64,
    sum: SumOverReaders,
) -> Result<Vec<[u32; 2]>, TooManyPairs> {
    let Some(first) = frames.first() else {
        return Ok(Vec::new());
    };
    let used: Vec<u32> = (0..first.len() as u32)
        .filter(|&v| used[v as usize])
        .collect();
    let (low, high) = used.iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(low, high), &v| {
            let p = first[v as usize];
            (low.inf(&p), high.sup(&p))
        },
    );
    let radius = tolerance * (high - low).norm();
    let grid = match radius > 0.0 && radius.is_finite() {
        true => Grid::Cells {
            origin: low,
            size: CELLS_PER_RADIUS * radius,
        },
        false => Grid::Bitwise,
    };
    let close_in = |p: &[Vector3<f64>], a: usize, b: usize| match grid {
        Grid::Bitwise => bitwise_key(&p[a]) == bitwise_key(&p[b]),
        Grid::Cells { .. } => (p[a] - p[b]).norm() <= radius,
    };
    // Vertices sorted by cell: a cell's vertices are one run, found by binary search.
    let mut cells: Vec<([u64; 3], u32)> = used
        .par_iter()
        .map(|&v| (grid.key(&first[v as usize]), v))
        .collect();
    cells.par_sort_unstable();
    let limit = MAX_PAIRS_PER_VERTEX * used.len();
    let found = AtomicUsize::new(0);
    let pairs: Vec<[u32; 2]> = used
        .par_iter()
        .flat_map_iter(|&a| {
            let mut pairs = Vec::new();
            if found.load(Ordering::Relaxed) > limit {
                return pairs;
            }
            grid.for_each_neighbour(&first[a as usize], |key| {
                let start = cells.partition_point(|(k, _)| *k < key);
                let run = cells[start..].iter().take_while(|(k, _)| *k == key);
                let partners = run.map(|&(_, b)| b);
                pairs.extend(
                    partners
                        .filter(|&b| a < b && close_in(first, a as usize, b as usize))
                        .map(|b| [a, b]),
                );
            });
            found.fetch_add(pairs.len(), Ordering::Relaxed);
            pairs
        })
        .collect();
    if found.into_inner() > limit {
        return Err(TooManyPairs { limit });
    }
    if pairs.is_empty() {
        return Ok(pairs);
    }
    let mut apart: Vec<f64> = pairs
        .par_iter()
        .map(|&[a, b]| {
            let close = frames[1..]
                .iter()
                .all(|p| close_in(p, a as usize, b as usize));
            f64::from(u8::from(!close))
        })
        .collect();
    sum(&mut apart);
    Ok((pairs.into_iter().zip(apart))
        .filter(|&(_, apart)| apart == 0.0)
        .map(|(pair, _)| pair)
        .collect())
}

/// Grid cells are this many times the welding radius: a vertex's partners lie in its own cell
/// or, when it is within a third of a cell of a cell face, across that face.
const CELLS_PER_RADIUS: f64 = 4.0;

/// How [`close_pairs`] buckets positions.
#[derive(Clone, Copy)]
enum Grid {
    /// One bucket per bit pattern.
    Bitwise,
    /// Cubes of side `size` from `origin`.
    Cells { origin: Vector3<f64>, size: f64 },
}

impl Grid {
    /// The bucket of `p`: its bits, or the bits of its floored f64 cell coordinates (which
    /// stay distinct for any ratio of extent to radius).
    fn key(&self, p: &Vector3<f64>) -> [u64; 3] {
        match *self {
            Grid::Bitwise => bitwise_key(p),
            Grid::Cells { origin, size } => {
                let q = ((p - origin) / size).map(f64::floor);
                [q.x, q.y, q.z].map(|c| (c + 0.0).to_bits())
            }
        }
    }

    /// Calls `visit` with each bucket where `p`'s partners may be, its own among them.
    fn for_each_neighbour(&self, p: &Vector3<f64>, mut visit: impl FnMut([u64; 3])) {
        let Grid::Cells { origin, size } = *self else {
            return visit(bitwise_key(p));
        };
        let q = (p - origin) / size;
        // Per axis: the cell, and its neighbour across a face less than a third of a cell away.
        let mut axes = [[0.0; 2]; 3];
        let mut counts = [1; 3];
        for axis in 0..3 {
            let k = q[axis].floor();
            let fraction = q[axis] - k;
            axes[axis][0] = k;
            let across = match fraction {
                f if f < 1.0 / 3.0 => k - 1.0,
                f if f > 2.0 / 3.0 => k + 1.0,
                _ => k,
            };
            // Far from the origin k ± 1 may round to k.
            if across != k {
                axes[axis][1] = across;
                counts[axis] = 2;
            }
        }
        for &x in &axes[0][..counts[0]] {
            for &y in &axes[1][..counts[1]] {
                for &z in &axes[2][..counts[2]] {
                    visit([x, y, z].map(|c: f64| (c + 0.0).to_bits()));
                }
            }
        }
    }
}

fn bitwise_key(p: &Vector3<f64>) -> [u64; 3] {
    // Adding 0.0 turns −0 into +0.
    [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits())
}

/// The welded vertices as explicit classes, which the manifold check may undo.
struct Classes {
    /// `class[i]`: the class (its first file vertex) of file vertex `i`.
    class: Vec<u32>,
    /// Members of the classes with more than one, by class.
    members: HashMap<u32, Vec<u32>>,
}

impl Classes {
    fn new(n: usize, joined: &mut UnionFind) -> Self {
        let class: Vec<u32> = (0..n).map(|i| joined.find(i) as u32).collect();
        // A root is its class's lowest member: members come in file order after it.
        let mut members: HashMap<u32, Vec<u32>> = HashMap::new();
        for (i, &c) in class.iter().enumerate().filter(|&(i, &c)| c as usize != i) {
            members.entry(c).or_insert_with(|| vec![c]).push(i as u32);
        }
        Self { class, members }
    }

    /// Rule 3: undoes the classes that are not manifold, and then those it breaks.
    fn undo_non_manifold(&mut self, surface: &Surface) {
        let mut pending: Vec<u32> = self.members.keys().copied().collect();
        pending.sort_unstable();
        while let Some(c) = pending.pop() {
            let Some(members) = self.members.get(&c) else {
                continue; // undone since it was queued
            };
            if self.is_manifold(members, surface) {
                continue;
            }
            let members = self.members.remove(&c).expect("present");
            for &m in &members {
                self.class[m as usize] = m;
            }
            for &m in &members {
                for (_, others) in surface.corners(m) {
                    let neighbours = others.map(|v| self.class[v as usize]);
                    pending.extend(neighbours.iter().filter(|x| self.members.contains_key(x)));
                }
            }
        }
    }

    /// Whether welding `members` keeps rule 3.
    fn is_manifold(&self, members: &[u32], surface: &Surface) -> bool {
        let class = self.class[members[0] as usize];
        // Each corner of the welded vertex: its face and the classes of the other two vertices.
        let corners: Vec<(u32, [u32; 2])> = members
            .iter()
            .flat_map(|&m| surface.corners(m))
            .map(|(f, others)| (f, others.map(|v| self.class[v as usize])))
            .collect();
        if corners.iter().any(|(_, others)| others.contains(&class)) {
            return false;
        }
        // Faces on each welded edge, and the most faces on one file edge welded into it.
        let mut welded_edges: HashMap<u32, Vec<usize>> = HashMap::new();
        for (k, (_, [x, y])) in corners.iter().enumerate() {
            welded_edges.entry(*x).or_default().push(k);
            if y != x {
                welded_edges.entry(*y).or_default().push(k);
            }
        }
        let most_in_file = |x: u32| {
            members
                .iter()
                .flat_map(|&m| file_edge_counts(m, surface))
                .filter(|&(v, _)| self.class[v as usize] == x)
                .map(|(_, count)| count)
                .max()
                .unwrap_or(0)
        };
        if welded_edges
            .iter()
            .any(|(&x, faces)| faces.len() > 2 && faces.len() > most_in_file(x))
        {
            return false;
        }
        let mut fans = UnionFind::new(corners.len());
        for faces in welded_edges.values() {
            if let [a, b] = faces[..] {
                fans.union(a, b);
            }
        }
        let n_fans = (0..corners.len()).filter(|&k| fans.find(k) == k).count();
        let most_in_file = members
            .iter()
            .map(|&m| file_fans(m, surface))
            .max()
            .unwrap_or(0);
        n_fans <= most_in_file.max(1)
    }
}

/// The file edges at `v`: each other end with the number of faces on the edge.
fn file_edge_counts(v: u32, surface: &Surface) -> Vec<(u32, usize)> {
    let mut counts: Vec<(u32, usize)> = Vec::new();
    for (_, others) in surface.corners(v) {
        for x in others {
            match counts.iter_mut().find(|(y, _)| *y == x) {
                Some((_, count)) => *count += 1,
                None => counts.push((x, 1)),
            }
        }
    }
    counts
}

/// How many fans file vertex `v` has in the file: its corners connected across edges with
/// exactly two faces.
fn file_fans(v: u32, surface: &Surface) -> usize {
    let corners: Vec<[u32; 2]> = surface.corners(v).map(|(_, others)| others).collect();
    let mut fans = UnionFind::new(corners.len());
    for (x, count) in file_edge_counts(v, surface) {
        if count != 2 {
            continue;
        }
        let mut on_edge = (0..corners.len()).filter(|&k| corners[k].contains(&x));
        if let (Some(a), Some(b)) = (on_edge.next(), on_edge.next()) {
            fans.union(a, b);
        }
    }
    (0..corners.len()).filter(|&k| fans.find(k) == k).count()
}
