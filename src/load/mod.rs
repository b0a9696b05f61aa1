//! Loading: files or arrays → a validated [`MeshSequence`](crate::flow::MeshSequence), above the
//! codecs of [`crate::format`].
//!
//! In: mesh sequences as OBJ, PLY or glTF frames, one glTF animation (morph targets, skin or
//! node transforms), or NPY arrays ([`load_sequence`], [`sequence_from_arrays`]); a known flow
//! to compare with ([`read_ground_truth`]); single meshes ([`load_mesh`]). Both loaders weld
//! seams ([`crate::mesh`]'s welding), drop unused vertices, orient and optionally repair the
//! faces, and keep a [`VertexMap`] between the files' vertices and the mesh's. The image's
//! channels are chosen by [`Channels`]; what a loader noticed and worked around comes back as
//! [`LoadWarning`]s, for the caller to show.
//!
//! The steps, in the order data flows: [`SequenceSource`] (which files, which format) →
//! the codecs' raw frames → `prepare` (weld, orient, repair, the vertex map) → channels and
//! times → [`MeshSequence`](crate::flow::MeshSequence) (validated).

mod channels;
mod ground_truth;
mod input;
mod no_data;
mod options;
mod prepare;
mod sequence;
mod vertex_map;
mod warning;

/// Moved to [`crate::format`] (the NPY sequence's layout); kept here for one release.
pub use crate::format::read_intensity_array;
pub use channels::{select_channels, Channels};
pub use ground_truth::read_ground_truth;
pub use input::{may_read, FrameFormat, SequenceSource};
pub use options::LoadOptions;
pub use prepare::{load_mesh, mesh_from_arrays, read_mesh_geometry, LoadedMesh};
pub(crate) use sequence::StaticImageCheck;
pub use sequence::{
    count_frames, load_frames, load_geometry, load_sequence, read_mesh, read_mesh_with,
    read_times_file, sequence_from_arrays, LoadedGeometry, LoadedSequence,
};
pub use vertex_map::VertexMap;
pub use warning::{LoadWarning, STATIC_IMAGE_TOLERANCE};
