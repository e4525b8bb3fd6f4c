//! A take as data: its header, its frames and what a reader found in it ([`TakeScan`]). The
//! take file's bytes (records, checksums, the reader and writer) are `frond_formats::take`; the
//! resampling of its poses at a fixed rate is `crate::resample`, re-exported here under the
//! paths callers have always used.

use frond_protocol::ElementId;
use serde::{Deserialize, Serialize};

pub use crate::resample::{
    MAX_INTERPOLATED_GAP_S, MAX_RESAMPLED_FRAMES, ResamplePlan, TooManyFrames, resample,
    resample_across_gaps, resample_plan,
};
use crate::sample::{HandSample, PoseFrame};

/// The `held` pose flag of [`TakeFrame::flags`] (same bit as `frond_protocol::PoseFlags::HELD`):
/// no new device report.
pub const FLAG_HELD: u32 = 1;
/// The `playback` pose flag of [`TakeFrame::flags`] (same bit as
/// `frond_protocol::PoseFlags::PLAYBACK`).
pub const FLAG_PLAYBACK: u32 = 1 << 4;

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
    /// The stage's master clock (LTC, issue 46) when frondd was locked to it as recording began:
    /// the take's timecode is then the stage's, not the host's time of day. Absent in takes
    /// recorded without a locked LTC input, offline, or before frond wrote it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stage_clock: Option<StageAnchor>,
}

/// One stage timecode frame pinned to the host's monotonic clock (see
/// [`TakeHeader::stage_clock`]): frame `frame_count` (label `label`) of the stage's day began at
/// CLOCK_MONOTONIC `host_ns`. A frame stamped later (or earlier) is that many nanoseconds of
/// the stage's clock away: interpolated from host time, never from a sample's device time.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StageAnchor {
    /// CLOCK_MONOTONIC, nanoseconds, at which the frame began.
    pub host_ns: u64,
    /// Its label as the stage sent it (`10:00:00:00`, or `01:00:00;02` at drop-frame).
    pub label: String,
    /// Frames since the stage's midnight at its rate (drop-frame labels counted as such).
    pub frame_count: u32,
    /// Frame labels per second: 24, 25 or 30 (30 also for 29.97, drop-frame or not).
    pub nominal_fps: u32,
    /// 29.97 drop-frame: frames last 1001/30000 s and labels skip as SMPTE 12M says.
    pub drop_frame: bool,
    /// Frames last 1001/30000 s: 29.97, drop-frame or not (a stage's 29.97 non-drop-frame
    /// has 30's labels, each frame 0.1 % longer). Absent in takes made before it was written:
    /// false, as they counted.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub ntsc: bool,
}

impl StageAnchor {
    /// Nanoseconds since the stage's midnight at which its anchor frame began: the frame count
    /// times the frame's length (1/nominal s, or 1001/30000 s at 29.97).
    fn label_ns(&self) -> u128 {
        let count = u128::from(self.frame_count);
        if self.drop_frame || self.ntsc {
            count * 1_001 * 1_000_000_000 / 30_000
        } else {
            count * 1_000_000_000 / u128::from(self.nominal_fps.max(1))
        }
    }

    /// SMPTE timecode at `fps` of a frame stamped `host_ns` (monotonic): the stage's time of
    /// day at that instant, counted forward (or back) from the anchor on the host's clock. At
    /// the stage's own rate this is the stage's label, frame for frame: a drop-frame stage
    /// exported at 29.97 gets drop-frame labels (`HH:MM:SS;FF`), a 29.97 non-drop-frame stage
    /// whole-frame labels counted at 29.97, any other rate whole-frame labels.
    pub fn timecode_of(&self, host_ns: u64, fps: f64) -> Option<crate::timecode::Timecode> {
        let rate = crate::timecode::nominal_rate(fps).ok()?;
        const DAY_NS: i128 = 86_400 * 1_000_000_000;
        let delta = i128::from(host_ns) - i128::from(self.host_ns);
        let of_day = (self.label_ns() as i128 + delta).rem_euclid(DAY_NS) as u64;
        if self.drop_frame && crate::timecode::is_ntsc_rate(fps) {
            return Some(crate::timecode::Timecode::drop_frame_from_ns(of_day));
        }
        if self.ntsc && crate::timecode::is_ntsc_rate(fps) {
            return Some(crate::timecode::Timecode::ntsc_from_ns(of_day));
        }
        Some(crate::timecode::Timecode::from_unix_ns(of_day, rate))
    }
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
            stage_clock: None,
        }
    }

    /// SMPTE timecode, at `fps`, of the first kept main-skeleton frame of `frames` (the first
    /// frame of every export: held frames are skipped), when the take knows its recording clock.
    /// The stage's clock ([`TakeHeader::stage_clock`]) wins over the host's time of day.
    pub fn start_timecode(&self, frames: &[TakeFrame], fps: f64) -> Option<crate::timecode::Timecode> {
        let main = main_element(frames)?;
        let first = frames.iter().find(|f| f.element == main && f.flags & FLAG_HELD == 0)?;
        self.timecode_of(first.host_ns, fps)
    }

    /// SMPTE timecode, at `fps`, of a frame stamped `host_ns` (monotonic): on the stage's clock
    /// when the take has one, else the host's time of day (UTC) when it knows its recording
    /// clock, else `None`.
    pub fn timecode_of(&self, host_ns: u64, fps: f64) -> Option<crate::timecode::Timecode> {
        match (&self.stage_clock, &self.clock) {
            (Some(stage), _) => stage.timecode_of(host_ns, fps),
            (None, Some(clock)) => clock.timecode_of(host_ns, fps),
            (None, None) => None,
        }
    }
}

/// The element a take's motion is read from by the tools that read one stream of poses (`take
/// list`, `take export`, alignment, previews): the plant (element 0) when the take has any frame
/// of it, else the lowest secondary element it has. A take of `frond record layer` holds only its
/// layer's frames (the hand published as, say, `leaf`): that layer is its motion. `None` for a
/// take without frames.
pub fn main_element(frames: &[TakeFrame]) -> Option<ElementId> {
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
    pub element: ElementId,
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
    pub fn main_element(&self) -> Option<ElementId> {
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
            .filter(|f| Some(f.element) == main && (include_held || f.flags & FLAG_HELD == 0))
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

#[cfg(test)]
mod tests {
    use super::*;

    fn at(element: u16, t: f64, flags: u32) -> TakeFrame {
        TakeFrame {
            element: ElementId::new(element),
            flags,
            pose: PoseFrame { t, ..PoseFrame::default() },
            ..TakeFrame::default()
        }
    }

    /// Issue 46: a take recorded while LTC was locked exports the stage's timecode, counted
    /// from the anchor on the host's clock; without the anchor, the host's time of day as before.
    #[test]
    fn the_stage_clock_wins_over_the_host_time_of_day() {
        // Host clock: monotonic 5 s is 13:45:10.5 UTC (frame 15 at 30 fps).
        let clock = TakeClock { unix_ns: 1_764_683_110_500_000_000, host_ns: 5_000_000_000 };
        let host_only = TakeHeader { clock: Some(clock), ..TakeHeader::offline("t", "grass", 1000) };
        let frames = [TakeFrame { host_ns: 5_000_000_000, ..TakeFrame::default() }];
        let tc = |h: &TakeHeader, fps| h.start_timecode(&frames, fps).map(|t| t.to_string());
        assert_eq!(tc(&host_only, 30.0).as_deref(), Some("13:45:10:15"));
        // Stage: 10:00:00:00 at 25 fps (frame 900,000 of the day) began at monotonic 4.99 s;
        // 10 ms later is still that frame, 40 ms later the next.
        let stage = StageAnchor {
            host_ns: 4_990_000_000,
            label: "10:00:00:00".into(),
            frame_count: 900_000,
            nominal_fps: 25,
            drop_frame: false,
            ntsc: false,
        };
        let both = TakeHeader { stage_clock: Some(stage.clone()), ..host_only.clone() };
        assert_eq!(tc(&both, 25.0).as_deref(), Some("10:00:00:00"));
        assert_eq!(both.timecode_of(5_030_000_000, 25.0).unwrap().to_string(), "10:00:00:01");
        assert_eq!(both.timecode_of(4_989_999_999, 25.0).unwrap().to_string(), "09:59:59:24");
        // At 50 fps the same instant is counted at 50: 10:00:00 and 10 ms is frame 0, 20 ms frame 1.
        assert_eq!(both.timecode_of(5_010_000_000, 50.0).unwrap().to_string(), "10:00:00:01");
        // Drop-frame: 00:01:00;02 is frame 1800, which began 1800 * 1001/30000 s after midnight
        // (60.06 s): at 30 fps that is 00:01:00:01 (frame 1801.8 of the nominal count, floored).
        let df = StageAnchor {
            label: "00:01:00;02".into(),
            frame_count: 1800,
            nominal_fps: 30,
            drop_frame: true,
            ..stage
        };
        let h = TakeHeader { stage_clock: Some(df), ..TakeHeader::offline("t", "grass", 1000) };
        assert_eq!(h.timecode_of(4_990_000_000, 30.0).unwrap().to_string(), "00:01:00:01");
        // Exported at the stage's own 29.97, the labels are the stage's: the anchor frame, and
        // 1001/30000 s later the next; a minute of frames (1798, as minute 1 drops two labels)
        // later, 00:02:00;02.
        let ntsc = 30_000.0 / 1_001.0;
        assert_eq!(h.timecode_of(4_990_000_000, ntsc).unwrap().to_string(), "00:01:00;02");
        assert_eq!(h.timecode_of(4_990_000_000 + 33_366_667, ntsc).unwrap().to_string(), "00:01:00;03");
        let minute_ns = 1_798 * 1_001 * 1_000_000_000 / 30_000 + 1; // rounded up into the frame
        assert_eq!(h.timecode_of(4_990_000_000 + minute_ns, 29.97).unwrap().to_string(), "00:02:00;02");
        assert_eq!(TakeHeader::offline("t", "grass", 1000).timecode_of(0, 30.0), None);

        // 29.97 non-drop-frame: 10:00:00:00 is frame 1,080,000 (30's labels), which began
        // 1,080,000 * 1001/30000 s = 36,036 s after the stage's midnight. 600 s of host clock
        // later the stage's LTC has run 600 * 30000/1001 = 17,982.02 frames: 10:09:59:12.
        // Counted at 30 (a stage that did not say 29.97) it would be 10:10:00:00, 18 frames on.
        let ndf = StageAnchor {
            label: "10:00:00:00".into(),
            frame_count: 1_080_000,
            nominal_fps: 30,
            drop_frame: false,
            ntsc: true,
            host_ns: 4_990_000_000,
        };
        let h = TakeHeader { stage_clock: Some(ndf.clone()), ..TakeHeader::offline("t", "grass", 1000) };
        assert_eq!(h.timecode_of(4_990_000_000, ntsc).unwrap().to_string(), "10:00:00:00");
        assert_eq!(h.timecode_of(4_990_000_000 + 600_000_000_000, ntsc).unwrap().to_string(), "10:09:59:12");
        let at_30 = TakeHeader { stage_clock: Some(StageAnchor { ntsc: false, ..ndf }), ..h };
        assert_eq!(
            at_30.timecode_of(4_990_000_000 + 600_000_000_000, ntsc).unwrap().to_string(),
            "10:10:00:00"
        );
    }

    #[test]
    fn a_layer_take_reads_as_its_layer() {
        // `frond record layer` writes only the layer's frames (here element 2); 4 frames over
        // 0.25..1.0 s, one of them held.
        let frames = vec![at(2, 0.25, 0), at(2, 0.5, FLAG_HELD), at(2, 0.75, 0), at(2, 1.0, 0)];
        let scan = TakeScan { frames, ..TakeScan::default() };
        assert_eq!(scan.main_element(), Some(ElementId::new(2)));
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
        assert_eq!(scan.main_element(), Some(ElementId::GLOBAL));
        assert_eq!(scan.main_frame_count(), 2);
        assert_eq!(scan.duration_s(), 2.0);
        assert_eq!(TakeScan::default().main_element(), None);
        assert_eq!(TakeScan::default().duration_s(), 0.0);
    }
}
