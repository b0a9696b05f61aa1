//! From the faces of a file to a valid [`Mesh`]: the steps every loader takes, in order.
//!
//! 1. **Weld** coincident copies along seams (unless `--no-weld`; see [`crate::mesh`]'s welding for the
//!    rule and `--weld-tolerance`).
//! 2. With `--repair`, **repair** ([`crate::mesh::repair`]): drop faces with a repeated vertex
//!    and duplicate faces, orient, cut non-manifold edges and orientation conflicts, split
//!    non-manifold vertices. Without it, **orient** ([`crate::mesh::orient`]) when neighbouring
//!    faces disagree, and refuse what only repair can fix, naming the file's vertices and
//!    suggesting `--repair`.
//! 3. **Drop** vertices that no face uses.
//!
//! The [`VertexMap`] records how file vertices became mesh vertices; every change is reported
//! as a [`LoadWarning`] naming the file (welding itself is not a warning: it is what seams
//! need). [`load_mesh`] reads one mesh file through these steps, geometry only.

use super::{FrameFormat, LoadOptions, LoadWarning, VertexMap};
use crate::format::gltf::read_gltf_geometry;
use crate::format::ply::read_ply;
use crate::format::{read_obj, FrameMesh, IoError};
use crate::mesh::{check_index_range, orient, repair, ConnectivityError, Mesh};
use crate::mesh::{weld, SumOverReaders, Weld};
use crate::mesh::{RepairReport, Repaired};
use crate::Error;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// A mesh built from a file's faces, and how it relates to the file.
#[derive(Clone, Debug)]
pub(crate) struct Prepared {
    pub mesh: Mesh,
    pub vertex_map: VertexMap,
    pub warnings: Vec<LoadWarning>,
}

/// Runs the module's steps on `faces` (file numbering, any indices) with one position per file
/// vertex in each of `frames`; `file` is named in errors and warnings.
pub(crate) fn prepare_mesh(
    file: &Path,
    faces: &[[u32; 3]],
    frames: &[&[Vector3<f64>]],
    options: &LoadOptions,
    sum: SumOverReaders,
) -> Result<Prepared, Error> {
    let n_file = frames.first().map_or(0, |f| f.len());
    check_index_range(faces, n_file).map_err(|e| Error::from(e).in_file(file))?;
    // Relative to the bounding-box diagonal: above 1 every vertex would coincide.
    if !(0.0..=1.0).contains(&options.weld_tolerance) {
        return Err(IoError::format(
            file,
            format!(
                "--weld-tolerance must be a number from 0 to 1 (relative to frame 0's \
                 bounding-box diagonal), got {:e}",
                options.weld_tolerance
            ),
        )
        .into());
    }
    let weld = match options.weld {
        true => weld(faces, frames, options.weld_tolerance, sum).map_err(|e| {
            IoError::format(
                file,
                format!(
                    "--weld-tolerance {} makes more than {} pairs of vertices coincide: seam \
                     copies are far closer than neighbouring vertices; give a smaller tolerance",
                    options.weld_tolerance, e.limit
                ),
            )
        })?,
        false => Weld::none(n_file),
    };
    let welded_faces: Vec<[u32; 3]> = faces
        .iter()
        .map(|f| f.map(|v| weld.welded[v as usize]))
        .collect();
    let names = VertexNames {
        file,
        welded: &weld.welded,
    };
    let (mut connected, mut report) = match options.repair {
        true => {
            let repaired = repair(weld.n_vertices, &welded_faces);
            let report = repaired.report;
            (repaired, report)
        }
        false => (
            drop_unused(weld.n_vertices, welded_faces),
            RepairReport::default(),
        ),
    };
    let welded_of = |m: u32| connected.vertex_origin[m as usize];
    let n_mesh = connected.vertex_origin.len();
    let mesh = match Mesh::new(n_mesh, connected.faces.clone()) {
        // Orienting costs as much as validating: only when needed (repair has oriented).
        Err(ConnectivityError::InconsistentOrientation { .. }) if !options.repair => {
            report.flipped_faces =
                orient(&mut connected.faces).map_err(|e| names.error(e, &welded_of))?;
            Mesh::new(n_mesh, connected.faces.clone())
        }
        built => built,
    }
    .map_err(|e| names.error(e, &welded_of))?;
    let vertex_map = vertex_map(faces, &weld, &connected);
    let warnings = warnings(file, faces, n_file, &weld, &report);
    Ok(Prepared {
        mesh,
        vertex_map,
        warnings,
    })
}

/// The faces over the used vertices only, renumbered in order (`vertex_origin`: the old
/// number of each new vertex), in [`repair`]'s output form.
fn drop_unused(n_vertices: usize, faces: Vec<[u32; 3]>) -> Repaired {
    let mut new_number = vec![u32::MAX; n_vertices];
    for &v in faces.iter().flatten() {
        new_number[v as usize] = 0;
    }
    let mut vertex_origin = Vec::new();
    for (v, number) in new_number.iter_mut().enumerate() {
        if *number == 0 {
            *number = vertex_origin.len() as u32;
            vertex_origin.push(v as u32);
        }
    }
    Repaired {
        face_origin: (0..faces.len() as u32).collect(),
        faces: faces
            .into_iter()
            .map(|f| f.map(|v| new_number[v as usize]))
            .collect(),
        vertex_origin,
        report: RepairReport::default(),
    }
}

/// Follows every corner of the mesh back to its file vertex (see [`VertexMap`]'s conventions).
fn vertex_map(file_faces: &[[u32; 3]], weld: &Weld, connected: &Repaired) -> VertexMap {
    const NONE: u32 = u32::MAX;
    let n_mesh = connected.vertex_origin.len();
    let mut mesh_vertices = vec![NONE; weld.welded.len()];
    let mut first_corner_file = vec![NONE; n_mesh];
    for (face, &origin) in connected.faces.iter().zip(&connected.face_origin) {
        let file_face = file_faces[origin as usize];
        for &m in face {
            let w = connected.vertex_origin[m as usize];
            let i = *file_face
                .iter()
                .find(|&&i| weld.welded[i as usize] == w)
                .expect("a mesh corner comes from a corner of its file face");
            if mesh_vertices[i as usize] == NONE {
                mesh_vertices[i as usize] = m;
            }
            if first_corner_file[m as usize] == NONE {
                first_corner_file[m as usize] = i;
            }
        }
    }
    // File vertices without a face left (their faces removed by repair) go with their welded
    // vertex's first piece, if it has one.
    let mut first_piece = vec![NONE; weld.n_vertices];
    for (m, &w) in connected.vertex_origin.iter().enumerate().rev() {
        first_piece[w as usize] = m as u32;
    }
    for (i, m) in mesh_vertices.iter_mut().enumerate() {
        if *m == NONE {
            *m = first_piece[weld.welded[i] as usize];
        }
    }
    VertexMap::with_fallback(mesh_vertices, &first_corner_file)
        .expect("every mesh vertex has a corner")
}

fn warnings(
    file: &Path,
    faces: &[[u32; 3]],
    n_file: usize,
    weld: &Weld,
    report: &RepairReport,
) -> Vec<LoadWarning> {
    let file = file.to_path_buf();
    let mut used = vec![false; n_file];
    faces
        .iter()
        .flatten()
        .for_each(|&v| used[v as usize] = true);
    let mut warnings = Vec::new();
    if let Some(first) = used.iter().position(|&u| !u) {
        warnings.push(LoadWarning::UnusedVertices {
            file: file.clone(),
            count: used.iter().filter(|&&u| !u).count(),
            first,
        });
    }
    if let Some([a, b]) = weld.first_apart {
        warnings.push(LoadWarning::TouchingVertices {
            file: file.clone(),
            count: weld.apart,
            first: [a as usize, b as usize],
        });
    }
    if report.flipped_faces > 0 {
        warnings.push(LoadWarning::FlippedFaces {
            file: file.clone(),
            count: report.flipped_faces,
        });
    }
    if !report.is_empty() {
        warnings.push(LoadWarning::Repaired {
            file,
            report: *report,
        });
    }
    warnings
}

/// Names welded vertices by their file vertices, for errors.
struct VertexNames<'a> {
    file: &'a Path,
    welded: &'a [u32],
}

impl VertexNames<'_> {
    /// `error` (vertices numbered `w` such that `welded_of(w)` is the welded vertex) in the
    /// file's numbering, with advice when `--repair` would fix it.
    fn error(&self, error: ConnectivityError, welded_of: &dyn Fn(u32) -> u32) -> Error {
        let message = error.describe(|v| self.describe(welded_of(v)));
        let advice = match error {
            ConnectivityError::NonManifoldEdge { .. }
            | ConnectivityError::NonManifoldVertex { .. } => {
                "; use --repair to split it into manifold pieces"
            }
            ConnectivityError::NonOrientable { .. } => {
                "; use --repair to cut it open where the orientation flips"
            }
            ConnectivityError::RepeatedVertex { .. } => "; use --repair to drop such faces",
            _ => "",
        };
        IoError::Connectivity {
            path: self.file.to_path_buf(),
            message: format!("{message}{advice}"),
            source: error,
        }
        .into()
    }

    /// "file vertex 4", or "file vertex 4 (welded with file vertices 9, 12)".
    fn describe(&self, w: u32) -> String {
        const SHOWN: usize = 4;
        let mut members = (0..self.welded.len()).filter(|&i| self.welded[i] == w);
        let first = members.next().unwrap_or(w as usize);
        let others: Vec<usize> = members.collect();
        let mut listed: Vec<String> = others.iter().take(SHOWN).map(usize::to_string).collect();
        if others.len() > SHOWN {
            listed.push(format!("… ({} in all)", others.len()));
        }
        match others.len() {
            0 => format!("file vertex {first}"),
            1 => format!(
                "file vertex {first} (welded with file vertex {})",
                others[0]
            ),
            _ => format!(
                "file vertex {first} (welded with file vertices {})",
                listed.join(", ")
            ),
        }
    }
}

/// One mesh read from a file by [`load_mesh`], geometry only.
#[derive(Clone, Debug)]
pub struct LoadedMesh {
    pub mesh: Mesh,
    /// Positions of the mesh vertices.
    pub positions: Vec<Vector3<f64>>,
    /// File vertices ↔ mesh vertices.
    pub vertex_map: VertexMap,
    pub file: PathBuf,
    /// What the loader changed (see [`LoadWarning`]).
    pub warnings: Vec<LoadWarning>,
}

/// Reads one mesh file (`.obj`, `.ply`, `.gltf`, `.glb`) without grey values (no textures are
/// opened) and builds its mesh as [`super::load_sequence`] does: seam copies welded, unused
/// vertices dropped, faces oriented, repaired on request (`docs/io.md`). Of `options`,
/// `weld`, `weld_tolerance` and `repair` apply.
pub fn load_mesh(path: &Path, options: &LoadOptions) -> Result<LoadedMesh, Error> {
    let FrameMesh {
        positions, faces, ..
    } = read_mesh_geometry(path)?;
    built_mesh(path, positions, &faces, options)
}

/// A mesh from arrays in memory, built as [`load_mesh`] builds a file's (`file` is `"arrays"`).
pub fn mesh_from_arrays(
    positions: Vec<Vector3<f64>>,
    faces: &[[u32; 3]],
    options: &LoadOptions,
) -> Result<LoadedMesh, Error> {
    built_mesh(Path::new(super::input::ARRAYS), positions, faces, options)
}

fn built_mesh(
    path: &Path,
    positions: Vec<Vector3<f64>>,
    faces: &[[u32; 3]],
    options: &LoadOptions,
) -> Result<LoadedMesh, Error> {
    crate::geometry::check_finite_positions(&positions)
        .map_err(|e| Error::from(e).in_file(path))?;
    let prepared = prepare_mesh(path, faces, &[&positions], options, &|_| {})?;
    Ok(LoadedMesh {
        positions: prepared.vertex_map.positions(&positions),
        mesh: prepared.mesh,
        vertex_map: prepared.vertex_map,
        file: path.to_path_buf(),
        warnings: prepared.warnings,
    })
}

/// Positions and faces of a mesh file, as stored (`intensity` is `None`): no colours are
/// read and no textures opened.
pub fn read_mesh_geometry(path: &Path) -> Result<FrameMesh, IoError> {
    let format = FrameFormat::of(path).ok_or_else(|| {
        IoError::format(
            path,
            "unknown mesh format (expected .obj, .ply, .gltf or .glb)",
        )
    })?;
    let (positions, faces) = match format {
        FrameFormat::Obj => {
            let obj = read_obj(path)?;
            (obj.positions, obj.faces)
        }
        FrameFormat::Ply => {
            let ply = read_ply(path)?;
            (ply.positions, ply.faces)
        }
        FrameFormat::Gltf => return read_gltf_geometry(path),
    };
    Ok(FrameMesh {
        positions,
        faces,
        image: None,
    })
}
