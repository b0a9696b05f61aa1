//! Files named inside other files: glTF `buffers[].uri` and `images[].uri`, OBJ `mtllib`, MTL
//! `map_Kd`.
//!
//! Such a name is the file author's, not the user's, so it is resolved under a policy
//! ([`crate::limits::LinkedFiles`]): relative to the naming file's directory, it must stay in
//! that directory or below it after `..` and links are followed, and it must be a regular
//! file. An absolute path, a `..` that climbs out, a link that leads out, a device
//! (`/dev/zero`), a FIFO or a directory is refused in one line naming the file, the field and
//! the name. [`LinkedFiles::Anywhere`](crate::limits::LinkedFiles::Anywhere) follows
//! absolute paths and `..` for trusted data; non-regular files stay refused.

use super::IoError;
use crate::limits::{linked_files, LinkedFiles};
use std::path::{Component, Path, PathBuf};

/// The path of the file that `naming` names as `written` in `field` ("buffer 0 uri",
/// "mtllib"), checked against the linked-file policy. `name` is the path `written` stands for
/// (a glTF URI percent-decoded; an OBJ name as written); errors quote `written`.
pub fn resolve_linked(
    naming: &Path,
    field: &str,
    written: &str,
    name: &str,
) -> Result<PathBuf, IoError> {
    let refuse = |why: &str| IoError::format(naming, format!("{field} {written:?}: {why}"));
    let trusted = linked_files() == LinkedFiles::Anywhere;
    let hint = "(--allow-external-files reads linked files outside the file's directory)";
    let relative = Path::new(name);
    if name.is_empty() || name.contains('\0') {
        return Err(refuse("not a file name"));
    }
    if (relative.has_root() || relative.is_absolute()) && !trusted {
        return Err(refuse(&format!(
            "an absolute path; a linked file must lie beside the file {hint}"
        )));
    }
    let directory = naming.parent().unwrap_or(Path::new(""));
    let directory = match directory.as_os_str().is_empty() {
        true => Path::new("."),
        false => directory,
    };
    if !trusted && climbs_out(relative) {
        return Err(refuse(&format!(
            "leads out of the file's directory with '..' {hint}"
        )));
    }
    let joined = directory.join(relative);
    let metadata = std::fs::metadata(&joined)
        .map_err(|e| refuse(&format!("cannot read {}: {e}", joined.display())))?;
    if !metadata.is_file() {
        return Err(refuse(&format!(
            "{} is not a regular file",
            joined.display()
        )));
    }
    if !trusted {
        let inside = joined
            .canonicalize()
            .and_then(|target| Ok((target, directory.canonicalize()?)))
            .map(|(target, base)| target.starts_with(base))
            .unwrap_or(false);
        if !inside {
            return Err(refuse(&format!(
                "a link that leads out of the file's directory {hint}"
            )));
        }
    }
    Ok(joined)
}

/// Whether `relative`'s `..` components climb above its start at any point.
fn climbs_out(relative: &Path) -> bool {
    let mut depth = 0i64;
    for component in relative.components() {
        match component {
            Component::ParentDir => depth -= 1,
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::RootDir | Component::Prefix(_) => return true,
        }
        if depth < 0 {
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parent_components_climb_out_only_above_the_start() {
        assert!(climbs_out(Path::new("../x.bin")));
        assert!(climbs_out(Path::new("a/../../x.bin")));
        assert!(!climbs_out(Path::new("a/../x.bin")));
        assert!(!climbs_out(Path::new("./textures/x.png")));
    }

    #[test]
    fn linked_files_outside_the_directory_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let inner = dir.path().join("model");
        std::fs::create_dir(&inner).unwrap();
        std::fs::write(dir.path().join("secret.txt"), "secret").unwrap();
        std::fs::write(inner.join("data.bin"), [0u8; 8]).unwrap();
        let naming = inner.join("model.gltf");
        assert_eq!(
            resolve_linked(&naming, "buffer 0 uri", "data.bin", "data.bin").unwrap(),
            inner.join("data.bin")
        );
        for name in [
            "../secret.txt",
            "/etc/passwd",
            "/dev/zero",
            "sub/../../secret.txt",
        ] {
            let error = resolve_linked(&naming, "buffer 0 uri", name, name).unwrap_err();
            let text = error.to_string();
            assert!(
                text.contains("model.gltf") && text.contains("buffer 0 uri") && text.contains(name),
                "{text}"
            );
        }
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(dir.path().join("secret.txt"), inner.join("link.bin"))
                .unwrap();
            let text = resolve_linked(&naming, "buffer 0 uri", "link.bin", "link.bin")
                .unwrap_err()
                .to_string();
            assert!(text.contains("link that leads out"), "{text}");
        }
        let text = resolve_linked(&naming, "buffer 0 uri", ".", ".")
            .unwrap_err()
            .to_string();
        assert!(text.contains("not a regular file"), "{text}");
    }
}
