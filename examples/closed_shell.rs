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

/// What the shell's stack shows.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    /// A bright layer with brighter cells in it.
    Layer,
    /// The same layer where three cells in ten are dim (at 30 % of the others' brightness),
    /// as real tissue is: the threshold opens holes through the layer there.
    Patchy,
    /// Nuclei alone: bright blobs in the layer's middle with dark gaps between them.
    Nuclei,
}

struct Scene {
    n: usize,
    kind: Kind,
    /// The voxel's depth in z against its sides (1: cubic voxels).
    z_scale: f64,
    /// Turn per frame (radians) about z.
    omega: f64,
    /// Relative growth of the x semi-axis, and shrinking of the z one, per frame.
    strain: f64,
    /// The noise's standard deviation.
    noise: f64,
    /// Directions of the cells on the unit sphere.
    cells: Vec<Vector3<f64>>,
}

impl Scene {
    fn new(n: usize, kind: Kind) -> Self {
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
        let env = |name: &str, default: f64| {
            std::env::var(name)
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(default)
        };
        Self {
            n,
            kind,
            z_scale: env("Z_SCALE", 1.0),
            omega: env("OMEGA", 0.04),
            strain: env("STRAIN", 0.01),
            noise: env("NOISE", 15.0),
            cells,
        }
    }

    /// Voxels in z.
    fn nz(&self) -> usize {
        ((self.n as f64) / self.z_scale).round() as usize
    }

    fn centre(&self) -> Vector3<f64> {
        let side = (self.n - 1) as f64 / 2.0;
        Vector3::new(side, side, self.z_scale * (self.nz() - 1) as f64 / 2.0)
    }

    /// The semi-axes at time `t` (voxel sides).
    fn axes(&self, t: f64) -> Vector3<f64> {
        let r = 0.36 * self.n as f64;
        Vector3::new(
            r * (1.0 + self.strain * t),
            0.9 * r,
            0.8 * r * (1.0 - self.strain * t),
        )
    }

    /// The material point (on the reference ellipsoid's scale) at `x` and time `t`.
    fn material(&self, x: &Vector3<f64>, t: f64) -> Vector3<f64> {
        let turned =
            Rotation3::from_axis_angle(&Vector3::z_axis(), -self.omega * t) * (x - self.centre());
        turned.component_div(&self.axes(t))
    }

    /// The image at `x` and time `t`, without noise.
    fn value(&self, x: &Vector3<f64>, t: f64) -> f64 {
        let m = self.material(x, t);
        let radius = m.norm();
        if self.kind == Kind::Nuclei {
            // Blobs of radius 0.05 (the ellipsoid's scale) at radius 0.925: 0.37 apart.
            let blobs: f64 = (self.cells.iter())
                .map(|c| (-(m - 0.925 * c).norm_squared() / (2.0 * 0.05f64.powi(2))).exp())
                .sum();
            return 20.0 + 180.0 * blobs.min(1.0);
        }
        if !(0.85..1.0).contains(&radius) {
            return 20.0;
        }
        let direction = m / radius;
        let near = |c: &&Vector3<f64>| (direction - *c).norm_squared();
        let nearest = (self.cells.iter().enumerate())
            .min_by(|(_, a), (_, b)| near(a).total_cmp(&near(b)))
            .map_or(0, |(i, _)| i);
        let cells: f64 = (self.cells.iter())
            .map(|c| (-(direction - c).norm_squared() / (2.0 * 0.1f64.powi(2))).exp())
            .sum();
        let brightness = match (self.kind, nearest % 10) {
            (Kind::Patchy, 0 | 3 | 7) => 0.3,
            _ => 1.0,
        };
        20.0 + brightness * (40.0 + 120.0 * cells.min(1.0))
    }

    /// The material's velocity at `x` and time `t` (voxels per frame).
    fn velocity(&self, x: &Vector3<f64>, t: f64) -> Vector3<f64> {
        let m = self.material(x, t);
        let (strain, omega) = (self.strain, self.omega);
        let rate = Vector3::new(
            strain / (1.0 + strain * t),
            0.0,
            -strain / (1.0 - strain * t),
        );
        let scaled = m.component_mul(&self.axes(t));
        let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), omega * t);
        rotation * (Vector3::z().cross(&scaled) * omega + scaled.component_mul(&rate))
    }

    /// Frame `k` as a volume with noise of standard deviation [`Scene::noise`].
    fn volume(&self, k: usize) -> Volume {
        let (n, nz) = (self.n, self.nz());
        let mut values = Vec::with_capacity(n * n * nz);
        let mut state = 0x9e37_79b9_7f4a_7c15u64 ^ k as u64;
        for z in 0..nz {
            for y in 0..n {
                for x in 0..n {
                    let p = Vector3::new(x as f64, y as f64, self.z_scale * z as f64);
                    // xorshift, two uniforms summed: a noise of standard deviation `noise`.
                    let mut uniform = || {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                    };
                    let noise = self.noise * 6f64.sqrt() * (uniform() + uniform());
                    values.push((self.value(&p, k as f64) + noise) as f32);
                }
            }
        }
        let voxel = Vector3::new(1.0, 1.0, self.z_scale);
        Volume::new([nz, n, n], values, voxel, Vector3::zeros()).expect("finite")
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
    let kind = match std::env::var("SCENE").as_deref() {
        Ok("patchy") => Kind::Patchy,
        Ok("nuclei") => Kind::Nuclei,
        _ => Kind::Layer,
    };
    let scene = Scene::new(n, kind);
    println!(
        "scene {kind:?}, voxels 1 × 1 × {}, {:.3} rad per frame, strain {} per frame, noise {}",
        scene.z_scale, scene.omega, scene.strain, scene.noise
    );
    let out = Path::new("out/closed_shell");
    std::fs::create_dir_all(out).map_err(|e| meshflow::format::IoError::file(out, e))?;
    let start = Instant::now();
    let volumes: Vec<Volume> = (0..k).map(|f| scene.volume(f)).collect();
    let stack: Vec<f64> = (volumes.iter())
        .flat_map(|v| v.values().iter().map(|&x| f64::from(x)))
        .collect();
    let (nk, nn) = (k as u64, n as u64);
    let shape = [nk, scene.nz() as u64, nn, nn];
    meshflow::format::write_npy(&out.join("stack.npy"), &shape, &stack)?;
    println!(
        "{k} volumes of {n}³ voxels rendered in {:.1} s",
        start.elapsed().as_secs_f64()
    );

    // meshflow surface stack.npy --shape closed
    let start = Instant::now();
    let mut frames = Vec::new();
    for (f, volume) in volumes.iter().enumerate() {
        let finding = IsosurfaceOptions {
            closing: std::env::var("CLOSING").ok().and_then(|v| v.parse().ok()),
            ..IsosurfaceOptions::default()
        };
        let found = find_surface(volume, &finding)?;
        let radii: Vec<f64> = (found.positions.iter())
            .map(|p| scene.material(p, f as f64).norm())
            .collect();
        let within = radii.iter().filter(|r| (0.85..1.0).contains(*r)).count();
        let mesh = meshflow::mesh::Mesh::new(found.positions.len(), found.faces.clone())?;
        // Folds of the frame's own surface: edges whose two faces face opposite ways.
        let normal = |f: usize| {
            let [a, b, c] = mesh.faces()[f].map(|v| found.positions[v as usize]);
            (b - a).cross(&(c - a))
        };
        let mut faces_of_edge = std::collections::HashMap::new();
        for (f, face) in mesh.faces().iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (face[e], face[(e + 1) % 3]);
                faces_of_edge
                    .entry((a.min(b), a.max(b)))
                    .or_insert_with(Vec::new)
                    .push(f);
            }
        }
        let folds = (faces_of_edge.values())
            .filter(|f| f.len() == 2 && normal(f[0]).dot(&normal(f[1])) < 0.0)
            .count();
        let tried: Vec<String> = (found.closings_tried.iter())
            .map(|c| format!("{:.1}: genus {}, share {:.2}", c.radius, c.genus, c.share))
            .collect();
        println!(
            "frame {f}: threshold {:.1}, component {} + {} filled, {} vertices, {folds} folded edges, genus {}, closed at radius {:.1} (tried {}), {:.1} % of them within the bright layer",
            found.threshold,
            found.component_voxels,
            found.filled_voxels,
            found.vertices,
            (2 - mesh.euler_characteristic()) / 2,
            found.closing_radius,
            tried.join("; "),
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
        // As `meshflow surface --shape closed` does.
        keep_coordinates: true,
        alignment: std::env::var("ALIGN").map_or(meshflow::track::Alignment::Rigid, |a| {
            a.parse().expect("ALIGN: rigid, similarity or none")
        }),
        ..TrackOptions::default()
    };
    let tracked = track(&frames, None, &options)?;
    for report in &tracked.report.frames {
        if let Some(a) = &report.alignment {
            println!(
                "frame {}: rigid fit {:.2}°, median distance {:.3} -> {:.3}, {}; mean step {:.3}",
                report.frame,
                a.rotation_degrees,
                a.median_distance_before,
                a.median_distance_after,
                if a.applied { "applied" } else { "not applied" },
                report.mean_step
            );
        }
    }
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
