//! Animated values over time: the samplers of the chosen animation's channels.
//!
//! A channel animates one node's `translation` or `scale` (3 numbers), `rotation` (a
//! quaternion `(x, y, z, w)`) or morph `weights` (one per target). Its sampler holds keyframe
//! times `t_0 < … < t_n` and values `v_k`; between keyframes `t_k ≤ t ≤ t_{k+1}`, with
//! `s = (t − t_k)/Δt`, `Δt = t_{k+1} − t_k` (glTF 2.0 Appendix C):
//!
//! ```text
//! STEP         v(t) = v_k
//! LINEAR       v(t) = (1 − s) v_k + s v_{k+1}
//!              rotations: q(t) = (sin((1 − s)θ) q_k + sin(sθ) q') / sin θ,
//!              q' = ±q_{k+1} with q_k · q' ≥ 0 (the shorter arc), θ the angle between q_k, q'
//! CUBICSPLINE  v(t) = (2s³ − 3s² + 1) v_k + Δt (s³ − 2s² + s) b_k
//!                   + (−2s³ + 3s²) v_{k+1} + Δt (s³ − s²) a_{k+1}
//! ```
//!
//! with out-tangents `b` and in-tangents `a`; rotations are normalized (the quaternions of the
//! keyframes, and the result). Outside the keyframes the first or last values hold.
//!
//! A file may hold several animations (clips). The one read is chosen by name or index, else it
//! is the first that moves the mesh (and a warning lists them all when there are several). A
//! channel moves the mesh when it animates the weights of the mesh node, or the translation,
//! rotation or scale of a node that places the mesh: a joint of its skin or an ancestor of
//! one, or for a mesh without skin the mesh node or an ancestor. Those channels are read, and
//! the frames are the union of their keyframe times.

use super::nodes::Nodes;
use super::{GltfFile, NO_ANIMATION};
use crate::format::IoError;
use gltf::animation::{Channel, Interpolation, Property};
use gltf::Node;
use nalgebra::Vector4;

/// One animation of a glTF file, as listed in messages: `1: "Pulse"`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AnimationClip {
    pub index: usize,
    pub name: Option<String>,
    /// Whether it moves the mesh: animates the morph weights of the mesh's node, or the
    /// transform of a node that places the mesh (only those can be read).
    pub moves_mesh: bool,
}

impl AnimationClip {
    /// `1: "Pulse"`, or `3: (unnamed)`.
    fn title(&self) -> String {
        match &self.name {
            Some(name) => format!("{}: {name:?}", self.index),
            None => format!("{}: (unnamed)", self.index),
        }
    }
}

impl std::fmt::Display for AnimationClip {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.title())?;
        match self.moves_mesh {
            true => Ok(()),
            false => f.write_str(" (does not move the mesh)"),
        }
    }
}

/// The animation read from a file with several when none was named: the first that moves the
/// mesh (`chosen`), among all of them (`clips`). The loader reports it as a warning.
#[derive(Clone, Debug, PartialEq)]
pub struct ImplicitClip {
    pub clips: Vec<AnimationClip>,
    pub chosen: AnimationClip,
}

/// `0: "A", 1: "B"`.
pub(crate) fn clip_list(clips: &[AnimationClip]) -> String {
    let listed: Vec<String> = clips.iter().map(ToString::to_string).collect();
    listed.join(", ")
}

/// The name of an animated property in the file (`"rotation"`, …).
fn property_name(property: Property) -> &'static str {
    match property {
        Property::Translation => "translation",
        Property::Rotation => "rotation",
        Property::Scale => "scale",
        Property::MorphTargetWeights => "weights",
    }
}

/// Which channels move a mesh: the weights of its node, the transforms of the nodes that
/// place it.
struct Movers<'a> {
    mesh_node: usize,
    /// Sorted.
    placing: &'a [usize],
}

impl Movers<'_> {
    fn moves(&self, channel: &Channel) -> bool {
        let node = channel.target().node().index();
        match channel.target().property() {
            Property::MorphTargetWeights => node == self.mesh_node,
            _ => self.placing.binary_search(&node).is_ok(),
        }
    }
}

/// The animation named (by name, else by index) by `choice`, or the first that moves the
/// mesh; with the list of clips when the choice was implicit among several animations.
fn chosen_animation<'a>(
    file: &'a GltfFile,
    movers: &Movers,
    choice: Option<&str>,
) -> Result<(gltf::Animation<'a>, Option<ImplicitClip>), IoError> {
    let animations: Vec<gltf::Animation> = file.document.animations().collect();
    let clips: Vec<AnimationClip> = animations
        .iter()
        .map(|a| AnimationClip {
            index: a.index(),
            name: a.name().map(str::to_string),
            moves_mesh: a.channels().any(|c| movers.moves(&c)),
        })
        .collect();
    let Some(choice) = choice else {
        let first = clips
            .iter()
            .position(|c| c.moves_mesh)
            .ok_or_else(|| file.error(NO_ANIMATION))?;
        let implicit = (clips.len() > 1).then(|| ImplicitClip {
            chosen: clips[first].clone(),
            clips: clips.clone(),
        });
        return Ok((animations[first].clone(), implicit));
    };
    let found = clips
        .iter()
        .position(|c| c.name.as_deref() == Some(choice))
        .or_else(|| choice.trim().parse().ok().filter(|&i| i < clips.len()));
    let listing = match clips.is_empty() {
        true => "the file has no animations".to_string(),
        false => format!("the file has {}", clip_list(&clips)),
    };
    match found {
        None => Err(file.error(format!("no animation {choice:?}: {listing}"))),
        Some(index) if !clips[index].moves_mesh => Err(file.error(format!(
            "animation {} does not move the mesh: {listing}",
            clips[index].title()
        ))),
        Some(index) => Ok((animations[index].clone(), None)),
    }
}

/// A channel of node motion: the translation, rotation or scale of one node.
struct NodeChannel {
    pub node: usize,
    pub property: Property,
    pub track: Track,
}

/// What the chosen animation does to the mesh.
pub(super) struct Motion {
    /// The union of the keyframe times of its channels.
    pub times: Vec<f64>,
    /// The mesh node's morph weights, if animated.
    weights: Option<Track>,
    nodes: Vec<NodeChannel>,
}

impl Motion {
    /// The channels that move the mesh of `mesh_node`, placed by the nodes `placing`, in the
    /// animation `choice` names (by name, else by index), or the first animation with one;
    /// see the module documentation.
    pub fn read(
        file: &GltfFile,
        nodes: &Nodes,
        mesh_node: &Node,
        placing: &[usize],
        target_count: usize,
        choice: Option<&str>,
    ) -> Result<(Self, Option<ImplicitClip>), IoError> {
        let movers = Movers {
            mesh_node: mesh_node.index(),
            placing,
        };
        let (animation, implicit) = chosen_animation(file, &movers, choice)?;
        let mut motion = Motion {
            times: Vec::new(),
            weights: None,
            nodes: Vec::new(),
        };
        let mut animated = Vec::new();
        for channel in animation.channels().filter(|c| movers.moves(c)) {
            let (node, property) = (channel.target().node().index(), channel.target().property());
            let what = format!(
                "animation {} animates the {} of {}",
                animation.index(),
                property_name(property),
                nodes.label(node)
            );
            if animated.contains(&(node, property)) {
                return Err(file.error(format!("{what} twice")));
            }
            animated.push((node, property));
            let sampler = channel.sampler();
            let track = match property {
                Property::MorphTargetWeights if target_count == 0 => {
                    return Err(file.error(format!("{what}, whose mesh has no morph targets")))
                }
                Property::MorphTargetWeights => {
                    motion.weights = Some(Track::read::<1>(file, &sampler, target_count, false)?);
                    continue;
                }
                _ if nodes.has_matrix(node) => {
                    return Err(file.error(format!(
                        "{what}, which has a matrix; glTF animates only nodes given by \
                         translation, rotation and scale"
                    )))
                }
                Property::Rotation => Track::read::<4>(file, &sampler, 1, true)?,
                Property::Translation | Property::Scale => {
                    Track::read::<3>(file, &sampler, 1, false)?
                }
            };
            motion.nodes.push(NodeChannel {
                node,
                property,
                track,
            });
        }
        let mut times: Vec<f64> = motion
            .weights
            .iter()
            .chain(motion.nodes.iter().map(|c| &c.track))
            .flat_map(|track| track.times.iter().copied())
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        motion.times = times;
        Ok((motion, implicit))
    }

    /// The morph weights at time `t`, if the animation drives them.
    pub fn weights(&self, t: f64) -> Option<Vec<f64>> {
        self.weights.as_ref().map(|track| track.at(t))
    }

    /// The node transforms at time `t`: `(node, property, value)` per translation, rotation
    /// and scale channel (what [`Nodes::pose`] takes).
    pub fn node_values(&self, t: f64) -> impl Iterator<Item = (usize, Property, Vec<f64>)> + '_ {
        (self.nodes.iter()).map(move |c| (c.node, c.property, c.track.at(t)))
    }
}

/// The keyframes of one sampler: `width` numbers per keyframe value.
pub(super) struct Track {
    pub times: Vec<f64>,
    interpolation: Interpolation,
    /// Per keyframe: the value, or for CUBICSPLINE in-tangent, value and out-tangent.
    outputs: Vec<f64>,
    width: usize,
    /// Values are quaternions: normalized, and interpolated along great arcs.
    rotation: bool,
}

impl Track {
    /// The keyframes of `sampler`, whose values are `elements` accessor elements of `N`
    /// components each (a rotation: one of 4, when `rotation`).
    fn read<const N: usize>(
        file: &GltfFile,
        sampler: &gltf::animation::Sampler,
        elements: usize,
        rotation: bool,
    ) -> Result<Self, IoError> {
        let label = format!(
            "animation {}, sampler {}",
            sampler.animation().index(),
            sampler.index()
        );
        let times: Vec<f64> = file
            .read_elements::<1>(&sampler.input(), &format!("{label}, input"), &[1], None)?
            .into_iter()
            .map(|[t]| t)
            .collect();
        if let Some(k) = (1..times.len()).find(|&k| times[k] <= times[k - 1]) {
            return Err(file.error(format!(
                "{label}: keyframe times must increase, but {} follows {}",
                times[k],
                times[k - 1]
            )));
        }
        let interpolation = sampler.interpolation();
        let parts = match interpolation {
            Interpolation::CubicSpline => 3,
            Interpolation::Linear | Interpolation::Step => 1,
        };
        let outputs = file
            .read_elements::<N>(
                &sampler.output(),
                &format!("{label}, output"),
                &[N],
                Some(times.len() * parts * elements),
            )?
            .into_iter()
            .flatten()
            .collect();
        let track = Self {
            times,
            interpolation,
            outputs,
            width: N * elements,
            rotation,
        };
        if rotation {
            if let Some(k) =
                (0..track.times.len()).find(|&k| track.key(k, 0).iter().all(|&c| c == 0.0))
            {
                return Err(file.error(format!(
                    "{label}, output: the rotation of keyframe {k} is the zero quaternion"
                )));
            }
        }
        Ok(track)
    }

    /// Part `part` of keyframe `k`'s outputs (0 = values; for CUBICSPLINE −1 = in-tangents,
    /// +1 = out-tangents).
    fn key(&self, k: usize, part: isize) -> &[f64] {
        let n = self.width;
        let start = match self.interpolation {
            Interpolation::CubicSpline => (3 * k + (1 + part) as usize) * n,
            Interpolation::Linear | Interpolation::Step => k * n,
        };
        &self.outputs[start..start + n]
    }

    /// The value at time `t`.
    pub fn at(&self, t: f64) -> Vec<f64> {
        let value = self.interpolated(t);
        match self.rotation {
            true => normalized(&value),
            false => value,
        }
    }

    fn interpolated(&self, t: f64) -> Vec<f64> {
        let last = self.times.len() - 1;
        let after = self.times.partition_point(|&tk| tk <= t);
        if after == 0 {
            return self.key(0, 0).to_vec();
        }
        let k = after - 1;
        if k == last {
            return self.key(last, 0).to_vec();
        }
        let dt = self.times[k + 1] - self.times[k];
        let s = (t - self.times[k]) / dt;
        let (v0, v1) = (self.key(k, 0), self.key(k + 1, 0));
        match self.interpolation {
            Interpolation::Step => v0.to_vec(),
            Interpolation::Linear if self.rotation => slerp(v0, v1, s),
            Interpolation::Linear => (0..self.width)
                .map(|j| (1.0 - s) * v0[j] + s * v1[j])
                .collect(),
            Interpolation::CubicSpline => {
                let (out0, in1) = (self.key(k, 1), self.key(k + 1, -1));
                let (s2, s3) = (s * s, s * s * s);
                (0..self.width)
                    .map(|j| {
                        (2.0 * s3 - 3.0 * s2 + 1.0) * v0[j]
                            + dt * (s3 - 2.0 * s2 + s) * out0[j]
                            + (-2.0 * s3 + 3.0 * s2) * v1[j]
                            + dt * (s3 - s2) * in1[j]
                    })
                    .collect()
            }
        }
    }
}

/// `v / |v|` (not finite for a zero `v`).
fn normalized(v: &[f64]) -> Vec<f64> {
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    v.iter().map(|x| x / norm).collect()
}

/// Spherical linear interpolation between the quaternions `a` and `b` (normalized first)
/// along the shorter arc. The angle is `θ = 2 atan2(|a − b'|, |a + b'|)`, accurate also for
/// nearly equal quaternions.
fn slerp(a: &[f64], b: &[f64], s: f64) -> Vec<f64> {
    let a = Vector4::from_column_slice(&normalized(a));
    let mut b = Vector4::from_column_slice(&normalized(b));
    if a.dot(&b) < 0.0 {
        b = -b;
    }
    let theta = 2.0 * (a - b).norm().atan2((a + b).norm());
    let sin = theta.sin();
    let q = match sin > 0.0 {
        true => (a * ((1.0 - s) * theta).sin() + b * (s * theta).sin()) / sin,
        false => a,
    };
    q.iter().copied().collect()
}

/// Frame times `t₀ + i/fps` from the first keyframe up to the last.
pub(super) fn resampled_times(keyframes: &[f64], fps: f64) -> Result<Vec<f64>, String> {
    if !(fps.is_finite() && fps > 0.0) {
        return Err(format!("the frame rate must be positive, not {fps}"));
    }
    let (first, last) = (keyframes[0], keyframes[keyframes.len() - 1]);
    // The tolerance keeps a final frame that lands on the last keyframe up to rounding.
    let steps = ((last - first) * fps * (1.0 + 1e-12)).floor();
    if steps > 1e7 {
        return Err(format!("{fps} frames per second give too many frames"));
    }
    Ok((0..=steps as usize)
        .map(|i| (first + i as f64 / fps).min(last))
        .collect())
}
