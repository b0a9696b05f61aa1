//! Trimming the reference to the region every frame covers.
//!
//! Surfaces segmented per time point are often cropped patches whose edge moves from frame to
//! frame (a meristem's dome as far as its cells were segmented, a field of view). Where frame
//! `k` ends before the tracked mesh does, the vertices beyond its boundary have no surface to
//! land on: moved to the closest point, they pile up on the boundary curve and their triangles
//! collapse. Such vertices (their normal line misses frame `k`, and its closest point lies on
//! the frame's boundary farther than round-off), vertices that relaxation would move over
//! the frame's edge, and the boundary vertices of triangles that flipped, are uncovered; the reference loses every face at an uncovered vertex or
//! at one of its neighbours (a margin of one ring), keeps its largest connected piece, and
//! tracking starts again from frame 0. What remains is the part of the surface that all frames cover.

use crate::mesh::{ConnectivityError, Mesh};
use crate::shapes::Surface;
use std::collections::HashMap;

/// `reference` without the faces at `uncovered` vertices and their neighbours, without ears
/// (triangles with two boundary edges), as a manifold mesh (faces at a vertex where two fans
/// meet are dropped too), its largest connected piece, renumbered;
/// `None` if nothing is left.
pub(super) fn trimmed(reference: &Surface, uncovered: &[usize]) -> Option<Surface> {
    // The uncovered vertices and their neighbours: the reference retreats from the frame's
    // edge by a ring, so that relaxation has room to move the new boundary.
    let mut dropped = vec![false; reference.positions.len()];
    uncovered.iter().for_each(|&v| dropped[v] = true);
    let ring: Vec<u32> = (reference.faces.iter())
        .filter(|f| f.iter().any(|&v| dropped[v as usize]))
        .flatten()
        .copied()
        .collect();
    ring.into_iter().for_each(|v| dropped[v as usize] = true);
    let mut faces: Vec<[u32; 3]> = reference.faces.clone();
    loop {
        faces.retain(|f| f.iter().all(|&v| !dropped[v as usize]));
        drop_ears(&mut faces);
        let surface = compact(&reference.positions, &faces, &mut Vec::new());
        match Mesh::new(surface.positions.len(), surface.faces.clone()) {
            Ok(mesh) => return largest_piece(&mesh, surface),
            Err(ConnectivityError::NonManifoldVertex { vertex, .. }) => {
                let mut kept = Vec::new();
                compact(&reference.positions, &faces, &mut kept);
                dropped[kept[vertex]] = true;
            }
            Err(ConnectivityError::NoFaces) => return None,
            Err(_) => return None,
        }
    }
}

/// Removes, until none is left, triangles with two or three boundary edges: such an ear
/// hangs on by one vertex or one edge and folds over at the slightest push.
fn drop_ears(faces: &mut Vec<[u32; 3]>) {
    loop {
        let mut count: HashMap<(u32, u32), u32> = HashMap::new();
        let edges = |f: &[u32; 3]| {
            let f = *f;
            (0..3).map(move |c| (f[c].min(f[(c + 1) % 3]), f[c].max(f[(c + 1) % 3])))
        };
        faces
            .iter()
            .flat_map(edges)
            .for_each(|e| *count.entry(e).or_default() += 1);
        let before = faces.len();
        faces.retain(|f| edges(f).filter(|e| count[e] == 1).count() < 2);
        if faces.len() == before {
            return;
        }
    }
}

/// The connected component with the most vertices.
fn largest_piece(mesh: &Mesh, surface: Surface) -> Option<Surface> {
    let components = mesh.connected_components();
    let largest = components.iter().max_by_key(|c| c.len())?;
    let mut keep = vec![false; surface.positions.len()];
    largest.iter().for_each(|&v| keep[v] = true);
    let faces: Vec<[u32; 3]> = (surface.faces.iter())
        .filter(|f| keep[f[0] as usize])
        .copied()
        .collect();
    Some(compact(&surface.positions, &faces, &mut Vec::new()))
}

/// The vertices `faces` use, renumbered in their order; `kept[new] = old`.
pub(super) fn compact(
    positions: &[nalgebra::Vector3<f64>],
    faces: &[[u32; 3]],
    kept: &mut Vec<usize>,
) -> Surface {
    let mut new_index = vec![u32::MAX; positions.len()];
    faces
        .iter()
        .flatten()
        .for_each(|&v| new_index[v as usize] = 0);
    kept.clear();
    for (old, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = kept.len() as u32;
            kept.push(old);
        }
    }
    Surface {
        positions: kept.iter().map(|&v| positions[v]).collect(),
        faces: faces
            .iter()
            .map(|f| f.map(|v| new_index[v as usize]))
            .collect(),
    }
}
