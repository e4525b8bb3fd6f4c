//! From take frames to keyframes: layers (element 0 = the plant, `k + 1` = secondary element `k`
//! of the rig), resampled to a fixed rate on one shared time base starting at 0, and joint
//! rotations as unit quaternions on a consistent hemisphere.

use frond_motion::take::MAX_INTERPOLATED_GAP_S;
use frond_motion::{JOINTS, PoseFrame, TakeFrame, resample_across_gaps};
use frond_protocol::convention::joint_quat;
use frond_protocol::{ElementId, PoseFlags};

/// Per joint `[pitch, yaw, roll]`, degrees.
pub type Joints = [[f32; 3]; JOINTS];

/// Largest accepted bake rate, frames per second.
pub const MAX_FPS: f64 = 1000.0;

/// One element's poses, resampled.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// Element id: 0 for the plant, `k + 1` for the rig's secondary element `k`.
    pub element: ElementId,
    /// One pose per key of [`Layers::times_s`].
    pub poses: Vec<Joints>,
}

/// Every layer of a take on one time base.
#[derive(Debug, Clone, PartialEq)]
pub struct Layers {
    /// Key rate, frames per second.
    pub fps: f64,
    /// Key times, seconds, `k / fps`, starting at 0.
    pub times_s: Vec<f64>,
    /// Element 0 first, then the others by id.
    pub layers: Vec<Layer>,
}

impl Layers {
    /// Resamples a take's frames to `fps`. Held frames (no new device report: the daemon
    /// repeats the last pose) are skipped, as `frond take export` does. Every layer shares the
    /// take's time base: time 0 is the first kept frame of any layer, and each layer holds its
    /// first pose before it starts and its last after it ends. A step in the shared time base
    /// longer than `MAX_INTERPOLATED_GAP_S` is a discontinuity (one key, not hours of
    /// interpolated ones), as in `frond_motion::resample`. A take without element-0 frames (a
    /// take of `frond record layer`, which holds only its layer) gets the plant at rest (every
    /// joint at 0 degrees: the bind pose) as its element 0, so its layer moves on a still plant.
    /// `None` when no frame remains.
    /// [`Layers::plan`] counts the keys first.
    pub fn from_frames(frames: &[TakeFrame], fps: f64) -> Option<Layers> {
        let kept = || {
            frames.iter().filter(|f| !PoseFlags(f.flags).contains(PoseFlags::HELD) && f.pose.t.is_finite())
        };
        kept().next()?;
        let rest_plant = !kept().any(|f| f.element.is_global());
        let timeline = TimeLine::new(kept().map(|f| f.pose.t), fps);
        let t_end = timeline.end();
        let mut ids: Vec<ElementId> = kept().map(|f| f.element).collect();
        ids.sort_unstable();
        ids.dedup();
        let mut layers = Vec::with_capacity(ids.len());
        let mut times_s = Vec::new();
        for id in ids {
            let mut poses: Vec<PoseFrame> = Vec::new();
            for f in kept().filter(|f| f.element == id) {
                // Out-of-order frames (never from the recorder) would confuse the resampler.
                let t = timeline.map(f.pose.t);
                if poses.last().is_none_or(|p| t >= p.t) {
                    poses.push(PoseFrame { t, ..f.pose });
                }
            }
            let first = poses[0];
            let last = poses[poses.len() - 1];
            if first.t > 0.0 {
                poses.insert(0, PoseFrame { t: 0.0, ..first });
            }
            if last.t < t_end {
                poses.push(PoseFrame { t: t_end, ..last });
            }
            let resampled = resample_across_gaps(&poses, fps);
            if times_s.is_empty() {
                times_s = resampled.iter().map(|p| p.t).collect();
            }
            layers.push(Layer { element: id, poses: resampled.iter().map(|p| p.joints_deg).collect() });
        }
        if rest_plant {
            let rest = Layer { element: ElementId::GLOBAL, poses: vec![[[0.0; 3]; JOINTS]; times_s.len()] };
            layers.insert(0, rest);
        }
        Some(Layers { fps, times_s, layers })
    }

    /// Keys [`Layers::from_frames`] would make and the time discontinuities it would collapse,
    /// counted without allocating the keys.
    pub fn plan(frames: &[TakeFrame], fps: f64) -> (u64, u64) {
        let kept =
            frames.iter().filter(|f| !PoseFlags(f.flags).contains(PoseFlags::HELD) && f.pose.t.is_finite());
        let timeline = TimeLine::new(kept.map(|f| f.pose.t), fps);
        let keys = (timeline.end() * fps + frond_motion::clip::FRAME_TOLERANCE).floor();
        let keys = if keys.is_finite() && keys < u64::MAX as f64 { keys as u64 + 1 } else { u64::MAX };
        (keys, timeline.discontinuities)
    }

    /// The plant's own layer (element 0).
    pub fn main(&self) -> &Layer {
        &self.layers[0]
    }

    /// Duration, seconds (time of the last key).
    pub fn duration_s(&self) -> f64 {
        self.times_s.last().copied().unwrap_or(0.0)
    }
}

/// Appends one joint's rotations for a sequence of `[pitch, yaw, roll]` angles, converted with
/// the protocol's convention (`R = R_yaw R_pitch R_roll`), renormalised in `f32`, each flipped
/// onto the hemisphere of the previous one (`q` and `-q` are the same rotation; LINEAR glTF
/// interpolation between keys with a negative dot product would take the long way round).
pub fn push_joint_quats(angles: impl IntoIterator<Item = [f32; 3]>, out: &mut Vec<[f32; 4]>) {
    let mut prev: Option<[f32; 4]> = None;
    for a in angles {
        let mut q = unit(joint_quat(a));
        if let Some(p) = prev
            && dot(p, q) < 0.0
        {
            q = q.map(|c| -c);
        }
        out.push(q);
        prev = Some(q);
    }
}

fn dot(a: [f32; 4], b: [f32; 4]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// `q / |q|` (computed in f64), identity for a degenerate input (never from finite angles).
pub fn unit(q: [f32; 4]) -> [f32; 4] {
    let n = q.iter().map(|&c| f64::from(c) * f64::from(c)).sum::<f64>().sqrt();
    if !(n.is_finite() && n > 0.0) {
        return [0.0, 0.0, 0.0, 1.0];
    }
    q.map(|c| (f64::from(c) / n) as f32)
}

/// A bake rate out of range.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("must be a number above 0 and at most {MAX_FPS}, got {0}")]
pub struct BadFps(pub f64);

/// Checks a bake rate.
pub fn check_fps(fps: f64) -> Result<f64, BadFps> {
    if fps.is_finite() && fps > 0.0 && fps <= MAX_FPS { Ok(fps) } else { Err(BadFps(fps)) }
}

/// The take's times on the bake's time line: from 0 at the first kept frame, with every step
/// between two successive distinct times longer than `MAX_INTERPOLATED_GAP_S` shortened to one
/// key (`1 / fps`).
struct TimeLine {
    /// Distinct input times, ascending.
    times: Vec<f64>,
    /// Their times on the bake's time line.
    mapped: Vec<f64>,
    discontinuities: u64,
}

impl TimeLine {
    fn new(times: impl Iterator<Item = f64>, fps: f64) -> TimeLine {
        let mut times: Vec<f64> = times.collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        let mut mapped = Vec::with_capacity(times.len());
        let mut discontinuities = 0;
        for (i, &t) in times.iter().enumerate() {
            let m = match i {
                0 => 0.0,
                _ => {
                    let dt = t - times[i - 1];
                    let step = if dt <= MAX_INTERPOLATED_GAP_S {
                        dt
                    } else {
                        discontinuities += 1;
                        1.0 / fps
                    };
                    mapped[i - 1] + step
                }
            };
            mapped.push(m);
        }
        TimeLine { times, mapped, discontinuities }
    }

    /// The time line's time of input time `t` (one of the times it was built from).
    fn map(&self, t: f64) -> f64 {
        match self.times.binary_search_by(|x| x.total_cmp(&t)) {
            Ok(i) => self.mapped[i],
            Err(i) => self.mapped.get(i.saturating_sub(1)).copied().unwrap_or(0.0),
        }
    }

    fn end(&self) -> f64 {
        self.mapped.last().copied().unwrap_or(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(element: u16, t: f64, a: f32, flags: u32) -> TakeFrame {
        TakeFrame {
            element: ElementId::new(element),
            flags,
            pose: PoseFrame { t, joints_deg: [[a, 0.0, 0.0]; JOINTS] },
            ..TakeFrame::default()
        }
    }

    #[test]
    fn layers_share_one_time_base_from_zero() {
        // Main layer 10.0 .. 11.0 s (pitch 0 -> 10), leaf layer 10.5 .. 10.75 s (pitch 100 -> 200).
        let frames = [
            frame(0, 10.0, 0.0, 0),
            frame(1, 10.5, 100.0, 0),
            frame(1, 10.75, 200.0, 0),
            frame(0, 11.0, 10.0, 0),
        ];
        let l = Layers::from_frames(&frames, 4.0).unwrap();
        assert_eq!(l.times_s, [0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!(l.layers.len(), 2);
        let pitch = |layer: &Layer| layer.poses.iter().map(|p| p[0][0]).collect::<Vec<_>>();
        assert_eq!(pitch(&l.layers[0]), [0.0, 2.5, 5.0, 7.5, 10.0]);
        // Held before its start and after its end.
        assert_eq!(pitch(&l.layers[1]), [100.0, 100.0, 100.0, 200.0, 200.0]);
    }

    #[test]
    fn a_gap_in_time_is_one_key_and_late_layers_stay_aligned() {
        // Two frames at t = 0 and t = 1e9: two keys, not 30 billion.
        let frames = [frame(0, 0.0, 1.0, 0), frame(0, 1e9, 5.0, 0)];
        assert_eq!(Layers::plan(&frames, 30.0), (2, 1));
        let l = Layers::from_frames(&frames, 30.0).unwrap();
        assert_eq!(l.times_s, [0.0, 1.0 / 30.0]);
        assert_eq!(l.main().poses.iter().map(|p| p[0][0]).collect::<Vec<_>>(), [1.0, 5.0]);
        // Main every 0.5 s over 0 .. 3 s, then a 1000 s gap, then 3 s more; a leaf only from
        // 2 s: the leaf holds its first pose until 2 s on the shared time line, and the gap
        // costs one key (at 2 FPS, 0.5 s) in both layers.
        let mut frames: Vec<TakeFrame> = (0..=6).map(|i| frame(0, i as f64 * 0.5, i as f32, 0)).collect();
        frames.push(frame(1, 2.0, 50.0, 0));
        frames.push(frame(1, 2.5, 60.0, 0));
        frames.extend((0..=6).map(|i| frame(0, 1003.0 + i as f64 * 0.5, 10.0 + i as f32, 0)));
        assert_eq!(Layers::plan(&frames, 2.0), (14, 1));
        let l = Layers::from_frames(&frames, 2.0).unwrap();
        assert_eq!(l.times_s.len(), 14);
        let pitch = |layer: &Layer| layer.poses.iter().map(|p| p[0][0]).collect::<Vec<_>>();
        let main: Vec<f32> = (0..=6).map(|i| i as f32).chain((0..=6).map(|i| 10.0 + i as f32)).collect();
        assert_eq!(pitch(&l.layers[0]), main);
        let mut leaf = vec![50.0; 5];
        leaf.extend([60.0; 9]);
        assert_eq!(pitch(&l.layers[1]), leaf);
    }

    #[test]
    fn held_frames_are_skipped_and_an_empty_main_layer_is_none() {
        let frames = [frame(0, 0.0, 0.0, 0), frame(0, 0.5, 99.0, PoseFlags::HELD.0), frame(0, 1.0, 10.0, 0)];
        let l = Layers::from_frames(&frames, 2.0).unwrap();
        assert_eq!(l.main().poses.iter().map(|p| p[0][0]).collect::<Vec<_>>(), [0.0, 5.0, 10.0]);
        assert!(Layers::from_frames(&[frame(0, 0.0, 0.0, PoseFlags::HELD.0)], 30.0).is_none());
        assert!(Layers::from_frames(&[], 30.0).is_none());
    }

    #[test]
    fn a_layer_take_moves_its_layer_on_a_plant_at_rest() {
        // Only leaf frames (element 1), pitch 10 at 5.0 s and 30 at 6.0 s, as `frond record
        // layer` writes them: at 2 FPS keys at 0, 0.5, 1 s; the plant is at rest in every key.
        let frames = [frame(1, 5.0, 10.0, 0), frame(1, 6.0, 30.0, 0)];
        let l = Layers::from_frames(&frames, 2.0).unwrap();
        assert_eq!(l.times_s, [0.0, 0.5, 1.0]);
        assert_eq!(l.layers.iter().map(|l| l.element.get()).collect::<Vec<_>>(), [0, 1]);
        assert_eq!(l.main().poses, vec![[[0.0f32; 3]; JOINTS]; 3]);
        assert_eq!(l.layers[1].poses.iter().map(|p| p[0][0]).collect::<Vec<_>>(), [10.0, 20.0, 30.0]);
    }

    #[test]
    fn quaternions_stay_on_one_hemisphere() {
        // Yaw 170, 179, then wrapped to -179, -170: the convention's quaternion for -179 is on
        // the other hemisphere from 179's (a 358 degree jump of the Euler value, a 2 degree
        // turn); the keys must not flip, so LINEAR interpolation takes the short way.
        let angles = [[0.0, 170.0, 0.0], [0.0, 179.0, 0.0], [0.0, -179.0, 0.0], [0.0, -170.0, 0.0]];
        let raw = joint_quat(angles[2]);
        assert!(dot(joint_quat(angles[1]), raw) < 0.0, "the test needs a sign flip");
        let mut q = Vec::new();
        push_joint_quats(angles, &mut q);
        for w in q.windows(2) {
            assert!(dot(w[0], w[1]) > 0.0, "{q:?}");
        }
        for k in &q {
            assert!((dot(*k, *k) - 1.0).abs() < 1e-6);
        }
        // The flipped key is the same rotation: exactly -q.
        for c in 0..4 {
            assert!((q[2][c] + raw[c]).abs() < 1e-6, "{:?} vs {raw:?}", q[2]);
        }
        // Half angle of -179 deg about +Z: (0, 0, -sin 89.5, cos 89.5), negated.
        let h = 89.5f32.to_radians();
        assert!((q[2][2] - h.sin()).abs() < 1e-6 && (q[2][3] + h.cos()).abs() < 1e-6, "{:?}", q[2]);
    }

    #[test]
    fn fps_bounds() {
        assert!(check_fps(30.0).is_ok());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e6] {
            assert!(check_fps(bad).is_err(), "{bad}");
        }
    }
}
