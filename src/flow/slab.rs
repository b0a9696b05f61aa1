//! Slabs: the time interval between two frames, with its mean geometry and image rates
//! (`docs/discretization.md` §3).

use super::anisotropy::{time_entries, SpaceTimeStructure};
use super::local::{local_motion_tensors, lumped_data_element, MotionTensor};
use super::{FlowError, FlowParams, MeshSequence, Regularizer, TimeCoupling, Weights};
use crate::connection::{polar_rotations, vertex_frames_in_r3, Connection};
use crate::fem::element::{self, DataElement};
use crate::geometry::{IntrinsicGeometry, Triangle};
use nalgebra::{Matrix2, Matrix3, Matrix3x2, Matrix6, Vector2, Vector6};
use rayon::prelude::*;

/// One image channel `c` on a slab: `I_mid = (I_s + I_{s+1}) / 2`, `τ = (I_{s+1} − I_s) / Δt_s`
/// per vertex, and the channel's weight `w_c` in the data term `Σ_c w_c (τ_c + dI_c(u))²`.
#[derive(Clone, Debug)]
pub struct SlabChannel {
    pub weight: f64,
    pub mid: Vec<f64>,
    pub rate: Vec<f64>,
}

impl SlabChannel {
    /// The channel between the images `before` (at `t_s`) and `after` (at `t_s + dt`).
    pub fn between(before: &[f64], after: &[f64], dt: f64, weight: f64) -> Self {
        Self {
            weight,
            mid: before
                .iter()
                .zip(after)
                .map(|(a, b)| 0.5 * (a + b))
                .collect(),
            rate: before
                .iter()
                .zip(after)
                .map(|(a, b)| (b - a) / dt)
                .collect(),
        }
    }
}

/// Slab `s = [t_s, t_{s+1}]`: lengths are the mean of the two frames' lengths; each image
/// channel's mid values and rates ([`SlabChannel`]).
#[derive(Clone, Debug)]
pub struct Slab {
    pub geometry: IntrinsicGeometry,
    pub connection: Connection,
    pub dt: f64,
    /// One per image channel (one for grey).
    pub channels: Vec<SlabChannel>,
    /// The flow the data term is linearized around (vertex frames), `None` for zero: with
    /// images warped by it, `∂_t I + dI(u)` becomes `τ + G·R_a (u_a − ū_a)` at corner `a`
    /// (see [`crate::flow::warped_slab`]).
    pub linearization: Option<Vec<Vector2<f64>>>,
    /// Per face, the weight of the regularizer (robust smoothness, [`crate::flow::robust`]);
    /// `None` for 1 everywhere.
    pub smoothness_weights: Option<Vec<f64>>,
    /// Per face, the weight of the data term (the robust data term,
    /// [`crate::flow::robust`]); `None` for 1 everywhere.
    pub data_weights: Option<Vec<f64>>,
    /// The vertex frames `P_i` in R³ on frame `s` (embedded sequences; the embedded
    /// regularizer uses them), `None` for intrinsic ones.
    pub embedding_frames: Option<Vec<Matrix3x2<f64>>>,
    /// Per face, the anisotropic regularizer's tensor `D` in the face frame
    /// ([`crate::flow::anisotropy`]); `None`: the isotropic regularizer (`D = Id`).
    pub diffusion_tensors: Option<Vec<Matrix2<f64>>>,
    /// The contrast `λ` the image-driven tensors were built with (`auto` resolved).
    pub contrast: Option<f64>,
    /// Per face, the presmoothed image's space-time gradient, for the anisotropic coupling in
    /// time ([`crate::flow::anisotropy`], "In time"); `None`: the paper's coupling.
    pub space_time: Option<Vec<SpaceTimeStructure>>,
    /// Per vertex, the averaged motion tensor of the combined local-global data term
    /// ([`crate::flow::local`]); `None`: the paper's data term.
    pub local_motion: Option<Vec<MotionTensor>>,
}

/// The element matrices of one face of one slab, before weighting by `Δt`, `β`, `γ`
/// (`stiffness`: the spatial regularizer's; `mass`: the scalar consistent mass, whose vector
/// element is [`Slab::vector_form_element`]).
pub struct FaceElements {
    pub data: DataElement,
    pub mass: Matrix3<f64>,
    pub stiffness: Matrix6<f64>,
}

impl Slab {
    /// Slab `s` of `sequence`, channel `c` weighted by `channel_weights[c]` (one per channel).
    pub(crate) fn new(
        sequence: &MeshSequence,
        s: usize,
        channel_weights: &[f64],
    ) -> Result<Self, FlowError> {
        let dt = sequence.slab_duration(s);
        let (before, after) = (sequence.channels(s), sequence.channels(s + 1));
        let channels = (before.iter().zip(after).zip(channel_weights))
            .map(|((b, a), &w)| SlabChannel::between(b, a, dt, w))
            .collect();
        Self::with_channels(sequence, s, channels, None)
    }

    /// Slab `s`'s geometry and connection with the given channels, linearized around `u`.
    pub(crate) fn with_channels(
        sequence: &MeshSequence,
        s: usize,
        channels: Vec<SlabChannel>,
        linearization: Option<Vec<Vector2<f64>>>,
    ) -> Result<Self, FlowError> {
        let geometry = sequence.slab_geometry(s)?;
        let connection = Connection::new(sequence.mesh(), &geometry);
        Ok(Self {
            geometry,
            connection,
            dt: sequence.slab_duration(s),
            channels,
            linearization,
            smoothness_weights: None,
            data_weights: None,
            embedding_frames: None,
            diffusion_tensors: None,
            contrast: None,
            space_time: None,
            local_motion: None,
        })
    }

    /// The data term's structure tensor on face `f`: `Σ_c w_c G_c G_cᵀ` (its trace is the
    /// squared gradient `|∇I|²` of a grey image).
    pub fn structure_tensor(&self, face: &[u32; 3], f: usize) -> Matrix2<f64> {
        let channels = self.channels.iter().map(|c| (c.weight, c.mid.as_slice()));
        structure_tensor(self.geometry.triangle(f), face, channels)
    }

    /// The data element of face `f`: `Σ_c w_c` times channel `c`'s [`element::data_element`],
    /// each rate shifted by the linearization (if any); the lumped element of the averaged
    /// motion tensors with the combined local-global term; without the robust weight.
    pub(super) fn data_element(&self, face: &[u32; 3], f: usize) -> DataElement {
        let triangle = self.geometry.triangle(f);
        if let Some(tensors) = &self.local_motion {
            return lumped_data_element(face, triangle.area, tensors);
        }
        let rotations = &self.connection.face_rotations(f);
        let mut sum = DataElement::zero();
        for channel in &self.channels {
            let intensity = face.map(|v| channel.mid[v as usize]);
            let rate = self.linearized_rates(channel, face, f, rotations);
            sum.add_scaled(
                &element::data_element(triangle, rotations, intensity, rate),
                channel.weight,
            );
        }
        sum
    }

    /// `channel`'s rates at the corners of face `f`, linearized around the slab's flow `ū`
    /// (if any): `τ_a − G·R_a ū_a`, `G` the face gradient of the channel's mid image and `R_a`
    /// the face's `rotations`.
    pub(super) fn linearized_rates(
        &self,
        channel: &SlabChannel,
        face: &[u32; 3],
        f: usize,
        rotations: &[Matrix2<f64>; 3],
    ) -> [f64; 3] {
        let mut rate = face.map(|v| channel.rate[v as usize]);
        if let Some(u) = &self.linearization {
            let intensity = face.map(|v| channel.mid[v as usize]);
            let gradient = element::face_gradient(self.geometry.triangle(f), intensity);
            for (a, &v) in face.iter().enumerate() {
                rate[a] -= gradient.dot(&(rotations[a] * u[v as usize]));
            }
        }
        rate
    }

    /// Data and regularizer (`regularizer`'s element: the connection stiffness for the paper's
    /// covariant term) of face `f` of this slab, and the scalar form `m` of its speed term
    /// (the consistent mass), whose vector element `V(m)` is [`Self::vector_form_element`].
    pub fn face_elements(
        &self,
        face: &[u32; 3],
        f: usize,
        regularizer: &Regularizer,
    ) -> FaceElements {
        let mut data = self.data_element(face, f);
        if let Some(weights) = &self.data_weights {
            data = DataElement::zero().plus_scaled(&data, weights[f]);
        }
        FaceElements {
            data,
            mass: element::consistent_mass(self.geometry.triangle(f)),
            stiffness: self.regularizer_element(face, f, regularizer)
                * self.smoothness_weights.as_ref().map_or(1.0, |w| w[f]),
        }
    }

    /// `V(m)`: the vector element of the scalar form `m` on face `f` under this slab's
    /// transports, block `(a, b) = m_ab R_aᵀ R_b` ([`element::vector_element`]). Linear in `m`,
    /// so that terms of one block that are scalar forms (speed, the time links' parts) are
    /// summed first and transported once.
    pub fn vector_form_element(&self, f: usize, m: &Matrix3<f64>) -> Matrix6<f64> {
        element::vector_element(m, &self.connection.face_rotations(f))
    }

    /// `regularizer`'s element of face `f` on this slab (its frames and tensor, if set),
    /// without the robust weight.
    pub fn regularizer_element(
        &self,
        face: &[u32; 3],
        f: usize,
        regularizer: &Regularizer,
    ) -> Matrix6<f64> {
        regularizer.element(
            self.geometry.triangle(f),
            &self.connection.face_rotations(f),
            self.corner_frames(face),
            self.diffusion_tensors.as_ref().map(|d| &d[f]),
        )
    }

    /// The R³ frames of `face`'s corners, once `Slab::embed` has set them.
    pub fn corner_frames(&self, face: &[u32; 3]) -> Option<[&Matrix3x2<f64>; 3]> {
        let frames = self.embedding_frames.as_ref()?;
        Some(face.map(|v| &frames[v as usize]))
    }

    /// Adds what `params`' regularizer needs beyond images and geometry (once): the R³ frames
    /// of the embedded regularizer, the face tensors of the anisotropic one. This is slab `s`
    /// of `sequence`.
    pub(crate) fn complete(
        &mut self,
        sequence: &MeshSequence,
        s: usize,
        params: &FlowParams,
    ) -> Result<(), FlowError> {
        if params.regularizer.needs_embedding() {
            self.embed(sequence, s)?;
        }
        if let (Some(rho), None) = (params.local_integration, &self.local_motion) {
            self.local_motion = Some(local_motion_tensors(sequence.mesh(), self, rho)?);
        }
        if let (Some(anisotropy), None) = (&params.anisotropy, &self.diffusion_tensors) {
            let tensors = anisotropy.face_tensors(sequence, self)?;
            self.diffusion_tensors = Some(tensors.tensors);
            self.contrast = Some(tensors.contrast);
            self.space_time = tensors.space_time;
        }
        Ok(())
    }

    /// Sets [`Slab::embedding_frames`] (if not yet set): `P_i` of every vertex on frame `s`,
    /// with this slab's polar angles. Only regularizers that differentiate in R³ need them.
    pub(crate) fn embed(&mut self, sequence: &MeshSequence, s: usize) -> Result<(), FlowError> {
        if self.embedding_frames.is_some() {
            return Ok(());
        }
        let positions = sequence.positions(s).ok_or(FlowError::NeedsEmbedding)?;
        let frames =
            vertex_frames_in_r3(sequence.mesh(), &self.geometry, &self.connection, positions)
                .map_err(|source| FlowError::Slab { slab: s, source })?;
        self.embedding_frames = Some(frames);
        Ok(())
    }
}

/// `Σ_c w_c G_c G_cᵀ` on `triangle` (corners `face`) for the channels `(w_c, values_c)` (one
/// value per vertex), `G_c` the face-frame gradient.
pub fn structure_tensor<'v>(
    triangle: &Triangle,
    face: &[u32; 3],
    channels: impl Iterator<Item = (f64, &'v [f64])>,
) -> Matrix2<f64> {
    channels
        .map(|(w, values)| {
            let g = element::face_gradient(triangle, face.map(|v| values[v as usize]));
            g * g.transpose() * w
        })
        .sum()
}

/// All slabs of a sequence, built in parallel, with one weight per image channel.
pub fn build_slabs(
    sequence: &MeshSequence,
    channel_weights: &[f64],
) -> Result<Vec<Slab>, FlowError> {
    (0..sequence.n_slabs())
        .into_par_iter()
        .map(|s| Slab::new(sequence, s, channel_weights))
        .collect()
}

/// The temporal coupling between slab `s` ("before") and `s + 1` ("after")
/// (`docs/discretization.md` §7): weight `c = γ / (α² h)`, `h = (Δt_s + Δt_{s+1}) / 2`, polar
/// rotation `Q_T` and mid area `Ā_T = (A^s_T + A^{s+1}_T) / 2` per face; with the anisotropic
/// coupling in time, also the space-time tensor's time entry `D_tt` per face.
#[derive(Clone, Debug)]
pub struct TimeLink {
    pub weight: f64,
    /// Per face, `D_tt` ([`crate::flow::anisotropy::time_entries`]); `None`: 1.
    pub face_weights: Option<Vec<f64>>,
    /// `(cos q_T, sin q_T)` of the polar rotation `Q_T` per face: 16 bytes per face and link
    /// (an angle and a matrix besides took 40, 0.77 GB at 199 links of 96,900 faces, all held
    /// during assembly).
    polar: Vec<Vector2<f64>>,
}

/// The links between neighbouring slabs (none for frame-by-frame flow, `α = ∞`).
pub fn time_links(slabs: &[Slab], weights: &Weights) -> Vec<TimeLink> {
    match weights.is_coupled() {
        true => (slabs.par_windows(2))
            .map(|w| TimeLink::new(&w[0], &w[1], weights))
            .collect(),
        false => Vec::new(),
    }
}

/// Completes every slab for `params` ([`Slab::complete`]; slab `s` of `sequence`).
pub fn complete_slabs(
    slabs: &mut [Slab],
    sequence: &MeshSequence,
    params: &FlowParams,
) -> Result<(), FlowError> {
    if params.anisotropy.is_some() {
        // Once, before the slabs share it.
        super::pyramid::heat_symbolic(sequence)?;
    }
    slabs
        .par_iter_mut()
        .enumerate()
        .try_for_each(|(s, slab)| slab.complete(sequence, s, params))
}

impl TimeLink {
    pub fn new(before: &Slab, after: &Slab, weights: &Weights) -> Self {
        let h = 0.5 * (before.dt + after.dt);
        Self {
            weight: weights.gamma / (weights.alpha * weights.alpha * h),
            face_weights: time_entries(before, after, weights.alpha),
            polar: polar_rotations(&before.geometry, &after.geometry),
        }
    }

    /// `Q_T` of face `f`.
    pub fn polar_rotation(&self, f: usize) -> Matrix2<f64> {
        let [c, s] = [self.polar[f].x, self.polar[f].y];
        Matrix2::new(c, -s, s, c)
    }

    /// The angle of `Q_T`, in `(−π, π]`.
    pub fn polar_angle(&self, f: usize) -> f64 {
        self.polar[f].y.atan2(self.polar[f].x)
    }

    /// `c D_tt Ā` of face `f`: its coupling weight times its mid area.
    fn face_coupling(&self, before: &Slab, after: &Slab, f: usize) -> f64 {
        let mid_area = 0.5 * (before.geometry.triangle(f).area + after.geometry.triangle(f).area);
        self.weight * self.face_weights.as_ref().map_or(1.0, |w| w[f]) * mid_area
    }

    /// The scalar weight matrix `c D_tt m̄` of face `f`: lumped `c D_tt Ā/3 I` or consistent
    /// `c D_tt Ā/12 (1 + I)`.
    pub fn scalar_element(
        &self,
        before: &Slab,
        after: &Slab,
        f: usize,
        coupling: TimeCoupling,
    ) -> Matrix3<f64> {
        let weight = self.face_coupling(before, after, f);
        match coupling {
            TimeCoupling::Lumped => Matrix3::identity() * (weight / 3.0),
            TimeCoupling::Consistent => {
                (Matrix3::repeat(1.0) + Matrix3::identity()) * (weight / 12.0)
            }
        }
    }

    /// The part of face `f` on the diagonal block of `slab` (either end of the link):
    /// `V(c D_tt m̄)` under `slab`'s transports.
    pub fn diagonal_element(
        &self,
        before: &Slab,
        after: &Slab,
        slab: &Slab,
        f: usize,
        coupling: TimeCoupling,
    ) -> Matrix6<f64> {
        slab.vector_form_element(f, &self.scalar_element(before, after, f, coupling))
    }

    /// The part of face `f` in the block below the diagonal (rows: after, columns: before).
    pub fn cross_element(
        &self,
        before: &Slab,
        after: &Slab,
        f: usize,
        coupling: TimeCoupling,
    ) -> Matrix6<f64> {
        let scalar = self.scalar_element(before, after, f, coupling);
        let (r0, r1) = (
            &before.connection.face_rotations(f),
            &after.connection.face_rotations(f),
        );
        -element::rotated_element(&scalar, r1, r0, &self.polar_rotation(f))
    }

    /// The lumped cross element's diagonal 2×2 blocks of face `f` (its only nonzero ones):
    /// `−c D_tt Ā/3 R¹_aᵀ Q R⁰_a` per corner `a`.
    pub fn lumped_cross_blocks(&self, before: &Slab, after: &Slab, f: usize) -> [Matrix2<f64>; 3] {
        let weight = self.face_coupling(before, after, f) / 3.0;
        let (r0, r1) = (
            &before.connection.face_rotations(f),
            &after.connection.face_rotations(f),
        );
        let q = self.polar_rotation(f);
        std::array::from_fn(|a| -(r1[a].transpose() * q * r0[a]) * weight)
    }

    /// Face `f`'s share of the temporal term at `x0` (slab before) and `x1` (slab after),
    /// `c D_tt Σ_ab m̄_ab w_a·w_b` with `w_a = R¹_a x1_a − Q R⁰_a x0_a`: what the blocks the
    /// system is assembled from give as `x0ᵀ B x0 + x1ᵀ A x1 + 2 x1ᵀ X x0` (`B`, `A`:
    /// [`Self::diagonal_element`] on either slab; `X`: [`Self::cross_element`]), without forming
    /// them.
    pub fn face_energy(
        &self,
        (before, after): (&Slab, &Slab),
        f: usize,
        coupling: TimeCoupling,
        (x0, x1): (&Vector6<f64>, &Vector6<f64>),
    ) -> f64 {
        let scalar = self.scalar_element(before, after, f, coupling);
        let (r0, r1) = (
            &before.connection.face_rotations(f),
            &after.connection.face_rotations(f),
        );
        let q = self.polar_rotation(f);
        let w: [Vector2<f64>; 3] = std::array::from_fn(|a| {
            r1[a] * x1.fixed_rows::<2>(2 * a) - q * (r0[a] * x0.fixed_rows::<2>(2 * a))
        });
        element::scalar_form(&scalar, &w, &w)
    }
}
