//! Welding vertices that were split at texture seams.
//!
//! Exporters that store one index per corner (glTF always, OBJ and PLY often) duplicate a vertex
//! wherever its texture coordinates or normals jump. For the flow the duplicates must be one
//! vertex, or the seam becomes a boundary. Vertices `i` and `j` are welded when their positions
//! are bitwise equal (with `−0 = +0`) **in every frame**: exact copies, never merely close
//! points, so two sheets that touch in one frame are not glued together.

use nalgebra::Vector3;
use std::collections::HashMap;

/// How the vertices of the files map onto the welded mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Welding {
    /// `vertex_map[i]` = welded vertex of file vertex `i`.
    pub vertex_map: Vec<u32>,
    /// `representatives[w]` = the first file vertex welded into `w`.
    pub representatives: Vec<u32>,
}

impl Welding {
    /// Welds the file vertices whose positions coincide in all `frames` (each one position per
    /// file vertex). Welded vertices are numbered in order of their first file vertex.
    pub fn of_coincident(frames: &[Vec<Vector3<f64>>]) -> Self {
        let n = frames.first().map_or(0, Vec::len);
        let coincide = |a: usize, b: usize| {
            frames
                .iter()
                .all(|p| position_key(&p[a]) == position_key(&p[b]))
        };
        // First welded vertex at each frame-0 position; further ones (same position in frame
        // 0 only, rare) in `others`.
        let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(n);
        let mut others: HashMap<[u64; 3], Vec<u32>> = HashMap::new();
        let mut vertex_map = Vec::with_capacity(n);
        let mut representatives: Vec<u32> = Vec::with_capacity(n);
        for (i, position) in frames.first().into_iter().flatten().enumerate() {
            let key = position_key(position);
            let next = representatives.len() as u32;
            let candidates = match first.get(&key) {
                None => {
                    first.insert(key, next);
                    &[][..]
                }
                Some(w) => std::slice::from_ref(w),
            };
            let existing = candidates
                .iter()
                .chain(others.get(&key).into_iter().flatten())
                .copied()
                .find(|&w| coincide(representatives[w as usize] as usize, i));
            let welded = match existing {
                Some(w) => w,
                None if candidates.is_empty() => next,
                None => {
                    others.entry(key).or_default().push(next);
                    next
                }
            };
            if welded == next {
                representatives.push(i as u32);
            }
            vertex_map.push(welded);
        }
        Self {
            vertex_map,
            representatives,
        }
    }

    /// No welding: every file vertex is its own.
    pub fn identity(n: usize) -> Self {
        let all: Vec<u32> = (0..n as u32).collect();
        Self {
            vertex_map: all.clone(),
            representatives: all,
        }
    }

    /// How many file vertices were merged into others.
    pub fn n_welded(&self) -> usize {
        self.vertex_map.len() - self.representatives.len()
    }

    pub fn n_vertices(&self) -> usize {
        self.representatives.len()
    }

    /// Positions of the welded vertices (the input itself when nothing was welded).
    pub fn positions(&self, positions: Vec<Vector3<f64>>) -> Vec<Vector3<f64>> {
        if self.n_welded() == 0 {
            return positions;
        }
        self.representatives
            .iter()
            .map(|&r| positions[r as usize])
            .collect()
    }

    /// Faces in welded vertex numbers.
    pub fn faces(&self, faces: Vec<[u32; 3]>) -> Vec<[u32; 3]> {
        if self.n_welded() == 0 {
            return faces;
        }
        faces
            .into_iter()
            .map(|f| f.map(|v| self.vertex_map[v as usize]))
            .collect()
    }

    /// Per-vertex values on the welded vertices: the mean over each group (texture samples on
    /// the two sides of a seam may differ slightly).
    pub fn values(&self, values: Vec<f64>) -> Vec<f64> {
        if self.n_welded() == 0 {
            return values;
        }
        let mut sum = vec![0.0; self.n_vertices()];
        let mut count = vec![0u32; self.n_vertices()];
        for (&w, &value) in self.vertex_map.iter().zip(&values) {
            sum[w as usize] += value;
            count[w as usize] += 1;
        }
        sum.iter().zip(&count).map(|(s, &c)| s / c as f64).collect()
    }
}

fn position_key(p: &Vector3<f64>) -> [u64; 3] {
    // Adding 0.0 turns −0 into +0.
    [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits())
}
