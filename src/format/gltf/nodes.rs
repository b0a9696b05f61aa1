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

use super::{node_label, GltfFile};
use crate::format::IoError;
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
    /// The nodes of `file`, after checking that they form a forest: every node the child of
    /// at most one node, and no cycle. A hostile file may nest 100 000 nodes or loop, so every
    /// walk up the hierarchy here is iterative and visits each node once.
    pub fn read(file: &GltfFile) -> Result<Self, IoError> {
        let labels: Vec<String> = file.document.nodes().map(|n| node_label(&n)).collect();
        let parents = parents(file, &labels)?;
        check_acyclic(file, &parents, &labels)?;
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
        Ok(Self {
            parents,
            rest,
            labels,
        })
    }

    pub fn label(&self, node: usize) -> &str {
        &self.labels[node]
    }

    /// Whether the node's transform is a matrix (which animations cannot change).
    pub fn has_matrix(&self, node: usize) -> bool {
        matches!(self.rest[node], Local::Matrix(_))
    }

    /// The given nodes and all their ancestors, sorted, each once.
    pub fn with_ancestors(&self, nodes: impl IntoIterator<Item = usize>) -> Vec<usize> {
        let mut seen = vec![false; self.parents.len()];
        let mut found = Vec::new();
        for node in nodes {
            let mut next = Some(node);
            // Stops at the first node already seen: its ancestors are in too.
            while let Some(k) = next.filter(|&k| !seen[k]) {
                seen[k] = true;
                found.push(k);
                next = self.parents[k];
            }
        }
        found.sort_unstable();
        found
    }

    /// The nodes as the file places them.
    pub fn rest(&self) -> Pose<'_> {
        Pose {
            nodes: self,
            animated: HashMap::new(),
            time: None,
        }
    }

    /// The nodes at time `t` of an animation whose channels give `values`, as
    /// `(node, property, value at t)`: they replace the translation, rotation and scale of the
    /// rest transforms.
    pub fn pose(
        &self,
        values: impl IntoIterator<Item = (usize, Property, Vec<f64>)>,
        t: f64,
    ) -> Pose<'_> {
        let mut animated = HashMap::new();
        for (node, property, value) in values {
            // Motion::read refused channels on nodes with a matrix.
            let Local::Trs(rest) = self.rest[node] else {
                continue;
            };
            let trs: &mut Trs = animated.entry(node).or_insert(rest);
            match property {
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
    /// The world transforms `L_root ⋯ L_node` of `nodes`: each ancestor's is computed once
    /// (a skin's joints share long chains).
    pub fn worlds(&self, file: &GltfFile, nodes: &[usize]) -> Result<Vec<Matrix4<f64>>, IoError> {
        let mut known: HashMap<usize, Matrix4<f64>> = HashMap::new();
        nodes
            .iter()
            .map(|&node| {
                let world = self.world_with(file, node, &mut known)?;
                if !world.iter().all(|x| x.is_finite()) {
                    return Err(file.error(format!(
                        "the world transform of {} is not finite{}",
                        self.nodes.label(node),
                        self.when()
                    )));
                }
                Ok(world)
            })
            .collect()
    }

    /// The world transform of `node`, from the nearest ancestor in `known` down; those on the
    /// way are added to it.
    fn world_with(
        &self,
        file: &GltfFile,
        node: usize,
        known: &mut HashMap<usize, Matrix4<f64>>,
    ) -> Result<Matrix4<f64>, IoError> {
        let mut path = Vec::new();
        let mut next = Some(node);
        while let Some(k) = next.filter(|k| !known.contains_key(k)) {
            path.push(k);
            next = self.nodes.parents[k];
        }
        let mut world = next.map_or_else(Matrix4::identity, |k| known[&k]);
        for &k in path.iter().rev() {
            world *= self.local(file, k)?;
            known.insert(k, world);
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

/// The parent of every node; an error names a node listed as the child of two nodes (glTF
/// allows one).
fn parents(file: &GltfFile, labels: &[String]) -> Result<Vec<Option<usize>>, IoError> {
    let mut parents: Vec<Option<usize>> = vec![None; labels.len()];
    for parent in file.document.nodes() {
        for child in parent.children() {
            let Some(slot) = parents.get_mut(child.index()) else {
                continue;
            };
            match *slot {
                Some(other) if other != parent.index() => {
                    return Err(file.error(format!(
                        "{} is a child of both {} and {}; a node has at most one parent",
                        labels[child.index()],
                        labels[other],
                        labels[parent.index()]
                    )))
                }
                _ => *slot = Some(parent.index()),
            }
        }
    }
    Ok(parents)
}

/// Refuses a cycle in the hierarchy, naming a node on it: each node is visited once, walking
/// up from every node until a node already cleared.
fn check_acyclic(
    file: &GltfFile,
    parents: &[Option<usize>],
    labels: &[String],
) -> Result<(), IoError> {
    #[derive(Clone, Copy, PartialEq)]
    enum Visit {
        New,
        OnPath,
        Cleared,
    }
    let mut visits = vec![Visit::New; parents.len()];
    let mut path = Vec::new();
    for start in 0..parents.len() {
        let mut next = Some(start);
        while let Some(k) = next {
            match visits[k] {
                Visit::Cleared => break,
                Visit::OnPath => {
                    return Err(file.error(format!(
                        "the node hierarchy has a cycle through {}",
                        labels[k]
                    )))
                }
                Visit::New => {}
            }
            visits[k] = Visit::OnPath;
            path.push(k);
            next = parents[k];
        }
        path.drain(..).for_each(|k| visits[k] = Visit::Cleared);
    }
    Ok(())
}
