//! Reading a named file safely, and writing one atomically.

use super::IoError;
use std::fs::File;
use std::io::{BufWriter, Write};
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

/// All of a stream (standard input, an archive member, bytes in memory), refused once it
/// passes the memory limit ([`crate::limits`]): a stream declares no size to check first, so
/// at most the limit and one byte are read. `name` stands for the stream in errors.
pub fn read_stream(reader: impl std::io::Read, name: &Path) -> Result<Vec<u8>, IoError> {
    use std::io::Read;
    let limit = crate::limits::memory_limit();
    let mut bytes = Vec::new();
    (reader.take(limit.saturating_add(1)).read_to_end(&mut bytes))
        .map_err(|e| IoError::file(name, e))?;
    crate::limits::check_declared("the stream", bytes.len() as u64)
        .map_err(|e| IoError::too_large(name, e))?;
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

/// Writes `path` through `write`, atomically: a temporary file in the same directory is filled,
/// flushed and synced, then renamed onto `path`. On any error the temporary file is removed and
/// `path` is left as it was.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), IoError> {
    let temporary = temporary_beside(path)?;
    let result = File::create(&temporary).and_then(|file| {
        let mut writer = BufWriter::new(file);
        write(&mut writer)?;
        writer.flush()?;
        writer.get_ref().sync_all()?;
        drop(writer);
        std::fs::rename(&temporary, path)
    });
    result.map_err(|source| {
        let _ = std::fs::remove_file(&temporary);
        IoError::file(path, source)
    })
}

/// Where [`write_atomically`] fills `path` before renaming it: `.NAME.PID.partial` beside it.
pub(crate) fn temporary_beside(path: &Path) -> Result<PathBuf, IoError> {
    let name = path
        .file_name()
        .ok_or_else(|| IoError::format(path, "not a file path"))?;
    Ok(path.with_file_name(format!(
        ".{}.{}.partial",
        name.to_string_lossy(),
        std::process::id()
    )))
}
