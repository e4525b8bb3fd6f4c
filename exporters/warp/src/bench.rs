//! Timing of the warp and of the whole pipeline, for `frond-warp bench` and `frond bench`.
//!
//! [`bench_warp`] times [`Warper::remap`] (single thread; [`bench_warp_with`] per kernel) on a synthetic RGBA frame with a smooth
//! displacement field; [`write_field`] writes that same frame and field (and our output) so that
//! `exporters/warp/bench/remap.py` can time OpenCV's `cv2.remap` on identical input in the same
//! run and report how far its output is from ours. [`bench_pipeline`] measures whole frames
//! (wind, waves, warp, composite) per second.

use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use crate::compose::Animator;
use crate::layers::{LayerInput, Rgba, Scene};
use crate::params::SceneParams;
use crate::warp::{RemapKernel, Warper};

/// Result of [`bench_warp`].
#[derive(Debug, Clone, Serialize)]
pub struct WarpBench {
    /// Frame width.
    pub width: usize,
    /// Frame height.
    pub height: usize,
    /// Timed iterations.
    pub iterations: usize,
    /// Median time per frame, milliseconds.
    pub median_ms: f64,
    /// Fastest frame, milliseconds.
    pub min_ms: f64,
    /// Megapixels per second at the median.
    pub mpix_per_s: f64,
    /// Median CPU time of this thread per frame, milliseconds: on a shared machine the wall time
    /// includes time other processes held the core; this does not.
    pub median_cpu_ms: f64,
    /// Kernel that ran ([`RemapKernel::name`]).
    pub kernel: &'static str,
}

/// CPU time consumed by the calling thread, seconds.
pub fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_THREAD_CPUTIME_ID needs nothing else.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Result of [`bench_pipeline`].
#[derive(Debug, Clone, Serialize)]
pub struct PipelineBench {
    /// Frame width.
    pub width: usize,
    /// Frame height.
    pub height: usize,
    /// Frames simulated and composed.
    pub frames: usize,
    /// Frames per second.
    pub fps: f64,
}

/// A deterministic test picture.
pub fn synthetic_frame(w: usize, h: usize) -> Vec<u8> {
    let mut v = vec![0u8; w * h * 4];
    for y in 0..h {
        for x in 0..w {
            let p = (y * w + x) * 4;
            v[p] = (x * 255 / w.max(1)) as u8;
            v[p + 1] = (y * 255 / h.max(1)) as u8;
            v[p + 2] = (((x / 8) ^ (y / 8)) & 1) as u8 * 200;
            v[p + 3] = 255;
        }
    }
    v
}

/// A warper over `w x h` (16 px cells) with a smooth field of up to about 6 pixels.
pub fn synthetic_warper(w: usize, h: usize) -> Warper {
    let mut warper = Warper::new(w, h, 16, 16);
    let (cols, rows) = warper.corners();
    for cy in 0..rows {
        for cx in 0..cols {
            let (x, y) = (cx as f32 * 0.21, cy as f32 * 0.17);
            warper.set_corner(cx, cy, [5.0 * (x + 0.5 * y).sin(), 3.0 * (0.7 * x - y).cos()]);
        }
    }
    warper
}

/// Times `iterations` warps of a `w x h` RGBA frame on this thread with the best kernel.
pub fn bench_warp(w: usize, h: usize, iterations: usize) -> WarpBench {
    bench_warp_with(RemapKernel::best(), w, h, iterations)
}

/// Times `iterations` warps of a `w x h` RGBA frame on this thread with `kernel`.
pub fn bench_warp_with(kernel: RemapKernel, w: usize, h: usize, iterations: usize) -> WarpBench {
    let src = synthetic_frame(w, h);
    let mut dst = vec![0u8; src.len()];
    let warper = synthetic_warper(w, h);
    warper.remap_with(kernel, &src, &mut dst); // warm-up
    let (mut times, mut cpu): (Vec<f64>, Vec<f64>) = (0..iterations.max(1))
        .map(|_| {
            let (t, c) = (Instant::now(), thread_cpu_s());
            warper.remap_with(kernel, &src, &mut dst);
            (t.elapsed().as_secs_f64() * 1e3, (thread_cpu_s() - c) * 1e3)
        })
        .unzip();
    times.sort_by(f64::total_cmp);
    cpu.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    WarpBench {
        width: w,
        height: h,
        iterations: times.len(),
        median_ms: median,
        min_ms: times[0],
        mpix_per_s: (w * h) as f64 / 1e6 / (median / 1e3),
        median_cpu_ms: cpu[cpu.len() / 2],
        kernel: if kernel.is_available() { kernel.name() } else { RemapKernel::Scalar.name() },
    }
}

/// Frames per second of the whole pipeline on a synthetic scene (one layer over the lower two
/// thirds, default parameters, steady wind).
pub fn bench_pipeline(w: usize, h: usize, frames: usize) -> PipelineBench {
    let pic = Rgba { width: w, height: h, data: synthetic_frame(w, h) };
    let mask: Vec<u8> = (0..w * h).map(|p| if p / w >= h / 3 { 255 } else { 0 }).collect();
    let scene = Scene::build(pic, vec![("bench".into(), LayerInput::Mask(mask))], None, None).expect("scene");
    let mut p = SceneParams::default();
    p.wind.strength = 0.8;
    let mut a = Animator::new(scene, p).expect("params");
    a.step(1.0 / 30.0);
    let t = Instant::now();
    for _ in 0..frames.max(1) {
        a.step(1.0 / 30.0);
    }
    PipelineBench {
        width: w,
        height: h,
        frames: frames.max(1),
        fps: frames.max(1) as f64 / t.elapsed().as_secs_f64(),
    }
}

/// Writes `src.rgba`, `map_x.f32`, `map_y.f32` (little-endian float32, row-major, pixels),
/// `ours.rgba` and `meta.json` for `remap.py`.
pub fn write_field(dir: &Path, w: usize, h: usize) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let src = synthetic_frame(w, h);
    let warper = synthetic_warper(w, h);
    let mut ours = vec![0u8; src.len()];
    warper.remap(&src, &mut ours);
    let (mx, my) = warper.source_maps();
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    std::fs::write(dir.join("src.rgba"), &src)?;
    std::fs::write(dir.join("ours.rgba"), &ours)?;
    std::fs::write(dir.join("map_x.f32"), f32s(&mx))?;
    std::fs::write(dir.join("map_y.f32"), f32s(&my))?;
    std::fs::write(dir.join("meta.json"), serde_json::json!({ "width": w, "height": h }).to_string())?;
    Ok(())
}

/// Result of [`bench_cage`]: one morph frame of seed 004 against the plain seed-001 remap.
#[derive(Debug, Clone, Serialize)]
pub struct CageBench {
    /// Frame width.
    pub width: usize,
    /// Frame height.
    pub height: usize,
    /// Cages in the tree, and vertices per cage.
    pub cages: usize,
    /// Vertices per cage.
    pub vertices: usize,
    /// Timed frames.
    pub iterations: usize,
    /// Median cage tree update (MVC propagation, Eq. 1, adaptation), milliseconds.
    pub tree_update_ms: f64,
    /// Median displacement field from the cages (grid corners by MVC), milliseconds.
    pub field_ms: f64,
    /// Median fade and region, milliseconds.
    pub layer_ms: f64,
    /// Median warp of the layer over the background, milliseconds.
    pub warp_ms: f64,
    /// Median whole morph frame (the four above), milliseconds.
    pub frame_ms: f64,
    /// Median plain seed-001 remap of the same frame size in the same run, milliseconds.
    pub remap_ms: f64,
}

/// Times morph frames of a synthetic `w x h` plant (three overlapping discs, its default cage
/// tree: 13 cages of 64 vertices) towards an ellipse, interleaved with the plain remap.
pub fn bench_cage(w: usize, h: usize, iterations: usize) -> CageBench {
    use frond_cage::morph::{MorphOptions, MorphPlan};
    use frond_cage::sketch::Sketch;
    let (fw, fh) = (w as f64, h as f64);
    let discs = [
        (0.42 * fw, 0.55 * fh, 0.28 * fh),
        (0.55 * fw, 0.42 * fh, 0.24 * fh),
        (0.52 * fw, 0.7 * fh, 0.2 * fh),
    ];
    let mask: Vec<u8> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
            if discs.iter().any(|&(cx, cy, r)| (x - cx).hypot(y - cy) < r) { 255 } else { 0 }
        })
        .collect();
    let tree =
        frond_cage::build_cage_tree(&mask, w, h, &frond_cage::BuildOptions::default()).expect("a tree");
    let pic = Rgba { width: w, height: h, data: synthetic_frame(w, h) };
    let scene = Scene::build(pic, vec![("bench".into(), LayerInput::Mask(mask))], None, None).expect("scene");
    let ellipse: Vec<[f64; 2]> = (0..256)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / 256.0;
            [0.5 * fw + 0.3 * fw * a.cos(), 0.55 * fh + 0.3 * fh * a.sin()]
        })
        .collect();
    let sketch = Sketch { closed: true, points: ellipse };
    let (cages, vertices) = (tree.cages.len(), tree.cages[0].vertices.len());
    let plan = MorphPlan::new(tree, &sketch, MorphOptions::default());
    let mut frames = crate::morph_frames::MorphFrames::new(&scene, &plan);
    let mut frame = scene.background.clone();
    let src = synthetic_frame(w, h);
    let mut dst = vec![0u8; src.len()];
    let plain = synthetic_warper(w, h);
    let n = iterations.max(1);
    let mut times = vec![[0.0f64; 5]; n];
    let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
    for (k, row) in times.iter_mut().enumerate() {
        let t = (k + 1) as f64 / (n + 1) as f64;
        let t0 = Instant::now();
        frames.update_cages(t);
        row[0] = ms(t0);
        let t0 = Instant::now();
        frames.update_layer(t);
        row[2] = ms(t0);
        let t0 = Instant::now();
        frames.update_field();
        row[1] = ms(t0);
        let t0 = Instant::now();
        frame.copy_from_slice(&scene.background);
        frames.warp_over(&mut frame);
        row[3] = ms(t0);
        let t0 = Instant::now();
        plain.remap(&src, &mut dst);
        row[4] = ms(t0);
    }
    let median = |i: usize| {
        let mut v: Vec<f64> = times.iter().map(|r| r[i]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mut whole: Vec<f64> = times.iter().map(|r| r[0] + r[1] + r[2] + r[3]).collect();
    whole.sort_by(f64::total_cmp);
    CageBench {
        width: w,
        height: h,
        cages,
        vertices,
        iterations: n,
        tree_update_ms: median(0),
        field_ms: median(1),
        layer_ms: median(2),
        warp_ms: median(3),
        frame_ms: whole[whole.len() / 2],
        remap_ms: median(4),
    }
}
