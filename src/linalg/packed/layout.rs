//! How a packed factor orders the entries of a supernode: faer's column-major layout for the
//! narrow supernodes, blocks of four columns in tiles of eight rows for the wide ones.
//!
//! faer stores supernode `s` (`w` columns, `m` rows below) column-major with `w + m` rows, its
//! dense `w × w` triangle on top (the upper half unused). A solve reads a wide supernode four
//! columns at a time: in that layout four short runs of `m` entries each, `4(w + m)` entries
//! apart, and the triangle's columns one run each, with gaps between them. On this machine
//! such passes read 4–7 GB/s where one run of the same entries reads 11–17 GB/s (a pass over
//! 64 MB of panels 32 × 124 and 128 × 480: 4.4 and 7.3 GB/s column-major, 7.6 and 17 GB/s
//! tiled). The kernels are bound by those reads, so a wide supernode is stored in the order
//! its solve reads it, one run:
//!
//! - its columns in blocks of [`BLOCK`] (the last block holds the remainder, `bw ≤ 4`), block
//!   `b` from column `c₀ = 4b`;
//! - per block, its `bw × bw` diagonal triangle (column-major, upper half unused), then its
//!   rows below that inside the supernode's triangle (`c₀ + bw .. w`), then the `m` kept rows
//!   below the supernode;
//! - each of those two row ranges in [`TILE`]-row tiles, column-major inside a tile (`bw`
//!   runs of eight), and the rows past the last whole tile column-major at the end.
//!
//! A block then takes `bw (w − c₀ + m)` entries; the supernode `T(w) + w m` with
//! `T(w) = Σ_b bw (w − c₀)` (about `w²/2`: the unused upper half of the triangle is gone).
//! Supernodes at most four columns wide keep faer's layout: their fused kernels read all
//! their columns per row (`kernels::scatter`, `kernels::gathered_dots`).

use std::ops::Range;

/// Columns per block of a wide supernode; a supernode at most this wide is narrow.
pub const BLOCK: usize = 4;
/// Rows per tile.
pub const TILE: usize = 8;

/// Whether supernodes `w` columns wide are stored in blocks.
#[inline(always)]
pub fn is_wide(w: usize) -> bool {
    w > BLOCK
}

/// Entries of a supernode `w` columns wide that do not depend on its rows below: `w²` in
/// faer's layout, `T(w) = Σ_b bw (w − c₀)` in blocks.
#[inline(always)]
pub fn triangle_entries(w: usize) -> usize {
    match blocks(w).next_back() {
        Some(last) if is_wide(w) => block_parts(w, 0, last)[2].end,
        _ => w * w,
    }
}

/// The blocks of a wide supernode, `(first column c₀, width bw)`, in order.
#[inline(always)]
pub fn blocks(w: usize) -> impl DoubleEndedIterator<Item = (usize, usize)> {
    (0..w.div_ceil(BLOCK)).map(move |b| (BLOCK * b, BLOCK.min(w - BLOCK * b)))
}

/// Where block `(c₀, bw)` of a wide supernode (`w` columns, `m` rows below) starts, and its
/// three parts: `[triangle, rows inside the supernode's triangle, rows below]` as ranges of
/// the supernode's values.
#[inline(always)]
pub fn block_parts(w: usize, m: usize, (c0, bw): (usize, usize)) -> [Range<usize>; 3] {
    // The blocks before are full: Σ_{b' < b} 4 (w + m − 4b') with b = c₀ / 4.
    let b = c0 / BLOCK;
    let start = BLOCK * b * (w + m) - BLOCK * BLOCK * b * b.saturating_sub(1) / 2;
    let inside = start + bw * bw;
    let below = inside + bw * (w - c0 - bw);
    [start..inside, inside..below, below..below + bw * m]
}

/// `visit(column-major start, blocked start, length)` for the runs of consecutive entries a
/// tiled range (`rows` rows and `bw` columns, from `to` in the block) takes from column-major
/// columns (`ld` apart, the range's first row at `from`): eight rows per column and tile, then
/// the rows past the last whole tile.
fn tiled_runs(
    (from, to): (usize, usize),
    (rows, bw, ld): (usize, usize, usize),
    visit: &mut impl FnMut(usize, usize, usize),
) {
    let whole = rows / TILE * TILE;
    for q in 0..rows / TILE {
        for t in 0..bw {
            visit(from + t * ld + q * TILE, to + (q * bw + t) * TILE, TILE);
        }
    }
    let rest = rows - whole;
    if rest > 0 {
        for t in 0..bw {
            visit(from + t * ld + whole, to + whole * bw + t * rest, rest);
        }
    }
}

/// `visit(column-major start, blocked start, length)` for every run of entries a wide
/// supernode stores (`w` columns, `m` rows below; column-major with `w + m` rows, as faer's).
fn for_each_run(w: usize, m: usize, mut visit: impl FnMut(usize, usize, usize)) {
    let ld = w + m;
    for (c0, bw) in blocks(w) {
        let [triangle, inside, below] = block_parts(w, m, (c0, bw));
        let first = c0 * ld;
        for t in 0..bw {
            visit(first + t * ld + c0 + t, triangle.start + t * bw + t, bw - t);
        }
        let inner_rows = w - c0 - bw;
        tiled_runs(
            (first + c0 + bw, inside.start),
            (inner_rows, bw, ld),
            &mut visit,
        );
        tiled_runs((first + w, below.start), (m, bw, ld), &mut visit);
    }
}

/// Reorders, in place, the values of supernodes with `shapes(s) = (w, m)` from faer's layout
/// (supernode `s` from `starts[s]`) into blocks, and sets `starts` to the new starts. The
/// values shrink to the blocked count.
pub fn to_blocked<E: Copy + Default>(
    values: &mut Vec<E>,
    starts: &mut [usize],
    shapes: impl Fn(usize) -> (usize, usize),
) {
    let mut scratch = Vec::new();
    let mut write = 0;
    for s in 0..starts.len() - 1 {
        let (w, m) = shapes(s);
        let old = starts[s]..starts[s + 1];
        starts[s] = write;
        let count = triangle_entries(w) + w * m;
        // The new start is never past the old one, nor the new end past the old end: what is
        // written overwrites only this supernode's own values, copied first where wide.
        if is_wide(w) {
            scratch.clear();
            scratch.extend_from_slice(&values[old]);
            let out = &mut values[write..write + count];
            for_each_run(w, m, |from, to, n| {
                out[to..to + n].copy_from_slice(&scratch[from..from + n])
            });
        } else {
            values.copy_within(old, write);
        }
        write += count;
    }
    *starts
        .last_mut()
        .expect("one start per supernode and the end") = write;
    values.truncate(write);
    values.shrink_to_fit();
}

/// The values of blocked supernodes (`starts`, `shapes` as [`to_blocked`] left them) in
/// faer's layout, the unused upper halves of the triangles zero, written over `out`.
pub fn to_column_major<E: Copy + Default>(
    values: &[E],
    starts: &[usize],
    shapes: impl Fn(usize) -> (usize, usize),
    out: &mut Vec<E>,
) {
    out.clear();
    for s in 0..starts.len() - 1 {
        let (w, m) = shapes(s);
        let stored = &values[starts[s]..starts[s + 1]];
        let first = out.len();
        if is_wide(w) {
            out.resize(first + w * (w + m), E::default());
            let column_major = &mut out[first..];
            for_each_run(w, m, |to, from, n| {
                column_major[to..to + n].copy_from_slice(&stored[from..from + n])
            });
        } else {
            out.extend_from_slice(stored);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stored entry has its own position, and the positions fill `T(w) + w m` but for
    /// the upper halves of the blocks' triangles; each block's parts follow one another.
    #[test]
    fn blocks_fill_their_supernode_once() {
        for (w, m) in [(5, 0), (5, 9), (8, 16), (11, 7), (13, 30), (64, 3)] {
            let count = triangle_entries(w) + w * m;
            let mut seen = vec![0; count];
            for_each_run(w, m, |_, to, n| {
                seen[to..to + n].iter_mut().for_each(|s| *s += 1)
            });
            let upper_halves: usize = blocks(w).map(|(_, bw)| bw * (bw - 1) / 2).sum();
            assert!(seen.iter().all(|&n| n <= 1), "{w} × {m}: {seen:?}");
            assert_eq!(seen.iter().filter(|&&n| n == 0).count(), upper_halves);
            let parts: Vec<_> = blocks(w).flat_map(|b| block_parts(w, m, b)).collect();
            assert!(
                parts.windows(2).all(|p| p[0].end == p[1].start),
                "{w} × {m}"
            );
            assert_eq!(parts.last().map(|p| p.end), Some(count), "{w} × {m}");
        }
        assert_eq!(triangle_entries(4), 16);
        assert_eq!(triangle_entries(9), 4 * 9 + 4 * 5 + 1);
    }

    /// Blocking and back gives faer's layout with the triangles' upper halves zero; narrow
    /// supernodes are copied as they are.
    #[test]
    fn blocked_values_come_back_column_major() {
        let shapes = [(2, 5), (9, 13), (4, 0), (6, 1), (17, 40)];
        let mut starts = vec![0];
        for (w, m) in shapes {
            starts.push(starts.last().unwrap() + w * (w + m));
        }
        let original: Vec<f32> = (0..*starts.last().unwrap())
            .map(|v| v as f32 + 1.0)
            .collect();
        let mut expected = original.clone();
        for (s, &(w, m)) in shapes.iter().enumerate().filter(|(_, &(w, _))| is_wide(w)) {
            for j in 0..w {
                (0..j).for_each(|i| expected[starts[s] + j * (w + m) + i] = 0.0);
            }
        }
        let (mut values, mut blocked_starts) = (original, starts.clone());
        to_blocked(&mut values, &mut blocked_starts, |s| shapes[s]);
        let stored: usize = shapes
            .iter()
            .map(|&(w, m)| triangle_entries(w) + w * m)
            .sum();
        assert_eq!(values.len(), stored);
        let mut back = Vec::new();
        to_column_major(&values, &blocked_starts, |s| shapes[s], &mut back);
        assert_eq!(back, expected);
    }
}
