//! Building and validating the connectivity tables of a [`Mesh`].

use super::{Corner, Mesh, NO_HALFEDGE};

/// Why a face list is not an oriented manifold triangle mesh.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConnectivityError {
    #[error("the mesh has no faces")]
    NoFaces,
    #[error("face {face} refers to vertex {index}, but the mesh has {n_vertices} vertices")]
    IndexOutOfRange {
        face: usize,
        index: u32,
        n_vertices: usize,
    },
    #[error("face {face} uses vertex {vertex} more than once")]
    RepeatedVertex { face: usize, vertex: u32 },
    #[error(
        "edge {vertices:?} is shared by {n_faces} faces (non-manifold edge), e.g. faces {faces:?}"
    )]
    NonManifoldEdge {
        vertices: [u32; 2],
        n_faces: usize,
        faces: [usize; 2],
    },
    #[error("faces {faces:?} traverse their shared edge {vertices:?} in the same direction (inconsistent orientation)")]
    InconsistentOrientation {
        vertices: [u32; 2],
        faces: [usize; 2],
    },
    #[error("vertex {vertex} has {n_fans} separate fans of faces (non-manifold vertex)")]
    NonManifoldVertex { vertex: usize, n_fans: usize },
    #[error("vertex {vertex} is not used by any face (isolated vertex)")]
    IsolatedVertex { vertex: usize },
}

pub(super) fn build(n_vertices: usize, faces: Vec<[u32; 3]>) -> Result<Mesh, ConnectivityError> {
    if faces.is_empty() {
        return Err(ConnectivityError::NoFaces);
    }
    check_face_indices(n_vertices, &faces)?;
    let (twins, halfedge_edges, edges) = pair_halfedges(&faces)?;
    let (fan_offsets, fan_corners, boundary_vertices) = build_fans(n_vertices, &faces, &twins)?;
    Ok(Mesh {
        n_vertices,
        faces,
        twins,
        halfedge_edges,
        edges,
        fan_offsets,
        fan_corners,
        boundary_vertices,
    })
}

/// Checks that every face index names one of `n_vertices` vertices: the first check of
/// [`Mesh::new`], and of anything that must index per-vertex arrays with faces before a mesh
/// exists (file writers, welding).
pub fn check_index_range(faces: &[[u32; 3]], n_vertices: usize) -> Result<(), ConnectivityError> {
    for (face, vertices) in faces.iter().enumerate() {
        if let Some(&index) = vertices.iter().find(|&&v| v as usize >= n_vertices) {
            return Err(ConnectivityError::IndexOutOfRange {
                face,
                index,
                n_vertices,
            });
        }
    }
    Ok(())
}

fn check_face_indices(n_vertices: usize, faces: &[[u32; 3]]) -> Result<(), ConnectivityError> {
    check_index_range(faces, n_vertices)?;
    for (f, face) in faces.iter().enumerate() {
        if face[0] == face[1] || face[0] == face[2] {
            return Err(ConnectivityError::RepeatedVertex {
                face: f,
                vertex: face[0],
            });
        }
        if face[1] == face[2] {
            return Err(ConnectivityError::RepeatedVertex {
                face: f,
                vertex: face[1],
            });
        }
    }
    Ok(())
}

type HalfedgeTables = (Vec<u32>, Vec<u32>, Vec<[u32; 2]>);

/// Groups halfedges by undirected edge (sorting, not hashing: linear memory, fast on 10^7
/// halfedges) and pairs each interior halfedge with its twin.
fn pair_halfedges(faces: &[[u32; 3]]) -> Result<HalfedgeTables, ConnectivityError> {
    let n_halfedges = 3 * faces.len();
    let vertices_of = |h: usize| [faces[h / 3][h % 3], faces[h / 3][(h + 1) % 3]];
    let mut keyed: Vec<(u64, u32)> = (0..n_halfedges)
        .map(|h| {
            let [i, j] = vertices_of(h);
            let key = ((i.min(j) as u64) << 32) | i.max(j) as u64;
            (key, h as u32)
        })
        .collect();
    keyed.sort_unstable();

    let mut twins = vec![NO_HALFEDGE; n_halfedges];
    let mut halfedge_edges = vec![0u32; n_halfedges];
    let mut edges = Vec::with_capacity(n_halfedges / 2 + 1);
    for run in keyed.chunk_by(|a, b| a.0 == b.0) {
        let vertices = [(run[0].0 >> 32) as u32, run[0].0 as u32];
        let first = run[0].1 as usize;
        if run.len() > 2 {
            return Err(ConnectivityError::NonManifoldEdge {
                vertices,
                n_faces: run.len(),
                faces: [first / 3, run[1].1 as usize / 3],
            });
        }
        if let [(_, a), (_, b)] = *run {
            let (a, b) = (a as usize, b as usize);
            if vertices_of(a) == vertices_of(b) {
                return Err(ConnectivityError::InconsistentOrientation {
                    vertices,
                    faces: [a / 3, b / 3],
                });
            }
            twins[a] = b as u32;
            twins[b] = a as u32;
        }
        for &(_, h) in run {
            halfedge_edges[h as usize] = edges.len() as u32;
        }
        edges.push(vertices);
    }
    Ok((twins, halfedge_edges, edges))
}

type FanTables = (Vec<usize>, Vec<Corner>, Vec<bool>);

/// Orders the corners around every vertex counter-clockwise and checks that they form one fan.
fn build_fans(
    n_vertices: usize,
    faces: &[[u32; 3]],
    twins: &[u32],
) -> Result<FanTables, ConnectivityError> {
    let mut offsets = vec![0usize; n_vertices + 1];
    for face in faces {
        for &v in face {
            offsets[v as usize + 1] += 1;
        }
    }
    for i in 0..n_vertices {
        offsets[i + 1] += offsets[i];
    }
    if let Some(vertex) = (0..n_vertices).find(|&i| offsets[i] == offsets[i + 1]) {
        return Err(ConnectivityError::IsolatedVertex { vertex });
    }
    // Corners grouped by vertex, in face order: the first one, in the lowest-numbered face, is
    // where an interior fan starts (docs/discretization.md fixes it: the reference edge of the
    // vertex frame depends on it).
    let mut unordered = vec![Corner { face: 0, local: 0 }; offsets[n_vertices]];
    let mut fill = offsets.clone();
    for (f, face) in faces.iter().enumerate() {
        for (c, &v) in face.iter().enumerate() {
            unordered[fill[v as usize]] = Corner {
                face: f as u32,
                local: c as u8,
            };
            fill[v as usize] += 1;
        }
    }

    let mut ordered = Vec::with_capacity(unordered.len());
    let mut boundary = vec![false; n_vertices];
    for i in 0..n_vertices {
        let corners = &unordered[offsets[i]..offsets[i + 1]];
        let starts: Vec<Corner> = corners
            .iter()
            .copied()
            .filter(|c| twins[c.first_halfedge()] == NO_HALFEDGE)
            .collect();
        if starts.len() > 1 {
            return Err(ConnectivityError::NonManifoldVertex {
                vertex: i,
                n_fans: starts.len(),
            });
        }
        boundary[i] = !starts.is_empty();
        let start = starts.first().copied().unwrap_or(corners[0]);
        let before = ordered.len();
        walk_fan(start, twins, corners.len(), &mut ordered);
        if ordered.len() - before != corners.len() {
            return Err(ConnectivityError::NonManifoldVertex {
                vertex: i,
                n_fans: 2,
            });
        }
    }
    Ok((offsets, ordered, boundary))
}

/// Appends the corners reached from `start` by stepping counter-clockwise (across the second
/// edge) until the boundary or the start is reached, at most `limit` corners.
fn walk_fan(start: Corner, twins: &[u32], limit: usize, out: &mut Vec<Corner>) {
    let mut corner = start;
    for _ in 0..limit {
        out.push(corner);
        let twin = twins[corner.incoming_halfedge()];
        if twin == NO_HALFEDGE {
            return;
        }
        corner = Corner {
            face: twin / 3,
            local: (twin % 3) as u8,
        };
        if corner == start {
            return;
        }
    }
}
