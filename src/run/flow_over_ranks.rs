//! Writing a flow computed over ranks (`mpirun -n R meshflow solve`) without gathering it.
//!
//! Each rank holds its time window's frames and its own slabs' flow
//! ([`crate::flow::window::flow_of_own_slabs`]). Rank 0 writes every file, slab by slab in
//! order: its own slabs from memory, the others' as their ranks send them, one message per
//! slab (slab `s`'s first frame — time, positions, image — and its flow, R³ vectors, tissue
//! velocity and warped residual), and the last frame from the rank that holds it. Each slab goes
//! straight into its rows of the NPY arrays and its `flow_SSSS.vtu` ([`SlabFiles`]) and is
//! dropped: no rank ever holds more than its window and one slab more, however long the
//! sequence. What `summary.json` needs of the whole sequence (all frame times, the largest
//! speed, the static-image warning of a reader of all frames) is collected as the slabs pass.
//! The files are those a single process writes from the whole result (`tests/mpi.rs`).
//!
//! Only rank 0 writes, so the outputs need no file system shared between the nodes (the input
//! does: every rank reads its own frames). `flow.glb`, pictures and scores against a ground
//! truth need all frames at once; `meshflow solve` gathers the whole result on rank 0 for them.

use super::flow_output::{summary_of, write_summary, SequenceFacts, SlabFiles, SlabOutput};
use super::{OutputFormat, Scores, StagedDir};
use crate::flow::distributed::TimeRanks;
use crate::flow::window::TimeWindow;
use crate::flow::{FlowParams, FlowResult, MeshSequence};
use crate::format::IoError;
use crate::load::{LoadWarning, LoadedSequence, StaticImageCheck};
use crate::render::View;
use nalgebra::{Vector2, Vector3};
use std::borrow::Cow;

/// What rank 0 learnt of the whole sequence while writing it.
#[derive(Clone, Debug, PartialEq)]
pub struct WrittenFlow {
    pub n_frames: usize,
    /// [`LoadWarning::StaticImage`] when the image never changes, which the reader of a window
    /// could not tell (`None` when rank 0 read all frames: its reader warned).
    pub static_image: Option<LoadWarning>,
}

/// Rank 0's part: writes the outputs of the flow whose own slabs are `result` (of the frames
/// `loaded`, this rank's window `window`) into `out`, receiving the other ranks' slabs as
/// [`send_own_slabs`] sends them. [`OutputFormat::Glb`] is an error (a glTF animation needs
/// all frames at once: gather the flow with `flow_over_ranks` and write it whole).
#[allow(clippy::too_many_arguments)]
pub fn write_flow_over_ranks(
    out: &StagedDir,
    loaded: &LoadedSequence,
    window: &TimeWindow,
    ranks: &dyn TimeRanks,
    params: &FlowParams,
    result: &FlowResult,
    formats: &[OutputFormat],
    view: &View,
) -> Result<WrittenFlow, IoError> {
    if formats.contains(&OutputFormat::Glb) {
        let message = "a glTF animation needs all frames at once: gather the flow to write it";
        return Err(out.in_target(IoError::format(out.path().join("flow.glb"), message)));
    }
    let sequence = &loaded.sequence;
    let layout = Layout::of(sequence, result);
    let owners = slab_owners(ranks.size(), window.n_slabs_in_all);
    let own = OwnSlabs {
        sequence,
        window,
        result,
    };
    let dir = out.path();
    let mesh = (&loaded.vertex_map, sequence.mesh().faces());
    let n_slabs = window.n_slabs_in_all;
    let mut files = SlabFiles::create(dir, mesh, formats, n_slabs, layout.embedded)?;
    let mut check: Option<StaticImageCheck> = None;
    let mut times = Vec::with_capacity(n_slabs + 1);
    let mut add_frame = |frame: &SlabOutput| {
        let channels = frame.channels_or_grey();
        let positions = frame.positions.as_deref();
        match &mut check {
            None => check = Some(StaticImageCheck::new((positions, &channels))),
            Some(check) => check.add((positions, &channels)),
        }
        times.push(frame.time);
    };
    for (s, &owner) in owners.iter().enumerate() {
        let slab = match owner {
            0 => own.slab(s),
            _ => layout.decode(&ranks.receive(owner), true),
        };
        add_frame(&slab);
        files.add(s, &slab).map_err(|e| out.in_target(e))?;
    }
    let last = match owners[n_slabs - 1] {
        0 => own.last_frame(),
        owner => layout.decode(&ranks.receive(owner), false),
    };
    add_frame(&last);
    let max_speed = files.finish().map_err(|e| out.in_target(e))?;
    // A window of all frames was read whole, and its reader gave the warning.
    let whole = window.frames() == (0..n_slabs + 1);
    let static_image = (check.filter(|_| !whole)).and_then(|check| check.warning(&loaded.path));
    let warnings: Vec<LoadWarning> = (loaded.warnings.iter().cloned())
        .chain(static_image.clone())
        .collect();
    let mut facts = SequenceFacts::of(sequence, &warnings, max_speed);
    (facts.n_frames, facts.times) = (n_slabs + 1, times);
    let summary = summary_of(&facts, loaded, params, result, Scores::default());
    write_summary(dir, summary, view).map_err(|e| out.in_target(e))?;
    Ok(WrittenFlow {
        n_frames: n_slabs + 1,
        static_image,
    })
}

/// A rank other than 0: sends its own slabs (`result`, of the frames `loaded` of its window
/// `window`) to rank 0, and the last frame if it holds it.
pub fn send_own_slabs(
    loaded: &LoadedSequence,
    window: &TimeWindow,
    ranks: &dyn TimeRanks,
    result: &FlowResult,
) {
    let layout = Layout::of(&loaded.sequence, result);
    let own = OwnSlabs {
        sequence: &loaded.sequence,
        window,
        result,
    };
    for s in window.slabs.clone() {
        ranks.send(0, &layout.encode(&own.slab(s), true));
    }
    if window.slabs.end == window.n_slabs_in_all {
        ranks.send(0, &layout.encode(&own.last_frame(), false));
    }
}

/// The rank of each slab's window ([`TimeWindow::of_rank`]).
fn slab_owners(n_ranks: usize, n_slabs: usize) -> Vec<usize> {
    (0..n_ranks)
        .flat_map(|r| {
            TimeWindow::of_rank(r, n_ranks, n_slabs)
                .slabs
                .map(move |_| r)
        })
        .collect()
}

/// A rank's own slabs as outputs: global slab `s` is frame `s − a′` of the window's frames
/// (from `a′`) and slab `s − a` of the result (from `a`).
struct OwnSlabs<'a> {
    sequence: &'a MeshSequence,
    window: &'a TimeWindow,
    result: &'a FlowResult,
}

impl<'a> OwnSlabs<'a> {
    fn slab(&self, s: usize) -> SlabOutput<'a> {
        let frame = s - self.window.frames().start;
        let slab = s - self.window.slabs.start;
        SlabOutput::of_result(self.sequence, frame, self.result, slab, None)
    }

    /// The sequence's last frame (the window must end with it), without flow.
    fn last_frame(&self) -> SlabOutput<'a> {
        SlabOutput::frame(self.sequence, self.sequence.n_frames() - 1)
    }
}

/// Which fields a slab's message carries; the same on every rank (one mesh, one image, one
/// set of parameters).
struct Layout {
    n_vertices: usize,
    embedded: bool,
    n_channels: usize,
    residual: bool,
}

impl Layout {
    fn of(sequence: &MeshSequence, result: &FlowResult) -> Self {
        Layout {
            n_vertices: sequence.mesh().n_vertices(),
            embedded: sequence.positions(0).is_some(),
            n_channels: sequence.n_channels(),
            residual: result.warped_residual.is_some(),
        }
    }

    /// `[time, positions, grey values, channels (when several)]`, then with `flow`
    /// `[intrinsic, vectors, velocity (when embedded), warped residual (with warping)]`.
    fn encode(&self, slab: &SlabOutput, flow: bool) -> Vec<f64> {
        let mut message = vec![slab.time];
        let vectors =
            |m: &mut Vec<f64>, v: &[Vector3<f64>]| m.extend(v.iter().flat_map(|u| [u.x, u.y, u.z]));
        if let Some(positions) = &slab.positions {
            vectors(&mut message, positions);
        }
        message.extend_from_slice(&slab.intensity);
        for channel in slab.channels.iter().flat_map(|c| c.iter()) {
            message.extend_from_slice(channel);
        }
        if flow {
            message.extend(slab.intrinsic.iter().flat_map(|u| [u.x, u.y]));
            for field in [&slab.vectors.as_deref(), &slab.velocity.as_deref()]
                .into_iter()
                .flatten()
            {
                vectors(&mut message, field);
            }
            if let Some(residual) = &slab.warped_residual {
                message.extend_from_slice(residual);
            }
        }
        message
    }

    /// The inverse of [`Layout::encode`].
    fn decode(&self, message: &[f64], flow: bool) -> SlabOutput<'static> {
        let v = self.n_vertices;
        let mut rest = message;
        let mut take = |n: usize| {
            let (head, tail) = rest.split_at(n);
            rest = tail;
            head
        };
        let time = take(1)[0];
        let vectors = |values: &[f64]| -> Vec<Vector3<f64>> {
            values.chunks(3).map(Vector3::from_column_slice).collect()
        };
        let positions = self.embedded.then(|| Cow::Owned(vectors(take(3 * v))));
        let intensity = Cow::Owned(take(v).to_vec());
        let channels = (self.n_channels > 1)
            .then(|| Cow::Owned((0..self.n_channels).map(|_| take(v).to_vec()).collect()));
        let mut slab = SlabOutput {
            time,
            positions,
            intensity,
            channels,
            intrinsic: Cow::Owned(Vec::new()),
            vectors: None,
            velocity: None,
            warped_residual: None,
            errors: None,
            // Not sent between ranks: a solve over ranks does not flag vertices without data.
            no_data: None,
        };
        if flow {
            let intrinsic = take(2 * v).chunks(2).map(Vector2::from_column_slice);
            slab.intrinsic = Cow::Owned(intrinsic.collect());
            if self.embedded {
                slab.vectors = Some(Cow::Owned(vectors(take(3 * v))));
                slab.velocity = Some(vectors(take(3 * v)));
            }
            slab.warped_residual = self.residual.then(|| Cow::Owned(take(v).to_vec()));
        }
        slab
    }
}
