//! Pictures of a whole flow: every slab drawn from one camera with one flow scale, so that the
//! pictures of a sequence can be compared (and played as an animation).
//!
//! For slabs `s` with the surface of frame `s`, its grey values `I_s` and the slab's flow `u_s`
//! in R^3, the camera frames the bounding box of all drawn frames from the chosen [`View`]; the
//! flow scale (the colour wheel's rim) is the robust maximum ([`robust_max`], the 99th
//! percentile) of `|u_s(i)|` over all slabs and vertices unless given, the arrows' the typical
//! speed of the moving part ([`arrow_scale`]); grey values span the finite range of all drawn frames;
//! angular errors span `[0, robust maximum]`. Per slab it writes
//!
//! | file | picture |
//! |---|---|
//! | `grey_SSSS.png` | [`grey_picture`]: the image on the surface |
//! | `flow_SSSS.png` | [`flow_picture`]: Middlebury colours of the flow's screen directions, with the wheel legend |
//! | `arrows_SSSS.png` | [`arrow_picture`]: arrows on an even subsample of visible vertices |
//! | `angular_error_SSSS.png` | [`scalar_picture`] of the angular error (degrees), when known |
//! | `track_errors_SSSS.png` | [`track_errors_picture`], with tracked points: [`write_track_error_pictures`] |
//! | `residual_SSSS.png` | [`scalar_picture`] of `|I⁺ − I⁻|`, the grey-value change left along the flow, with warping |
//!
//! labelled `slab s  t = t_s` (times with six significant digits, [`format_number`]). Vertices
//! without data in the slab ([`SlabView::no_data`]) are drawn in [`super::NO_DATA_COLOUR`] in
//! every picture, and the label says so.
//! [`SlabSelection`] reads which slabs to draw from a list such as `0,5,10-20,last`.

use super::color_wheel::{arrow_scale, robust_max};
use super::colormap::finite_range;
use super::text::format_number;
use super::RenderError;
use super::{
    arrow_picture, flow_picture, grey_picture, scalar_picture, track_errors_picture, write_png,
    Camera, PictureStyle, Surface, View,
};
use crate::accuracy::TrackPoint;
use crate::flow::{FlowResult, MeshSequence};
use crate::Error;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// One slab as drawn: the surface of frame `slab` and the slab's flow.
#[derive(Clone, Copy, Debug)]
pub struct SlabView<'a> {
    pub slab: usize,
    /// `t_s`, shown in the label.
    pub time: f64,
    pub positions: &'a [Vector3<f64>],
    pub intensity: &'a [f64],
    pub flow: &'a [Vector3<f64>],
    /// Angular error against a ground truth, degrees, one per vertex.
    pub angular_error: Option<&'a [f64]>,
    /// With warping, the grey-value change left between the slab's frames read along the flow
    /// ([`FlowResult::warped_residual`](crate::flow::FlowResult)).
    pub warped_residual: Option<&'a [f64]>,
    /// Vertices without data in the slab, drawn in [`super::NO_DATA_COLOUR`]
    /// ([`crate::load::LoadedSequence::slab_no_data`]).
    pub no_data: Option<&'a [bool]>,
}

/// The views of slabs `slabs` of an embedded `sequence` with its R^3 flow `vectors[s]` (as in
/// [`FlowResult::vectors`](crate::flow::FlowResult)) and, when known, angular errors
/// `angular_errors[s]`.
pub fn sequence_views<'a>(
    sequence: &'a MeshSequence,
    vectors: &'a [Vec<Vector3<f64>>],
    angular_errors: Option<&'a [Vec<f64>]>,
    slabs: impl IntoIterator<Item = usize>,
) -> Result<Vec<SlabView<'a>>, RenderError> {
    slabs
        .into_iter()
        .map(|s| {
            Ok(SlabView {
                slab: s,
                time: sequence.times()[s],
                positions: sequence.positions(s).ok_or(RenderError::Intrinsic)?,
                intensity: sequence.intensities(s),
                flow: &vectors[s],
                angular_error: angular_errors.map(|errors| errors[s].as_slice()),
                warped_residual: None,
                no_data: None,
            })
        })
        .collect()
}

/// The views of all slabs of a computed `result` on its `sequence`: [`sequence_views`] with the
/// result's R³ flow and, after warping, the grey-value change it left.
pub fn result_views<'a>(
    sequence: &'a MeshSequence,
    result: &'a FlowResult,
    angular_errors: Option<&'a [Vec<f64>]>,
) -> Result<Vec<SlabView<'a>>, RenderError> {
    let vectors = result.vectors.as_deref().ok_or(RenderError::Intrinsic)?;
    let mut views = sequence_views(sequence, vectors, angular_errors, 0..sequence.n_slabs())?;
    if let Some(residual) = &result.warped_residual {
        for view in &mut views {
            view.warped_residual = Some(&residual[view.slab]);
        }
    }
    Ok(views)
}

/// Size, view and style of the pictures of [`write_slab_pictures`].
#[derive(Clone, Debug, PartialEq)]
pub struct FigureOptions {
    pub width: u32,
    pub height: u32,
    pub view: View,
    /// Flow speed at the colour wheel's rim and of the reference arrow; `None`: the robust
    /// maximum of all drawn speeds.
    pub flow_scale: Option<f64>,
    pub style: PictureStyle,
}

impl Default for FigureOptions {
    /// 960 × 720 pixels, the default view and style, automatic scale.
    fn default() -> Self {
        Self {
            width: 960,
            height: 720,
            view: View::default(),
            flow_scale: None,
            style: PictureStyle::default(),
        }
    }
}

/// What all slabs share: camera, flow scale and value ranges.
struct Shared {
    camera: Camera,
    /// The colour wheel's rim.
    scale: f64,
    /// The reference arrow's length.
    arrow_scale: f64,
    grey_range: (f64, f64),
    error_range: (f64, f64),
    residual_range: (f64, f64),
}

impl Shared {
    fn new(slabs: &[SlabView], options: &FigureOptions) -> Self {
        let points: Vec<Vector3<f64>> = slabs
            .iter()
            .flat_map(|v| v.positions.iter().copied())
            .filter(|p| p.iter().all(|c| c.is_finite()))
            .collect();
        let camera = Camera::framing(&points, options.view, options.width, options.height);
        let speeds: Vec<f64> = slabs
            .iter()
            .flat_map(|v| v.flow.iter().map(|u| u.norm()))
            .collect();
        let intensities: Vec<f64> = slabs
            .iter()
            .flat_map(|v| v.intensity.iter().copied())
            .collect();
        let errors: Vec<f64> = slabs
            .iter()
            .flat_map(|v| v.angular_error.unwrap_or(&[]).iter().copied())
            .collect();
        let residuals: Vec<f64> = slabs
            .iter()
            .flat_map(|v| v.warped_residual.unwrap_or(&[]).iter().map(|r| r.abs()))
            .collect();
        Self {
            camera,
            residual_range: (0.0, robust_max(&residuals)),
            scale: options.flow_scale.unwrap_or_else(|| robust_max(&speeds)),
            arrow_scale: options.flow_scale.unwrap_or_else(|| arrow_scale(&speeds)),
            grey_range: widened(finite_range(&intensities).unwrap_or((0.0, 1.0))),
            error_range: (0.0, robust_max(&errors)),
        }
    }
}

/// A range of positive width: a constant image is drawn mid-grey.
fn widened((min, max): (f64, f64)) -> (f64, f64) {
    if max > min {
        (min, max)
    } else {
        (min - 0.5, max + 0.5)
    }
}

/// Draws every slab of `slabs` (see the module documentation) into `dir`, slabs in parallel;
/// `progress` is called once per finished slab. Returns the files written, slab by slab.
pub fn write_slab_pictures(
    dir: &Path,
    faces: &[[u32; 3]],
    slabs: &[SlabView],
    options: &FigureOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<PathBuf>, Error> {
    let all: Vec<usize> = (0..slabs.len()).collect();
    write_chosen_slab_pictures(dir, faces, slabs, &all, options, progress)
}

/// [`write_slab_pictures`] for the slabs `chosen` (indices into `slabs`) only, with the
/// camera, flow scale and value ranges of all `slabs`: a picture of slab 3 is the same whether
/// it is drawn alone or with the others.
pub fn write_chosen_slab_pictures(
    dir: &Path,
    faces: &[[u32; 3]],
    slabs: &[SlabView],
    chosen: &[usize],
    options: &FigureOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<PathBuf>, Error> {
    if slabs.is_empty() || chosen.is_empty() {
        return Ok(Vec::new());
    }
    let shared = Shared::new(slabs, options);
    let written: Vec<Result<Vec<PathBuf>, Error>> = chosen
        .par_iter()
        .map(|&k| {
            let files = write_one_slab(dir, faces, &slabs[k], &shared, &options.style);
            progress();
            files
        })
        .collect();
    // Sequentially, so that the first failing slab is the one reported.
    let written: Vec<Vec<PathBuf>> = written.into_iter().collect::<Result<_, _>>()?;
    Ok(written.into_iter().flatten().collect())
}

/// `track_errors_SSSS.png` for the slabs `chosen` (indices into `slabs`) that hold scored
/// points ([`track_errors_picture`]: true displacements red, the flow's black), seen as
/// [`write_chosen_slab_pictures`] sees them; arrows are sized by [`arrow_scale`] of the true
/// displacements of all points.
pub fn write_track_error_pictures(
    dir: &Path,
    faces: &[[u32; 3]],
    slabs: &[SlabView],
    chosen: &[usize],
    points: &[TrackPoint],
    options: &FigureOptions,
) -> Result<Vec<PathBuf>, Error> {
    if slabs.is_empty() || points.is_empty() {
        return Ok(Vec::new());
    }
    let shared = Shared::new(slabs, options);
    let lengths: Vec<f64> = points.iter().map(|p| p.truth.norm()).collect();
    let scale = arrow_scale(&lengths);
    let mut written = Vec::new();
    for view in chosen.iter().map(|&k| &slabs[k]) {
        let here: Vec<&TrackPoint> = points.iter().filter(|p| p.slab == view.slab).collect();
        if here.is_empty() {
            continue;
        }
        let field =
            |f: fn(&TrackPoint) -> Vector3<f64>| here.iter().map(|p| f(p)).collect::<Vec<_>>();
        let style = PictureStyle {
            label: Some(format!(
                "slab {}: cells' displacements (red) and the flow's (black)",
                view.slab
            )),
            no_data: (view.no_data)
                .filter(|mask| mask.iter().any(|&m| m))
                .map(<[bool]>::to_vec),
            ..options.style.clone()
        };
        let surface = Surface {
            positions: view.positions,
            faces,
        };
        let image = track_errors_picture(
            &shared.camera,
            surface,
            (view.intensity, shared.grey_range),
            &field(|p| p.position),
            (&field(|p| p.truth), &field(|p| p.computed)),
            scale,
            &style,
        )?;
        let path = dir.join(format!("track_errors_{:04}.png", view.slab));
        write_png(&path, &image)?;
        written.push(path);
    }
    Ok(written)
}

fn write_one_slab(
    dir: &Path,
    faces: &[[u32; 3]],
    view: &SlabView,
    shared: &Shared,
    style: &PictureStyle,
) -> Result<Vec<PathBuf>, Error> {
    let marked = view.no_data.filter(|mask| mask.iter().any(|&m| m));
    let style = PictureStyle {
        label: Some(format!(
            "slab {}  t = {}{}",
            view.slab,
            format_number(view.time),
            if marked.is_some() {
                "  (grey: no data)"
            } else {
                ""
            }
        )),
        no_data: marked.map(<[bool]>::to_vec),
        ..style.clone()
    };
    let surface = Surface {
        positions: view.positions,
        faces,
    };
    let camera = &shared.camera;
    let mut pictures = vec![
        (
            "grey",
            grey_picture(camera, surface, view.intensity, shared.grey_range, &style)?,
        ),
        (
            "flow",
            flow_picture(camera, surface, view.flow, shared.scale, &style)?,
        ),
        (
            "arrows",
            arrow_picture(
                camera,
                surface,
                view.intensity,
                shared.grey_range,
                view.flow,
                shared.arrow_scale,
                &style,
            )?,
        ),
    ];
    if let Some(errors) = view.angular_error {
        let style = PictureStyle {
            label: Some(format!("angular error (°), slab {}", view.slab)),
            ..style.clone()
        };
        pictures.push((
            "angular_error",
            scalar_picture(camera, surface, errors, shared.error_range, &style)?,
        ));
    }
    if let Some(residual) = view.warped_residual {
        let style = PictureStyle {
            label: Some(format!("|warped residual|, slab {}", view.slab)),
            ..style.clone()
        };
        let magnitude: Vec<f64> = residual.iter().map(|r| r.abs()).collect();
        pictures.push((
            "residual",
            scalar_picture(camera, surface, &magnitude, shared.residual_range, &style)?,
        ));
    }
    pictures
        .into_iter()
        .map(|(name, image)| {
            let path = dir.join(format!("{name}_{:04}.png", view.slab));
            write_png(&path, &image)?;
            Ok(path)
        })
        .collect()
}

/// Which slabs to draw, as a user writes it: comma-separated slab numbers (`5`), inclusive
/// ranges (`10-20`), `last` for the last slab (also as a range end, `10-last`), and `all`.
/// [`SlabSelection::resolve`] checks it against a slab count.
#[derive(Clone, Debug, PartialEq)]
pub struct SlabSelection {
    text: String,
    /// Each item as written, with its first and last slab (inclusive).
    items: Vec<(String, SlabIndex, SlabIndex)>,
}

/// A slab number or the last slab.
#[derive(Clone, Copy, Debug, PartialEq)]
enum SlabIndex {
    Number(usize),
    Last,
}

impl SlabSelection {
    /// Every slab.
    pub fn all() -> Self {
        "all".parse().expect("'all' parses")
    }

    /// The chosen slabs of a sequence with `n_slabs` slabs, ascending and without repeats; an
    /// error names the first item that goes beyond the last slab or runs backwards.
    pub fn resolve(&self, n_slabs: usize) -> Result<Vec<usize>, RenderError> {
        let error = |reason: String| RenderError::Slabs {
            text: self.text.clone(),
            reason,
        };
        let Some(last) = n_slabs.checked_sub(1) else {
            return Err(error("there are no slabs".into()));
        };
        let mut chosen = vec![false; n_slabs];
        for (item, first, end) in &self.items {
            let number = |index: &SlabIndex| match index {
                SlabIndex::Number(s) => *s,
                SlabIndex::Last => last,
            };
            let (first, end) = (number(first), number(end));
            if end > last {
                return Err(error(format!(
                    "{item:?} names slab {end}, but there are {n_slabs} slabs (0-{last})"
                )));
            }
            if first > end {
                return Err(error(format!(
                    "{item:?} runs backwards (slab {first} to {end})"
                )));
            }
            chosen[first..=end].iter_mut().for_each(|c| *c = true);
        }
        Ok((0..n_slabs).filter(|&s| chosen[s]).collect())
    }
}

impl FromStr for SlabSelection {
    type Err = RenderError;

    /// Parses the syntax of [`SlabSelection`]; slab numbers are checked by
    /// [`SlabSelection::resolve`].
    fn from_str(text: &str) -> Result<Self, RenderError> {
        let error = |reason: String| RenderError::Slabs {
            text: text.to_string(),
            reason,
        };
        let index = |item: &str, part: &str| match part.trim() {
            "last" => Ok(SlabIndex::Last),
            number => number.parse().map(SlabIndex::Number).map_err(|_| {
                error(format!(
                    "{item:?} is not a slab number, a range FIRST-LAST, 'last' or 'all'"
                ))
            }),
        };
        let mut items = Vec::new();
        for item in text.split(',').map(str::trim) {
            let (first, end) = match item {
                "" => return Err(error("an item is empty".into())),
                "all" => (SlabIndex::Number(0), SlabIndex::Last),
                _ => match item.split_once('-') {
                    Some((first, end)) => (index(item, first)?, index(item, end)?),
                    None => {
                        let single = index(item, item)?;
                        (single, single)
                    }
                },
            };
            if let (SlabIndex::Number(a), SlabIndex::Number(b)) = (first, end) {
                if a > b {
                    return Err(error(format!("{item:?} runs backwards")));
                }
            }
            items.push((item.to_string(), first, end));
        }
        Ok(Self {
            text: text.to_string(),
            items,
        })
    }
}
