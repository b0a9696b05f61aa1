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

use super::{ancestry, GltfFile, NO_ANIMATION};
use crate::io::IoError;
use gltf::animation::{Interpolation, Property};
use gltf::Node;

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
    /// The sampler of the first `weights` channel on `node`.
    pub fn read(file: &GltfFile, node: &Node, target_count: usize) -> Result<Self, IoError> {
        if target_count == 0 {
            return Err(file.error(format!("the mesh has no morph targets: {NO_ANIMATION}")));
        }
        let channel = file
            .document
            .animations()
            .flat_map(|a| a.channels())
            .find(|c| {
                c.target().node().index() == node.index()
                    && c.target().property() == Property::MorphTargetWeights
            })
            .ok_or_else(|| file.error(NO_ANIMATION))?;
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
        Ok(Self {
            times,
            interpolation,
            outputs,
            target_count,
        })
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
