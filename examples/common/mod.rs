//! Shared by the `paper_torus` and `graph_surface` examples: solving a sequence and reading
//! its flow in a parameter domain, comparing two such flows, writing the comparison as VTU,
//! 3D and parameter-domain PNGs and a table.

use meshflow::accuracy::angular_error;
use meshflow::chart::Chart;
use meshflow::flow::{FlowParams, FlowProblem, FlowResult, MeshSequence, SolveEvent};
use meshflow::format::vtk::NamedArray;
use meshflow::render::color_wheel::{flow_color, robust_max};
use meshflow::render::colormap::viridis;
use meshflow::render::{
    chart_picture, sequence_views, write_png, write_slab_pictures, FigureOptions, View,
};
use meshflow::run::write_slab_vtus;
use nalgebra::{Vector2, Vector3};
use std::path::Path;

/// A flow and its pull-back to the chart, `pixels[s][i]` in grid units per frame.
pub struct ChartFlow {
    pub result: FlowResult,
    pub pixels: Vec<Vec<Vector2<f64>>>,
}

/// Solves, reporting progress on stderr, and pulls the flow back to the chart.
pub fn solve_in_chart(
    sequence: &MeshSequence,
    chart: &Chart,
    params: &FlowParams,
    name: &str,
) -> Result<ChartFlow, meshflow::Error> {
    let problem = FlowProblem::new(sequence, params)?;
    let report = |event: SolveEvent| {
        if let SolveEvent::Iteration {
            iteration,
            relative_residual,
        } = event
        {
            eprint!("\r{name}: iteration {iteration}, residual {relative_residual:.1e}   ");
        }
    };
    let result = problem.solve(&report)?;
    eprintln!(
        "\r{name}: solved ({}, {} iterations)          ",
        result.method, result.iterations
    );
    let pixels = chart.pull_back(sequence.mesh(), &problem.slabs(), &result.intrinsic)?;
    Ok(ChartFlow { result, pixels })
}

/// Two flows of the same images in the same chart and their angular difference per slab and
/// vertex (degrees; each flow with a 1 appended as time component, as in the paper).
pub struct Comparison {
    pub names: [&'static str; 2],
    pub flows: [ChartFlow; 2],
    pub difference: Vec<Vec<f64>>,
}

impl Comparison {
    pub fn new(names: [&'static str; 2], flows: [ChartFlow; 2]) -> Self {
        let lift = |w: &Vector2<f64>| Vector3::new(w.x, w.y, 0.0);
        let difference = flows[0]
            .pixels
            .iter()
            .zip(&flows[1].pixels)
            .map(|(a, b)| {
                a.iter()
                    .zip(b)
                    .map(|(a, b)| angular_error(&lift(a), &lift(b)).to_degrees())
                    .collect()
            })
            .collect();
        Self {
            names,
            flows,
            difference,
        }
    }

    /// A flow scale shared by both flows' colour pictures: the robust maximum of all speeds.
    pub fn scale(&self) -> f64 {
        let speeds: Vec<f64> = self
            .flows
            .iter()
            .flat_map(|f| f.pixels.iter().flatten())
            .map(|w| w.norm())
            .collect();
        robust_max(&speeds)
    }

    /// Per slab: mean speed of each flow and mean and largest angular difference.
    pub fn print_table(&self) {
        let mean = |values: &[f64]| values.iter().sum::<f64>() / values.len() as f64;
        let speeds = |f: &ChartFlow, s: usize| -> Vec<f64> {
            f.pixels[s].iter().map(|w| w.norm()).collect()
        };
        println!(
            "{:>5} {:>16} {:>16} {:>11} {:>10}",
            "slab",
            format!("mean |w| {}", self.names[0]),
            format!("mean |w| {}", self.names[1]),
            "mean diff°",
            "max diff°"
        );
        for (s, difference) in self.difference.iter().enumerate() {
            println!(
                "{s:>5} {:>16.4} {:>16.4} {:>11.3} {:>10.2}",
                mean(&speeds(&self.flows[0], s)),
                mean(&speeds(&self.flows[1], s)),
                mean(difference),
                difference.iter().copied().fold(0.0, f64::max)
            );
        }
        println!("|w| in grid units per frame; diff = angular difference of the two flows");
    }

    /// One VTU per slab on frame `s` of `sequence` (embedded): the R^3 flow of the first model,
    /// both chart flows, their difference and the image; plus `NAME.pvd`.
    fn write_vtus(
        &self,
        out: &Path,
        name: &str,
        sequence: &MeshSequence,
    ) -> Result<(), meshflow::Error> {
        let vectors = self.flows[0]
            .result
            .vectors
            .as_ref()
            .expect("the first model is embedded");
        write_slab_vtus(out, name, sequence, |s| {
            let [first, second] = self.names.map(|n| format!("flow_grid_{n}"));
            vec![
                NamedArray::vectors("flow", &vectors[s]),
                NamedArray::vectors2(&first, &self.flows[0].pixels[s]),
                NamedArray::vectors2(&second, &self.flows[1].pixels[s]),
                NamedArray::scalars("angular_difference", &self.difference[s]),
                NamedArray::scalars("intensity", sequence.intensities(s)),
            ]
        })?;
        Ok(())
    }

    /// Everything the examples write: the VTU series `NAME_SSSS.vtu` + `NAME.pvd`, and for the
    /// first, middle and last slab the 3D pictures of the first model's flow seen from `view`
    /// and the parameter-domain pictures.
    pub fn write_outputs(
        &self,
        out: &Path,
        name: &str,
        sequence: &MeshSequence,
        grid: ChartGrid,
        view: View,
    ) -> Result<(), meshflow::Error> {
        self.write_vtus(out, name, sequence)?;
        let slabs = sequence.n_slabs();
        let chosen = [0, slabs / 2, slabs - 1];
        let vectors = self.flows[0]
            .result
            .vectors
            .as_ref()
            .expect("the first model is embedded");
        let views = sequence_views(sequence, vectors, None, chosen)?;
        let options = FigureOptions {
            view,
            ..FigureOptions::default()
        };
        write_slab_pictures(out, sequence.mesh().faces(), &views, &options, &|| {})?;
        for s in chosen {
            self.write_chart_pictures(out, sequence, s, grid)?;
        }
        Ok(())
    }

    /// Parameter-domain pictures of slab `s`: the image, both flows (Middlebury colours with
    /// x1 to the right and x2 downwards) and the angular difference (viridis, 0 to its
    /// maximum), one `grid.pixel_size²` block per vertex.
    fn write_chart_pictures(
        &self,
        out: &Path,
        sequence: &MeshSequence,
        s: usize,
        grid: ChartGrid,
    ) -> Result<(), meshflow::Error> {
        let scale = self.scale();
        let image: Vec<[f64; 3]> = sequence
            .intensities(s)
            .iter()
            .map(|&v| [v.clamp(0.0, 1.0); 3])
            .collect();
        let flow_colours = |f: &ChartFlow| -> Vec<[f64; 3]> {
            f.pixels[s]
                .iter()
                .map(|w| flow_color(w.x / scale, w.y / scale))
                .collect()
        };
        let largest = self.difference[s].iter().copied().fold(0.0, f64::max);
        let difference = self.difference[s]
            .iter()
            .map(|&d| viridis(d, 0.0, largest))
            .collect();
        let pictures = [
            ("image".to_string(), image),
            (
                format!("flow_{}", self.names[0]),
                flow_colours(&self.flows[0]),
            ),
            (
                format!("flow_{}", self.names[1]),
                flow_colours(&self.flows[1]),
            ),
            ("angular_difference".to_string(), difference),
        ];
        for (name, colours) in pictures {
            let picture = chart_picture(
                grid.rows,
                grid.cols,
                &grid.rows_of(&colours),
                grid.pixel_size,
            )?;
            write_png(&out.join(format!("{name}_{s:04}.png")), &picture)?;
        }
        Ok(())
    }
}

/// How a chart's vertices are laid out as picture rows and columns.
#[derive(Clone, Copy)]
pub struct ChartGrid {
    pub rows: usize,
    pub cols: usize,
    /// Whether vertex `c · rows + r` (column-major, as the torus grid) rather than `r · cols + c`.
    pub column_major: bool,
    pub pixel_size: u32,
}

impl ChartGrid {
    fn rows_of<T: Copy>(self, values: &[T]) -> Vec<T> {
        if !self.column_major {
            return values.to_vec();
        }
        (0..self.rows)
            .flat_map(|r| (0..self.cols).map(move |c| values[c * self.rows + r]))
            .collect()
    }
}
