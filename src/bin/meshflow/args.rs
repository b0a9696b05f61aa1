//! Arguments several commands share: the input mesh options and `--force`.

use meshflow::load::LoadOptions;

use meshflow::run::Overwrite;

#[derive(clap::Args)]
pub(crate) struct ForceArg {
    /// Write into the output directory even if it holds files that meshflow did not write
    /// (they stay; without --force such a directory is refused)
    #[arg(long)]
    pub(crate) force: bool,
}

impl ForceArg {
    pub(crate) fn overwrite(&self) -> Overwrite {
        match self.force {
            true => Overwrite::Force,
            false => Overwrite::EarlierRun,
        }
    }
}

/// How the mesh is built from the files' faces (`solve` and `operators`).
#[derive(clap::Args)]
pub(crate) struct MeshArgs {
    /// Keep coincident vertices apart (default: weld seam copies, which exporters split at
    /// texture seams: coincident vertices joined by coincident edges, never where the surface
    /// only touches itself)
    #[arg(long)]
    pub(crate) no_weld: bool,
    /// Welding distance relative to the bounding-box diagonal of frame 0 (0: bitwise equal
    /// positions)
    #[arg(long, value_name = "REL", default_value_t = LoadOptions::DEFAULT_WELD_TOLERANCE, allow_negative_numbers = true)]
    pub(crate) weld_tolerance: f64,
    /// Split non-manifold edges and vertices into manifold pieces, cut non-orientable surfaces
    /// open, drop faces with a repeated vertex and duplicate faces (default: refuse them)
    #[arg(long)]
    pub(crate) repair: bool,
}

impl MeshArgs {
    pub(crate) fn options(&self) -> LoadOptions {
        LoadOptions {
            weld: !self.no_weld,
            weld_tolerance: self.weld_tolerance,
            repair: self.repair,
            ..LoadOptions::default()
        }
    }
}
