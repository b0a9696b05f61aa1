//! `meshflow sample`: a microscope recording carried onto a moving surface. Per vertex and
//! frame the volume is read along the vertex normal over a shell and reduced (a
//! maximum-intensity projection by default): `intensity.npy` for `meshflow solve`
//! (`meshflow::volume::sample`).

use crate::args::{MeshArgs, VolumePlacement};
use crate::progress::{count_progress, during};
use crate::usage;
use meshflow::format::{
    no_data_file, write_atomically, write_image_and_no_data, INTENSITY, NO_DATA,
};
use meshflow::load::{count_frames, load_geometry, LoadOptions};
use meshflow::mesh::Mesh;
use meshflow::run::{
    input_files, refuse_output_over_inputs, OutputKind, RecordingRecord, RunManifest,
};
use meshflow::volume::{
    count_volume_frames, sample_stream, SampleOptions, SampledSequence, StreamEvent, VolumeError,
    VolumeOptions, VolumeStream, VoxelSizeSource,
};
use meshflow::Error;
use nalgebra::Vector3;
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
    refuse_swapped_arguments(&request)?;
    let out = output_file(&request)?;
    check_output(&request, &out)?;
    check_output(&request, &no_data_file(&out))?;
    check_frame_counts(&request)?;
    let geometry = during(format!("reading {}", request.sequence.display()), || {
        load_geometry(request.sequence, &request.load)
    })?;
    crate::print_warnings(&geometry.warnings);
    let (sampled, recording) = sample_streamed(&request, &geometry.mesh, &geometry.positions)?;
    let map = &geometry.vertex_map;
    let image: Vec<Vec<Vec<f64>>> = (sampled.values.iter())
        .map(|frame| vec![map.file_rows(frame, 0.0)])
        .collect();
    let no_data: Vec<Vec<bool>> = (sampled.no_data.iter())
        .map(|frame| map.file_rows(frame, false))
        .collect();
    // Together: a failure leaves the earlier image and its mask, never one beside the other.
    write_image_and_no_data(&out, &image, &no_data_file(&out), &no_data)?;
    if replaces_intensity(&request, &out) {
        register_in_manifest(request.sequence, recording)?;
    }
    let outside: usize = sampled.outside.iter().sum();
    if outside > 0 {
        let total = sampled.values.len() * geometry.mesh.n_vertices();
        stderr_line!(
            "meshflow: warning: {outside} of {total} vertex frames ({:.1} %) have a shell that leaves the volume: written as 0, and marked in {}",
            100.0 * outside as f64 / total as f64,
            no_data_file(&out).display()
        );
    }
    stdout_line!(
        "{}",
        describe(&request, &sampled, geometry.mesh.n_vertices(), &out)
    );
    Ok(())
}

/// The volumes read and sampled one frame at a time ([`sample_stream`]): only one frame's
/// volume and its smoothed copy are held, whatever the recording's length. Also the record of
/// the recording for the sequence's manifest (its grid as read).
fn sample_streamed(
    request: &SampleRequest,
    mesh: &Mesh,
    positions: &[Vec<Vector3<f64>>],
) -> Result<(SampledSequence, Option<RecordingRecord>), Error> {
    let mut stream = VolumeStream::open(request.volumes, &request.volume)?;
    let bar = count_progress(
        stream.n_frames() as u64,
        "sampling the volumes onto the surface",
    );
    let mut on_event = |event: StreamEvent| match event {
        StreamEvent::VoxelSize(source) => {
            bar.suspend(|| report_voxel_size(request.volumes, source))
        }
        StreamEvent::Sampled(_) => bar.inc(1),
        StreamEvent::MissingChunks {
            frame,
            missing,
            chunks,
        } => bar.suspend(|| report_missing_chunks(request.volumes, frame, missing, chunks)),
    };
    let sampled = sample_stream(
        &mut stream,
        mesh,
        positions,
        &request.sampling,
        &mut on_event,
    )?;
    bar.finish();
    let recording = match (stream.voxel_size(), stream.origin()) {
        (Some(voxel_size), Some(origin)) => Some(RecordingRecord {
            path: RecordingRecord::path_from(request.sequence, request.volumes),
            shape: stream.shape(),
            voxel_size: voxel_size.into(),
            origin: origin.into(),
            channel: request.volume.channel,
            resolution_level: request.volume.resolution_level,
        }),
        _ => None,
    };
    Ok((sampled, recording))
}

/// Warns that frame `frame` of the OME-Zarr image `volumes` lacked `missing` of its `chunks`.
pub(crate) fn report_missing_chunks(volumes: &Path, frame: usize, missing: u64, chunks: u64) {
    stderr_line!(
        "meshflow: warning: {}: frame {frame}: {missing} of its {chunks} chunks are not stored and read as the array's fill value (written without empty chunks, or damaged?)",
        volumes.display()
    )
}

pub(crate) fn report_voxel_size(volumes: &Path, source: &VoxelSizeSource) {
    match source {
        VoxelSizeSource::Default => stderr_line!(
            "meshflow: warning: {}: no voxel size given (--voxel-size X,Y,Z) or found in the files: taking 1 × 1 × 1",
            volumes.display()
        ),
        VoxelSizeSource::GivenOverInvalid(why) => stderr_line!(
            "meshflow: warning: {}: the files' voxel size metadata is invalid ({why}): using --voxel-size",
            volumes.display()
        ),
        VoxelSizeSource::File(said) => stdout_line!("voxel size from the {said}"),
        VoxelSizeSource::Given => {}
    }
}

/// Refuses an output over any input, before anything is read. The files inside the sequence
/// that `sample` may replace are `SEQUENCE/intensity.npy` and its `no_data.npy` (its default
/// output, an earlier sample's): they are checked against the sequence's other files instead
/// of the directory, so a link from one of them to another file is refused still.
fn check_output(request: &SampleRequest, out: &Path) -> Result<(), Error> {
    let named = [request.volumes, request.sequence];
    let mut inputs: Vec<PathBuf> = input_files(&named);
    match replaces_intensity(request, out) {
        true => {
            let ours = |name: &std::ffi::OsStr| name == INTENSITY || name == NO_DATA;
            inputs.retain(|f| f.file_name().is_none_or(|name| !ours(name)));
            inputs.push(request.volumes.to_path_buf());
        }
        false => inputs.extend(named.iter().map(|p| p.to_path_buf())),
    }
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    Ok(refuse_output_over_inputs(out, OutputKind::File, &inputs)?)
}

/// Whether `out` is `intensity.npy` (or its `no_data.npy`) directly in the sequence directory.
fn replaces_intensity(request: &SampleRequest, out: &Path) -> bool {
    let parent = match out.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    let same_dir = match (parent.canonicalize(), request.sequence.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let ours = out
        .file_name()
        .is_some_and(|n| n == INTENSITY || n == NO_DATA);
    same_dir && request.sequence.is_dir() && ours
}

/// The volumes' frames against the sequence's, from headers alone, before either is read.
fn check_frame_counts(request: &SampleRequest) -> Result<(), Error> {
    let frames = count_frames(request.sequence, &request.load)?;
    let volumes = count_volume_frames(request.volumes)?;
    match volumes == frames {
        true => Ok(()),
        false => {
            Err(Error::from(VolumeError::FrameCount { volumes, frames }).in_file(request.volumes))
        }
    }
}

/// Lists `intensity.npy` in the sequence directory's run manifest (where it is a meshflow
/// output, e.g. of `meshflow surface`), so that the next output written there (a new surface)
/// replaces it instead of leaving an image of the old surface beside the new one; and the
/// recording it came from, which viewers show the surface over (napari).
fn register_in_manifest(sequence: &Path, recording: Option<RecordingRecord>) -> Result<(), Error> {
    use std::io::Write;
    let Some(mut manifest) = RunManifest::read(sequence) else {
        return Ok(());
    };
    for written in [INTENSITY, NO_DATA] {
        if !manifest.files.iter().any(|f| f == written) {
            manifest.files.push(written.into());
        }
    }
    manifest.files.sort();
    manifest.recording = recording;
    manifest.commands.push(crate::command_line());
    let path = sequence.join(meshflow::run::RUN_MANIFEST);
    write_atomically(&path, |w| {
        serde_json::to_writer_pretty(&mut *w, &manifest).map_err(std::io::Error::other)?;
        writeln!(w)
    })?;
    Ok(())
}

/// `--out` (a file, not a directory), else `intensity.npy` in the sequence's directory.
fn output_file(request: &SampleRequest) -> Result<PathBuf, Error> {
    let bad = |path: &Path, message: &str| -> Result<PathBuf, Error> {
        Err(meshflow::format::IoError::format(path, message).into())
    };
    match request.out {
        Some(out) if out.is_dir() => bad(out, "a directory: --out names the .npy file to write"),
        Some(out) => Ok(out.to_path_buf()),
        None if request.sequence.is_dir() => Ok(request.sequence.join(INTENSITY)),
        None => bad(
            request.sequence,
            "not a directory: the surface is a sequence directory (e.g. of meshflow surface); for another sequence, give the output file with --out FILE.npy",
        ),
    }
}

/// `sample SEQUENCE VOLUMES` for `sample VOLUMES SEQUENCE`: the first argument holds a surface
/// sequence (`positions.npy`), or the second is one volume file.
fn refuse_swapped_arguments(request: &SampleRequest) -> Result<(), Error> {
    let is_sequence = |p: &Path| p.join(meshflow::format::POSITIONS).is_file();
    let is_volume = |p: &Path| {
        let extension = p.extension().map(|e| e.to_string_lossy().to_lowercase());
        p.is_file() && matches!(extension.as_deref(), Some("tif" | "tiff"))
    };
    match is_sequence(request.volumes) || (is_volume(request.sequence) && !is_sequence(request.sequence)) {
        true => Err(usage(format!(
            "{} is a surface and {} volumes: the order is meshflow sample VOLUMES SEQUENCE; swap them",
            request.volumes.display(),
            request.sequence.display()
        ))),
        false => Ok(()),
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
        "{}: {} onto {} vertices of {}: {:?} of {} layers over [−{}, +{}] along the normals{smoothing} -> {}",
        request.volumes.display(),
        crate::plural(sampled.values.len(), "frame"),
        vertices,
        request.sequence.display(),
        request.sampling.reduce,
        shell.layers,
        shell.inside,
        shell.outside,
        out.display()
    )
}

#[derive(clap::Args)]
pub(crate) struct SampleArgs {
    /// Volumes, one per frame: a .npy (Z, Y, X) or (K, Z, Y, X), a .tif/.tiff stack (pages =
    /// z) or ImageJ hyperstack (frames in one file), an OME-Zarr image, or a directory or
    /// quoted glob of .npy/.tif files (natural order)
    pub(crate) volumes: PathBuf,
    /// The moving surface: any sequence `solve` reads (an image is not needed), e.g. the
    /// output of `meshflow surface` or `meshflow track`
    pub(crate) sequence: PathBuf,
    /// Output .npy [default: SEQUENCE/intensity.npy]
    #[arg(long, value_name = "FILE.npy")]
    pub(crate) out: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) placement: VolumePlacement,
    /// How far the shell reaches inside and outside along the normal, in the surface's units
    /// [default: two of the largest voxel sides each way]
    #[arg(
        long,
        value_name = "INSIDE,OUTSIDE",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    pub(crate) shell: Option<Vec<f64>>,
    /// Samples across the --shell, evenly spaced; only with --shell (the default shell has 9)
    /// [default: 9]
    #[arg(long, value_name = "N", requires = "shell")]
    pub(crate) layers: Option<usize>,
    /// max (maximum-intensity projection), mean, or layer:L (sample L, 0 the innermost)
    #[arg(long, default_value = "max")]
    pub(crate) reduce: meshflow::volume::Reduce,
    /// Gaussian smoothing of each volume first, σ in the surface's units (0: none)
    /// [default: 2 of the smallest voxel sides]
    #[arg(long, value_name = "SIGMA", allow_negative_numbers = true)]
    pub(crate) smooth: Option<f64>,
    /// Sample even where more than half of a frame's vertices lie outside its volume (refused
    /// by default: the voxel size, its units or the origin are most likely wrong)
    #[arg(long)]
    pub(crate) allow_outside: bool,
    #[command(flatten)]
    pub(crate) building: MeshArgs,
}

impl SampleArgs {
    pub(crate) fn request(&self) -> Result<SampleRequest<'_>, meshflow::Error> {
        let shell = match self.shell.as_deref() {
            None => None,
            Some(&[inside, outside]) => Some(meshflow::volume::Shell {
                inside,
                outside,
                layers: self
                    .layers
                    .unwrap_or(meshflow::volume::sample::DEFAULT_LAYERS),
            }),
            Some(other) => {
                return Err(usage(format!(
                    "--shell takes two distances INSIDE,OUTSIDE, got {} numbers",
                    other.len()
                )))
            }
        };
        Ok(SampleRequest {
            volumes: &self.volumes,
            sequence: &self.sequence,
            out: self.out.as_deref(),
            volume: self.placement.options()?,
            sampling: meshflow::volume::SampleOptions {
                smoothing: self.smooth,
                shell,
                layers: None,
                reduce: self.reduce,
                allow_outside: self.allow_outside,
            },
            load: self.building.options(),
        })
    }
}
