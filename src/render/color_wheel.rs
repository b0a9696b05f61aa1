//! (in progress)
pub fn flow_color(_u: f64, _v: f64) -> [f64; 3] {
    [0.0; 3]
}
pub fn robust_max(_speeds: &[f64]) -> f64 {
    1.0
}
pub fn flow_colors(vectors: &[[f64; 2]], _scale: f64) -> Vec<[f64; 3]> {
    vec![[0.0; 3]; vectors.len()]
}
