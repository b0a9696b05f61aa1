//! Morphological closing of a voxel mask by a ball: what [`super::isosurface`] needs to seal
//! the gaps of a patchy layer or between nuclei.
//!
//! **Closing** by the ball `B_r` of physical radius `r` (voxel sides `d = (d_x, d_y, d_z)`):
//! the dilation `D = {x : dist(x, M) ≤ r}`, then its erosion `C = {x : dist(x, Dᶜ) > r}`, with
//! `dist` the Euclidean distance between voxel centres in physical units. `M ⊂ C`, and a gap
//! of `M` narrower than `2r` is filled. Beyond the grid is background, as everywhere the image
//! does not show the object: the transforms run over the mask's box padded by the ball, past
//! the grid where the object is near its border. Both distances come from exact squared
//! Euclidean distance transforms, separable along z, y and x (Felzenszwalb & Huttenlocher,
//! "Distance transforms of sampled functions", Theory of Computing 8, 2012): per line, the
//! lower envelope of the parabolas `(d (q − p))² + f(p)`. Written here: no well-kept crate
//! offers an anisotropic 3-D transform over our `(z, y, x)` grids.

use rayon::prelude::*;

/// `mask` closed by the ball of physical radius `radius` on a grid of `shape` (`(n_z, n_y,
/// n_x)`, C order) with voxel sides `voxel` (`(d_x, d_y, d_z)`). Beyond the grid is
/// background: the closing is computed in the mask's bounding box padded by the ball (and a
/// voxel), which may reach past the grid, so an object near the grid's border is not closed
/// onto it. The box's voxels are checked against the memory limit.
pub(super) fn closed(
    mask: &[bool],
    shape: [usize; 3],
    voxel: [f64; 3],
    radius: f64,
) -> Result<Vec<bool>, crate::limits::OverBudget> {
    let Some((low, high)) = bounding_box(mask, shape) else {
        return Ok(mask.to_vec());
    };
    // Padding per axis (z, y, x), in voxels.
    let pad = [voxel[2], voxel[1], voxel[0]].map(|side| (radius / side).ceil() as usize + 1);
    let boxed = [0, 1, 2].map(|a| high[a] - low[a] + 2 * pad[a]);
    let box_voxels = boxed.iter().fold(1u64, |n, &d| n.saturating_mul(d as u64));
    let what =
        format!("closing the foreground by a ball of radius {radius:.3e} ({boxed:?} voxels)");
    // The distance field (4 bytes), the dilation and the closing (1 each).
    crate::limits::check_items(what, box_voxels, 6)?;
    let [bz, by, bx] = boxed;
    let [_, ny, nx] = shape;
    // Box voxel (k, j, i) is grid voxel low + (k, j, i) − pad, where that is in the grid.
    let grid_of = |k: usize, j: usize, i: usize| -> Option<usize> {
        let at = [k, j, i];
        let g: [usize; 3] = std::array::from_fn(|a| (low[a] + at[a]).wrapping_sub(pad[a]));
        (g.iter().zip(&shape).all(|(&g, &n)| g < n)).then(|| (g[0] * ny + g[1]) * nx + g[2])
    };
    let in_box: Vec<bool> = (0..bz * by * bx)
        .into_par_iter()
        .map(|b| grid_of(b / (by * bx), b / bx % by, b % bx).is_some_and(|g| mask[g]))
        .collect();
    let limit = (radius * radius) as f32;
    let to_mask = squared_distances(boxed, voxel, |b| in_box[b]);
    drop(in_box);
    let dilated: Vec<bool> = to_mask.par_iter().map(|&d| d <= limit).collect();
    drop(to_mask);
    let to_outside = squared_distances(boxed, voxel, |b| !dilated[b]);
    drop(dilated);
    let mut closed = vec![false; mask.len()];
    for k in 0..bz {
        for j in 0..by {
            for i in 0..bx {
                if let Some(g) = grid_of(k, j, i) {
                    closed[g] = to_outside[(k * by + j) * bx + i] > limit;
                }
            }
        }
    }
    Ok(closed)
}

/// The radius of the largest ball inside `solid` (physical units, to the nearest voxel centre
/// outside it; beyond the grid is outside): how thick the object is. A shell whose cavity
/// opens to the outside through a hole is as thin as its layer; filled, it is as thick as its
/// smallest semi-axis.
pub(super) fn inscribed_radius(solid: &[bool], shape: [usize; 3], voxel: [f64; 3]) -> f64 {
    let Some((low, high)) = bounding_box(solid, shape) else {
        return 0.0;
    };
    // A large box is measured on every `stride`-th voxel: the radius is then known to a
    // stride, far finer than the thickness tests it serves, at an eighth of the cost or less.
    let voxels: usize = (0..3).map(|a| high[a] - low[a]).product();
    let stride = ((voxels as f64 / INSCRIBED_VOXELS).cbrt().ceil() as usize).max(1);
    // The strided box with one voxel of outside around it.
    let boxed = [0, 1, 2].map(|a| (high[a] - low[a]).div_ceil(stride) + 2);
    let [bz, by, bx] = boxed;
    let [_, ny, nx] = shape;
    let inside: Vec<bool> = (0..bz * by * bx)
        .into_par_iter()
        .map(|b| {
            let at = [b / (by * bx), b / bx % by, b % bx];
            let g: [usize; 3] =
                std::array::from_fn(|a| (low[a] + at[a] * stride).wrapping_sub(stride));
            let within = g.iter().zip(&shape).all(|(&g, &n)| g < n) && at.iter().all(|&c| c > 0);
            within && solid[(g[0] * ny + g[1]) * nx + g[2]]
        })
        .collect();
    let spacing = voxel.map(|v| v * stride as f64);
    let to_outside = squared_distances(boxed, spacing, |b| !inside[b]);
    let deepest = (to_outside.par_iter().zip(&inside))
        .filter(|(_, &i)| i)
        .map(|(&d, _)| d)
        .reduce(|| 0.0, f32::max);
    f64::from(deepest).sqrt()
}

/// The most voxels [`inscribed_radius`] measures on before it strides.
const INSCRIBED_VOXELS: f64 = (1 << 22) as f64;

/// The smallest box `[low, high)` (z, y, x) holding every voxel of `set` on a grid of `shape`;
/// `None` when it holds none.
pub(super) fn bounding_box(
    set: &[bool],
    [_, ny, nx]: [usize; 3],
) -> Option<([usize; 3], [usize; 3])> {
    let mut low = [usize::MAX; 3];
    let mut high = [0; 3];
    for (row, line) in set.chunks_exact(nx).enumerate() {
        let Some(first) = line.iter().position(|&s| s) else {
            continue;
        };
        let last = line.iter().rposition(|&s| s).expect("one is set");
        let (k, j) = (row / ny, row % ny);
        low = [low[0].min(k), low[1].min(j), low[2].min(first)];
        high = [
            high[0].max(k + 1),
            high[1].max(j + 1),
            high[2].max(last + 1),
        ];
    }
    (low[0] != usize::MAX).then_some((low, high))
}

/// The squared physical distance from each voxel's centre to the nearest voxel where `site`
/// holds (`f32::INFINITY` where none does): three passes of the 1-D transform, along x, y
/// and z.
fn squared_distances(
    shape: [usize; 3],
    voxel: [f64; 3],
    site: impl Fn(usize) -> bool + Sync,
) -> Vec<f32> {
    let [nz, ny, nx] = shape;
    let [dx, dy, dz] = voxel.map(|d| d as f32);
    let mut field: Vec<f32> = (0..nz * ny * nx)
        .into_par_iter()
        .map(|at| if site(at) { 0.0 } else { f32::INFINITY })
        .collect();
    // Along x: the rows are contiguous.
    field.par_chunks_mut(nx).for_each_init(
        || Envelope::new(nx),
        |envelope, row| envelope.transform(row, dx),
    );
    // Along y, plane by plane; along z, column block by column block: gathered into lines.
    let plane = ny * nx;
    field.par_chunks_mut(plane).for_each_init(
        || (Envelope::new(ny), vec![0.0; ny]),
        |(envelope, line), slab| {
            for i in 0..nx {
                (0..ny).for_each(|j| line[j] = slab[j * nx + i]);
                envelope.transform(line, dy);
                (0..ny).for_each(|j| slab[j * nx + i] = line[j]);
            }
        },
    );
    let columns: Vec<usize> = (0..plane).collect();
    let updated: Vec<(usize, Vec<f32>)> = columns
        .par_chunks(1024)
        .flat_map_iter(|block| {
            let mut envelope = Envelope::new(nz);
            let field = &field;
            block.iter().map(move |&c| {
                let mut line: Vec<f32> = (0..nz).map(|k| field[k * plane + c]).collect();
                envelope.transform(&mut line, dz);
                (c, line)
            })
        })
        .collect();
    for (c, line) in updated {
        (0..nz).for_each(|k| field[k * plane + c] = line[k]);
    }
    field
}

/// The lower envelope of parabolas of one line, with its buffers.
struct Envelope {
    /// Sites of the parabolas in the envelope, and where each starts to be the lowest.
    sites: Vec<usize>,
    starts: Vec<f32>,
    out: Vec<f32>,
}

impl Envelope {
    fn new(n: usize) -> Self {
        Self {
            sites: Vec::with_capacity(n),
            starts: Vec::with_capacity(n + 1),
            out: vec![0.0; n],
        }
    }

    /// `f(q) ← min_p (step (q − p))² + f(p)` over the line `f`, in place.
    fn transform(&mut self, f: &mut [f32], step: f32) {
        let w = step * step;
        self.sites.clear();
        self.starts.clear();
        // Where the parabolas of sites p and q (p < q) cross, in index units.
        let cross = |f: &[f32], p: usize, q: usize| {
            let (p, q, fp, fq) = (p as f32, q as f32, f[p], f[q]);
            ((fq + w * q * q) - (fp + w * p * p)) / (2.0 * w * (q - p))
        };
        for q in 0..f.len() {
            if f[q].is_infinite() {
                continue;
            }
            while let Some(&last) = self.sites.last() {
                let s = cross(f, last, q);
                if s <= *self.starts.last().expect("one start per site") {
                    self.sites.pop();
                    self.starts.pop();
                } else {
                    break;
                }
            }
            let start = match self.sites.last() {
                Some(&last) => cross(f, last, q),
                None => f32::NEG_INFINITY,
            };
            self.sites.push(q);
            self.starts.push(start);
        }
        if self.sites.is_empty() {
            return; // no site on this line: it stays infinite
        }
        let mut k = 0;
        for q in 0..f.len() {
            while k + 1 < self.sites.len() && self.starts[k + 1] < q as f32 {
                k += 1;
            }
            let p = self.sites[k];
            let d = q as f32 - p as f32;
            self.out[q] = w * d * d + f[p];
        }
        f.copy_from_slice(&self.out[..f.len()]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(shape: [usize; 3], inside: impl Fn(usize, usize, usize) -> bool) -> Vec<bool> {
        let [nz, ny, nx] = shape;
        (0..nz * ny * nx)
            .map(|at| inside(at / (ny * nx), at / nx % ny, at % nx))
            .collect()
    }

    #[test]
    fn distances_are_exact_and_anisotropic() {
        let shape = [5, 6, 7];
        let voxel = [1.0, 2.0, 3.0];
        let sites = [(1usize, 2usize, 3usize), (4, 5, 0)];
        let field = squared_distances(shape, voxel, |at| {
            sites.iter().any(|&(k, j, i)| at == (k * 6 + j) * 7 + i)
        });
        for (at, &found) in field.iter().enumerate() {
            let (k, j, i) = (at / 42, at / 7 % 6, at % 7);
            let brute = sites
                .iter()
                .map(|&(a, b, c)| {
                    let d = [
                        (i as f64 - c as f64) * 1.0,
                        (j as f64 - b as f64) * 2.0,
                        (k as f64 - a as f64) * 3.0,
                    ];
                    d.iter().map(|x| x * x).sum::<f64>()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                (f64::from(found) - brute).abs() < 1e-3,
                "{at}: {found} {brute}"
            );
        }
    }

    #[test]
    fn closing_fills_gaps_narrower_than_its_diameter_and_keeps_the_mask() {
        let shape = [9, 20, 20];
        let middle = |i: usize| (4 * 20 + 10) * 20 + i;
        // Two slabs 3 voxels apart: a radius of 2 bridges them, 1 does not.
        let mask = grid(shape, |_, _, i| {
            (3..8).contains(&i) || (11..16).contains(&i)
        });
        let bridged = closed(&mask, shape, [1.0; 3], 2.0).unwrap();
        assert!((8..11).all(|i| bridged[middle(i)]));
        let kept = closed(&mask, shape, [1.0; 3], 1.0).unwrap();
        assert!(!kept[middle(9)]);
        assert!(
            mask.iter().zip(&bridged).all(|(&m, &c)| !m || c),
            "the mask stays"
        );
        // Nothing grows outward: beyond the slabs stays empty.
        assert!(!bridged[middle(1)] && !bridged[middle(18)]);
        // Beyond the grid is background: two slabs lying along its border (y < 2) are not
        // closed onto it, and the ball passes by their ends there (the gap stays open at y = 0).
        let edge = grid(shape, |_, j, i| {
            j < 2 && ((3..8).contains(&i) || (11..16).contains(&i))
        });
        let closed_edge = closed(&edge, shape, [1.0; 3], 2.0).unwrap();
        assert!(!closed_edge[(4 * 20 + 2) * 20 + 9] && !closed_edge[(4 * 20) * 20 + 9]);
        assert!(edge.iter().zip(&closed_edge).all(|(&m, &c)| !m || c));
    }

    #[test]
    fn the_inscribed_ball_measures_thickness() {
        let shape = [12, 12, 12];
        let ball = grid(shape, |k, j, i| {
            let d = |c: usize| c as f64 - 5.5;
            (d(k).powi(2) + d(j).powi(2) + d(i).powi(2)).sqrt() < 5.0
        });
        let radius = inscribed_radius(&ball, shape, [1.0; 3]);
        // Voxel centres: the discrete ball is √19 deep along (3, 3, 1), not 5.
        assert!((19f64.sqrt() - radius).abs() < 1e-6, "{radius}");
        let sheet = grid(shape, |k, _, _| k == 5 || k == 6);
        assert!((inscribed_radius(&sheet, shape, [1.0; 3]) - 1.0).abs() < 1e-6);
    }
}
