//! `meshflow analyze RUN --out DIR`: what a finished run's flow tells (`meshflow::analysis`):
//! divergence, curl, Helmholtz–Hodge parts and the tissue's strain rate, as NPY, ParaView and
//! `summary.json`, with a table per slab on stdout and, with `--png`, pictures.

use crate::pictures::ViewArgs;
use crate::progress::{count_progress, during};
use crate::run::FinishedRun;
use meshflow::analysis::{analyze_flow, SlabAnalysis};
use meshflow::flow::smoothed_over_length;
use meshflow::load::LoadedSequence;
use meshflow::render::color_wheel::arrow_scale;
use meshflow::render::colormap::symmetric_range;
use meshflow::render::text::format_number;
use meshflow::render::{
    series_chart, signed_picture, write_png, Camera, PictureStyle, Series, Surface, UpChoice,
};
use meshflow::run::{write_analysis_outputs, OutputFormat, Overwrite};
use meshflow::Error;
use rayon::prelude::*;
use std::path::Path;

/// `meshflow analyze`'s request.
pub struct AnalyzeRequest<'a> {
    pub run: &'a Path,
    pub out: &'a Path,
    pub overwrite: Overwrite,
    /// `--format`: npy, vtu.
    pub formats: &'a [OutputFormat],
    /// `--png` with its picture options.
    pub pictures: Option<&'a ViewArgs>,
    /// `--tissue-scale`: the drawn fields smoothed along the surface over this length.
    pub tissue_scale: Option<f64>,
}

pub fn analyze(request: AnalyzeRequest) -> Result<(), Error> {
    let AnalyzeRequest {
        run,
        out,
        overwrite,
        formats,
        pictures,
        tissue_scale,
    } = request;
    let input = crate::run::solve_input(run)?;
    let staged = crate::run::stage_output(run, &input, &[], out, overwrite)?;
    let FinishedRun { loaded, flow, .. } = FinishedRun::read(run, input)?;
    let start = std::time::Instant::now();
    let slabs = during("analysing the flow", || {
        analyze_flow(&loaded.sequence, &flow)
    })?;
    let seconds = start.elapsed().as_secs_f64();
    during(format!("writing {}", out.display()), || {
        write_analysis_outputs(staged.path(), &loaded, &slabs, run, formats)
    })
    .map_err(|e| staged.in_target(e))?;
    if let Some(args) = pictures {
        let speeds: Vec<f64> = flow.iter().flatten().map(|u| u.norm()).collect();
        let scales = DrawnScales {
            floor: rate_floor(&slabs, &speeds),
            tissue: tissue_scale,
        };
        let written = draw(staged.path(), &loaded, &slabs, args, scales)
            .map_err(|e| staged.error_in_target(e))?;
        stdout_line!("pictures: {written} PNG files in {}", out.display());
    }
    staged.commit()?;
    stdout_line!(
        "{}: {} x {} faces analysed in {seconds:.2} s -> {}",
        run.display(),
        crate::plural(slabs.len(), "slab"),
        loaded.sequence.mesh().n_faces(),
        out.display()
    );
    print_table(&loaded.sequence.times()[..slabs.len()], &slabs);
    Ok(())
}

/// Per slab: the means over the surface and the shares of the Hodge parts in `∫|U|²`.
fn print_table(times: &[f64], slabs: &[SlabAnalysis]) {
    stdout_line!(
        "{:>5} {:>10} {:>10} {:>10} {:>11} {:>11} {:>11} {:>10}  Hodge exact / co-exact / harmonic",
        "slab",
        "time",
        "area",
        "speed",
        "divergence",
        "curl",
        "areal rate",
        "shear"
    );
    for (a, t) in slabs.iter().zip(times) {
        let totals = &a.totals;
        let share = |part: f64| 100.0 * part / totals.energy.max(f64::MIN_POSITIVE);
        stdout_line!(
            "{:>5} {:>10.4} {:>10.4e} {:>10.3e} {:>11.3e} {:>11.3e} {:>11.3e} {:>10.3e}  {:.1} % / {:.1} % / {:.1} %",
            a.slab,
            t,
            totals.area,
            totals.mean_speed,
            totals.mean_divergence,
            totals.mean_curl,
            totals.mean_areal_rate,
            totals.mean_shear_rate,
            share(totals.exact_energy),
            share(totals.coexact_energy),
            share(totals.harmonic_energy),
        );
    }
}

/// The quantities drawn per slab: name, and values per vertex.
type Drawn = (&'static str, fn(&SlabAnalysis, &LoadedSequence) -> Vec<f64>);

const DRAWN: [Drawn; 3] = [
    ("divergence", |a, _| a.vertex_divergence.clone()),
    ("curl", |a, _| a.vertex_curl.clone()),
    ("areal_rate", |a, loaded| {
        let areal: Vec<f64> = a.strain.iter().map(|d| d.areal).collect();
        face_values_at_vertices(loaded, &areal)
    }),
];

/// Per vertex, the mean of its faces' values (what a picture of a face quantity shows).
fn face_values_at_vertices(loaded: &LoadedSequence, values: &[f64]) -> Vec<f64> {
    let mesh = loaded.sequence.mesh();
    (0..mesh.n_vertices())
        .map(|i| {
            let fan = mesh.vertex_fan(i);
            fan.iter().map(|c| values[c.face as usize]).sum::<f64>() / fan.len() as f64
        })
        .collect()
}

/// How the drawn rates are scaled: the least half-range of their colours, and the length they
/// are smoothed over first.
#[derive(Clone, Copy, Debug)]
struct DrawnScales {
    floor: f64,
    tissue: Option<f64>,
}

/// The least half-range of the rate pictures, `2 U / ρ`: the curl of the whole surface turning
/// at the typical speed `U` ([`arrow_scale`] of the speeds), `ρ = √(A / 4π)` its radius. A
/// field as strong as that is drawn saturated; discretization noise (±0.03 on the rigidly
/// turning sample sphere, whose curl is about 0.1) stays pale instead of filling the range.
fn rate_floor(slabs: &[SlabAnalysis], speeds: &[f64]) -> f64 {
    let area = slabs.first().map_or(0.0, |a| a.totals.area);
    let radius = (area / (4.0 * std::f64::consts::PI)).sqrt();
    match radius > 0.0 {
        true => 2.0 * arrow_scale(speeds) / radius,
        false => 0.0,
    }
}

/// `divergence_SSSS.png`, `curl_SSSS.png`, `areal_rate_SSSS.png` for the chosen slabs (one
/// camera for the run, one symmetric range per quantity over all slabs, at least
/// `scales.floor`; each field smoothed over `scales.tissue` first, where given) and
/// `time_series.png`; the number of files written.
fn draw(
    dir: &Path,
    loaded: &LoadedSequence,
    slabs: &[SlabAnalysis],
    args: &ViewArgs,
    scales: DrawnScales,
) -> Result<usize, Error> {
    let sequence = &loaded.sequence;
    let view = args.announced_view(&UpChoice::of_sequence(loaded));
    let chosen = args.slabs(slabs.len())?;
    let (width, height) = args.size();
    let everywhere: Vec<_> = (0..sequence.n_frames())
        .flat_map(|k| sequence.positions(k).unwrap_or_default().iter().copied())
        .collect();
    let camera = Camera::framing(&everywhere, view, width, height);
    let values: Vec<Vec<Vec<f64>>> = DRAWN
        .iter()
        .map(|(_, of)| {
            (slabs.iter())
                .map(|a| tissue_scaled(loaded, a.slab, of(a, loaded), scales.tissue))
                .collect::<Result<_, Error>>()
        })
        .collect::<Result<_, Error>>()?;
    let ranges: Vec<(f64, f64)> = values
        .iter()
        .map(|v| {
            let (_, m) = symmetric_range(&v.concat());
            let m = m.max(scales.floor);
            (-m, m)
        })
        .collect();
    let smoothed = match scales.tissue {
        Some(length) => format!("  smoothed over {}", format_number(length)),
        None => String::new(),
    };
    let bar = count_progress(chosen.len() as u64, "drawing slabs");
    let drawn: Result<Vec<()>, Error> = chosen
        .par_iter()
        .map(|&s| {
            let surface = Surface {
                positions: sequence.positions(s).unwrap_or_default(),
                faces: sequence.mesh().faces(),
            };
            for (q, (name, _)) in DRAWN.iter().enumerate() {
                let time = format_number(sequence.times()[s]);
                let style = PictureStyle {
                    label: Some(format!("{name}  slab {s}  t = {time}{smoothed}")),
                    ..Default::default()
                };
                let picture = signed_picture(&camera, surface, &values[q][s], ranges[q], &style)?;
                write_png(&dir.join(format!("{name}_{s:04}.png")), &picture)?;
            }
            bar.inc(1);
            Ok(())
        })
        .collect();
    bar.finish();
    drawn?;
    write_png(
        &dir.join("time_series.png"),
        &time_series(sequence.times(), slabs)?,
    )?;
    Ok(DRAWN.len() * chosen.len() + 1)
}

/// `values` (per vertex of slab `s`'s frame) smoothed over `length` along the surface
/// ([`smoothed_over_length`]), or as they are.
fn tissue_scaled(
    loaded: &LoadedSequence,
    s: usize,
    values: Vec<f64>,
    length: Option<f64>,
) -> Result<Vec<f64>, Error> {
    let Some(length) = length else {
        return Ok(values);
    };
    let smoothed = smoothed_over_length(&loaded.sequence, s, &[&values], length)?;
    Ok(smoothed.into_iter().next().expect("one field"))
}

/// The means over the surface per slab, against the slabs' start times.
fn time_series(
    times: &[f64],
    slabs: &[SlabAnalysis],
) -> Result<image::RgbImage, meshflow::render::RenderError> {
    let column = |f: fn(&meshflow::analysis::SlabTotals) -> f64| -> Vec<f64> {
        slabs.iter().map(|a| f(&a.totals)).collect()
    };
    let (divergence, curl) = (column(|t| t.mean_divergence), column(|t| t.mean_curl));
    let (areal, shear) = (column(|t| t.mean_areal_rate), column(|t| t.mean_shear_rate));
    let series = [
        Series {
            name: "mean divergence",
            values: &divergence,
        },
        Series {
            name: "mean curl",
            values: &curl,
        },
        Series {
            name: "mean areal rate",
            values: &areal,
        },
        Series {
            name: "mean shear rate",
            values: &shear,
        },
    ];
    let x = &times[..slabs.len()];
    series_chart(
        "means over the surface, per slab (1/time)",
        "time",
        x,
        &series,
        960,
        540,
    )
}
