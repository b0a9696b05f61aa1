//! OBJ materials: colours from the diffuse texture (`map_Kd`) at each vertex.
//!
//! A vertex's colour is the mean of the bilinear texture samples (see [`Texture`]) at the
//! texture coordinates of its face corners, each corner using the `map_Kd` image of its face's
//! material. OBJ's `v` runs upwards, so a corner with `vt u v` samples at `(u, 1 − v)`. Averaging
//! over corners makes vertices on a UV seam (one vertex, several `vt`) and vertices split at the
//! seam and later welded give the same value.
//!
//! # Reading `.mtl` files
//!
//! Material libraries are parsed by `tobj` ([`tobj::load_mtl_buf`]); the OBJ geometry is not
//! (see [`crate::format::read_obj`]: tobj renumbers vertices by first use). Only the statements meshflow
//! reads, `newmtl` and `map_Kd`, are handed to it (the others become blank lines, so line
//! numbers stay): tobj 4.0 panics on a colour with fewer than three numbers (`Kd 0.8`) and
//! rejects forms the MTL specification allows (`Kd spectral paint.rfl`, `d -halo 0.5`), none
//! of which changes a texture. Three things stay by hand, because tobj does not do them:
//!
//! - **`map_Kd` options.** tobj keeps the whole rest of the line as the texture name, options
//!   included (`-s 1 1 1 -clamp on wood grain.png`); [`map_file_name`] skips the options and
//!   their values and keeps the name, which may contain spaces. The options themselves (scale,
//!   offset, clamping) are not applied: the texture is sampled as it is.
//! - **Which line is broken.** tobj rejects a malformed statement (an empty `newmtl` or
//!   `map_Kd`) with a bare error kind; its statements are line by line, so the library is then
//!   parsed again a line at a time to name the one tobj rejects.
//! - **A `map_Kd` before the first `newmtl`.** tobj silently drops statements that belong to
//!   no material, which would lose the texture without a word; it is refused, naming the line.
//!
//! The file is read here (so a missing one is an error naming it) and decoded leniently, so a
//! file name in another encoding does not fail the whole library.

use super::{resolve_linked, IoError, ObjMesh, Texture};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Decoded images by path, so frames sharing a texture decode it once.
/// Frames read in parallel share it; two threads may both decode an image the first time.
#[derive(Default)]
pub struct TextureCache {
    textures: Mutex<HashMap<PathBuf, Arc<Texture>>>,
}

impl TextureCache {
    fn get(&self, path: &Path) -> Result<Arc<Texture>, IoError> {
        if let Some(texture) = self.lock().get(path) {
            return Ok(texture.clone());
        }
        let texture = Arc::new(Texture::open(path)?);
        self.lock().insert(path.to_path_buf(), texture.clone());
        Ok(texture)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<PathBuf, Arc<Texture>>> {
        // A panic elsewhere cannot leave the map half-updated: recover it.
        self.textures.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Colours sampled from the materials' `map_Kd` textures, or `None` when no face of the file
/// has both texture coordinates and a textured material. Every vertex must then lie on a
/// textured face.
pub fn texture_colors(
    obj: &ObjMesh,
    obj_path: &Path,
    cache: &TextureCache,
) -> Result<Option<Vec<[f64; 3]>>, IoError> {
    let textures = material_textures(obj, obj_path, cache)?;
    if textures.iter().all(Option::is_none) {
        return Ok(None);
    }
    let n = obj.positions.len();
    let (mut sum, mut count) = (vec![[0.0; 3]; n], vec![0u32; n]);
    let corners = obj
        .faces
        .iter()
        .zip(&obj.face_texcoords)
        .zip(&obj.face_materials);
    for ((face, texcoords), material) in corners {
        let texture = material.and_then(|m| textures[m as usize].as_ref());
        let (Some(texture), Some(texcoords)) = (texture, texcoords) else {
            continue;
        };
        for (&vertex, &t) in face.iter().zip(texcoords) {
            let [u, v] = obj.texcoords[t as usize];
            let value = texture.sample(u, 1.0 - v).ok_or_else(|| {
                IoError::format(
                    obj_path,
                    format!("texture coordinate {} is not finite", t + 1),
                )
            })?;
            for (total, v) in sum[vertex as usize].iter_mut().zip(value) {
                *total += v;
            }
            count[vertex as usize] += 1;
        }
    }
    if let Some(vertex) = count.iter().position(|&c| c == 0) {
        return Err(IoError::format(
            obj_path,
            format!(
                "vertex {} lies on no textured face, so it has no colour",
                vertex + 1
            ),
        ));
    }
    Ok(Some(
        (sum.iter().zip(&count))
            .map(|(s, &c)| s.map(|x| x / c as f64))
            .collect(),
    ))
}

/// The `map_Kd` texture of each material of `obj` (`None` for untextured ones). A library or
/// image that fails is an error about the OBJ file that names it.
fn material_textures(
    obj: &ObjMesh,
    obj_path: &Path,
    cache: &TextureCache,
) -> Result<Vec<Option<Arc<Texture>>>, IoError> {
    if obj.materials.is_empty() || obj.face_texcoords.iter().all(Option::is_none) {
        return Ok(vec![None; obj.materials.len()]);
    }
    let referenced = |context: String| {
        move |source: IoError| IoError::Referenced {
            path: obj_path.to_path_buf(),
            context,
            source: Box::new(source),
        }
    };
    // Material name → (image, the library that names it).
    let mut maps = HashMap::new();
    for library in &obj.material_libraries {
        let path = resolve_linked(obj_path, "mtllib", library, library)?;
        let images = read_mtl(&path).map_err(referenced(format!("material library {library}")))?;
        maps.extend(
            images
                .into_iter()
                .map(|(name, image)| (name, (image, path.clone()))),
        );
    }
    obj.materials
        .iter()
        .map(|name| match maps.get(name) {
            Some((image, library)) => cache.get(image).map(Some).map_err(referenced(format!(
                "texture of material '{name}' ({})",
                library.display()
            ))),
            None => Ok(None),
        })
        .collect()
}

/// Material name → absolute path of its `map_Kd` image, from one `.mtl` file.
fn read_mtl(path: &Path) -> Result<HashMap<String, PathBuf>, IoError> {
    let bytes = super::read_file(path)?;
    let text = statements_read_here(&String::from_utf8_lossy(&bytes));
    if let Some(line) = map_before_any_newmtl(&text) {
        let message = "map_Kd before any newmtl".to_string();
        return Err(IoError::at_line(path, (line, message)));
    }
    let (materials, _) = tobj::load_mtl_buf(&mut text.as_bytes())
        .map_err(|error| IoError::at_line(path, rejected_line(&text, error)))?;
    let textured = materials
        .into_iter()
        .filter_map(|m| Some((m.name, m.diffuse_texture?)));
    textured
        .map(|(name, map)| match map_file_name(&map) {
            file if file.is_empty() => Err(IoError::format(
                path,
                format!("material '{name}': map_Kd '{map}' names no image, only options"),
            )),
            file => {
                let image =
                    resolve_linked(path, &format!("material '{name}': map_Kd"), &file, &file)?;
                Ok((name, image))
            }
        })
        .collect()
}

/// `text` with every line but the `newmtl` and `map_Kd` statements blank.
fn statements_read_here(text: &str) -> String {
    let read_here = |line: &&str| matches!(keyword(line), Some("newmtl" | "map_Kd"));
    let lines: Vec<&str> = text
        .lines()
        .map(|line| Some(line).filter(read_here).unwrap_or(""))
        .collect();
    lines.join("\n")
}

/// The first word of a line.
fn keyword(line: &str) -> Option<&str> {
    line.split_whitespace().next()
}

/// The line number of a `map_Kd` that comes before any `newmtl` in an `.mtl` text.
fn map_before_any_newmtl(text: &str) -> Option<usize> {
    statements(text)
        .take_while(|(_, statement)| keyword(statement) != Some("newmtl"))
        .find(|(_, statement)| keyword(statement) == Some("map_Kd"))
        .map(|(number, _)| number)
}

/// `(line number, statement)` of the non-blank, non-comment lines, trimmed.
fn statements(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .map(str::trim)
        .enumerate()
        .filter(|(_, line)| !line.is_empty() && !line.starts_with('#'))
        .map(|(i, line)| (i + 1, line))
}

/// The line of `text` that tobj rejects with `error`, parsed alone after a `newmtl`, and what
/// is wrong with it (line 0 if no single line fails).
fn rejected_line(text: &str, error: tobj::LoadError) -> (usize, String) {
    let fails_alone = |statement: &str| {
        let alone = format!("newmtl probe\n{statement}\n");
        tobj::load_mtl_buf(&mut alone.as_bytes()).err()
    };
    statements(text)
        .find_map(|(number, statement)| {
            let error = fails_alone(statement)?;
            Some((number, format!("'{statement}': {error}")))
        })
        .unwrap_or((0, error.to_string()))
}

/// The file name of a `map_Kd` statement: what follows its options (`-o 0 0 0`, `-clamp on`, …);
/// names may contain spaces.
fn map_file_name(arguments: &str) -> String {
    let tokens: Vec<&str> = arguments.split_whitespace().collect();
    let mut i = 0;
    while i < tokens.len() && tokens[i].starts_with('-') {
        i += 1;
        while i < tokens.len() && is_option_value(tokens[i]) {
            i += 1;
        }
    }
    tokens[i..].join(" ")
}

fn is_option_value(token: &str) -> bool {
    token.parse::<f64>().is_ok() || matches!(token, "on" | "off")
}
