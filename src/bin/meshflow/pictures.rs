//! PNG pictures of a flow: `meshflow render DIR` (from a solve output's VTU files) and
//! `meshflow solve … --png` (from the flow in memory). Both draw the chosen slabs with
//! [`write_slab_pictures`].

use crate::progress::{count_progress, during};
use meshflow::format::vtk::{read_pvd, read_vtu, VtuMesh};
use meshflow::format::IoError;
use meshflow::render::{
    write_chosen_slab_pictures, FigureOptions, RenderError, SlabSelection, SlabView, UpAxis,
    UpChoice, View,
};
use meshflow::run::{run_file, Overwrite, StagedDir};
use meshflow::Error;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// Picture options shared by `render`, `solve --png` and `analyze --png`: size, view, slabs.
#[derive(clap::Args)]
pub struct ViewArgs {
    /// Picture size in pixels, WIDTHxHEIGHT
    #[arg(long, default_value = "960x720", value_parser = parse_size)]
    size: (u32, u32),
    /// Direction from the surface to the camera, AZIMUTH,ELEVATION[,ROLL] in degrees: azimuth
    /// about the up axis, elevation above the plane across it, roll turning the picture
    /// counter-clockwise [default: -60,30 (solve), the solve's view (render)]
    #[arg(long, allow_hyphen_values = true)]
    view: Option<View>,
    /// The world axis that points up in pictures: x, y, z, -x, -y or -z [default: y for glTF
    /// input, else chosen from frame 0's shape, printed with the reason (solve); the solve's
    /// axis (render)]
    #[arg(long, allow_hyphen_values = true)]
    up: Option<UpAxis>,
    /// The slabs to draw: numbers, ranges FIRST-LAST and 'last', e.g. 0,5,10-20,last
    /// [default: all]
    #[arg(long, value_name = "LIST")]
    slabs: Option<SlabSelection>,
}

/// The pictures of a flow (`render`, `solve --png`): [`ViewArgs`] and the flow's scale.
#[derive(clap::Args)]
pub struct PictureArgs {
    #[command(flatten)]
    shown: ViewArgs,
    /// Flow speed at the rim of the colour wheel and of the reference arrow (default: the 99th
    /// percentile of all speeds for the wheel, the typical speed of the moving part for arrows)
    #[arg(long, value_name = "SPEED", allow_negative_numbers = true, value_parser = parse_positive)]
    flow_scale: Option<f64>,
}

impl std::ops::Deref for PictureArgs {
    type Target = ViewArgs;

    fn deref(&self) -> &ViewArgs {
        &self.shown
    }
}

impl PictureArgs {
    pub fn options(&self, view: View) -> FigureOptions {
        FigureOptions {
            width: self.size.0,
            height: self.size.1,
            view,
            flow_scale: self.flow_scale,
            ..FigureOptions::default()
        }
    }
}

impl ViewArgs {
    /// `base` with the angles of `--view` and the axis of `--up`, where given.
    pub fn view(&self, base: View) -> View {
        let up = self.up.unwrap_or(base.up);
        self.view.unwrap_or(base).with_up(up)
    }

    /// The default view about `default`'s up axis, with `--view` and `--up` where given; prints
    /// the up axis and why it was chosen.
    pub fn announced_view(&self, default: &UpChoice) -> View {
        match self.up {
            Some(up) => {
                stdout_line!("view: up axis {up} (--up)");
                self.view(View::default().with_up(up))
            }
            None => {
                stdout_line!("{}", up_axis_line(default, Some(default.alternative())));
                self.view(default.view())
            }
        }
    }

    /// The slabs of `--slabs` among `n_slabs`, all by default.
    pub fn slabs(&self, n_slabs: usize) -> Result<Vec<usize>, RenderError> {
        match &self.slabs {
            Some(selection) => selection.resolve(n_slabs),
            None => SlabSelection::all().resolve(n_slabs),
        }
    }

    /// `--size`: width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// Whether `--slabs` was given.
    pub fn chooses_slabs(&self) -> bool {
        self.slabs.is_some()
    }
}

/// "view: up axis y (chosen from the data: …; --up z to change)", the hint where `--up` can
/// change it.
pub fn up_axis_line(choice: &UpChoice, alternative: Option<UpAxis>) -> String {
    let hint = alternative
        .map(|axis| format!("; --up {axis} to change"))
        .unwrap_or_default();
    format!("view: up axis {} ({}{hint})", choice.axis, choice.reason)
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

/// A positive, finite number (a speed, a length).
pub(crate) fn parse_positive(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("'{text}' is not a positive number")),
    }
}

/// Draws the slabs `chosen` of `views` (all of the run's slabs, which share one camera and one
/// flow scale) into `out` as seen from `view`, with a progress bar.
pub fn draw(
    out: &Path,
    faces: &[[u32; 3]],
    views: &[SlabView],
    chosen: &[usize],
    args: &PictureArgs,
    view: View,
) -> Result<Vec<PathBuf>, Error> {
    let options = args.options(view);
    let bar = count_progress(chosen.len() as u64, "drawing slabs");
    let written = write_chosen_slab_pictures(out, faces, views, chosen, &options, &|| bar.inc(1));
    bar.finish();
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

    /// The bytes its arrays hold.
    fn bytes(&self) -> u64 {
        let mesh = &self.mesh;
        let values: usize = mesh.point_data.iter().map(|a| a.values.len()).sum();
        (24 * mesh.points.len() + 12 * mesh.triangles.len() + 8 * values) as u64
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

/// `meshflow render DIR`: reads `DIR/flow.pvd` and the slab files it lists (all of them before
/// drawing anything), then draws the chosen slabs into `out` (default `DIR`, where the new
/// pictures replace the earlier ones and the run's other files stay).
pub fn render_output(
    dir: &Path,
    out: Option<&Path>,
    overwrite: Overwrite,
    args: &PictureArgs,
) -> Result<(), Error> {
    let pvd = dir.join("flow.pvd");
    if std::fs::symlink_metadata(&pvd).is_err() && dir.join("flow.npy").exists() {
        let message = "this run has no ParaView files (solved with --format npy?); render reads \
                       flow.pvd and its flow_SSSS.vtu: solve again with vtu among the formats \
                       (the default), or with --png";
        return Err(IoError::format(dir, message).into());
    }
    let into_run = out.is_none_or(|out| same_directory(out, dir));
    let target = out.unwrap_or(dir);
    let mut staged = match into_run {
        // Pictures are the run's only PNG files.
        true => StagedDir::update(dir, overwrite, |name| !name.ends_with(".png"))?,
        false => StagedDir::create_apart_from(&[dir], target, overwrite)?,
    };
    staged.record_command(crate::command_line());
    let datasets = read_pvd(&run_file(dir, "flow.pvd")?)?;
    let slabs: Vec<SlabFile> = during(format!("reading {} slab files", datasets.len()), || {
        let mut held = 0u64;
        (datasets.into_iter())
            .map(|(time, path)| {
                let slab = SlabFile::read(time, path)?;
                // All slabs are held at once: together they must fit the memory limit too.
                held = held.saturating_add(slab.bytes());
                meshflow::limits::check_declared("the slab files read so far", held)
                    .map_err(|e| IoError::too_large(&pvd, e))?;
                Ok(slab)
            })
            .collect::<Result<_, Error>>()
    })?;
    let Some(first) = slabs.first() else {
        return Err(IoError::format(pvd, "lists no slabs").into());
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
    let chosen = args.slabs(slabs.len())?;
    let view = match solved_view(dir)? {
        Some(view) => args.view(view),
        None => args.announced_view(&UpChoice::from_shape(
            &first.mesh.points,
            &first.mesh.triangles,
        )),
    };
    let flows: Vec<Vec<Vector3<f64>>> = slabs.iter().map(SlabFile::flow).collect();
    let no_data: Vec<Option<Vec<bool>>> = (slabs.iter())
        .map(|slab| Some(slab.array("no_data")?.iter().map(|&m| m > 0.0).collect()))
        .collect();
    let views: Vec<SlabView> = (0..slabs.len())
        .zip(&flows)
        .map(|(s, flow)| SlabView {
            slab: s,
            time: slabs[s].time,
            positions: &slabs[s].mesh.points,
            intensity: slabs[s].array("intensity").expect("checked on reading"),
            flow,
            angular_error: slabs[s].array("angular_error"),
            warped_residual: slabs[s].array("warped_residual"),
            no_data: no_data[s].as_deref(),
        })
        .collect();
    let written = draw(
        staged.path(),
        &first.mesh.triangles,
        &views,
        &chosen,
        args,
        view,
    )
    .map_err(|e| staged.error_in_target(e))?;
    staged.commit()?;
    let drawn = match chosen.len() == slabs.len() {
        true => crate::plural(slabs.len(), "slab"),
        false => format!("{} of {} slabs", chosen.len(), slabs.len()),
    };
    stdout_line!(
        "{}: {drawn} -> {} pictures in {}",
        dir.display(),
        written.len(),
        target.display()
    );
    Ok(())
}

/// Whether two paths name the same existing directory.
fn same_directory(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// The view that `meshflow solve` recorded in `DIR/summary.json`; `None` for outputs without
/// one.
fn solved_view(dir: &Path) -> Result<Option<View>, Error> {
    let file = dir.join("summary.json");
    let text = match std::fs::read(&file) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(IoError::file(&file, e).into()),
    };
    let summary: serde_json::Value = serde_json::from_slice(&text)
        .map_err(|e| IoError::format(&file, format!("not JSON ({e})")))?;
    summary
        .get("view")
        .map(|view| serde_json::from_value(view.clone()))
        .transpose()
        .map_err(|e| IoError::format(&file, format!("'view' is not a view ({e})")).into())
}
