//! Moving triangle meshes from glTF 2.0 files (`.gltf` JSON or `.glb` binary).
//!
//! A sequence is one mesh moved by an animation: through the morph weights of its node, the
//! joints of its skin, or the transforms of its node and the node's ancestors. At time `t`
//! vertex `i` is
//!
//! ```text
//! p_i(t) = M(t) p̃_i(t)                              (no skin)
//! p_i(t) = Σ_k ω_ik J_{j_ik}(t) B_{j_ik} p̃_i(t)     (skinned: linear-blend skinning)
//! p̃_i(t) = b_i + Σ_j w_j(t) δ_ij
//! ```
//!
//! with `b` the base POSITION, `δ_j` the POSITION deltas of target `j` (morphing comes before
//! skinning, as glTF specifies), `M = L_root ⋯ L_parent L_node` the world transform of the
//! mesh's node, `J_j` that of joint `j`'s node, `B_j` the skin's inverse bind matrix of joint
//! `j` and `ω_ik` the weights of vertex `i`'s joints `j_ik`, normalized to sum 1 (module
//! `skin`). As glTF specifies, the mesh node's own transform is ignored for a skinned mesh:
//! the joints place it. Local transforms `L = T · R · S` come from a node's translation,
//! rotation and scale, each replaced by the value of its animation channel at `t` (module
//! `nodes`); the weights `w(t)` from the sampler of the mesh node's `weights`, else the node's
//! or mesh's default weights. Samplers interpolate between keyframes as glTF specifies (module
//! `animation`): LINEAR (rotations by spherical linear interpolation along the shorter arc),
//! STEP, CUBICSPLINE (the cubic Hermite spline of Appendix C, rotations normalized); before the
//! first and after the last keyframe the end values hold.
//!
//! Colours (the image, see [`crate::load::Channels`]) come from `COLOR_0` (RGB, alpha ignored) plus its
//! morph-target deltas, the same weighted sum; without `COLOR_0`, from the material's
//! base-colour texture sampled bilinearly (see [`Texture`], always with repeat wrapping) at
//! the texture coordinates it names (`TEXCOORD_n` plus deltas, `t` from the top as glTF
//! has it). Colours and texels are taken as stored: `baseColorFactor`, sampler wrap modes and
//! texture transforms are ignored. Skinning and node motion carry them with the surface.
//!
//! # What a file must hold
//!
//! Exactly one node with a mesh; all of that mesh's primitives triangle lists.
//! Several primitives are merged into one mesh: their vertices follow each other in primitive
//! order and their triangles are renumbered accordingly; they then have colours only if
//! every primitive has a source for them. Vertices are returned as stored, one per glTF
//! vertex: glTF splits vertices along texture and normal seams, so the caller welds
//! coincident vertices. Indices may be `u8`, `u16` or `u32`, or absent (triangles
//! `(0, 1, 2), (3, 4, 5), …`). When the node has a skin, every primitive has `JOINTS_0` and
//! `WEIGHTS_0` (and further sets in pairs). For an animation, the one chosen by name or index
//! is used, else the first that moves the mesh (with a warning listing all of them when there
//! are several); its frames are at the keyframes of all its channels that move the mesh. A
//! static frame is the mesh with every node at its own transform.

mod animation;
mod file;
mod glb;
mod nodes;
mod skin;
mod write;

use super::{FrameMesh, IoError, KeepRows, RawSequence, Texture, VertexValues};
pub(crate) use animation::clip_list;
use animation::{resampled_times, Motion};
pub use animation::{AnimationClip, ImplicitClip};
use file::GltfFile;
use gltf::mesh::{Mode, Semantic};
use gltf::Node;
use nalgebra::Vector3;
use nodes::{Nodes, Pose};
use skin::{Influences, Skin};
use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;
pub use write::{write_glb_animation, AnimationFrame};

/// Which frames of a file's animation to read.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AnimationOptions {
    /// The animation, by name or index; `None`: the first that moves the mesh.
    pub animation: Option<String>,
    /// Frames at `t₀, t₀ + 1/fps, …` up to the last keyframe, interpolated; `None`: one frame
    /// per keyframe.
    pub fps: Option<f64>,
}

/// Reads an animation (`options.animation`, by name or index, else the first that moves the
/// mesh): one frame per keyframe of its channels that move the mesh (`options.fps = None`), or
/// frames at `t₀, t₀ + 1/fps, …` up to the last keyframe, interpolated. See the module
/// documentation for what the file must contain. `times` are the frame times, `sources` the
/// path once per frame.
pub fn read_gltf_animation(
    path: &Path,
    options: &AnimationOptions,
) -> Result<RawSequence, IoError> {
    Ok(read_gltf_animation_frames(path, options, &|_| true)?.0)
}

/// [`read_gltf_animation`] evaluated at the frames `keep` only (`positions`, `images` and
/// `sources` hold those; `times` all of them), and the number of frames: what a rank reading
/// its time window needs. With no frame kept, only the animation's times are read.
pub fn read_gltf_animation_frames(
    path: &Path,
    options: &AnimationOptions,
    keep: KeepRows,
) -> Result<(RawSequence, usize), IoError> {
    let file = GltfFile::open(path)?;
    let node = mesh_node(&file)?;
    let nodes = Nodes::read(&file)?;
    let surface = Surface::read(&file, &node, true)?;
    let (motion, implicit_clip) = Motion::read(
        &file,
        &nodes,
        &node,
        &surface.placing(&nodes),
        surface.target_count,
        options.animation.as_deref(),
    )?;
    let times = match options.fps {
        None => motion.times.clone(),
        Some(fps) => resampled_times(&motion.times, fps).map_err(|m| file.error(m))?,
    };
    let rest_weights = default_weights(&file, &node, surface.target_count)?;
    let kept: Vec<f64> = (times.iter().enumerate())
        .filter(|&(k, _)| keep(k))
        .map(|(_, &t)| t)
        .collect();
    surface.check_frames(&file, kept.len(), options.fps)?;
    let mut positions = Vec::with_capacity(kept.len());
    let mut images = Vec::with_capacity(kept.len());
    for &t in &kept {
        let weights = motion.weights(t).unwrap_or_else(|| rest_weights.clone());
        positions.push(surface.positions(
            &weights,
            &nodes.pose(motion.node_values(t), t),
            &file,
        )?);
        images.push(surface.image(&weights, &file)?);
    }
    let n_frames = times.len();
    let raw = RawSequence {
        faces: surface.faces,
        positions,
        images: images.into_iter().collect(),
        sources: vec![path.to_path_buf(); kept.len()],
        times: Some(times),
        implicit_clip,
    };
    Ok((raw, n_frames))
}

/// Reads one static mesh (for sequences stored one file per frame): the mesh node's
/// geometry in world coordinates (skinned by the joints at their nodes' own transforms), at
/// the default morph weights of the node or mesh (zero if neither gives any), with colours as
/// in [`read_gltf_animation`]. Animations are ignored.
pub fn read_gltf_frame(path: &Path) -> Result<FrameMesh, IoError> {
    read_static(path, true)
}

/// [`read_gltf_frame`] without its image: no colours are read and no image is decoded.
pub fn read_gltf_geometry(path: &Path) -> Result<FrameMesh, IoError> {
    read_static(path, false)
}

fn read_static(path: &Path, colors: bool) -> Result<FrameMesh, IoError> {
    let file = GltfFile::open(path)?;
    let node = mesh_node(&file)?;
    let nodes = Nodes::read(&file)?;
    let surface = Surface::read(&file, &node, colors)?;
    let weights = default_weights(&file, &node, surface.target_count)?;
    Ok(FrameMesh {
        positions: surface.positions(&weights, &nodes.rest(), &file)?,
        image: surface.image(&weights, &file)?,
        faces: surface.faces,
    })
}

/// Advice for files without an animation of the mesh.
const NO_ANIMATION: &str = "no animation moves the mesh (its morph weights, skin joints or \
                            node transforms); for one file per frame use a directory";

/// The one node carrying a mesh.
fn mesh_node<'a>(file: &'a GltfFile) -> Result<Node<'a>, IoError> {
    let nodes: Vec<Node> = file
        .document
        .nodes()
        .filter(|n| n.mesh().is_some())
        .collect();
    match nodes.as_slice() {
        [node] => Ok(node.clone()),
        [] => Err(file.error("no mesh: no node of the file carries a mesh")),
        _ => Err(file.error(format!(
            "{} nodes carry meshes; only files with one (moving) mesh are supported",
            nodes.len()
        ))),
    }
}

fn node_label(node: &Node) -> String {
    match node.name() {
        Some(name) => format!("node {} ({name:?})", node.index()),
        None => format!("node {}", node.index()),
    }
}

/// The node's default morph weights (its own, else its mesh's, else zeros).
fn default_weights(file: &GltfFile, node: &Node, target_count: usize) -> Result<Vec<f64>, IoError> {
    let weights = node
        .weights()
        .or_else(|| node.mesh().and_then(|m| m.weights()));
    match weights {
        None => Ok(vec![0.0; target_count]),
        Some(w) if w.len() == target_count => Ok(w.iter().map(|&x| f64::from(x)).collect()),
        Some(w) => Err(file.error(format!(
            "{}: {} default weights for {target_count} morph targets",
            node_label(node),
            w.len()
        ))),
    }
}

/// Per-vertex data with morph-target deltas: `base + Σ_j w_j delta_j`.
struct Morphed<const N: usize> {
    base: Vec<[f64; N]>,
    /// Per target; `None` if the target leaves this attribute alone.
    deltas: Vec<Option<Vec<[f64; N]>>>,
}

impl<const N: usize> Morphed<N> {
    fn at(&self, weights: &[f64]) -> Vec<[f64; N]> {
        let mut values = self.base.clone();
        for (&w, delta) in weights.iter().zip(&self.deltas) {
            // Skipping zero weights saves work and keeps keyframe poses bit-exact (adding 0·δ
            // would turn a −0 into +0).
            let Some(delta) = delta.as_ref().filter(|_| w != 0.0) else {
                continue;
            };
            for (value, d) in values.iter_mut().zip(delta) {
                for c in 0..N {
                    value[c] += w * d[c];
                }
            }
        }
        values
    }
}

/// Where a primitive's colours come from.
enum ColorSource {
    Colors(Morphed<3>),
    Texture {
        coords: Morphed<2>,
        texture: Rc<Texture>,
        label: String,
    },
}

impl ColorSource {
    fn at(&self, weights: &[f64], file: &GltfFile) -> Result<Vec<[f64; 3]>, IoError> {
        match self {
            ColorSource::Colors(colors) => Ok(colors.at(weights)),
            ColorSource::Texture {
                coords,
                texture,
                label,
            } => coords
                .at(weights)
                .into_iter()
                .enumerate()
                .map(|(i, [s, t])| {
                    texture.sample(s, t).ok_or_else(|| {
                        file.error(format!(
                            "{label}: texture coordinates of vertex {i} are not finite"
                        ))
                    })
                })
                .collect(),
        }
    }
}

/// One triangle primitive: morphing positions and perhaps a colour source.
struct MorphPrimitive {
    positions: Morphed<3>,
    colors: Option<ColorSource>,
}

/// The mesh of the mesh node, all primitives merged, and what places it in the world.
struct Surface {
    faces: Vec<[u32; 3]>,
    primitives: Vec<MorphPrimitive>,
    target_count: usize,
    placement: Placement,
}

/// How the mesh is placed in the world.
enum Placement {
    /// By the world transform of the mesh node.
    Node(usize),
    /// By the joints of the node's skin, with the influences of every vertex.
    Skin {
        skin: Skin,
        influences: Vec<Influences>,
    },
}

impl Surface {
    /// The surface of `node`, with the primitives' colour sources when `colors`.
    fn read(file: &GltfFile, node: &Node, colors: bool) -> Result<Self, IoError> {
        let mesh = node
            .mesh()
            .ok_or_else(|| file.error(format!("{} has no mesh", node_label(node))))?;
        if mesh.primitives().len() == 0 {
            return Err(file.error(format!("mesh {} has no primitives", mesh.index())));
        }
        check_mesh_size(file, &mesh)?;
        let placement = match node.skin() {
            Some(skin) => Placement::Skin {
                skin: Skin::read(file, &skin)?,
                influences: Vec::new(),
            },
            None => Placement::Node(node.index()),
        };
        let mut surface = Surface {
            faces: Vec::new(),
            primitives: Vec::new(),
            target_count: 0,
            placement,
        };
        let mut textures = HashMap::new();
        for primitive in mesh.primitives() {
            let reader = PrimitiveReader {
                file,
                label: primitive_label(&mesh, &primitive),
                mesh: mesh.index(),
                primitive,
            };
            let (faces, read) = reader.read(colors.then_some(&mut textures))?;
            let target_count = read.positions.deltas.len();
            // glTF requires all primitives of a mesh to have the same morph targets.
            if !surface.primitives.is_empty() && target_count != surface.target_count {
                return Err(file.error(format!(
                    "{}: {target_count} morph targets, the first primitive has {}",
                    reader.label, surface.target_count
                )));
            }
            surface.target_count = target_count;
            let vertex_count = read.positions.base.len();
            if let Placement::Skin { skin, influences } = &mut surface.placement {
                influences.extend(reader.influences(skin.joint_count(), vertex_count)?);
            }
            let first_vertex = surface.vertex_count();
            if u32::try_from(first_vertex + vertex_count).is_err() {
                return Err(file.error("more than 2³² vertices"));
            }
            let first_vertex = first_vertex as u32;
            surface
                .faces
                .extend(faces.into_iter().map(|f| f.map(|i| i + first_vertex)));
            surface.primitives.push(read);
        }
        Ok(surface)
    }

    fn vertex_count(&self) -> usize {
        self.primitives.iter().map(|p| p.positions.base.len()).sum()
    }

    /// The nodes whose transforms place the mesh, sorted.
    fn placing(&self, nodes: &Nodes) -> Vec<usize> {
        match &self.placement {
            Placement::Node(node) => nodes.with_ancestors([*node]),
            Placement::Skin { skin, .. } => skin.placing(nodes),
        }
    }

    /// Checks that `frames` frames of this surface (positions, and colours where it has
    /// them) fit the memory limit before they are computed; `fps` (`--fps`) is named when it
    /// set the frame count.
    fn check_frames(
        &self,
        file: &GltfFile,
        frames: usize,
        fps: Option<f64>,
    ) -> Result<(), IoError> {
        let vertices = self.vertex_count() as u64;
        let images = self.primitives.iter().all(|p| p.colors.is_some());
        // Positions and colours, 24 bytes a vertex each, and a frame's vectors.
        let frame_bytes = vertices * if images { 48 } else { 24 } + 64;
        let cause = match fps {
            Some(fps) => format!("--fps {fps} gives {frames} frames"),
            None => format!("the animation has {frames} frames"),
        };
        crate::limits::check_items(
            format!("{cause} of {vertices} vertices, which"),
            frames as u64,
            frame_bytes,
        )
        .map_err(|e| IoError::too_large(file.path, e))
    }

    /// World positions of all vertices at the given morph weights and node pose.
    fn positions(
        &self,
        weights: &[f64],
        pose: &Pose,
        file: &GltfFile,
    ) -> Result<Vec<Vector3<f64>>, IoError> {
        let morphed = self.primitives.iter().flat_map(|p| p.positions.at(weights));
        match &self.placement {
            Placement::Node(node) => {
                let world = pose.worlds(file, &[*node])?[0];
                let linear = world.fixed_view::<3, 3>(0, 0);
                let translation = world.fixed_view::<3, 1>(0, 3);
                Ok(morphed
                    .map(|p| linear * Vector3::from(p) + translation)
                    .collect())
            }
            Placement::Skin { skin, influences } => Ok(skin::blend(
                morphed,
                influences,
                &skin.matrices(file, pose)?,
            )),
        }
    }

    /// Colours of all vertices, if every primitive has a source for them.
    fn image(&self, weights: &[f64], file: &GltfFile) -> Result<Option<VertexValues>, IoError> {
        let mut colors = Vec::with_capacity(self.vertex_count());
        for primitive in &self.primitives {
            match &primitive.colors {
                Some(source) => colors.extend(source.at(weights, file)?),
                None => return Ok(None),
            }
        }
        Ok(Some(VertexValues::Colors(colors)))
    }
}

/// Checks what the primitives of `mesh` declare against the memory limit before any is read:
/// their POSITION counts times one plus their morph targets, at 48 bytes (a position and a
/// colour), and their index counts at 4 bytes. Primitives may share accessors, so this bounds
/// what the data present cannot.
fn check_mesh_size(file: &GltfFile, mesh: &gltf::Mesh) -> Result<(), IoError> {
    let mut bytes = 0u64;
    for primitive in mesh.primitives() {
        let vertices = primitive.get(&Semantic::Positions).map_or(0, |a| a.count());
        let copies = 1 + primitive.morph_targets().len();
        let indices = primitive.indices().map_or(0, |a| a.count());
        let declared = (vertices as u64)
            .saturating_mul(copies as u64)
            .saturating_mul(48)
            .saturating_add(4 * indices as u64);
        bytes = bytes.saturating_add(declared);
    }
    let what = format!(
        "mesh {} ({} primitives: vertices × morph targets, indices)",
        mesh.index(),
        mesh.primitives().len()
    );
    crate::limits::check_declared(what, bytes).map_err(|e| IoError::too_large(file.path, e))
}

fn primitive_label(mesh: &gltf::Mesh, primitive: &gltf::Primitive) -> String {
    let name = mesh.name().map(|n| format!(" ({n:?})")).unwrap_or_default();
    format!(
        "mesh {}{name}, primitive {}",
        mesh.index(),
        primitive.index()
    )
}

/// Reads one primitive of mesh `mesh`.
struct PrimitiveReader<'f, 'p> {
    file: &'f GltfFile<'p>,
    primitive: gltf::Primitive<'f>,
    mesh: usize,
    label: String,
}

impl PrimitiveReader<'_, '_> {
    /// The primitive's triangles (local vertex numbers) and data, with its colour source
    /// when given `textures` (a cache of decoded images by index).
    fn read(
        &self,
        textures: Option<&mut HashMap<usize, Rc<Texture>>>,
    ) -> Result<(Vec<[u32; 3]>, MorphPrimitive), IoError> {
        if self.primitive.mode() != Mode::Triangles {
            return Err(self.error(format!(
                "{:?} primitive; only triangle lists are supported",
                self.primitive.mode()
            )));
        }
        let positions = self.attribute::<3>(&Semantic::Positions, "POSITION", &[3], None)?;
        let positions = positions.ok_or_else(|| self.error("no POSITION attribute".to_string()))?;
        let vertex_count = positions.base.len();
        let faces = self.faces(vertex_count)?;
        let colors = match textures {
            Some(textures) => self.color_source(vertex_count, textures)?,
            None => None,
        };
        Ok((faces, MorphPrimitive { positions, colors }))
    }

    fn error(&self, message: String) -> IoError {
        self.file.error(format!("{}: {message}", self.label))
    }

    /// An attribute with its morph-target deltas; `None` if the primitive lacks it.
    fn attribute<const N: usize>(
        &self,
        semantic: &Semantic,
        name: &str,
        widths: &[usize],
        vertex_count: Option<usize>,
    ) -> Result<Option<Morphed<N>>, IoError> {
        let Some(accessor) = self.primitive.get(semantic) else {
            return Ok(None);
        };
        let label = format!("{}, {name}", self.label);
        let base = self
            .file
            .read_elements::<N>(&accessor, &label, widths, vertex_count)?;
        let deltas = (0..self.primitive.morph_targets().len())
            .map(|target| {
                let accessor =
                    self.file
                        .target_accessor(&self.primitive, self.mesh, target, name)?;
                let label = format!("{}, morph target {target}, {name}", self.label);
                accessor
                    .map(|a| {
                        self.file
                            .read_elements::<N>(&a, &label, widths, Some(base.len()))
                    })
                    .transpose()
            })
            .collect::<Result<_, _>>()?;
        Ok(Some(Morphed { base, deltas }))
    }

    /// The triangles, from the indices or, without them, consecutive vertex triples.
    fn faces(&self, vertex_count: usize) -> Result<Vec<[u32; 3]>, IoError> {
        let Some(accessor) = self.primitive.indices() else {
            if !vertex_count.is_multiple_of(3) {
                return Err(self.error(format!(
                    "{vertex_count} vertices without indices do not form triangles"
                )));
            }
            return Ok((0..vertex_count as u32 / 3)
                .map(|f| [3 * f, 3 * f + 1, 3 * f + 2])
                .collect());
        };
        if !matches!(
            accessor.data_type(),
            gltf::accessor::DataType::U8
                | gltf::accessor::DataType::U16
                | gltf::accessor::DataType::U32
        ) {
            return Err(self.error(format!("indices of type {:?}", accessor.data_type())));
        }
        let label = format!("{}, indices", self.label);
        let indices = self
            .file
            .read_elements::<1>(&accessor, &label, &[1], None)?;
        if indices.len() % 3 != 0 {
            return Err(self.error(format!("{} indices do not form triangles", indices.len())));
        }
        if let Some([i]) = indices.iter().find(|[i]| *i >= vertex_count as f64) {
            return Err(self.error(format!("index {i} beyond the {vertex_count} vertices")));
        }
        // Exact: the values are unsigned integers below the vertex count.
        Ok(indices
            .chunks_exact(3)
            .map(|t| [t[0][0] as u32, t[1][0] as u32, t[2][0] as u32])
            .collect())
    }

    /// `COLOR_0` if present, else the base-colour texture at its texture coordinates.
    fn color_source(
        &self,
        vertex_count: usize,
        textures: &mut HashMap<usize, Rc<Texture>>,
    ) -> Result<Option<ColorSource>, IoError> {
        let count = Some(vertex_count);
        if let Some(colors) =
            self.attribute::<3>(&Semantic::Colors(0), "COLOR_0", &[3, 4], count)?
        {
            return Ok(Some(ColorSource::Colors(colors)));
        }
        let material = self.primitive.material();
        let Some(info) = material.pbr_metallic_roughness().base_color_texture() else {
            return Ok(None);
        };
        let set = info.tex_coord();
        let name = format!("TEXCOORD_{set}");
        let coords = self
            .attribute::<2>(&Semantic::TexCoords(set), &name, &[2], count)?
            .ok_or_else(|| {
                self.error(format!(
                    "the base colour texture needs {name}, which is missing"
                ))
            })?;
        let image = info.texture().source();
        let texture = match textures.get(&image.index()) {
            Some(texture) => Rc::clone(texture),
            None => {
                let texture = Rc::new(self.file.texture(image.clone())?);
                textures.insert(image.index(), Rc::clone(&texture));
                texture
            }
        };
        Ok(Some(ColorSource::Texture {
            coords,
            texture,
            label: self.label.clone(),
        }))
    }
}
