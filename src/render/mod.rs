//! Pictures of flows: colour coding of tangent vectors.

pub mod color_wheel;
