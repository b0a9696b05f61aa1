//! Linear-blend skinning: vertices carried by the joints of a skin.
//!
//! Vertex `i`, at its morphed position `p̃_i`, moves with the joints `j_ik` its `JOINTS_n`
//! attributes name, weighted by its `WEIGHTS_n` (`n = 0, 1, …`, four joints each):
//!
//! ```text
//! p_i = Σ_k ω_ik · J_{j_ik} · B_{j_ik} · p̃_i,    ω_ik = w_ik / Σ_l w_il
//! ```
//!
//! with `J_j` the world transform of joint `j`'s node and `B_j` its inverse bind matrix
//! (`inverseBindMatrices`, the identity without them). The weights `w` are normalized to sum
//! 1 per vertex (exporters round them); a vertex whose weights are all zero is an error, and
//! joints of weight zero are skipped (their indices are not checked). Joint indices are
//! unsigned bytes or shorts; weights floats, or normalized unsigned bytes or shorts, and not
//! negative.

use super::nodes::{Nodes, Pose};
use super::{GltfFile, PrimitiveReader};
use crate::format::IoError;
use gltf::accessor::DataType;
use gltf::mesh::Semantic;
use nalgebra::{Matrix3x4, Matrix4, Vector3, Vector4};

/// The joints moving one vertex, with their weights (summing to 1).
pub(super) type Influences = Vec<(usize, f64)>;

/// A skin: its joints' nodes and inverse bind matrices.
pub(super) struct Skin {
    nodes: Vec<usize>,
    inverse_binds: Vec<Matrix4<f64>>,
}

impl Skin {
    pub fn read(file: &GltfFile, skin: &gltf::Skin) -> Result<Self, IoError> {
        let name = skin.name().map(|n| format!(" ({n:?})")).unwrap_or_default();
        let label = format!("skin {}{name}", skin.index());
        let joints: Vec<usize> = skin.joints().map(|joint| joint.index()).collect();
        if joints.is_empty() {
            return Err(file.error(format!("{label} has no joints")));
        }
        let inverse_binds = match skin.inverse_bind_matrices() {
            None => vec![Matrix4::identity(); joints.len()],
            Some(accessor) => file
                .read_elements::<16>(
                    &accessor,
                    &format!("{label}, inverseBindMatrices"),
                    &[16],
                    Some(joints.len()),
                )?
                .iter()
                .map(|m| Matrix4::from_column_slice(m))
                .collect(),
        };
        Ok(Self {
            nodes: joints,
            inverse_binds,
        })
    }

    pub fn joint_count(&self) -> usize {
        self.nodes.len()
    }

    /// The nodes whose transforms move the skin: the joints and their ancestors, sorted.
    pub fn placing(&self, nodes: &Nodes) -> Vec<usize> {
        nodes.with_ancestors(self.nodes.iter().copied())
    }

    /// The skinning matrices `J_j · B_j` of all joints at `pose`.
    pub fn matrices(&self, file: &GltfFile, pose: &Pose) -> Result<Vec<Matrix4<f64>>, IoError> {
        let worlds = pose.worlds(file, &self.nodes)?;
        Ok(worlds
            .iter()
            .zip(&self.inverse_binds)
            .map(|(world, inverse_bind)| world * inverse_bind)
            .collect())
    }
}

/// The skinned positions `Σ_k ω_k M_{j_k} p` of `points`, one list of influences each, for
/// skinning matrices `M`.
pub(super) fn blend(
    points: impl Iterator<Item = [f64; 3]>,
    influences: &[Influences],
    matrices: &[Matrix4<f64>],
) -> Vec<Vector3<f64>> {
    points
        .zip(influences)
        .map(|([x, y, z], joints)| {
            let blended: Matrix3x4<f64> = joints
                .iter()
                .map(|&(j, w)| matrices[j].fixed_view::<3, 4>(0, 0) * w)
                .sum();
            blended * Vector4::new(x, y, z, 1.0)
        })
        .collect()
}

impl PrimitiveReader<'_, '_> {
    /// Per vertex of the primitive, the joints of a skin of `joint_count` joints that move it
    /// (from `JOINTS_n` and `WEIGHTS_n`, `n = 0, 1, …`), weights normalized.
    pub(super) fn influences(
        &self,
        joint_count: usize,
        vertex_count: usize,
    ) -> Result<Vec<Influences>, IoError> {
        let mut influences = vec![Influences::new(); vertex_count];
        for set in 0.. {
            let joints = self.primitive.get(&Semantic::Joints(set));
            let weights = self.primitive.get(&Semantic::Weights(set));
            let (joints, weights) = match (joints, weights) {
                (Some(joints), Some(weights)) => (joints, weights),
                (None, None) if set > 0 => break,
                (None, None) => {
                    return Err(self.error(
                        "its node has a skin, but it has no JOINTS_0 and WEIGHTS_0".to_string(),
                    ))
                }
                (Some(_), None) => {
                    return Err(self.error(format!("JOINTS_{set} without WEIGHTS_{set}")))
                }
                (None, Some(_)) => {
                    return Err(self.error(format!("WEIGHTS_{set} without JOINTS_{set}")))
                }
            };
            let joint_label = format!("JOINTS_{set} (accessor {})", joints.index());
            let weight_label = format!("WEIGHTS_{set} (accessor {})", weights.index());
            let integer = matches!(joints.data_type(), DataType::U8 | DataType::U16);
            if !integer || joints.normalized() {
                let normalized = if joints.normalized() {
                    "normalized "
                } else {
                    ""
                };
                return Err(self.error(format!(
                    "{joint_label} has {normalized}components of type {:?}; joint indices are \
                     unsigned bytes or shorts",
                    joints.data_type(),
                )));
            }
            let normalized =
                matches!(weights.data_type(), DataType::U8 | DataType::U16) && weights.normalized();
            if weights.data_type() != DataType::F32 && !normalized {
                return Err(self.error(format!(
                    "{weight_label} has components of type {:?}; weights are floats or \
                     normalized unsigned bytes or shorts",
                    weights.data_type()
                )));
            }
            let label = |name: &str| format!("{}, {name}_{set}", self.label);
            let count = Some(vertex_count);
            let joints = self
                .file
                .read_elements::<4>(&joints, &label("JOINTS"), &[4], count)?;
            let weights = self
                .file
                .read_elements::<4>(&weights, &label("WEIGHTS"), &[4], count)?;
            for (i, (vertex, (joints, weights))) in influences
                .iter_mut()
                .zip(joints.iter().zip(&weights))
                .enumerate()
            {
                for (&joint, &weight) in joints.iter().zip(weights) {
                    if weight < 0.0 {
                        return Err(self.error(format!(
                            "{weight_label}: vertex {i} has the negative weight {weight}"
                        )));
                    }
                    if weight == 0.0 {
                        continue;
                    }
                    if joint >= joint_count as f64 {
                        return Err(self.error(format!(
                            "{joint_label}: vertex {i} names joint {joint}, but the skin has \
                             {joint_count} joints"
                        )));
                    }
                    // Exact: an unsigned integer below the joint count.
                    vertex.push((joint as usize, weight));
                }
            }
        }
        for (i, vertex) in influences.iter_mut().enumerate() {
            let total: f64 = vertex.iter().map(|(_, w)| w).sum();
            if total == 0.0 {
                return Err(self.error(format!(
                    "vertex {i} has no joint: its skin weights are all zero"
                )));
            }
            for (_, w) in vertex.iter_mut() {
                *w /= total;
            }
        }
        Ok(influences)
    }
}
