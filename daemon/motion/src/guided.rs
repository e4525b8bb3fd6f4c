//! Guided procedural motion (seed 000, section 6.4, Eq. 8): only the root is authored; the upper
//! joints follow it with a delay controlled by the top thumb joint:
//! `P_i(t) = P_0(t - s_g(i) G_3 sigma_i)`, `i = 1..3`, with `G_3` the top thumb joint bend
//! normalised by its range to `0..1` at time `t` and `sigma_i` in seconds (softer plant: larger).
//! The same delayed lookup as the field (Eq. 6-7).
//!
//! Eq. 8 drives the bend (pitch and yaw). Roll keeps the take's own twist (Eq. 4): the root never
//! twists (`P_roll(0) = 0` for every `tau <= 3`), so copying it would erase the twisting the seed
//! still authors with the wrist roll (section 6.4: "as in Sections 5.1 and 5.2").

use crate::clip::{Clip, DelayLine};
use crate::sample::{HandSample, JOINTS, PoseFrame};

/// Parameters of Eq. 8.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidedParams {
    /// `sigma_1..sigma_3`, seconds (>= 0).
    pub sigma_s: [f64; 3],
    /// `s_g(1)..s_g(3)` (>= 0).
    pub s_g: [f64; 3],
    /// Range of the top thumb joint, degrees (> 0): `G_3 = thumb[2] / range`, clamped to 0..1.
    pub g3_range_deg: f32,
}

/// A [`GuidedParams`] value out of its range.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum GuidedParamsError {
    /// A `sigma_i` or `s_g(i)` is not between 0 and 60; `option` names the list (`--sigma`,
    /// `--sg`).
    #[error("{option} values must be between 0 and 60, got {value}")]
    OutOfRange {
        /// The option of the list: `--sigma` or `--sg`.
        option: &'static str,
        /// The value out of range.
        value: f64,
    },
    /// The top thumb joint's range is not a positive number of degrees.
    #[error("the thumb range must be > 0 degrees, got {0}")]
    ThumbRange(f32),
}

impl GuidedParams {
    /// Checks the parameters, naming the bad one.
    pub fn validate(&self) -> Result<(), GuidedParamsError> {
        for (option, v) in [("--sigma", self.sigma_s), ("--sg", self.s_g)] {
            if let Some(&value) = v.iter().find(|x| !(x.is_finite() && **x >= 0.0 && **x <= 60.0)) {
                return Err(GuidedParamsError::OutOfRange { option, value });
            }
        }
        if !(self.g3_range_deg.is_finite() && self.g3_range_deg > 0.0) {
            return Err(GuidedParamsError::ThumbRange(self.g3_range_deg));
        }
        Ok(())
    }

    /// The longest delay these parameters can ask for, seconds.
    pub fn max_delay_s(&self) -> f64 {
        (0..3).map(|i| self.s_g[i] * self.sigma_s[i]).fold(0.0, f64::max)
    }

    /// The delays `s_g(i) G_3 sigma_i` of joints 1..3 for a calibrated hand sample.
    pub fn delays_s(&self, hand: &HandSample) -> [f64; 3] {
        let g3 = (hand.thumb_deg[2] as f64 / self.g3_range_deg as f64).clamp(0.0, 1.0);
        let g3 = if g3.is_nan() { 0.0 } else { g3 };
        std::array::from_fn(|i| self.s_g[i] * g3 * self.sigma_s[i])
    }
}

/// Eq. 8 over a clip with its hand samples (same rate, `hands[k]` for frame `k`; missing samples
/// count as an open thumb, `G_3 = 0`).
pub fn guided(clip: &Clip, hands: &[HandSample], p: &GuidedParams) -> Result<Clip, GuidedParamsError> {
    p.validate()?;
    let frames = clip.frames.iter().enumerate().map(|(k, f)| {
        let d = hands.get(k).map_or([0.0; 3], |h| p.delays_s(h));
        let mut j = f.joints_deg;
        for i in 1..JOINTS {
            let root = clip.at_time(f.t - d[i - 1])[0];
            j[i] = [root[0], root[1], f.joints_deg[i][2]];
        }
        j
    });
    Ok(Clip::from_joints(frames.collect::<Vec<_>>(), clip.fps))
}

/// Eq. 8 live, as a rig option in the daemon: push every mapped pose with its calibrated hand
/// sample, get the guided pose. Allocation-free after [`GuidedLive::new`].
#[derive(Debug, Clone)]
pub struct GuidedLive {
    params: GuidedParams,
    roots: DelayLine,
}

impl GuidedLive {
    /// A guided-motion stage for a loop running at `rate_hz`.
    pub fn new(params: GuidedParams, rate_hz: f64) -> Self {
        GuidedLive { params, roots: DelayLine::new(DelayLine::capacity_for(params.max_delay_s(), rate_hz)) }
    }

    /// Forgets the root history (e.g. after a device loss).
    pub fn reset(&mut self) {
        self.roots.clear();
    }

    /// Records `pose`'s root and returns the pose with joints 1..3 bent as Eq. 8 says.
    pub fn apply(&mut self, pose: &PoseFrame, hand: &HandSample) -> PoseFrame {
        self.roots.push(*pose);
        let d = self.params.delays_s(hand);
        let mut out = *pose;
        for i in 1..JOINTS {
            let root = self.roots.at_time(pose.t - d[i - 1]).map_or(pose.joints_deg[0], |j| j[0]);
            out.joints_deg[i][0] = root[0];
            out.joints_deg[i][1] = root[1];
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp_clip() -> Clip {
        // 10 FPS, root pitch 10 k and yaw -k at frame k; upper joints with their own roll 7.
        Clip::from_joints(
            (0..=20)
                .map(|k| [[10.0 * k as f32, -(k as f32), 0.0], [0.0, 0.0, 7.0], [0.0; 3], [0.0, 0.0, 7.0]]),
            10.0,
        )
    }

    fn hand(g3: f32) -> HandSample {
        HandSample { t: 0.0, wrist_deg: [0.0; 3], thumb_deg: [0.0, 0.0, g3] }
    }

    #[test]
    fn eq8_by_hand() {
        // G_3 = 30 / 60 = 0.5; sigma = (0.2, 0.4, 0.6) s, s_g = (1, 1, 1): delays 0.1, 0.2, 0.3 s.
        // At t = 1.0 s (root pitch 100): P_1 = P_0(0.9) = 90, P_2 = P_0(0.8) = 80,
        // P_3 = P_0(0.7) = 70; yaw likewise -9, -8, -7; roll keeps 7, 0, 7.
        let p = GuidedParams { sigma_s: [0.2, 0.4, 0.6], s_g: [1.0; 3], g3_range_deg: 60.0 };
        let c = ramp_clip();
        let out = guided(&c, &vec![hand(30.0); c.len()], &p).unwrap();
        let f = out.frames[10].joints_deg;
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-4);
        assert!(close(f[0], [100.0, -10.0, 0.0]), "{f:?}");
        assert!(close(f[1], [90.0, -9.0, 7.0]), "{f:?}");
        assert!(close(f[2], [80.0, -8.0, 0.0]), "{f:?}");
        assert!(close(f[3], [70.0, -7.0, 7.0]), "{f:?}");
        // s_g(2) = 0.5 halves joint 2's delay (0.1 s): 90. A straight thumb (G_3 = 0): no delay.
        let p2 = GuidedParams { s_g: [1.0, 0.5, 1.0], ..p };
        assert!(
            (guided(&c, &vec![hand(30.0); c.len()], &p2).unwrap().frames[10].joints_deg[2][0] - 90.0).abs()
                < 1e-4
        );
        let f = guided(&c, &vec![hand(0.0); c.len()], &p).unwrap().frames[10].joints_deg;
        assert_eq!([f[1][0], f[2][0], f[3][0]], [100.0, 100.0, 100.0]);
        // G_3 beyond its range is clamped to 1: delays 0.2, 0.4, 0.6 -> P_3 = P_0(0.4) = 40.
        let f = guided(&c, &vec![hand(90.0); c.len()], &p).unwrap().frames[10].joints_deg;
        assert!((f[3][0] - 40.0).abs() < 1e-4);
        let e = guided(&c, &[], &GuidedParams { sigma_s: [-1.0, 0.0, 0.0], ..p }).unwrap_err();
        assert_eq!(e, GuidedParamsError::OutOfRange { option: "--sigma", value: -1.0 });
        assert_eq!(e.to_string(), "--sigma values must be between 0 and 60, got -1");
        let e = GuidedParams { g3_range_deg: 0.0, ..p }.validate().unwrap_err();
        assert_eq!(e.to_string(), "the thumb range must be > 0 degrees, got 0");
    }

    #[test]
    fn live_matches_offline() {
        let p = GuidedParams { sigma_s: [0.2, 0.4, 0.6], s_g: [1.0; 3], g3_range_deg: 60.0 };
        let c = ramp_clip();
        let offline = guided(&c, &vec![hand(30.0); c.len()], &p).unwrap();
        let mut live = GuidedLive::new(p, 10.0);
        for (f, want) in c.frames.iter().zip(&offline.frames) {
            let got = live.apply(f, &hand(30.0));
            for (x, y) in got.joints_deg.iter().flatten().zip(want.joints_deg.iter().flatten()) {
                assert!((x - y).abs() < 1e-4, "t {}: {got:?} vs {want:?}", f.t);
            }
        }
    }
}
