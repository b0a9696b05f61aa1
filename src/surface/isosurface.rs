//! A closed surface found in a 3-D image: the boundary of the object the image shows (an
//! embryo, an organoid, a gut), as a triangle mesh, one frame at a time.
//!
//! Per volume, as TubULAR, ImSAnE and blender-tissue-cartography do it:
//!
//! 1. **Smooth** by a Gaussian of `σ` (physical units; [`Volume::smoothed`]).
//! 2. **Threshold** at a level `c`: given, or Otsu's (the level that maximizes the
//!    between-class variance `ω₀ω₁(μ₀ − μ₁)²` of a 256-bin histogram of the smoothed values).
//!    A probability map works at 0.5.
//! 3. **The object, of the right topology.** Drop the specks of `v > c` (components under
//!    [`SPECK_SHARE`] of it), close the rest by a ball of radius `r` (dilate, then erode, by
//!    an exact anisotropic Euclidean distance transform: `closing`) and keep the
//!    largest 6-connected component, with its holes filled: every voxel that the outside (the
//!    volume's border, 6-connected) cannot reach joins it. A hollow shell becomes a solid, so
//!    its outer boundary is the surface. `r` starts at none ([`IsosurfaceOptions::closing`])
//!    and grows from the largest voxel side by half, up to half the object's smallest extent,
//!    until the surface (steps 4–5) has at most [`IsosurfaceOptions::genus`] handles and the
//!    object is [`THICK`] (a shell whose cavity opens through a gap of its layer is as thin as
//!    the layer). That closes the gaps between nuclei and the holes a threshold opens where
//!    cells are dim, as morphological snakes or level sets do in TubULAR and ImSAnE, at the
//!    smallest scale that gives the topology. For genus 0 the radii are then tried again with
//!    the holes of every slice (along z, y and x) filled too: a cavity cut open by the stack's
//!    first slice is ringed in its slices. A porous foreground (more than `POROUS_GENUS` (8)
//!    handles at the first try: a nuclear label) is smoothed twice as wide first, when the
//!    smoothing is ours to choose.
//! 4. **Take the isosurface** `φ = 0` of `φ = c − v`, clamped to the component
//!    (`φ ≤ −ε` inside it, `φ ≥ ε` outside), by naive surface nets (the `fast-surface-nets`
//!    crate): a vertex per grid cell the surface crosses, at the mean of its edges' linear
//!    crossings, and two triangles per crossed grid edge. The volume is padded so that the
//!    surface is closed where the object touches the border.
//! 5. **Clean it to a manifold.** Before the isosurface, the solid is made well composed: a
//!    2 × 2 × 2 cell whose solid (or empty) voxels touch only along an edge or at a corner is
//!    filled, since one surface-nets vertex there would join two sheets. What remains
//!    non-manifold is split ([`crate::mesh::repair`]), and only the largest connected piece
//!    is kept.
//! 6. **Move to the middle of the layer.** A tissue is often a bright layer around a dark
//!    inside (an epithelium, a shell): filled, its surface is the layer's outer side. From
//!    each vertex `p` with outward normal `n`, the smoothed image is read inward along
//!    `p − t n` (steps of half the smallest voxel side, each crossing then bisected to a
//!    sixteenth): where it rises above the threshold (`t₀`) and where it falls below again
//!    (`t₁`). If it falls within a quarter of the object's smallest extent (its axis-aligned
//!    box), the layer's middle lies at depth `d = (t₀ + t₁)/2` below the vertex. Where that is
//!    so below at least a third (`SHELL_SHARE`) of the vertices, every vertex moves to `p − d n`:
//!    vertices over a gap take their neighbours' depths, ring by ring, and the depths are
//!    averaged over the neighbours five rounds (a whole layer) or about `(thickness / edge)²`
//!    rounds (nuclei, patches), so that neither noise nor the gaps fold the surface. A solid
//!    object, bright throughout or a layer only in places, keeps its boundary.
//! 7. **Smooth** by Taubin's λ|μ steps (twenty rounds, λ = 0.5, μ = −0.53; also before
//!    step 6, so that the staircase's normals do not scatter the depths): the voxel
//!    staircase goes, and so do the folds left where neighbours moved by different depths in
//!    step 6 (3078 of 679,444 faces turned inward on a 128 × 512 × 512 frame before, and the
//!    reference simplified from it pinched), without the shrinking of plain Laplacian steps.
//!    Edges whose triangles still face opposite ways are smoothed out where they are
//!    ([`crate::geometry::folds`]).
//!
//! The frames' meshes have their own vertices; `meshflow surface --shape closed` then tracks
//! one reference through them ([`crate::track`]), which makes the fixed connectivity.
//!
//! Surface nets come from a well-kept crate; Otsu's threshold, the flood fills and the table of
//! critical cells are a few lines each over our `(z, y, x)` grids and are written here.

use super::closing;
use super::reference::compact;
use crate::connection::vertex_normals;
use crate::geometry::folds::{folded_edges, smooth_out};
use crate::mesh::{repair, Mesh, UnionFind, VertexNeighbours};
use crate::volume::{Volume, VolumeError};
use fast_surface_nets::ndshape::{RuntimeShape, Shape};
use fast_surface_nets::{surface_nets, SurfaceNetsBuffer};
use nalgebra::Vector3;
use rayon::prelude::*;

/// The threshold of the volume: Otsu's, or a value of the smoothed image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Level {
    Otsu,
    Value(f64),
}

impl std::str::FromStr for Level {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" | "otsu" => Ok(Level::Otsu),
            other => match other.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(Level::Value(v)),
                _ => Err(format!("'{other}' is not a number or 'auto'")),
            },
        }
    }
}

/// How a frame's surface is found (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsosurfaceOptions {
    /// Gaussian smoothing, physical units; `None`: one voxel (the largest voxel size).
    pub smoothing: Option<f64>,
    pub level: Level,
    /// The genus the object's surface has: 0 (a sphere's topology: an embryo, an organoid)
    /// unless the object really has handles (step 3).
    pub genus: usize,
    /// The radius of the ball the foreground is closed by first (step 3), physical units;
    /// `None`: none, then as wide as the genus and the object's thickness need.
    pub closing: Option<f64>,
}

impl Default for IsosurfaceOptions {
    fn default() -> Self {
        Self {
            smoothing: None,
            level: Level::Otsu,
            genus: 0,
            closing: None,
        }
    }
}

/// What finding one frame's surface found: its report in `surface.json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FoundSurface {
    #[serde(skip)]
    pub positions: Vec<Vector3<f64>>,
    #[serde(skip)]
    pub faces: Vec<[u32; 3]>,
    /// The threshold used, in the image's values.
    pub threshold: f64,
    /// Voxels above it.
    pub foreground_voxels: usize,
    /// Voxels of the largest component, before its holes were filled.
    pub component_voxels: usize,
    /// `component_voxels / foreground_voxels`: how much of the foreground the surface bounds.
    pub component_share: f64,
    /// Voxels added by filling holes.
    pub filled_voxels: usize,
    /// Voxels of the component on the volume's border: the object leaves the field of view
    /// there (its surface is closed along the border).
    pub border_voxels: usize,
    /// The genus of the surface found (step 3): at most [`IsosurfaceOptions::genus`].
    pub genus: usize,
    /// The radius of the closing that sealed the layer's gaps (physical units; 0: none was
    /// needed), and the genus and share of each radius tried before it, in order.
    pub closing_radius: f64,
    /// Whether the slices' holes were filled too (a cavity open through a hole wider than
    /// any closing).
    pub slices_filled: bool,
    pub closings_tried: Vec<ClosingTried>,
    /// The Gaussian smoothing's σ used (physical units): as asked, or by default the largest
    /// voxel side, doubled for a porous foreground.
    pub smoothing: f64,
    /// Vertices moved to the middle of a bright layer (step 6), and the layer's median
    /// thickness there (0 when none moved).
    pub layer_vertices: usize,
    pub layer_thickness: f64,
    pub vertices: usize,
    #[serde(rename = "faces")]
    pub faces_count: usize,
}

/// One closing tried (step 3): its radius, whether slices were filled, the genus of the
/// surface it gave, the share of the voxels above the threshold that the object holds, and
/// the object's thickness (the radius of the largest ball inside it).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ClosingTried {
    pub radius: f64,
    /// The slices' holes filled too (the last pass for genus 0).
    pub slices_filled: bool,
    pub genus: i64,
    pub share: f64,
    pub thickness: f64,
}

/// How thick an object must be against its smallest extent for a closing to stop there: a
/// filled shell, a tube or a solid is half its smallest extent thick; a shell whose cavity
/// still opens to the outside through a gap is as thin as its layer (a twentieth).
pub const THICK: f64 = 0.15;

/// Why no surface was found in a volume.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IsosurfaceError {
    #[error(transparent)]
    Volume(#[from] VolumeError),
    #[error("the image is constant ({value}): there is no object to bound")]
    Constant { value: f64 },
    #[error("no voxel is above the threshold {threshold} (the image ranges over {min}–{max}): give --level below the object's brightness")]
    Empty { threshold: f64, min: f64, max: f64 },
    #[error("every voxel is above the threshold {threshold} (the image ranges over {min}–{max}): give --level above the background")]
    Full { threshold: f64, min: f64, max: f64 },
    #[error("the object ({voxels} voxels) is too small to bound: smooth less or lower --level")]
    TooSmall { voxels: usize },
    #[error("the closing radius must be a length of 0 or more, got {0}")]
    BadClosing(f64),
    #[error("the surface keeps genus {genus} (handles) up to a closing of radius {radius:.3e}, half the object's smallest extent: if the object has {genus} handles, give --genus {genus}; otherwise smooth more or raise --level")]
    Genus { genus: i64, radius: f64 },
    #[error(transparent)]
    TooLarge(#[from] crate::limits::OverBudget),
}

/// The surface of the object in `volume` (module docs), in the volume's physical coordinates.
pub fn find_surface(
    volume: &Volume,
    options: &IsosurfaceOptions,
) -> Result<FoundSurface, IsosurfaceError> {
    find_surface_consuming(volume.clone(), options)
}

/// [`find_surface`] of a volume that is not needed afterwards: it is smoothed in place, so
/// that the original and its smoothed copy are never held together (a frame of a recording
/// read one at a time).
pub fn find_surface_consuming(
    volume: Volume,
    options: &IsosurfaceOptions,
) -> Result<FoundSurface, IsosurfaceError> {
    check_memory(&volume)?;
    let mut sigma = options.smoothing.unwrap_or(volume.voxel_size().max());
    let widest = POROUS_SMOOTHING * volume.voxel_size().min();
    let (mut smoothed, mut threshold) = smoothed_threshold(volume, sigma, options)?;
    // A porous foreground (a nuclear label: nuclei with gaps between them) is smoothed more
    // when the smoothing is ours to choose: twice as wide, by smoothing again by √3 σ.
    for resmoothing in 0.. {
        let may_resmooth = options.smoothing.is_none()
            && options.genus == 0
            && resmoothing < RESMOOTHINGS
            && 2.0 * sigma <= widest;
        if let Some(found) = surface_of_smoothed(&smoothed, threshold, options, may_resmooth)? {
            return Ok(FoundSurface {
                smoothing: sigma,
                ..found
            });
        }
        (smoothed, threshold) = smoothed_threshold(smoothed, 3f64.sqrt() * sigma, options)?;
        sigma *= 2.0;
    }
    unreachable!("the loop returns once it may not smooth again")
}

/// The smoothed copy, the masks, the labels and the padded distance field, against the
/// memory limit.
fn check_memory(volume: &Volume) -> Result<(), IsosurfaceError> {
    let what = format!("finding the surface in {:?} voxels", volume.shape());
    let voxels = volume.values().len() as u64;
    Ok(crate::limits::check_items(what, voxels, BYTES_PER_VOXEL)?)
}

/// Steps 3 to 7 (module docs) on the smoothed volume and its threshold; `None` where the
/// foreground is porous and `may_resmooth`.
fn surface_of_smoothed(
    smoothed: &Volume,
    threshold: f32,
    options: &IsosurfaceOptions,
    may_resmooth: bool,
) -> Result<Option<FoundSurface>, IsosurfaceError> {
    let values = smoothed.values();
    let t = f64::from(threshold);
    let foreground: Vec<bool> = values.par_iter().map(|&v| v > threshold).collect();
    let foreground_voxels = foreground.par_iter().filter(|&&f| f).count();
    let object = Object::of_foreground(
        &foreground,
        foreground_voxels,
        options,
        (smoothed, threshold),
        may_resmooth,
    )?;
    drop(foreground);
    let Some(object) = object else {
        return Ok(None);
    };
    let (mut positions, faces, mesh) = object.surface;
    let neighbours = VertexNeighbours::open(&mesh);
    // Smoothed before the layer's middle is looked for along the normals: the voxel
    // staircase's normals would scatter vertices moved by a few voxels (the middle of a layer
    // of nuclei lies half a nucleus below the surface closed over them).
    taubin_smooth(&mut positions, &neighbours, TAUBIN_ROUNDS);
    let (layer_vertices, layer_thickness) = to_layer_middle(
        &mut positions,
        &mesh,
        &neighbours,
        smoothed,
        f64::from(threshold),
    );
    taubin_smooth(&mut positions, &neighbours, TAUBIN_ROUNDS);
    let folded = |x: &[Vector3<f64>]| folded_edges(&mesh, x);
    smooth_out(
        &mesh,
        &neighbours,
        &mut positions,
        UNFOLD_ROUNDS,
        UNFOLD_RINGS,
        folded,
        |_, x| x,
    );
    Ok(Some(FoundSurface {
        smoothing: 0.0, // set by the caller
        genus: object.genus,
        closing_radius: object.radius,
        slices_filled: object.slices_filled,
        closings_tried: object.tried,
        layer_vertices,
        layer_thickness,
        vertices: positions.len(),
        faces_count: faces.len(),
        positions,
        faces,
        threshold: t,
        foreground_voxels,
        component_voxels: object.component_voxels,
        component_share: object.share,
        filled_voxels: object.filled_voxels,
        border_voxels: object.border_voxels,
    }))
}

/// The object found (step 3) and its surface (steps 4 and 5), and how it was made.
struct Object {
    /// The largest manifold piece of its surface: positions, faces, mesh.
    surface: Piece,
    genus: usize,
    radius: f64,
    slices_filled: bool,
    /// The radius of the largest ball inside it ([`closing::inscribed_radius`]).
    thickness: f64,
    tried: Vec<ClosingTried>,
    component_voxels: usize,
    share: f64,
    filled_voxels: usize,
    border_voxels: usize,
}

impl Object {
    /// The object in the foreground (step 3): its specks dropped, closed by a ball, its largest
    /// component with holes filled, and the largest manifold piece of its surface; with at
    /// most `options.genus` handles. The closing's radius starts at `options.closing` (by
    /// default none: a clean layer needs no closing, and costs none), and where the genus is
    /// wrong or the object is not [`THICK`] (its cavity open through a gap of the layer, or
    /// only one nucleus of many), it goes to the largest voxel side, then grows by half, up to
    /// half the foreground's smallest extent, where closing nears the convex hull. For genus 0
    /// the same radii are then tried with the slices' holes filled too. Past that, the
    /// thickest object of the right genus is kept.
    ///
    /// `None` where `may_resmooth` and the first try has more than [`POROUS_GENUS`] handles:
    /// the foreground is porous, and is better smoothed more than closed.
    fn of_foreground(
        foreground: &[bool],
        foreground_voxels: usize,
        options: &IsosurfaceOptions,
        (volume, threshold): (&Volume, f32),
        may_resmooth: bool,
    ) -> Result<Option<Self>, IsosurfaceError> {
        if let Some(r) = options.closing.filter(|r| !(r.is_finite() && *r >= 0.0)) {
            return Err(IsosurfaceError::BadClosing(r));
        }
        let shape = volume.shape();
        let voxel = volume.voxel_size();
        let kept = without_specks(foreground, shape);
        let extent = closing::bounding_box(&kept, shape)
            .map(|(low, high)| {
                let sides = [0, 1, 2].map(|a| (high[a] - low[a]) as f64);
                (Vector3::new(sides[2], sides[1], sides[0]).component_mul(&voxel)).min()
            })
            .unwrap_or(0.0);
        // After no closing, the first: the largest voxel side (a tunnel of noise is sealed
        // at once, and the object keeps its shape), then wider by half each time.
        let first = voxel.max();
        let next = |r: f64| match r > 0.0 {
            true => 1.5 * r,
            false => first,
        };
        let radii = std::iter::successors(Some(options.closing.unwrap_or(0.0)), |&r| Some(next(r)))
            .enumerate()
            .take_while(|&(i, r)| i == 0 || (r > 0.0 && r <= 0.5 * extent))
            .map(|(_, r)| r);
        let mut tried: Vec<ClosingTried> = Vec::new();
        let mut best: Option<Object> = None;
        // For genus 0, a last pass fills the slices' holes too: a cavity opened by a hole
        // wider than any closing (a cut through the lumen) is still ringed in its slices.
        let radii: Vec<f64> = radii.collect();
        let slice_filled = radii.iter().map(|&r| (r, true));
        let passes =
            (radii.iter().map(|&r| (r, false))).chain(slice_filled.filter(|_| options.genus == 0));
        for (radius, fill_slices) in passes {
            let closed;
            let mask: &[bool] = match radius > 0.0 {
                true => {
                    closed = closing::closed(&kept, shape, voxel.into(), radius)?;
                    &closed
                }
                false => &kept,
            };
            let Some(object) = Self::of_mask(
                mask,
                foreground,
                foreground_voxels,
                (radius, fill_slices),
                volume,
                threshold,
            ) else {
                continue;
            };
            if may_resmooth && tried.is_empty() && object.genus > POROUS_GENUS {
                return Ok(None);
            }
            tried.push(ClosingTried {
                radius,
                slices_filled: fill_slices,
                genus: object.genus as i64,
                share: object.share,
                thickness: object.thickness,
            });
            if object.genus > options.genus {
                continue;
            }
            if object.thickness >= THICK * extent {
                return Ok(Some(Self { tried, ..object }));
            }
            if best.as_ref().is_none_or(|b| object.thickness > b.thickness) {
                best = Some(object);
            }
        }
        match best {
            Some(object) => Ok(Some(Self { tried, ..object })),
            // No closing left a surface to bound: the object is a voxel or a sliver.
            None if tried.is_empty() => Err(IsosurfaceError::TooSmall {
                voxels: largest_component(shape, |at| kept[at]).1,
            }),
            None => Err(IsosurfaceError::Genus {
                genus: tried.iter().map(|t| t.genus).min().unwrap_or(0),
                radius: tried.last().map_or(0.0, |t| t.radius),
            }),
        }
    }

    /// The largest component of `mask` (the foreground closed by `radius`), holes filled
    /// (with `fill_slices`, the slices' holes too) and made well composed, and its surface;
    /// `None` where nothing is left of it.
    fn of_mask(
        mask: &[bool],
        foreground: &[bool],
        foreground_voxels: usize,
        (radius, fill_slices): (f64, bool),
        volume: &Volume,
        threshold: f32,
    ) -> Option<Self> {
        let shape = volume.shape();
        let (component, component_voxels, _) = largest_component(shape, |at| mask[at]);
        let border_voxels = on_border(shape).filter(|&at| component[at]).count();
        let held = (component.par_iter().zip(foreground))
            .filter(|(&c, &f)| c && f)
            .count();
        let mut solid = filled(&component, shape);
        drop(component);
        if fill_slices {
            with_slice_holes_filled(&mut solid, shape);
            solid = filled(&solid, shape);
        }
        well_composed(&mut solid, shape);
        let filled_voxels = solid.iter().filter(|&&s| s).count() - component_voxels;
        let thickness = closing::inscribed_radius(&solid, shape, volume.voxel_size().into());
        let (positions, faces) = nets(volume.values(), &solid, threshold, volume);
        drop(solid);
        let surface = largest_manifold_piece(positions, &faces).filter(|(_, f, _)| f.len() >= 4)?;
        let genus = (2 - surface.2.euler_characteristic()).max(0) as usize / 2;
        Some(Self {
            surface,
            genus,
            radius,
            slices_filled: fill_slices,
            thickness,
            tried: Vec::new(),
            component_voxels,
            share: held as f64 / foreground_voxels as f64,
            filled_voxels,
            border_voxels,
        })
    }
}

/// The foreground without its specks: components holding less than [`SPECK_SHARE`] of it
/// (noise, beads, debris), which a closing would otherwise bridge to the object. Pieces of
/// an object (nuclei, patches of a layer: a few hundred to a few thousand of them) stay, to be
/// joined by the closing.
fn without_specks(foreground: &[bool], shape: [usize; 3]) -> Vec<bool> {
    let total = foreground.par_iter().filter(|&&f| f).count();
    let mut kept = vec![false; foreground.len()];
    let mut seen = vec![false; foreground.len()];
    for start in 0..foreground.len() {
        if seen[start] || !foreground[start] {
            continue;
        }
        let size = spread([start], shape, &mut seen, true, |at| foreground[at]);
        if size as f64 >= SPECK_SHARE * total as f64 {
            spread([start], shape, &mut kept, true, |at| foreground[at]);
        }
    }
    kept
}

/// Components of the foreground below this share of it are specks ([`without_specks`]): a
/// nucleus of 2000 is a share of 5e-4, a bead of 30 voxels beside an embryo's layer of 10⁵ is
/// 3e-4.
pub const SPECK_SHARE: f64 = 2e-4;

/// Below this share of the foreground, the largest component is reported: the object split,
/// or the threshold caught other things.
pub const SPLIT_SHARE: f64 = 0.8;

impl FoundSurface {
    /// What a surface could still be made of but looks wrong: the object touching the
    /// volume's border, or holding less than [`SPLIT_SHARE`] of the foreground.
    pub fn warnings(&self) -> Vec<String> {
        let mut warnings = Vec::new();
        if self.border_voxels > 0 {
            warnings.push(format!(
                "the object touches the volume's border at {} voxels: it leaves the field of view, and its surface is closed along the border there",
                self.border_voxels
            ));
        }
        if self.component_share < SPLIT_SHARE {
            warnings.push(format!(
                "the largest object holds only {:.1} % of the voxels above the threshold: the object may have split, or the threshold caught other things (try --level or --smooth)",
                100.0 * self.component_share
            ));
        }
        warnings
    }
}

/// The voxels on the faces of a grid of `shape` (`(n_z, n_y, n_x)`, C order), each once:
/// the first and last planes whole, and of the planes between, the first and last rows whole
/// and the ends of the rows between.
fn on_border([nz, ny, nx]: [usize; 3]) -> impl Iterator<Item = usize> {
    let plane = ny * nx;
    (0..nz).flat_map(move |k| {
        let whole = k == 0 || k + 1 == nz;
        (0..ny).flat_map(move |j| {
            let row = k * plane + j * nx;
            let all = whole || j == 0 || j + 1 == ny;
            let ends = [row, row + nx - 1];
            let inner = (!all).then_some(ends.into_iter().take(if nx > 1 { 2 } else { 1 }));
            let full = all.then_some(row..row + nx);
            inner
                .into_iter()
                .flatten()
                .chain(full.into_iter().flatten())
        })
    })
}

/// Steps 1 and 2 (module docs): the smoothed volume and its threshold; an error where the
/// image is constant or the threshold leaves no voxel above it, or none below.
pub(super) fn smoothed_threshold(
    volume: Volume,
    sigma: f64,
    options: &IsosurfaceOptions,
) -> Result<(Volume, f32), IsosurfaceError> {
    let smoothed = volume.into_smoothed(sigma)?;
    let values = smoothed.values();
    let (min, max) = values
        .par_iter()
        .fold(
            || (f32::INFINITY, f32::NEG_INFINITY),
            |(lo, hi), &v| (lo.min(v), hi.max(v)),
        )
        .reduce(
            || (f32::INFINITY, f32::NEG_INFINITY),
            |(a, b), (c, d)| (a.min(c), b.max(d)),
        );
    if min >= max {
        return Err(IsosurfaceError::Constant {
            value: f64::from(min),
        });
    }
    let threshold = match options.level {
        Level::Otsu => otsu(values, min, max),
        Level::Value(v) => v as f32,
    };
    let (t, min, max) = (f64::from(threshold), f64::from(min), f64::from(max));
    if max <= t {
        return Err(IsosurfaceError::Empty {
            threshold: t,
            min,
            max,
        });
    }
    if min > t {
        return Err(IsosurfaceError::Full {
            threshold: t,
            min,
            max,
        });
    }
    Ok((smoothed, threshold))
}

/// Moves each vertex to the middle of the bright layer below it, where there is one (module
/// docs, step 6): how many moved, and the median thickness of the layer at them.
fn to_layer_middle(
    positions: &mut [Vector3<f64>],
    mesh: &Mesh,
    neighbours: &VertexNeighbours,
    smoothed: &Volume,
    threshold: f64,
) -> (usize, f64) {
    let normals = vertex_normals(mesh, positions);
    let (low, high) = positions.iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    let reach = 0.25 * (high - low).min();
    let step = LAYER_STEP * smoothed.voxel_size().min();
    let bright = |p: Vector3<f64>| smoothed.sample(&p).is_some_and(|v| v > threshold);
    // (depth of the layer's middle, thickness) below each vertex, where there is a layer.
    let layers: Vec<Option<(f64, f64)>> = (positions.par_iter().zip(&normals))
        .map(|(p, n)| {
            let at = |t: f64| bright(p - t * n);
            let enter = first_crossing(0.0, reach, step, at)?;
            let leave = first_crossing(enter, reach, step, |t| !at(t))?;
            Some((0.5 * (enter + leave), leave - enter))
        })
        .collect();
    let thicknesses: Vec<f64> = layers.iter().flatten().map(|&(_, t)| t).collect();
    if thicknesses.is_empty() {
        return (0, 0.0); // a solid object keeps its boundary
    }
    // Where no layer is below a vertex (a gap between nuclei, a dim cell), its depth comes
    // from its neighbours', ring by ring: a vertex left on the outside there would fold the
    // surface against its neighbours in the layer.
    let mut depths: Vec<Option<f64>> = layers.iter().map(|l| l.map(|(d, _)| d)).collect();
    while depths.iter().any(Option::is_none) {
        let next: Vec<Option<f64>> = (0..depths.len())
            .map(|i| {
                depths[i].or_else(|| {
                    let known = neighbours.of(i).iter().filter_map(|&j| depths[j as usize]);
                    let (sum, count) = known.fold((0.0, 0.0), |(s, c), d| (s + d, c + 1.0));
                    (count > 0.0).then(|| sum / count)
                })
            })
            .collect();
        if next == depths {
            break; // a piece without any layer: it stays
        }
        depths = next;
    }
    // The depths averaged over each vertex's neighbours a few times: noise in where the layer
    // ends must not fold the surface. Where the layer is found below less than
    // [`WHOLE_LAYER`] of the vertices (nuclei, dim cells), over about the layer's thickness
    // (averaging diffuses over about the square root of its rounds in edges): the depths
    // filled in at the gaps, and the bumps of a layer of nuclei, must not fold it either.
    // A solid object seen as a layer here and there (a dim yolk below part of a tissue):
    // moving only those parts, or all by their depths, would make its surface jump from frame
    // to frame as the parts change.
    if (thicknesses.len() as f64) < SHELL_SHARE * positions.len() as f64 {
        return (0, 0.0);
    }
    let thickness = crate::statistics::median(thicknesses.clone());
    let edge = crate::geometry::mean_edge_length_at(mesh, positions);
    let rounds = match thicknesses.len() as f64 >= WHOLE_LAYER * positions.len() as f64 {
        true => LAYER_SMOOTHING,
        false => ((thickness / edge).powi(2) as usize).clamp(LAYER_SMOOTHING, MAX_LAYER_SMOOTHING),
    };
    let mut depths: Vec<f64> = depths.into_iter().map(|d| d.unwrap_or(0.0)).collect();
    for _ in 0..rounds {
        depths = (0..depths.len())
            .map(|i| {
                let around = neighbours.of(i);
                let sum: f64 = around.iter().map(|&j| depths[j as usize]).sum();
                (depths[i] + sum) / (1 + around.len()) as f64
            })
            .collect();
    }
    for ((p, n), depth) in positions.iter_mut().zip(&normals).zip(&depths) {
        *p -= *depth * n;
    }
    (thicknesses.len(), thickness)
}

/// Taubin's λ|μ smoothing (Taubin 1995, "A signal processing approach to fair surface
/// design"): `rounds` pairs of umbrella steps `x_i += w (x̄_i − x_i)`, `x̄_i` the mean of
/// the neighbours, with `w = λ` and then `w = μ`. It removes the voxel staircase and the small
/// folds left where neighbouring vertices moved to the layer's middle by different depths,
/// without shrinking the surface as plain Laplacian smoothing does (pass band `k = 1/λ + 1/μ
/// ≈ 0.11`).
fn taubin_smooth(positions: &mut [Vector3<f64>], neighbours: &VertexNeighbours, rounds: usize) {
    let mut moved = positions.to_vec();
    for _ in 0..rounds {
        for weight in [TAUBIN_LAMBDA, TAUBIN_MU] {
            let from = &*positions;
            moved.par_iter_mut().enumerate().for_each(|(i, out)| {
                let around = neighbours.of(i);
                if around.is_empty() {
                    return;
                }
                let sum: Vector3<f64> = around.iter().map(|&j| from[j as usize]).sum();
                let mean = sum / around.len() as f64;
                *out = from[i] + weight * (mean - from[i]);
            });
            positions.copy_from_slice(&moved);
        }
    }
}

/// The most rounds of smoothing out the folds the move to the layer's middle leaves (step 7),
/// and the rings around each fold it moves ([`crate::geometry::folds`]): where a surface
/// closed over nuclei is concave between them (creases where the closing meets a nucleus), a
/// move inward along the normals crosses neighbours over.
const UNFOLD_ROUNDS: usize = 100;
const UNFOLD_RINGS: usize = 2;

/// Taubin's weights and rounds (module docs, step 7): twenty rounds unfold the noisiest test
/// shell (`tests/isosurface.rs`), ten left two faces folded.
const TAUBIN_LAMBDA: f64 = 0.5;
const TAUBIN_MU: f64 = -0.53;
const TAUBIN_ROUNDS: usize = 20;

/// The first `t` in `[from, to]` where `holds`, found in steps of `step` and then refined by
/// [`CROSSING_BISECTIONS`] bisections between the last step where it did not hold and the
/// first where it does (to `step / 2^CROSSING_BISECTIONS`); `from` itself where it holds.
fn first_crossing(from: f64, to: f64, step: f64, holds: impl Fn(f64) -> bool) -> Option<f64> {
    if holds(from) {
        return Some(from);
    }
    let steps = ((to - from) / step).floor() as usize;
    let first = (1..=steps).find(|&s| holds(from + s as f64 * step))?;
    let (mut outside, mut inside) = (from + (first - 1) as f64 * step, from + first as f64 * step);
    for _ in 0..CROSSING_BISECTIONS {
        let middle = 0.5 * (outside + inside);
        match holds(middle) {
            true => inside = middle,
            false => outside = middle,
        }
    }
    Some(inside)
}

/// The layer march's step, in smallest voxel sides: after smoothing by a voxel the layer is
/// wider than that, so no layer is stepped over.
const LAYER_STEP: f64 = 0.5;

/// Bisections refining each crossing of the layer march: to a sixteenth of a voxel.
const CROSSING_BISECTIONS: usize = 3;

/// Whether the voxels `set` (bit `i + 2j + 4k` of a 2 × 2 × 2 cell's corners) fall apart into
/// several face-connected pieces within the cell.
fn split_within_cell(set: u8) -> bool {
    let Some(start) = (0..8).find(|&c| set & (1 << c) != 0) else {
        return false;
    };
    let mut reached = 1u8 << start;
    loop {
        let grown = (0..8)
            .filter(|&c| reached & (1 << c) != 0)
            .flat_map(|c| [c ^ 1, c ^ 2, c ^ 4])
            .fold(reached, |r, n| r | (set & (1 << n)));
        if grown == reached {
            return reached != set;
        }
        reached = grown;
    }
}

/// Makes `solid` well composed: no 2 × 2 × 2 cell whose solid or empty corners fall apart
/// within it (pieces touching along an edge or at a corner only), where one surface-nets vertex
/// would join two sheets and the surface would not be a manifold. Such a cell is filled; cells
/// on the volume's border keep their outside (the padding is empty).
fn well_composed(solid: &mut [bool], [nz, ny, nx]: [usize; 3]) {
    let critical: Vec<bool> = (0..=255u8)
        .map(|set| split_within_cell(set) || split_within_cell(!set))
        .collect();
    let at = |k: usize, j: usize, i: usize| (k * ny + j) * nx + i;
    for _ in 0..WELL_COMPOSED_PASSES {
        let mut changed = false;
        for k in 0..nz.saturating_sub(1) {
            for j in 0..ny.saturating_sub(1) {
                for i in 0..nx.saturating_sub(1) {
                    let corners = (0..8).map(|c| at(k + (c >> 2), j + (c >> 1 & 1), i + (c & 1)));
                    let set = corners
                        .clone()
                        .enumerate()
                        .fold(0u8, |set, (c, v)| set | (u8::from(solid[v]) << c));
                    if critical[set as usize] {
                        corners.for_each(|v| solid[v] = true);
                        changed = true;
                    }
                }
            }
        }
        if !changed {
            return;
        }
    }
}

/// The most passes [`well_composed`] makes (each fills what the one before left critical).
const WELL_COMPOSED_PASSES: usize = 8;

/// More handles than this at the first closing tried: the foreground is porous (nuclei with
/// gaps between them), and is smoothed twice as wide, [`RESMOOTHINGS`] times at most. A
/// neural-tube organoid's nuclear label has 35 handles smoothed by a voxel, 3 by two.
const POROUS_GENUS: usize = 8;
const RESMOOTHINGS: usize = 1;

/// The widest smoothing a porous foreground gets, in smallest voxel sides: wider would blur a
/// layer across its thickness where voxels are long in z (a shell of nuclei in voxels 1 × 1 × 3
/// lost its layer at σ = 6).
const POROUS_SMOOTHING: f64 = 2.5;

/// The share of vertices with a layer below them above which the layer is whole, not nuclei
/// or patches ([`to_layer_middle`]).
const WHOLE_LAYER: f64 = 0.9;

/// The share of vertices with a layer below them under which the object is solid and keeps
/// its boundary ([`to_layer_middle`]). A shell of nuclei shows a layer below half of them, a
/// patchy one below 85 %; a real embryo whose yolk is dim in places, below 16 %.
const SHELL_SHARE: f64 = 1.0 / 3.0;

/// Rounds of neighbour averaging of the layer depths: at least, and at most.
const LAYER_SMOOTHING: usize = 5;
const MAX_LAYER_SMOOTHING: usize = 400;

/// Otsu's threshold of `values` in `[min, max]` from a 256-bin histogram: the upper edge of
/// the bin that maximizes the between-class variance.
pub fn otsu(values: &[f32], min: f32, max: f32) -> f32 {
    const BINS: usize = 256;
    let width = (max - min) / BINS as f32;
    let histogram = values
        .par_chunks(1 << 16)
        .map(|chunk| {
            let mut histogram = [0u64; BINS];
            for &v in chunk {
                histogram[(((v - min) / width) as usize).min(BINS - 1)] += 1;
            }
            histogram
        })
        .reduce(
            || [0u64; BINS],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
                a
            },
        );
    let centre = |b: usize| f64::from(min) + (b as f64 + 0.5) * f64::from(width);
    let total = values.len() as f64;
    let sum: f64 = (0..BINS).map(|b| histogram[b] as f64 * centre(b)).sum();
    let (mut below, mut below_sum) = (0.0, 0.0);
    let (mut best, mut best_bin) = (-1.0, 0);
    for (b, &count) in histogram.iter().enumerate().take(BINS - 1) {
        below += count as f64;
        below_sum += count as f64 * centre(b);
        let above = total - below;
        if below == 0.0 || above == 0.0 {
            continue;
        }
        let difference = below_sum / below - (sum - below_sum) / above;
        let between = below * above * difference * difference;
        if between > best {
            (best, best_bin) = (between, b);
        }
    }
    min + width * (best_bin + 1) as f32
}

/// Marks `label` on the voxels 6-connected to `seeds` through voxels where `passable` holds
/// and `labels` is still unmarked (`T::default()`); returns how many it marked. A scanline
/// fill: each popped seed marks its whole run along x, and the runs above and below it
/// (y ± 1, z ± 1) are pushed once each, so memory moves row by row and no voxel index is
/// divided more than once per run.
fn spread<T: Copy + PartialEq + Default>(
    seeds: impl IntoIterator<Item = usize>,
    [nz, ny, nx]: [usize; 3],
    labels: &mut [T],
    label: T,
    passable: impl Fn(usize) -> bool,
) -> usize {
    let plane = ny * nx;
    let free = |labels: &[T], at: usize| labels[at] == T::default() && passable(at);
    let mut stack: Vec<usize> = seeds.into_iter().collect();
    let mut marked = 0;
    while let Some(at) = stack.pop() {
        if !free(labels, at) {
            continue;
        }
        let row = at - at % nx;
        let (mut low, mut high) = (at, at + 1);
        while low > row && free(labels, low - 1) {
            low -= 1;
        }
        while high < row + nx && free(labels, high) {
            high += 1;
        }
        labels[low..high].fill(label);
        marked += high - low;
        let (k, j) = (at / plane, at / nx % ny);
        let rows = [
            (j > 0).then(|| row - nx),
            (j + 1 < ny).then(|| row + nx),
            (k > 0).then(|| row - plane),
            (k + 1 < nz).then(|| row + plane),
        ];
        for next in rows.into_iter().flatten() {
            let mut in_run = false;
            for n in next + (low - row)..next + (high - row) {
                let open = free(labels, n);
                if open && !in_run {
                    stack.push(n);
                }
                in_run = open;
            }
        }
    }
    marked
}

/// The voxels 6-connected to `seeds` through voxels where `passable` holds.
fn flood(
    seeds: impl IntoIterator<Item = usize>,
    passable: impl Fn(usize) -> bool,
    shape: [usize; 3],
) -> Vec<bool> {
    let mut reached = vec![false; shape.iter().product()];
    spread(seeds, shape, &mut reached, true, passable);
    reached
}

/// The largest 6-connected component of the voxels where `inside` holds, its size, and the
/// size of every component. Sizes are found with one mask of the voxels seen, which is then
/// cleared and the largest grown again: one byte a voxel instead of a four-byte label each.
fn largest_component(
    shape: [usize; 3],
    inside: impl Fn(usize) -> bool,
) -> (Vec<bool>, usize, Vec<usize>) {
    let mut seen = vec![false; shape.iter().product()];
    let (mut best, mut best_size) = (None, 0);
    let mut sizes = Vec::new();
    for start in 0..seen.len() {
        if seen[start] || !inside(start) {
            continue;
        }
        let size = spread([start], shape, &mut seen, true, &inside);
        sizes.push(size);
        if size > best_size {
            (best, best_size) = (Some(start), size);
        }
    }
    seen.fill(false);
    if let Some(start) = best {
        spread([start], shape, &mut seen, true, &inside);
    }
    (seen, best_size, sizes)
}

/// `object` with its holes filled: every voxel the border cannot reach through the
/// background.
fn filled(object: &[bool], shape: [usize; 3]) -> Vec<bool> {
    let mut solid = flood(on_border(shape), |at| !object[at], shape);
    solid.iter_mut().for_each(|s| *s = !*s);
    solid
}

/// `solid` with the holes of its slices filled, along each axis in turn: every voxel of a
/// slice that the slice's border cannot reach through empty voxels (4-connected) joins it. A
/// cavity open to the outside through a hole too wide to close (an organoid's lumen cut open
/// by the stack's first slice, a cup) is closed where a slice rings it.
fn with_slice_holes_filled(solid: &mut [bool], shape: [usize; 3]) {
    for axis in 0..3 {
        let [a, b] = match axis {
            0 => [1, 2],
            1 => [0, 2],
            _ => [0, 1],
        };
        let (na, nb) = (shape[a], shape[b]);
        let index = |s: usize, i: usize, j: usize| {
            let mut at = [0; 3];
            (at[axis], at[a], at[b]) = (s, i, j);
            (at[0] * shape[1] + at[1]) * shape[2] + at[2]
        };
        let fills: Vec<Vec<usize>> = (0..shape[axis])
            .into_par_iter()
            .map(|s| {
                let empty = |i: usize, j: usize| !solid[index(s, i, j)];
                let mut outside = vec![false; na * nb];
                let mut stack: Vec<(usize, usize)> = (0..na)
                    .flat_map(|i| [(i, 0), (i, nb - 1)])
                    .chain((0..nb).flat_map(|j| [(0, j), (na - 1, j)]))
                    .collect();
                while let Some((i, j)) = stack.pop() {
                    if outside[i * nb + j] || !empty(i, j) {
                        continue;
                    }
                    outside[i * nb + j] = true;
                    let next = [
                        (i > 0).then(|| (i - 1, j)),
                        (i + 1 < na).then(|| (i + 1, j)),
                        (j > 0).then(|| (i, j - 1)),
                        (j + 1 < nb).then(|| (i, j + 1)),
                    ];
                    stack.extend(next.into_iter().flatten());
                }
                (0..na * nb)
                    .filter(|&c| !outside[c] && empty(c / nb, c % nb))
                    .map(|c| index(s, c / nb, c % nb))
                    .collect()
            })
            .collect();
        fills.into_iter().flatten().for_each(|at| solid[at] = true);
    }
}

/// What finding a surface holds per voxel, bounded: the volume and its smoothed copy (8 bytes;
/// 4 where it is smoothed in place), three masks (3) and the distance field over the object's
/// box (at most 4): 15 bytes, within the 24 budgeted when the components took u32 labels.
const BYTES_PER_VOXEL: u64 = 24;

/// Cells of padding around the volume: the surface closes inside them.
const PAD: usize = 2;

/// Surface nets of `φ = threshold − v` clamped to `solid`, in `volume`'s coordinates. Only
/// the solid's bounding box, padded by [`PAD`], is handed to surface nets: every cell the
/// surface crosses has a solid corner, so it lies within one voxel of the box, and the
/// padding holds the image's own values where the volume has them (the same mesh as over the
/// whole volume, at the cost of the object's box).
fn nets(
    values: &[f32],
    solid: &[bool],
    threshold: f32,
    volume: &Volume,
) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let [nz, ny, nx] = volume.shape();
    let Some((low, high)) = closing::bounding_box(solid, [nz, ny, nx]) else {
        return (Vec::new(), Vec::new());
    };
    // The padded box in volume coordinates (z, y, x), possibly beyond the volume.
    let start = low.map(|c| c as i64 - PAD as i64);
    let extent = [0, 1, 2].map(|a| high[a] - low[a] + 2 * PAD);
    let dims = [extent[2], extent[1], extent[0]].map(|d| d as u32);
    let shape = RuntimeShape::<u32, 3>::new(dims);
    // The smallest |φ| clamped to: a tenth of the image's typical contrast is far below a level
    // crossing and above round-off.
    let epsilon = 1e-3 * (threshold.abs() + 1e-6);
    let mut sdf = vec![1.0f32; shape.usize()];
    let within = |c: i64, n: usize| (c >= 0 && (c as usize) < n).then_some(c as usize);
    for (row, cells) in sdf.chunks_exact_mut(extent[2]).enumerate() {
        let (dk, dj) = (row / extent[1], row % extent[1]);
        let (Some(k), Some(j)) = (
            within(start[0] + dk as i64, nz),
            within(start[1] + dj as i64, ny),
        ) else {
            continue;
        };
        for (di, cell) in cells.iter_mut().enumerate() {
            let Some(i) = within(start[2] + di as i64, nx) else {
                continue;
            };
            let at = (k * ny + j) * nx + i;
            let phi = threshold - values[at];
            *cell = match solid[at] {
                true => phi.min(-epsilon),
                false => phi.max(epsilon),
            };
        }
    }
    let mut buffer = SurfaceNetsBuffer::default();
    surface_nets(&sdf, &shape, [0; 3], dims.map(|d| d - 1), &mut buffer);
    drop(sdf);
    let origin = volume.origin();
    let size = volume.voxel_size();
    let corner = Vector3::new(start[2], start[1], start[0]).map(|c| c as f64);
    let positions = (buffer.positions.iter())
        .map(|p| {
            let grid = Vector3::new(p[0], p[1], p[2]).map(f64::from) + corner;
            origin + grid.component_mul(&size)
        })
        .collect();
    let faces = (buffer.indices.chunks_exact(3))
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    (positions, faces)
}

/// A piece of a surface: its positions, its triangles over them, and its mesh.
type Piece = (Vec<Vector3<f64>>, Vec<[u32; 3]>, Mesh);

/// The largest connected piece of the triangles, made manifold and oriented outward (positive
/// enclosed volume), with only the vertices it uses, and its mesh; `None` where nothing valid
/// is left. The pieces are found by joining each face's vertices, so the mesh is built once,
/// for the piece kept.
fn largest_manifold_piece(positions: Vec<Vector3<f64>>, faces: &[[u32; 3]]) -> Option<Piece> {
    let repaired = repair(positions.len(), faces);
    let positions: Vec<Vector3<f64>> = (repaired.vertex_origin.iter())
        .map(|&v| positions[v as usize])
        .collect();
    let mut pieces = UnionFind::new(positions.len());
    for &[a, b, c] in &repaired.faces {
        pieces.union(a as usize, b as usize);
        pieces.union(a as usize, c as usize);
    }
    let mut faces_of_piece = vec![0usize; positions.len()];
    for f in &repaired.faces {
        faces_of_piece[pieces.find(f[0] as usize)] += 1;
    }
    let (largest, _) = (faces_of_piece.iter().enumerate()).max_by_key(|&(_, n)| *n)?;
    let piece_faces: Vec<[u32; 3]> = (repaired.faces.iter())
        .filter(|f| pieces.find(f[0] as usize) == largest)
        .copied()
        .collect();
    let (kept, mut faces) = compact(&positions, &piece_faces);
    let enclosed: f64 = (faces.iter())
        .map(|&[a, b, c]| {
            let [a, b, c] = [a, b, c].map(|v| kept[v as usize]);
            a.dot(&b.cross(&c))
        })
        .sum();
    if enclosed < 0.0 {
        faces.iter_mut().for_each(|f| f.swap(1, 2));
    }
    let mesh = Mesh::new(kept.len(), faces.clone()).ok()?;
    Some((kept, faces, mesh))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_split_where_voxels_touch_along_an_edge_or_at_a_corner_only() {
        assert!(!split_within_cell(0b0000_0000));
        assert!(!split_within_cell(0b0000_0001));
        assert!(!split_within_cell(0b0000_0011), "face neighbours");
        assert!(split_within_cell(0b0000_1001), "along an edge only");
        assert!(split_within_cell(0b1000_0001), "at a corner only");
        assert!(!split_within_cell(0b1000_1011), "joined through the cell");
    }

    #[test]
    fn a_checkerboard_becomes_well_composed() {
        let shape = [2, 2, 2];
        let mut solid = vec![true, false, false, true, false, false, false, false];
        well_composed(&mut solid, shape);
        assert!(solid.iter().all(|&s| s), "the critical cell is filled");
        let mut solid = vec![true, true, false, false, false, false, false, false];
        well_composed(&mut solid, shape);
        assert_eq!(
            solid.iter().filter(|&&s| s).count(),
            2,
            "a face pair stays as it is"
        );
    }

    /// The 6-connected components of `mask` by a plain breadth-first search: each voxel's
    /// component number (0 outside the mask).
    fn components_by_search(mask: &[bool], [nz, ny, nx]: [usize; 3]) -> Vec<usize> {
        let mut label = vec![0; mask.len()];
        let mut next = 0;
        for start in 0..mask.len() {
            if !mask[start] || label[start] != 0 {
                continue;
            }
            next += 1;
            label[start] = next;
            let mut queue = std::collections::VecDeque::from([start]);
            while let Some(at) = queue.pop_front() {
                let (k, j, i) = (at / (ny * nx), at / nx % ny, at % nx);
                let around = [
                    (i > 0).then(|| at - 1),
                    (i + 1 < nx).then(|| at + 1),
                    (j > 0).then(|| at - nx),
                    (j + 1 < ny).then(|| at + nx),
                    (k > 0).then(|| at - ny * nx),
                    (k + 1 < nz).then(|| at + ny * nx),
                ];
                for n in around.into_iter().flatten() {
                    if mask[n] && label[n] == 0 {
                        label[n] = next;
                        queue.push_back(n);
                    }
                }
            }
        }
        label
    }

    #[test]
    fn scanline_fills_find_the_components_a_search_finds() {
        let shape = [7, 9, 11];
        let n: usize = shape.iter().product();
        for density in [30, 45, 55, 70] {
            let mask: Vec<bool> = (0..n).map(|i| (i * 2654435761) % 97 < density).collect();
            let labels = components_by_search(&mask, shape);
            let mut sizes = std::collections::HashMap::new();
            labels
                .iter()
                .filter(|&&l| l > 0)
                .for_each(|&l| *sizes.entry(l).or_insert(0usize) += 1);
            let (&largest, &size) = sizes
                .iter()
                .max_by_key(|&(l, s)| (s, -(*l as i64)))
                .unwrap();
            let (component, found, _) = largest_component(shape, |at| mask[at]);
            assert_eq!(found, size, "density {density}");
            let expected: Vec<bool> = labels.iter().map(|&l| l == largest).collect();
            assert_eq!(component, expected, "density {density}");
            // Holes: what the border cannot reach through the background.
            let outside = components_by_search(&mask.iter().map(|m| !m).collect::<Vec<_>>(), shape);
            let open: std::collections::HashSet<usize> = on_border(shape)
                .map(|at| outside[at])
                .filter(|&l| l > 0)
                .collect();
            let solid = filled(&mask, shape);
            let expected: Vec<bool> = (0..n)
                .map(|at| mask[at] || !open.contains(&outside[at]))
                .collect();
            assert_eq!(solid, expected, "density {density}");
        }
    }

    #[test]
    fn the_border_is_every_voxel_on_a_face_once() {
        for [nz, ny, nx] in [
            [1, 1, 1],
            [1, 4, 5],
            [3, 1, 4],
            [4, 5, 1],
            [3, 4, 5],
            [6, 2, 7],
        ] {
            let border: Vec<usize> = on_border([nz, ny, nx]).collect();
            let expected: Vec<usize> = (0..nz * ny * nx)
                .filter(|&at| {
                    let (k, j, i) = (at / (ny * nx), at / nx % ny, at % nx);
                    k == 0 || j == 0 || i == 0 || k + 1 == nz || j + 1 == ny || i + 1 == nx
                })
                .collect();
            assert_eq!(border, expected, "{:?}", [nz, ny, nx]);
        }
    }
}
