//! Stage timecode at any host monotonic instant, interpolated from the last LTC frame.
//!
//! LTC gives one label per frame (every 33-42 ms); frond records at its own rate. The issue
//! asks that every recorded frame get its stage timecode "interpolated between LTC frames from
//! the host monotonic clock, never taken from a sample's untrusted time": [`StageClock`] keeps
//! the last frame's label and the monotonic time its frame began, and counts forward from it
//! at the frame rate, for at most a bounded time (after that, no timecode rather than a guess).
//! The word of frame N is sent during frame N, bit 0 at its start (SMPTE 12M), so a frame
//! began one frame period before its sync word ended.

use crate::decoder::LtcFrame;
use crate::timecode::{FrameRate, SmpteTime};

/// A stage timecode with the fraction of a frame elapsed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageTime {
    /// The label of the frame in progress.
    pub time: SmpteTime,
    /// Its rate.
    pub rate: FrameRate,
    /// How far into that frame, 0 to below 1.
    pub subframe: f64,
}

#[derive(Debug, Clone, Copy)]
struct Anchor {
    count: u32,
    rate: FrameRate,
    start_ns: u64,
}

/// Maps host monotonic time to stage timecode from the latest locked LTC frame.
#[derive(Debug, Clone)]
pub struct StageClock {
    anchor: Option<Anchor>,
    max_extrapolation_ns: u64,
}

impl StageClock {
    /// A clock that answers for at most `max_extrapolation_ns` after the last frame began
    /// (a few frames: past that the source is lost, and the reader says so).
    pub fn new(max_extrapolation_ns: u64) -> StageClock {
        StageClock { anchor: None, max_extrapolation_ns }
    }

    /// Takes a frame whose sync word ended at host monotonic `end_ns`. Frames without a rate
    /// (the reader has not measured one yet) are not used.
    pub fn on_frame(&mut self, frame: &LtcFrame, end_ns: u64) {
        let Some(rate) = frame.rate else { return };
        if rate.check(frame.time).is_err() {
            return;
        }
        let period_ns = (1e9 / rate.fps()) as u64;
        self.anchor = Some(Anchor {
            count: rate.frame_count(frame.time),
            rate,
            start_ns: end_ns.saturating_sub(period_ns),
        });
    }

    /// Forgets the anchor (the reader lost its lock).
    pub fn on_lost(&mut self) {
        self.anchor = None;
    }

    /// The stage timecode at host monotonic `now_ns`; `None` without a frame, or further than
    /// the bound from the last one (before it or after it).
    pub fn at(&self, now_ns: u64) -> Option<StageTime> {
        let anchor = self.anchor?;
        let elapsed_ns = i128::from(now_ns) - i128::from(anchor.start_ns);
        if elapsed_ns.unsigned_abs() > u128::from(self.max_extrapolation_ns) {
            return None;
        }
        let frames = elapsed_ns as f64 * anchor.rate.fps() / 1e9;
        let whole = frames.floor();
        let day = i64::from(anchor.rate.frames_per_day());
        let count = (i64::from(anchor.count) + whole as i64).rem_euclid(day) as u32;
        Some(StageTime {
            time: anchor.rate.from_frame_count(count),
            rate: anchor.rate,
            subframe: frames - whole,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(text: &str, rate: Option<FrameRate>) -> LtcFrame {
        LtcFrame {
            time: SmpteTime::parse(text).unwrap(),
            rate,
            user_bits: 0,
            colour_frame: false,
            end_sample: 0.0,
        }
    }

    #[test]
    fn counts_forward_from_the_frame_start_at_the_frame_rate() {
        let mut clock = StageClock::new(200_000_000);
        assert_eq!(clock.at(0), None);
        // 25 fps: 40 ms frames. Frame 10:00:00:00 ended at 1.040 s, so it began at 1.000 s.
        clock.on_frame(&frame("10:00:00:00", Some(FrameRate::Fps25)), 1_040_000_000);
        let at = |clock: &StageClock, ns| {
            clock.at(ns).map(|t| (t.time.to_string(), (t.subframe * 100.0).round() as u32))
        };
        assert_eq!(at(&clock, 1_000_000_000), Some(("10:00:00:00".into(), 0)));
        assert_eq!(at(&clock, 1_050_000_000), Some(("10:00:00:01".into(), 25)));
        assert_eq!(at(&clock, 990_000_000), Some(("09:59:59:24".into(), 75)));
        assert_eq!(at(&clock, 1_000_000_000 + 200_000_001), None, "too far from the last frame");
        clock.on_lost();
        assert_eq!(at(&clock, 1_000_000_000), None);
    }

    #[test]
    fn drop_frame_interpolation_skips_the_dropped_labels_and_frames_without_rate_are_unused() {
        let mut clock = StageClock::new(1_000_000_000);
        clock.on_frame(&frame("00:00:59;29", None), 5_000_000_000);
        assert_eq!(clock.at(5_000_000_000), None);
        let df = FrameRate::Fps2997Df;
        let period = 1e9 / df.fps();
        clock.on_frame(&frame("00:00:59;29", Some(df)), 5_000_000_000);
        let start = 5_000_000_000.0 - period.floor();
        let next = clock.at((start + period * 1.5) as u64).unwrap();
        assert_eq!(next.time.to_string(), "00:01:00;02");
        assert_eq!(next.rate, df);
    }
}
