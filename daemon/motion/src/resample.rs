//! The one frame-count rule of every fixed-rate output ([`frame_count`]) and the resampling of
//! poses onto it ([`resample`]). Takes, clips, loops, edits and exports all count and resample
//! frames here, so the rule lives in one place that none of them has to import the others for.
//!
//! Time ([`resample`]): a step between two frames of more than [`MAX_INTERPOLATED_GAP_S`], or
//! backwards, is a discontinuity: the resampled frames jump across it (the frame after the gap
//! follows one output frame later) instead of interpolating hours of frames. [`resample_plan`]
//! counts the output before anything is allocated, so callers can refuse past a budget.

use thiserror::Error;

use crate::sample::PoseFrame;

/// Upper bound on the number of frames [`resample`] produces (about 6 days at 30 FPS).
pub const MAX_RESAMPLED_FRAMES: usize = 1 << 24;
/// The longest step between two frames that [`resample`] interpolates across, seconds; a longer
/// (or backwards) step is a discontinuity.
pub const MAX_INTERPOLATED_GAP_S: f64 = 1.0;

/// How far, in frames, a duration may fall short of a frame and still reach it
/// ([`frame_count`]). Time stamps written with six decimals (as `frond take export --jsonl`
/// writes them and `frond take import` reads them back) are each off by up to 0.5 µs, so a
/// duration is off by up to 1 µs: 0.01 frame at 10 kHz, the highest rate any `--fps` accepts. A
/// twentieth of a frame covers that with room to spare; the frame it admits lies at most 1/20
/// of a frame past the last sample, where the last pose is held.
pub const FRAME_TOLERANCE: f64 = 0.05;

/// The one frame-count rule of every fixed-rate output (`--fps` resampling and export, retiming,
/// loops, baked keys): frames `k = 0, 1, ...` at `t = k / fps` for every `k` with
/// `k <= duration_s * fps + FRAME_TOLERANCE`, i.e. `floor(duration_s * fps + FRAME_TOLERANCE) +
/// 1`. A sequence of `n` frames at `fps` therefore comes back as `n` frames even when its last
/// time stamp was rounded down a little. A zero, negative or non-finite duration gives 1 frame
/// (a single pose); a non-positive or non-finite `fps` gives 0. At most
/// [`MAX_RESAMPLED_FRAMES`].
pub fn frame_count(duration_s: f64, fps: f64) -> usize {
    usize::try_from(frames_needed(duration_s, fps)).unwrap_or(usize::MAX).min(MAX_RESAMPLED_FRAMES)
}

/// [`frame_count`] without its cap (saturating at `u64::MAX`): what an output would need, to
/// refuse it before anything is computed rather than cut it short.
pub fn frames_needed(duration_s: f64, fps: f64) -> u64 {
    if !(fps.is_finite() && fps > 0.0) {
        return 0;
    }
    if !(duration_s.is_finite() && duration_s > 0.0) {
        return 1;
    }
    // `as` saturates: a product past u64's range (or infinite) counts as u64::MAX frames.
    ((duration_s * fps + FRAME_TOLERANCE).floor() as u64).saturating_add(1)
}
/// What [`resample`] will produce, counted without allocating.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ResamplePlan {
    /// Output frames (not capped at [`MAX_RESAMPLED_FRAMES`]; saturating).
    pub frames: u64,
    /// Output duration, seconds, discontinuities collapsed.
    pub duration_s: f64,
    /// Steps treated as discontinuities (longer than [`MAX_INTERPOLATED_GAP_S`], or backwards).
    pub discontinuities: u64,
    /// Index of the input frame after the first discontinuity.
    pub first_discontinuity: Option<usize>,
    /// The largest forward step between two input frames, seconds.
    pub largest_gap_s: f64,
}

/// A resampling budget that was exceeded.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("resampling at {fps} FPS gives {frames} frames, more than the limit of {limit}")]
pub struct TooManyFrames {
    /// Frames the resampling would give.
    pub frames: u64,
    /// The rate asked for.
    pub fps: f64,
    /// The limit.
    pub limit: u64,
}

impl ResamplePlan {
    /// `Err` when the output would be more than `limit` frames.
    pub fn check(&self, fps: f64, limit: u64) -> Result<(), TooManyFrames> {
        if self.frames > limit { Err(TooManyFrames { frames: self.frames, fps, limit }) } else { Ok(()) }
    }
}

/// The step between two input times that [`resample`] uses: the real one, or one output frame
/// (`1 / fps`) across a discontinuity. 0 for a repeated time.
fn effective_step(prev: f64, t: f64, fps: f64, max_gap_s: f64) -> (f64, bool) {
    let dt = t - prev;
    if dt.is_finite() && (0.0..=max_gap_s).contains(&dt) { (dt, false) } else { (1.0 / fps, true) }
}

/// Counts what [`resample`] of `frames` at `fps` gives, before anything is allocated.
pub fn resample_plan(frames: &[PoseFrame], fps: f64) -> ResamplePlan {
    let mut plan = ResamplePlan::default();
    if frames.is_empty() || !(fps.is_finite() && fps > 0.0) {
        return plan;
    }
    for (i, w) in frames.windows(2).enumerate() {
        let dt = w[1].t - w[0].t;
        if dt.is_finite() && dt > plan.largest_gap_s {
            plan.largest_gap_s = dt;
        }
        let (step, jump) = effective_step(w[0].t, w[1].t, fps, MAX_INTERPOLATED_GAP_S);
        plan.duration_s += step;
        if jump {
            plan.discontinuities += 1;
            plan.first_discontinuity.get_or_insert(i + 1);
        }
    }
    let last = (plan.duration_s * fps + FRAME_TOLERANCE).floor();
    plan.frames = if plan.duration_s > 0.0 && last.is_finite() {
        if last >= u64::MAX as f64 { u64::MAX } else { last as u64 + 1 }
    } else {
        1
    };
    plan
}

/// Resamples poses at a fixed rate by linear interpolation of every angle.
///
/// Output frame `k` has `t = k / fps`, relative to the first input frame, for every
/// `k / fps <= duration` up to a twentieth of a frame (the one rule of
/// [`frame_count`]), so the take's whole duration is covered, the output starts at
/// 0, and `n` frames at `fps` with rounded time stamps resample to `n` frames.
/// A frame whose time repeats the previous one replaces it. A step of more than
/// [`MAX_INTERPOLATED_GAP_S`], or backwards (a tracker that restarted), is a discontinuity: the
/// output jumps from the frame before it to the frame after it in one output frame, so a gap
/// of hours costs one frame, not hours of interpolated ones. Empty input gives empty output; one
/// frame gives one frame at `t = 0`; a non-positive or non-finite `fps` gives empty output. At
/// most [`MAX_RESAMPLED_FRAMES`] (see [`resample_plan`] to refuse before that).
pub fn resample(frames: &[PoseFrame], fps: f64) -> Vec<PoseFrame> {
    resample_with_gap(frames, fps, MAX_INTERPOLATED_GAP_S)
}

/// [`resample`] interpolating across every forward gap, however long: for callers that have
/// already collapsed discontinuities on a time line several layers share (a layer that starts
/// late holds its first pose until then). Backwards steps are still discontinuities. The
/// caller bounds the output (`frame_count` of the span) before calling.
pub fn resample_across_gaps(frames: &[PoseFrame], fps: f64) -> Vec<PoseFrame> {
    resample_with_gap(frames, fps, f64::INFINITY)
}

fn resample_with_gap(frames: &[PoseFrame], fps: f64, max_gap_s: f64) -> Vec<PoseFrame> {
    if frames.is_empty() || !(fps.is_finite() && fps > 0.0) {
        return Vec::new();
    }
    // Each input frame's time on the output's time line (discontinuities collapsed).
    let mut te = Vec::with_capacity(frames.len());
    te.push(0.0);
    for w in frames.windows(2) {
        let prev = te[te.len() - 1];
        te.push(prev + effective_step(w[0].t, w[1].t, fps, max_gap_s).0);
    }
    let duration = te[te.len() - 1];
    let count = frame_count(duration, fps);
    let mut out = Vec::with_capacity(count);
    let mut j = 0; // frames[j] is the last frame at or before the target time
    for k in 0..count {
        let t = k as f64 / fps;
        while j + 1 < frames.len() && te[j + 1] <= t {
            j += 1;
        }
        let a = &frames[j];
        let mut joints_deg = a.joints_deg;
        if let Some(b) = (j + 1..frames.len()).find(|&b| te[b] > te[j]) {
            let u = ((t - te[j]) / (te[b] - te[j])).clamp(0.0, 1.0);
            for (o, (pa, pb)) in joints_deg.iter_mut().zip(a.joints_deg.iter().zip(&frames[b].joints_deg)) {
                for c in 0..3 {
                    let (x, y) = (pa[c] as f64, pb[c] as f64);
                    o[c] = (x + u * (y - x)) as f32;
                }
            }
        }
        out.push(PoseFrame { t, joints_deg });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::JOINTS;

    #[test]
    fn frame_count_by_hand() {
        // 200 frames at 30 FPS whose last stamp was written with six decimals: 199 / 30 =
        // 6.6333...3 became 6.633333, 198.99999 frames; it still reaches frame 199.
        assert_eq!(frame_count(6.633333, 30.0), 200);
        assert_eq!(frame_count(199.0 / 30.0, 30.0), 200);
        // Rounded up instead (2.966667 for 89 / 30): no extra frame.
        assert_eq!(frame_count(2.966667, 30.0), 90);
        // Within a twentieth of a frame of the next frame reaches it; further short does not.
        assert_eq!(frame_count(1.0 - 0.04 / 30.0, 30.0), 31);
        assert_eq!(frame_count(1.0 - 0.06 / 30.0, 30.0), 30);
        // Between frames: up to the last whole frame.
        assert_eq!(frame_count(1.02, 30.0), 31);
        assert_eq!(frame_count(1.049, 30.0), 32); // 31.47 frames
        assert_eq!(frame_count(20.0, 30.0), 601);
        // Degenerate input.
        assert_eq!(frame_count(0.0, 30.0), 1);
        assert_eq!(frame_count(-1.0, 30.0), 1);
        assert_eq!(frame_count(f64::NAN, 30.0), 1);
        assert_eq!(frame_count(f64::INFINITY, 30.0), 1);
        assert_eq!(frame_count(1.0, 0.0), 0);
        assert_eq!(frame_count(1.0, f64::NAN), 0);
        assert_eq!(frame_count(1e30, 30.0), MAX_RESAMPLED_FRAMES);
        assert_eq!(frames_needed(1e30, 30.0), u64::MAX);
        // 3.5 s at speed 1e-9 and 30 FPS: 1.05e11 frames, one more for t = 0.
        assert_eq!(frames_needed(3.5e9, 30.0), 105_000_000_001);
        assert_eq!((frames_needed(0.0, 30.0), frames_needed(1.0, 0.0)), (1, 0));
    }

    proptest::proptest! {
        /// `n` frames at a common rate, stamped with six decimals the way JSONL export writes
        /// them (rounded to the microsecond, either way), count as `n` frames again.
        #[test]
        fn rounded_stamps_keep_their_frame_count(
            n in 1usize..=20_000,
            fps in proptest::sample::select(vec![24.0, 25.0, 29.97, 30.0, 48.0, 50.0, 60.0, 120.0, 1000.0, 10_000.0]),
            t0_us in 0u64..10_000_000_000,
        ) {
            let stamp = |k: usize| ((t0_us as f64 / 1e6 + k as f64 / fps) * 1e6).round() / 1e6;
            let d = stamp(n - 1) - stamp(0);
            proptest::prop_assert_eq!(frame_count(d, fps), n, "duration {}", d);
        }
    }

    fn pose(t: f64, v: f32) -> PoseFrame {
        PoseFrame { t, joints_deg: [[v, -v, 2.0 * v]; JOINTS] }
    }

    #[test]
    fn resample_by_hand() {
        // Frames at t = 10.0, 10.1, 10.2 with value 0, 1, 4. At 20 FPS: targets 0, 0.05, 0.1,
        // 0.15, 0.2 -> values 0, 0.5, 1, 2.5, 4.
        let frames = [pose(10.0, 0.0), pose(10.1, 1.0), pose(10.2, 4.0)];
        let out = resample(&frames, 20.0);
        let got: Vec<(f64, f32)> = out.iter().map(|p| (p.t, p.joints_deg[1][0])).collect();
        let want = [(0.0, 0.0), (0.05, 0.5), (0.1, 1.0), (0.15, 2.5), (0.2, 4.0)];
        assert_eq!(got.len(), want.len(), "{got:?}");
        for ((t, v), (wt, wv)) in got.iter().zip(want) {
            assert!((t - wt).abs() < 1e-12);
            assert!((v - wv).abs() < 1e-5, "{got:?}");
        }
        assert!((out[3].joints_deg[2][1] + 2.5).abs() < 1e-5);
        assert!((out[3].joints_deg[0][2] - 5.0).abs() < 1e-5);
    }

    #[test]
    fn resample_edge_cases() {
        assert!(resample(&[], 30.0).is_empty());
        let one = resample(&[pose(5.0, 3.0)], 30.0);
        assert_eq!(one, vec![pose(0.0, 3.0)]);
        assert!(resample(&[pose(0.0, 1.0), pose(1.0, 2.0)], 0.0).is_empty());
        assert!(resample(&[pose(0.0, 1.0), pose(1.0, 2.0)], f64::NAN).is_empty());
        // Duplicate timestamps: the later frame wins, no NaN from a zero-length interval.
        let out = resample(&[pose(0.0, 1.0), pose(0.5, 2.0), pose(0.5, 3.0), pose(1.0, 4.0)], 4.0);
        let v: Vec<f32> = out.iter().map(|p| p.joints_deg[0][0]).collect();
        // t = 0, .25, .5, .75, 1 -> 1, 1.5, 3, 3.5, 4
        assert_eq!(v.len(), 5);
        for (a, b) in v.iter().zip([1.0, 1.5, 3.0, 3.5, 4.0]) {
            assert!((a - b).abs() < 1e-6, "{v:?}");
        }
    }

    #[test]
    fn a_gap_in_time_is_a_discontinuity_not_interpolated_frames() {
        // Two frames at t = 0 and t = 1e9 (a tracker clock that jumped): at 30 FPS they are two
        // frames, the second one output frame after the first, each exactly an input pose.
        let frames = [pose(0.0, 1.0), pose(1e9, 5.0)];
        let plan = resample_plan(&frames, 30.0);
        assert_eq!(plan.frames, 2);
        assert_eq!(plan.discontinuities, 1);
        assert_eq!(plan.first_discontinuity, Some(1));
        assert_eq!(plan.largest_gap_s, 1e9);
        let out = resample(&frames, 30.0);
        assert_eq!(out, vec![pose(0.0, 1.0), pose(1.0 / 30.0, 5.0)]);
        // Backwards (a restarted clock) too; steps up to the limit are interpolated as before.
        let back = [pose(100.0, 1.0), pose(100.5, 2.0), pose(3.0, 7.0), pose(3.5, 9.0)];
        let plan = resample_plan(&back, 10.0);
        assert_eq!((plan.discontinuities, plan.first_discontinuity), (1, Some(2)));
        // 0.5 s + one frame (0.1 s) + 0.5 s = 1.1 s at 10 FPS: 12 frames.
        assert_eq!(plan.frames, 12);
        let out = resample(&back, 10.0);
        assert_eq!(out.len(), 12);
        let v: Vec<f32> = out.iter().map(|p| p.joints_deg[0][0]).collect();
        assert!((v[5] - 2.0).abs() < 1e-6 && (v[6] - 7.0).abs() < 1e-6, "{v:?}");
        assert!((v[11] - 9.0).abs() < 1e-6, "{v:?}");
        let exactly = [pose(0.0, 0.0), pose(MAX_INTERPOLATED_GAP_S, 10.0)];
        assert_eq!(resample_plan(&exactly, 10.0).discontinuities, 0);
        assert_eq!(resample(&exactly, 10.0).len(), 11);
    }

    #[test]
    fn the_plan_counts_before_allocating_and_checks_a_budget() {
        // 0..3600 s in steps of 1 s at 1000 FPS: 3.6 million frames and a bit.
        let frames: Vec<PoseFrame> = (0..=3600).map(|i| pose(i as f64, 0.0)).collect();
        let plan = resample_plan(&frames, 1000.0);
        assert_eq!(plan.frames, 3_600_001);
        assert_eq!(plan.discontinuities, 0);
        let err = plan.check(1000.0, 1_000_000).unwrap_err();
        assert_eq!(err, TooManyFrames { frames: 3_600_001, fps: 1000.0, limit: 1_000_000 });
        assert!(err.to_string().contains("limit of 1000000"), "{err}");
        assert!(plan.check(1000.0, 3_600_001).is_ok());
        assert_eq!(resample_plan(&[], 30.0).frames, 0);
        assert_eq!(resample_plan(&frames[..1], 30.0).frames, 1);
    }
}
