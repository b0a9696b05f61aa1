//! Building and validating the connectivity tables of a [`Mesh`].

use super::{Corner, Mesh, NO_HALFEDGE};

/// Why a face list is not an oriented manifold triangle mesh.
///
/// `Display` names vertices "vertex i"; [`ConnectivityError::describe`] gives the same message
/// with vertices named otherwise (e.g. in a file's numbering).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConnectivityError {
    NoFaces,
    IndexOutOfRange {
        face: usize,
        index: u32,
        n_vertices: usize,
    },
    RepeatedVertex {
        face: usize,
        vertex: u32,
    },
    NonManifoldEdge {
        vertices: [u32; 2],
        n_faces: usize,
        faces: [usize; 2],
    },
    InconsistentOrientation {
        vertices: [u32; 2],
        faces: [usize; 2],
    },
    /// No flips make the faces of a connected component agree (a Möbius strip): orienting
    /// breadth-first, `faces` still traverse their shared edge in the same direction.
    NonOrientable {
        vertices: [u32; 2],
        faces: [usize; 2],
    },
    NonManifoldVertex {
        vertex: usize,
        n_fans: usize,
    },
    IsolatedVertex {
        vertex: usize,
    },
}

impl ConnectivityError {
    /// The message, with every vertex of the mesh named by `vertex` (e.g. `"vertex 3"`).
    pub fn describe(&self, vertex: impl Fn(u32) -> String) -> String {
        let edge = |[a, b]: [u32; 2]| format!("the edge between {} and {}", vertex(a), vertex(b));
        match self {
            Self::NoFaces => "the mesh has no faces".into(),
            Self::IndexOutOfRange {
                face,
                index,
                n_vertices,
            } => format!(
                "face {face} refers to vertex {index}, but the mesh has {n_vertices} vertices"
            ),
            Self::RepeatedVertex { face, vertex: v } => {
                format!("face {face} uses {} more than once", vertex(*v))
            }
            Self::NonManifoldEdge {
                vertices,
                n_faces,
                faces,
            } => format!(
                "{} is shared by {n_faces} faces (non-manifold edge), e.g. faces {faces:?}",
                edge(*vertices)
            ),
            Self::InconsistentOrientation { vertices, faces } => format!(
                "faces {faces:?} traverse {} in the same direction (inconsistent orientation)",
                edge(*vertices)
            ),
            Self::NonOrientable { vertices, faces } => format!(
                "the surface is not orientable: no flips make faces {faces:?} traverse {} in \
                 opposite directions",
                edge(*vertices)
            ),
            Self::NonManifoldVertex { vertex: v, n_fans } => format!(
                "{} has {n_fans} separate fans of faces (non-manifold vertex)",
                vertex(*v as u32)
            ),
            Self::IsolatedVertex { vertex: v } => format!(
                "{} is not used by any face (isolated vertex)",
                vertex(*v as u32)
            ),
        }
    }
}

impl std::fmt::Display for ConnectivityError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe(|v| format!("vertex {v}")))
    }
}

impl std::error::Error for ConnectivityError {}

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
    check_repeated_vertices(faces)
}

/// Fails on the first face that names a vertex twice.
pub(super) fn check_repeated_vertices(faces: &[[u32; 3]]) -> Result<(), ConnectivityError> {
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
    let vertices_of = |h: usize| halfedge_vertices(faces, h);
    let keyed = halfedges_by_edge(faces);
    let mut twins = vec![NO_HALFEDGE; n_halfedges];
    let mut halfedge_edges = vec![0u32; n_halfedges];
    let mut edges = Vec::with_capacity(n_halfedges / 2 + 1);
    for run in keyed.chunk_by(|a, b| a.0 == b.0) {
        let vertices = edge_of_key(run[0].0);
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

/// Tail and head of halfedge `h` (see the module conventions).
pub(super) fn halfedge_vertices(faces: &[[u32; 3]], h: usize) -> [u32; 2] {
    [faces[h / 3][h % 3], faces[h / 3][(h + 1) % 3]]
}

/// Every halfedge as `(edge key, halfedge)`, sorted: the halfedges of one undirected edge
/// `[i, j]`, `i < j` (key `i << 32 | j`), follow each other in halfedge order.
pub(super) fn halfedges_by_edge(faces: &[[u32; 3]]) -> Vec<(u64, u32)> {
    let mut keyed: Vec<(u64, u32)> = (0..3 * faces.len())
        .map(|h| {
            let [i, j] = halfedge_vertices(faces, h);
            let key = ((i.min(j) as u64) << 32) | i.max(j) as u64;
            (key, h as u32)
        })
        .collect();
    keyed.sort_unstable();
    keyed
}

/// The two vertices of an edge key of [`halfedges_by_edge`].
pub(super) fn edge_of_key(key: u64) -> [u32; 2] {
    [(key >> 32) as u32, key as u32]
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
                n_fans: count_fans(&starts, corners, twins),
            });
        }
    }
    Ok((offsets, ordered, boundary))
}

/// How many fans the corners of one vertex form: one per boundary start, then closed ones.
fn count_fans(starts: &[Corner], corners: &[Corner], twins: &[u32]) -> usize {
    let mut seen = std::collections::HashSet::new();
    let mut fans = 0;
    let mut fan = Vec::new();
    for &corner in starts.iter().chain(corners) {
        if seen.contains(&corner) {
            continue;
        }
        fans += 1;
        fan.clear();
        walk_fan(corner, twins, corners.len(), &mut fan);
        seen.extend(fan.iter().copied());
    }
    fans
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
