//! What the `frond-ltc` thread (`ltc_thread`) shares with the control threads (issue 46): the
//! stage clock it keeps from the LTC frames it decodes, and the state and counts status shows.
//!
//! One mutex, held for a copy or an update by the LTC thread (once per chunk of samples) and by
//! the control threads (a status, a take's start): never by the realtime loop.

use std::sync::Mutex;

use frond_ltc::{FrameRate, StageClock};
use frond_motion::take::StageAnchor;
use frond_protocol::LtcStatus;

/// How long the stage clock counts on from its last frame: past this the input is lost and a
/// take gets no stage timecode (a guess would be worse than none).
pub const MAX_EXTRAPOLATION_NS: u64 = 250_000_000;

/// The LTC state frondd shares: one per daemon with an LTC input.
pub struct LtcLink {
    book: Mutex<Book>,
}

/// What the LTC thread keeps and the control threads read.
struct Book {
    status: LtcStatus,
    clock: StageClock,
    /// Whether the clock may be used (locked at the expected rate).
    locked: bool,
    /// Monotonic ns at which the last frame ended.
    last_frame_ns: Option<u64>,
}

/// The states status names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LtcState {
    /// No lock yet.
    Searching,
    /// Locked: the stage clock is in use.
    Locked,
    /// Was locked; no frames now (a dropout, a FIFO's writer gone, a rate that is not ltc.fps).
    Lost,
    /// A file read to its end.
    Ended,
}

impl LtcState {
    /// The word status shows.
    pub fn word(self) -> &'static str {
        match self {
            LtcState::Searching => "searching",
            LtcState::Locked => "locked",
            LtcState::Lost => "lost",
            LtcState::Ended => "ended",
        }
    }
}

impl LtcLink {
    /// A link for `input` at `sample_rate_hz`, searching.
    pub fn new(input: &str, sample_rate_hz: u32) -> LtcLink {
        let status = LtcStatus {
            input: input.to_string(),
            state: LtcState::Searching.word().into(),
            sample_rate_hz,
            ..LtcStatus::default()
        };
        LtcLink {
            book: Mutex::new(Book {
                status,
                clock: StageClock::new(MAX_EXTRAPOLATION_NS),
                locked: false,
                last_frame_ns: None,
            }),
        }
    }

    fn book(&self) -> std::sync::MutexGuard<'_, Book> {
        self.book.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The status section, the last frame's age measured at `now_ns` (monotonic).
    pub fn status(&self, now_ns: u64) -> LtcStatus {
        let book = self.book();
        let mut status = book.status.clone();
        status.last_age_s = book.last_frame_ns.map(|at| now_ns.saturating_sub(at) as f64 / 1e9);
        status
    }

    /// Lets the LTC thread change what status shows.
    pub fn update(&self, change: impl FnOnce(&mut LtcStatus)) {
        change(&mut self.book().status);
    }

    /// A frame labelled `label` at `rate` ended at monotonic `end_ns`; `usable` when the reader
    /// is locked at the rate expected, so the stage clock may be used.
    pub fn on_frame(&self, frame: &frond_ltc::LtcFrame, end_ns: u64, usable: bool) {
        let mut book = self.book();
        book.last_frame_ns = Some(end_ns);
        book.status.last_timecode = Some(frame.time.to_string());
        if let Some(rate) = frame.rate {
            book.status.fps = Some(rate.to_string());
        }
        if usable {
            book.clock.on_frame(frame, end_ns);
        }
        book.locked = usable;
    }

    /// Sets the state (and forgets the clock unless locked).
    pub fn set_state(&self, state: LtcState) {
        let mut book = self.book();
        book.status.state = state.word().into();
        if state != LtcState::Locked {
            book.locked = false;
            book.clock.on_lost();
        }
    }

    /// The stage timecode at monotonic `now_ns` as a take's anchor: the frame in progress and
    /// when it began; `None` unless locked and within [`MAX_EXTRAPOLATION_NS`] of a frame.
    pub fn anchor(&self, now_ns: u64) -> Option<StageAnchor> {
        let book = self.book();
        if !book.locked {
            return None;
        }
        let at = book.clock.at(now_ns)?;
        Some(anchor_of(at, now_ns))
    }
}

/// The anchor of a stage master's own label `time` (a capture trigger's `TimeCode`) at `rate`,
/// taken to begin at monotonic `at_ns`; `None` when `rate` has no such label (a frame past the
/// rate's last, a label drop-frame skips, a drop-frame label at a whole-frame rate).
pub fn master_anchor(time: frond_ltc::SmpteTime, rate: FrameRate, at_ns: u64) -> Option<StageAnchor> {
    if time.drop_frame != rate.is_drop_frame() || rate.check(time).is_err() {
        return None;
    }
    Some(anchor_of(frond_ltc::StageTime { time, rate, subframe: 0.0 }, at_ns))
}

/// The anchor of stage time `at`, read at monotonic `now_ns`: its frame began `subframe`
/// frames earlier.
fn anchor_of(at: frond_ltc::StageTime, now_ns: u64) -> StageAnchor {
    let period_ns = 1e9 / at.rate.fps();
    let into_ns = (at.subframe * period_ns) as u64;
    StageAnchor {
        host_ns: now_ns.saturating_sub(into_ns),
        label: at.time.to_string(),
        frame_count: at.rate.frame_count(at.time),
        nominal_fps: at.rate.nominal_fps(),
        drop_frame: at.rate == FrameRate::Fps2997Df,
        ntsc: at.rate.is_ntsc(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_masters_label_anchors_at_its_rate_and_an_impossible_one_does_not() {
        let tc = |h, m, s, f, drop_frame| frond_ltc::SmpteTime {
            hours: h,
            minutes: m,
            seconds: s,
            frames: f,
            drop_frame,
        };
        let a = master_anchor(tc(10, 0, 0, 0, false), FrameRate::Fps25, 7_000).unwrap();
        // 10 h at 25 fps is frame 900,000 of the day, and it began at the message.
        assert_eq!(
            (a.host_ns, a.label.as_str(), a.frame_count, a.nominal_fps, a.drop_frame),
            (7_000, "10:00:00:00", 900_000, 25, false)
        );
        // 00:01:00;02 is the first label of minute 1 at 29.97 drop-frame: frame 1,800.
        let df = master_anchor(tc(0, 1, 0, 2, true), FrameRate::Fps2997Df, 0).unwrap();
        assert_eq!((df.frame_count, df.nominal_fps, df.drop_frame), (1_800, 30, true));
        assert_eq!(master_anchor(tc(0, 0, 0, 25, false), FrameRate::Fps25, 0), None, "frame 25 at 25 fps");
        assert_eq!(master_anchor(tc(0, 1, 0, 0, true), FrameRate::Fps2997Df, 0), None, "a dropped label");
        assert_eq!(master_anchor(tc(0, 1, 0, 5, true), FrameRate::Fps30, 0), None, "drop-frame at 30");
        assert_eq!(
            master_anchor(tc(0, 1, 0, 5, false), FrameRate::Fps2997Df, 0),
            None,
            "whole-frame at 29.97df"
        );
    }
    use frond_ltc::{LtcFrame, SmpteTime};

    #[test]
    fn a_locked_link_anchors_takes_at_the_frame_in_progress_and_a_lost_one_does_not() {
        let link = LtcLink::new("/run/frond/ltc.fifo", 48_000);
        let frame = LtcFrame {
            time: SmpteTime::parse("10:00:00:00").unwrap(),
            rate: Some(FrameRate::Fps25),
            user_bits: 0,
            colour_frame: false,
            end_sample: 0.0,
        };
        // 10:00:00:00 ended at 1.040 s: it began at 1.000 s; 1.050 s is 10 ms into :01.
        link.on_frame(&frame, 1_040_000_000, false);
        assert_eq!(link.anchor(1_050_000_000), None, "not locked yet");
        link.on_frame(&frame, 1_040_000_000, true);
        link.set_state(LtcState::Locked);
        link.on_frame(&frame, 1_040_000_000, true);
        let a = link.anchor(1_050_000_000).unwrap();
        assert_eq!(
            (a.label.as_str(), a.frame_count, a.nominal_fps, a.drop_frame),
            ("10:00:00:01", 900_001, 25, false)
        );
        assert!((1_039_999_000..=1_040_001_000).contains(&a.host_ns), "{}", a.host_ns);
        let s = link.status(1_140_000_000);
        assert_eq!(
            (s.state.as_str(), s.fps.as_deref(), s.last_timecode.as_deref()),
            ("locked", Some("25"), Some("10:00:00:00"))
        );
        assert!((s.last_age_s.unwrap() - 0.1).abs() < 1e-9);
        assert_eq!(link.anchor(1_000_000_000 + MAX_EXTRAPOLATION_NS + 1), None, "too long after the frame");
        link.set_state(LtcState::Lost);
        assert_eq!(link.anchor(1_050_000_000), None);
        assert_eq!(link.status(0).state, "lost");
    }
}
