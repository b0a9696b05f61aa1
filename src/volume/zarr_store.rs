//! The one door through which an OME-Zarr image's files are read: a filesystem store of our
//! own, given to `zarrs` for the metadata it parses and used directly for the chunks.
//!
//! Why not `zarrs`' own `FilesystemStore`: it maps a key to `ROOT/KEY` and opens whatever is
//! there, following links. A store is a directory of many files, each a possible trap: a chunk
//! linked to a file elsewhere is decoded as image data, an array directory linked to another
//! store reads that image, `.zarray` linked to `/etc/passwd` is opened, a chunk that is a FIFO
//! blocks the read forever, and a 50 GB sparse chunk is read whole. Here every key goes through
//! the rules that files named inside other files obey ([`crate::format::resolve_linked`],
//! [`crate::limits::LinkedFiles`]):
//!
//! - a key is plain components below the store's root (no `..`, `.`, empty parts, backslashes);
//! - after links are followed it must still lie below the root (`--allow-external-files`
//!   lifts that for trusted data);
//! - it must be a regular file: FIFOs, devices and directories are refused before they are
//!   opened, and the open is non-blocking in case one appears in between
//!   ([`crate::format::open_regular`]);
//! - its size is checked against a bound before anything is read ([`ContainedStore::most`]:
//!   a metadata document's, or a chunk's largest encoded size), and against the memory limit.
//!
//! A missing key is `None` (a chunk never written, read as the fill value); anything else that
//! is wrong is an error naming the file.

use crate::format::{open_regular, IoError};
use crate::limits::{linked_files, LinkedFiles};
use std::io::Read;
use std::path::{Path, PathBuf};
use zarrs::storage::byte_range::ByteRangeIterator;
use zarrs::storage::{
    Bytes, MaybeBytes, MaybeBytesIterator, ReadableStorageTraits, StorageError, StoreKey,
};

/// The most bytes a metadata document (`zarr.json`, `.zarray`, `.zattrs`, `.zgroup`) may have.
pub(super) const METADATA_MOST_BYTES: u64 = 16 << 20;

/// A read-only filesystem store whose keys are files below one root (module docs).
#[derive(Clone, Debug)]
pub(super) struct ContainedStore {
    /// The store's directory as the user named it, for messages.
    named: PathBuf,
    /// The same with links resolved: where every key must stay.
    root: PathBuf,
    /// The most bytes one value may have.
    most: u64,
}

impl ContainedStore {
    /// The store at `directory`, whose values may have at most `most` bytes.
    pub fn new(directory: &Path, most: u64) -> Result<Self, IoError> {
        let root = directory
            .canonicalize()
            .map_err(|e| IoError::file(directory, e))?;
        Ok(Self {
            named: directory.to_path_buf(),
            root,
            most,
        })
    }

    /// The same store with another bound on a value's size.
    pub fn with_most(&self, most: u64) -> Self {
        Self {
            most,
            ..self.clone()
        }
    }

    /// The file of `key` as the user's path names it, for messages.
    pub fn file_of(&self, key: &str) -> PathBuf {
        self.named.join(key)
    }

    /// The whole value of `key`; `None` where nothing is stored under it.
    pub fn read(&self, key: &str) -> Result<Option<Vec<u8>>, IoError> {
        let Some(path) = self.locate(key)? else {
            return Ok(None);
        };
        let shown = self.file_of(key);
        let (file, length) = open_regular(&path).map_err(|e| relabel(e, &shown))?;
        if length > self.most {
            let why = format!(
                "{} stored, over the {} it can hold (a corrupt or hostile store)",
                crate::limits::format_size(length),
                crate::limits::format_size(self.most)
            );
            return Err(IoError::format(shown, why));
        }
        crate::limits::check_declared("the file", length)
            .map_err(|e| IoError::too_large(&shown, e))?;
        let mut bytes = Vec::with_capacity(length as usize);
        (file.take(length).read_to_end(&mut bytes)).map_err(|e| IoError::file(&shown, e))?;
        Ok(Some(bytes))
    }

    /// Where `key` is on disk, checked (module docs); `None` where nothing is there.
    fn locate(&self, key: &str) -> Result<Option<PathBuf>, IoError> {
        let shown = self.file_of(key);
        let refuse = |why: &str| IoError::format(&shown, why.to_string());
        let plain = |part: &str| !matches!(part, "" | "." | "..") && !part.contains(['\\', '\0']);
        if !key.split('/').all(plain) {
            return Err(refuse(
                "not a key of the store (empty parts, '.', '..' or '\\')",
            ));
        }
        let path = self.root.join(key);
        match std::fs::symlink_metadata(&path) {
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(IoError::file(&shown, e)),
        }
        if linked_files() == LinkedFiles::Contained {
            let resolved = path.canonicalize().map_err(|e| IoError::file(&shown, e))?;
            if !resolved.starts_with(&self.root) {
                return Err(refuse(
                    "a link that leads out of the store (--allow-external-files follows it)",
                ));
            }
            return Ok(Some(resolved));
        }
        Ok(Some(path))
    }

    /// [`Self::read`] as `zarrs` asks for it.
    fn value(&self, key: &StoreKey) -> Result<MaybeBytes, StorageError> {
        match self.read(key.as_str()) {
            Ok(value) => Ok(value.map(Bytes::from)),
            Err(e) => Err(StorageError::Other(e.to_string())),
        }
    }
}

/// `error` about `path` instead of the resolved file it names.
fn relabel(mut error: IoError, path: &Path) -> IoError {
    *error.path_mut() = path.to_path_buf();
    error
}

impl ReadableStorageTraits for ContainedStore {
    fn get_partial_many<'a>(
        &'a self,
        key: &StoreKey,
        byte_ranges: ByteRangeIterator<'a>,
    ) -> Result<MaybeBytesIterator<'a>, StorageError> {
        let Some(value) = self.value(key)? else {
            return Ok(None);
        };
        let length = value.len() as u64;
        let parts = byte_ranges.map(move |range| {
            let (start, end) = (range.start(length), range.end(length));
            match start <= end && end <= length {
                true => Ok(value.slice(start as usize..end as usize)),
                false => Err(StorageError::Other(format!(
                    "bytes {start}..{end} of a value of {length} bytes"
                ))),
            }
        });
        Ok(Some(Box::new(parts)))
    }

    fn size_key(&self, key: &StoreKey) -> Result<Option<u64>, StorageError> {
        let located = self.locate(key.as_str());
        let path = located.map_err(|e| StorageError::Other(e.to_string()))?;
        Ok(path
            .and_then(|p| std::fs::metadata(p).ok())
            .map(|m| m.len()))
    }

    fn supports_get_partial(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_stay_inside_the_store() {
        let dir = tempfile::tempdir().unwrap();
        let store_dir = dir.path().join("image.zarr");
        std::fs::create_dir_all(store_dir.join("0")).unwrap();
        std::fs::write(store_dir.join("0/chunk"), [1u8, 2, 3]).unwrap();
        std::fs::write(dir.path().join("secret"), b"secret").unwrap();
        let store = ContainedStore::new(&store_dir, 1 << 20).unwrap();
        assert_eq!(store.read("0/chunk").unwrap(), Some(vec![1, 2, 3]));
        assert_eq!(store.read("0/missing").unwrap(), None);
        for key in [
            "../secret",
            "0/../../secret",
            "/etc/passwd",
            "0//chunk",
            "./0/chunk",
        ] {
            let error = store.read(key).unwrap_err().to_string();
            assert!(error.contains("not a key"), "{key}: {error}");
        }
        let error = store.read("0").unwrap_err().to_string();
        assert!(error.contains("not a regular file"), "{error}");
        assert!(store
            .with_most(2)
            .read("0/chunk")
            .unwrap_err()
            .to_string()
            .contains("over the"));
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(dir.path().join("secret"), store_dir.join("0/out")).unwrap();
            let error = store.read("0/out").unwrap_err().to_string();
            assert!(error.contains("leads out of the store"), "{error}");
            std::os::unix::fs::symlink(store_dir.join("0/chunk"), store_dir.join("0/in")).unwrap();
            assert_eq!(store.read("0/in").unwrap(), Some(vec![1, 2, 3]));
            std::os::unix::fs::symlink("/dev/zero", store_dir.join("0/zero")).unwrap();
            assert!(store.read("0/zero").is_err());
        }
    }
}
