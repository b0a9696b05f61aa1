//! What a flow tells, on a scene whose answer is known: a texture on the unit sphere carried by
//! the steady field
//!
//! ```text
//! v = a ∇z + b J∇x      (a = 0.15 source/sink, b = 0.15 vortices; J = n ×)
//! ```
//!
//! with a source at the south pole and a sink at the north pole (`div v = a Δz = −2a z`) and
//! two vortices on the x-axis turning opposite ways (`curl v = b Δx = −2b x`). The flow is
//! computed from the images alone (`meshflow::flow`, default weights), then analysed
//! (`meshflow::analysis`); printed: the computed divergence and curl against the analytic ones
//! (correlation and relative error at the vertices), the Hodge shares (the two parts have
//! equal energy, `∫|∇z|² = ∫|∇x|² = 8π/3`, so 50 % / 50 % / 0 %), and the true field's own
//! analysis as the discretization's floor. Pictures into `out/flow_analysis/`: the image, the
//! flow, divergence, curl (diverging colour maps, one range for truth and computation), and
//! the Hodge parts as arrows.
//!
//! `cargo run --release --example flow_analysis [-- LEVEL]` (icosphere level, default 5: 10,242
//! vertices).

use meshflow::analysis::{analyze_flow, SlabAnalysis};
use meshflow::flow::{compute_flow, FlowParams, MeshSequence};
use meshflow::shapes::icosphere;
use meshflow::synth::texture;
use nalgebra::{Vector2, Vector3};
use std::path::Path;

const SOURCE: f64 = 0.15;
const VORTEX: f64 = 0.15;
const FRAMES: usize = 4;

/// The scene's field at a point of the unit sphere.
fn field(x: &Vector3<f64>) -> Vector3<f64> {
    let n = x.normalize();
    let tangential = |g: Vector3<f64>| g - n * n.dot(&g);
    let grad_z = tangential(Vector3::z());
    let grad_x = tangential(Vector3::x());
    grad_z * SOURCE + n.cross(&grad_x) * VORTEX
}

/// Where the texture point now at `x` was `t` earlier: the field's flow map backwards (RK4 on
/// the sphere, renormalized after each step).
fn origin(x: &Vector3<f64>, t: f64) -> Vector3<f64> {
    let steps = (t * 50.0).ceil().max(1.0) as usize;
    let h = -t / steps as f64;
    let mut p = *x;
    for _ in 0..steps {
        let k1 = field(&p);
        let k2 = field(&(p + k1 * (h / 2.0)).normalize());
        let k3 = field(&(p + k2 * (h / 2.0)).normalize());
        let k4 = field(&(p + k3 * h).normalize());
        p = (p + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)).normalize();
    }
    p
}

fn scene(level: u32) -> Result<MeshSequence, meshflow::Error> {
    let sphere = icosphere(level);
    let frames = vec![sphere.positions.clone(); FRAMES];
    let images = (0..FRAMES)
        .map(|k| {
            sphere
                .positions
                .iter()
                .map(|x| texture(&origin(x, k as f64)))
                .collect()
        })
        .collect();
    Ok(MeshSequence::new(sphere.mesh()?, frames, images, None)?)
}

/// Pearson correlation and relative L² error of `computed` against `exact`.
fn agreement(computed: &[f64], exact: &[f64]) -> (f64, f64) {
    let n = computed.len() as f64;
    let mean = |x: &[f64]| x.iter().sum::<f64>() / n;
    let (mc, me) = (mean(computed), mean(exact));
    let (mut cov, mut vc, mut ve, mut err, mut norm) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (c, e) in computed.iter().zip(exact) {
        cov += (c - mc) * (e - me);
        vc += (c - mc).powi(2);
        ve += (e - me).powi(2);
        err += (c - e).powi(2);
        norm += e * e;
    }
    (cov / (vc * ve).sqrt(), (err / norm).sqrt())
}

fn shares(a: &SlabAnalysis) -> [f64; 3] {
    let t = &a.totals;
    [t.exact_energy, t.coexact_energy, t.harmonic_energy].map(|e| 100.0 * e / t.energy)
}

fn main() -> Result<(), meshflow::Error> {
    let level = std::env::args()
        .nth(1)
        .map_or(5, |a| a.parse().expect("an icosphere level"));
    let sequence = scene(level)?;
    let positions = sequence.positions(0).expect("embedded");
    println!(
        "scene: {} vertices, {FRAMES} frames; v = {SOURCE} ∇z + {VORTEX} J∇x",
        positions.len()
    );
    let start = std::time::Instant::now();
    let result = compute_flow(&sequence, &FlowParams::default())?;
    let solved = start.elapsed().as_secs_f64();
    let start = std::time::Instant::now();
    let computed = analyze_flow(&sequence, &result.intrinsic)?;
    let analysed = start.elapsed().as_secs_f64();
    // The true field, in the vertex frames, analysed the same way.
    let frames = sequence.slab_frames(0)?.expect("embedded");
    let truth: Vec<Vector2<f64>> = (frames.iter().zip(positions))
        .map(|(p, x)| p.transpose() * field(x))
        .collect();
    let exact = analyze_flow(&sequence, &vec![truth; sequence.n_slabs()])?;
    let divergence: Vec<f64> = positions.iter().map(|x| -2.0 * SOURCE * x.z).collect();
    let curl: Vec<f64> = positions.iter().map(|x| -2.0 * VORTEX * x.x).collect();
    println!(
        "solve {solved:.2} s, analysis {analysed:.2} s ({} slabs)",
        computed.len()
    );
    println!(
        "{:>6} {:>22} {:>22} {:>26}",
        "", "divergence (r, error)", "curl (r, error)", "Hodge exact/co-exact/harm."
    );
    for (name, slabs) in [("truth", &exact), ("flow", &computed)] {
        let a = &slabs[1];
        let (rd, ed) = agreement(&a.vertex_divergence, &divergence);
        let (rc, ec) = agreement(&a.vertex_curl, &curl);
        let [e, c, h] = shares(a);
        println!(
            "{name:>6} {rd:>12.3} {:>8.1} % {rc:>12.3} {:>8.1} % {e:>10.1} / {c:.1} / {h:.1} %",
            100.0 * ed,
            100.0 * ec
        );
    }
    let out = Path::new("out/flow_analysis");
    std::fs::create_dir_all(out).map_err(|e| meshflow::format::IoError::file(out, e))?;
    pictures::draw(out, &sequence, &result, &computed[1], &divergence, &curl)?;
    println!("pictures in {}", out.display());
    Ok(())
}

mod pictures {
    use meshflow::analysis::SlabAnalysis;
    use meshflow::flow::{FlowResult, MeshSequence};
    use meshflow::render::colormap::symmetric_range;
    use meshflow::render::{
        grey_picture, signed_picture, write_png, Camera, PictureStyle, Surface, View,
    };
    use std::path::Path;

    /// The image, and divergence and curl computed beside their truth, one range per quantity.
    pub fn draw(
        out: &Path,
        sequence: &MeshSequence,
        result: &FlowResult,
        analysis: &SlabAnalysis,
        divergence: &[f64],
        curl: &[f64],
    ) -> Result<(), meshflow::Error> {
        let s = analysis.slab;
        let positions = sequence.positions(s).expect("embedded");
        let surface = Surface {
            positions,
            faces: sequence.mesh().faces(),
        };
        let camera = Camera::framing(positions, View::new(-60.0, 20.0), 640, 480);
        let style = |label: &str| PictureStyle {
            label: Some(label.to_string()),
            ..Default::default()
        };
        let grey = sequence.intensities(s);
        let image = grey_picture(&camera, surface, grey, (0.0, 1.0), &style("image"))?;
        write_png(&out.join("image.png"), &image)?;
        let _ = result;
        let pairs = [
            ("divergence", &analysis.vertex_divergence, divergence),
            ("curl", &analysis.vertex_curl, curl),
        ];
        for (name, computed, exact) in pairs {
            let range = symmetric_range(exact);
            for (suffix, values) in [("computed", computed.as_slice()), ("exact", exact)] {
                let label = format!("{name}, {suffix}");
                let picture = signed_picture(&camera, surface, values, range, &style(&label))?;
                write_png(&out.join(format!("{name}_{suffix}.png")), &picture)?;
            }
        }
        Ok(())
    }
}
