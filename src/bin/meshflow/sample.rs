//! `meshflow sample`: a microscope recording carried onto a moving surface. Per vertex and
//! frame the volume is read along the vertex normal over a shell and reduced (a
//! maximum-intensity projection by default): `intensity.npy` for `meshflow solve`
//! (`meshflow::volume::sample`).

use crate::progress::during;
use meshflow::io::{load_geometry, write_npy, LoadOptions};
use meshflow::volume::{
    read_volumes, sample_sequence, SampleOptions, SampledSequence, VolumeError, VolumeOptions,
    VoxelSizeSource,
};
use meshflow::Error;
use std::path::{Path, PathBuf};

/// What `sample` needs from the command line.
pub struct SampleRequest<'a> {
    pub volumes: &'a Path,
    pub sequence: &'a Path,
    /// Default: `SEQUENCE/intensity.npy` for a sequence directory.
    pub out: Option<&'a Path>,
    pub volume: VolumeOptions,
    pub sampling: SampleOptions,
    pub load: LoadOptions,
}

pub fn run(request: SampleRequest) -> Result<(), Error> {
    let out = output_file(&request)?;
    let geometry = during(format!("reading {}", request.sequence.display()), || {
        load_geometry(request.sequence, &request.load)
    })?;
    crate::print_warnings(&geometry.warnings);
    let frames = during(format!("reading {}", request.volumes.display()), || {
        read_volumes(request.volumes, &request.volume)
    })?;
    match &frames.voxel_size_source {
        VoxelSizeSource::Default => eprintln!(
            "meshflow: warning: {}: no voxel size given (--voxel-size X,Y,Z) or found in the files: taking 1 × 1 × 1",
            request.volumes.display()
        ),
        VoxelSizeSource::File(said) => println!("voxel size from the {said}"),
        VoxelSizeSource::Given => {}
    }
    let in_volumes = |e: VolumeError| Error::from(e).in_file(request.volumes);
    let sampled = during("sampling the volumes onto the surface", || {
        sample_sequence(
            &frames.volumes,
            &geometry.mesh,
            &geometry.positions,
            &request.sampling,
        )
    })
    .map_err(in_volumes)?;
    let map = &geometry.vertex_map;
    let values: Vec<f64> = (sampled.values.iter())
        .flat_map(|frame| map.file_rows(frame, 0.0))
        .collect();
    let shape = [sampled.values.len() as u64, map.n_file_vertices() as u64];
    write_npy(&out, &shape, &values)?;
    let outside: usize = sampled.outside.iter().sum();
    if outside > 0 {
        let total = sampled.values.len() * geometry.mesh.n_vertices();
        eprintln!(
            "meshflow: warning: {outside} of {total} vertex frames ({:.1} %) have a shell that leaves the volume: written as 0",
            100.0 * outside as f64 / total as f64
        );
    }
    println!(
        "{}",
        describe(&request, &sampled, geometry.mesh.n_vertices(), &out)
    );
    Ok(())
}

/// `--out`, else `intensity.npy` in the sequence's directory.
fn output_file(request: &SampleRequest) -> Result<PathBuf, Error> {
    if let Some(out) = request.out {
        return Ok(out.to_path_buf());
    }
    match request.sequence.is_dir() {
        true => Ok(request.sequence.join("intensity.npy")),
        false => Err(meshflow::io::IoError::format(
            request.sequence,
            "not a directory: give the output file with --out FILE.npy",
        )
        .into()),
    }
}

fn describe(
    request: &SampleRequest,
    sampled: &SampledSequence,
    vertices: usize,
    out: &Path,
) -> String {
    let shell = sampled.shell;
    let smoothing = match sampled.smoothing {
        0.0 => String::new(),
        sigma => format!(", smoothed by a Gaussian of σ = {sigma:.4}"),
    };
    format!(
        "{}: {} frames onto {} vertices of {}: {:?} of {} layers over [−{}, +{}] along the normals{smoothing} -> {}",
        request.volumes.display(),
        sampled.values.len(),
        vertices,
        request.sequence.display(),
        request.sampling.reduce,
        shell.layers,
        shell.inside,
        shell.outside,
        out.display()
    )
}
