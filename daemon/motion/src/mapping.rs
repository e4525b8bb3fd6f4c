//! The hand-to-plant mapping of seed 000 (section 5, Eq. 2-4, with the wrist calibration of
//! section 5.4), and [`Mapper`], the one code path from a raw hand sample to a pose used by both
//! the daemon's realtime loop and `frond map`.
//!
//! Degrees in, degrees out. Joint 0 is the root, joint 3 the top.

use crate::filter::{FilterSpec, HandFilter};
use crate::sample::{HandSample, JOINTS, PoseFrame};

/// What the mapping needs from a calibration. `Copy`, no heap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationParams {
    /// Wrist neutral `[pitch, yaw, roll]`, degrees.
    pub neutral_wrist_deg: [f32; 3],
    /// Thumb neutral `[g1, g2, g3]`, degrees.
    pub neutral_thumb_deg: [f32; 3],
    /// `G_R1..G_R3` (seed 000, Eq. 3), degrees.
    pub thumb_range_deg: [f32; 3],
    /// The comfortable wrist reach from the neutral, `[below, above]` for pitch and for yaw,
    /// degrees (`neutral - min` and `max - neutral` of `wrist_range_deg`; at least
    /// [`crate::calibration::MIN_WRIST_REACH_DEG`] when validated), or `None` when the wrist was not measured. The
    /// mapping scales the root so these reach the rig's `bend_range_deg` (section 5.4).
    pub wrist_reach_deg: Option<[[f32; 2]; 2]>,
}

impl CalibrationParams {
    /// Zero neutral with the given thumb ranges, no wrist reach.
    pub fn neutral(thumb_range_deg: [f32; 3]) -> Self {
        CalibrationParams {
            neutral_wrist_deg: [0.0; 3],
            neutral_thumb_deg: [0.0; 3],
            thumb_range_deg,
            wrist_reach_deg: None,
        }
    }

    /// `W = wrist - neutral`, `G_i = thumb_i - neutral_i`; `t` unchanged. Differences of finite
    /// values saturate at `±f32::MAX` instead of overflowing to infinity.
    pub fn apply(&self, raw: &HandSample) -> HandSample {
        let sub = |a: f32, b: f32| ((a as f64 - b as f64) as f32).clamp(-f32::MAX, f32::MAX);
        let mut out = *raw;
        for k in 0..3 {
            out.wrist_deg[k] = sub(raw.wrist_deg[k], self.neutral_wrist_deg[k]);
            out.thumb_deg[k] = sub(raw.thumb_deg[k], self.neutral_thumb_deg[k]);
        }
        out
    }
}

/// Per-rig mapping parameters. `Copy`, so the realtime loop swaps them atomically by value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MappingParams {
    /// Per joint `[s_pitch(i), s_yaw(i), s_roll(i)]` (seed 000, Eq. 2-4 scaling factors).
    pub scale: [[f32; 3]; JOINTS],
    /// Number of twistable joints `tau` (seed 000, Eq. 4), 0..=3; the top `tau` joints twist.
    pub tau: u8,
    /// The rig's desired root bend `[pitch, yaw]`, degrees (> 0), at a performer's comfortable
    /// wrist extremes (seed 000, section 5.4; see [`root_scale`]), or `None`.
    pub bend_range_deg: Option<[f32; 2]>,
}

impl Default for MappingParams {
    /// All scales 1, `tau = 2` (the seed's usual setting), no bend range.
    fn default() -> Self {
        MappingParams { scale: [[1.0; 3]; JOINTS], tau: 2, bend_range_deg: None }
    }
}

/// Saturating `f64` -> finite `f32` (NaN stays NaN). Intermediate products are formed in `f64`,
/// where no product of a few `f32` values can overflow, so finite input always maps to a finite
/// pose (huge values saturate at `±f32::MAX` instead of becoming infinite, then NaN via `inf * 0`).
fn sat(v: f64) -> f32 {
    (v as f32).clamp(-f32::MAX, f32::MAX)
}

/// `G_i / G_R_i`, or 0 when the range is not a positive finite number (a validated calibration
/// never has such a range; this keeps unvalidated input from producing NaN).
fn bend_ratio(g_deg: f32, range_deg: f32) -> f64 {
    if range_deg > 0.0 && range_deg.is_finite() { g_deg as f64 / range_deg as f64 } else { 0.0 }
}

fn usable(v: f32) -> bool {
    v.is_finite() && v > 0.0
}

/// Eq. 2's root scale for wrist axis `axis` (0 = pitch, 1 = yaw) at the calibrated deflection
/// `w_deg`, calibrated per performer as seed 000, section 5.4 asks ("we also set s_i for
/// calibrating the bending of wrist and thumb in order to map the user's comfortable ranges ...
/// with his/her desired bending ranges of plant's joints"):
///
/// - when the rig declares `bend_range_deg` and the calibration measured the wrist
///   (`wrist_reach_deg`): `bend / reach`, with the reach on `w`'s side of the neutral (`max -
///   neutral` for `w >= 0`, `neutral - min` below), so the comfortable extremes map exactly to
///   `+bend` and `-bend` whoever performs; past them the bend keeps growing linearly (as Eq. 3's
///   `G_i / G_R_i` does past the thumb's range). This replaces the rig's `s_pitch(0)` /
///   `s_yaw(0)`;
/// - otherwise (either is missing, or a value is not a positive finite number, which a validated
///   rig and calibration never have): the rig's `s_pitch(0)` / `s_yaw(0)`, as before.
///
/// Another `axis` gets the rig's scale of that axis (roll: `s_roll(0)`), or 0 past it.
pub fn root_scale(params: &MappingParams, calibration: &CalibrationParams, axis: usize, w_deg: f32) -> f64 {
    let rig = params.scale[0].get(axis).map_or(0.0, |&s| s as f64);
    let bend = params.bend_range_deg.and_then(|b| b.get(axis).copied());
    let reach = calibration.wrist_reach_deg.and_then(|r| r.get(axis).copied());
    let (Some(bend), Some(reach)) = (bend, reach) else {
        return rig;
    };
    let reach = reach[usize::from(w_deg >= 0.0)];
    if usable(bend) && usable(reach) { bend as f64 / reach as f64 } else { rig }
}

/// Whether joint `i` twists: seed 000, Eq. 4, `P_roll(i) = 0` for `i = 0..=3 - tau`, so the top
/// `tau` joints twist. `tau >= 4` would make every joint twist (rigs refuse it).
pub fn is_twistable(i: usize, tau: u8) -> bool {
    i + tau as usize > JOINTS - 1
}

/// Maps one calibrated hand sample (`W` = wrist, `G_i` = thumb, seed 000 notation; the neutral is
/// already subtracted) to a pose. From the calibration it takes the thumb ranges `G_R_i` and the
/// wrist reach.
///
/// - Seed 000, Eq. 2: `P_pitch(0) = s_pitch(0) * W_pitch`, `P_yaw(0) = s_yaw(0) * W_yaw`, with
///   the root scales of [`root_scale`] (the rig's, or its bend range over the performer's
///   comfortable wrist reach, section 5.4).
/// - Seed 000, Eq. 3: for `i = 1..=3`, `P_pitch(i) = s_pitch(i) * P_pitch(0) * G_i / G_R_i`, and
///   the same for yaw. `G_i` is `hand.thumb_deg[i - 1]`, `G_R_i` is `thumb_range_deg[i - 1]`.
///   The upper joints follow the root's bending direction and scale with its magnitude.
/// - Seed 000, Eq. 4: `P_roll(i) = 0` for `i <= 3 - tau`, otherwise `s_roll(i) * W_roll`.
///   The seed writes `s_roll(0)` for every twisting joint; frond has a roll scale per joint,
///   which reduces to the seed's formula when all `s_roll(i)` are equal (the default rigs).
///
/// Output `t` is `hand.t`. Pure, no allocation, no panic for any input; finite input gives a
/// finite pose (huge values saturate at `±f32::MAX`).
pub fn map_pose(params: &MappingParams, calibration: &CalibrationParams, hand: &HandSample) -> PoseFrame {
    let s = &params.scale;
    let w = hand.wrist_deg;
    let thumb_range_deg = calibration.thumb_range_deg;
    // Eq. 2, kept in f64 for Eq. 3.
    let root_pitch = root_scale(params, calibration, 0, w[0]) * w[0] as f64;
    let root_yaw = root_scale(params, calibration, 1, w[1]) * w[1] as f64;
    let roll = w[2] as f64;

    let mut joints_deg = [[0.0f32; 3]; JOINTS];
    joints_deg[0][0] = sat(root_pitch);
    joints_deg[0][1] = sat(root_yaw);
    for (i, joint) in joints_deg.iter_mut().enumerate().skip(1) {
        // Eq. 3.
        let ratio = bend_ratio(hand.thumb_deg[i - 1], thumb_range_deg[i - 1]);
        joint[0] = sat(s[i][0] as f64 * root_pitch * ratio);
        joint[1] = sat(s[i][1] as f64 * root_yaw * ratio);
    }
    for (i, joint) in joints_deg.iter_mut().enumerate() {
        // Eq. 4.
        joint[2] = if is_twistable(i, params.tau) { sat(s[i][2] as f64 * roll) } else { 0.0 };
    }
    PoseFrame { t: hand.t, joints_deg }
}

/// Calibrate -> filter -> map, with its state (the filter history). `Copy`, no heap: the realtime
/// loop owns one by value, `frond map` another, and they compute identical poses from identical
/// samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mapper {
    mapping: MappingParams,
    calibration: CalibrationParams,
    filter: HandFilter,
    /// The previous sample's time, seconds (`None` before the first).
    last_t: Option<f64>,
    /// Whether the last processed sample broke the timeline.
    discontinuity: bool,
    /// Samples that broke the timeline so far.
    discontinuities: u64,
    /// The next sample breaks the timeline whatever its time.
    force_break: bool,
}

/// Largest forward step between two samples' times that is still one timeline, seconds: a
/// longer gap (a tracker paused or restarted with a new clock) is a discontinuity.
pub const MAX_TIME_STEP_S: f64 = 1.0;

/// Whether a sample at `t` after one at `last_t` (`None`: the first) starts a new timeline: the
/// step jumps forward over [`MAX_TIME_STEP_S`], goes back, repeats or is not finite. The one
/// rule for untrusted time, used by [`Mapper::process`] and by the replay source's pacing.
pub fn breaks_timeline(last_t: Option<f64>, t: f64) -> bool {
    let Some(last) = last_t else { return false };
    let dt = t - last;
    !(dt.is_finite() && dt > 0.0 && dt <= MAX_TIME_STEP_S)
}

impl Mapper {
    /// A mapper with a fresh filter.
    pub fn new(mapping: MappingParams, calibration: CalibrationParams, filter: FilterSpec) -> Self {
        Mapper {
            mapping,
            calibration,
            filter: HandFilter::new(filter),
            last_t: None,
            discontinuity: false,
            discontinuities: 0,
            force_break: false,
        }
    }

    /// Replaces the rig's mapping parameters (filter state kept).
    pub fn set_mapping(&mut self, mapping: MappingParams) {
        self.mapping = mapping;
    }

    /// Replaces the calibration. The filter state is kept, so a change of neutral is smoothed
    /// by an active filter rather than jumping.
    pub fn set_calibration(&mut self, calibration: CalibrationParams) {
        self.calibration = calibration;
    }

    /// Replaces the filter and resets its state (the next sample passes through).
    pub fn set_filter(&mut self, filter: FilterSpec) {
        self.filter = HandFilter::new(filter);
    }

    /// The running filter's spec.
    pub fn filter_spec(&self) -> FilterSpec {
        self.filter.spec()
    }

    /// The current mapping parameters.
    pub fn mapping(&self) -> MappingParams {
        self.mapping
    }

    /// The current calibration.
    pub fn calibration(&self) -> CalibrationParams {
        self.calibration
    }

    /// Forgets the filter history (e.g. after the device was lost).
    pub fn reset_filter(&mut self) {
        self.filter.reset();
    }

    /// Whether the sample last processed broke the timeline (see [`Mapper::process`]).
    pub fn discontinuity(&self) -> bool {
        self.discontinuity
    }

    /// Samples that broke the timeline since this mapper was made.
    pub fn discontinuities(&self) -> u64 {
        self.discontinuities
    }

    /// Marks the next sample as a discontinuity whatever its time (the loop resumed after a
    /// pause and skipped stale reports): the filter starts afresh there.
    pub fn break_timeline(&mut self) {
        self.force_break = true;
    }

    /// Processes one raw sample: calibrate (`W = wrist - neutral`, `G_i = thumb_i - neutral_i`),
    /// filter, then map (seed 000, Eq. 2-4). Returns the calibrated-and-filtered sample and the
    /// pose. Never allocates, never panics; finite input gives finite output.
    ///
    /// Time is untrusted input: a sample whose time goes backwards, repeats, is not finite or
    /// jumps forward by more than [`MAX_TIME_STEP_S`] starts a new timeline. The filter is
    /// reset there (the sample passes through), so one absurd timestamp or a tracker that
    /// restarts its clock cannot freeze the filter; [`Mapper::discontinuity`] says so and
    /// [`Mapper::discontinuities`] counts it. The live loop and `frond map` share this rule.
    pub fn process(&mut self, raw: &HandSample) -> (HandSample, PoseFrame) {
        self.discontinuity = std::mem::take(&mut self.force_break) || breaks_timeline(self.last_t, raw.t);
        if self.discontinuity {
            self.discontinuities += 1;
            self.filter.reset();
        }
        self.last_t = Some(raw.t);
        let calibrated = self.calibration.apply(raw);
        let filtered = self.filter.apply(&calibrated);
        let pose = map_pose(&self.mapping, &self.calibration, &filtered);
        (filtered, pose)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hand(wrist: [f32; 3], thumb: [f32; 3]) -> HandSample {
        HandSample { t: 0.5, wrist_deg: wrist, thumb_deg: thumb }
    }

    #[test]
    fn a_time_that_jumps_goes_back_or_repeats_resets_the_filter_instead_of_freezing_it() {
        let params = MappingParams::default();
        let cal = CalibrationParams::neutral([60.0, 70.0, 60.0]);
        let mut m = Mapper::new(params, cal, FilterSpec::LowPass { cutoff_hz: 1.0 });
        let at = |t: f64, w: f32| HandSample { t, wrist_deg: [w, 0.0, 0.0], thumb_deg: [0.0; 3] };
        // A steady 10 deg at 100 Hz, then one absurd timestamp carrying 50 deg.
        for i in 0..100 {
            m.process(&at(f64::from(i) * 0.01, 10.0));
            assert!(!m.discontinuity());
        }
        let (h, _) = m.process(&at(1e9, 50.0));
        assert!(m.discontinuity(), "a jump of 1e9 s is a new timeline");
        assert_eq!(h.wrist_deg[0], 50.0, "the filter was reset: the sample passes through");
        // The tracker's clock is back near 1 s: backwards, so a new timeline again, and the
        // filter follows the hand from there (before the fix it held 50 deg for ever).
        let (h, _) = m.process(&at(1.01, 20.0));
        assert!(m.discontinuity());
        assert_eq!(h.wrist_deg[0], 20.0);
        let (h, _) = m.process(&at(1.02, 20.0));
        assert!(!m.discontinuity());
        assert_eq!(h.wrist_deg[0], 20.0);
        // A repeated time and a NaN time break it too; a forward step of exactly 1 s does not.
        m.process(&at(1.02, 20.0));
        assert!(m.discontinuity());
        m.process(&at(f64::NAN, 20.0));
        assert!(m.discontinuity());
        m.process(&at(5.0, 20.0));
        assert!(m.discontinuity(), "after NaN the next time starts a timeline");
        m.process(&at(6.0, 20.0));
        assert!(!m.discontinuity());
        assert_eq!(m.discontinuities(), 5);
        m.break_timeline();
        m.process(&at(6.01, 20.0));
        assert!(m.discontinuity(), "a forced break");
    }

    #[test]
    fn twistable_joints_by_tau() {
        // Eq. 4: zero for i = 0..=3-tau.
        let twist = |tau| (0..4).map(|i| is_twistable(i, tau)).collect::<Vec<_>>();
        assert_eq!(twist(0), [false, false, false, false]);
        assert_eq!(twist(1), [false, false, false, true]);
        assert_eq!(twist(2), [false, false, true, true]);
        assert_eq!(twist(3), [false, true, true, true]);
    }

    #[test]
    fn unit_scales_tau_2_by_hand() {
        // W = (20, -10, 30), G = (30, 35, 15), G_R = (60, 70, 60): ratios 0.5, 0.5, 0.25.
        // Eq. 2: P0 = (20, -10). Eq. 3: P1 = P2 = (10, -5), P3 = (5, -2.5).
        // Eq. 4 (tau 2): roll 0, 0, 30, 30.
        let p = map_pose(
            &MappingParams::default(),
            &CalibrationParams::neutral([60.0, 70.0, 60.0]),
            &hand([20.0, -10.0, 30.0], [30.0, 35.0, 15.0]),
        );
        assert_eq!(p.t, 0.5);
        assert_eq!(
            p.joints_deg,
            [[20.0, -10.0, 0.0], [10.0, -5.0, 0.0], [10.0, -5.0, 30.0], [5.0, -2.5, 30.0]]
        );
    }

    #[test]
    fn root_scale_maps_the_comfortable_reach_onto_the_bend_range() {
        // Reach below/above neutral: pitch 40 / 60, yaw 20 / 30. Bend range: pitch 30, yaw 15.
        let params = MappingParams { bend_range_deg: Some([30.0, 15.0]), ..MappingParams::default() };
        let cal = CalibrationParams {
            wrist_reach_deg: Some([[40.0, 60.0], [20.0, 30.0]]),
            ..CalibrationParams::neutral([60.0; 3])
        };
        assert_eq!(root_scale(&params, &cal, 0, 60.0), 0.5); // +60 -> +30
        assert_eq!(root_scale(&params, &cal, 0, -40.0), 0.75); // -40 -> -30
        assert_eq!(root_scale(&params, &cal, 1, 30.0), 0.5); // +30 -> +15
        assert_eq!(root_scale(&params, &cal, 1, -20.0), 0.75); // -20 -> -15
        assert_eq!(root_scale(&params, &cal, 0, 0.0), 0.5);
        // Past the comfortable extreme the bend keeps growing linearly: +120 -> +60.
        let p = map_pose(&params, &cal, &hand([120.0, -20.0, 0.0], [0.0; 3]));
        assert_eq!(p.joints_deg[0], [60.0, -15.0, 0.0]);
        // Without a bend range, or without a measured wrist, the rig's s(0) (here 1).
        let plain = MappingParams::default();
        assert_eq!(root_scale(&plain, &cal, 0, 60.0), 1.0);
        assert_eq!(root_scale(&params, &CalibrationParams::neutral([60.0; 3]), 0, 60.0), 1.0);
        // Unusable values (never validated) fall back instead of dividing by zero.
        let zero = CalibrationParams { wrist_reach_deg: Some([[0.0, 60.0], [20.0, f32::NAN]]), ..cal };
        assert_eq!(root_scale(&params, &zero, 0, -5.0), 1.0);
        assert_eq!(root_scale(&params, &zero, 0, 5.0), 0.5);
        assert_eq!(root_scale(&params, &zero, 1, 5.0), 1.0);
        // Not a bend axis: the rig's scale, never a panic.
        assert_eq!(root_scale(&params, &cal, 2, 5.0), 1.0);
        assert_eq!(root_scale(&params, &cal, 7, 5.0), 0.0);
    }

    #[test]
    fn zero_range_does_not_make_nan() {
        let p = map_pose(
            &MappingParams::default(),
            &CalibrationParams::neutral([0.0, f32::NAN, -1.0]),
            &hand([10.0; 3], [5.0; 3]),
        );
        for j in &p.joints_deg[1..] {
            assert_eq!(j[0], 0.0);
            assert_eq!(j[1], 0.0);
        }
    }
}
