//! A flow scored at tracked cells, cell by cell ([`crate::accuracy::tracks`]): which cells the
//! flow gets wrong, and where.
//!
//! | file | contents |
//! |---|---|
//! | `track_errors.csv` | one row per scored cell and slab: `frame` (the slab: the cell moves from frame `s` to `s+1`), `track` (its index in the tracks file), `x,y,z` (its nearest point on the surface of frame `s`), `distance` (of the cell from the surface), `true_x,true_y,true_z` (`r`: its tangential displacement, relative to the mesh), `flow_x,flow_y,flow_z` (`r̂ = Δt u_s`: the flow's), `endpoint_error` (`|r̂ − r|`), `direction_error_degrees` and `speed_ratio` (`|r̂|/|r|`; empty where the cell did not move) |
//! | `track_errors.vtu` | the same as a ParaView point set: point data `true_displacement`, `flow_displacement`, `endpoint_error`, `direction_error_degrees`, `speed_ratio` (NaN where the cell did not move), `distance`, `frame`, `track` |

use crate::accuracy::{TrackPoint, TrackScores};
use crate::format::vtk::{write_point_vtu, NamedArray};
use crate::format::{write_atomically, IoError};
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;

/// The per-cell table.
pub const TRACK_ERRORS_CSV: &str = "track_errors.csv";
/// The per-cell point set.
pub const TRACK_ERRORS_VTU: &str = "track_errors.vtu";

/// Writes `track_errors.csv` into `dir`, and `track_errors.vtu` with `vtu` (module docs).
pub fn write_track_errors(dir: &Path, scores: &TrackScores, vtu: bool) -> Result<(), IoError> {
    write_atomically(&dir.join(TRACK_ERRORS_CSV), |w| {
        writeln!(
            w,
            "frame,track,x,y,z,distance,true_x,true_y,true_z,flow_x,flow_y,flow_z,endpoint_error,direction_error_degrees,speed_ratio"
        )?;
        scores
            .points
            .iter()
            .try_for_each(|p| writeln!(w, "{}", csv_row(p)))
    })?;
    if vtu {
        write_points(&dir.join(TRACK_ERRORS_VTU), &scores.points)?;
    }
    Ok(())
}

/// One cell's row; a measure that does not apply (NaN) is empty.
fn csv_row(p: &TrackPoint) -> String {
    let number = |x: f64| match x.is_finite() {
        true => format!("{x}"),
        false => String::new(),
    };
    let vector = |v: &Vector3<f64>| v.iter().map(|&c| number(c)).collect::<Vec<_>>().join(",");
    format!(
        "{},{},{},{},{},{},{},{},{}",
        p.slab,
        p.track,
        vector(&p.position),
        number(p.distance),
        vector(&p.truth),
        vector(&p.computed),
        number(p.endpoint),
        number(p.direction_degrees),
        number(p.speed_ratio),
    )
}

fn write_points(path: &Path, points: &[TrackPoint]) -> Result<(), IoError> {
    let positions: Vec<Vector3<f64>> = points.iter().map(|p| p.position).collect();
    let vectors = |f: fn(&TrackPoint) -> Vector3<f64>| points.iter().map(f).collect::<Vec<_>>();
    let scalars = |f: fn(&TrackPoint) -> f64| points.iter().map(f).collect::<Vec<_>>();
    let arrays = [
        NamedArray::vectors("true_displacement", &vectors(|p| p.truth)),
        NamedArray::vectors("flow_displacement", &vectors(|p| p.computed)),
        NamedArray::scalars("endpoint_error", &scalars(|p| p.endpoint)),
        NamedArray::scalars("direction_error_degrees", &scalars(|p| p.direction_degrees)),
        NamedArray::scalars("speed_ratio", &scalars(|p| p.speed_ratio)),
        NamedArray::scalars("distance", &scalars(|p| p.distance)),
        NamedArray::scalars("frame", &scalars(|p| p.slab as f64)),
        NamedArray::scalars("track", &scalars(|p| p.track as f64)),
    ];
    let point_data: Vec<_> = arrays.iter().map(NamedArray::as_point_array).collect();
    write_point_vtu(path, &positions, &point_data)
}
