//! Colour textures sampled at vertex texture coordinates.
//!
//! A texture is a `width × height` grid of RGB colours (channels in `[0, 1]`) with texel
//! `(x, y)` centred at `((x + ½)/width, (y + ½)/height)` in texture space, `y` counted from
//! the top row of the image. Sampling is bilinear between the four nearest texel centres with
//! wrap-around (repeat) addressing, the default of OBJ and glTF.

use super::IoError;
use std::path::Path;

/// A colour image for sampling at texture coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    texels: Vec<[f64; 3]>,
}

impl Texture {
    /// A texture from colours in row-major order, top row first. `None` if the sizes do not
    /// match or the image is empty.
    pub fn new(width: usize, height: usize, texels: Vec<[f64; 3]>) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width * height).then_some(Self {
            width,
            height,
            texels,
        })
    }

    /// Decodes an image file (PNG or JPEG) with channels scaled to `[0, 1]` (alpha ignored).
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let bytes = super::read_file(path)?;
        Self::decode(&bytes).map_err(|message| IoError::format(path, message))
    }

    /// Decodes an image in memory (PNG or JPEG) like [`Self::open`]. Its declared size is
    /// checked against the memory limit ([`crate::limits`]) before any pixel is decoded: a
    /// small file can declare a gigapixel image.
    pub fn decode(bytes: &[u8]) -> Result<Self, String> {
        let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| format!("cannot read the image ({e})"))?;
        let (width, height) = reader
            .into_dimensions()
            .map_err(|e| format!("cannot decode the image ({e})"))?;
        // Decoded pixels, their f32 RGB copy and the f64 texels.
        let per_pixel = 8 + 12 + 24;
        let declared = format!("an image of {width} × {height} pixels");
        crate::limits::check_items(declared, u64::from(width) * u64::from(height), per_pixel)
            .map_err(|e| e.to_string())?;
        let image =
            image::load_from_memory(bytes).map_err(|e| format!("cannot decode the image ({e})"))?;
        Self::from_image(&image).ok_or_else(|| "the image has no pixels".to_string())
    }

    /// The colours of a decoded image (channels scaled to `[0, 1]`, alpha ignored).
    pub fn from_image(image: &image::DynamicImage) -> Option<Self> {
        let rgb = image.to_rgb32f();
        let texels = rgb.pixels().map(|p| p.0.map(f64::from)).collect();
        Self::new(rgb.width() as usize, rgb.height() as usize, texels)
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Bilinear sample at texture coordinates `(s, t)` with `t` measured from the **top** row
    /// (glTF's convention; for OBJ's bottom-up `v` pass `t = 1 − v`). Coordinates wrap
    /// (repeat); non-finite coordinates give `None`.
    pub fn sample(&self, s: f64, t: f64) -> Option<[f64; 3]> {
        if !(s.is_finite() && t.is_finite()) {
            return None;
        }
        let (x0, x1, fx) = texel_pair(s, self.width);
        let (y0, y1, fy) = texel_pair(t, self.height);
        let corners = [
            (x0, y0, (1.0 - fx) * (1.0 - fy)),
            (x1, y0, fx * (1.0 - fy)),
            (x0, y1, (1.0 - fx) * fy),
            (x1, y1, fx * fy),
        ];
        let mut colour = [0.0; 3];
        for (x, y, w) in corners {
            let texel = self.texels[y * self.width + x];
            for c in 0..3 {
                colour[c] += w * texel[c];
            }
        }
        Some(colour)
    }
}

/// The two texel indices around coordinate `c` (wrapped) and the weight of the second.
fn texel_pair(c: f64, n: usize) -> (usize, usize, f64) {
    let x = c * n as f64 - 0.5;
    let floor = x.floor();
    let i = (floor as i64).rem_euclid(n as i64) as usize;
    (i, (i + 1) % n, x - floor)
}
