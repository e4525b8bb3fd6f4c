//! Take editing (seed 000, sections 6.3 "Animation editing" and 7.2): resampling, post-processing low-pass, and splicing a re-authored range with linear blends.
//!
//! All functions work on the frames of one layer; the `frond take` commands apply them to a
//! chosen layer and keep the others.

use frond_protocol::ElementId;
use thiserror::Error;

use crate::clip::lerp_joints;
use crate::filter::{FilterSpec, LowPass, OneEuro};
use crate::resample::{MAX_RESAMPLED_FRAMES, resample};
use crate::sample::{HandSample, JOINTS, PoseFrame};
use crate::take::TakeFrame;

/// Why an edit was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EditError {
    /// A parameter is out of range.
    #[error("{0}")]
    Invalid(String),
}

/// Resamples hand samples like [`resample`] does poses: output `k` at `t = k / fps` relative to
/// the first sample, every value linearly interpolated.
pub fn resample_hands(hands: &[HandSample], fps: f64) -> Vec<HandSample> {
    // Reuse the pose resampler: wrist and thumb are 6 of its 12 channels.
    let as_poses: Vec<PoseFrame> = hands
        .iter()
        .map(|h| {
            let mut j = [[0.0; 3]; JOINTS];
            j[0] = h.wrist_deg;
            j[1] = h.thumb_deg;
            PoseFrame { t: h.t, joints_deg: j }
        })
        .collect();
    resample(&as_poses, fps)
        .into_iter()
        .map(|p| HandSample { t: p.t, wrist_deg: p.joints_deg[0], thumb_deg: p.joints_deg[1] })
        .collect()
}

/// Resamples one layer's frames (poses and hand samples) to `fps`, `seq = k`, times from 0.
/// Held frames are expected to be dropped first ([`crate::layers::Take::layer`]).
pub fn resample_frames(frames: &[TakeFrame], fps: f64) -> Result<Vec<TakeFrame>, EditError> {
    if !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0) {
        return Err(EditError::Invalid(format!("fps must be in (0, 10000], got {fps}")));
    }
    let poses: Vec<PoseFrame> = frames.iter().map(|f| f.pose).collect();
    let hands: Vec<HandSample> = frames.iter().map(|f| HandSample { t: f.pose.t, ..f.hand }).collect();
    let p = resample(&poses, fps);
    let h = resample_hands(&hands, fps);
    let (element, flags) =
        frames.first().map_or((ElementId::GLOBAL, 0), |f| (f.element, f.flags & !crate::take::FLAG_HELD));
    Ok(p.into_iter()
        .zip(h)
        .enumerate()
        .map(|(k, (pose, hand))| TakeFrame {
            seq: k as u64,
            device_time_us: (pose.t * 1e6).round() as u64,
            host_ns: 0,
            flags,
            element,
            pose,
            hand,
        })
        .take(MAX_RESAMPLED_FRAMES)
        .collect())
}

enum Channel {
    None,
    Low(LowPass),
    Euro(OneEuro),
}

impl Channel {
    fn new(spec: FilterSpec) -> Self {
        match spec {
            FilterSpec::None => Channel::None,
            FilterSpec::LowPass { cutoff_hz } => Channel::Low(LowPass::new(cutoff_hz)),
            FilterSpec::OneEuro { min_cutoff, beta, d_cutoff } => {
                Channel::Euro(OneEuro::new(min_cutoff, beta, d_cutoff))
            }
        }
    }
    fn run(&mut self, t: f64, x: f32) -> f32 {
        match self {
            Channel::None => x,
            Channel::Low(f) => f.filter(t, x),
            Channel::Euro(f) => f.filter(t, x),
        }
    }
}

/// Post-processing low-pass of poses (seed 000, section 7.2: "apply the low-pass filter as a
/// post processing step"): the chosen filter (`lowpass` or `one-euro`, the same filters as live)
/// runs on each of the 12 joint angles over the frame times, forwards and then backwards in
/// time, so the result has no lag (zero phase; the effective order doubles). Times and frame
/// count are unchanged; `none` returns the input.
pub fn post_filter(poses: &[PoseFrame], spec: FilterSpec) -> Result<Vec<PoseFrame>, EditError> {
    spec.validate().map_err(|e| EditError::Invalid(e.to_string()))?;
    let mut out = poses.to_vec();
    if spec == FilterSpec::None {
        return Ok(out);
    }
    for j in 0..JOINTS {
        for c in 0..3 {
            let mut f = Channel::new(spec);
            for p in out.iter_mut() {
                p.joints_deg[j][c] = f.run(p.t, p.joints_deg[j][c]);
            }
            let mut b = Channel::new(spec);
            for p in out.iter_mut().rev() {
                p.joints_deg[j][c] = b.run(-p.t, p.joints_deg[j][c]);
            }
        }
    }
    Ok(out)
}

/// Re-authors a range (seed 000, section 6.3 "Animation editing"): frames `from..=to` of `base`
/// are replaced by all of `new`, and the first and last `blend` frames of the inserted part are
/// linearly blended with the neighbouring kept frame (`base[from - 1]` at the start,
/// `base[to + 1]` at the end): inserted frame `k` of the start blend is
/// `lerp(base[from - 1], new[k], (k + 1) / (blend + 1))`, and symmetrically at the end, so the
/// motion eases from the old take into the new one and back. Both inputs must be at the same
/// frame rate `fps`; the result is re-stamped `t = k / fps`, `seq = k`. Frames outside the range
/// keep their poses and hand samples bit-exact (only their times shift when the lengths differ).
pub fn splice(
    base: &[TakeFrame],
    from: usize,
    to: usize,
    new: &[TakeFrame],
    blend: usize,
    fps: f64,
) -> Result<Vec<TakeFrame>, EditError> {
    if base.is_empty() {
        return Err(EditError::Invalid("the base take has no frames".into()));
    }
    if from > to || to >= base.len() {
        return Err(EditError::Invalid(format!(
            "range {from}..={to} is not inside the base take's {} frames",
            base.len()
        )));
    }
    if new.is_empty() {
        return Err(EditError::Invalid("the new take has no frames".into()));
    }
    if !(fps.is_finite() && fps > 0.0) {
        return Err(EditError::Invalid(format!("fps must be > 0, got {fps}")));
    }
    let mut inserted: Vec<TakeFrame> = new.to_vec();
    let n = inserted.len();
    let blend = blend.min(n);
    if from > 0 {
        let anchor = base[from - 1].pose.joints_deg;
        for (k, f) in inserted.iter_mut().take(blend).enumerate() {
            let u = (k + 1) as f64 / (blend + 1) as f64;
            f.pose.joints_deg = lerp_joints(&anchor, &f.pose.joints_deg, u);
        }
    }
    if to + 1 < base.len() {
        let anchor = base[to + 1].pose.joints_deg;
        for k in 0..blend {
            let f = &mut inserted[n - 1 - k];
            let u = (k + 1) as f64 / (blend + 1) as f64;
            f.pose.joints_deg = lerp_joints(&anchor, &f.pose.joints_deg, u);
        }
    }
    let element = base[0].element;
    let mut out: Vec<TakeFrame> = Vec::with_capacity(base.len() - (to + 1 - from) + n);
    out.extend_from_slice(&base[..from]);
    out.extend(inserted.into_iter().map(|mut f| {
        f.element = element;
        f
    }));
    out.extend_from_slice(&base[to + 1..]);
    for (k, f) in out.iter_mut().enumerate() {
        let t = k as f64 / fps;
        f.seq = k as u64;
        f.pose.t = t;
        f.device_time_us = (t * 1e6).round() as u64;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn frames(values: &[f32]) -> Vec<TakeFrame> {
        values
            .iter()
            .enumerate()
            .map(|(k, &v)| TakeFrame {
                seq: k as u64,
                pose: PoseFrame { t: k as f64 / 10.0, joints_deg: [[v, -v, 0.0]; JOINTS] },
                hand: HandSample { t: k as f64 / 10.0, wrist_deg: [v, 0.0, 0.0], thumb_deg: [0.0; 3] },
                ..Default::default()
            })
            .collect()
    }

    #[test]
    fn resample_frames_interpolates_hands_too() {
        let f = resample_frames(&frames(&[0.0, 10.0]), 20.0).unwrap();
        assert_eq!(f.len(), 3);
        assert_eq!(f[1].pose.joints_deg[0][0], 5.0);
        assert_eq!(f[1].hand.wrist_deg[0], 5.0);
        assert_eq!(f[2].seq, 2);
        assert!(resample_frames(&frames(&[0.0]), 0.0).is_err());
    }

    #[test]
    fn post_filter_smooths_without_lag() {
        // A step from 0 to 10 at t = 1 s, 100 FPS; low-pass 2 Hz forwards and backwards is
        // symmetric about the step: the value at the step midpoint stays near 5 and far from it
        // the signal is untouched.
        let poses: Vec<PoseFrame> = (0..200)
            .map(|k| PoseFrame {
                t: k as f64 / 100.0,
                joints_deg: [[if k < 100 { 0.0 } else { 10.0 }; 3]; JOINTS],
            })
            .collect();
        let out = post_filter(&poses, FilterSpec::LowPass { cutoff_hz: 2.0 }).unwrap();
        assert_eq!(out.len(), 200);
        let v = |k: usize| out[k].joints_deg[2][1];
        assert!(v(0).abs() < 0.01 && (v(199) - 10.0).abs() < 0.01, "{} {}", v(0), v(199));
        assert!((v(99) + v(100) - 10.0).abs() < 0.6, "{} {}", v(99), v(100));
        assert!(v(90) > 0.5 && v(110) < 9.5, "smoothed: {} {}", v(90), v(110));
        assert_eq!(post_filter(&poses, FilterSpec::None).unwrap(), poses);
        assert!(post_filter(&poses, FilterSpec::LowPass { cutoff_hz: -1.0 }).is_err());
    }

    #[test]
    fn splice_by_hand() {
        // Base 0..=9 (value k*10), replace 3..=6 by three frames of 100, blend 1:
        // start blend: lerp(base[2] = 20, 100, 1/2) = 60; end blend: lerp(base[7] = 70, 100, 1/2) = 85.
        let base = frames(&[0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0]);
        let out = splice(&base, 3, 6, &frames(&[100.0, 100.0, 100.0]), 1, 10.0).unwrap();
        let v: Vec<f32> = out.iter().map(|f| f.pose.joints_deg[0][0]).collect();
        assert_eq!(v, [0.0, 10.0, 20.0, 60.0, 100.0, 85.0, 70.0, 80.0, 90.0]);
        assert_eq!(out[8].seq, 8);
        assert!((out[8].pose.t - 0.8).abs() < 1e-12);
        assert!(splice(&base, 5, 10, &base, 1, 10.0).unwrap_err().to_string().contains("not inside"));
        assert!(splice(&base, 6, 5, &base, 1, 10.0).is_err());
        assert!(splice(&base, 1, 2, &[], 1, 10.0).is_err());
    }

    proptest! {
        #[test]
        fn splice_keeps_frames_outside_the_range_bit_exact(
            values in proptest::collection::vec(-90.0f32..90.0, 2..60),
            new in proptest::collection::vec(-90.0f32..90.0, 1..40),
            a in 0usize..60, b in 0usize..60, blend in 0usize..10,
        ) {
            let base = frames(&values);
            let (from, to) = (a.min(b) % values.len(), a.max(b) % values.len());
            let (from, to) = (from.min(to), from.max(to));
            let out = splice(&base, from, to, &frames(&new), blend, 10.0).unwrap();
            prop_assert_eq!(out.len(), values.len() - (to + 1 - from) + new.len());
            let same = |x: &TakeFrame, y: &TakeFrame| {
                x.pose.joints_deg.iter().flatten().zip(y.pose.joints_deg.iter().flatten()).all(|(p, q)| p.to_bits() == q.to_bits())
                    && x.hand == y.hand && x.flags == y.flags && x.element == y.element
            };
            for k in 0..from {
                prop_assert!(same(&out[k], &base[k]));
                prop_assert_eq!(out[k].pose.t.to_bits(), base[k].pose.t.to_bits());
            }
            for (k, b) in base.iter().enumerate().skip(to + 1) {
                let j = k + new.len() - (to + 1 - from);
                prop_assert!(same(&out[j], b));
            }
        }
    }
}
