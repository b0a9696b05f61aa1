//! Arguments several commands share: the input mesh options, `--force`, and where volumes
//! lie in space.

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

/// Where volumes lie in space (`sample`, `surface --shape closed`).
#[derive(clap::Args)]
pub(crate) struct VolumePlacement {
    /// Voxel size x,y,z in the surface's units [default: from ImageJ TIFF or OME-Zarr
    /// metadata, else 1,1,1]
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    pub(crate) voxel_size: Option<Vec<f64>>,
    /// Position of voxel (0, 0, 0), x,y,z
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    pub(crate) origin: Option<Vec<f64>>,
    /// OME-Zarr images and ImageJ hyperstack TIFFs: the channel to read [default: 0]
    #[arg(long, value_name = "C")]
    pub(crate) channel: Option<usize>,
    /// OME-Zarr images: the resolution level to read, 0 the finest [default: 0]
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub(crate) resolution_level: usize,
}

impl VolumePlacement {
    pub(crate) fn options(&self) -> Result<meshflow::volume::VolumeOptions, meshflow::Error> {
        Ok(meshflow::volume::VolumeOptions {
            voxel_size: triple(&self.voxel_size, "--voxel-size")?,
            origin: triple(&self.origin, "--origin")?.unwrap_or_default(),
            channel: self.channel,
            resolution_level: self.resolution_level,
        })
    }
}

/// Three numbers x,y,z of `name`, if given.
fn triple(
    values: &Option<Vec<f64>>,
    name: &str,
) -> Result<Option<nalgebra::Vector3<f64>>, meshflow::Error> {
    match values.as_deref() {
        None => Ok(None),
        Some(&[x, y, z]) => Ok(Some(nalgebra::Vector3::new(x, y, z))),
        Some(other) => Err(crate::usage(format!(
            "{name} takes three numbers x,y,z, got {}",
            other.len()
        ))),
    }
}
