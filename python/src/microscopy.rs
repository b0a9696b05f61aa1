//! Microscopy: surfaces fitted through points (`meshflow surface`) or found in volumes
//! (`--shape closed`), and volumes sampled onto surfaces (`meshflow sample`).

use crate::convert::{
    faces_array, frames_array, parse, points_array, read_faces, read_points, read_positions,
};
use crate::{to_py_err, value_error};
use meshflow::mesh::Mesh;
use meshflow::surface::{
    FitOptions, FoundSurface, IsosurfaceOptions, Level, Reference, Resolution, Shape,
};
use meshflow::volume::{
    Reduce, SampleOptions, SampledSequence, Shell, StreamEvent, Volume, VolumeOptions,
    VolumeStream, VoxelSizeSource,
};
use meshflow::{surface, volume, Error};
use nalgebra::Vector3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// A moving surface fitted through point clouds (`meshflow surface`): `frames[k]` (N_k, 3).
/// Returns a dict: `positions` (K, V, 3), `faces` (F, 3), `reference`, `frames` (per-frame
/// fit), `mean_point_spacing`, `lambda`.
#[pyfunction]
#[pyo3(signature = (frames, shape, whole_sphere, vertices, edge_length, smoothing, margin))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per option
pub(crate) fn fit_surface<'py>(
    py: Python<'py>,
    frames: Vec<PyReadonlyArray2<'py, f64>>,
    shape: &str,
    whole_sphere: bool,
    vertices: Option<usize>,
    edge_length: Option<f64>,
    smoothing: f64,
    margin: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let shape = match (shape, whole_sphere) {
        ("sphere-like", whole) => Shape::SphereLike { whole },
        ("graph", false) => Shape::Graph,
        ("graph", true) => {
            return Err(value_error(
                "whole_sphere applies to shape=\"sphere-like\" only, not \"graph\"",
            ))
        }
        (other, _) => {
            return Err(value_error(format!(
                "shape: '{other}': expected sphere-like or graph"
            )))
        }
    };
    let resolution = match (vertices, edge_length) {
        (Some(_), Some(_)) => {
            return Err(value_error(
                "give one of vertices and edge_length, not both",
            ))
        }
        (Some(n), None) => Resolution::Vertices(n),
        (None, Some(length)) => Resolution::EdgeLength(length),
        (None, None) => FitOptions::default().resolution,
    };
    let options = FitOptions {
        shape,
        resolution,
        smoothing,
        margin,
    };
    let frames: Vec<Vec<Vector3<f64>>> = frames.iter().map(read_points).collect();
    let fitted = py
        .detach(|| surface::fit_surface(&frames, &options))
        .map_err(|e| to_py_err(e.into()))?;
    let k = fitted.positions.len();
    let v = fitted.positions.first().map_or(0, Vec::len);
    let all: Vec<Vector3<f64>> = fitted.positions.concat();
    let positions = points_array(&all)
        .into_shape_with_order((k, v, 3))
        .expect("K × V × 3");
    let out = PyDict::new(py);
    out.set_item("positions", positions.into_pyarray(py))?;
    out.set_item("faces", faces_array(&fitted.faces).into_pyarray(py))?;
    out.set_item("reference", reference_dict(py, &fitted.reference)?)?;
    let fits = fitted
        .frames
        .iter()
        .map(|fit| -> PyResult<_> {
            let dict = PyDict::new(py);
            dict.set_item("points", fit.points)?;
            dict.set_item("dropped", fit.dropped)?;
            dict.set_item("rms_residual", fit.rms_residual)?;
            dict.set_item("max_residual", fit.max_residual)?;
            Ok(dict)
        })
        .collect::<PyResult<Vec<_>>>()?;
    out.set_item("frames", fits)?;
    out.set_item("mean_point_spacing", fitted.mean_point_spacing)?;
    out.set_item("lambda", fitted.lambda)?;
    Ok(out)
}

/// `{"kind": "sphere", "centre", "radius", "cap_degrees" (None: whole), "axis"}` or
/// `{"kind": "plane", "min", "max"}` (the rectangle of `z = 0` in `x` and `y`); points as
/// tuples.
pub(crate) fn reference_dict<'py>(
    py: Python<'py>,
    reference: &Reference,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    match *reference {
        Reference::Sphere {
            centre,
            radius,
            cap_degrees,
            axis,
        } => {
            dict.set_item("kind", "sphere")?;
            dict.set_item("centre", (centre[0], centre[1], centre[2]))?;
            dict.set_item("radius", radius)?;
            dict.set_item("cap_degrees", cap_degrees)?;
            dict.set_item("axis", (axis[0], axis[1], axis[2]))?;
        }
        Reference::Plane { min, max } => {
            dict.set_item("kind", "plane")?;
            dict.set_item("min", (min[0], min[1]))?;
            dict.set_item("max", (max[0], max[1]))?;
        }
    }
    Ok(dict)
}

/// One volume's shape `[n_z, n_y, n_x]` and its values in C order.
pub(crate) fn read_volume(array: &PyReadonlyArray3<f32>) -> ([usize; 3], Vec<f32>) {
    let array = array.as_array();
    let shape = [array.shape()[0], array.shape()[1], array.shape()[2]];
    let values = match array.as_slice() {
        Some(values) => values.to_vec(),
        None => array.iter().copied().collect(),
    };
    (shape, values)
}

/// The surface of the object in `volume` (Z, Y, X), as `meshflow surface --shape closed`
/// finds it in a frame. Returns a dict: `positions` (V, 3), `faces` (F, 3) and the report's
/// numbers.
#[pyfunction]
#[pyo3(signature = (volume, voxel_size, origin, level, smoothing, genus, closing))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per option
pub(crate) fn find_surface<'py>(
    py: Python<'py>,
    volume: PyReadonlyArray3<'py, f32>,
    voxel_size: (f64, f64, f64),
    origin: (f64, f64, f64),
    level: &str,
    smoothing: Option<f64>,
    genus: usize,
    closing: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let level = parse::<Level>(level, "level")?;
    let (shape, values) = read_volume(&volume);
    let voxel_size = Vector3::new(voxel_size.0, voxel_size.1, voxel_size.2);
    let origin = Vector3::new(origin.0, origin.1, origin.2);
    let found = py
        .detach(|| -> Result<FoundSurface, Error> {
            let volume = Volume::new(shape, values, voxel_size, origin)?;
            let options = IsosurfaceOptions {
                smoothing,
                level,
                genus,
                closing,
            };
            Ok(surface::find_surface(&volume, &options)?)
        })
        .map_err(to_py_err)?;
    let out = PyDict::new(py);
    out.set_item("positions", points_array(&found.positions).into_pyarray(py))?;
    out.set_item("faces", faces_array(&found.faces).into_pyarray(py))?;
    out.set_item("threshold", found.threshold)?;
    out.set_item("foreground_voxels", found.foreground_voxels)?;
    out.set_item("component_voxels", found.component_voxels)?;
    out.set_item("component_share", found.component_share)?;
    out.set_item("filled_voxels", found.filled_voxels)?;
    out.set_item("genus", found.genus)?;
    out.set_item("closing_radius", found.closing_radius)?;
    out.set_item("slices_filled", found.slices_filled)?;
    out.set_item("smoothing", found.smoothing)?;
    out.set_item("layer_vertices", found.layer_vertices)?;
    out.set_item("layer_thickness", found.layer_thickness)?;
    out.set_item("border_voxels", found.border_voxels)?;
    out.set_item("warnings", found.warnings())?;
    Ok(out)
}

/// A recording carried onto a moving surface (`meshflow sample`): `volumes[k]` (Z, Y, X)
/// read along the vertex normals of frame `k` of (`positions`, `faces`). Returns a dict:
/// `values` (K, V), `outside` (per frame), `no_data` (K, V), `shell` (inside, outside,
/// layers), `smoothing`.
#[pyfunction]
#[pyo3(signature = (volumes, positions, faces, voxel_size, origin, smoothing, shell, layers, reduce, allow_outside))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per option
pub(crate) fn sample_volume<'py>(
    py: Python<'py>,
    volumes: Vec<PyReadonlyArray3<'py, f32>>,
    positions: PyReadonlyArray3<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    voxel_size: (f64, f64, f64),
    origin: (f64, f64, f64),
    smoothing: Option<f64>,
    shell: Option<(f64, f64)>,
    layers: usize,
    reduce: &str,
    allow_outside: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let surface = SampledSurface::read(&positions, &faces)?;
    let options = sample_options(smoothing, shell, layers, reduce, allow_outside)?;
    let grids: Vec<([usize; 3], Vec<f32>)> = volumes.iter().map(read_volume).collect();
    let voxel_size = Vector3::new(voxel_size.0, voxel_size.1, voxel_size.2);
    let origin = Vector3::new(origin.0, origin.1, origin.2);
    let sampled = py.detach(|| -> PyResult<SampledSequence> {
        let volumes = grids
            .into_iter()
            .enumerate()
            .map(|(k, (shape, values))| {
                Volume::new(shape, values, voxel_size, origin)
                    .map_err(|e| value_error(format!("volumes[{k}]: {e}")))
            })
            .collect::<PyResult<Vec<_>>>()?;
        let mesh = surface.mesh().map_err(to_py_err)?;
        volume::sample_sequence(&volumes, &mesh, &surface.positions, &options)
            .map_err(|e| to_py_err(e.into()))
    })?;
    sampled_dict(py, sampled, surface.n_vertices)
}

/// The moving surface a recording is sampled onto: positions (K, V, 3) and faces.
struct SampledSurface {
    positions: Vec<Vec<Vector3<f64>>>,
    faces: Vec<[u32; 3]>,
    n_vertices: usize,
}

impl SampledSurface {
    fn read(
        positions: &PyReadonlyArray3<'_, f64>,
        faces: &PyReadonlyArray2<'_, i64>,
    ) -> PyResult<Self> {
        let faces = read_faces(faces)?;
        let positions = read_positions(positions);
        let n_vertices = positions.first().map_or(0, Vec::len);
        Ok(Self {
            positions,
            faces,
            n_vertices,
        })
    }

    fn mesh(&self) -> Result<Mesh, Error> {
        Ok(Mesh::new(self.n_vertices, self.faces.clone())?)
    }
}

/// The sampling's options: `shell` (inside, outside) or the library's default reach (± two
/// of the largest voxel sides), with `layers` layers either way.
fn sample_options(
    smoothing: Option<f64>,
    shell: Option<(f64, f64)>,
    layers: usize,
    reduce: &str,
    allow_outside: bool,
) -> PyResult<SampleOptions> {
    let reduce = parse::<Reduce>(reduce, "reduce")?;
    Ok(SampleOptions {
        smoothing,
        shell: shell.map(|(inside, outside)| Shell {
            inside,
            outside,
            layers,
        }),
        layers: Some(layers),
        reduce,
        allow_outside,
    })
}

/// `values` (K, V), `outside`, `no_data` (K, V), `shell` and `smoothing` of a sampling.
fn sampled_dict(
    py: Python<'_>,
    sampled: SampledSequence,
    n_vertices: usize,
) -> PyResult<Bound<'_, PyDict>> {
    let k = sampled.values.len();
    let values =
        Array2::from_shape_vec((k, n_vertices), sampled.values.concat()).expect("K × V values");
    let out = PyDict::new(py);
    out.set_item("values", values.into_pyarray(py))?;
    out.set_item("outside", sampled.outside)?;
    let no_data =
        Array2::from_shape_vec((k, n_vertices), sampled.no_data.concat()).expect("K × V flags");
    out.set_item("no_data", no_data.into_pyarray(py))?;
    let shell = sampled.shell;
    out.set_item("shell", (shell.inside, shell.outside, shell.layers))?;
    out.set_item("smoothing", sampled.smoothing)?;
    Ok(out)
}

/// Where and what of the volumes at `path` is read: the caller's voxel size (`None`: the
/// files' metadata, else 1), origin, channel and resolution level.
fn volume_options(
    voxel_size: Option<(f64, f64, f64)>,
    origin: (f64, f64, f64),
    channel: Option<usize>,
    resolution_level: usize,
) -> VolumeOptions {
    VolumeOptions {
        voxel_size: voxel_size.map(|(x, y, z)| Vector3::new(x, y, z)),
        origin: Vector3::new(origin.0, origin.1, origin.2),
        channel,
        resolution_level,
    }
}

/// Where the voxel size came from, in words (`None` where the caller gave it).
fn voxel_size_said(source: Option<&VoxelSizeSource>) -> Option<String> {
    match source? {
        VoxelSizeSource::Given => None,
        VoxelSizeSource::GivenOverInvalid(why) => Some(format!(
            "given, in place of the files' invalid metadata ({why})"
        )),
        VoxelSizeSource::File(said) => Some(said.clone()),
        VoxelSizeSource::Default => Some("none given or found in the files: 1 × 1 × 1".to_string()),
    }
}

/// [`sample_volume`] of the volumes that `path` names (NPY, TIFF, ImageJ hyperstack, OME-Zarr,
/// or a directory of them), read and sampled one frame at a time. The dict adds
/// `voxel_size` (as used), `voxel_size_source`, and the frames' `shape` (z, y, x) and `origin`
/// (voxel (0, 0, 0)'s centre, an OME-Zarr image's own translation included).
#[pyfunction]
#[pyo3(signature = (path, positions, faces, voxel_size, origin, channel, resolution_level, smoothing, shell, layers, reduce, allow_outside))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per option
pub(crate) fn sample_volume_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    positions: PyReadonlyArray3<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    voxel_size: Option<(f64, f64, f64)>,
    origin: (f64, f64, f64),
    channel: Option<usize>,
    resolution_level: usize,
    smoothing: Option<f64>,
    shell: Option<(f64, f64)>,
    layers: usize,
    reduce: &str,
    allow_outside: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let surface = SampledSurface::read(&positions, &faces)?;
    let options = sample_options(smoothing, shell, layers, reduce, allow_outside)?;
    let placement = volume_options(voxel_size, origin, channel, resolution_level);
    let (sampled, voxel, said, grid) = py
        .detach(|| -> Result<_, Error> {
            let mesh = surface.mesh()?;
            let mut stream = VolumeStream::open(&path, &placement)?;
            let mut voxel = None;
            let mut on_event = |event: StreamEvent| {
                if let StreamEvent::VoxelSize(source) = event {
                    voxel = Some(source.clone());
                }
            };
            let sampled = volume::sample_stream(
                &mut stream,
                &mesh,
                &surface.positions,
                &options,
                &mut on_event,
            )?;
            let size = stream.voxel_size();
            let grid = (stream.shape(), stream.origin());
            Ok((sampled, size, voxel, grid))
        })
        .map_err(to_py_err)?;
    let out = sampled_dict(py, sampled, surface.n_vertices)?;
    out.set_item("voxel_size", voxel.map(|v| (v.x, v.y, v.z)))?;
    out.set_item("shape", grid.0)?;
    out.set_item("origin", grid.1.map(|o| (o.x, o.y, o.z)))?;
    out.set_item("voxel_size_source", voxel_size_said(said.as_ref()))?;
    Ok(out)
}

/// The volumes that `path` names, as one `(K, Z, Y, X)` float32 array (only `frames`, in
/// their order, where given: the others are passed over unread), with the voxel size and
/// origin they are placed at. The frames held are checked against the memory limit first.
#[pyfunction]
#[pyo3(signature = (path, voxel_size, origin, channel, resolution_level, frames))]
pub(crate) fn read_volumes<'py>(
    py: Python<'py>,
    path: PathBuf,
    voxel_size: Option<(f64, f64, f64)>,
    origin: (f64, f64, f64),
    channel: Option<usize>,
    resolution_level: usize,
    frames: Option<Vec<usize>>,
) -> PyResult<Bound<'py, PyDict>> {
    let placement = volume_options(voxel_size, origin, channel, resolution_level);
    let read = py
        .detach(|| -> Result<_, Error> {
            let mut stream = VolumeStream::open(&path, &placement)?;
            let wanted: Vec<usize> = frames
                .clone()
                .unwrap_or_else(|| (0..stream.n_frames()).collect());
            let volumes = stream.read_frames(&wanted)?;
            let [z, y, x] = stream.shape();
            // One array; each volume dropped once copied in.
            let mut values = Vec::with_capacity(volumes.len() * z * y * x);
            for volume in volumes {
                values.extend_from_slice(volume.values());
            }
            let source = stream.voxel_size_source().cloned();
            Ok((
                values,
                [wanted.len(), z, y, x],
                stream.voxel_size(),
                stream.origin(),
                source,
            ))
        })
        .map_err(to_py_err)?;
    let (values, [k, z, y, x], voxel, origin, source) = read;
    let volumes =
        numpy::ndarray::Array4::from_shape_vec((k, z, y, x), values).expect("K × Z × Y × X values");
    let out = PyDict::new(py);
    out.set_item("volumes", volumes.into_pyarray(py))?;
    out.set_item("voxel_size", voxel.map(|v| (v.x, v.y, v.z)))?;
    out.set_item("origin", origin.map(|o| (o.x, o.y, o.z)))?;
    out.set_item("voxel_size_source", voxel_size_said(source.as_ref()))?;
    Ok(out)
}

/// The object's surface found in every frame of the recording `path` and tracked into one
/// moving mesh, as `meshflow surface PATH --shape closed` makes it ([`surface::closed_sequence`]).
/// Returns a dict: `positions` (K, V, 3), `faces` (F, 3), `times` (K,), `voxel_size` (as
/// used), `report` (`surface.json`'s, as JSON text). `progress` is called with
/// `{"kind": "surface", "frame": k, "frames": K}` as each frame's surface is found.
#[pyfunction]
#[pyo3(signature = (path, voxel_size, origin, channel, resolution_level, level, smoothing, genus, closing, vertices, times, relax_iterations, keep_going, progress))]
#[allow(clippy::too_many_arguments)] // the Python signature, one argument per option
pub(crate) fn closed_surface_sequence<'py>(
    py: Python<'py>,
    path: PathBuf,
    voxel_size: Option<(f64, f64, f64)>,
    origin: (f64, f64, f64),
    channel: Option<usize>,
    resolution_level: usize,
    level: &str,
    smoothing: Option<f64>,
    genus: usize,
    closing: Option<f64>,
    vertices: Option<usize>,
    times: Option<Vec<f64>>,
    relax_iterations: usize,
    keep_going: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    use meshflow::track::{Alignment, Relaxation, TrackOptions};
    let placement = volume_options(voxel_size, origin, channel, resolution_level);
    let options = surface::ClosedOptions {
        finding: IsosurfaceOptions {
            smoothing,
            level: parse::<Level>(level, "level")?,
            genus,
            closing,
        },
        vertices,
        // As the command line's defaults for a closed surface: rigid alignment.
        tracking: TrackOptions {
            keep_going,
            relaxation: match relax_iterations {
                0 => Relaxation::None,
                iterations => Relaxation::Arap { iterations },
            },
            alignment: Alignment::Rigid,
            ..TrackOptions::default()
        },
        times,
    };
    let (closed, used) = py
        .detach(|| -> Result<_, Error> {
            let mut stream = VolumeStream::open(&path, &placement)?;
            let frames = stream.n_frames();
            let mut on_event = |event: surface::ClosedEvent| {
                if let (surface::ClosedEvent::Found { frame, .. }, Some(callback)) =
                    (event, progress.as_ref())
                {
                    // Progress only: an exception here is the caller's to see in its log.
                    Python::attach(|py| {
                        let report = PyDict::new(py);
                        let _ = report.set_item("kind", "surface");
                        let _ = report.set_item("frame", frame);
                        let _ = report.set_item("frames", frames);
                        if let Err(e) = callback.call1(py, (report,)) {
                            e.print(py);
                        }
                    });
                }
            };
            let closed = surface::closed_sequence(&mut stream, &options, &mut on_event).map_err(
                |e| match e {
                    Error::Closed(surface::ClosedError::OneFrame(_)) => e.in_file(&path),
                    other => other,
                },
            )?;
            Ok((closed, stream.voxel_size()))
        })
        .map_err(to_py_err)?;
    let sequence = &closed.tracked.sequence;
    let positions: Vec<Vec<Vector3<f64>>> = (0..sequence.n_frames())
        .map(|k| sequence.positions(k).map(<[_]>::to_vec).unwrap_or_default())
        .collect();
    let out = PyDict::new(py);
    out.set_item("positions", frames_array(&positions).into_pyarray(py))?;
    out.set_item(
        "faces",
        faces_array(sequence.mesh().faces()).into_pyarray(py),
    )?;
    out.set_item("times", sequence.times().to_vec().into_pyarray(py))?;
    out.set_item("voxel_size", used.map(|v| (v.x, v.y, v.z)))?;
    out.set_item("report", closed.report().to_string())?;
    Ok(out)
}
