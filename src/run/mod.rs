//! One command's output directory, the top of meshflow's I/O: what a run writes and how it
//! reads a run back.
//!
//! Every writer goes through [`crate::format::write_atomically`]: the bytes land in a
//! temporary file next to the target, which is renamed over it only when complete, so a
//! failed run never leaves a half-written output behind. Output directories are staged whole
//! ([`StagedDir`]): each holds exactly one run, marked by its manifest [`RUN_MANIFEST`], and
//! no output may replace one of the run's inputs ([`refuse_output_over_inputs`]).
//!
//! The flow (and its errors against a known one) goes out as NPY, ParaView VTU/PVD and glTF
//! ([`write_flow_outputs`]; over ranks, slab by slab as the ranks send their slabs:
//! [`write_flow_over_ranks`]), an analysis of it likewise ([`write_analysis_outputs`]), each
//! with a `summary.json`. A solve's output is read back, its input loaded as the solve loaded
//! it, by [`SolveInput::of_run`] and [`read_flow`].

mod analysis_output;
mod finished;
mod flow_output;
mod flow_over_ranks;
mod guard;
mod staging;
mod track_output;

pub use analysis_output::{
    analysis_arrays, analysis_json, file_faces, write_analysis_outputs, AnalysisArray,
};
pub use finished::{read_flow, run_file, RecordBase, RecordingRecord, SolveInput, SolveRecord};
pub use flow_output::{
    summary_json, track_scores_json, write_flow_outputs, write_run_input, write_slab_vtus,
    write_slab_vtus_with_cells, GroundTruthReport, OutputFormat, Scores, TrackReport,
};
pub use flow_over_ranks::{send_own_slabs, write_flow_over_ranks, WrittenFlow};
pub use guard::{refuse_output_over_inputs, OutputKind};
pub use staging::{
    input_files, remove_live_staging, Overwrite, RecordedInput, RunManifest, StagedDir,
    RUN_MANIFEST,
};
pub use track_output::{write_track_errors, TRACK_ERRORS_CSV, TRACK_ERRORS_VTU};
