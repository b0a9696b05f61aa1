//! Morph weights over time: the animation sampler of the mesh node's `weights`.
//!
//! Between keyframes `t_k ≤ t ≤ t_{k+1}`, with `s = (t − t_k)/Δt`, `Δt = t_{k+1} − t_k`
//! (glTF 2.0 Appendix C):
//!
//! ```text
//! STEP         w(t) = v_k
//! LINEAR       w(t) = (1 − s) v_k + s v_{k+1}
//! CUBICSPLINE  w(t) = (2s³ − 3s² + 1) v_k + Δt (s³ − 2s² + s) b_k
//!                   + (−2s³ + 3s²) v_{k+1} + Δt (s³ − s²) a_{k+1}
//! ```
//!
//! with keyframe values `v`, out-tangents `b` and in-tangents `a`; outside the keyframes the
//! first or last values hold.
//!
//! A file may hold several animations (clips). The one read is chosen by name or index, else it
//! is the first with a `weights` channel on the mesh node (and a warning lists them all when
//! there are several).

use super::{ancestry, GltfFile, NO_ANIMATION};
use crate::io::{IoError, LoadWarning};
use gltf::animation::{Interpolation, Property};
use gltf::Node;

/// One animation of a glTF file, as listed in messages: `1: "Pulse"`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AnimationClip {
    pub index: usize,
    pub name: Option<String>,
    /// Whether it animates the morph weights of the mesh's node (only those can be read).
    pub moves_mesh: bool,
}

impl std::fmt::Display for AnimationClip {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.name {
            Some(name) => write!(f, "{}: {name:?}", self.index)?,
            None => write!(f, "{}: (unnamed)", self.index)?,
        }
        match self.moves_mesh {
            true => Ok(()),
            false => f.write_str(" (no morph weights)"),
        }
    }
}

/// `0: "A", 1: "B"`.
pub(crate) fn clip_list(clips: &[AnimationClip]) -> String {
    let listed: Vec<String> = clips.iter().map(ToString::to_string).collect();
    listed.join(", ")
}

/// The `weights` channel of `animation` on `node`.
fn weights_channel<'a>(
    animation: &gltf::Animation<'a>,
    node: &Node,
) -> Option<gltf::animation::Channel<'a>> {
    animation.channels().find(|c| {
        c.target().node().index() == node.index()
            && c.target().property() == Property::MorphTargetWeights
    })
}

/// The `weights` channel to read: that of the animation named (by name, else by index) by
/// `choice`, or of the first animation that has one; with a warning when the choice was
/// implicit among several animations.
fn chosen_channel<'a>(
    file: &'a GltfFile,
    node: &Node,
    choice: Option<&str>,
) -> Result<(gltf::animation::Channel<'a>, Option<LoadWarning>), IoError> {
    let animations: Vec<gltf::Animation> = file.document.animations().collect();
    let clips: Vec<AnimationClip> = animations
        .iter()
        .map(|a| AnimationClip {
            index: a.index(),
            name: a.name().map(str::to_string),
            moves_mesh: weights_channel(a, node).is_some(),
        })
        .collect();
    let Some(choice) = choice else {
        let first = clips
            .iter()
            .position(|c| c.moves_mesh)
            .ok_or_else(|| file.error(NO_ANIMATION))?;
        let warning = (clips.len() > 1).then(|| LoadWarning::SeveralAnimations {
            file: file.path.to_path_buf(),
            chosen: clips[first].clone(),
            clips: clips.clone(),
        });
        let channel = weights_channel(&animations[first], node).expect("it moves the mesh");
        return Ok((channel, warning));
    };
    let found = clips
        .iter()
        .position(|c| c.name.as_deref() == Some(choice))
        .or_else(|| choice.trim().parse().ok().filter(|&i| i < clips.len()));
    let listing = match clips.is_empty() {
        true => "the file has no animations".to_string(),
        false => format!("the file has {}", clip_list(&clips)),
    };
    let Some(index) = found else {
        return Err(file.error(format!("no animation {choice:?}: {listing}")));
    };
    match weights_channel(&animations[index], node) {
        Some(channel) => Ok((channel, None)),
        None => Err(file.error(format!(
            "animation {} does not animate the morph weights of the mesh: {listing}",
            clips[index]
        ))),
    }
}

/// The animated morph weights of the mesh node.
pub(super) struct WeightTrack {
    pub times: Vec<f64>,
    interpolation: Interpolation,
    /// Per keyframe: the weights (`target_count` values), or for CUBICSPLINE in-tangents,
    /// values and out-tangents.
    outputs: Vec<f64>,
    target_count: usize,
}

impl WeightTrack {
    /// The sampler of the `weights` channel on `node` of the animation `choice` names (by name,
    /// else by index), or of the first animation with one; see the module documentation.
    pub fn read(
        file: &GltfFile,
        node: &Node,
        target_count: usize,
        choice: Option<&str>,
    ) -> Result<(Self, Option<LoadWarning>), IoError> {
        if target_count == 0 {
            return Err(file.error(format!("the mesh has no morph targets: {NO_ANIMATION}")));
        }
        let (channel, warning) = chosen_channel(file, node, choice)?;
        check_no_node_motion(file, &channel.animation(), node)?;
        let sampler = channel.sampler();
        let label = format!(
            "animation {}, sampler {}",
            channel.animation().index(),
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
        let per_keyframe = match interpolation {
            Interpolation::CubicSpline => 3 * target_count,
            Interpolation::Linear | Interpolation::Step => target_count,
        };
        let outputs = file
            .read_elements::<1>(
                &sampler.output(),
                &format!("{label}, output"),
                &[1],
                Some(times.len() * per_keyframe),
            )?
            .into_iter()
            .map(|[w]| w)
            .collect();
        let track = Self {
            times,
            interpolation,
            outputs,
            target_count,
        };
        Ok((track, warning))
    }

    /// Part `part` of keyframe `k`'s outputs (0 = values; for CUBICSPLINE −1 = in-tangents,
    /// +1 = out-tangents).
    fn key(&self, k: usize, part: isize) -> &[f64] {
        let n = self.target_count;
        let start = match self.interpolation {
            Interpolation::CubicSpline => (3 * k + (1 + part) as usize) * n,
            Interpolation::Linear | Interpolation::Step => k * n,
        };
        &self.outputs[start..start + n]
    }

    /// The weights at time `t`.
    pub fn at(&self, t: f64) -> Vec<f64> {
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
            Interpolation::Linear => (0..self.target_count)
                .map(|j| (1.0 - s) * v0[j] + s * v1[j])
                .collect(),
            Interpolation::CubicSpline => {
                let (out0, in1) = (self.key(k, 1), self.key(k + 1, -1));
                let (s2, s3) = (s * s, s * s * s);
                (0..self.target_count)
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

/// Rejects translation/rotation/scale channels of `animation` on `node` or its ancestors,
/// which would move the mesh in ways the morph weights do not describe.
fn check_no_node_motion(
    file: &GltfFile,
    animation: &gltf::Animation,
    node: &Node,
) -> Result<(), IoError> {
    let chain = ancestry(file, node)?;
    match animation.channels().find(|c| {
        c.target().property() != Property::MorphTargetWeights
            && chain.contains(&c.target().node().index())
    }) {
        Some(channel) => Err(file.error(format!(
            "animation {} also animates the {:?} of node {}; only morph-target animation is \
             supported",
            animation.index(),
            channel.target().property(),
            channel.target().node().index()
        ))),
        None => Ok(()),
    }
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
