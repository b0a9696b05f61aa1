//! File formats, the lowest layer of meshflow's I/O: bytes in and out of files, below the
//! loading of sequences and the writing of a run's outputs ([`crate::load`], [`crate::run`]).
//!
//! It holds what every format shares: the error type ([`IoError`], naming the file and the line
//! or element at fault), reading a named file only if it is a regular file within the memory
//! limit ([`read_file`], [`open_regular`]), which files make the frames ([`frame_files`], in
//! [`natural_order`]), and writing one atomically ([`write_atomically`]: a
//! temporary file beside the target, renamed onto it); the rule for files named inside other
//! files ([`resolve_linked`]); and the codecs: NPY arrays (`npy`), OBJ geometry (`obj`), MTL
//! materials and their textures (`mtl`, `texture`), PLY ([`ply`]), VTK XML ([`vtk`]) and
//! MatrixMarket matrices (`mtx`), glTF 2.0 ([`gltf`]: static and animated meshes in, an
//! animated `.glb` out). Every mesh reader yields the same raw frame ([`FrameMesh`], with the
//! file's grey values or colours as [`VertexValues`]) or, from a single animated file, a
//! [`RawSequence`]; welding, orientation and validation come later, in the loader.
//!
//! Readers of self-contained files also take a stream (`impl Read`: standard input, an archive
//! member, bytes in memory) beside a path, as tobj's `load_obj_buf` does: [`read_obj_from`],
//! [`ply::read_ply_from`], [`vtk::read_vtu_from`], [`read_npy_from`],
//! [`read_matrix_market_from`]. A stream declares no size, so [`read_stream`] stops at the
//! memory limit. glTF, MTL and PVD read from paths only: they name other files relative to
//! their own location.

mod error;
mod file;
mod frame_mesh;
mod frames;
pub mod gltf;
mod linked;
mod mtl;
mod mtx;
mod npy;
mod npy_sequence;
mod number;
mod obj;
pub mod ply;
mod texture;
pub mod vtk;

pub use error::{quoted, IoError};
pub(crate) use file::temporary_beside;
pub use file::{
    open_regular, read_file, read_file_at_most, read_stream, write_all_atomically,
    write_atomically, FileContents,
};
pub use frame_mesh::{grey_value, grey_values, FrameMesh, RawSequence, VertexValues};
pub(crate) use frames::{directory_files, glob_files};
pub use frames::{frame_files, natural_order};
pub use linked::resolve_linked;
pub use mtl::{texture_colors, TextureCache};
pub use mtx::{read_matrix_market, read_matrix_market_from, write_matrix_market};
pub use npy::{
    npy_contents, read_npy, read_npy_f32, read_npy_f32_rows, read_npy_float, read_npy_float_rows,
    read_npy_from, read_npy_image, read_npy_image_rows, read_npy_indices, write_npy,
    write_npy_vectors, KeepRows, NpyArray, NpyRows,
};
pub use npy_sequence::{
    no_data_file, read_intensity_array, read_npy_sequence, write_image_and_no_data,
    write_intensity_array, write_no_data, write_npy_sequence, FACES, INTENSITY, NO_DATA, POSITIONS,
    TIMES,
};
pub(crate) use npy_sequence::{read_intensity_rows, VertexCount, IMAGE};
pub use number::format_number;
pub use obj::{read_obj, read_obj_from, write_obj, ObjMesh};
pub use texture::Texture;
