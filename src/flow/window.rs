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

/// The slabs of rank `rank` of `ranks` when `n_slabs` are split into runs as even as possible:
/// `[rank · S / R, (rank + 1) · S / R)`.
pub fn rank_slabs(rank: usize, ranks: usize, n_slabs: usize) -> Range<usize> {
    rank * n_slabs / ranks..(rank + 1) * n_slabs / ranks
}

/// The frames that the slabs `window` of a sequence of `n_frames` frames need.
pub fn window_frames(window: &Range<usize>, n_frames: usize) -> Range<usize> {
    window.start.saturating_sub(1)..(window.end + 2).min(n_frames)
}

/// The slabs of one time window, built from its frames ([`window_frames`]).
pub struct WindowSlabs {
    /// The slabs of the frames, from slab `offset` on.
    slabs: Vec<Slab>,
    offset: usize,
    window: Range<usize>,
}

impl WindowSlabs {
    /// `frames` holds the whole sequence's frames `offset ..` (at least up to the frame after
    /// the window's last slab, and from the one before its first where there is one).
    pub fn new(
        frames: &MeshSequence,
        offset: usize,
        window: Range<usize>,
        params: &FlowParams,
    ) -> Result<Self, FlowError> {
        params.validate()?;
        if window.is_empty() || window.start < offset || window.end > offset + frames.n_slabs() {
            return Err(FlowError::CountMismatch {
                what: "slabs of the window's frames",
                expected: window.end.saturating_sub(offset),
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
        &self.slabs[self.window.start - self.offset..self.window.end - self.offset]
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
        Ok(system.window(self.window.start - self.offset..self.window.end - self.offset))
    }
}
