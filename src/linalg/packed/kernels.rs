//! The loops of a packed factor's triangular solves, over a run of supernodes.
//!
//! Per supernode of `w` columns and `m` kept rows below (values column-major, `ld = w + m`):
//!
//! - `L y = b`: the triangle by columns (`y_j /= L_jj`, then an axpy on the later columns), then
//!   `y_r −= Σ_j L_rj y_j` for each row `r` below. Up to four columns wide, each row's sum is
//!   taken straight into `y_r`; wider panels are summed into scratch four columns at a time
//!   (one pass over the scratch per four columns), then scattered.
//! - `Lᵀ x = y`, in reverse: each column's dot product with the solved rows below (gathered
//!   straight from `y` up to four columns wide, two rows per step so that two sums are in
//!   flight; wider panels gather once and take four columns per pass), then the triangle
//!   backwards, each column's dot product with the later columns.
//!
//! Each loop is compiled twice: portable, and with AVX2 and fused multiply–add, chosen once
//! per factor ([`Kernels::detect`]). The two builds round differently (a fused multiply–add
//! rounds once), so their solves differ in the last bits of `f32`.

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

/// Independent sums of a lone dot product or axpy, in `f32` lanes: two AVX registers.
const LANES: usize = 16;
/// Lanes per column where four columns are summed together: one AVX register each.
const PANEL_LANES: usize = 8;

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
            let ld = w + below.len();
            let y = &mut columns.own[first..first + w];
            for j in 0..w {
                let column = &l[j * ld + j..j * ld + w];
                let yj = y[j] / column[0].widen();
                y[j] = yj;
                axpy::<E, FMA>(&mut y[j + 1..], &column[1..], -yj);
            }
            if below.len() == 0 {
                continue;
            }
            let panel = |j: usize| &l[j * ld + w..(j + 1) * ld];
            macro_rules! narrow {
                ($w:literal) => {{
                    let solved: [f32; $w] = std::array::from_fn(|t| columns.own[first + t]);
                    scatter::<E, $w, FMA, WHOLE>(std::array::from_fn(panel), solved, below, columns)
                }};
            }
            match w {
                1 => narrow!(1),
                2 => narrow!(2),
                3 => narrow!(3),
                4 => narrow!(4),
                _ => {
                    let (update, solved) = scratch.split_at_mut(below.len());
                    let solved = &mut solved[..w];
                    solved.copy_from_slice(&columns.own[first..first + w]);
                    update.fill(0.0);
                    let blocks = w / 4;
                    for b in 0..blocks {
                        let a = std::array::from_fn(|t| solved[4 * b + t]);
                        panel_axpy::<E, FMA>(update, std::array::from_fn(|t| panel(4 * b + t)), a);
                    }
                    for (j, &a) in solved.iter().enumerate().skip(4 * blocks) {
                        axpy::<E, FMA>(update, panel(j), a);
                    }
                    below.for_each(|k, r| columns.take_off::<WHOLE>(r, update[k]));
                }
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
            let ld = w + below.len();
            let panel = |j: usize| &l[j * ld + w..(j + 1) * ld];
            if below.len() > 0 {
                // A whole solve's rows are all its own, from column 0.
                let solved = |r: usize| match (WHOLE, r < end) {
                    (true, _) => own[r],
                    (false, true) => own[r - offset],
                    (false, false) => beyond[r - beyond_start],
                };
                macro_rules! narrow {
                    ($w:literal) => {{
                        let sums =
                            gathered_dots::<E, $w, FMA>(std::array::from_fn(panel), below, solved);
                        (own[first..first + $w].iter_mut())
                            .zip(sums)
                            .for_each(|(y, s)| *y -= s);
                    }};
                }
                match w {
                    1 => narrow!(1),
                    2 => narrow!(2),
                    3 => narrow!(3),
                    4 => narrow!(4),
                    _ => {
                        let gathered = &mut scratch[..below.len()];
                        below.for_each(|k, r| gathered[k] = solved(r));
                        let blocks = w / 4;
                        for b in 0..blocks {
                            let columns = std::array::from_fn(|t| panel(4 * b + t));
                            let sums = panel_dots::<E, FMA>(gathered, columns);
                            (own[first + 4 * b..first + 4 * b + 4].iter_mut())
                                .zip(sums)
                                .for_each(|(y, s)| *y -= s);
                        }
                        for j in 4 * blocks..w {
                            own[first + j] -= dot::<E, FMA>(panel(j), gathered);
                        }
                    }
                }
            }
            let y = &mut own[first..first + w];
            for j in (0..w).rev() {
                let column = &l[j * ld + j..j * ld + w];
                let later = dot::<E, FMA>(&column[1..], &y[j + 1..]);
                y[j] = (y[j] - later) / column[0].widen();
            }
        }
    }
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
/// `solved`; where all rows are kept, two rows per step into separate sums.
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
            for (q, pair) in pairs.enumerate() {
                add(&mut even, 2 * q, solved(pair[0]));
                add(&mut odd, 2 * q + 1, solved(pair[1]));
            }
            if let Some((k, r)) = last {
                add(&mut even, k, solved(r));
            }
        }
        None => below.for_each(|k, r| add(&mut even, k, solved(r))),
    }
    std::array::from_fn(|t| even[t] + odd[t])
}

/// `update += Σ_t columns_t a_t`, four columns per pass.
#[inline(always)]
fn panel_axpy<E: Entry, const FMA: bool>(update: &mut [f32], columns: [&[E]; 4], a: [f32; 4]) {
    let [c0, c1, c2, c3] = columns;
    let rows = update.iter_mut().zip(c0).zip(c1).zip(c2).zip(c3);
    for ((((u, x0), x1), x2), x3) in rows {
        let sum = madd::<FMA>(x0.widen(), a[0], madd::<FMA>(x1.widen(), a[1], *u));
        *u = madd::<FMA>(x2.widen(), a[2], madd::<FMA>(x3.widen(), a[3], sum));
    }
}

/// `columns_t · g` for four columns, one register of lanes each.
#[inline(always)]
fn panel_dots<E: Entry, const FMA: bool>(g: &[f32], columns: [&[E]; 4]) -> [f32; 4] {
    let mut lanes = [[0.0f32; PANEL_LANES]; 4];
    let full = g.len() / PANEL_LANES * PANEL_LANES;
    for (q, g) in g[..full].chunks_exact(PANEL_LANES).enumerate() {
        let at = q * PANEL_LANES;
        for (lanes, column) in lanes.iter_mut().zip(&columns) {
            let column = &column[at..at + PANEL_LANES];
            for e in 0..PANEL_LANES {
                lanes[e] = madd::<FMA>(column[e].widen(), g[e], lanes[e]);
            }
        }
    }
    std::array::from_fn(|t| {
        let tail = (columns[t][full..].iter().zip(&g[full..]))
            .fold(0.0, |sum, (x, g)| madd::<FMA>(x.widen(), *g, sum));
        lanes[t].iter().sum::<f32>() + tail
    })
}

/// `update += l a`.
#[inline(always)]
fn axpy<E: Entry, const FMA: bool>(update: &mut [f32], l: &[E], a: f32) {
    for (u, x) in update.iter_mut().zip(l) {
        *u = madd::<FMA>(x.widen(), a, *u);
    }
}

/// `l · g`, in [`LANES`] independent sums.
#[inline(always)]
fn dot<E: Entry, const FMA: bool>(l: &[E], g: &[f32]) -> f32 {
    let mut lanes = [0.0f32; LANES];
    let (x, v) = (l.chunks_exact(LANES), g.chunks_exact(LANES));
    let tail = (x.remainder().iter())
        .zip(v.remainder())
        .fold(0.0, |sum, (x, g)| madd::<FMA>(x.widen(), *g, sum));
    for (x, v) in x.zip(v) {
        for k in 0..LANES {
            lanes[k] = madd::<FMA>(x[k].widen(), v[k], lanes[k]);
        }
    }
    lanes.iter().sum::<f32>() + tail
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
