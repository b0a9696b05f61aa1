//! What a flow tells: divergence, curl, the Helmholtz–Hodge parts and the tissue's strain rate,
//! per slab on the slab's mean geometry, everything intrinsic like the flow itself.
//!
//! For slab `s` with flow `u` (vertex-frame vectors, as [`FlowResult::intrinsic`]):
//!
//! | quantity | where | formula | units |
//! |---|---|---|---|
//! | divergence, curl | per face | `tr ∇U_T`, `(∇U_T)₂₁ − (∇U_T)₁₂` ([`derivatives`]) | 1/time |
//! | divergence, curl | per vertex | weak form over the barycentric area, with boundary flux ([`derivatives`]) | 1/time |
//! | `∇φ`, `J∇ψ`, `h` | per face | Hodge parts of `U_T`, the mean of the corner vectors ([`hodge`]) | length/time |
//! | `φ`, `ψ` | vertices, edges | their potentials | length²/time |
//! | `D` | per face | `½ ġ + Sym ∇U_T`, areal rate `tr D`, shear rate `|dev D|`, principal rates and directions ([`strain`]) | 1/time |
//!
//! Signs: `J` turns by +90° counter-clockwise about the normal of the faces' orientation;
//! positive divergence is a source (the tissue spreads), negative a sink; positive curl turns
//! counter-clockwise. `div ∇f = curl J∇f = Δf` (the Laplace–Beltrami operator, negative
//! semi-definite), so on the unit sphere `u = ∇Y_l` has `div u = −l(l+1) Y_l`.
//!
//! Face quantities are in the face's layout frame of the slab geometry; [`face_frames`] maps
//! them into R³ on frame `s` (the affine map of the layout onto the frame's triangle), as the
//! flow's own vectors are shown on frame `s`.
//!
//! [`FlowResult::intrinsic`]: crate::flow::FlowResult::intrinsic

pub mod derivatives;
pub mod hodge;
pub mod strain;

use crate::connection::Connection;
use crate::flow::{FlowError, MeshSequence};
use crate::geometry::IntrinsicGeometry;
use crate::mesh::Mesh;
use derivatives::{divergence_and_curl, face_vectors, field_gradient, vertex_divergence_and_curl};
pub use hodge::{HodgeParts, HodgeSolver};
use nalgebra::{Matrix2, Matrix3x2, Vector2, Vector3};
use rayon::prelude::*;
pub use strain::StrainRate;

/// Everything read from one slab's flow.
#[derive(Clone, Debug)]
pub struct SlabAnalysis {
    pub slab: usize,
    pub face_divergence: Vec<f64>,
    pub face_curl: Vec<f64>,
    pub vertex_divergence: Vec<f64>,
    pub vertex_curl: Vec<f64>,
    pub hodge: HodgeParts,
    /// Per face.
    pub strain: Vec<StrainRate>,
    pub totals: SlabTotals,
}

/// Per slab: sizes and means over the surface (area-weighted over faces) and the energies
/// `∫|·|²` of the field and its Hodge parts (which add up: the parts are orthogonal).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SlabTotals {
    pub area: f64,
    pub mean_speed: f64,
    pub mean_divergence: f64,
    pub mean_curl: f64,
    pub mean_areal_rate: f64,
    pub mean_shear_rate: f64,
    pub energy: f64,
    pub exact_energy: f64,
    pub coexact_energy: f64,
    pub harmonic_energy: f64,
}

/// Analyses every slab of `sequence` with its flow `flow[s][i]` (vertex-frame vectors, as
/// [`crate::flow::FlowResult::intrinsic`]); one [`HodgeSolver`] serves all slabs, which are
/// analysed in parallel. The solver's per-mesh set-up runs beside the slabs' derivatives and
/// strain rates, which do not need it.
pub fn analyze_flow(
    sequence: &MeshSequence,
    flow: &[Vec<Vector2<f64>>],
) -> Result<Vec<SlabAnalysis>, FlowError> {
    check_sizes(sequence, flow)?;
    let (hodge, derived) = rayon::join(
        || HodgeSolver::new(sequence.mesh()),
        || {
            (0..sequence.n_slabs())
                .into_par_iter()
                .map(|s| SlabDerivatives::new(sequence, s, &flow[s]))
                .collect::<Result<Vec<_>, _>>()
        },
    );
    (derived?.into_par_iter())
        .map(|derived| derived.with_hodge(sequence.mesh(), &hodge))
        .collect()
}

fn check_sizes(sequence: &MeshSequence, flow: &[Vec<Vector2<f64>>]) -> Result<(), FlowError> {
    let count = |what, expected, got| match expected == got {
        true => Ok(()),
        false => Err(FlowError::CountMismatch {
            what,
            expected,
            got,
        }),
    };
    count("flow slabs", sequence.n_slabs(), flow.len())?;
    let n = sequence.mesh().n_vertices();
    flow.iter()
        .try_for_each(|u| count("flow vectors per slab", n, u.len()))
}

/// The analysis of slab `s` with flow `u`.
pub fn analyze_slab(
    sequence: &MeshSequence,
    s: usize,
    u: &[Vector2<f64>],
    hodge: &HodgeSolver,
) -> Result<SlabAnalysis, FlowError> {
    SlabDerivatives::new(sequence, s, u)?.with_hodge(sequence.mesh(), hodge)
}

/// What a slab's analysis reads from its flow without the Hodge decomposition.
struct SlabDerivatives {
    slab: usize,
    geometry: IntrinsicGeometry,
    face_divergence: Vec<f64>,
    face_curl: Vec<f64>,
    vertex_divergence: Vec<f64>,
    vertex_curl: Vec<f64>,
    /// `U_T`, the mean of each face's corner vectors.
    field: Vec<Vector2<f64>>,
    strain: Vec<StrainRate>,
}

impl SlabDerivatives {
    fn new(sequence: &MeshSequence, s: usize, u: &[Vector2<f64>]) -> Result<Self, FlowError> {
        let mesh = sequence.mesh();
        let geometry = sequence.slab_geometry(s)?;
        let connection = Connection::new(mesh, &geometry);
        let n_faces = mesh.n_faces();
        let dt = sequence.slab_duration(s);
        let (before, after) = (sequence.edge_lengths(s), sequence.edge_lengths(s + 1));
        let mut face_divergence = Vec::with_capacity(n_faces);
        let mut face_curl = Vec::with_capacity(n_faces);
        let mut field = Vec::with_capacity(n_faces);
        let mut strain = Vec::with_capacity(n_faces);
        let vectors: Vec<[Vector2<f64>; 3]> = (0..n_faces)
            .map(|f| face_vectors(mesh, &connection, f, u))
            .collect();
        for (f, v) in vectors.iter().enumerate() {
            let triangle = geometry.triangle(f);
            let gradient = field_gradient(triangle, v);
            let (div, curl) = divergence_and_curl(&gradient);
            face_divergence.push(div);
            face_curl.push(curl);
            field.push((v[0] + v[1] + v[2]) / 3.0);
            let lengths = |all: &[f64]| std::array::from_fn(|c| all[mesh.halfedge_edge(3 * f + c)]);
            strain.push(strain::face_strain_rate(
                triangle,
                lengths(before),
                lengths(after),
                dt,
                &gradient,
            ));
        }
        let (vertex_divergence, vertex_curl) =
            vertex_divergence_and_curl(mesh, &geometry, &vectors);
        Ok(SlabDerivatives {
            slab: s,
            geometry,
            face_divergence,
            face_curl,
            vertex_divergence,
            vertex_curl,
            field,
            strain,
        })
    }

    fn with_hodge(self, mesh: &Mesh, hodge: &HodgeSolver) -> Result<SlabAnalysis, FlowError> {
        let geometry = &self.geometry;
        let hodge = hodge.decompose(mesh, geometry, self.field)?;
        let totals = totals(
            geometry,
            &self.face_divergence,
            &self.face_curl,
            &self.strain,
            &hodge,
        );
        Ok(SlabAnalysis {
            slab: self.slab,
            face_divergence: self.face_divergence,
            face_curl: self.face_curl,
            vertex_divergence: self.vertex_divergence,
            vertex_curl: self.vertex_curl,
            hodge,
            strain: self.strain,
            totals,
        })
    }
}

fn totals(
    geometry: &IntrinsicGeometry,
    divergence: &[f64],
    curl: &[f64],
    strain: &[StrainRate],
    hodge: &HodgeParts,
) -> SlabTotals {
    let areas: Vec<f64> = geometry.triangles().iter().map(|t| t.area).collect();
    let area: f64 = areas.iter().sum();
    let mean = |values: &mut dyn Iterator<Item = f64>| {
        values.zip(&areas).map(|(x, a)| x * a).sum::<f64>() / area
    };
    let energy = |part: &[Vector2<f64>]| hodge::inner_product(geometry, part, part);
    SlabTotals {
        area,
        mean_speed: mean(&mut hodge.field.iter().map(|v| v.norm())),
        mean_divergence: mean(&mut divergence.iter().copied()),
        mean_curl: mean(&mut curl.iter().copied()),
        mean_areal_rate: mean(&mut strain.iter().map(|d| d.areal)),
        mean_shear_rate: mean(&mut strain.iter().map(|d| d.shear)),
        energy: energy(&hodge.field),
        exact_energy: energy(&hodge.exact),
        coexact_energy: energy(&hodge.coexact),
        harmonic_energy: energy(&hodge.harmonic),
    }
}

/// Per face of slab `s`, the linear map (3×2) from its layout frame in the slab geometry onto
/// its triangle on frame `s` in R³: `M_T = [P_b − P_a, P_c − P_a] [p_b − p_a, p_c − p_a]⁻¹`.
/// `None` for a sequence of edge lengths.
pub fn face_frames(
    sequence: &MeshSequence,
    s: usize,
) -> Result<Option<Vec<Matrix3x2<f64>>>, FlowError> {
    let Some(positions) = sequence.positions(s) else {
        return Ok(None);
    };
    let geometry = sequence.slab_geometry(s)?;
    let maps = (sequence.mesh().faces().iter().enumerate())
        .map(|(f, face)| {
            let [a, b, c] = face.map(|i| positions[i as usize]);
            let embedded = Matrix3x2::from_columns(&[b - a, c - a]);
            let layout: Matrix2<f64> = geometry.triangle(f).layout_edge_matrix();
            // A valid triangle's layout edges are independent.
            embedded * layout.try_inverse().unwrap_or_else(Matrix2::zeros)
        })
        .collect();
    Ok(Some(maps))
}

/// Face-frame vectors mapped into R³ by [`face_frames`].
pub fn in_r3(maps: &[Matrix3x2<f64>], vectors: &[Vector2<f64>]) -> Vec<Vector3<f64>> {
    maps.iter().zip(vectors).map(|(m, v)| m * v).collect()
}
