//! The paths of meshflow 0.x's single I/O module, kept for one release so that code written
//! against `meshflow::io::…` keeps compiling.
//!
//! I/O now lives in three layers that change for different reasons:
//! - [`crate::format`]: file codecs, bytes ↔ arrays (OBJ, PLY, glTF, VTK, NPY, MTL and
//!   textures, MatrixMarket), the error type [`IoError`] and [`write_atomically`];
//! - [`crate::load`]: files or arrays → a validated [`MeshSequence`](crate::flow::MeshSequence)
//!   ([`load_sequence`], [`LoadOptions`], [`LoadWarning`], …);
//! - [`crate::run`]: one command's output directory ([`write_flow_outputs`], [`StagedDir`],
//!   [`RunManifest`], …).
//!
//! New code should name those modules; everything here is a re-export of them.

pub use crate::format::gltf as gltf_read;
pub use crate::format::gltf as gltf_write;
pub use crate::format::*;
pub use crate::load::*;
pub use crate::mesh::SumOverReaders;
pub use crate::run::*;
