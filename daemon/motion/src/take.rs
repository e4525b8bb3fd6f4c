//! A take as data: its header, its frames and what a reader found in it ([`TakeScan`]), and the
//! resampling of its poses at a fixed rate. The take file's bytes (records, checksums, the
//! reader and writer) are `frond_formats::take`.
//!
//! Time ([`resample`]): a step between two frames of more than [`MAX_INTERPOLATED_GAP_S`], or
//! backwards, is a discontinuity: the resampled frames jump across it (the frame after the gap
//! follows one output frame later) instead of interpolating hours of frames. [`resample_plan`]
//! counts the output before anything is allocated, so callers can refuse past a budget.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::sample::{HandSample, PoseFrame};

/// Upper bound on the number of frames [`resample`] produces (about 6 days at 30 FPS).
pub const MAX_RESAMPLED_FRAMES: usize = 1 << 24;
/// The longest step between two frames that [`resample`] interpolates across, seconds; a longer
/// (or backwards) step is a discontinuity.
pub const MAX_INTERPOLATED_GAP_S: f64 = 1.0;

/// Take metadata, the first record (JSON, so it can grow; unknown fields are ignored).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TakeHeader {
    /// Take name (file stem).
    pub name: String,
    /// Rig the take was recorded with.
    pub rig_name: String,
    /// Calibration id (`none` for the neutral default).
    pub calibration_id: String,
    /// Filter spec text (`FilterSpec` display form).
    pub filter: String,
    /// Daemon tick rate, Hz.
    pub tick_rate_hz: u32,
    /// Creation time, Unix seconds.
    pub created_unix_s: u64,
    /// `frondd` version.
    pub daemon_version: String,
    /// Rig joint names, root first.
    pub joint_names: Vec<String>,
    /// The host's clocks read together when recording began, so that a frame's `host_ns` has a
    /// wall-clock time (and timecode); absent in takes made offline or before frond wrote it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock: Option<TakeClock>,
    /// For a take recorded from a stage over Zenoh (`frond record start NAME --stage STAGE`):
    /// where it came from and how its host's clock compared with the recorder's. Its `clock` is
    /// then on the recorder's clock already (the offset subtracted), so the takes of one
    /// recording share one timeline.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stage: Option<TakeStage>,
}

/// Where a stage take came from (issue 20), see [`TakeHeader::stage`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TakeStage {
    /// The stage's name.
    pub stage: String,
    /// The source (performer) on it.
    pub source: String,
    /// The source host's realtime clock minus the recorder's, nanoseconds, as measured.
    pub clock_offset_ns: i64,
    /// How far that measurement may be off (half its round trip), nanoseconds.
    pub clock_uncertainty_ns: u64,
}

impl TakeHeader {
    /// The header of a take made away from a daemon (a simulation, an import, a test): the
    /// neutral calibration (`none`), no filter (`none`), no creation time (0), no recording
    /// clock and no stage; `daemon_version` names this crate's version. Change what differs
    /// with struct update syntax: `TakeHeader { joint_names, ..TakeHeader::offline(..) }`.
    pub fn offline(name: &str, rig_name: &str, tick_rate_hz: u32) -> TakeHeader {
        TakeHeader {
            name: name.to_string(),
            rig_name: rig_name.to_string(),
            calibration_id: "none".to_string(),
            filter: "none".to_string(),
            tick_rate_hz,
            created_unix_s: 0,
            daemon_version: concat!("frond ", env!("CARGO_PKG_VERSION"), " (offline)").to_string(),
            joint_names: Vec::new(),
            clock: None,
            stage: None,
        }
    }

    /// SMPTE timecode, at `fps`, of the first kept main-skeleton frame of `frames` (the first
    /// frame of every export: held frames are skipped), when the take knows its recording clock.
    pub fn start_timecode(&self, frames: &[TakeFrame], fps: f64) -> Option<crate::timecode::Timecode> {
        let clock = self.clock?;
        let main = main_element(frames)?;
        let first = frames.iter().find(|f| f.element == main && f.flags & crate::layers::FLAG_HELD == 0)?;
        clock.timecode_of(first.host_ns, fps)
    }
}

/// The element a take's motion is read from by the tools that read one stream of poses (`take
/// list`, `take export`, alignment, previews): the plant (element 0) when the take has any frame
/// of it, else the lowest secondary element it has. A take of `frond record layer` holds only its
/// layer's frames (the hand published as, say, `leaf`): that layer is its motion. `None` for a
/// take without frames.
pub fn main_element(frames: &[TakeFrame]) -> Option<u16> {
    frames.iter().map(|f| f.element).min()
}

/// The host's wall clock and monotonic clock read together: a frame stamped `host_ns`
/// (CLOCK_MONOTONIC) happened at Unix time `unix_ns + (host_ns - self.host_ns)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct TakeClock {
    /// CLOCK_REALTIME, nanoseconds since 1970.
    pub unix_ns: u64,
    /// CLOCK_MONOTONIC at the same instant, nanoseconds.
    pub host_ns: u64,
}

impl TakeClock {
    /// Unix time of a frame stamped `host_ns` (monotonic).
    pub fn unix_ns_of(&self, host_ns: u64) -> u64 {
        let d = i128::from(host_ns) - i128::from(self.host_ns);
        (i128::from(self.unix_ns) + d).clamp(0, i128::from(u64::MAX)) as u64
    }

    /// SMPTE timecode (UTC time of day) of a frame stamped `host_ns`, at `fps`.
    pub fn timecode_of(&self, host_ns: u64, fps: f64) -> Option<crate::timecode::Timecode> {
        let rate = crate::timecode::nominal_rate(fps).ok()?;
        Some(crate::timecode::Timecode::from_unix_ns(self.unix_ns_of(host_ns), rate))
    }
}

/// One recorded tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TakeFrame {
    /// Published sequence number.
    pub seq: u64,
    /// Device timestamp, microseconds.
    pub device_time_us: u64,
    /// Host CLOCK_MONOTONIC, nanoseconds.
    pub host_ns: u64,
    /// Protocol pose flags (`held`, `device_lost`, `filtered`, ...).
    pub flags: u32,
    /// 0 for the main skeleton, `k + 1` for secondary element `k` of the rig.
    pub element: u16,
    /// The mapped pose.
    pub pose: PoseFrame,
    /// The calibrated and filtered hand sample it came from.
    pub hand: HandSample,
}

/// Everything read from a take.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TakeScan {
    /// The header, if the file got that far.
    pub header: Option<TakeHeader>,
    /// All frames, in file order.
    pub frames: Vec<TakeFrame>,
    /// Markers as `(seq, label)`, in file order.
    pub markers: Vec<(u64, String)>,
    /// True when the End record was read (the take was closed cleanly).
    pub ended: bool,
    /// Bytes up to the end of the last good record (0 if even the magic is incomplete).
    pub valid_len: u64,
    /// Bytes after `valid_len` that do not form a whole record (torn or still being written).
    pub torn_bytes: u64,
    /// Damaged stretches skipped in the middle of the file, in file order (empty for a sound take).
    pub skipped: Vec<Skipped>,
    /// The frame count of the End record, when there is one.
    pub end_frames: Option<u64>,
}

/// A stretch of a take the reader could not use and skipped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Skipped {
    /// Where it starts (byte offset from the start of the file).
    pub offset: u64,
    /// Its length in bytes; the next record starts at `offset + len`.
    pub len: u64,
    /// Why (`checksum mismatch`, `implausible record length 99999999`, a non-finite value).
    pub reason: String,
    /// Frames known to be lost with it: 1 for a non-finite frame dropped by
    /// `frond_formats::take::scan_take_salvaging`, 0 for damaged bytes (whose content cannot be told).
    pub frames: u64,
}

impl std::fmt::Display for Skipped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} bytes at offset {} ({})", self.len, self.offset, self.reason)
    }
}

impl TakeScan {
    /// The element the take's motion is read from ([`main_element`]): 0, or the layer of a
    /// layer take.
    pub fn main_element(&self) -> Option<u16> {
        main_element(&self.frames)
    }

    /// Frames of [`TakeScan::main_element`], held ones included: what `frond take list` counts.
    pub fn main_frame_count(&self) -> u64 {
        let main = self.main_element();
        self.frames.iter().filter(|f| Some(f.element) == main).count() as u64
    }

    /// The poses of the main skeleton (element 0; a layer take's layer, see [`main_element`]),
    /// in order.
    pub fn poses(&self) -> Vec<PoseFrame> {
        self.main_poses(true)
    }

    /// The poses of the main skeleton (a layer take's layer, see [`main_element`]), in order,
    /// held frames (no new report) left out unless `include_held`: what `frond take export`
    /// prints.
    pub fn main_poses(&self, include_held: bool) -> Vec<PoseFrame> {
        let main = self.main_element();
        self.frames
            .iter()
            .filter(|f| Some(f.element) == main && (include_held || f.flags & crate::layers::FLAG_HELD == 0))
            .map(|f| f.pose)
            .collect()
    }

    /// Time from the first to the last main-skeleton pose (a layer take's layer, see
    /// [`main_element`]), seconds (0 with fewer than two).
    pub fn duration_s(&self) -> f64 {
        let id = self.main_element();
        let mut main = self.frames.iter().filter(|f| Some(f.element) == id);
        match (main.next(), main.next_back()) {
            (Some(a), Some(b)) => b.pose.t - a.pose.t,
            _ => 0.0,
        }
    }

    /// The take's state as `frond take list` names it, for a file of `size` bytes: `empty`,
    /// `damaged` (stretches skipped), `torn` (a torn tail), `complete` (End record) or `open`.
    pub fn state(&self, size: u64) -> &'static str {
        if size == 0 {
            "empty"
        } else if !self.skipped.is_empty() {
            "damaged"
        } else if self.torn_bytes > 0 {
            "torn"
        } else if self.ended {
            "complete"
        } else {
            "open"
        }
    }
}

impl TakeScan {
    /// Frames known to be lost in skipped stretches (non-finite frames dropped).
    pub fn lost_frames(&self) -> u64 {
        self.skipped.iter().map(|s| s.frames).sum()
    }

    /// Bytes in skipped stretches.
    pub fn skipped_bytes(&self) -> u64 {
        self.skipped.iter().map(|s| s.len).sum()
    }

    /// What was skipped, in words: `3 damaged stretches skipped (381 bytes; the first 127 bytes at
    /// offset 1016 (checksum mismatch)), 3 frames lost`; `None` for a sound take.
    pub fn damage(&self) -> Option<String> {
        let first = self.skipped.first()?;
        let n = self.skipped.len();
        let lost = self.missing_frames() + self.lost_frames();
        // Without an End record the frames in damaged bytes cannot be counted.
        let lost = if self.ended || lost > 0 {
            format!(", {lost} frame{} lost", if lost == 1 { "" } else { "s" })
        } else {
            String::new()
        };
        Some(format!(
            "{n} damaged stretch{} skipped ({} bytes; {}{first}){lost}",
            if n == 1 { "" } else { "es" },
            self.skipped_bytes(),
            if n == 1 { "" } else { "the first " },
        ))
    }

    /// Frames the End record counts that this scan neither read nor skipped as non-finite
    /// (lost in damaged stretches; 0 without an End record: unknown).
    pub fn missing_frames(&self) -> u64 {
        self.end_frames.map_or(0, |n| n.saturating_sub(self.frames.len() as u64 + self.lost_frames()))
    }
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
    let last = (plan.duration_s * fps + crate::clip::FRAME_TOLERANCE).floor();
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
/// [`crate::clip::frame_count`]), so the take's whole duration is covered, the output starts at
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
    let count = crate::clip::frame_count(duration, fps);
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

    fn at(element: u16, t: f64, flags: u32) -> TakeFrame {
        TakeFrame { element, flags, pose: PoseFrame { t, ..PoseFrame::default() }, ..TakeFrame::default() }
    }

    #[test]
    fn a_layer_take_reads_as_its_layer() {
        // `frond record layer` writes only the layer's frames (here element 2); 4 frames over
        // 0.25..1.0 s, one of them held.
        let frames =
            vec![at(2, 0.25, 0), at(2, 0.5, crate::layers::FLAG_HELD), at(2, 0.75, 0), at(2, 1.0, 0)];
        let scan = TakeScan { frames, ..TakeScan::default() };
        assert_eq!(scan.main_element(), Some(2));
        assert_eq!(scan.main_frame_count(), 4);
        assert_eq!(scan.duration_s(), 0.75);
        let t: Vec<f64> = scan.main_poses(false).iter().map(|p| p.t).collect();
        assert_eq!(t, [0.25, 0.75, 1.0]);
        assert_eq!(scan.poses().len(), 4);
    }

    #[test]
    fn a_layered_take_reads_as_its_plant() {
        // The plant (element 0) over 0..2 s and a leaf (element 1) over 0..0.5 s: the plant.
        let frames = vec![at(1, 0.0, 0), at(0, 0.0, 0), at(1, 0.5, 0), at(0, 2.0, 0)];
        let scan = TakeScan { frames, ..TakeScan::default() };
        assert_eq!(scan.main_element(), Some(0));
        assert_eq!(scan.main_frame_count(), 2);
        assert_eq!(scan.duration_s(), 2.0);
        assert_eq!(TakeScan::default().main_element(), None);
        assert_eq!(TakeScan::default().duration_s(), 0.0);
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
