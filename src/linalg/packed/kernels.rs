//! The loops of a packed factor's triangular solves, over a run of supernodes.
//!
//! Per supernode of `w` columns and `m` kept rows below:
//!
//! - `L y = b`: up to four columns wide (column-major, `ld = w + m`), the triangle by columns
//!   (`y_j /= L_jj`, then the later columns), unrolled for its width, then `y_r −= Σ_j L_rj y_j`
//!   for each row `r` below, each row's sum taken straight into `y_r`. Wider, block by block of
//!   four columns ([`layout`]): the block's triangle, then its tiles of rows inside the
//!   supernode's triangle straight into `y`, and its tiles of rows below summed into scratch,
//!   which is scattered once per supernode.
//! - `Lᵀ x = y`, in reverse: up to four columns wide, each column's dot product with the
//!   solved rows below (gathered straight from `y`, two rows per step so that two sums are in
//!   flight), then the triangle backwards, unrolled for its width. Wider, the rows below
//!   gathered once, then block by block from the last: the tiles' dot products with the
//!   gathered rows and with the later columns, then the block's triangle backwards. The tiles
//!   are read from the last, so that the upper solve reads the factor in one backward run as
//!   the lower one reads it in one forward run.
//!
//! A narrow supernode's triangle is unrolled for its width (one to four columns, a constant of
//! the loop): as loops of run-time length, the one-vertex supernodes that make up most of a
//! factor paid their short loops' branches in every solve (paper slab: 7.0–7.3 → 6.5–6.9 ms a
//! solve, bfloat16 factors of 128 × 95 grids 10–16 % less, `tests::timing`).
//!
//! Each loop is compiled twice: portable, and with AVX2 and fused multiply–add, chosen once
//! per factor ([`Kernels::detect`]). The two builds round differently (a fused multiply–add
//! rounds once), so their solves differ in the last bits of `f32`.

use super::layout::{self, TILE};
use super::{Below, Columns, Entry, Supernodes};
use std::ops::Range;

/// Which build of the loops a factor's solves run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernels {
    /// Plain multiplies and adds, vectorized for the target's baseline.
    Portable,
    /// AVX2 with fused multiply–add: only from [`Kernels::detect`], on a processor that has
    /// both.
    Avx2Fma,
}

impl Kernels {
    /// AVX2 with FMA where this processor has both, portable otherwise.
    pub fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            return Self::Avx2Fma;
        }
        Self::Portable
    }
}

/// `self.$avx2::<E, WHOLE>(args)` where the factor's kernels are AVX2 + FMA, otherwise the
/// portable `self.$portable::<E, false, WHOLE>(args)`, with `WHOLE` the value of `$whole`.
macro_rules! dispatch {
    ($self:ident, $whole:expr, $avx2:ident, $portable:ident, ($($arg:expr),*)) => {
        match ($self.kernels, $whole) {
            // SAFETY: `Avx2Fma` comes only from `Kernels::detect`, which found both features.
            #[cfg(target_arch = "x86_64")]
            (Kernels::Avx2Fma, true) => unsafe { $self.$avx2::<E, true>($($arg),*) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            (Kernels::Avx2Fma, false) => unsafe { $self.$avx2::<E, false>($($arg),*) },
            (_, true) => $self.$portable::<E, false, true>($($arg),*),
            (_, false) => $self.$portable::<E, false, false>($($arg),*),
        }
    };
}

/// `$block::<E, W, FMA>(args)` with `W` the width of `block = (c₀, W)`, a wide supernode's
/// block (four columns, or one to three in the last).
macro_rules! by_width {
    ($block:ident, $b:expr, ($($arg:expr),*)) => {
        match $b.1 {
            1 => $block::<E, 1, FMA>($($arg),*),
            2 => $block::<E, 2, FMA>($($arg),*),
            3 => $block::<E, 3, FMA>($($arg),*),
            _ => $block::<E, 4, FMA>($($arg),*),
        }
    };
}

impl Supernodes<'_> {
    /// `L y = b` over the supernodes `part`, whose columns and descendants' are
    /// `columns.own`; what they take off their ancestors' columns is added to
    /// `columns.beyond`. `scratch` holds at least `n` values.
    pub(super) fn lower_solve_part<E: Entry>(
        &self,
        part: Range<usize>,
        values: &[E],
        columns: &mut Columns<'_>,
        scratch: &mut [f32],
    ) {
        let whole = columns.offset == 0 && columns.beyond.is_empty();
        dispatch!(
            self,
            whole,
            lower_avx2,
            lower,
            (part, values, columns, scratch)
        )
    }

    /// `Lᵀ x = y` over the supernodes `part`, whose columns and descendants' are `own` (from
    /// column `offset`), reading their ancestors' solved columns in `beyond` (from column
    /// `beyond_start`). `scratch` holds at least `n` values.
    pub(super) fn upper_solve_part<E: Entry>(
        &self,
        part: Range<usize>,
        values: &[E],
        own: (&mut [f32], usize),
        beyond: (&[f32], usize),
        scratch: &mut [f32],
    ) {
        let whole = own.1 == 0 && beyond.0.is_empty();
        dispatch!(
            self,
            whole,
            upper_avx2,
            upper,
            (part, values, own, beyond, scratch)
        )
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn lower_avx2<E: Entry, const WHOLE: bool>(
        &self,
        part: Range<usize>,
        values: &[E],
        columns: &mut Columns<'_>,
        scratch: &mut [f32],
    ) {
        self.lower::<E, true, WHOLE>(part, values, columns, scratch)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn upper_avx2<E: Entry, const WHOLE: bool>(
        &self,
        part: Range<usize>,
        values: &[E],
        own: (&mut [f32], usize),
        beyond: (&[f32], usize),
        scratch: &mut [f32],
    ) {
        self.upper::<E, true, WHOLE>(part, values, own, beyond, scratch)
    }

    #[inline(always)]
    fn lower<E: Entry, const FMA: bool, const WHOLE: bool>(
        &self,
        part: Range<usize>,
        values: &[E],
        columns: &mut Columns<'_>,
        scratch: &mut [f32],
    ) {
        for s in part {
            let (first, w, below, l) = self.supernode(s, values);
            let first = first - columns.offset;
            if layout::is_wide(w) {
                let update = &mut scratch[..below.len()];
                update.fill(0.0);
                let y = &mut columns.own[first..first + w];
                for block in layout::blocks(w) {
                    let parts = layout::block_parts(w, below.len(), block).map(|r| &l[r]);
                    by_width!(lower_block, block, (y, block.0, parts, update));
                }
                below.for_each(|k, r| columns.take_off::<WHOLE>(r, update[k]));
                continue;
            }
            let ld = w + below.len();
            let panel = |j: usize| &l[j * ld + w..(j + 1) * ld];
            macro_rules! narrow {
                ($w:literal) => {{
                    let y = &mut columns.own[first..first + $w];
                    let solved = lower_triangle::<E, $w, FMA>(l, ld, y);
                    if below.len() > 0 {
                        let panels = std::array::from_fn(panel);
                        scatter::<E, $w, FMA, WHOLE>(panels, solved, below, columns)
                    }
                }};
            }
            match w {
                1 => narrow!(1),
                2 => narrow!(2),
                3 => narrow!(3),
                _ => narrow!(4),
            }
        }
    }

    #[inline(always)]
    fn upper<E: Entry, const FMA: bool, const WHOLE: bool>(
        &self,
        part: Range<usize>,
        values: &[E],
        (own, offset): (&mut [f32], usize),
        (beyond, beyond_start): (&[f32], usize),
        scratch: &mut [f32],
    ) {
        let end = offset + own.len();
        for s in part.rev() {
            let (first, w, below, l) = self.supernode(s, values);
            let first = first - offset;
            // A whole solve's rows are all its own, from column 0.
            let solved = |r: usize| match (WHOLE, r < end) {
                (true, _) => own[r],
                (false, true) => own[r - offset],
                (false, false) => beyond[r - beyond_start],
            };
            if layout::is_wide(w) {
                let gathered = &mut scratch[..below.len()];
                below.for_each(|k, r| gathered[k] = solved(r));
                let y = &mut own[first..first + w];
                for block in layout::blocks(w).rev() {
                    let parts = layout::block_parts(w, below.len(), block).map(|r| &l[r]);
                    by_width!(upper_block, block, (y, block.0, parts, gathered));
                }
                continue;
            }
            let ld = w + below.len();
            let panel = |j: usize| &l[j * ld + w..(j + 1) * ld];
            macro_rules! narrow {
                ($w:literal) => {{
                    let sums = match below.len() {
                        0 => [0.0; $w],
                        _ => gathered_dots::<E, $w, FMA>(std::array::from_fn(panel), below, solved),
                    };
                    narrow_upper_triangle::<E, $w, FMA>(l, ld, &mut own[first..first + $w], sums);
                }};
            }
            match w {
                1 => narrow!(1),
                2 => narrow!(2),
                3 => narrow!(3),
                _ => narrow!(4),
            }
        }
    }
}

/// `L y = b` on block `(c₀, W)` of a wide supernode whose own columns are `y`: the block's
/// triangle, then its rows inside the supernode's triangle straight into `y`, and its rows
/// below added to `update` (the block's `[triangle, inside, below]`, [`layout::block_parts`]).
#[inline(always)]
fn lower_block<E: Entry, const W: usize, const FMA: bool>(
    y: &mut [f32],
    c0: usize,
    [triangle, inside, below]: [&[E]; 3],
    update: &mut [f32],
) {
    let (solved, later) = y[c0..].split_at_mut(W);
    let a = lower_triangle::<E, W, FMA>(triangle, W, solved);
    tiled_axpy::<E, W, FMA>(later, inside, a.map(|a| -a));
    tiled_axpy::<E, W, FMA>(update, below, a);
}

/// `Lᵀ x = y` on block `(c₀, W)` of a wide supernode whose own columns are `y` (the later
/// blocks solved), with `gathered` its solved rows below: the dot products of the block's
/// rows below and inside, then its triangle backwards.
#[inline(always)]
fn upper_block<E: Entry, const W: usize, const FMA: bool>(
    y: &mut [f32],
    c0: usize,
    [triangle, inside, below]: [&[E]; 3],
    gathered: &[f32],
) {
    let (own, later) = y[c0..].split_at_mut(W);
    let (outer, inner) = (
        tiled_dots::<E, W, FMA>(gathered, below),
        tiled_dots::<E, W, FMA>(later, inside),
    );
    for j in (0..W).rev() {
        let later = (j + 1..W).fold(outer[j] + inner[j], |sum, i| {
            madd::<FMA>(triangle[j * W + i].widen(), own[i], sum)
        });
        own[j] = (own[j] - later) / triangle[j * W + j].widen();
    }
}

/// `L y = b` on a triangle `W` columns wide, column-major with `ld` rows a column (a narrow
/// supernode in faer's layout, `ld = w + m`; a wide supernode's block, `ld = W`), whose own
/// columns are `y`: the solved values, also written to `y`. The width is known at compile
/// time, so the triangle is straight-line code.
#[inline(always)]
fn lower_triangle<E: Entry, const W: usize, const FMA: bool>(
    l: &[E],
    ld: usize,
    y: &mut [f32],
) -> [f32; W] {
    let mut solved: [f32; W] = std::array::from_fn(|t| y[t]);
    for j in 0..W {
        solved[j] /= l[j * ld + j].widen();
        for i in j + 1..W {
            solved[i] = madd::<FMA>(l[j * ld + i].widen(), -solved[j], solved[i]);
        }
    }
    y[..W].copy_from_slice(&solved);
    solved
}

/// `Lᵀ x = y` on the triangle of a narrow supernode `W` columns wide, its own columns `y`, with
/// `sums` its columns' dot products with the solved rows below. (A wide supernode's block,
/// [`upper_block`], adds its sums to the later columns' before subtracting: another rounding,
/// so it keeps its own loop.)
#[inline(always)]
fn narrow_upper_triangle<E: Entry, const W: usize, const FMA: bool>(
    l: &[E],
    ld: usize,
    y: &mut [f32],
    sums: [f32; W],
) {
    (y.iter_mut()).zip(sums).for_each(|(y, s)| *y -= s);
    for j in (0..W).rev() {
        let later = (j + 1..W).fold(0.0, |sum, i| madd::<FMA>(l[j * ld + i].widen(), y[i], sum));
        y[j] = (y[j] - later) / l[j * ld + j].widen();
    }
}

/// `target += Σ_t region_t a_t` over a tiled range ([`layout`]) of `target.len()`
/// rows and `W` columns.
#[inline(always)]
fn tiled_axpy<E: Entry, const W: usize, const FMA: bool>(
    target: &mut [f32],
    region: &[E],
    a: [f32; W],
) {
    let whole = target.len() / TILE * TILE;
    let (tiles, tail) = region.split_at(whole * W);
    let (target, rest) = target.split_at_mut(whole);
    for (y, tile) in target
        .chunks_exact_mut(TILE)
        .zip(tiles.chunks_exact(TILE * W))
    {
        for (t, column) in tile.chunks_exact(TILE).enumerate() {
            for e in 0..TILE {
                y[e] = madd::<FMA>(column[e].widen(), a[t], y[e]);
            }
        }
    }
    let n = rest.len();
    for (t, &a) in a.iter().enumerate() {
        axpy::<E, FMA>(rest, &tail[t * n..(t + 1) * n], a);
    }
}

/// `region_t · g` for each column `t` of a tiled range of `g.len()` rows and `W` columns,
/// read backwards (the upper solve walks the factor from its end: one descending run for the
/// prefetcher, where ascending runs taken in descending order make it start over at each).
#[inline(always)]
fn tiled_dots<E: Entry, const W: usize, const FMA: bool>(g: &[f32], region: &[E]) -> [f32; W] {
    let whole = g.len() / TILE * TILE;
    let (tiles, tail) = region.split_at(whole * W);
    let (g, rest) = g.split_at(whole);
    let tails: [f32; W] = std::array::from_fn(|t| {
        let column = &tail[t * rest.len()..(t + 1) * rest.len()];
        (column.iter().zip(rest)).fold(0.0, |sum, (x, g)| madd::<FMA>(x.widen(), *g, sum))
    });
    let mut lanes = [[0.0f32; TILE]; W];
    for (g, tile) in (g.chunks_exact(TILE).zip(tiles.chunks_exact(TILE * W))).rev() {
        for t in 0..W {
            let column = &tile[t * TILE..(t + 1) * TILE];
            for e in 0..TILE {
                lanes[t][e] = madd::<FMA>(column[e].widen(), g[e], lanes[t][e]);
            }
        }
    }
    std::array::from_fn(|t| lanes[t].iter().sum::<f32>() + tails[t])
}

/// `a b + c`, fused where the build has FMA.
#[inline(always)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    match FMA {
        true => a.mul_add(b, c),
        false => a * b + c,
    }
}

/// `y_r −= Σ_t panel_t[k] a_t` for the `k`-th kept row `r` below a supernode of `W` columns.
#[inline(always)]
fn scatter<E: Entry, const W: usize, const FMA: bool, const WHOLE: bool>(
    panel: [&[E]; W],
    a: [f32; W],
    below: Below<'_>,
    columns: &mut Columns<'_>,
) {
    // Cut to the rows' count, so that the loop over them needs no bounds checks.
    let panel = panel.map(|p| &p[..below.len()]);
    let mut row = |k: usize, r: usize| {
        let sum = (0..W).fold(0.0, |sum, t| madd::<FMA>(panel[t][k].widen(), a[t], sum));
        columns.take_off::<WHOLE>(r, sum);
    };
    match below.all() {
        Some(rows) => (0..panel[0].len()).for_each(|k| row(k, rows[k])),
        None => below.for_each(row),
    }
}

/// `Σ_k panel_t[k] y_r` over the kept rows `r` below a supernode of `W` columns, `y_r` from
/// `solved`; where all rows are kept, two rows per step into separate sums, from the last
/// (backwards, as [`tiled_dots`]).
#[inline(always)]
fn gathered_dots<E: Entry, const W: usize, const FMA: bool>(
    panel: [&[E]; W],
    below: Below<'_>,
    solved: impl Fn(usize) -> f32,
) -> [f32; W] {
    let panel = panel.map(|p| &p[..below.len()]);
    let (mut even, mut odd) = ([0.0f32; W], [0.0f32; W]);
    let add = |sums: &mut [f32; W], k: usize, y: f32| {
        for t in 0..W {
            sums[t] = madd::<FMA>(panel[t][k].widen(), y, sums[t]);
        }
    };
    match below.all() {
        Some(rows) => {
            let rows = &rows[..panel[0].len()];
            let pairs = rows.chunks_exact(2);
            let last = pairs.remainder().first().map(|&r| (rows.len() - 1, r));
            if let Some((k, r)) = last {
                add(&mut even, k, solved(r));
            }
            for (q, pair) in pairs.enumerate().rev() {
                add(&mut even, 2 * q, solved(pair[0]));
                add(&mut odd, 2 * q + 1, solved(pair[1]));
            }
        }
        None => below.for_each(|k, r| add(&mut even, k, solved(r))),
    }
    std::array::from_fn(|t| even[t] + odd[t])
}

/// `update += l a`.
#[inline(always)]
fn axpy<E: Entry, const FMA: bool>(update: &mut [f32], l: &[E], a: f32) {
    for (u, x) in update.iter_mut().zip(l) {
        *u = madd::<FMA>(x.widen(), a, *u);
    }
}

/// `y ← L⁻¹ y` for faer's simplicial (CSC, diagonal first in each column) layout: small
/// systems only, so the portable loop.
pub(super) fn simplicial_lower_solve<E: Entry>(
    columns: &[usize],
    rows: &[usize],
    values: &[E],
    y: &mut [f32],
) {
    for j in 0..y.len() {
        let range = columns[j]..columns[j + 1];
        let yj = y[j] / values[range.start].widen();
        y[j] = yj;
        for (&r, x) in rows[range.clone()].iter().zip(&values[range]).skip(1) {
            y[r] -= x.widen() * yj;
        }
    }
}

/// `y ← L⁻ᵀ y` for the simplicial layout.
pub(super) fn simplicial_upper_solve<E: Entry>(
    columns: &[usize],
    rows: &[usize],
    values: &[E],
    y: &mut [f32],
) {
    for j in (0..y.len()).rev() {
        let range = columns[j]..columns[j + 1];
        let sum: f32 = (rows[range.clone()].iter().zip(&values[range.clone()]))
            .skip(1)
            .map(|(&r, x)| x.widen() * y[r])
            .sum();
        y[j] = (y[j] - sum) / values[range.start].widen();
    }
}
