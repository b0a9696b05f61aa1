//! Closed edge 1-forms that span the first cohomology, from a tree–cotree decomposition
//! (Eppstein, "Dynamic generators of topologically embedded graphs", 2003; Erickson &
//! Whittlesey, "Greedy optimal homotopy and homology generators", 2005).
//!
//! A 1-form `ω` gives each edge `e` a number `ω_e`, read along `edges[e][0] → edges[e][1]`;
//! it is *closed* when its signed sum around every face vanishes, and *exact* when it is the
//! difference `φ_j − φ_i` of vertex values. Exact forms are closed; the closed forms modulo
//! the exact ones (H¹) have dimension `2g` on a closed component of genus `g` and `2g + b − 1`
//! on one with `b ≥ 1` boundary loops: the circulations around handles and holes.
//!
//! Construction, all combinatorial (no lengths):
//! 1. `T`, a spanning forest of the vertex graph (`V − c` edges for `c` components);
//! 2. `C`, a spanning forest of the dual graph (faces joined across edges not in `T`) in which
//!    the boundary edges of all components lead to one outside node, its root: every face of
//!    a component with boundary gets a parent edge, a closed component's first face is the
//!    root of its own tree and has none;
//! 3. the edges in neither are the *generators*. Generator `k`'s form is 1 on it, 0 on `T`
//!    and the other generators, and on `C` fixed face by face from the leaves: each face's
//!    sum vanishes by its parent edge, whose other faces' edges are known by then. A closed
//!    component's root face closes by itself, since its edges' sum is minus all other faces'
//!    (every interior edge enters two faces with opposite signs).
//!
//! Cutting a surface along a spanning tree leaves its faces connected, so `C` reaches every
//! face and the generators number `E − (V − c) − F + c_closed`, the dimension above.

use super::{Mesh, UnionFind};

/// The tree–cotree split of a mesh's edges (see the module documentation).
pub struct TreeCotree {
    /// Faces in breadth-first order of the dual forest, roots first.
    order: Vec<usize>,
    /// `parent[f]`: the halfedge of face `f` across which it was reached (`None` at a root).
    parent: Vec<Option<usize>>,
    /// The edges in neither forest.
    generators: Vec<usize>,
}

impl TreeCotree {
    pub fn new(mesh: &Mesh) -> Self {
        let in_tree = spanning_forest(mesh);
        let (order, parent) = dual_forest(mesh, &in_tree);
        let mut in_cotree = vec![false; mesh.n_edges()];
        for h in parent.iter().flatten() {
            in_cotree[mesh.halfedge_edge(*h)] = true;
        }
        let generators = (0..mesh.n_edges())
            .filter(|&e| !in_tree[e] && !in_cotree[e])
            .collect();
        TreeCotree {
            order,
            parent,
            generators,
        }
    }

    /// The dimension of H¹: `2g` per closed component, `2g + b − 1` per one with boundary.
    pub fn n_generators(&self) -> usize {
        self.generators.len()
    }

    /// The closed 1-form of generator `k` (one value per edge, along `edges[e][0] →
    /// edges[e][1]`).
    pub fn closed_form(&self, mesh: &Mesh, k: usize) -> Vec<f64> {
        let mut form = vec![0.0; mesh.n_edges()];
        form[self.generators[k]] = 1.0;
        for &f in self.order.iter().rev() {
            let Some(up) = self.parent[f] else { continue };
            let others: f64 = (3 * f..3 * f + 3)
                .filter(|&h| h != up)
                .map(|h| halfedge_sign(mesh, h) * form[mesh.halfedge_edge(h)])
                .sum();
            form[mesh.halfedge_edge(up)] = -halfedge_sign(mesh, up) * others;
        }
        form
    }

    /// All generators' closed forms.
    pub fn closed_forms(&self, mesh: &Mesh) -> Vec<Vec<f64>> {
        (0..self.n_generators())
            .map(|k| self.closed_form(mesh, k))
            .collect()
    }
}

/// `+1` when halfedge `h` runs along its edge's orientation (`edges[e][0] → edges[e][1]`).
pub fn halfedge_sign(mesh: &Mesh, h: usize) -> f64 {
    let tail = mesh.halfedge_vertices(h)[0];
    match mesh.edges()[mesh.halfedge_edge(h)][0] == tail {
        true => 1.0,
        false => -1.0,
    }
}

/// Which edges form a spanning forest of the vertex graph (Kruskal in edge order).
fn spanning_forest(mesh: &Mesh) -> Vec<bool> {
    let mut joined = UnionFind::new(mesh.n_vertices());
    (mesh.edges().iter())
        .map(|&[i, j]| {
            let (i, j) = (i as usize, j as usize);
            let apart = joined.find(i) != joined.find(j);
            if apart {
                joined.union(i, j);
            }
            apart
        })
        .collect()
}

/// Breadth-first dual forest avoiding `in_tree`: first from the outside node (every boundary
/// edge not in the tree), then from the first unreached face of each remaining component.
fn dual_forest(mesh: &Mesh, in_tree: &[bool]) -> (Vec<usize>, Vec<Option<usize>>) {
    let mut search = DualSearch {
        parent: vec![None; mesh.n_faces()],
        reached: vec![false; mesh.n_faces()],
        order: Vec::with_capacity(mesh.n_faces()),
    };
    let usable = |h: usize| !in_tree[mesh.halfedge_edge(h)];
    for h in (0..mesh.n_halfedges()).filter(|&h| mesh.is_boundary_halfedge(h) && usable(h)) {
        search.reach(h / 3, Some(h));
    }
    let (mut next, mut root) = (0, 0);
    loop {
        if next == search.order.len() {
            // The queue ran dry: the next closed component's first face is a root.
            match (root..mesh.n_faces()).find(|&f| !search.reached[f]) {
                Some(f) => (root, _) = (f, search.reach(f, None)),
                None => break,
            }
        }
        let f = search.order[next];
        next += 1;
        for h in (3 * f..3 * f + 3).filter(|&h| usable(h)) {
            if let Some(t) = mesh.twin(h) {
                search.reach(t / 3, Some(t));
            }
        }
    }
    (search.order, search.parent)
}

/// The state of [`dual_forest`]'s search; `order` doubles as its queue.
struct DualSearch {
    parent: Vec<Option<usize>>,
    reached: Vec<bool>,
    order: Vec<usize>,
}

impl DualSearch {
    fn reach(&mut self, f: usize, across: Option<usize>) {
        if !std::mem::replace(&mut self.reached[f], true) {
            self.parent[f] = across;
            self.order.push(f);
        }
    }
}
