//! # meshflow: optical flow on moving surfaces
//!
//! Given a deforming triangle mesh (frames `k = 0..K−1` at times `t_k`, fixed connectivity) and a
//! grey value `I_k(i)` per vertex and frame, meshflow finds the tangent vector field `u` that
//! moves the image along the surface. It minimizes the energy of Bauer, Grasmair & Kirisits,
//! "Optical Flow on Moving Manifolds" (SIAM J. Imaging Sci. 8(1), 2015):
//!
//! ```text
//! E(u) = ∫∫ (∂_t I + dI(u))² + β |u|²_g + γ |∇u|²_g + (γ/α²) |∇_t u|²_g  dA_g dt
//! ```
//!
//! with `g(t)` the metric of the surface at time `t` and `∇` its Levi-Civita connection, whose
//! Euler–Lagrange equation involves the Bochner (connection) Laplacian `∇*∇`.
//!
//! Everything is intrinsic: operators depend on edge lengths only. The discretization (P1
//! tangent-field finite elements with the connection of [`connection`]) is written out in
//! `docs/discretization.md`; each module opens with the part of it that it implements.
//!
//! Data flows one way through the modules: [`mesh`] (connectivity) → [`geometry`] (intrinsic
//! quantities) → [`connection`] (frames and transport) → [`fem`] (element matrices and
//! assembly) → [`flow`] (the space-time energy and its minimizer) → [`analysis`] (what a flow
//! tells: divergence, curl, Hodge parts, strain rate); [`chart`] reads flows in a
//! parameter domain, [`render`] draws PNG pictures, [`shapes`] makes sample surfaces, [`synth`] sample sequences with known flow, and [`accuracy`] measures
//! a computed flow against a known one or at tracked points. Before the flow, recordings
//! become moving meshes: [`track`] follows frames meshed each on its own, [`surface`] fits a
//! moving surface through points (cell centres) and [`volume`] carries 3-D images (microscope
//! stacks) onto it. Every reader treats its files as hostile: [`limits`] holds the process's
//! memory limit, against which declared sizes are checked before allocating, and the policy
//! for files named inside other files. The user guide is `docs/guide.md`.
//!
//! Files are three layers, each above the one before: [`format`](mod@format) (bytes ↔ arrays: OBJ, PLY,
//! glTF, VTK, NPY, MTL and textures, MatrixMarket; paths or streams), [`load`] (files or arrays
//! → a validated [`flow::MeshSequence`]: welding, orientation, repair, channels, times,
//! warnings) and [`run`] (one command's output directory: staging, manifests, the flow and
//! analysis writers, reading a run back). [`io`] re-exports all three under the paths of
//! earlier versions. Shared numerics sit low: `linalg` (sparse Cholesky), [`spatial`] (a
//! frame's surface as a spatial query structure), [`statistics`] (medians), [`subnormals`]
//! (the floating-point mode of the solver's threads). No module imports one above it: the
//! `use crate::` lines form no cycle.
//!
//! ```
//! use meshflow::{connection::Connection, fem, geometry::IntrinsicGeometry, shapes};
//!
//! let sphere = shapes::icosphere(2); // 162 vertices on the unit sphere
//! let mesh = sphere.mesh()?;
//! let geometry = IntrinsicGeometry::from_positions(&mesh, &sphere.positions)?;
//! let connection = Connection::new(&mesh, &geometry);
//!
//! // Bochner Laplacian and vector mass, 2V × 2V, DOFs (2i, 2i+1) = vertex i's frame.
//! let k = fem::connection_laplacian(&mesh, &geometry, &connection);
//! let m = fem::vector_mass(&mesh, &geometry, &connection, fem::MassKind::Consistent);
//! assert_eq!((k.nrows(), m.nrows()), (2 * 162, 2 * 162));
//!
//! // Tangent vectors in R^3: P_i maps vertex i's frame components to R^3.
//! let frames = meshflow::connection::vertex_frames_in_r3(&mesh, &geometry, &connection, &sphere.positions)?;
//! assert!(frames[0].column(0).dot(&sphere.positions[0]).abs() < 1e-2);
//! # Ok::<(), meshflow::Error>(())
//! ```

/// Parses the lowercase names used on the command line (`neumann`, `rigid`, …): a `FromStr`
/// whose error lists the names. Defined before the modules so that all of them can use it.
macro_rules! parse_by_name {
    ($type:ty, $($name:literal => $value:expr),+) => {
        impl std::str::FromStr for $type {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($name => Ok($value),)+
                    other => Err(format!("'{other}' is not one of: {}", [$($name),+].join(", "))),
                }
            }
        }
    };
}

pub mod accuracy;
pub mod analysis;
pub mod chart;
pub mod connection;
pub mod fem;
pub mod flow;
pub mod format;
pub mod geometry;
pub mod io;
pub mod limits;
pub(crate) mod linalg;
pub mod load;
pub mod mesh;
pub mod render;
pub mod run;
pub mod shapes;
pub mod spatial;
pub mod statistics;
pub mod subnormals;
pub mod surface;
pub mod synth;
pub mod track;
pub mod volume;

use std::path::PathBuf;

/// The README's Rust examples, compiled with the doctests so that they stay true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeExamples;

/// Any error meshflow reports. Variants carry the element (vertex, face, edge, line) at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Connectivity(#[from] mesh::ConnectivityError),
    #[error(transparent)]
    Geometry(#[from] geometry::GeometryError),
    #[error(transparent)]
    Io(#[from] format::IoError),
    #[error(transparent)]
    Flow(#[from] flow::FlowError),
    #[error(transparent)]
    Accuracy(#[from] accuracy::AccuracyError),
    #[error(transparent)]
    Chart(#[from] chart::ChartError),
    #[error(transparent)]
    Render(#[from] render::RenderError),
    #[error(transparent)]
    Track(#[from] track::TrackError),
    #[error(transparent)]
    Spatial(#[from] spatial::SpatialError),
    #[error(transparent)]
    Volume(#[from] volume::VolumeError),
    #[error(transparent)]
    Surface(#[from] surface::SurfaceError),
    #[error(transparent)]
    Isosurface(#[from] surface::IsosurfaceError),
    #[error(transparent)]
    Closed(#[from] surface::ClosedError),
    /// An error in the contents of a file, with the file's name.
    #[error("{}: {source}", path.display())]
    InFile { path: PathBuf, source: Box<Error> },
}

impl Error {
    /// Attaches the file whose contents caused this error.
    pub fn in_file(self, path: impl Into<PathBuf>) -> Self {
        Error::InFile {
            path: path.into(),
            source: Box::new(self),
        }
    }
}
