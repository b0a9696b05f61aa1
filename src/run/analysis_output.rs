//! Writing what a flow tells ([`crate::analysis`]): `meshflow analyze RUN --out DIR`.
//!
//! Vertex arrays are in the files' numbering (as `flow.npy`; NaN at dropped vertices), face
//! arrays follow `faces.npy`, the mesh's triangles over file vertices (each mesh vertex as its
//! first file vertex). Vectors are in R³ on frame `s`; rates in 1/time.
//!
//! | file | contents |
//! |---|---|
//! | `divergence.npy`, `curl.npy` | (S, V_file): weak vertex divergence and curl |
//! | `potential.npy`, `stream.npy` | (S, V_file): the Hodge potentials `φ` and `ψ` (`ψ` at a vertex: the mean of its edges' values) |
//! | `face_divergence.npy`, `face_curl.npy` | (S, F): per face |
//! | `areal_rate.npy`, `shear_rate.npy` | (S, F): `tr D`, `|dev D|` of the rate of deformation |
//! | `principal_rates.npy` | (S, F, 2): `λ₁ ≥ λ₂` |
//! | `stretch_direction.npy` | (S, F, 3): the unit direction of `λ₁` |
//! | `hodge_exact.npy`, `hodge_coexact.npy`, `hodge_harmonic.npy` | (S, F, 3): `∇φ`, `J∇ψ`, `h` |
//! | `faces.npy` | (F, 3) int64 |
//! | `analysis_SSSS.vtu`, `analysis.pvd` | ParaView: frame `s` with the vertex arrays as point data (`divergence`, `curl`, `potential`, `stream`, `intensity`) and the face arrays as cell data (`divergence`, `curl`, `areal_rate`, `shear_rate`, `principal_rates`, `stretch_direction`, `field`, `exact`, `coexact`, `harmonic`) |
//! | `summary.json` | per slab: time, duration, total area, mean speed, mean divergence, curl, areal and shear rate, the energies `∫|·|²` of the field and its Hodge parts |

use super::write_slab_vtus_with_cells;
use super::OutputFormat;
use crate::analysis::{face_frames, in_r3, SlabAnalysis};
use crate::flow::MeshSequence;
use crate::format::vtk::NamedArray;
use crate::format::{write_atomically, write_npy, IoError};
use crate::load::LoadedSequence;
use nalgebra::{Matrix3x2, Vector2, Vector3};
use std::path::Path;

/// A named per-slab array: the file it goes into, and how to read it from a slab's analysis.
type Column<'a> = (&'static str, &'a dyn Fn(&SlabAnalysis) -> Vec<f64>);

/// Writes the analysis of every slab of `loaded` into `dir` (see the module documentation) in
/// `formats` (NPY and VTU; `summary.json` always); `input` names the run in `summary.json`.
pub fn write_analysis_outputs(
    dir: &Path,
    loaded: &LoadedSequence,
    slabs: &[SlabAnalysis],
    input: &Path,
    formats: &[OutputFormat],
) -> Result<(), IoError> {
    if formats.contains(&OutputFormat::Glb) {
        return Err(IoError::format(
            dir,
            "the analysis is written as npy and vtu, not glb",
        ));
    }
    let sequence = &loaded.sequence;
    let fields = FaceFields::new(slabs, &face_maps(loaded)?);
    if formats.contains(&OutputFormat::Npy) {
        for array in arrays_with(loaded, slabs, &fields) {
            write_npy(
                &dir.join(format!("{}.npy", array.name)),
                &array.shape,
                &array.values,
            )?;
        }
        let faces = file_faces(loaded);
        write_npy(
            &dir.join("faces.npy"),
            &[faces.len() as u64, 3],
            faces.as_flattened(),
        )?;
    }
    if formats.contains(&OutputFormat::Vtu) {
        write_slab_vtus_with_cells(dir, "analysis", sequence, |s| {
            (
                point_arrays(sequence, &slabs[s], s),
                cell_arrays(&slabs[s], &fields, s),
            )
        })?;
    }
    write_summary(&dir.join("summary.json"), sequence, slabs, input)
}

/// The R³ vectors of every slab's face fields.
struct FaceFields {
    field: Vec<Vec<Vector3<f64>>>,
    exact: Vec<Vec<Vector3<f64>>>,
    coexact: Vec<Vec<Vector3<f64>>>,
    harmonic: Vec<Vec<Vector3<f64>>>,
    stretch: Vec<Vec<Vector3<f64>>>,
}

impl FaceFields {
    fn new(slabs: &[SlabAnalysis], maps: &[Vec<Matrix3x2<f64>>]) -> Self {
        let each = |part: fn(&SlabAnalysis) -> &[Vector2<f64>]| -> Vec<Vec<Vector3<f64>>> {
            slabs
                .iter()
                .zip(maps)
                .map(|(a, m)| in_r3(m, part(a)))
                .collect()
        };
        let stretch = slabs
            .iter()
            .zip(maps)
            .map(|(a, m)| {
                (a.strain.iter().zip(m))
                    .map(|(d, m)| (m * d.directions[0]).try_normalize(0.0).unwrap_or_default())
                    .collect()
            })
            .collect();
        FaceFields {
            field: each(|a| &a.hodge.field),
            exact: each(|a| &a.hodge.exact),
            coexact: each(|a| &a.hodge.coexact),
            harmonic: each(|a| &a.hodge.harmonic),
            stretch,
        }
    }
}

/// One array of the analysis: its name (the file's, without `.npy`), shape and values in C
/// order.
#[derive(Clone, Debug, PartialEq)]
pub struct AnalysisArray {
    pub name: &'static str,
    pub shape: Vec<u64>,
    pub values: Vec<f64>,
}

/// Every array of the module documentation's table but `faces.npy` ([`file_faces`]), for
/// `slabs` of `loaded`.
pub fn analysis_arrays(
    loaded: &LoadedSequence,
    slabs: &[SlabAnalysis],
) -> Result<Vec<AnalysisArray>, IoError> {
    let maps = face_maps(loaded)?;
    Ok(arrays_with(loaded, slabs, &FaceFields::new(slabs, &maps)))
}

fn face_maps(loaded: &LoadedSequence) -> Result<Vec<Vec<Matrix3x2<f64>>>, IoError> {
    let sequence = &loaded.sequence;
    (0..sequence.n_slabs())
        .map(|s| match face_frames(sequence, s) {
            Ok(Some(maps)) => Ok(maps),
            _ => Err(IoError::format(
                &loaded.frame_files[s],
                "the analysis needs vertex positions (an embedded sequence)",
            )),
        })
        .collect()
}

fn arrays_with(
    loaded: &LoadedSequence,
    slabs: &[SlabAnalysis],
    fields: &FaceFields,
) -> Vec<AnalysisArray> {
    let map = &loaded.vertex_map;
    let mesh = loaded.sequence.mesh();
    let (s, v, f) = (
        slabs.len() as u64,
        map.n_file_vertices() as u64,
        mesh.n_faces() as u64,
    );
    let vertex_columns: [Column; 4] = [
        ("divergence", &|a| a.vertex_divergence.clone()),
        ("curl", &|a| a.vertex_curl.clone()),
        ("potential", &|a| a.hodge.potential.clone()),
        ("stream", &|a| a.hodge.stream_at_vertices(mesh)),
    ];
    let face_columns: [Column; 4] = [
        ("face_divergence", &|a| a.face_divergence.clone()),
        ("face_curl", &|a| a.face_curl.clone()),
        ("areal_rate", &|a| {
            a.strain.iter().map(|d| d.areal).collect()
        }),
        ("shear_rate", &|a| {
            a.strain.iter().map(|d| d.shear).collect()
        }),
    ];
    let mut arrays: Vec<AnalysisArray> = vertex_columns
        .iter()
        .map(|(name, column)| AnalysisArray {
            name,
            shape: vec![s, v],
            values: (slabs.iter())
                .flat_map(|a| map.file_rows(&column(a), f64::NAN))
                .collect(),
        })
        .collect();
    arrays.extend(face_columns.iter().map(|(name, column)| AnalysisArray {
        name,
        shape: vec![s, f],
        values: slabs.iter().flat_map(column).collect(),
    }));
    arrays.push(AnalysisArray {
        name: "principal_rates",
        shape: vec![s, f, 2],
        values: (slabs.iter())
            .flat_map(|a| a.strain.iter().flat_map(|d| d.principal))
            .collect(),
    });
    let vectors = [
        ("stretch_direction", &fields.stretch),
        ("hodge_exact", &fields.exact),
        ("hodge_coexact", &fields.coexact),
        ("hodge_harmonic", &fields.harmonic),
    ];
    arrays.extend(vectors.map(|(name, rows)| {
        AnalysisArray {
            name,
            shape: vec![s, f, 3],
            values: rows
                .iter()
                .flatten()
                .flat_map(|v| [v.x, v.y, v.z])
                .collect(),
        }
    }));
    arrays
}

/// The mesh's triangles over file vertices ([`crate::load::VertexMap::file_faces`]), as int64: what
/// the face arrays are per.
pub fn file_faces(loaded: &LoadedSequence) -> Vec<[i64; 3]> {
    let faces = loaded.vertex_map.file_faces(loaded.sequence.mesh().faces());
    faces.iter().map(|f| f.map(i64::from)).collect()
}

fn point_arrays(sequence: &MeshSequence, a: &SlabAnalysis, s: usize) -> Vec<NamedArray> {
    vec![
        NamedArray::scalars("divergence", &a.vertex_divergence),
        NamedArray::scalars("curl", &a.vertex_curl),
        NamedArray::scalars("potential", &a.hodge.potential),
        NamedArray::scalars("stream", &a.hodge.stream_at_vertices(sequence.mesh())),
        NamedArray::scalars("intensity", sequence.intensities(s)),
    ]
}

fn cell_arrays(a: &SlabAnalysis, fields: &FaceFields, s: usize) -> Vec<NamedArray> {
    let strain = |f: fn(&crate::analysis::StrainRate) -> f64| -> Vec<f64> {
        a.strain.iter().map(f).collect()
    };
    let rates: Vec<f64> = a.strain.iter().flat_map(|d| d.principal).collect();
    vec![
        NamedArray::scalars("divergence", &a.face_divergence),
        NamedArray::scalars("curl", &a.face_curl),
        NamedArray::scalars("areal_rate", &strain(|d| d.areal)),
        NamedArray::scalars("shear_rate", &strain(|d| d.shear)),
        NamedArray {
            name: "principal_rates".into(),
            components: 2,
            values: rates,
        },
        NamedArray::vectors("stretch_direction", &fields.stretch[s]),
        NamedArray::vectors("field", &fields.field[s]),
        NamedArray::vectors("exact", &fields.exact[s]),
        NamedArray::vectors("coexact", &fields.coexact[s]),
        NamedArray::vectors("harmonic", &fields.harmonic[s]),
    ]
}

/// `summary.json`: the run, and per slab its time, duration and totals.
pub fn analysis_json(
    sequence: &MeshSequence,
    slabs: &[SlabAnalysis],
    input: &Path,
) -> serde_json::Value {
    let rows: Vec<serde_json::Value> = slabs
        .iter()
        .map(|a| {
            let mut row = serde_json::to_value(a.totals).expect("numbers serialize");
            row["slab"] = a.slab.into();
            row["time"] = sequence.times()[a.slab].into();
            row["duration"] = sequence.slab_duration(a.slab).into();
            row
        })
        .collect();
    serde_json::json!({
        "input": input.display().to_string(),
        "frames": sequence.n_frames(),
        "vertices": sequence.mesh().n_vertices(),
        "faces": sequence.mesh().n_faces(),
        "slabs": rows,
    })
}

fn write_summary(
    path: &Path,
    sequence: &MeshSequence,
    slabs: &[SlabAnalysis],
    input: &Path,
) -> Result<(), IoError> {
    let json = analysis_json(sequence, slabs, input);
    write_atomically(path, |w| {
        serde_json::to_writer_pretty(&mut *w, &json).map_err(std::io::Error::other)?;
        std::io::Write::write_all(w, b"\n")
    })
}
