//! OBJ materials: colours from the diffuse texture (`map_Kd`) at each vertex.
//!
//! A vertex's colour is the mean of the bilinear texture samples (see [`Texture`]) at the
//! texture coordinates of its face corners, each corner using the `map_Kd` image of its face's
//! material. OBJ's `v` runs upwards, so a corner with `vt u v` samples at `(u, 1 − v)`. Averaging
//! over corners makes vertices on a UV seam (one vertex, several `vt`) and vertices split at the
//! seam and later welded give the same value.

use super::{IoError, ObjMesh, Texture};
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
    let base = obj_path.parent().unwrap_or(Path::new(""));
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
        let path = base.join(library);
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
    let text = std::fs::read(path).map_err(|e| IoError::file(path, e))?;
    let base = path.parent().unwrap_or(Path::new(""));
    let mut maps = HashMap::new();
    let mut current = None;
    for (number, line) in String::from_utf8_lossy(&text).lines().enumerate() {
        let line = line.trim();
        if let Some(name) = line.strip_prefix("newmtl") {
            current = Some(name.trim().to_string());
        } else if let Some(arguments) = line.strip_prefix("map_Kd") {
            let material = current.clone().ok_or_else(|| {
                IoError::at_line(path, (number + 1, "map_Kd before any newmtl".into()))
            })?;
            maps.insert(material, base.join(map_file_name(arguments)));
        }
    }
    Ok(maps)
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
