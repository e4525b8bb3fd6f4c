//! Vegetation layers over a background (seed 001, section III-B).
//!
//! A scene is one picture, any number of vegetation layers and a background, all of one size:
//!
//! - a layer given as a **mask** (a greyscale or colour image without alpha; its luminance is the
//!   matte) cuts its vegetation out of the picture: the layer's colour is the picture, its alpha
//!   the mask;
//! - a layer given as an **RGBA image** (colour with an alpha channel) is its own vegetation;
//! - the background is `--background` when given; otherwise the picture, with the area fully
//!   covered by mask layers (mask 255) [`inpaint`](crate::inpaint)ed. Partly covered pixels keep the
//!   picture's colour, so a still scene reproduces the picture byte for byte.
//!
//! Each layer may only draw inside its region: the pixels its alpha covers, grown by its
//! `sway_margin_px`. With a margin of 0, pixels outside every layer never change.

use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::inpaint::inpaint;

/// Largest image file read (picture, layer, background, scale map), bytes: checked before
/// reading, as for every file frond opens (`frond_formats::rig_files`).
pub const MAX_IMAGE_FILE_BYTES: u64 = 256 << 20;
/// Largest decoded image side, pixels (a 16384 x 16384 RGBA picture is 1 GiB).
pub const MAX_IMAGE_SIDE_PX: u32 = 16_384;

/// An 8-bit RGBA image, straight alpha, row-major.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rgba {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height * 4` bytes.
    pub data: Vec<u8>,
}

impl Rgba {
    /// A filled image.
    pub fn filled(width: usize, height: usize, px: [u8; 4]) -> Rgba {
        Rgba { width, height, data: px.iter().copied().cycle().take(width * height * 4).collect() }
    }
}

/// What a `--layer` file holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LayerInput {
    /// A matte (one byte per pixel, 255 = vegetation) cutting the layer out of the picture.
    Mask(Vec<u8>),
    /// A vegetation image with its own alpha.
    Rgba(Rgba),
}

/// Errors building a scene.
#[derive(Debug, Error)]
pub enum SceneError {
    /// A file could not be read or decoded.
    #[error("cannot read {what} {path}: {source}")]
    Read {
        /// Which input (`image`, `layer`, `background`, `scale map`).
        what: &'static str,
        /// The file.
        path: PathBuf,
        /// Why.
        source: image::ImageError,
    },
    /// A file is not a regular file, or is larger than [`MAX_IMAGE_FILE_BYTES`].
    #[error("cannot read {what} {}: {}", .error.path().display(), .error.reason())]
    File {
        /// Which input.
        what: &'static str,
        /// Why.
        error: frond_formats::rig_files::FileError,
    },
    /// No vegetation layer was given: every frame would be the picture itself.
    #[error(
        "nothing in the picture is marked as vegetation: give at least one --layer (a greyscale mask \
         of the plants, or an RGBA image of them with alpha); without one every frame would be the \
         picture itself"
    )]
    NoLayers,
    /// An input has another size than the picture.
    #[error(
        "{what} {name} is {got_w}x{got_h} but the picture is {want_w}x{want_h}; every input must have the picture's size"
    )]
    SizeMismatch {
        /// Which input.
        what: &'static str,
        /// Its name (file path or index).
        name: String,
        /// Its width.
        got_w: usize,
        /// Its height.
        got_h: usize,
        /// The picture's width.
        want_w: usize,
        /// The picture's height.
        want_h: usize,
    },
    /// A layer covers no pixel.
    #[error("layer {name} is empty: its mask/alpha is zero everywhere")]
    EmptyLayer {
        /// The layer's name.
        name: String,
    },
    /// The picture has no pixel.
    #[error("the picture is empty (0 pixels)")]
    EmptyPicture,
}

/// One vegetation layer, ready to animate.
#[derive(Debug, Clone)]
pub struct Layer {
    /// Name (file path or index) for messages.
    pub name: String,
    /// Straight-alpha RGBA pixels of the vegetation.
    pub pixels: Vec<u8>,
    /// Alpha > 0, one byte per pixel (before growing by the sway margin).
    pub coverage: Vec<u8>,
    /// First row with coverage (top of the layer, for Eq. 6).
    pub top: usize,
    /// Last row with coverage (bottom of the layer, for Eq. 6).
    pub bottom: usize,
}

impl Layer {
    /// The region the layer may draw in: its coverage grown by `margin` pixels (square).
    pub fn region(&self, width: usize, height: usize, margin: usize) -> Vec<u8> {
        dilate(&self.coverage, width, height, margin)
    }
}

/// Picture, layers, background and optional scale map of one animation.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Opaque RGBA background.
    pub background: Vec<u8>,
    /// Vegetation layers, back to front.
    pub layers: Vec<Layer>,
    /// |lambda| per pixel in [0, 1] (seed 001, Fig. 4), or none.
    pub scale_map: Option<Vec<f32>>,
}

impl Scene {
    /// Builds a scene from decoded inputs; see the module docs for the rules.
    pub fn build(
        picture: Rgba,
        layers: Vec<(String, LayerInput)>,
        background: Option<Rgba>,
        scale_map: Option<(String, Vec<u8>, usize, usize)>,
    ) -> Result<Scene, SceneError> {
        let (w, h) = (picture.width, picture.height);
        if w == 0 || h == 0 {
            return Err(SceneError::EmptyPicture);
        }
        let mismatch = |what, name: &str, gw, gh| SceneError::SizeMismatch {
            what,
            name: name.to_string(),
            got_w: gw,
            got_h: gh,
            want_w: w,
            want_h: h,
        };
        let mut hole = vec![false; w * h];
        let mut built = Vec::new();
        for (name, input) in layers {
            let pixels = match input {
                LayerInput::Mask(mask) => {
                    if mask.len() != w * h {
                        return Err(mismatch("layer mask", &name, mask.len() / h.max(1), h));
                    }
                    let mut px = picture.data.clone();
                    for (p, &m) in mask.iter().enumerate() {
                        px[p * 4 + 3] = m;
                        if m == 255 {
                            hole[p] = true;
                        }
                    }
                    px
                }
                LayerInput::Rgba(img) => {
                    if (img.width, img.height) != (w, h) {
                        return Err(mismatch("layer image", &name, img.width, img.height));
                    }
                    img.data
                }
            };
            let coverage: Vec<u8> = pixels.chunks_exact(4).map(|p| u8::from(p[3] > 0)).collect();
            let rows = (0..h).filter(|&y| coverage[y * w..(y + 1) * w].iter().any(|&c| c != 0));
            let (mut top, mut bottom) = (usize::MAX, 0);
            for y in rows {
                top = top.min(y);
                bottom = bottom.max(y);
            }
            if top == usize::MAX {
                return Err(SceneError::EmptyLayer { name });
            }
            built.push(Layer { name, pixels, coverage, top, bottom });
        }
        let mut background = match background {
            Some(bg) => {
                if (bg.width, bg.height) != (w, h) {
                    return Err(mismatch("background", "", bg.width, bg.height));
                }
                bg.data
            }
            None => {
                let mut bg = picture.data.clone();
                inpaint(&mut bg, w, h, &hole);
                bg
            }
        };
        for p in background.chunks_exact_mut(4) {
            p[3] = 255;
        }
        let scale_map = match scale_map {
            Some((name, grey, sw, sh)) => {
                if (sw, sh) != (w, h) {
                    return Err(mismatch("scale map", &name, sw, sh));
                }
                Some(grey.iter().map(|&g| g as f32 / 255.0).collect())
            }
            None => None,
        };
        Ok(Scene { width: w, height: h, background, layers: built, scale_map })
    }

    /// Reads the files and builds the scene (see [`Scene::build`]).
    pub fn load(
        picture: &Path,
        layers: &[PathBuf],
        background: Option<&Path>,
        scale_map: Option<&Path>,
    ) -> Result<Scene, SceneError> {
        if layers.is_empty() {
            return Err(SceneError::NoLayers);
        }
        let pic = read_rgba("image", picture)?;
        let mut inputs = Vec::new();
        for path in layers {
            let img = read_image("layer", path)?;
            let input = if img.color().has_alpha() && img.color().has_color() {
                let rgba = img.to_rgba8();
                LayerInput::Rgba(Rgba {
                    width: rgba.width() as usize,
                    height: rgba.height() as usize,
                    data: rgba.into_raw(),
                })
            } else {
                let l = img.to_luma8();
                if (l.width() as usize, l.height() as usize) != (pic.width, pic.height) {
                    return Err(SceneError::SizeMismatch {
                        what: "layer mask",
                        name: path.display().to_string(),
                        got_w: l.width() as usize,
                        got_h: l.height() as usize,
                        want_w: pic.width,
                        want_h: pic.height,
                    });
                }
                LayerInput::Mask(l.into_raw())
            };
            inputs.push((path.display().to_string(), input));
        }
        let bg = background.map(|p| read_rgba("background", p)).transpose()?;
        let sm = match scale_map {
            Some(p) => {
                let img = read_image("scale map", p)?;
                let l = img.to_luma8();
                let (sw, sh) = (l.width() as usize, l.height() as usize);
                Some((p.display().to_string(), l.into_raw(), sw, sh))
            }
            None => None,
        };
        Scene::build(pic, inputs, bg, sm)
    }

    /// The still composite (every layer unwarped over the background).
    pub fn still(&self) -> Vec<u8> {
        let mut frame = self.background.clone();
        let warper = crate::warp::Warper::new(self.width, self.height, 16, 16);
        for layer in &self.layers {
            warper.warp_over(&layer.pixels, &layer.coverage, &mut frame);
        }
        frame
    }
}

/// Reads and decodes an image file: a regular file of at most [`MAX_IMAGE_FILE_BYTES`] (a FIFO or
/// a device is refused without blocking), sides of at most [`MAX_IMAGE_SIDE_PX`].
pub fn read_image(what: &'static str, path: &Path) -> Result<image::DynamicImage, SceneError> {
    let bytes = frond_formats::rig_files::read_small_file(path, MAX_IMAGE_FILE_BYTES)
        .map_err(|error| SceneError::File { what, error })?;
    let read_err = |source| SceneError::Read { what, path: path.to_path_buf(), source };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| read_err(image::ImageError::IoError(e)))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE_PX);
    limits.max_image_height = Some(MAX_IMAGE_SIDE_PX);
    reader.limits(limits);
    reader.decode().map_err(read_err)
}

/// Reads an image file as RGBA (see [`read_image`]).
pub fn read_rgba(what: &'static str, path: &Path) -> Result<Rgba, SceneError> {
    let rgba = read_image(what, path)?.to_rgba8();
    Ok(Rgba { width: rgba.width() as usize, height: rgba.height() as usize, data: rgba.into_raw() })
}

/// Square dilation of a 0/1 map by `r` pixels (separable running max).
fn dilate(map: &[u8], w: usize, h: usize, r: usize) -> Vec<u8> {
    if r == 0 {
        return map.to_vec();
    }
    let mut tmp = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            let lo = x.saturating_sub(r);
            let hi = (x + r).min(w - 1);
            tmp[y * w + x] = map[y * w + lo..=y * w + hi].iter().copied().max().unwrap_or(0);
        }
    }
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        let lo = y.saturating_sub(r);
        let hi = (y + r).min(h - 1);
        for x in 0..w {
            out[y * w + x] = (lo..=hi).map(|yy| tmp[yy * w + x]).max().unwrap_or(0);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mask_layer_takes_picture_colours_and_inpaints_only_full_coverage() {
        let pic = Rgba::filled(8, 6, [10, 20, 30, 255]);
        let mut mask = vec![0u8; 48];
        mask[2 * 8 + 3] = 255;
        mask[2 * 8 + 4] = 100;
        let scene =
            Scene::build(pic.clone(), vec![("m".into(), LayerInput::Mask(mask))], None, None).unwrap();
        let l = &scene.layers[0];
        assert_eq!((l.top, l.bottom), (2, 2));
        assert_eq!(&l.pixels[(2 * 8 + 4) * 4..(2 * 8 + 4) * 4 + 4], &[10, 20, 30, 100]);
        assert_eq!(scene.still(), pic.data);
    }

    #[test]
    fn size_mismatch_and_empty_layers_are_errors() {
        let pic = Rgba::filled(8, 6, [0, 0, 0, 255]);
        let err =
            Scene::build(pic.clone(), vec![("m.png".into(), LayerInput::Mask(vec![255; 40]))], None, None)
                .unwrap_err();
        assert!(err.to_string().contains("m.png"), "{err}");
        let err = Scene::build(pic.clone(), vec![("z".into(), LayerInput::Mask(vec![0; 48]))], None, None)
            .unwrap_err();
        assert!(matches!(err, SceneError::EmptyLayer { .. }), "{err}");
        let err = Scene::build(pic, vec![], Some(Rgba::filled(7, 6, [0, 0, 0, 255])), None)
            .unwrap_err()
            .to_string();
        assert!(err.contains("7x6") && err.contains("8x6"), "{err}");
    }

    #[test]
    fn dilation_grows_by_the_margin() {
        let mut m = vec![0u8; 7 * 7];
        m[3 * 7 + 3] = 1;
        let d = dilate(&m, 7, 7, 2);
        assert_eq!(d.iter().filter(|&&v| v == 1).count(), 25);
        assert_eq!(d[7 + 1], 1);
        assert_eq!(d[0], 0);
    }
}
