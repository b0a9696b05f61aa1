//! The node hierarchy: world transforms at rest and under an animation.
//!
//! A node's local transform is its `matrix`, or
//!
//! ```text
//! L = T(t) · R(q) · S(s)
//! ```
//!
//! from its `translation` t, `rotation` q (a quaternion `(x, y, z, w)`, normalized here) and
//! `scale` s; an animation replaces any of t, q, s by its channel's value at time `t` (glTF
//! animates only nodes without a `matrix`). The world transform of a node is
//!
//! ```text
//! W = L_root ⋯ L_parent · L_node
//! ```

use super::animation::Motion;
use super::{node_label, GltfFile};
use crate::io::IoError;
use gltf::animation::Property;
use nalgebra::{Matrix3, Matrix4, Quaternion, Unit, Vector3};
use std::collections::HashMap;

/// The nodes of a file: their parents and rest transforms.
pub(super) struct Nodes {
    parents: Vec<Option<usize>>,
    rest: Vec<Local>,
    labels: Vec<String>,
}

/// A node's local transform as the file gives it.
#[derive(Clone, Copy)]
enum Local {
    Matrix(Matrix4<f64>),
    Trs(Trs),
}

/// Translation, rotation (not necessarily of unit length) and scale.
#[derive(Clone, Copy)]
struct Trs {
    translation: Vector3<f64>,
    rotation: Quaternion<f64>,
    scale: Vector3<f64>,
}

impl Nodes {
    pub fn read(file: &GltfFile) -> Self {
        let count = file.document.nodes().len();
        let mut parents = vec![None; count];
        for parent in file.document.nodes() {
            for child in parent.children() {
                if let Some(slot) = parents.get_mut(child.index()) {
                    *slot = Some(parent.index());
                }
            }
        }
        let rest = file
            .document
            .nodes()
            .map(|node| match node.transform() {
                gltf::scene::Transform::Matrix { matrix } => {
                    Local::Matrix(Matrix4::from(matrix).cast())
                }
                gltf::scene::Transform::Decomposed {
                    translation,
                    rotation: [x, y, z, w],
                    scale,
                } => Local::Trs(Trs {
                    translation: Vector3::from(translation).cast(),
                    rotation: Quaternion::new(w, x, y, z).cast(),
                    scale: Vector3::from(scale).cast(),
                }),
            })
            .collect();
        let labels = file.document.nodes().map(|n| node_label(&n)).collect();
        Self {
            parents,
            rest,
            labels,
        }
    }

    pub fn label(&self, node: usize) -> &str {
        &self.labels[node]
    }

    /// Whether the node's transform is a matrix (which animations cannot change).
    pub fn has_matrix(&self, node: usize) -> bool {
        matches!(self.rest[node], Local::Matrix(_))
    }

    /// `node` and its ancestors, node first.
    pub fn ancestry(&self, file: &GltfFile, node: usize) -> Result<Vec<usize>, IoError> {
        let mut chain = vec![node];
        while let Some(parent) = self.parents[chain[chain.len() - 1]] {
            if chain.contains(&parent) {
                return Err(file.error(format!(
                    "the node hierarchy has a cycle through node {parent}"
                )));
            }
            chain.push(parent);
        }
        Ok(chain)
    }

    /// The nodes as the file places them.
    pub fn rest(&self) -> Pose<'_> {
        Pose {
            nodes: self,
            animated: HashMap::new(),
            time: None,
        }
    }

    /// The nodes at time `t` of `motion`: its translation, rotation and scale channels replace
    /// those of the rest transforms.
    pub fn pose(&self, motion: &Motion, t: f64) -> Pose<'_> {
        let mut animated = HashMap::new();
        for channel in motion.node_channels() {
            // Motion::read refused channels on nodes with a matrix.
            let Local::Trs(rest) = self.rest[channel.node] else {
                continue;
            };
            let trs: &mut Trs = animated.entry(channel.node).or_insert(rest);
            let value = channel.track.at(t);
            match channel.property {
                Property::Translation => trs.translation = Vector3::from_column_slice(&value),
                Property::Scale => trs.scale = Vector3::from_column_slice(&value),
                Property::Rotation => {
                    trs.rotation = Quaternion::new(value[3], value[0], value[1], value[2])
                }
                Property::MorphTargetWeights => {}
            }
        }
        Pose {
            nodes: self,
            animated,
            time: Some(t),
        }
    }
}

/// The local transforms of the nodes at one moment.
pub(super) struct Pose<'n> {
    nodes: &'n Nodes,
    /// The transforms of animated nodes; the others are at rest.
    animated: HashMap<usize, Trs>,
    /// The animation time, for messages (`None` at rest).
    time: Option<f64>,
}

impl Pose<'_> {
    /// The world transform `L_root ⋯ L_node` of a node given with its ancestry (node first).
    pub fn world(&self, file: &GltfFile, chain: &[usize]) -> Result<Matrix4<f64>, IoError> {
        let mut world = Matrix4::identity();
        for &node in chain {
            world = self.local(file, node)? * world;
        }
        if !world.iter().all(|x| x.is_finite()) {
            return Err(file.error(format!(
                "the world transform of {} is not finite{}",
                self.nodes.label(chain[0]),
                self.when()
            )));
        }
        Ok(world)
    }

    /// A node's local transform `T · R · S` (or its matrix).
    fn local(&self, file: &GltfFile, node: usize) -> Result<Matrix4<f64>, IoError> {
        let trs = match (self.animated.get(&node), self.nodes.rest[node]) {
            (Some(&trs), _) | (None, Local::Trs(trs)) => trs,
            (None, Local::Matrix(matrix)) => return Ok(matrix),
        };
        let rotation = Unit::try_new(trs.rotation, 0.0)
            .filter(|q| q.coords.iter().all(|c| c.is_finite()))
            .ok_or_else(|| {
                file.error(format!(
                    "{} has a zero rotation quaternion{}",
                    self.nodes.label(node),
                    self.when()
                ))
            })?;
        let linear =
            rotation.to_rotation_matrix().into_inner() * Matrix3::from_diagonal(&trs.scale);
        let mut m = linear.to_homogeneous();
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&trs.translation);
        Ok(m)
    }

    fn when(&self) -> String {
        match self.time {
            Some(t) => format!(" at time {t}"),
            None => String::new(),
        }
    }
}
