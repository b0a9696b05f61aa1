//! A tissue shell seen only as a noisy 4-D stack: the flow from the volumes alone, against the
//! material's known velocity.
//!
//! The scene: an ellipsoidal shell (the bright layer between ellipsoidal radii 0.85 and 1)
//! that turns about z by `ω` per frame and deforms (one semi-axis grows, another shrinks),
//! carrying "cells" (Gaussian blobs fixed to the material) in its layer, rendered into `K`
//! volumes of `N³` voxels with noise. A material point `X` of the reference ellipsoid is at
//! `x(X, t) = c + R(ωt) S(t) X` (`S` the semi-axes' scaling), so its velocity is
//! `v = R(ω ẑ × (S X) + Ṡ X)`.
//!
//! The pipeline is `meshflow surface STACK --shape closed`, `meshflow sample`, `meshflow solve`
//! (the library calls each makes): the surface found in the volumes and tracked, the volumes
//! sampled onto it, the flow solved with the defaults. The material's velocity
//! (`velocity.npy`: the mesh's motion plus the flow) is compared, tangentially, with the truth
//! at the slabs' middles: the relative endpoint error `Σ|v − v*| / Σ|v*|` and the median speed
//! ratio `|v| / |v*|` (where the true speed is at least a quarter of its median).
//!
//! `cargo run --release --example closed_shell [N] [K]` (default 64 voxels, 5 frames;
//! `SMOOTH=σ` and `VERTICES=N` set the sampling's smoothing, default 2 voxels, and the mesh's
//! size, default 4000). The stack is written to `out/closed_shell/stack.npy`, so the CLI can
//! be run on it too:
//!
//! ```text
//! meshflow surface out/closed_shell/stack.npy --shape closed --vertices 4000 --out S
//! meshflow sample out/closed_shell/stack.npy S
//! meshflow solve S --out FLOW
//! SURFACE=S FLOW=FLOW cargo run --release --example closed_shell   # scores that run too
//! ```

use meshflow::connection::vertex_normals;
use meshflow::flow::{compute_flow, tissue_velocity, FlowParams, MeshSequence};
use meshflow::surface::{find_surface, IsosurfaceOptions};
use meshflow::track::{track, TrackFrame, TrackOptions};
use meshflow::volume::{sample_sequence, SampleOptions, Volume};
use nalgebra::{Rotation3, Vector3};
use std::path::Path;
use std::time::Instant;

/// Turn per frame (radians).
const OMEGA: f64 = 0.04;
/// Relative growth of the x semi-axis, and shrinking of the z one, per frame.
const STRAIN: f64 = 0.01;

struct Scene {
    n: usize,
    /// Directions of the cells on the unit sphere.
    cells: Vec<Vector3<f64>>,
}

impl Scene {
    fn new(n: usize) -> Self {
        // A golden-spiral of cell directions, jittered by a fixed hash.
        let count = 80;
        let cells = (0..count)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
                let phi = i as f64 * 2.399_963 + 0.3 * ((i * 7919) % 13) as f64 / 13.0;
                let r = (1.0 - z * z).sqrt();
                Vector3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        Self { n, cells }
    }

    fn centre(&self) -> Vector3<f64> {
        Vector3::repeat((self.n - 1) as f64 / 2.0)
    }

    /// The semi-axes at time `t` (voxels).
    fn axes(&self, t: f64) -> Vector3<f64> {
        let r = 0.36 * self.n as f64;
        Vector3::new(
            r * (1.0 + STRAIN * t),
            0.9 * r,
            0.8 * r * (1.0 - STRAIN * t),
        )
    }

    /// The material point (on the reference ellipsoid's scale) at `x` and time `t`.
    fn material(&self, x: &Vector3<f64>, t: f64) -> Vector3<f64> {
        let turned =
            Rotation3::from_axis_angle(&Vector3::z_axis(), -OMEGA * t) * (x - self.centre());
        turned.component_div(&self.axes(t))
    }

    /// The image at `x` and time `t`, without noise.
    fn value(&self, x: &Vector3<f64>, t: f64) -> f64 {
        let m = self.material(x, t);
        let radius = m.norm();
        if !(0.85..1.0).contains(&radius) {
            return 20.0;
        }
        let direction = m / radius;
        let cells: f64 = (self.cells.iter())
            .map(|c| (-(direction - c).norm_squared() / (2.0 * 0.1f64.powi(2))).exp())
            .sum();
        60.0 + 120.0 * cells.min(1.0)
    }

    /// The material's velocity at `x` and time `t` (voxels per frame).
    fn velocity(&self, x: &Vector3<f64>, t: f64) -> Vector3<f64> {
        let m = self.material(x, t);
        let rate = Vector3::new(
            STRAIN / (1.0 + STRAIN * t),
            0.0,
            -STRAIN / (1.0 - STRAIN * t),
        );
        let scaled = m.component_mul(&self.axes(t));
        let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), OMEGA * t);
        rotation * (Vector3::z().cross(&scaled) * OMEGA + scaled.component_mul(&rate))
    }

    /// Frame `k` as a volume with noise of standard deviation 15.
    fn volume(&self, k: usize) -> Volume {
        let n = self.n;
        let mut values = Vec::with_capacity(n * n * n);
        let mut state = 0x9e37_79b9_7f4a_7c15u64 ^ k as u64;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let p = Vector3::new(x as f64, y as f64, z as f64);
                    // xorshift, two uniforms summed: a noise of standard deviation 15.
                    let mut uniform = || {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                    };
                    let noise = 15.0 * 6f64.sqrt() * (uniform() + uniform());
                    values.push((self.value(&p, k as f64) + noise) as f32);
                }
            }
        }
        Volume::new([n; 3], values, Vector3::repeat(1.0), Vector3::zeros()).expect("finite")
    }
}

fn main() -> Result<(), meshflow::Error> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let (n, k) = (
        args.first().copied().unwrap_or(64),
        args.get(1).copied().unwrap_or(5),
    );
    let scene = Scene::new(n);
    let out = Path::new("out/closed_shell");
    std::fs::create_dir_all(out).map_err(|e| meshflow::format::IoError::file(out, e))?;
    let start = Instant::now();
    let volumes: Vec<Volume> = (0..k).map(|f| scene.volume(f)).collect();
    let stack: Vec<f64> = (volumes.iter())
        .flat_map(|v| v.values().iter().map(|&x| f64::from(x)))
        .collect();
    let (nk, nn) = (k as u64, n as u64);
    meshflow::format::write_npy(&out.join("stack.npy"), &[nk, nn, nn, nn], &stack)?;
    println!(
        "{k} volumes of {n}³ voxels rendered in {:.1} s",
        start.elapsed().as_secs_f64()
    );

    // meshflow surface stack.npy --shape closed
    let start = Instant::now();
    let mut frames = Vec::new();
    for (f, volume) in volumes.iter().enumerate() {
        let found = find_surface(volume, &IsosurfaceOptions::default())?;
        let radii: Vec<f64> = (found.positions.iter())
            .map(|p| scene.material(p, f as f64).norm())
            .collect();
        let within = radii.iter().filter(|r| (0.85..1.0).contains(*r)).count();
        println!(
            "frame {f}: threshold {:.1}, {} vertices, {:.1} % of them within the bright layer",
            found.threshold,
            found.vertices,
            100.0 * within as f64 / radii.len() as f64
        );
        frames.push(TrackFrame {
            intensity: vec![0.0; found.positions.len()],
            positions: found.positions,
            faces: found.faces,
        });
    }
    let env = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f64>().ok());
    let options = TrackOptions {
        reference_vertices: Some(env("VERTICES").map_or(4000, |v| v as usize)),
        keep_uncovered: true,
        ..TrackOptions::default()
    };
    let tracked = track(&frames, None, &options)?;
    let mesh = tracked.sequence.mesh().clone();
    let positions: Vec<Vec<Vector3<f64>>> = (0..k)
        .map(|f| tracked.sequence.positions(f).expect("in R³").to_vec())
        .collect();
    println!(
        "surface: {} vertices tracked through {k} frames in {:.1} s",
        mesh.n_vertices(),
        start.elapsed().as_secs_f64()
    );

    // meshflow sample stack.npy SURFACE
    let sampling = SampleOptions {
        smoothing: env("SMOOTH"),
        ..SampleOptions::default()
    };
    let sampled = sample_sequence(&volumes, &mesh, &positions, &sampling)?;
    let sequence = MeshSequence::new(mesh.clone(), positions.clone(), sampled.values, None)?;

    // meshflow solve SURFACE
    let start = Instant::now();
    let result = compute_flow(&sequence, &FlowParams::default())?;
    let flow = result.vectors.as_ref().expect("in R³");
    let velocity = tissue_velocity(&sequence, flow);
    println!(
        "flow: {} slabs in {:.1} s",
        k - 1,
        start.elapsed().as_secs_f64()
    );

    score("library", &scene, &mesh, &positions, &velocity);
    // A CLI run on the same stack, if there is one (the commands in the module docs).
    if let (Some(surface), Some(flow)) = (std::env::var_os("SURFACE"), std::env::var_os("FLOW")) {
        let loaded = meshflow::load::load_sequence(surface.as_ref(), &Default::default())?;
        let array = meshflow::format::read_npy(&Path::new(&flow).join("velocity.npy"))?;
        let v = loaded.vertex_map.n_file_vertices();
        let velocity: Vec<Vec<Vector3<f64>>> = (array.data.chunks(3 * v))
            .map(|slab| {
                let rows: Vec<Vector3<f64>> =
                    slab.chunks(3).map(Vector3::from_column_slice).collect();
                let map = &loaded.vertex_map;
                (0..map.n_mesh_vertices())
                    .map(|m| rows[map.representative(m)])
                    .collect()
            })
            .collect();
        let positions: Vec<Vec<Vector3<f64>>> = (0..loaded.sequence.n_frames())
            .map(|f| loaded.sequence.positions(f).expect("in R³").to_vec())
            .collect();
        score("CLI", &scene, loaded.sequence.mesh(), &positions, &velocity);
    }
    Ok(())
}

/// The tangential errors of `velocity[s][i]` (mesh vertex `i` of `mesh`, slab `s`) against
/// the scene's, at the slabs' middles (module docs).
fn score(
    what: &str,
    scene: &Scene,
    mesh: &meshflow::mesh::Mesh,
    positions: &[Vec<Vector3<f64>>],
    velocity: &[Vec<Vector3<f64>>],
) {
    let (mut error, mut truth, mut ratios) = (0.0, 0.0, Vec::new());
    for (s, estimated) in velocity.iter().enumerate() {
        let middle: Vec<Vector3<f64>> = (positions[s].iter().zip(&positions[s + 1]))
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        let normals = vertex_normals(mesh, &middle);
        let tangential = |v: Vector3<f64>, n: &Vector3<f64>| v - n * n.dot(&v);
        let pairs: Vec<(Vector3<f64>, Vector3<f64>)> = (middle.iter().zip(&normals))
            .zip(estimated)
            .map(|((p, n), v)| {
                let exact = tangential(scene.velocity(p, s as f64 + 0.5), n);
                (tangential(*v, n), exact)
            })
            .collect();
        let speeds: Vec<f64> = pairs.iter().map(|(_, t)| t.norm()).collect();
        let typical = meshflow::statistics::median(speeds);
        for (v, t) in &pairs {
            error += (v - t).norm();
            truth += t.norm();
            if t.norm() >= 0.25 * typical {
                ratios.push(v.norm() / t.norm());
            }
        }
    }
    let relative = error / truth;
    let ratio = meshflow::statistics::median(ratios);
    println!(
        "{what}: material velocity, tangential: relative endpoint error {:.1} % (target ≤ 25 %), \
         median speed ratio {ratio:.3} (target 0.8–1.2)",
        100.0 * relative
    );
}
