//! SMPTE timecode (`HH:MM:SS:FF`) so that takes and exports line up with reference video and
//! audio: a take's frames get the time of day of the host's wall clock when they were recorded
//! (UTC), or of the stage's master clock (LTC), counted in frames of the export's rate, or a
//! start the user gives.
//!
//! Rates are whole frames per second (a 29.97 or 59.94 Hz export is counted at 30 or 60, as
//! non-drop-frame timecode does), except that a take recorded on a 29.97 drop-frame stage and
//! exported at 29.97 is labelled drop-frame (`HH:MM:SS;FF`, SMPTE 12M's skipped labels, the
//! arithmetic of `frond_ltc`), as the stage's other systems label it; the count wraps at 24
//! hours.

use std::fmt;

/// Frames per second a timecode may count (1 to 1000).
pub const MAX_TIMECODE_RATE: u32 = 1000;
const SECONDS_PER_DAY: u64 = 86_400;
const DROP_FRAME: frond_ltc::FrameRate = frond_ltc::FrameRate::Fps2997Df;

/// A position in the day, in frames of `rate` per second.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timecode {
    /// Frames since midnight.
    pub frames: u64,
    /// Frames per second (30 for 29.97 drop-frame).
    pub rate: u32,
    /// 29.97 drop-frame: `frames` are frames of 1001/30000 s and the label skips as SMPTE 12M
    /// says (`rate` is 30).
    pub drop_frame: bool,
}

/// Whether `fps` is 29.97 (30000/1001), the one rate drop-frame labels count.
pub fn is_ntsc_rate(fps: f64) -> bool {
    (fps - 30_000.0 / 1_001.0).abs() < 0.005
}

/// Why a timecode or its rate was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TimecodeError {
    /// Not `HH:MM:SS:FF`.
    #[error("{0:?}: expected HH:MM:SS:FF (hours 0-23, minutes and seconds 0-59, frames below the rate)")]
    Syntax(String),
    /// A field out of range.
    #[error("{text:?}: {field} {value} is out of range (at most {max})")]
    Range {
        /// The text.
        text: String,
        /// Which field.
        field: &'static str,
        /// Its value.
        value: u64,
        /// Its largest value.
        max: u64,
    },
    /// A rate that is no timecode rate.
    #[error("a timecode counts 1 to {MAX_TIMECODE_RATE} frames per second, not {0}")]
    Rate(f64),
}

/// The whole-frame rate a timecode counts at `fps` (29.97 counts at 30).
pub fn nominal_rate(fps: f64) -> Result<u32, TimecodeError> {
    let r = fps.round();
    if !(fps.is_finite() && r >= 1.0 && r <= f64::from(MAX_TIMECODE_RATE)) {
        return Err(TimecodeError::Rate(fps));
    }
    Ok(r as u32)
}

/// Whole frames of 1001/30000 s (29.97, drop-frame or not) in `ns` nanoseconds.
fn ntsc_frames(ns: u64) -> u64 {
    (u128::from(ns) * 30_000 / (1_001 * 1_000_000_000)) as u64
}

impl Timecode {
    /// The frame of the day that contains Unix time `unix_ns` (UTC), at `rate`.
    pub fn from_unix_ns(unix_ns: u64, rate: u32) -> Timecode {
        let day_ns = unix_ns % (SECONDS_PER_DAY * 1_000_000_000);
        let frames = u128::from(day_ns) * u128::from(rate) / 1_000_000_000;
        Timecode { frames: frames as u64, rate, drop_frame: false }
    }

    /// The 29.97 drop-frame frame that contains `of_day_ns` nanoseconds since midnight.
    pub fn drop_frame_from_ns(of_day_ns: u64) -> Timecode {
        let day = u64::from(DROP_FRAME.frames_per_day());
        Timecode { frames: ntsc_frames(of_day_ns) % day, rate: 30, drop_frame: true }
    }

    /// The 29.97 non-drop-frame frame that contains `of_day_ns` nanoseconds since the stage's
    /// midnight: 30 labels a second, each frame 1001/30000 s (so the labels run 0.1 % behind
    /// the wall clock).
    pub fn ntsc_from_ns(of_day_ns: u64) -> Timecode {
        Timecode { frames: ntsc_frames(of_day_ns) % (30 * SECONDS_PER_DAY), rate: 30, drop_frame: false }
    }

    /// Parses `HH:MM:SS:FF` (`;` before the frames accepted too) at `rate`.
    pub fn parse(text: &str, rate: u32) -> Result<Timecode, TimecodeError> {
        let syntax = || TimecodeError::Syntax(text.to_string());
        let parts: Vec<&str> = text.trim().split([':', ';']).collect();
        let [h, m, s, f] = parts.as_slice() else { return Err(syntax()) };
        let num = |p: &str| -> Result<u64, TimecodeError> {
            if p.is_empty() || p.len() > 4 || !p.bytes().all(|b| b.is_ascii_digit()) {
                return Err(syntax());
            }
            p.parse().map_err(|_| syntax())
        };
        let (h, m, s, f) = (num(h)?, num(m)?, num(s)?, num(f)?);
        for (field, value, max) in
            [("hours", h, 23), ("minutes", m, 59), ("seconds", s, 59), ("frames", f, u64::from(rate) - 1)]
        {
            if value > max {
                return Err(TimecodeError::Range { text: text.to_string(), field, value, max });
            }
        }
        Ok(Timecode { frames: ((h * 60 + m) * 60 + s) * u64::from(rate) + f, rate, drop_frame: false })
    }

    /// `n` frames later, wrapping at midnight.
    pub fn plus_frames(self, n: u64) -> Timecode {
        let day = if self.drop_frame {
            u64::from(DROP_FRAME.frames_per_day())
        } else {
            SECONDS_PER_DAY * u64::from(self.rate)
        };
        Timecode { frames: (self.frames + n % day) % day, ..self }
    }

    /// Hours, minutes, seconds, frames (of the label: at drop-frame, with the skips).
    pub fn parts(&self) -> (u64, u64, u64, u64) {
        if self.drop_frame {
            let count = (self.frames % u64::from(DROP_FRAME.frames_per_day())) as u32;
            let t = DROP_FRAME.from_frame_count(count);
            return (t.hours.into(), t.minutes.into(), t.seconds.into(), t.frames.into());
        }
        let r = u64::from(self.rate);
        let (secs, f) = (self.frames / r, self.frames % r);
        (secs / 3600 % 24, secs / 60 % 60, secs % 60, f)
    }
}

impl fmt::Display for Timecode {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (h, m, s, f) = self.parts();
        let width = if self.rate > 100 { 3 } else { 2 };
        // SMPTE's habit: a semicolon before the frames of a drop-frame label.
        let sep = if self.drop_frame { ';' } else { ':' };
        write!(out, "{h:02}:{m:02}:{s:02}{sep}{f:0width$}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timecodes_worked_out_by_hand() {
        // 2026-12-02 13:45:10.5 UTC: 1_764_683_110.5 s since 1970; 13:45:10 and half a second
        // is frame 15 at 30 fps.
        let unix_ns = 1_764_683_110_500_000_000;
        let tc = Timecode::from_unix_ns(unix_ns, 30);
        assert_eq!(tc.to_string(), "13:45:10:15");
        assert_eq!(tc.plus_frames(15).to_string(), "13:45:11:00");
        assert_eq!(Timecode::parse("23:59:59:29", 30).unwrap().plus_frames(1).to_string(), "00:00:00:00");
        assert_eq!(Timecode::parse("01:02:03;04", 25).unwrap().frames, ((3600 + 120 + 3) * 25) + 4);
        assert_eq!(nominal_rate(29.97).unwrap(), 30);
        assert!(nominal_rate(0.2).is_err() && nominal_rate(f64::NAN).is_err());
        let e = Timecode::parse("10:00:00:30", 30).unwrap_err().to_string();
        assert!(e.contains("frames 30 is out of range (at most 29)"), "{e}");
        assert!(Timecode::parse("10:00:00", 30).is_err() && Timecode::parse("aa:00:00:00", 30).is_err());
        assert_eq!(Timecode { frames: 5, rate: 120, drop_frame: false }.to_string(), "00:00:00:005");
    }

    #[test]
    fn drop_frame_labels_worked_out_by_hand() {
        let df = |frames| Timecode { frames, rate: 30, drop_frame: true };
        // Minute 1 has no labels ;00 and ;01: frame 1800 (60 s of 30 labels) is 00:01:00;02.
        assert_eq!(df(1_799).to_string(), "00:00:59;29");
        assert_eq!(df(1_800).to_string(), "00:01:00;02");
        // Ten minutes hold 17,982 frames (10 * 1800 - 9 * 2), and minute 10 keeps ;00.
        assert_eq!(df(17_981).to_string(), "00:09:59;29");
        assert_eq!(df(17_982).to_string(), "00:10:00;00");
        // One hour is 6 * 17,982 = 107,892 frames; the day 24 hours of them, then it wraps.
        assert_eq!(df(107_892).to_string(), "01:00:00;00");
        assert_eq!(df(2_589_407).plus_frames(1).to_string(), "00:00:00;00");
        // Drop-frame labels follow the wall clock: an hour of 29.97 frames (3600 s) is about
        // 01:00:00;00 (107,892 frames of 1001/30000 s last 3599.9964 s, so 3600 s is frame
        // 107,892, its first 3.6 ms in).
        let hour = Timecode::drop_frame_from_ns(3_600 * 1_000_000_000);
        assert_eq!((hour.frames, hour.to_string().as_str()), (107_892, "01:00:00;00"));
        assert!(is_ntsc_rate(29.97) && is_ntsc_rate(30_000.0 / 1_001.0) && !is_ntsc_rate(30.0));
    }
}
