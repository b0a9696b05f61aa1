//! `meshflow._meshflow`: the Rust half of the Python package (the NumPy-facing wrappers,
//! docstrings and argument checks are in `meshflow/__init__.py`).
//!
//! Every function takes arrays the Python half has already given their dtype (float64
//! positions and grey values, int64 faces, float32 volumes) and checked for shape; it copies
//! them into the library's types with the GIL held, then releases the GIL (`Python::detach`)
//! for everything long. Library errors become Python exceptions carrying the library's
//! one-line message (`to_py_err`); nothing here panics on user input.
//!
//! A running solve reacquires the GIL once per event (iteration, warp, factorization) to call
//! the `progress` callback and to check for Ctrl-C (`PyErr_CheckSignals`); either raising stops
//! the solve within one iteration, and the exception is re-raised (`flow::PythonObserver`).
//!
//! Modules by concern: `convert` (arrays in and out, keyword words), `load` (files and arrays
//! in, one mesh's operators), `flow` (`compute_flow` and the `Flow` class), `tracks`
//! (`track`, `match_tracks`), `microscopy` (`fit_surface`, `sample_volume`) and `keywords`
//! (the library's messages in Python words); this file holds the errors, the limits and the
//! module's table of functions.

mod convert;
mod flow;
mod keywords;
mod load;
mod microscopy;
mod run;
mod tracks;

use crate::flow::Flow;
use meshflow::format::IoError;
use meshflow::Error;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError, PyValueError};
use pyo3::prelude::*;

/// The exception for a library error: `FileNotFoundError`, `PermissionError` or `OSError`
/// when the operating system refused a file, `ValueError` for everything else (bad data,
/// broken files, bad parameters). The message is the library's one line.
pub(crate) fn to_py_err(error: Error) -> PyErr {
    let message = keywords::in_python_words(&error.to_string());
    match os_error(&error).map(std::io::Error::kind) {
        Some(std::io::ErrorKind::NotFound) => PyFileNotFoundError::new_err(message),
        Some(std::io::ErrorKind::PermissionDenied) => PyPermissionError::new_err(message),
        Some(_) => PyOSError::new_err(message),
        None => PyValueError::new_err(message),
    }
}

/// The operating-system error at the root of `error`, if that is what it is.
fn os_error(error: &Error) -> Option<&std::io::Error> {
    fn in_io(error: &IoError) -> Option<&std::io::Error> {
        match error {
            IoError::File { source, .. } => Some(source),
            IoError::Referenced { source, .. } => in_io(source),
            _ => None,
        }
    }
    match error {
        Error::Io(io) => in_io(io),
        Error::InFile { source, .. } => os_error(source),
        _ => None,
    }
}

/// A `ValueError` with `message`.
pub(crate) fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// The process's memory limit and linked-file policy (`--memory-limit`,
/// `--allow-external-files`): sets those given (`"default"`: the machine's physical memory),
/// returns both as they are then.
#[pyfunction]
#[pyo3(signature = (memory_limit=None, allow_external_files=None))]
fn limits(memory_limit: Option<&str>, allow_external_files: Option<bool>) -> PyResult<(u64, bool)> {
    use meshflow::limits::{self, LinkedFiles};
    match memory_limit {
        Some("default") => limits::set_memory_limit(0),
        Some(size) => limits::set_memory_limit(
            limits::parse_size(size)
                .map_err(|e| PyValueError::new_err(format!("memory_limit: {e}")))?,
        ),
        None => {}
    }
    if let Some(allow) = allow_external_files {
        limits::set_linked_files(match allow {
            true => LinkedFiles::Anywhere,
            false => LinkedFiles::Contained,
        });
    }
    Ok((
        limits::memory_limit(),
        limits::linked_files() == LinkedFiles::Anywhere,
    ))
}

/// The library's message `message` in the Python package's words (for tests).
#[pyfunction]
fn python_words(message: &str) -> String {
    keywords::in_python_words(message)
}

#[pymodule]
fn _meshflow(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Flow>()?;
    m.add_function(wrap_pyfunction!(flow::compute_flow, m)?)?;
    m.add_function(wrap_pyfunction!(load::operators, m)?)?;
    m.add_function(wrap_pyfunction!(load::load_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(load::load_mesh_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(python_words, m)?)?;
    m.add_function(wrap_pyfunction!(limits, m)?)?;
    m.add_function(wrap_pyfunction!(tracks::track, m)?)?;
    m.add_function(wrap_pyfunction!(tracks::match_tracks, m)?)?;
    m.add_function(wrap_pyfunction!(microscopy::fit_surface, m)?)?;
    m.add_function(wrap_pyfunction!(microscopy::find_surface, m)?)?;
    m.add_function(wrap_pyfunction!(microscopy::sample_volume, m)?)?;
    m.add_function(wrap_pyfunction!(microscopy::sample_volume_file, m)?)?;
    m.add_function(wrap_pyfunction!(microscopy::read_volumes, m)?)?;
    m.add_function(wrap_pyfunction!(microscopy::closed_surface_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(run::read_run, m)?)?;
    m.add_function(wrap_pyfunction!(run::write_sequence, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
