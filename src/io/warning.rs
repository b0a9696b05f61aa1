//! Things a loader noticed and worked around without failing: the caller decides how to show
//! them (the CLI prints each as one `meshflow: warning: …` line).

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
