//! Which files make a sequence's frames: a directory's or a glob's files in natural order
//! (`frame2` before `frame10`), or one named file.

use super::IoError;
use std::cmp::Ordering;
use std::path::{Path, PathBuf};

/// The files that `path` names, in natural order, for readers of one file per frame (volumes,
/// point clouds): a directory's or a glob's files that `accepts`, or the one file `path`.
/// `what` names them in the error when there are none (e.g. "volumes (.npy, .tif)").
pub fn frame_files(
    path: &Path,
    accepts: impl Fn(&Path) -> bool,
    what: &str,
) -> Result<Vec<PathBuf>, IoError> {
    let text = path.to_string_lossy();
    let mut files = if text.contains(['*', '?', '[']) && !path.exists() {
        glob_files(&text, path)?
    } else if std::fs::metadata(path)
        .map_err(|e| IoError::file(path, e))?
        .is_dir()
    {
        directory_files(path)?
    } else {
        vec![path.to_path_buf()]
    };
    files.retain(|f| accepts(f));
    if files.is_empty() {
        return Err(IoError::format(path, format!("no {what} here")));
    }
    files.sort_by(|a, b| natural_order(&a.to_string_lossy(), &b.to_string_lossy()));
    Ok(files)
}

pub(crate) fn directory_files(dir: &Path) -> Result<Vec<PathBuf>, IoError> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::file(dir, e))? {
        files.push(entry.map_err(|e| IoError::file(dir, e))?.path());
    }
    Ok(files)
}

pub(crate) fn glob_files(pattern: &str, path: &Path) -> Result<Vec<PathBuf>, IoError> {
    let matches = glob::glob(pattern)
        .map_err(|e| IoError::format(path, format!("not a valid glob ({e})")))?;
    matches
        .map(|m| m.map_err(|e| IoError::file(e.path().to_path_buf(), e.into())))
        .collect()
}

/// Compares strings with digit runs ordered by value: `f2 < f10`.
pub fn natural_order(a: &str, b: &str) -> Ordering {
    let (mut x, mut y) = (a.as_bytes(), b.as_bytes());
    loop {
        match (x.first(), y.first()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(p), Some(q)) if p.is_ascii_digit() && q.is_ascii_digit() => {
                let (dx, rx) = split_digits(x);
                let (dy, ry) = split_digits(y);
                let (tx, ty) = (dx.trim_start_matches('0'), dy.trim_start_matches('0'));
                let order = tx
                    .len()
                    .cmp(&ty.len())
                    .then_with(|| tx.cmp(ty))
                    .then_with(|| dx.len().cmp(&dy.len()));
                if order != Ordering::Equal {
                    return order;
                }
                (x, y) = (rx, ry);
            }
            (Some(p), Some(q)) => {
                if p != q {
                    return p.cmp(q);
                }
                (x, y) = (&x[1..], &y[1..]);
            }
        }
    }
}

fn split_digits(s: &[u8]) -> (&str, &[u8]) {
    let n = s.iter().take_while(|c| c.is_ascii_digit()).count();
    (std::str::from_utf8(&s[..n]).expect("ASCII digits"), &s[n..])
}
