//! Sample surfaces in R^3: icosphere, torus, flat grid. Used by the shipped meshes, the tests
//! and the examples; all faces counter-clockwise seen from outside (+z for the grid).

use crate::mesh::{ConnectivityError, Mesh};
use nalgebra::Vector3;
use std::collections::HashMap;
use std::f64::consts::PI;

/// Vertex positions and triangles: a mesh before validation.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    pub positions: Vec<Vector3<f64>>,
    pub faces: Vec<[u32; 3]>,
}

impl Surface {
    /// The validated connectivity.
    pub fn mesh(&self) -> Result<Mesh, ConnectivityError> {
        Mesh::new(self.positions.len(), self.faces.clone())
    }
}

/// Unit icosphere: the icosahedron subdivided `level` times (each triangle into four, new
/// vertices projected to the sphere). `10 · 4^level + 2` vertices: 12, 42, 162, 642, 2562, …
pub fn icosphere(level: u32) -> Surface {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<Vector3<f64>> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vector3::from(*p).normalize())
    .collect();
    let mut faces = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut midpoints = HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vector3<f64>>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push((positions[a as usize] + positions[b as usize]).normalize());
                positions.len() as u32 - 1
            })
        };
        faces = faces
            .iter()
            .flat_map(|&[a, b, c]| {
                let ab = midpoint(a, b, &mut positions);
                let bc = midpoint(b, c, &mut positions);
                let ca = midpoint(c, a, &mut positions);
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    Surface { positions, faces }
}

/// Ring torus `((R + r cos v) cos u, (R + r cos v) sin u, r sin v)` on an `n_major × n_minor`
/// periodic grid (`u` around the z-axis, `v` around the tube).
pub fn torus(major_radius: f64, minor_radius: f64, n_major: usize, n_minor: usize) -> Surface {
    let positions = (0..n_major)
        .flat_map(|i| (0..n_minor).map(move |j| (i, j)))
        .map(|(i, j)| {
            let (u, v) = (
                2.0 * PI * i as f64 / n_major as f64,
                2.0 * PI * j as f64 / n_minor as f64,
            );
            let ring = major_radius + minor_radius * v.cos();
            Vector3::new(ring * u.cos(), ring * u.sin(), minor_radius * v.sin())
        })
        .collect();
    let index = |i: usize, j: usize| ((i % n_major) * n_minor + j % n_minor) as u32;
    Surface {
        positions,
        faces: grid_faces(n_major, n_minor, index),
    }
}

/// The unit sphere as a latitude–longitude mesh: `n_lat` bands from pole to pole (`n_lat − 1`
/// rings of `n_lon` vertices, plus the two poles), quads split along a diagonal, triangle fans
/// at the poles. Counter-clockwise seen from outside.
pub fn uv_sphere(n_lat: usize, n_lon: usize) -> Surface {
    use std::f64::consts::{PI, TAU};
    let ring_vertex = |j: usize, i: usize| (1 + (j - 1) * n_lon + i % n_lon) as u32;
    let south = (1 + (n_lat - 1) * n_lon) as u32;
    let mut positions = vec![Vector3::z()];
    for j in 1..n_lat {
        let (sin_theta, cos_theta) = (PI * j as f64 / n_lat as f64).sin_cos();
        positions.extend((0..n_lon).map(|i| {
            let (sin_phi, cos_phi) = (TAU * i as f64 / n_lon as f64).sin_cos();
            Vector3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
        }));
    }
    positions.push(-Vector3::z());
    let mut faces = Vec::with_capacity(2 * n_lat * n_lon);
    for i in 0..n_lon {
        faces.push([ring_vertex(1, i), ring_vertex(1, i + 1), 0]);
        for j in 1..n_lat - 1 {
            let (u0, u1) = (ring_vertex(j, i), ring_vertex(j, i + 1));
            let (l0, l1) = (ring_vertex(j + 1, i), ring_vertex(j + 1, i + 1));
            faces.extend([[l0, l1, u1], [l0, u1, u0]]);
        }
        faces.push([
            south,
            ring_vertex(n_lat - 1, i + 1),
            ring_vertex(n_lat - 1, i),
        ]);
    }
    Surface { positions, faces }
}

/// Flat `width × height` rectangle in the plane z = 0 with its lower-left corner at the
/// origin, `nx × ny` squares each split along its diagonal.
pub fn grid(nx: usize, ny: usize, width: f64, height: f64) -> Surface {
    let positions = (0..=ny)
        .flat_map(|j| (0..=nx).map(move |i| (i, j)))
        .map(|(i, j)| {
            Vector3::new(
                width * i as f64 / nx as f64,
                height * j as f64 / ny as f64,
                0.0,
            )
        })
        .collect();
    let index = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    Surface {
        positions,
        faces: grid_faces(nx, ny, index),
    }
}

/// Two counter-clockwise triangles per cell `(i, j)` of an `n_i × n_j` grid of cells, with
/// `index(i, j)` the vertex at grid point `(i, j)` (`i` along the first, `j` the second axis).
fn grid_faces(n_i: usize, n_j: usize, index: impl Fn(usize, usize) -> u32) -> Vec<[u32; 3]> {
    (0..n_i)
        .flat_map(|i| (0..n_j).map(move |j| (i, j)))
        .flat_map(|(i, j)| {
            let (a, b, c, d) = (
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            );
            [[a, b, c], [a, c, d]]
        })
        .collect()
}
