//! Things a loader noticed and worked around without failing: the caller decides how to show
//! them (the CLI prints each as one `meshflow: warning: …` line).

use crate::format::gltf::{clip_list, AnimationClip};
use crate::mesh::RepairReport;
use std::path::PathBuf;

/// A remark about an input that was read successfully but not exactly as written.
///
/// Every variant names the file it is about; `Display` gives one line for a user.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LoadWarning {
    /// File vertices that are shared by no face were left out of the mesh.
    #[error("{}: dropped {} that no face uses (e.g. file vertex {first}); outputs keep the file's numbering", file.display(), counted(*count, "vertex", "vertices"))]
    UnusedVertices {
        file: PathBuf,
        count: usize,
        first: usize,
    },
    /// A glTF file holds several animations and none was chosen: `chosen`, the first that
    /// moves the mesh, was read.
    #[error("{}: {} animations ({}); read {chosen}, the first that moves the mesh; choose one with --animation NAME|INDEX", file.display(), clips.len(), clip_list(clips))]
    SeveralAnimations {
        file: PathBuf,
        clips: Vec<AnimationClip>,
        chosen: AnimationClip,
    },
    /// The grey values of every frame equal those of frame 0 (to [`STATIC_IMAGE_TOLERANCE`]
    /// of their range) while the surface moves: the image moves with the surface (a texture
    /// fixed to the mesh, say), so the flow along the surface is zero.
    #[error("{}: the grey values are the same in all {frames} frames while the surface moves: the image moves with the surface (e.g. a texture fixed to the mesh), so the flow is zero", file.display())]
    StaticImage { file: PathBuf, frames: usize },
    /// Coincident vertices that were not welded: joining them would make the mesh
    /// non-manifold (the surface touches itself there).
    #[error("{}: kept {} of coincident vertices apart where the surface touches itself (e.g. file vertices {} and {}); they are not seam copies", file.display(), counted(*count, "pair", "pairs"), first[0], first[1])]
    TouchingVertices {
        file: PathBuf,
        count: usize,
        first: [usize; 2],
    },
    /// Faces flipped to agree with their neighbours.
    #[error("{}: flipped {} to orient them like their neighbours", file.display(), counted(*count, "face", "faces"))]
    FlippedFaces { file: PathBuf, count: usize },
    /// What `--repair` changed.
    #[error("{}: repaired: {}", file.display(), describe_repair(report))]
    Repaired { file: PathBuf, report: RepairReport },
}

/// The non-zero counts of a repair (flips are reported on their own).
fn describe_repair(report: &RepairReport) -> String {
    let mut said = Vec::new();
    if report.degenerate_faces > 0 {
        let faces = counted(report.degenerate_faces, "face", "faces");
        said.push(format!("removed {faces} with a repeated vertex"));
    }
    if report.duplicate_faces > 0 {
        let faces = counted(report.duplicate_faces, "duplicate face", "duplicate faces");
        said.push(format!("removed {faces}"));
    }
    if report.non_manifold_edges > 0 {
        let edges = counted(report.non_manifold_edges, "edge", "edges");
        said.push(format!("cut {edges} with three or more faces"));
    }
    if report.orientation_cuts > 0 {
        let edges = counted(report.orientation_cuts, "edge", "edges");
        said.push(format!(
            "cut {edges} where the orientation flips (not orientable)"
        ));
    }
    if report.split_vertices > 0 {
        let vertices = counted(
            report.split_vertices,
            "non-manifold vertex",
            "non-manifold vertices",
        );
        let pieces = report.split_vertices + report.added_vertices;
        said.push(format!("split {vertices} into {pieces}"));
    }
    said.join(", ")
}

/// "1 face", "2 faces".
fn counted(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// Grey values closer than this fraction of their range count as equal for
/// [`LoadWarning::StaticImage`]: round-off, and far below any change that carries a flow.
pub const STATIC_IMAGE_TOLERANCE: f64 = 1e-6;
