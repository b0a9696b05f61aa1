//! Reading a named file safely, and writing one atomically.

use super::IoError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The whole of a regular file, after checking its size against the memory limit
/// ([`crate::limits`]): a device such as `/dev/zero` or a FIFO would never end.
pub fn read_file(path: &Path) -> Result<Vec<u8>, IoError> {
    read_file_at_most(path, u64::MAX, "the file")
}

/// [`read_file`] for a file of a kind that is never large (a run manifest, a JSON document of
/// metadata): refused, naming it as `what`, when it is over `most` bytes, before anything is
/// read.
pub fn read_file_at_most(path: &Path, most: u64, what: &str) -> Result<Vec<u8>, IoError> {
    use std::io::Read;
    let (file, length) = open_regular(path)?;
    if length > most {
        let why = format!(
            "{} for {what}, which is at most {}: not meshflow's",
            crate::limits::format_size(length),
            crate::limits::format_size(most)
        );
        return Err(IoError::format(path, why));
    }
    crate::limits::check_declared(what, length).map_err(|e| IoError::too_large(path, e))?;
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
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    // Non-blocking: a FIFO put in the file's place since the check above opens at once
    // (and is refused below) instead of waiting for a writer. Reads of a regular file ignore it.
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
    let file = options.open(path).map_err(|e| IoError::file(path, e))?;
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
    write_all_atomically(vec![(path, Box::new(write))])
}

/// What fills one file of [`write_all_atomically`].
pub type FileContents<'a> = Box<dyn FnOnce(&mut BufWriter<File>) -> std::io::Result<()> + 'a>;

/// Writes files that belong together (an image and its mask) as [`write_atomically`] writes
/// one, renaming none before every one is filled and synced and no directory stands at any
/// path: an error while filling any leaves all of them as they were. Only the renames
/// themselves, back to back, stand between them.
pub fn write_all_atomically(files: Vec<(&Path, FileContents<'_>)>) -> Result<(), IoError> {
    let mut filled: Vec<(PathBuf, &Path)> = Vec::with_capacity(files.len());
    let remove_all = |filled: &[(PathBuf, &Path)]| {
        filled.iter().for_each(|(temporary, _)| {
            let _ = std::fs::remove_file(temporary);
        })
    };
    for (path, write) in files {
        let temporary = temporary_beside(path).inspect_err(|_| remove_all(&filled))?;
        let result = File::create(&temporary).and_then(|file| {
            let mut writer = BufWriter::new(file);
            write(&mut writer)?;
            writer.flush()?;
            writer.get_ref().sync_all()
        });
        filled.push((temporary, path));
        if let Err(source) = result {
            remove_all(&filled);
            return Err(IoError::file(path, source));
        }
    }
    // A rename fails where a directory stands at the path: found before any is renamed.
    if let Some((_, path)) = filled.iter().find(|(_, path)| path.is_dir()) {
        remove_all(&filled);
        let source = std::io::Error::new(std::io::ErrorKind::IsADirectory, "Is a directory");
        return Err(IoError::file(path, source));
    }
    for (at, (temporary, path)) in filled.iter().enumerate() {
        if let Err(source) = std::fs::rename(temporary, path) {
            remove_all(&filled[at..]);
            return Err(IoError::file(path, source));
        }
    }
    Ok(())
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
