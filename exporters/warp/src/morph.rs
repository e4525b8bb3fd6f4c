//! `frond-warp morph`: a layer of a picture morphed towards a sketch by its cage tree (seed 004,
//! section 5), the pixels moved by the seed-001 remap with a displacement field from the cages.
//!
//! Per frame (in-between `t = k / (frames - 1)`): the plan's cages at `t`
//! ([`frond_cage::morph::MorphPlan::cages_at`]); every grid corner's source point by the leaf cage
//! holding it ([`frond_cage::morph::MorphPlan::inverse_map`]); the layer warped over the
//! background, only inside the deformed crowns (grown by the layer's own slack beyond its rest
//! crowns, so a still morph is the picture byte for byte); pruned lobes fade out with `t`.
//! The quality report (section 6.2) is the discrete Frechet distance of each frame's layer outline
//! (traced from the warped alpha) to the reference: the rest crown outline linearly interpolated
//! towards the target.

use std::path::{Path, PathBuf};

use frond_cage::contour::{Bitmap, label_parts, trace_outer};
use frond_cage::morph::{MorphOptions, MorphPlan};
use frond_cage::outline::{frechet_closed, resample_closed, start_nearest};
use frond_cage::raster::fill_polygon;
use frond_cage::sketch::Sketch;
use frond_cage::tree::outside_by;
use frond_cage::{BuildOptions, CageTree, Point, build_cage_tree};
use frond_motion::rig_files::read_small_text;

use crate::Scene;
use crate::cages::{CageCommandError, read_cage_file};
use crate::layers::dilate;
use crate::render::{OutputKind, Progress, Sink};
use crate::warp::Warper;

/// Largest `sketch.json` read, bytes.
pub const MAX_SKETCH_FILE_BYTES: u64 = 4 << 20;
/// Grid cell of the cage warp, pixels (the field is smooth inside a leaf cage).
pub const CAGE_CELL_PX: usize = 4;
/// Most slack a layer may have beyond its rest crowns, pixels.
const MAX_SLACK_PX: usize = 16;

/// Everything `frond-warp morph` was asked.
#[derive(Debug, Clone)]
pub struct MorphJob {
    /// The picture.
    pub image: PathBuf,
    /// The vegetation layer that morphs.
    pub layer: PathBuf,
    /// Background under it (default: the picture, inpainted under the mask).
    pub background: Option<PathBuf>,
    /// Its cage tree (default: built from the layer with the default options).
    pub cage: Option<PathBuf>,
    /// The sketch.
    pub sketch: PathBuf,
    /// Frames (>= 1; the last is the target).
    pub frames: usize,
    /// Frame rate of the animation.
    pub fps: f32,
    /// Output.
    pub output: OutputKind,
    /// Quality report file.
    pub report: Option<PathBuf>,
    /// Adaptation and pruning.
    pub opts: MorphOptions,
    /// No progress bar.
    pub quiet: bool,
}

/// What a morph did.
#[derive(Debug, Clone)]
pub struct MorphSummary {
    /// Frames written.
    pub frames: usize,
    /// The sketched crown's cage id.
    pub crown: u32,
    /// Pruned cage ids.
    pub pruned: Vec<u32>,
    /// `t` of each frame.
    pub t: Vec<f64>,
    /// Frechet distance of each frame's outline to the reference, pixels.
    pub frechet_px: Vec<f64>,
}

impl MorphSummary {
    /// The report file's JSON: `{"t":[...],"frechet_px":[...],"crown":ID,"pruned":[IDS]}`.
    pub fn report_json(&self) -> String {
        let round = |v: &[f64]| v.iter().map(|x| (x * 1e4).round() / 1e4).collect::<Vec<_>>();
        serde_json::json!({
            "t": round(&self.t),
            "frechet_px": round(&self.frechet_px),
            "crown": self.crown,
            "pruned": self.pruned,
        })
        .to_string()
    }
}

/// Reads the inputs, plans the morph and renders it.
pub fn run(job: &MorphJob) -> Result<MorphSummary, CageCommandError> {
    let scene = Scene::load(&job.image, std::slice::from_ref(&job.layer), job.background.as_deref(), None)?;
    let (w, h) = (scene.width, scene.height);
    let tree = match &job.cage {
        Some(path) => {
            let tree = read_cage_file(path)?;
            if tree.size != [w as u32, h as u32] {
                return Err(CageCommandError::Argument(format!(
                    "cage file {} is for a {}x{} picture; {} is {w}x{h}",
                    path.display(),
                    tree.size[0],
                    tree.size[1],
                    job.image.display()
                )));
            }
            tree
        }
        None => {
            let matte: Vec<u8> = scene.layers[0].pixels.chunks_exact(4).map(|p| p[3]).collect();
            build_cage_tree(&matte, w, h, &BuildOptions::default())
                .map_err(|error| CageCommandError::Build { path: job.layer.display().to_string(), error })?
        }
    };
    let sketch = read_sketch(&job.sketch, tree.size)?;
    let plan = MorphPlan::new(tree, &sketch, job.opts);
    render(&scene, &plan, job)
}

fn read_sketch(path: &Path, size: [u32; 2]) -> Result<Sketch, CageCommandError> {
    let text = read_small_text(path, MAX_SKETCH_FILE_BYTES).map_err(CageCommandError::File)?;
    Sketch::from_json(&text, size)
        .map_err(|e| CageCommandError::Argument(format!("sketch {}: {e}", path.display())))
}

fn render(scene: &Scene, plan: &MorphPlan, job: &MorphJob) -> Result<MorphSummary, CageCommandError> {
    let (w, h) = (scene.width, scene.height);
    let layer = &scene.layers[0];
    let tree = plan.tree();
    let roots: Vec<usize> = tree.roots().collect();
    let slack = layer_slack(layer.pixels.as_slice(), w, tree, &roots);
    // Pixels of pruned cages at rest: they fade with t.
    let mut pruned_px = vec![0u8; w * h];
    for (i, c) in tree.cages.iter().enumerate() {
        if plan.pruned()[i] {
            fill_polygon(&c.vertices, w, h, &mut pruned_px);
        }
    }
    let any_pruned = plan.pruned().iter().any(|&p| p);
    let mut warper = Warper::new(w, h, CAGE_CELL_PX, CAGE_CELL_PX);
    let (cols, rows) = warper.corners();
    let mut sink = Sink::open(&job.output, w, h, job.fps).map_err(render_err)?;
    let progress = Progress::new(job.frames, job.quiet);
    let crown = plan.crown();
    let n = tree.cages[crown].vertices.len();
    let mut layer_t = layer.pixels.clone();
    let mut warped = vec![0u8; w * h * 4];
    let mut weights = Vec::new();
    let mut summary = MorphSummary {
        frames: job.frames,
        crown: tree.cages[crown].id,
        pruned: (0..tree.cages.len()).filter(|&i| plan.pruned()[i]).map(|i| tree.cages[i].id).collect(),
        t: Vec::with_capacity(job.frames),
        frechet_px: Vec::with_capacity(job.frames),
    };
    for k in 0..job.frames {
        let t = if job.frames > 1 { k as f64 / (job.frames - 1) as f64 } else { 1.0 };
        let now = plan.cages_at(t);
        for cy in 0..rows {
            for cx in 0..cols {
                let p = [(cx * CAGE_CELL_PX) as f64 + 0.5, (cy * CAGE_CELL_PX) as f64 + 0.5];
                let src = plan.inverse_map(&now, p, &mut weights);
                warper.set_corner(cx, cy, [(src[0] - p[0]) as f32, (src[1] - p[1]) as f32]);
            }
        }
        if any_pruned {
            let keep = 1.0 - t;
            for (px, (out, &pr)) in
                layer.pixels.chunks_exact(4).zip(layer_t.chunks_exact_mut(4).zip(&pruned_px))
            {
                out[3] = if pr != 0 { (px[3] as f64 * keep).round() as u8 } else { px[3] };
            }
        }
        let mut region = vec![0u8; w * h];
        for &r in &roots {
            fill_polygon(&now[r], w, h, &mut region);
        }
        let region = dilate(&region, w, h, slack);
        let mut frame = scene.background.clone();
        warper.warp_over(&layer_t, &region, &mut frame);
        sink.push(k, &frame).map_err(render_err)?;
        // Section 6.2: this frame's outline against the reference in-between.
        warper.remap(&layer_t, &mut warped);
        let reference: Vec<Point> = tree.cages[crown]
            .vertices
            .iter()
            .zip(plan.target())
            .map(|(a, b)| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])
            .collect();
        summary.t.push(t);
        summary.frechet_px.push(outline_distance(&warped, &region, w, h, &reference, n));
        progress.tick(k + 1);
    }
    sink.finish().map_err(render_err)?;
    Ok(summary)
}

/// How far the layer's vegetation reaches outside its rest crowns (whole pixels, at least 1).
fn layer_slack(pixels: &[u8], w: usize, tree: &CageTree, roots: &[usize]) -> usize {
    let mut worst = 0.0f64;
    for (i, px) in pixels.chunks_exact(4).enumerate() {
        if px[3] == 0 {
            continue;
        }
        let p = [(i % w) as f64 + 0.5, (i / w) as f64 + 0.5];
        let d = roots.iter().map(|&r| outside_by(&tree.cages[r].vertices, p)).fold(f64::INFINITY, f64::min);
        worst = worst.max(d);
    }
    (worst.ceil() as usize + 1).min(MAX_SLACK_PX)
}

/// Frechet distance between the outline of the warped layer's largest part (alpha >= 128 inside
/// the region) and `reference`, both resampled to `n` vertices from the points nearest each other.
fn outline_distance(warped: &[u8], region: &[u8], w: usize, h: usize, reference: &[Point], n: usize) -> f64 {
    let bits: Vec<bool> = warped.chunks_exact(4).zip(region).map(|(p, &r)| r != 0 && p[3] >= 128).collect();
    let map = Bitmap { width: w, height: h, bits };
    let (labels, sizes) = label_parts(&map);
    let Some(best) = (0..sizes.len()).max_by_key(|&l| sizes[l]) else {
        return f64::INFINITY;
    };
    let part = Bitmap { width: w, height: h, bits: labels.iter().map(|&l| l == best as u32).collect() };
    let Some(traced) = trace_outer(&part) else {
        return f64::INFINITY;
    };
    let reference = resample_closed(reference, n);
    let outline = resample_closed(&start_nearest(&traced, reference[0]), n);
    frechet_closed(&outline, &reference)
}

fn render_err(e: crate::render::RenderError) -> CageCommandError {
    CageCommandError::Argument(e.to_string())
}
