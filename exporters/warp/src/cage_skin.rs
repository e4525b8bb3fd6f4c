//! The skeleton-driven cage mode (issue 17): the crown cage of a picture's plant is skinned to
//! the plant skeleton (seed 000, Eq. 1 with its height weights), so the hand, live or from a take,
//! bends the plant in the picture while the cage tree keeps its shape (seed 004).
//!
//! The picture is the skeleton's XY plane seen from +Z: the skeleton stands at the anchor (a
//! picture point, default the bottom centre of the crown's box) growing up the picture (+Y is up,
//! image y down), and the crown's top is at the top joint's height, which sets the pixels per
//! metre. Each crown vertex takes the procedural weights of its height, is skinned by the pose's
//! joint matrices and projected back (its Z dropped).

use std::path::PathBuf;

use frond_cage::morph::{MorphOptions, MorphPlan};
use frond_cage::{CageTree, Point};
use frond_motion::skeleton::{Skeleton, skin_point};
use glam::Vec3;

use crate::Scene;
use crate::cages::CageCommandError;
use crate::morph_frames::MorphFrames;
use crate::render::{OutputKind, PoseTrack, Progress, Sink};

/// A crown cage bound to a skeleton at a point of the picture.
#[derive(Debug, Clone)]
pub struct CageSkin {
    skeleton: Skeleton,
    anchor: Point,
    px_per_m: f64,
    rest: Vec<Point>,
    weights: Vec<[f32; 4]>,
}

impl CageSkin {
    /// Binds cage `crown` of `tree` to `skeleton` standing at `anchor` (default: the bottom
    /// centre of the crown's bounding box).
    pub fn new(tree: &CageTree, crown: usize, skeleton: Skeleton, anchor: Option<Point>) -> CageSkin {
        let rest = tree.cages[crown].vertices.clone();
        let [x0, y0, x1, y1] = frond_cage::outline::bounds(&rest);
        let anchor = anchor.unwrap_or([(x0 + x1) / 2.0, y1]);
        let top_m = f64::from(skeleton.heights_m[3]).max(1e-6);
        let px_per_m = ((anchor[1] - y0) / top_m).max(1e-6);
        let weights =
            rest.iter().map(|p| skeleton.weights_at(((anchor[1] - p[1]) / px_per_m) as f32)).collect();
        CageSkin { skeleton, anchor, px_per_m, rest, weights }
    }

    /// The anchor, picture pixels.
    pub fn anchor(&self) -> Point {
        self.anchor
    }

    /// Pixels per metre of skeleton.
    pub fn px_per_m(&self) -> f64 {
        self.px_per_m
    }

    /// The crown's vertices under the pose `joints_deg` (seed 000, Eq. 1).
    pub fn crown_at(&self, joints_deg: &[[f32; 3]; 4]) -> Vec<Point> {
        let m = self.skeleton.skinning_matrices(joints_deg);
        let s = self.px_per_m;
        self.rest
            .iter()
            .zip(&self.weights)
            .map(|(p, w)| {
                let v = Vec3::new(
                    ((p[0] - self.anchor[0]) / s) as f32,
                    ((self.anchor[1] - p[1]) / s) as f32,
                    0.0,
                );
                let q = skin_point(&m, w, v);
                [self.anchor[0] + f64::from(q.x) * s, self.anchor[1] - f64::from(q.y) * s]
            })
            .collect()
    }
}

/// `render --mode cage --take TAKE`: what to render.
#[derive(Debug, Clone)]
pub struct CageTakeJob {
    /// The layer's cage tree (default: built from the layer).
    pub cage: Option<PathBuf>,
    /// Where the skeleton stands (default: the bottom centre of the crown).
    pub anchor: Option<Point>,
    /// The skeleton (the take's rig).
    pub skeleton: Skeleton,
    /// Frames and rate.
    pub frames: usize,
    /// Frames per second.
    pub fps: f32,
    /// Output.
    pub output: OutputKind,
    /// Self-adaptive cages.
    pub adapt: bool,
    /// No progress bar.
    pub quiet: bool,
}

/// Renders `scene`'s first layer bent by the take's poses through its skinned crown cage.
/// Frame `k` shows the take's last pose at or before `k / fps` seconds (looping).
pub fn render_take(scene: &Scene, track: &PoseTrack, job: &CageTakeJob) -> Result<usize, CageCommandError> {
    let (w, h) = (scene.width, scene.height);
    let tree = crate::morph::scene_tree(scene, job.cage.as_deref())?;
    let plan = MorphPlan::driven(tree, MorphOptions { adapt: job.adapt, prune: false });
    let skin = CageSkin::new(plan.tree(), plan.crown(), job.skeleton, job.anchor);
    let mut frames = MorphFrames::new(scene, &plan);
    let mut sink = Sink::open(&job.output, w, h, job.fps).map_err(crate::morph::render_err)?;
    let progress = Progress::new(job.frames, job.quiet);
    let mut frame = Vec::with_capacity(w * h * 4);
    let duration = track.times_s.last().copied().unwrap_or(0.0);
    let dt = 1.0 / f64::from(job.fps);
    let mut cursor = 0usize;
    for k in 0..job.frames {
        let t = (k as f64 * dt) % (duration + dt);
        if cursor >= track.times_s.len() || track.times_s[cursor] > t {
            cursor = 0; // looped
        }
        while cursor + 1 < track.times_s.len() && track.times_s[cursor + 1] <= t {
            cursor += 1;
        }
        frames.set_crown(&skin.crown_at(&track.joints_deg[cursor]));
        frames.compose(0.0, &mut frame);
        sink.push(k, &frame).map_err(crate::morph::render_err)?;
        progress.tick(k + 1);
    }
    sink.finish().map_err(crate::morph::render_err)?;
    Ok(job.frames)
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_cage::CageKind;

    /// Worked by hand: only the root joint yaws by 90 degrees, so the whole plant turns rigidly
    /// about the root joint (0, h_0): a point (x, y) in metres goes to (-(y - h_0), x + h_0)
    /// (rotation about +Z, counter-clockwise seen from +Z, i.e. to the left in the picture).
    #[test]
    fn a_root_yaw_turns_the_crown_about_the_root_joint() {
        let crown = vec![[40.0, 20.0], [60.0, 20.0], [60.0, 100.0], [40.0, 100.0]];
        let tree = CageTree::from_parts([100, 120], [(0, None, CageKind::Leaf, crown)]).unwrap();
        let sk = Skeleton { heights_m: [0.1, 0.3, 0.5, 0.8] };
        let skin = CageSkin::new(&tree, 0, sk, None);
        assert_eq!(skin.anchor(), [50.0, 100.0]);
        assert!((skin.px_per_m() - 100.0).abs() < 1e-4, "80 px for the 0.8 m top joint");
        let mut pose = [[0.0f32; 3]; 4];
        pose[0][1] = 90.0;
        let got = skin.crown_at(&pose);
        // (40, 20) px is (-0.1, 0.8) m; turned about (0, 0.1): (-0.7, 0.0) m -> (-20, 100) px.
        let want = [[-20.0, 100.0], [-20.0, 80.0], [60.0, 80.0], [60.0, 100.0]];
        for (g, w) in got.iter().zip(want) {
            assert!((g[0] - w[0]).abs() < 1e-3 && (g[1] - w[1]).abs() < 1e-3, "{got:?}");
        }
        assert_eq!(
            skin.crown_at(&[[0.0; 3]; 4])
                .iter()
                .zip(&tree.cages[0].vertices)
                .filter(|(a, b)| (a[0] - b[0]).abs() > 1e-4 || (a[1] - b[1]).abs() > 1e-4)
                .count(),
            0
        );
    }
}
