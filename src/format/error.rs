//! The error of every file reader and writer: which file, and what is wrong with it.

use std::path::PathBuf;

/// A file could not be read, parsed or written.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    #[error("{}: {source}", path.display())]
    File {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}, line {line}: {message}", path.display())]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{}: {message}", path.display())]
    Format { path: PathBuf, message: String },
    /// The faces of a file are not an oriented manifold; `message` tells it in the file's
    /// vertex numbers (`source` has the mesh's).
    #[error("{}: {message}", path.display())]
    Connectivity {
        path: PathBuf,
        message: String,
        #[source]
        source: crate::mesh::ConnectivityError,
    },
    /// A size `path` declares does not fit the memory limit ([`crate::limits`]).
    #[error("{}: {source}", path.display())]
    TooLarge {
        path: PathBuf,
        #[source]
        source: crate::limits::OverBudget,
    },
    /// An output would replace or lie among a command's inputs.
    #[error("{}: {message}", path.display())]
    OverInput { path: PathBuf, message: String },
    /// A file that `path` refers to (an OBJ's material library or texture) failed.
    #[error("{}: {context}: {source}", path.display())]
    Referenced {
        path: PathBuf,
        context: String,
        source: Box<IoError>,
    },
}

impl IoError {
    /// An operating-system error about `path`.
    pub fn file(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::File {
            path: path.into(),
            source,
        }
    }

    /// A declared size of `path` over the memory limit.
    pub fn too_large(path: impl Into<PathBuf>, source: crate::limits::OverBudget) -> Self {
        Self::TooLarge {
            path: path.into(),
            source,
        }
    }

    /// The file the error is about.
    pub fn path(&self) -> &std::path::Path {
        match self {
            Self::File { path, .. }
            | Self::Parse { path, .. }
            | Self::Format { path, .. }
            | Self::Connectivity { path, .. }
            | Self::TooLarge { path, .. }
            | Self::OverInput { path, .. }
            | Self::Referenced { path, .. } => path,
        }
    }

    pub(crate) fn path_mut(&mut self) -> &mut PathBuf {
        match self {
            Self::File { path, .. }
            | Self::Parse { path, .. }
            | Self::Format { path, .. }
            | Self::Connectivity { path, .. }
            | Self::TooLarge { path, .. }
            | Self::OverInput { path, .. }
            | Self::Referenced { path, .. } => path,
        }
    }

    /// An error at `line` of `path` (1-based), or about the whole file when `line` is 0.
    pub(crate) fn at_line(path: &std::path::Path, (line, message): (usize, String)) -> Self {
        match line {
            0 => Self::format(path, message),
            line => Self::Parse {
                path: path.to_path_buf(),
                line,
                message,
            },
        }
    }

    /// A problem with the contents of `path` (not tied to a line).
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Format {
            path: path.into(),
            message: message.into(),
        }
    }
}

/// `text` in single quotes for a message, control characters escaped, shortened to its first
/// 60 characters where it is longer (a hostile file can hold a name or field of megabytes, or
/// a line break; an error stays one short line).
pub fn quoted(text: &str) -> String {
    const MOST: usize = 60;
    match text.char_indices().nth(MOST) {
        None => format!("'{}'", text.escape_debug()),
        Some((at, _)) => format!("'{}'… ({} bytes)", text[..at].escape_debug(), text.len()),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn long_text_is_quoted_shortened() {
        assert_eq!(super::quoted("../x"), "'../x'");
        assert_eq!(super::quoted("a\nb"), "'a\\nb'");
        let long = "a".repeat(1000);
        let quoted = super::quoted(&long);
        assert!(
            quoted.len() < 90 && quoted.ends_with("(1000 bytes)"),
            "{quoted}"
        );
    }
}
