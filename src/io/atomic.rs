//! Write-then-rename output: single files and whole output directories.

use super::IoError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes `path` through `write`, atomically: a temporary file in the same directory is filled,
/// flushed and synced, then renamed onto `path`. On any error the temporary file is removed and
/// `path` is left as it was.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), IoError> {
    let name = path
        .file_name()
        .ok_or_else(|| IoError::format(path, "not a file path"))?;
    let temporary = path.with_file_name(format!(
        ".{}.{}.partial",
        name.to_string_lossy(),
        std::process::id()
    ));
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

/// An output directory that appears complete or not at all.
///
/// Files are written into a hidden staging directory next to the target
/// (`.NAME.partial-PID`); [`StagedDir::commit`] renames it onto the target, or, when the target
/// already exists, moves the files in one by one (each rename replaces an old file atomically).
/// Dropped uncommitted, the staging directory is removed. Creating it first also checks, before
/// any long computation, that the output location is writable.
#[derive(Debug)]
pub struct StagedDir {
    target: PathBuf,
    staging: PathBuf,
    committed: bool,
}

impl StagedDir {
    /// Creates the staging directory for `target` (and `target`'s parent directories).
    pub fn new(target: &Path) -> Result<Self, IoError> {
        if target.is_file() {
            return Err(IoError::format(target, "is a file, not a directory"));
        }
        let name = target
            .file_name()
            .ok_or_else(|| IoError::format(target, "not a directory name"))?;
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        std::fs::create_dir_all(parent).map_err(|e| IoError::file(target, e))?;
        let staging = parent.join(format!(
            ".{}.partial-{}",
            name.to_string_lossy(),
            std::process::id()
        ));
        std::fs::create_dir_all(&staging).map_err(|e| IoError::file(target, e))?;
        Ok(Self {
            target: target.to_path_buf(),
            staging,
            committed: false,
        })
    }

    /// Where to write the files now.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Where the files will be.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// `error` with a staged file's path replaced by its final path, for messages.
    pub fn in_target(&self, mut error: IoError) -> IoError {
        let path = error.path_mut();
        if let Ok(relative) = path.strip_prefix(&self.staging) {
            *path = self.target.join(relative);
        }
        error
    }

    /// Moves the staged files to the target directory.
    pub fn commit(mut self) -> Result<(), IoError> {
        let fail = |e| IoError::file(&self.target, e);
        if !self.target.exists() {
            std::fs::rename(&self.staging, &self.target).map_err(fail)?;
        } else {
            for entry in std::fs::read_dir(&self.staging).map_err(fail)? {
                let file = entry.map_err(fail)?.path();
                let name = file.file_name().expect("directory entries have names");
                std::fs::rename(&file, self.target.join(name)).map_err(fail)?;
            }
            std::fs::remove_dir(&self.staging).map_err(fail)?;
        }
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}
