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

use frond_cage::morph::{MorphOptions, MorphPlan};
use frond_cage::sketch::Sketch;
use frond_cage::{BuildOptions, CageTree, build_cage_tree};
use frond_formats::rig_files::read_small_text;

use crate::Scene;
use crate::cages::{CageCommandError, read_cage_file};
use crate::morph_frames::MorphFrames;
use crate::render::{OutputKind, Progress, Sink};

/// Largest `sketch.json` read, bytes.
pub const MAX_SKETCH_FILE_BYTES: u64 = 4 << 20;

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
    let tree = scene_tree(&scene, job.cage.as_deref())?;
    let sketch = read_sketch(&job.sketch, tree.size)?;
    let plan = MorphPlan::new(tree, &sketch, job.opts);
    render(&scene, &plan, job)
}

/// The cage tree of `scene`'s first layer: the file `cage` (for a picture of the scene's size),
/// or built from the layer's alpha with the default options.
pub fn scene_tree(scene: &Scene, cage: Option<&Path>) -> Result<CageTree, CageCommandError> {
    let (w, h) = (scene.width, scene.height);
    match cage {
        Some(path) => {
            let tree = read_cage_file(path)?;
            if tree.size != [w as u32, h as u32] {
                return Err(CageCommandError::Argument(format!(
                    "cage file {} is for a {}x{} picture; the picture is {w}x{h}",
                    path.display(),
                    tree.size[0],
                    tree.size[1]
                )));
            }
            Ok(tree)
        }
        None => {
            let layer = &scene.layers[0];
            let matte: Vec<u8> = layer.pixels.chunks_exact(4).map(|p| p[3]).collect();
            build_cage_tree(&matte, w, h, &BuildOptions::default())
                .map_err(|error| CageCommandError::Build { path: layer.name.clone(), error })
        }
    }
}

fn read_sketch(path: &Path, size: [u32; 2]) -> Result<Sketch, CageCommandError> {
    let text = read_small_text(path, MAX_SKETCH_FILE_BYTES).map_err(CageCommandError::File)?;
    Sketch::from_json(&text, size)
        .map_err(|e| CageCommandError::Argument(format!("sketch {}: {e}", path.display())))
}

fn render(scene: &Scene, plan: &MorphPlan, job: &MorphJob) -> Result<MorphSummary, CageCommandError> {
    let (w, h) = (scene.width, scene.height);
    let tree = plan.tree();
    let crown = plan.crown();
    let mut frames = MorphFrames::new(scene, plan);
    let mut sink = Sink::open(&job.output, w, h, job.fps).map_err(render_err)?;
    let progress = Progress::new(job.frames, job.quiet);
    let mut frame = Vec::with_capacity(w * h * 4);
    let mut warped = Vec::new();
    let mut summary = MorphSummary {
        frames: job.frames,
        crown: tree.cages[crown].id,
        pruned: (0..tree.cages.len()).filter(|&i| plan.pruned()[i]).map(|i| tree.cages[i].id).collect(),
        t: Vec::with_capacity(job.frames),
        frechet_px: Vec::with_capacity(job.frames),
    };
    for k in 0..job.frames {
        let t = if job.frames > 1 { k as f64 / (job.frames - 1) as f64 } else { 1.0 };
        frames.frame_at(t, &mut frame);
        sink.push(k, &frame).map_err(render_err)?;
        // Section 6.2: this frame's outline against the reference in-between.
        summary.t.push(t);
        summary.frechet_px.push(frames.outline_distance(t, &mut warped));
        progress.tick(k + 1);
    }
    sink.finish().map_err(render_err)?;
    Ok(summary)
}

pub(crate) fn render_err(e: crate::render::RenderError) -> CageCommandError {
    CageCommandError::Argument(e.to_string())
}
