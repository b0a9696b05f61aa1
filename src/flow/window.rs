//! Time windows: the slabs `[a, b)` of a sequence assembled from its frames `a − 1 … b + 1`
//! alone, equal to the same slabs of the whole problem — what each rank of a solve distributed
//! over time would assemble (`docs/scaling.md`).
//!
//! A slab's diagonal block carries the diagonal parts of both its time links, and a link needs
//! both slabs' geometry and image, so a window needs one slab beyond each end (where there is
//! one): frames `a − 1 ..= b + 1`. The weights depend on the data's scales over *all* slabs;
//! each window measures its own slabs' [`ScaleSums`], and their sum (one all-reduce) gives the
//! scales every window assembles with.
//!
//! Not done per window: the check that the minimizer is unique (`uniqueness`), which couples
//! all slabs; a distributed solve has to reduce it across windows too.

use super::slab::{build_slabs, embed_where_needed, time_links, Slab};
use super::system::SystemWindow;
use super::{DataScales, FlowError, FlowParams, MeshSequence, ScaleSums, SpaceTimeSystem};
use std::ops::Range;

/// The slabs `[a, b)` of a sequence of `n_slabs_in_all` slabs that one rank holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TimeWindow {
    pub slabs: Range<usize>,
    pub n_slabs_in_all: usize,
}

impl TimeWindow {
    /// The window of rank `rank` of `ranks` when the slabs are split into runs as even as
    /// possible: `[rank · S / R, (rank + 1) · S / R)`.
    pub fn of_rank(rank: usize, ranks: usize, n_slabs_in_all: usize) -> Self {
        TimeWindow {
            slabs: rank * n_slabs_in_all / ranks..(rank + 1) * n_slabs_in_all / ranks,
            n_slabs_in_all,
        }
    }

    /// The frames its slabs need: `a − 1 ..= b + 1`, within the sequence's `S + 1` frames.
    pub fn frames(&self) -> Range<usize> {
        self.slabs.start.saturating_sub(1)..(self.slabs.end + 2).min(self.n_slabs_in_all + 1)
    }
}

/// The slabs of one time window, built from its frames ([`window_frames`]).
pub struct WindowSlabs {
    /// The slabs of the frames, from slab `offset` on.
    slabs: Vec<Slab>,
    offset: usize,
    window: TimeWindow,
}

impl WindowSlabs {
    /// `frames` holds the whole sequence's frames `offset ..` (at least those of
    /// [`TimeWindow::frames`]).
    pub fn new(
        frames: &MeshSequence,
        offset: usize,
        window: TimeWindow,
        params: &FlowParams,
    ) -> Result<Self, FlowError> {
        params.validate()?;
        let slabs = &window.slabs;
        let held = offset..offset + frames.n_slabs();
        if slabs.is_empty() || slabs.start < held.start || slabs.end > held.end {
            return Err(FlowError::CountMismatch {
                what: "slabs of the window's frames",
                expected: slabs.end.saturating_sub(offset),
                got: frames.n_slabs(),
            });
        }
        let channel_weights = params.channel_weights_for(frames.n_channels())?;
        let mut slabs = build_slabs(frames, &channel_weights)?;
        embed_where_needed(&mut slabs, frames, params)?;
        Ok(WindowSlabs {
            slabs,
            offset,
            window,
        })
    }

    /// The window's own slabs (not the ones beyond its ends).
    fn own(&self) -> &[Slab] {
        &self.slabs[self.local(&self.window.slabs)]
    }

    /// The window's share of the data's scales.
    pub fn scale_sums(&self, frames: &MeshSequence) -> ScaleSums {
        ScaleSums::measure(frames.mesh(), self.own())
    }

    /// The window's blocks, links and right-hand side with the whole sequence's `scales`.
    pub fn assemble(
        &self,
        frames: &MeshSequence,
        params: &FlowParams,
        scales: &DataScales,
    ) -> Result<SystemWindow, FlowError> {
        let weights = params.weights(scales)?;
        let links = time_links(&self.slabs, &weights);
        let system =
            SpaceTimeSystem::assemble(frames.mesh(), &self.slabs, &links, params, &weights);
        let mut window = system.window(self.local(&self.window.slabs));
        window.slabs = self.window.slabs.clone();
        window.n_slabs_in_all = self.window.n_slabs_in_all;
        Ok(window)
    }

    /// Global slabs as indices into the window's frames' slabs.
    fn local(&self, slabs: &Range<usize>) -> Range<usize> {
        slabs.start - self.offset..slabs.end - self.offset
    }
}
