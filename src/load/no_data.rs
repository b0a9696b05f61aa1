//! The no-data mask of an image: which vertices of which frames hold no measurement.
//!
//! `meshflow sample` gives a vertex whose shell leaves the recording the value 0 and writes a
//! (K, V) uint8 mask beside the image ([`no_data_file`]: `no_data.npy` beside
//! `intensity.npy`). The loader reads it with the image, when it is there, so that a solve
//! can flag the flow where the data term saw no image ([`LoadedSequence::no_data`]). A mesh
//! vertex has no data when any of its file vertices (welded copies) has none.
//!
//! [`LoadedSequence::no_data`]: super::LoadedSequence::no_data

use super::input::SequenceSource;
use super::options::LoadOptions;
use super::vertex_map::VertexMap;
use crate::format::{
    no_data_file, read_intensity_rows, resolve_linked, IoError, KeepRows, VertexCount,
    VertexValues, INTENSITY,
};
use std::path::PathBuf;

/// The image file whose mask is looked for: `--intensity`, else an NPY directory's
/// `intensity.npy`; `None` for images carried by the frames (colours, textures).
fn image_file(source: &SequenceSource, options: &LoadOptions) -> Option<PathBuf> {
    match (&options.intensity, source) {
        (Some(file), _) => Some(file.clone()),
        (None, SequenceSource::Npy(dir)) => Some(dir.join(INTENSITY)),
        _ => None,
    }
}

/// Per held frame and mesh vertex, whether it has no data; `None` without a mask file. The
/// mask's rows are the files' vertices or the mesh's, `counts` in that order (as the image's).
///
/// The mask is named by convention beside its image, so it is read as a linked file
/// ([`resolve_linked`]): a link out of the image's directory, a FIFO, a device or a directory
/// in its place is an error, not "no mask"; and it must hold 0 and 1 alone (NaN or 0.5 would
/// read as data).
pub(super) fn read_no_data(
    source: &SequenceSource,
    options: &LoadOptions,
    n_frames: usize,
    counts: &[VertexCount],
    keep: KeepRows,
    vertex_map: &VertexMap,
) -> Result<Option<Vec<Vec<bool>>>, IoError> {
    let Some(image) = image_file(source, options) else {
        return Ok(None);
    };
    let name = no_data_file(&image);
    if std::fs::symlink_metadata(&name).is_err() {
        return Ok(None);
    }
    let written = name.file_name().map(|n| n.to_string_lossy().into_owned());
    let written = written.unwrap_or_default();
    let file = resolve_linked(&image, "its no-data mask", &written, &written)?;
    let (frames, count) = read_intensity_rows(MASK, &file, n_frames, counts, keep)?;
    if let Some(why) = first_not_a_flag(&frames) {
        return Err(IoError::format(
            &file,
            format!("{why}: a {MASK} holds 0 or 1"),
        ));
    }
    let on_mesh = count == 1;
    let masks = frames
        .iter()
        .map(|frame| {
            let values = frame.to_grey();
            let values = match on_mesh {
                true => values,
                false => vertex_map.mean_values(&values),
            };
            values.iter().map(|&v| v > 0.0).collect()
        })
        .collect();
    Ok(Some(masks))
}

/// What [`read_no_data`] calls the mask in its errors.
const MASK: &str = "no-data mask";

/// Where the first value of a mask that is neither 0 nor 1 is (frame as the file's row), as a
/// phrase.
fn first_not_a_flag(frames: &[VertexValues]) -> Option<String> {
    frames.iter().enumerate().find_map(|(k, frame)| {
        let values = frame.clone().into_channels().concat();
        let (i, v) = (values.iter().enumerate()).find(|(_, &v)| v != 0.0 && v != 1.0)?;
        Some(format!("row {k}, value {i} is {v}"))
    })
}

impl super::LoadedSequence {
    /// Per slab `s` and mesh vertex: no data in frame `s` or `s + 1`, so that the slab's data
    /// term had no image there; `None` without a mask.
    pub fn slab_no_data(&self) -> Option<Vec<Vec<bool>>> {
        let frames = self.no_data.as_ref()?;
        Some(
            (frames.windows(2))
                .map(|pair| {
                    pair[0]
                        .iter()
                        .zip(&pair[1])
                        .map(|(&a, &b)| a || b)
                        .collect()
                })
                .collect(),
        )
    }
}
