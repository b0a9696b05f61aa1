//! MatrixMarket (coordinate, real, general): written through sprs, read by a parser of our own
//! that checks the declared size against the memory limit (sprs reserves the declared entry
//! count up front, and loops forever on a file that ends before its size line).

use super::{write_atomically, IoError};
use crate::fem::SparseMatrix;
use faer::sparse::{SparseColMat, Triplet};
use std::path::Path;

/// Writes a sparse matrix as MatrixMarket `coordinate real general` (1-based indices, every
/// stored entry), readable by `scipy.io.mmread` and MATLAB's `mmread`.
pub fn write_matrix_market(path: &Path, matrix: &SparseMatrix) -> Result<(), IoError> {
    let (symbolic, values) = matrix.parts();
    let csc = sprs::CsMat::new_csc(
        (matrix.nrows(), matrix.ncols()),
        symbolic.col_ptr().to_vec(),
        symbolic.row_idx().to_vec(),
        values.to_vec(),
    );
    write_atomically(path, |w| sprs::io::write_matrix_market_to_bufwrite(w, &csc))
}

/// Reads a real (or integer) MatrixMarket coordinate matrix, general or symmetric, into a
/// sparse matrix; errors name the line.
pub fn read_matrix_market(path: &Path) -> Result<SparseMatrix, IoError> {
    matrix_from_bytes(&super::read_file(path)?, path)
}

/// [`read_matrix_market`] from a stream; `name` stands for it in errors.
pub fn read_matrix_market_from(
    reader: impl std::io::Read,
    name: &Path,
) -> Result<SparseMatrix, IoError> {
    matrix_from_bytes(&super::read_stream(reader, name)?, name)
}

/// The MatrixMarket matrix in `bytes`, read from `path`.
fn matrix_from_bytes(bytes: &[u8], path: &Path) -> Result<SparseMatrix, IoError> {
    let text = std::str::from_utf8(bytes).map_err(|_| IoError::format(path, "not UTF-8 text"))?;
    let market = parse(text).map_err(|e| IoError::at_line(path, e))?;
    let (rows, cols) = market.shape;
    // The matrix's column pointers and faer's work arrays, then its entries.
    crate::limits::check_items(
        format!("a {rows} × {cols} matrix"),
        (rows as u64).saturating_add(cols as u64),
        16,
    )
    .map_err(|e| IoError::too_large(path, e))?;
    SparseColMat::try_new_from_triplets(rows, cols, &market.entries)
        .map_err(|e| IoError::format(path, format!("{e:?}")))
}

/// A parsed MatrixMarket file.
struct Market {
    shape: (usize, usize),
    entries: Vec<Triplet<usize, usize, f64>>,
}

/// A 1-based line and a message; line 0 for the whole file.
type ParseError = (usize, String);

fn parse(text: &str) -> Result<Market, ParseError> {
    let mut lines = (1..).zip(text.lines());
    let banner = lines.next().map_or("", |(_, l)| l).to_ascii_lowercase();
    let symmetric = banner_symmetry(&banner).map_err(|m| (1, m))?;
    let mut lines = lines.filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('%'));
    let (size_line, size) = lines
        .next()
        .ok_or((0, "no size line (rows, columns, entries)".to_string()))?;
    let [rows, cols, nnz] = numbers::<usize, 3>(size).map_err(|m| (size_line, m))?;
    let mut market = Market {
        shape: (rows, cols),
        entries: Vec::new(),
    };
    // The entries come one a line, so the text bounds what is reserved.
    let per_entry = 1 + usize::from(symmetric);
    crate::limits::check_items(
        format!("{nnz} entries"),
        (nnz as u64).saturating_mul(per_entry as u64),
        24,
    )
    .map_err(|e| (size_line, e.to_string()))?;
    market.entries.reserve(nnz.min(text.len() / 6) * per_entry);
    let mut count = 0;
    for (line, entry) in lines {
        count += 1;
        if count > nnz {
            return Err((
                line,
                format!("more entries than the {nnz} the size line declares"),
            ));
        }
        let triplet = parse_entry(entry, (rows, cols)).map_err(|m| (line, m))?;
        if symmetric && triplet.row != triplet.col {
            market
                .entries
                .push(Triplet::new(triplet.col, triplet.row, triplet.val));
        }
        market.entries.push(triplet);
    }
    if count < nnz {
        return Err((
            0,
            format!("truncated file: {count} entries of the {nnz} declared"),
        ));
    }
    Ok(market)
}

/// Whether the banner declares a symmetric matrix; an error for what is not read.
fn banner_symmetry(banner: &str) -> Result<bool, String> {
    let words: Vec<&str> = banner.split_whitespace().collect();
    match words[..] {
        ["%%matrixmarket", "matrix", "coordinate", "real" | "integer", symmetry] => match symmetry {
            "general" => Ok(false),
            "symmetric" => Ok(true),
            other => Err(format!("'{other}' matrices are not supported (general or symmetric)")),
        },
        _ => Err(
            "not a MatrixMarket coordinate real matrix ('%%MatrixMarket matrix coordinate real              general')"
                .into(),
        ),
    }
}

/// One entry line: 1-based row and column within `shape`, and a finite value.
fn parse_entry(line: &str, shape: (usize, usize)) -> Result<Triplet<usize, usize, f64>, String> {
    let [row, col] = numbers::<usize, 2>(line)
        .map_err(|_| format!("'{}' is not an entry (row column value)", short(line)))?;
    let value: f64 = (line.split_whitespace().nth(2))
        .and_then(|t| t.parse().ok())
        .filter(|v: &f64| v.is_finite())
        .ok_or_else(|| format!("'{}' has no finite value", short(line)))?;
    let within = |index: usize, size: usize| (1..=size).contains(&index);
    if !within(row, shape.0) || !within(col, shape.1) {
        return Err(format!(
            "entry ({row}, {col}) lies outside the {} × {} matrix",
            shape.0, shape.1
        ));
    }
    Ok(Triplet::new(row - 1, col - 1, value))
}

/// The first `N` whitespace-separated numbers of `line` (the size line: exactly `N`).
fn numbers<T: std::str::FromStr, const N: usize>(line: &str) -> Result<[T; N], String> {
    let mut tokens = line.split_whitespace().map(str::parse::<T>);
    let error = || {
        format!(
            "'{}' does not start with {N} non-negative integers",
            short(line)
        )
    };
    let values: Vec<T> = (tokens.by_ref().take(N))
        .collect::<Result<_, _>>()
        .map_err(|_| error())?;
    values.try_into().map_err(|_| error())
}

/// At most 40 characters of `text`, for messages.
fn short(text: &str) -> String {
    text.chars().take(40).collect()
}
