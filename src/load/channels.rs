//! Which image channels a sequence carries: the files' grey values or colours, as `--channels`
//! chooses ([`Channels`]).
//!
//! Readers keep what the file stores ([`VertexValues`]): a grey value per vertex (a PLY scalar
//! property), an RGB colour (vertex colours, a texture sampled at the vertices), or any number of
//! channels (an `(K, V, C)` array). [`select_channels`] then makes the sequence's
//! [`Images`]:
//!
//! | `--channels` | grey input | colour input | `C` channels |
//! |---|---|---|---|
//! | `auto` (default) | 1 channel | 3 (R, G, B); 1 if every colour is grey (`r = g = b`) | all `C` |
//! | `rgb` | error | 3 | `C = 3` only |
//! | `luma` | 1 channel | Rec. 709 luma ([`grey_value`]) | `C = 3` only |
//! | `grey` | 1 channel | mean `(r + g + b)/3` | mean of the `C` |
//!
//! Colours are taken as stored (no gamma decoding): brightness constancy needs a consistent
//! scale per channel, not a perceptual one.

use crate::flow::Images;
use crate::format::{grey_value, VertexValues};
use crate::statistics::channel_mean;

/// The image channels a sequence is made of (`--channels`; see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Channels {
    /// Every channel the input has; colours that are all grey count as one.
    #[default]
    Auto,
    /// The three colour channels.
    Rgb,
    /// Rec. 709 luma of the colours.
    Luma,
    /// The unweighted mean of the channels.
    Grey,
}

impl std::str::FromStr for Channels {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Channels::Auto),
            "rgb" => Ok(Channels::Rgb),
            "luma" => Ok(Channels::Luma),
            "grey" | "gray" => Ok(Channels::Grey),
            other => Err(format!("'{other}' is not one of: auto, rgb, luma, grey")),
        }
    }
}

/// The sequence's images from the frames' values by `choice`, or why not (a sentence naming the
/// frame). Frames must agree in kind: a mix of grey and colour frames is read as colour (grey
/// `g` as `(g, g, g)`); frames of `C` channels must all have `C`.
pub fn select_channels(frames: Vec<VertexValues>, choice: Channels) -> Result<Images, String> {
    let colour = frames.iter().any(|f| matches!(f, VertexValues::Colors(_)));
    let arrays = frames
        .iter()
        .position(|f| matches!(f, VertexValues::Channels(_)));
    if let (true, Some(k)) = (colour, arrays) {
        return Err(format!(
            "frame {k} has a channel array while other frames have colours"
        ));
    }
    let frames: Vec<VertexValues> = match colour {
        true => frames.into_iter().map(as_colors).collect(),
        false => frames,
    };
    let n_channels = frames[0].n_channels();
    if let Some(k) = frames.iter().position(|f| f.n_channels() != n_channels) {
        let got = frames[k].n_channels();
        return Err(format!(
            "frame {k} has {got} image channels, frame 0 has {n_channels}"
        ));
    }
    let all_grey_colours = colour
        && frames.iter().all(|f| match f {
            VertexValues::Colors(c) => c.iter().all(|&[r, g, b]| r == g && g == b),
            _ => true,
        });
    let needs_three = |option: &str| {
        match n_channels {
        3 => Ok(()),
        1 => Err(format!(
            "--channels {option} needs colours (vertex colours, a texture or a (frames, vertices, 3) array); this input has grey values only"
        )),
        c => Err(format!(
            "--channels {option} needs 3 colour channels; this input has {c} (use --channels auto or grey)"
        )),
    }
    };
    let channels: Vec<Vec<Vec<f64>>> = frames
        .into_iter()
        .map(VertexValues::into_channels)
        .collect();
    match choice {
        Channels::Auto if all_grey_colours => Ok(first_channel(channels)),
        Channels::Auto => Ok(Images::from_channels(channels)),
        Channels::Rgb => needs_three("rgb").map(|()| Images::from_channels(channels)),
        Channels::Luma if n_channels == 1 => Ok(first_channel(channels)),
        Channels::Luma => needs_three("luma")
            .map(|()| Images::grey(channels.iter().map(|c| luma_of_channels(c)).collect())),
        Channels::Grey => Ok(Images::grey(
            channels.iter().map(|c| channel_mean(c)).collect(),
        )),
    }
}

/// Grey frames as colours `(g, g, g)`, so that they mix with coloured ones.
fn as_colors(values: VertexValues) -> VertexValues {
    match values {
        VertexValues::Grey(v) => VertexValues::Colors(v.into_iter().map(|g| [g; 3]).collect()),
        other => other,
    }
}

fn first_channel(frames: Vec<Vec<Vec<f64>>>) -> Images {
    Images::grey(frames.into_iter().map(|mut c| c.swap_remove(0)).collect())
}

fn luma_of_channels(channels: &[Vec<f64>]) -> Vec<f64> {
    (0..channels[0].len())
        .map(|i| grey_value([channels[0][i], channels[1][i], channels[2][i]]))
        .collect()
}
