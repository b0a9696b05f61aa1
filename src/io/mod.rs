//! Reading and writing files: OBJ meshes, MatrixMarket matrices, NPY arrays.
//!
//! Every writer goes through [`write_atomically`]: the bytes land in a temporary file next to the
//! target, which is renamed over it only when complete, so a failed run never leaves a
//! half-written output behind.

mod atomic;
mod flow_output;
mod frame;
pub mod gltf_read;
pub mod gltf_write;
mod mtx;
mod npy;
mod obj;
pub mod ply;
mod sequence;
mod texture;
pub mod vtk;

pub use atomic::write_atomically;
pub use flow_output::{summary_json, write_flow_outputs};
pub use frame::{grey_value, FrameMesh, RawSequence};
pub use mtx::{read_matrix_market, write_matrix_market};
pub use npy::{read_npy, write_npy, NpyArray};
pub use obj::{read_obj, write_obj, ObjMesh};
pub use sequence::{load_obj_sequence, natural_order, obj_frames};
pub use texture::Texture;

use std::path::PathBuf;

/// A file could not be read, parsed or written.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    #[error("{}: {source}", path.display())]
    File {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}, line {line}: {message}", path.display())]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{}: {message}", path.display())]
    Format { path: PathBuf, message: String },
}

impl IoError {
    pub(crate) fn file(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::File {
            path: path.into(),
            source,
        }
    }

    pub(crate) fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Format {
            path: path.into(),
            message: message.into(),
        }
    }
}
