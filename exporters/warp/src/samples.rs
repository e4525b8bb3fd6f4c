//! Procedurally drawn sample assets (`frond-warp make-samples DIR`): the pictures in
//! `rig-files/images/` are generated here, so the project owns every pixel.
//!
//! - `grass.png` + `grass-mask.png` (+ `grass-scale.png`): a meadow under a sky; the mask covers
//!   the field up to above the tallest blade (the smooth sky inside it moves invisibly), the scale
//!   map fades the motion towards the far (upper) part of the field.
//! - `shrub-background.png` + `shrub.png`: a fence and a path, and a shrub with its own alpha.

use std::path::Path;

use crate::layers::Rgba;

/// Width of the samples.
pub const SAMPLE_W: usize = 320;
/// Height of the samples.
pub const SAMPLE_H: usize = 240;

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn f(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f()
    }
}

fn sky(img: &mut Rgba, horizon: usize) {
    for y in 0..img.height {
        let t = (y as f32 / horizon.max(1) as f32).min(1.0);
        let c = [(110.0 + 90.0 * t) as u8, (170.0 + 60.0 * t) as u8, (235.0 - 10.0 * t) as u8, 255];
        for x in 0..img.width {
            let p = (y * img.width + x) * 4;
            img.data[p..p + 4].copy_from_slice(&c);
        }
    }
}

/// Blends `c` with coverage `a` (0..1) at `(x, y)`.
fn plot(img: &mut Rgba, x: i32, y: i32, c: [u8; 3], a: f32) {
    if x < 0 || y < 0 || x >= img.width as i32 || y >= img.height as i32 {
        return;
    }
    let p = (y as usize * img.width + x as usize) * 4;
    for (d, &s) in img.data[p..p + 3].iter_mut().zip(&c) {
        *d = (*d as f32 * (1.0 - a) + s as f32 * a).round() as u8;
    }
    img.data[p + 3] = img.data[p + 3].max((a * 255.0).round() as u8);
}

/// A tapering blade from `(x0, y0)` leaning by `lean` pixels at height `len`.
fn blade(img: &mut Rgba, mask: &mut [u8], x0: f32, y0: f32, len: f32, lean: f32, c: [u8; 3]) {
    let steps = (len * 2.0) as usize;
    for s in 0..=steps {
        let t = s as f32 / steps as f32;
        let x = x0 + lean * t * t;
        let y = y0 - len * t;
        let half = 1.6 * (1.0 - t) + 0.3;
        let shade = 0.75 + 0.35 * t;
        let col = c.map(|v| (v as f32 * shade).min(255.0) as u8);
        let xi = x.floor() as i32;
        for dx in -2..=2 {
            let d = ((xi + dx) as f32 + 0.5 - x).abs();
            let a = (half + 0.5 - d).clamp(0.0, 1.0);
            if a > 0.0 {
                plot(img, xi + dx, y as i32, col, a);
                let (px, py) = (xi + dx, y as i32);
                if px >= 0 && py >= 0 && (px as usize) < img.width && (py as usize) < img.height {
                    let m = &mut mask[py as usize * img.width + px as usize];
                    *m = (*m).max((a * 255.0) as u8);
                }
            }
        }
    }
}

/// The grass picture, its mask and its scale map (greyscale bytes).
pub fn grass() -> (Rgba, Vec<u8>, Vec<u8>) {
    let (w, h) = (SAMPLE_W, SAMPLE_H);
    let mut img = Rgba::filled(w, h, [0, 0, 0, 255]);
    let ground = 110;
    sky(&mut img, ground);
    // Soil under the blades.
    for y in ground..h {
        for x in 0..w {
            let p = (y * w + x) * 4;
            let t = (y - ground) as f32 / (h - ground) as f32;
            img.data[p..p + 3].copy_from_slice(&[(70.0 + 30.0 * t) as u8, (110.0 + 20.0 * t) as u8, 40]);
        }
    }
    let mut blades = vec![0u8; w * h];
    let mut rng = Rng(0xF00D);
    // Back to front: far blades short and pale, near ones long and saturated.
    for row in 0..26 {
        let base_y = ground as f32 + 8.0 + row as f32 * 4.8;
        let depth = row as f32 / 25.0;
        for _ in 0..70 {
            let x = rng.range(-10.0, w as f32 + 10.0);
            let len = rng.range(18.0, 34.0) * (0.6 + 0.9 * depth);
            let lean = rng.range(-9.0, 9.0);
            let g = rng.range(0.0, 1.0);
            let c =
                [(40.0 + 60.0 * g) as u8, (120.0 + 80.0 * g + 20.0 * depth) as u8, (30.0 + 30.0 * g) as u8];
            blade(&mut img, &mut blades, x, base_y + rng.range(-2.0, 2.0), len, lean, c);
        }
    }
    // Mask: everything below the highest blade tip in each column band, plus a few pixels.
    let mut top = h;
    for y in 0..h {
        if blades[y * w..(y + 1) * w].iter().any(|&m| m > 0) {
            top = y;
            break;
        }
    }
    let edge = top.saturating_sub(4);
    let mask: Vec<u8> = (0..w * h).map(|p| if p / w >= edge { 255 } else { 0 }).collect();
    let scale: Vec<u8> = (0..w * h)
        .map(|p| {
            let y = p / w;
            let t = (y.saturating_sub(edge)) as f32 / (h - edge) as f32;
            (80.0 + 175.0 * t).min(255.0) as u8
        })
        .collect();
    (img, mask, scale)
}

/// The shrub's background and the shrub (RGBA with alpha).
pub fn shrub() -> (Rgba, Rgba) {
    let (w, h) = (SAMPLE_W, SAMPLE_H);
    let mut bg = Rgba::filled(w, h, [0, 0, 0, 255]);
    let ground = 170;
    sky(&mut bg, ground);
    for y in ground..h {
        for x in 0..w {
            let p = (y * w + x) * 4;
            let path = ((x as f32 - 160.0).abs() < 20.0 + (y - ground) as f32 * 0.9) as u8 as f32;
            let c = [(90.0 + 80.0 * path) as u8, (140.0 + 30.0 * path) as u8, (60.0 + 60.0 * path) as u8];
            bg.data[p..p + 3].copy_from_slice(&c);
        }
    }
    // A fence: posts and two rails.
    for post in 0..9 {
        let x0 = 8 + post * 38;
        for y in 120..ground + 6 {
            for x in x0..(x0 + 6).min(w) {
                plot(&mut bg, x as i32, y as i32, [150, 110, 70], 1.0);
            }
        }
    }
    for rail in [132usize, 152] {
        for y in rail..rail + 5 {
            for x in 0..w {
                plot(&mut bg, x as i32, y as i32, [170, 128, 84], 1.0);
            }
        }
    }
    let mut shrub = Rgba::filled(w, h, [0, 0, 0, 0]);
    let mut rng = Rng(0x5EED);
    let (cx, cy) = (170.0f32, 130.0f32);
    for _ in 0..900 {
        let ang = rng.range(0.0, std::f32::consts::TAU);
        let rad = rng.f().sqrt();
        let x = cx + ang.cos() * rad * 95.0;
        let y = cy + ang.sin() * rad * 55.0;
        if y > ground as f32 + 8.0 {
            continue;
        }
        let r = rng.range(3.0, 7.0);
        let shade = 0.55 + 0.45 * (1.0 - (y - (cy - 55.0)) / 130.0) + rng.range(-0.1, 0.1);
        let c =
            [(50.0 * shade) as u8, ((110.0 + 60.0 * rng.f()) * shade).min(255.0) as u8, (40.0 * shade) as u8];
        for dy in -8..=8 {
            for dx in -8..=8 {
                let d = ((dx * dx + dy * dy) as f32).sqrt();
                let a = (r - d + 0.5).clamp(0.0, 1.0);
                if a > 0.0 {
                    plot(&mut shrub, x as i32 + dx, y as i32 + dy, c, a);
                }
            }
        }
    }
    (bg, shrub)
}

/// Writes every sample into `dir` (created if needed); returns the file names.
pub fn write_samples(dir: &Path) -> Result<Vec<String>, image::ImageError> {
    std::fs::create_dir_all(dir).map_err(image::ImageError::IoError)?;
    let (w, h) = (SAMPLE_W as u32, SAMPLE_H as u32);
    let (g, gm, gs) = grass();
    let (bg, sh) = shrub();
    let rgba =
        |name: &str, img: Rgba| image::save_buffer(dir.join(name), &img.data, w, h, image::ColorType::Rgba8);
    let rgb = |name: &str, img: &Rgba| {
        let data: Vec<u8> = img.data.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        image::save_buffer(dir.join(name), &data, w, h, image::ColorType::Rgb8)
    };
    let grey = |name: &str, data: &[u8]| image::save_buffer(dir.join(name), data, w, h, image::ColorType::L8);
    rgb("grass.png", &g)?;
    grey("grass-mask.png", &gm)?;
    grey("grass-scale.png", &gs)?;
    rgb("shrub-background.png", &bg)?;
    rgba("shrub.png", sh)?;
    Ok(["grass.png", "grass-mask.png", "grass-scale.png", "shrub-background.png", "shrub.png"]
        .map(String::from)
        .to_vec())
}
