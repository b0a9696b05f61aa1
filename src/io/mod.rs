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
mod ground_truth;
mod guard;
mod input;
mod prepare;
mod sequence;
mod vertex_map;
mod warning;

pub use crate::format::gltf as gltf_read;
pub use crate::format::gltf as gltf_write;
pub use crate::format::{frame_files, natural_order};
pub use crate::format::{grey_value, grey_values, FrameMesh, RawSequence, VertexValues};
pub use crate::format::{ply, vtk};
pub use crate::format::{read_matrix_market, write_matrix_market};
pub use crate::format::{
    read_npy, read_npy_f32, read_npy_float, read_npy_float_rows, read_npy_image,
    read_npy_image_rows, read_npy_indices, write_npy, write_npy_sequence, write_npy_vectors,
    KeepRows, NpyArray, NpyRows,
};
pub use crate::format::{read_obj, write_obj, ObjMesh};
pub use crate::format::{resolve_linked, texture_colors, Texture, TextureCache};
pub use analysis_output::{
    analysis_arrays, analysis_json, file_faces, write_analysis_outputs, AnalysisArray,
};
pub use atomic::RUN_MANIFEST;
pub use atomic::{
    input_files, remove_live_staging, Overwrite, RecordedInput, RunManifest, StagedDir,
};
pub use channels::{select_channels, Channels};
pub use flow_output::{
    summary_json, track_scores_json, write_flow_outputs, write_run_input, write_slab_vtus,
    write_slab_vtus_with_cells, GroundTruthReport, OutputFormat, Scores, TrackReport,
};
pub use flow_over_ranks::{send_own_slabs, write_flow_over_ranks, WrittenFlow};
pub use ground_truth::read_ground_truth;
pub use guard::{refuse_output_over_inputs, OutputKind};
pub use input::{FrameFormat, SequenceSource};
pub use prepare::{load_mesh, mesh_from_arrays, read_mesh_geometry, LoadedMesh};
pub use sequence::{
    count_frames, load_frames, load_geometry, load_sequence, read_intensity_array, read_mesh,
    read_mesh_with, read_times_file, sequence_from_arrays, LoadOptions, LoadedGeometry,
    LoadedSequence, SumOverReaders,
};
pub use vertex_map::VertexMap;
pub use warning::{LoadWarning, STATIC_IMAGE_TOLERANCE};

pub use crate::format::{open_regular, read_file, write_atomically, IoError};
