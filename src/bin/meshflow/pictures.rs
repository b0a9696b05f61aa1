//! PNG pictures of a flow: `meshflow render DIR` (from a solve output's VTU files) and
//! `meshflow solve … --png` (from the flow in memory). Both draw every slab with
//! [`write_slab_pictures`].

use crate::progress::count_progress;
use meshflow::io::vtk::{read_pvd, read_vtu, VtuMesh};
use meshflow::io::IoError;
use meshflow::render::{write_slab_pictures, FigureOptions, SlabView, View};
use meshflow::Error;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// Picture options shared by `render` and `solve --png`.
#[derive(clap::Args)]
pub struct PictureArgs {
    /// Picture size in pixels, WIDTHxHEIGHT
    #[arg(long, default_value = "960x720", value_parser = parse_size)]
    size: (u32, u32),
    /// Direction from the surface to the camera, AZIMUTH,ELEVATION in degrees (azimuth from +x
    /// towards +y, elevation above the xy-plane; +z is up)
    #[arg(long, default_value = "-60,30", allow_hyphen_values = true)]
    view: View,
    /// Flow speed at the rim of the colour wheel and of the reference arrow (default: the 99th
    /// percentile of all speeds)
    #[arg(long, value_name = "SPEED", allow_negative_numbers = true, value_parser = parse_speed)]
    flow_scale: Option<f64>,
}

impl PictureArgs {
    fn options(&self) -> FigureOptions {
        FigureOptions {
            width: self.size.0,
            height: self.size.1,
            view: self.view,
            flow_scale: self.flow_scale,
            ..FigureOptions::default()
        }
    }
}

fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let parsed = text
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)));
    match parsed {
        Some((w, h)) if (16..=8192).contains(&w) && (16..=8192).contains(&h) => Ok((w, h)),
        _ => Err(format!(
            "'{text}' is not a size WIDTHxHEIGHT with 16 to 8192 pixels a side, e.g. 960x720"
        )),
    }
}

fn parse_speed(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(speed) if speed.is_finite() && speed > 0.0 => Ok(speed),
        _ => Err(format!("'{text}' is not a positive speed")),
    }
}

/// Draws every slab of `views` into `out`, with a progress bar.
pub fn draw(
    out: &Path,
    faces: &[[u32; 3]],
    views: &[SlabView],
    args: &PictureArgs,
) -> Result<Vec<PathBuf>, Error> {
    let options = args.options();
    let bar = count_progress(views.len() as u64, "drawing slabs");
    let written = write_slab_pictures(out, faces, views, &options, &|| bar.inc(1));
    bar.finish_and_clear();
    written
}

/// One slab of a solve output, as read from its `.vtu` file.
struct SlabFile {
    time: f64,
    path: PathBuf,
    mesh: VtuMesh,
}

impl SlabFile {
    fn read(time: f64, path: PathBuf) -> Result<Self, Error> {
        let mesh = read_vtu(&path)?;
        for (name, components) in [("flow", 3), ("intensity", 1)] {
            let found = mesh.point_array(name).map(|a| a.components);
            if found != Some(components) {
                return Err(IoError::format(
                    &path,
                    format!(
                        "no point array '{name}' with {components} component(s); \
                         is this a `meshflow solve` output?"
                    ),
                )
                .into());
            }
        }
        Ok(Self { time, path, mesh })
    }

    fn flow(&self) -> Vec<Vector3<f64>> {
        let values = &self
            .mesh
            .point_array("flow")
            .expect("checked on reading")
            .values;
        values
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect()
    }

    fn array(&self, name: &str) -> Option<&[f64]> {
        self.mesh
            .point_array(name)
            .filter(|a| a.components == 1)
            .map(|a| a.values.as_slice())
    }
}

/// `meshflow render DIR`: reads `DIR/flow.pvd` and every slab file it lists (all of them before
/// drawing anything), then draws them into `out`.
pub fn render_output(dir: &Path, out: &Path, args: &PictureArgs) -> Result<(), Error> {
    let datasets = read_pvd(&dir.join("flow.pvd"))?;
    let slabs: Vec<SlabFile> = datasets
        .into_iter()
        .map(|(time, path)| SlabFile::read(time, path))
        .collect::<Result<_, _>>()?;
    let Some(first) = slabs.first() else {
        return Err(IoError::format(dir.join("flow.pvd"), "lists no slabs").into());
    };
    if let Some(other) = slabs
        .iter()
        .find(|s| s.mesh.triangles != first.mesh.triangles)
    {
        return Err(IoError::format(
            &other.path,
            format!(
                "its triangles differ from those of {}",
                first.path.display()
            ),
        )
        .into());
    }
    std::fs::create_dir_all(out).map_err(|e| IoError::file(out, e))?;
    let flows: Vec<Vec<Vector3<f64>>> = slabs.iter().map(SlabFile::flow).collect();
    let views: Vec<SlabView> = slabs
        .iter()
        .zip(&flows)
        .enumerate()
        .map(|(s, (slab, flow))| SlabView {
            slab: s,
            time: slab.time,
            positions: &slab.mesh.points,
            intensity: slab.array("intensity").expect("checked on reading"),
            flow,
            angular_error: slab.array("angular_error"),
        })
        .collect();
    let written = draw(out, &first.mesh.triangles, &views, args)?;
    println!(
        "{}: {} slabs -> {} pictures in {}",
        dir.display(),
        slabs.len(),
        written.len(),
        out.display()
    );
    Ok(())
}
