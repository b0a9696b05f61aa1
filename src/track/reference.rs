//! A reference mesh of a chosen size made from frame 0: edge-collapse simplification by
//! quadric error metrics (Garland & Heckbert 1997) through `meshopt` (meshoptimizer), with its
//! regularizing option, then cleaned for finite elements, which need triangles far from
//! degenerate: edges are flipped where the two angles opposite them sum to more than π (the
//! Delaunay criterion, only between nearly coplanar triangles so the shape stays), and
//! vertices are moved a few times towards the centroid of their neighbours within the surface
//! (tangential Laplacian smoothing, projected back onto frame 0; boundary vertices stay).
//! meshoptimizer neither flips edges nor smooths, and both are a few lines on a face list. Where
//! a collapse flattens a thin part to a pair of back-to-back faces (four faces on each of their
//! edges), the pair is removed; a simplification that still pinches the surface or opens a
//! hole in it is tried again with a slightly smaller target.
//!
//! Surfaces meshed per time point by a segmentation are often finer than the flow needs, and
//! tracking a coarser mesh is faster and folds less. The simplified mesh's vertices are a subset
//! of frame 0's, so it lies on frame 0's surface exactly; simplification never refines, so a
//! target at or above frame 0's vertex count returns frame 0's mesh.

use super::FrameSurface;
use crate::geometry::folds::{folded_edges, smooth_out_widening};
use crate::mesh::Mesh;
use crate::shapes::Surface;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// How many rounds adjust the triangle target to land near the asked vertex count.
const ROUNDS: usize = 3;
/// How many more rounds try another target when a collapse left a non-manifold edge (two
/// sheets pinched together where the surface was thin or folded): 3 % below, 3 % above, 6 %
/// below … the target the first rounds found, so the count stays within 9 % of it.
const MANIFOLD_RETRIES: usize = 6;

/// Passes of edge flips and of smoothing, and the most rounds of smoothing out folds.
const FLIP_PASSES: usize = 10;
const SMOOTHING_PASSES: usize = 5;
const UNFOLD_ROUNDS: usize = 50;

/// Two triangles are flipped only if their normals differ by less than this (degrees).
const FLIP_CREASE_DEGREES: f64 = 20.0;

/// Frame 0's mesh (`positions`, `faces`) simplified to about `vertices` vertices (the count is
/// met within a few percent where the surface's topology allows).
pub fn simplified_reference(
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    vertices: usize,
) -> Surface {
    let all_faces = faces;
    let used = used_vertices(positions.len(), faces.iter().flatten().copied());
    if vertices >= used {
        return compact(positions, faces.to_vec());
    }
    let coordinates: Vec<[f32; 3]> = positions
        .iter()
        .map(|p| [p.x as f32, p.y as f32, p.z as f32])
        .collect();
    let bytes = meshopt::typed_to_bytes(&coordinates);
    let adapter = meshopt::VertexDataAdapter::new(bytes, std::mem::size_of::<[f32; 3]>(), 0)
        .expect("a stride of three floats divides three-float vertices");
    let indices: Vec<u32> = faces.iter().flatten().copied().collect();
    // A triangle mesh has about twice as many triangles as vertices.
    let mut target_faces = 2 * vertices;
    let mut faces = faces.to_vec();
    let mut retry = 0usize;
    let mut found_target = target_faces;
    for round in 0..ROUNDS + MANIFOLD_RETRIES {
        let result = meshopt::simplify(
            &indices,
            &adapter,
            3 * target_faces.max(1),
            1.0,
            meshopt::SimplifyOptions::Regularize,
            None,
        );
        faces = result.chunks_exact(3).map(|f| [f[0], f[1], f[2]]).collect();
        drop_back_to_back(&mut faces);
        let got = used_vertices(positions.len(), faces.iter().flatten().copied());
        let near = got == 0 || got.abs_diff(vertices) * 50 <= vertices;
        // Manifold, with no boundary the surface did not have (a dropped pair leaves a hole).
        let manifold = || {
            let compacted = compact(positions, faces.clone());
            let mesh = Mesh::new(compacted.positions.len(), compacted.faces);
            mesh.is_ok() && boundary_edges(&faces) <= boundary_edges(all_faces)
        };
        match (near || round + 1 >= ROUNDS, got == 0 || manifold()) {
            (true, true) => break,
            // A collapse pinched two sheets together: another target collapses otherwise.
            (true, false) => {
                if retry == 0 {
                    found_target = target_faces;
                }
                retry += 1;
                let step = 0.03 * retry.div_ceil(2) as f64;
                let sign = if retry % 2 == 1 { -1.0 } else { 1.0 };
                target_faces = (found_target as f64 * (1.0 + sign * step)).round() as usize;
            }
            (false, _) => {
                target_faces = (target_faces as f64 * vertices as f64 / got as f64).round() as usize
            }
        }
    }
    for _ in 0..FLIP_PASSES {
        if flip_to_delaunay(positions, &mut faces) == 0 {
            break;
        }
    }
    let mut reference = compact(positions, faces);
    smooth_on(&mut reference, positions, all_faces);
    reference
}

/// How many edges of `faces` have one face.
fn boundary_edges(faces: &[[u32; 3]]) -> usize {
    let mut edges: Vec<(u32, u32)> = (faces.iter())
        .flat_map(|f| (0..3).map(move |c| (f[c].min(f[(c + 1) % 3]), f[c].max(f[(c + 1) % 3]))))
        .collect();
    edges.sort_unstable();
    edges
        .chunk_by(|a, b| a == b)
        .filter(|run| run.len() == 1)
        .count()
}

/// Removes pairs of faces on the same three vertices (back to back, opposite orientations):
/// what an edge collapse leaves where it flattens a thin part to nothing, with four faces on
/// each of its edges.
fn drop_back_to_back(faces: &mut Vec<[u32; 3]>) {
    let key = |f: &[u32; 3]| {
        let mut k = *f;
        k.sort_unstable();
        k
    };
    let mut count: std::collections::HashMap<[u32; 3], usize> = Default::default();
    faces
        .iter()
        .for_each(|f| *count.entry(key(f)).or_default() += 1);
    faces.retain(|f| count[&key(f)] == 1);
}

/// One pass of Delaunay flips between nearly coplanar triangles (module docs); how many.
fn flip_to_delaunay(x: &[Vector3<f64>], faces: &mut [[u32; 3]]) -> usize {
    let mut edges: BTreeMap<(u32, u32), Vec<(usize, usize)>> = BTreeMap::new();
    for (f, face) in faces.iter().enumerate() {
        for c in 0..3 {
            let (a, b) = (face[c], face[(c + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push((f, c));
        }
    }
    let crease = FLIP_CREASE_DEGREES.to_radians().cos();
    let normal = |f: [u32; 3]| {
        let [a, b, c] = f.map(|v| x[v as usize]);
        (b - a).cross(&(c - a))
    };
    let angle = |at: u32, p: u32, q: u32| {
        let (u, v) = (
            x[p as usize] - x[at as usize],
            x[q as usize] - x[at as usize],
        );
        u.angle(&v)
    };
    let mut touched = vec![false; faces.len()];
    // Edges this pass made: two flips must not make the same edge (four faces on it).
    let mut made = std::collections::BTreeSet::new();
    let mut flips = 0;
    for pair in edges.values() {
        let &[(f, c), (g, _)] = pair.as_slice() else {
            continue;
        };
        if touched[f] || touched[g] {
            continue;
        }
        let (a, b, opposite_c) = (faces[f][c], faces[f][(c + 1) % 3], faces[f][(c + 2) % 3]);
        let Some(&d) = faces[g].iter().find(|&&v| v != a && v != b) else {
            continue;
        };
        let (n_f, n_g) = (normal(faces[f]), normal(faces[g]));
        let coplanar = n_f.normalize().dot(&n_g.normalize()) >= crease;
        let delaunay = angle(opposite_c, a, b) + angle(d, a, b) <= std::f64::consts::PI + 1e-9;
        let new_edge = (opposite_c.min(d), opposite_c.max(d));
        let exists = edges.contains_key(&new_edge) || made.contains(&new_edge);
        let (new_f, new_g) = ([a, d, opposite_c], [d, b, opposite_c]);
        let keeps_side = normal(new_f).dot(&n_f) > 0.0 && normal(new_g).dot(&n_f) > 0.0;
        if coplanar && !delaunay && !exists && keeps_side {
            faces[f] = new_f;
            faces[g] = new_g;
            made.insert(new_edge);
            touched[f] = true;
            touched[g] = true;
            flips += 1;
        }
    }
    flips
}

/// Tangential Laplacian smoothing of `mesh` on the surface `(positions, faces)` (module docs).
fn smooth_on(mesh: &mut Surface, positions: &[Vector3<f64>], faces: &[[u32; 3]]) {
    let Ok(connectivity) = Mesh::new(mesh.positions.len(), mesh.faces.clone()) else {
        return;
    };
    let zeros = vec![0.0; positions.len()];
    let Ok(surface) = FrameSurface::new(0, positions, faces, &zeros) else {
        return;
    };
    let mut neighbours = vec![Vec::new(); mesh.positions.len()];
    for &[i, j] in connectivity.edges() {
        neighbours[i as usize].push(j as usize);
        neighbours[j as usize].push(i as usize);
    }
    for _ in 0..SMOOTHING_PASSES {
        let x = &mesh.positions;
        let next: Vec<Vector3<f64>> = (0..x.len())
            .into_par_iter()
            .map(|i| {
                if connectivity.is_boundary_vertex(i) || neighbours[i].is_empty() {
                    return x[i];
                }
                let centroid = neighbours[i].iter().map(|&j| x[j]).sum::<Vector3<f64>>()
                    / neighbours[i].len() as f64;
                let (_, n) = surface.closest_point_and_normal(&x[i]);
                let shift = centroid - x[i];
                surface
                    .closest_point(&(x[i] + 0.5 * (shift - n * n.dot(&shift))))
                    .position
            })
            .collect();
        mesh.positions = next;
    }
    // A collapse may leave a fold (a sliver turned over against its neighbours): smoothed out
    // on the surface, since tracking measures every turn against the reference.
    let vertex_neighbours = crate::mesh::VertexNeighbours::open(&connectivity);
    let folded = |x: &[Vector3<f64>]| folded_edges(&connectivity, x);
    let onto = |_: usize, x: Vector3<f64>| surface.closest_point(&x).position;
    smooth_out_widening(
        &connectivity,
        &vertex_neighbours,
        &mut mesh.positions,
        UNFOLD_ROUNDS,
        folded,
        onto,
    );
}

fn used_vertices(n: usize, indices: impl Iterator<Item = u32>) -> usize {
    let mut used = vec![false; n];
    indices.for_each(|v| used[v as usize] = true);
    used.iter().filter(|&&u| u).count()
}

fn compact(positions: &[Vector3<f64>], faces: Vec<[u32; 3]>) -> Surface {
    super::trim::compact(positions, &faces, &mut Vec::new())
}
