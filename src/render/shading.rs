//! Lambert shading with a directional light fixed to the camera.
//!
//! A surface point with unit normal `n` and colour `c` is drawn as
//!
//! ```text
//! c · (ambient + diffuse · |n · l|)
//! ```
//!
//! with `l` the unit direction *towards* the light. The absolute value makes the shading
//! two-sided: inside views and open surfaces seen from behind read like front sides, and the
//! orientation of the faces does not matter. The light is given in camera coordinates
//! (right, down, forward), so it moves with the camera: `(0, 0, −1)` is a headlight shining
//! along the view axis.
//!
//! Normals are the area-weighted vertex normals `n_i ∝ Σ_{f ∋ i} (p_b − p_a) × (p_c − p_a)`
//! over the faces `[a, b, c]` around vertex `i` (the cross product's length is twice the face
//! area), interpolated across each triangle and normalized per sample.

use nalgebra::Vector3;

/// Ambient and diffuse weights and the light direction; see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    pub ambient: f64,
    pub diffuse: f64,
    /// Direction from the surface towards the light in camera coordinates (right, down,
    /// forward); need not be normalized.
    pub towards_light: [f64; 3],
}

impl Default for Lighting {
    /// A light slightly above-left of the camera (about 22° off the view axis), ambient 0.4,
    /// diffuse 0.6: surfaces facing the viewer show about 0.95 of their colour, grazing ones
    /// 0.4, so colours stay recognizable while the shape reads.
    fn default() -> Self {
        Self {
            ambient: 0.4,
            diffuse: 0.6,
            towards_light: [-0.25, -0.32, -1.0],
        }
    }
}

impl Lighting {
    /// A headlight along the view axis (`l = −forward`).
    pub fn headlight(ambient: f64, diffuse: f64) -> Self {
        Self {
            ambient,
            diffuse,
            towards_light: [0.0, 0.0, -1.0],
        }
    }

    /// No shading: every point shows its colour as it is.
    pub fn unlit() -> Self {
        Self::headlight(1.0, 0.0)
    }

    /// The factor `ambient + diffuse · |n · l|` for unit vectors `n` and `l`.
    pub fn intensity(&self, normal: &Vector3<f64>, towards_light: &Vector3<f64>) -> f64 {
        self.ambient + self.diffuse * normal.dot(towards_light).abs()
    }
}

/// Twice the area times the unit normal of triangle `(a, b, c)`: `(b − a) × (c − a)`.
pub fn face_normal(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Vector3<f64> {
    (b - a).cross(&(c - a))
}

/// Area-weighted vertex normals (not normalized; zero at vertices without a finite face).
/// Faces with a non-finite corner are left out. `faces` must index `positions`.
pub fn vertex_normals(positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> Vec<Vector3<f64>> {
    let mut normals = vec![Vector3::zeros(); positions.len()];
    for face in faces {
        let [a, b, c] = face.map(|v| &positions[v as usize]);
        let normal = face_normal(a, b, c);
        if normal.iter().all(|x| x.is_finite()) {
            for &v in face {
                normals[v as usize] += normal;
            }
        }
    }
    normals
}
