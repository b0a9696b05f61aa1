//! Things a loader noticed and worked around without failing: the caller decides how to show
//! them (the CLI prints each as one `meshflow: warning: …` line).

use std::path::PathBuf;

/// A remark about an input that was read successfully but not exactly as written.
///
/// Every variant names the file it is about; `Display` gives one line for a user.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LoadWarning {
    /// File vertices that are shared by no face were left out of the mesh.
    #[error("{}: dropped {count} vertices that no face uses (e.g. file vertex {first}); outputs keep the file's numbering", file.display())]
    UnusedVertices {
        file: PathBuf,
        count: usize,
        first: usize,
    },
}
