//! File formats, the lowest layer of meshflow's I/O: bytes in and out of files, below the
//! loading of sequences and the writing of a run's outputs ([`crate::io`]).
//!
//! So far it holds what every format shares: the error type ([`IoError`], naming the file and
//! the line or element at fault), reading a named file only if it is a regular file within the
//! memory limit ([`read_file`], [`open_regular`]), and writing one atomically
//! ([`write_atomically`]: a temporary file beside the target, renamed onto it). The codecs
//! themselves (OBJ, PLY, NPY, glTF, VTK, …) still live in `io` and move here next (issue 39).

mod error;
mod file;

pub use error::IoError;
pub(crate) use file::temporary_beside;
pub use file::{open_regular, read_file, write_atomically};
