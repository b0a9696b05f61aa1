//! A closed surface found in every frame of a recording and tracked into one moving mesh: what
//! `meshflow surface --shape closed` writes, and what the Python package's
//! `closed_surface_sequence` (and the napari widget) return.
//!
//! Frame by frame, the object's surface is found in the volume ([`find_surface_consuming`]) and
//! handed to the tracker at once ([`track_as_they_come`]), so memory holds one volume and two
//! frames' surfaces whatever the recording's length. Two choices keep the frames alike:
//!
//! - each frame's closing starts at the widest radius an earlier frame needed, and its
//!   smoothing at the largest σ used (frame 0's porous foreground doubles it): the same object,
//!   closed and smoothed alike, keeps its shape from frame to frame;
//! - the tracked reference has about [`ClosedOptions::vertices`] vertices, by default
//!   [`DEFAULT_VERTICES`] or fewer where its edges would be shorter than the smoothing's σ
//!   (the surfaces are not known below σ, and a finer mesh tracks their noise and folds), and
//!   never more than half of frame 0's surface-nets vertices (their slivers are never kept).
//!
//! The result is checked before it is used ([`check_tracked`]): one closed, connected manifold
//! of frame 0's genus, and no frame folded over itself at more than [`FOLDS_TOLERATED`] of
//! its edges (fewer, or any with `keep_going`, are listed as [`FoldedFrame`]s).

use super::{find_surface_consuming, FoundSurface, IsosurfaceOptions};
use crate::track::{track_as_they_come, TrackEvent, TrackFrame, TrackOptions, Tracked};
use crate::volume::{VolumeStream, VoxelSizeSource};
use crate::Error;

/// The tracked mesh's size when [`ClosedOptions::vertices`] is not given (as for surfaces
/// through points).
pub const DEFAULT_VERTICES: usize = 16000;

/// The share of the tracked mesh's edges that may be folded in a frame before it is an error
/// (without `keep_going`): a lone crease is a warning, a tangle is refused.
pub const FOLDS_TOLERATED: f64 = 1e-3;

/// How the surfaces are found and tracked.
#[derive(Clone, Debug)]
pub struct ClosedOptions {
    pub finding: IsosurfaceOptions,
    /// About this many vertices in the tracked mesh; `None`: [`DEFAULT_VERTICES`], or fewer
    /// where edges would be shorter than the smoothing's σ (module docs).
    pub vertices: Option<usize>,
    /// How the tracked mesh follows the frames' surfaces (`reference_vertices` and
    /// `keep_uncovered` are set here, from `vertices` and the surface being closed).
    pub tracking: TrackOptions,
    /// The frame times (`None`: 0, 1, 2, …).
    pub times: Option<Vec<f64>>,
}

/// What happens while [`closed_sequence`] runs, for progress and logs.
pub enum ClosedEvent<'a> {
    /// Where the voxel size came from (after frame 0 is read).
    VoxelSize(&'a VoxelSizeSource),
    /// Frame `frame` of an OME-Zarr image lacked `missing` of its `chunks`.
    MissingChunks {
        frame: usize,
        missing: u64,
        chunks: u64,
    },
    /// Frame `frame`'s surface was found.
    Found {
        frame: usize,
        surface: &'a FoundSurface,
    },
    /// The reference gets `vertices`, fewer than the `asked` ones: half of frame 0's
    /// `frame_vertices`.
    FewerVertices {
        vertices: usize,
        asked: usize,
        frame_vertices: usize,
    },
    /// The tracker's own events.
    Track(TrackEvent<'a>),
}

/// A frame in which the tracked mesh folds over itself at `folded_edges` edges.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct FoldedFrame {
    pub frame: usize,
    pub folded_edges: usize,
}

/// The tracked surface, the report of each frame's surface and the frames that fold (fewer
/// edges than tolerated, or any with `keep_going`).
pub struct ClosedSequence {
    pub tracked: Tracked,
    pub found: Vec<FoundSurface>,
    pub folds: Vec<FoldedFrame>,
}

/// Why a closed surface sequence could not be made (besides the volumes' and the finding's
/// own errors).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClosedError {
    #[error("the recording holds {0} frame: a moving surface needs 2 frames at least (one frame's surface: meshflow.find_surface in Python)")]
    OneFrame(usize),
    #[error("{given} times for the {frames} frames of the recording")]
    Times { given: usize, frames: usize },
    #[error("frame 0: the tracked mesh is {} with {components} component(s) and genus {genus}, where frame 0's surface is closed, connected and of genus {wanted}; try other --vertices", if *.closed { "closed" } else { "open" })]
    Topology {
        closed: bool,
        components: usize,
        genus: i64,
        wanted: usize,
    },
    #[error("frame {frame}: the tracked mesh folds over itself at {folded} of its {edges} edges (their triangles face opposite ways); try fewer --vertices, or --keep-going to write it anyway")]
    Folded {
        frame: usize,
        folded: usize,
        edges: usize,
    },
}

/// The surface of the object in each frame of `stream`, tracked into one moving mesh (module
/// docs); `on_event` hears of each step. Errors name the file and frame at fault.
pub fn closed_sequence(
    stream: &mut VolumeStream,
    options: &ClosedOptions,
    on_event: &mut dyn FnMut(ClosedEvent),
) -> Result<ClosedSequence, Error> {
    let n_frames = stream.n_frames();
    if n_frames < 2 {
        return Err(ClosedError::OneFrame(n_frames).into());
    }
    // From the files' headers: wrong times fail before any reading.
    if let Some(times) = options.times.as_ref().filter(|t| t.len() != n_frames) {
        let given = times.len();
        return Err(ClosedError::Times {
            given,
            frames: n_frames,
        }
        .into());
    }
    let mut found: Vec<FoundSurface> = Vec::with_capacity(n_frames);
    let finding = &options.finding;
    let first = next_frame(stream, finding, &mut found, on_event)?.expect("2 frames at least");
    let vertices = reference_vertices(options.vertices, &first, &found[0], on_event);
    // A closed surface has no boundary to trim at: a vertex whose normal misses the next
    // frame's surface takes its closest point.
    let tracking = TrackOptions {
        reference_vertices: Some(vertices),
        keep_uncovered: true,
        keep_coordinates: true,
        ..options.tracking.clone()
    };
    let mut failure: Option<Error> = None;
    // The tracker pulls frames through `rest` and reports through `on_track`, never both at
    // once: one `RefCell` lends `on_event` to each in turn.
    let on_event = std::cell::RefCell::new(on_event);
    let tracked = {
        // `rest` cannot return an error: the first one ends the frames, and is returned once
        // the tracker stops.
        let mut rest = std::iter::from_fn(|| {
            let mut on_event = on_event.borrow_mut();
            match next_frame(stream, finding, &mut found, &mut **on_event) {
                Ok(frame) => frame,
                Err(e) => {
                    failure = Some(e);
                    None
                }
            }
        });
        let mut on_track = |event: TrackEvent| (on_event.borrow_mut())(ClosedEvent::Track(event));
        track_as_they_come(
            first,
            &mut rest,
            options.times.clone(),
            &tracking,
            &mut on_track,
        )
    };
    if let Some(error) = failure {
        return Err(error);
    }
    let tracked = tracked?;
    let folds = check_tracked(&tracked, &found, options)?;
    Ok(ClosedSequence {
        tracked,
        found,
        folds,
    })
}

/// Reads frame `found.len()` of `stream`, finds its surface (closing and smoothing from where
/// earlier frames needed them, module docs) and hands its mesh on; `None` after the last.
fn next_frame(
    stream: &mut VolumeStream,
    finding: &IsosurfaceOptions,
    found: &mut Vec<FoundSurface>,
    on_event: &mut dyn FnMut(ClosedEvent),
) -> Result<Option<TrackFrame>, Error> {
    let Some(read) = stream.next() else {
        return Ok(None);
    };
    let (volume, file) = read?;
    let frame = found.len();
    if let Some((missing, chunks)) = stream.missing_chunks() {
        on_event(ClosedEvent::MissingChunks {
            frame,
            missing,
            chunks,
        });
    }
    if frame == 0 {
        if let Some(source) = stream.voxel_size_source() {
            on_event(ClosedEvent::VoxelSize(source));
        }
    }
    let widest = found.iter().map(|f| f.closing_radius).fold(0.0, f64::max);
    let smoothest = found.iter().map(|f| f.smoothing).fold(0.0, f64::max);
    let options = IsosurfaceOptions {
        closing: finding.closing.or((widest > 0.0).then_some(widest)),
        smoothing: finding.smoothing.or((frame > 0).then_some(smoothest)),
        ..*finding
    };
    let mut surface = find_surface_consuming(volume, &options)
        .map_err(|e| Error::from(e).in_file(format!("{} (frame {frame})", file.display())))?;
    on_event(ClosedEvent::Found {
        frame,
        surface: &surface,
    });
    // The mesh moves to the tracker; `found` keeps the report (`vertices`, `faces`).
    let mesh = TrackFrame {
        intensity: vec![0.0; surface.positions.len()],
        positions: std::mem::take(&mut surface.positions),
        faces: std::mem::take(&mut surface.faces),
    };
    found.push(surface);
    Ok(Some(mesh))
}

/// The reference's vertex count (module docs): `asked`, by default [`DEFAULT_VERTICES`] or
/// the count whose edges are the smoothing's σ, at most half of frame 0's.
fn reference_vertices(
    asked: Option<usize>,
    first: &TrackFrame,
    found: &FoundSurface,
    on_event: &mut dyn FnMut(ClosedEvent),
) -> usize {
    let area = crate::geometry::surface_area(&first.faces, &first.positions);
    let coarsest = triangle_mesh_vertices(area, found.smoothing);
    let asked = asked.unwrap_or(DEFAULT_VERTICES.min(coarsest));
    let vertices = asked.min(found.vertices / 2);
    if vertices < asked {
        on_event(ClosedEvent::FewerVertices {
            vertices,
            asked,
            frame_vertices: found.vertices,
        });
    }
    vertices
}

/// About how many vertices a mesh of equilateral triangles of side `edge` has over `area`:
/// two triangles of `√3/4 edge²` per vertex.
fn triangle_mesh_vertices(area: f64, edge: f64) -> usize {
    (area / (3f64.sqrt() / 2.0 * edge * edge)).round().max(4.0) as usize
}

/// The tracked mesh checked (module docs): one closed, connected manifold of frame 0's genus
/// (its connectivity was built as one), and the frames where it folds.
pub fn check_tracked(
    tracked: &Tracked,
    found: &[FoundSurface],
    options: &ClosedOptions,
) -> Result<Vec<FoldedFrame>, ClosedError> {
    let sequence = &tracked.sequence;
    let mesh = sequence.mesh();
    let components = mesh.connected_components().len();
    let genus = (2 - mesh.euler_characteristic()) / 2;
    let wanted = found.first().map_or(options.finding.genus, |f| f.genus);
    if !mesh.is_closed() || components != 1 || genus != wanted as i64 {
        return Err(ClosedError::Topology {
            closed: mesh.is_closed(),
            components,
            genus,
            wanted,
        });
    }
    let mut folds = vec![];
    let edges = mesh.n_edges();
    let tolerated = (FOLDS_TOLERATED * edges as f64).floor() as usize;
    for frame in 0..sequence.n_frames() {
        let positions = sequence.positions(frame).expect("tracked in R^3");
        let folded = crate::geometry::folds::folded_halfedges(mesh, positions).len();
        if folded == 0 {
            continue;
        }
        if folded > tolerated && !options.tracking.keep_going {
            return Err(ClosedError::Folded {
                frame,
                folded,
                edges,
            });
        }
        folds.push(FoldedFrame {
            frame,
            folded_edges: folded,
        });
    }
    Ok(folds)
}

impl ClosedSequence {
    /// The warnings of the frames' surfaces and of the folds, each naming its frame.
    pub fn warnings(&self) -> Vec<String> {
        let found = self.found.iter().enumerate().flat_map(|(k, s)| {
            s.warnings()
                .into_iter()
                .map(move |w| format!("frame {k}: {w}"))
        });
        let folds = self.folds.iter().map(|f| {
            format!(
                "frame {}: the tracked mesh folds over itself at {} edge(s)",
                f.frame, f.folded_edges
            )
        });
        found.chain(folds).collect()
    }

    /// `surface.json`'s report: the mesh's size and genus, the folds, each frame's surface,
    /// the tracking and the warnings.
    pub fn report(&self) -> serde_json::Value {
        let mesh = self.tracked.sequence.mesh();
        serde_json::json!({
            "shape": "closed",
            "vertices": mesh.n_vertices(),
            "faces": mesh.n_faces(),
            "genus": (2 - mesh.euler_characteristic()) / 2,
            "folds": self.folds,
            "frames": self.found,
            "tracking": self.tracked.report,
            "warnings": self.warnings(),
        })
    }
}
