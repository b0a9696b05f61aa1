//! Reading and writing files.
//!
//! In: mesh sequences as OBJ, PLY or glTF frames, one glTF animation (morph targets, skin or
//! node transforms), or NPY arrays ([`load_sequence`]); a known flow to compare with
//! ([`read_ground_truth`]); single meshes ([`load_mesh`]). Both loaders weld seams, drop unused vertices, orient and optionally
//! repair the faces, and keep a [`VertexMap`] between the files' vertices and the mesh's. Out: the flow (and its errors against a known one) as NPY, ParaView
//! VTU/PVD and glTF ([`write_flow_outputs`]; over ranks, slab by slab as the ranks send their
//! slabs: [`write_flow_over_ranks`]), operators as MatrixMarket.
//!
//! Every writer goes through [`write_atomically`]: the bytes land in a temporary file next to the
//! target, which is renamed over it only when complete, so a failed run never leaves a
//! half-written output behind. Output directories are staged whole ([`StagedDir`]): each holds
//! exactly one run, marked by its manifest [`RUN_MANIFEST`].

mod analysis_output;
mod atomic;
mod channels;
mod flow_output;
mod flow_over_ranks;
mod frame;
mod glb;
pub mod gltf_read;
pub mod gltf_write;
mod ground_truth;
mod guard;
mod input;
mod linked;
mod mtl;
mod mtx;
mod npy;
mod obj;
pub mod ply;
mod prepare;
mod sequence;
mod texture;
mod vertex_map;
pub mod vtk;
mod warning;
mod weld;

pub use analysis_output::{
    analysis_arrays, analysis_json, file_faces, write_analysis_outputs, AnalysisArray,
};
pub use atomic::RUN_MANIFEST;
pub use atomic::{
    input_files, remove_live_staging, write_atomically, Overwrite, RecordedInput, RunManifest,
    StagedDir,
};
pub use channels::{select_channels, Channels, VertexValues};
pub use flow_output::{
    summary_json, track_scores_json, write_flow_outputs, write_run_input, write_slab_vtus,
    write_slab_vtus_with_cells, GroundTruthReport, OutputFormat, Scores, TrackReport,
};
pub use flow_over_ranks::{send_own_slabs, write_flow_over_ranks, WrittenFlow};
pub use frame::{grey_value, grey_values, FrameMesh, RawSequence};
pub use ground_truth::read_ground_truth;
pub use guard::{refuse_output_over_inputs, OutputKind};
pub use input::{frame_files, FrameFormat, SequenceSource};
pub use linked::resolve_linked;
pub use mtl::{texture_colors, TextureCache};
pub use mtx::{read_matrix_market, write_matrix_market};
pub use npy::{
    read_npy, read_npy_f32, read_npy_float, read_npy_float_rows, read_npy_image,
    read_npy_image_rows, read_npy_indices, write_npy, write_npy_sequence, write_npy_vectors,
    KeepRows, NpyArray, NpyRows,
};
pub use obj::{read_obj, write_obj, ObjMesh};
pub use prepare::{load_mesh, mesh_from_arrays, read_mesh_geometry, LoadedMesh};
pub use sequence::{
    count_frames, load_frames, load_geometry, load_sequence, natural_order, read_intensity_array,
    read_mesh, read_mesh_with, read_times_file, sequence_from_arrays, LoadOptions, LoadedGeometry,
    LoadedSequence, SumOverReaders,
};
pub use texture::Texture;
pub use vertex_map::VertexMap;
pub use warning::{LoadWarning, STATIC_IMAGE_TOLERANCE};

use std::path::{Path, PathBuf};

/// The whole of a regular file, after checking its size against the memory limit
/// ([`crate::limits`]): a device such as `/dev/zero` or a FIFO would never end.
pub fn read_file(path: &Path) -> Result<Vec<u8>, IoError> {
    use std::io::Read;
    let (file, length) = open_regular(path)?;
    crate::limits::check_declared("the file", length).map_err(|e| IoError::too_large(path, e))?;
    let mut bytes = Vec::with_capacity(length as usize);
    (file.take(length).read_to_end(&mut bytes)).map_err(|e| IoError::file(path, e))?;
    Ok(bytes)
}

/// `path` opened for reading if it is a regular file, with its length: a FIFO would block the
/// open itself, a device never end.
pub fn open_regular(path: &Path) -> Result<(std::fs::File, u64), IoError> {
    let not_regular = || IoError::format(path, "not a regular file");
    let metadata = std::fs::metadata(path).map_err(|e| IoError::file(path, e))?;
    if !metadata.is_file() {
        return Err(not_regular());
    }
    let file = std::fs::File::open(path).map_err(|e| IoError::file(path, e))?;
    // Checked again on what was opened: the path may have changed in between.
    let metadata = file.metadata().map_err(|e| IoError::file(path, e))?;
    match metadata.is_file() {
        true => Ok((file, metadata.len())),
        false => Err(not_regular()),
    }
}

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
    /// The faces of a file are not an oriented manifold; `message` tells it in the file's
    /// vertex numbers (`source` has the mesh's).
    #[error("{}: {message}", path.display())]
    Connectivity {
        path: PathBuf,
        message: String,
        #[source]
        source: crate::mesh::ConnectivityError,
    },
    /// A size `path` declares does not fit the memory limit ([`crate::limits`]).
    #[error("{}: {source}", path.display())]
    TooLarge {
        path: PathBuf,
        #[source]
        source: crate::limits::OverBudget,
    },
    /// An output would replace or lie among a command's inputs.
    #[error("{}: {message}", path.display())]
    OverInput { path: PathBuf, message: String },
    /// A file that `path` refers to (an OBJ's material library or texture) failed.
    #[error("{}: {context}: {source}", path.display())]
    Referenced {
        path: PathBuf,
        context: String,
        source: Box<IoError>,
    },
}

impl IoError {
    /// An operating-system error about `path`.
    pub fn file(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::File {
            path: path.into(),
            source,
        }
    }

    /// A declared size of `path` over the memory limit.
    pub fn too_large(path: impl Into<PathBuf>, source: crate::limits::OverBudget) -> Self {
        Self::TooLarge {
            path: path.into(),
            source,
        }
    }

    /// The file the error is about.
    pub fn path(&self) -> &std::path::Path {
        match self {
            Self::File { path, .. }
            | Self::Parse { path, .. }
            | Self::Format { path, .. }
            | Self::Connectivity { path, .. }
            | Self::TooLarge { path, .. }
            | Self::OverInput { path, .. }
            | Self::Referenced { path, .. } => path,
        }
    }

    fn path_mut(&mut self) -> &mut PathBuf {
        match self {
            Self::File { path, .. }
            | Self::Parse { path, .. }
            | Self::Format { path, .. }
            | Self::Connectivity { path, .. }
            | Self::TooLarge { path, .. }
            | Self::OverInput { path, .. }
            | Self::Referenced { path, .. } => path,
        }
    }

    /// An error at `line` of `path` (1-based), or about the whole file when `line` is 0.
    pub(crate) fn at_line(path: &std::path::Path, (line, message): (usize, String)) -> Self {
        match line {
            0 => Self::format(path, message),
            line => Self::Parse {
                path: path.to_path_buf(),
                line,
                message,
            },
        }
    }

    /// A problem with the contents of `path` (not tied to a line).
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Format {
            path: path.into(),
            message: message.into(),
        }
    }
}
