//! Outputs never overwrite inputs.
//!
//! Every command checks its output path against the files and directories it reads before it
//! reads anything ([`refuse_output_over_inputs`]): the output may not be one of its inputs
//! (also through a link or a hard link), may not be a directory that holds an input, and may
//! not lie inside an input directory. Paths are compared after links are resolved; an output
//! that does not exist yet is resolved through its nearest existing ancestor, and a glob input
//! (`'frames/*.obj'`) counts as the directory it lists.

use crate::format::IoError;
use std::path::{Component, Path, PathBuf};

/// What a command writes at its output path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// One file (`match --out TRACKS.npy`, `sample --out FILE.npy`).
    File,
    /// A directory of files (`solve --out DIR`).
    Directory,
}

/// Refuses `out` (a `kind` output) when it is one of `inputs`, holds one, or lies inside an
/// input directory (a glob's directory). Inputs that do not exist are skipped: their reader
/// reports them.
pub fn refuse_output_over_inputs(
    out: &Path,
    kind: OutputKind,
    inputs: &[&Path],
) -> Result<(), IoError> {
    let resolved_out = resolve(out);
    for &input in inputs {
        let location = glob_location(input);
        let Ok(resolved_input) = location.canonicalize() else {
            continue;
        };
        let refuse = |what: String| IoError::OverInput {
            path: out.to_path_buf(),
            message: match kind {
                OutputKind::File => format!("{what}; choose another output file"),
                OutputKind::Directory => format!(
                    "{what}: the outputs would mix with the input's files; choose another output \
                     directory"
                ),
            },
        };
        if resolved_out == resolved_input || same_file(out, &location) {
            return Err(refuse(format!("is the input {}", input.display())));
        }
        if resolved_input.starts_with(&resolved_out) && kind == OutputKind::Directory {
            return Err(refuse(format!("holds the input {}", input.display())));
        }
        if location.is_dir() && resolved_out.starts_with(&resolved_input) {
            return Err(refuse(format!(
                "lies inside the input directory {}",
                input.display()
            )));
        }
    }
    Ok(())
}

/// `input`, or for a glob that names no file the directory its pattern lists.
fn glob_location(input: &Path) -> PathBuf {
    if input.exists() {
        return input.to_path_buf();
    }
    let location: PathBuf = (input.components())
        .take_while(|c| !c.as_os_str().to_string_lossy().contains(['*', '?', '[']))
        .collect();
    match location.as_os_str().is_empty() {
        true => PathBuf::from("."),
        false => location,
    }
}

/// `path` with links resolved, also where its last components do not exist yet (resolved
/// through the nearest existing ancestor, the rest normalized lexically).
pub(super) fn resolve(path: &Path) -> PathBuf {
    let absolute = match path.is_absolute() {
        true => path.to_path_buf(),
        false => std::env::current_dir()
            .map(|cwd| cwd.join(path))
            .unwrap_or_else(|_| path.to_path_buf()),
    };
    let mut existing = absolute.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(resolved) = existing.canonicalize() {
            let mut result = resolved;
            for component in rest.iter().rev() {
                match component {
                    Component::ParentDir => {
                        result.pop();
                    }
                    Component::CurDir => {}
                    other => result.push(other.as_os_str()),
                }
            }
            return result;
        }
        match (existing.parent(), existing.components().next_back()) {
            (Some(parent), Some(last)) => {
                rest.push(last);
                existing = parent;
            }
            _ => return absolute,
        }
    }
}

/// Whether two existing paths are the same file (a hard link or a link to it).
#[cfg(unix)]
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_: &Path, _: &Path) -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_over_inputs_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let input_dir = dir.path().join("seq");
        std::fs::create_dir(&input_dir).unwrap();
        let file = input_dir.join("positions.npy");
        std::fs::write(&file, b"x").unwrap();
        let volume = dir.path().join("volume.npy");
        std::fs::write(&volume, b"v").unwrap();
        let inputs = [input_dir.as_path(), volume.as_path()];
        let refused = |out: &Path, kind| refuse_output_over_inputs(out, kind, &inputs).is_err();
        assert!(refused(&volume, OutputKind::File));
        assert!(refused(&file, OutputKind::File));
        assert!(refused(&input_dir.join("new/out"), OutputKind::Directory));
        assert!(refused(dir.path(), OutputKind::Directory));
        assert!(refused(
            &input_dir.join("x/../../volume.npy"),
            OutputKind::File
        ));
        assert!(!refused(&dir.path().join("out"), OutputKind::Directory));
        // A glob counts as the directory it lists: a new file there would match it next time.
        let glob = input_dir.join("*.npy");
        let by_glob = |out: &Path| refuse_output_over_inputs(out, OutputKind::File, &[&glob]);
        assert!(by_glob(&input_dir.join("tracks.npy")).is_err());
        assert!(by_glob(&dir.path().join("tracks.npy")).is_ok());
        assert!(!refused(&dir.path().join("tracks.npy"), OutputKind::File));
        #[cfg(unix)]
        {
            let hard = dir.path().join("hard.npy");
            std::fs::hard_link(&volume, &hard).unwrap();
            assert!(refused(&hard, OutputKind::File));
            let soft = dir.path().join("soft");
            std::os::unix::fs::symlink(&input_dir, &soft).unwrap();
            assert!(refused(&soft.join("out"), OutputKind::Directory));
        }
        let message = refuse_output_over_inputs(&volume, OutputKind::File, &inputs)
            .unwrap_err()
            .to_string();
        assert!(message.contains("is the input"), "{message}");
    }
}
