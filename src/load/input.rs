//! Where a sequence comes from: what a path given on the command line names.
//!
//! | path | sequence |
//! |---|---|
//! | directory with `positions.npy` | NPY arrays: `positions.npy` (K, V, 3), `faces.npy` (F, 3), `intensity.npy` (K, V) |
//! | directory of `.obj`, `.ply`, `.gltf` or `.glb` files | one frame per file, natural order (`frame_2` before `frame_10`) |
//! | glob such as `run/frame_*.ply` | the matching files, natural order |
//! | one `.gltf` or `.glb` file | an animation of its mesh (morph targets, skin, node transforms), one frame per keyframe |

use crate::format::{directory_files, glob_files, natural_order};
use crate::format::{IoError, FACES, POSITIONS, TIMES};
use std::path::{Path, PathBuf};

/// What errors name when the input came as arrays (the Python package, library callers).
pub(super) const ARRAYS: &str = "arrays";

/// The format of per-frame mesh files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameFormat {
    Obj,
    Ply,
    Gltf,
}

impl FrameFormat {
    /// The format of a file, from its extension.
    pub fn of(path: &Path) -> Option<Self> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        match extension.as_str() {
            "obj" => Some(Self::Obj),
            "ply" => Some(Self::Ply),
            "gltf" | "glb" => Some(Self::Gltf),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Obj => "OBJ",
            Self::Ply => "PLY",
            Self::Gltf => "glTF",
        }
    }
}

/// Whether a file in an input directory is one a load may read: a mesh frame, an NPY array,
/// `times.txt`, or what a frame names beside it (a material library, a texture, a glTF
/// buffer). A later command that reads a run's input again must find each such file as the
/// run recorded it ([`crate::run::RunManifest::check_inputs`]); notes and other files beside
/// the frames are not read.
pub fn may_read(file: &Path) -> bool {
    let extension = file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let named = file.file_name().and_then(|n| n.to_str()) == Some(TIMES);
    let linked = ["npy", "mtl", "bin", "png", "jpg", "jpeg"];
    named
        || FrameFormat::of(file).is_some()
        || extension.is_some_and(|e| linked.contains(&e.as_str()))
}

/// A sequence's files, as found from the path the user gave.
#[derive(Clone, Debug, PartialEq)]
pub enum SequenceSource {
    /// One mesh file per frame, in frame order.
    Frames {
        format: FrameFormat,
        files: Vec<PathBuf>,
    },
    /// One glTF/GLB file holding an animation of its mesh (morph targets, skin or node
    /// transforms).
    GltfAnimation(PathBuf),
    /// A directory with `positions.npy`, `faces.npy` and optionally `intensity.npy`.
    Npy(PathBuf),
    /// Arrays in memory ([`super::sequence_from_arrays`]): no files.
    Arrays,
}

/// Why `files` hold no frames, with what to do where they are compressed mesh files.
fn no_frames_message(files: &[PathBuf]) -> String {
    const COMPRESSED: [&str; 4] = ["gz", "bz2", "xz", "zst"];
    let compressed = files.iter().filter(|f| {
        let extension = f.extension().map(|e| e.to_string_lossy().to_lowercase());
        let inner = f.file_stem().map(Path::new).and_then(FrameFormat::of);
        extension.is_some_and(|e| COMPRESSED.contains(&e.as_str())) && inner.is_some()
    });
    match compressed.clone().next() {
        Some(first) => format!(
            "{} compressed mesh frames ({}, …): meshflow reads them uncompressed; decompress them first (e.g. gunzip -k)",
            compressed.count(),
            first.file_name().unwrap_or_default().to_string_lossy()
        ),
        None => "no mesh frames here (.obj, .ply, .gltf, .glb files, or positions.npy + faces.npy)".into(),
    }
}

impl SequenceSource {
    /// Finds the sequence that `path` names (see the module table).
    pub fn detect(path: &Path) -> Result<Self, IoError> {
        let text = path.to_string_lossy();
        if text.contains(['*', '?', '[']) && !path.exists() {
            return Self::frames(path, glob_files(&text, path)?);
        }
        let metadata = std::fs::metadata(path).map_err(|e| IoError::file(path, e))?;
        if metadata.is_dir() {
            if path.join(POSITIONS).exists() {
                return Ok(Self::Npy(path.to_path_buf()));
            }
            return Self::frames(path, directory_files(path)?);
        }
        match FrameFormat::of(path) {
            Some(FrameFormat::Gltf) => Ok(Self::GltfAnimation(path.to_path_buf())),
            Some(_) => Err(IoError::format(
                path,
                "one mesh file is one frame; give the directory of frames or a glob such as 'dir/frame_*.obj'",
            )),
            None => Err(IoError::format(path, "not a mesh sequence: expected a directory, a glob, or a .gltf/.glb animation")),
        }
    }

    /// The files of all frames (the one file of an animation, the arrays of an NPY sequence).
    pub fn files(&self) -> Vec<PathBuf> {
        match self {
            Self::Frames { files, .. } => files.clone(),
            Self::GltfAnimation(file) => vec![file.clone()],
            Self::Npy(dir) => vec![dir.join(POSITIONS), dir.join(FACES)],
            Self::Arrays => Vec::new(),
        }
    }

    /// Where a `times.txt` for this sequence would be: beside its files (`None` for arrays).
    pub fn times_file(&self) -> Option<PathBuf> {
        let directory = match self {
            Self::Npy(dir) => dir.as_path(),
            Self::Frames { files, .. } => files[0].parent().unwrap_or(Path::new(".")),
            Self::GltfAnimation(file) => file.parent().unwrap_or(Path::new(".")),
            Self::Arrays => return None,
        };
        Some(directory.join(TIMES))
    }

    /// A short description, e.g. "6 OBJ frames".
    pub fn describe(&self) -> String {
        match self {
            Self::Frames { format, files } => format!("{} {} frames", files.len(), format.name()),
            Self::GltfAnimation(_) => "glTF animation".into(),
            Self::Npy(_) => "NPY arrays".into(),
            Self::Arrays => "arrays in memory".into(),
        }
    }

    /// Mesh files of one format, sorted naturally.
    fn frames(path: &Path, mut files: Vec<PathBuf>) -> Result<Self, IoError> {
        let formats: Vec<FrameFormat> = files.iter().filter_map(|f| FrameFormat::of(f)).collect();
        let Some(&format) = formats.first() else {
            return Err(IoError::format(path, no_frames_message(&files)));
        };
        if let Some(other) = formats.iter().find(|&&f| f != format) {
            return Err(IoError::format(
                path,
                format!(
                    "mixes {} and {} files; keep one format per sequence",
                    format.name(),
                    other.name()
                ),
            ));
        }
        files.retain(|f| FrameFormat::of(f).is_some());
        files.sort_by(|a, b| natural_order(&a.to_string_lossy(), &b.to_string_lossy()));
        Ok(Self::Frames { format, files })
    }
}
