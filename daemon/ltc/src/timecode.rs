//! SMPTE timecode values and their arithmetic, drop-frame included.
//!
//! An LTC frame and a capture-trigger message both carry a time of day as `HH:MM:SS:FF`; what
//! the frame number means depends on the rate. At 29.97 fps drop-frame (SMPTE 12M), frame
//! numbers 0 and 1 are skipped at the start of every minute except minutes 0, 10, 20, 30, 40
//! and 50, so that the label keeps up with wall-clock time: 17,982 frames in every ten minutes
//! instead of 18,000. [`FrameRate::frame_count`] and [`FrameRate::from_frame_count`] convert
//! between the label and the count of frames since midnight, the one place that rule lives.

use std::fmt;

/// The rates LTC is read at. 29.97 non-drop-frame ([`FrameRate::Fps2997Ndf`]) has the labels of
/// [`FrameRate::Fps30`] and frames 0.1 % longer: three frames' spacing cannot tell the two
/// apart, so the reader locks such LTC as 30 and a stage declares 29.97 (`ltc.fps`,
/// [`FrameRate::read_as`]). It matters over a take: counted at 30 from its start, a label drifts
/// 18 frames from the stage's in ten minutes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameRate {
    /// 24 frames per second (film).
    Fps24,
    /// 25 frames per second (PAL/SECAM).
    Fps25,
    /// 30000/1001 frames per second, drop-frame labels (NTSC).
    Fps2997Df,
    /// 30 frames per second, non-drop.
    Fps30,
    /// 30000/1001 frames per second, whole-frame labels (the labels of 30 fps, running 0.1 %
    /// slower than the wall clock).
    Fps2997Ndf,
}

/// Frames in ten minutes of 29.97 drop-frame: 10 * 60 * 30 - 9 * 2.
const DF_FRAMES_PER_10_MIN: u32 = 17_982;
/// Frames in a minute of 29.97 drop-frame that is not a multiple of ten: 60 * 30 - 2.
const DF_FRAMES_PER_MIN: u32 = 1_798;

impl FrameRate {
    /// Every rate, slowest first, for tests and for callers listing them.
    pub const ALL: [FrameRate; 5] =
        [FrameRate::Fps24, FrameRate::Fps25, FrameRate::Fps2997Df, FrameRate::Fps2997Ndf, FrameRate::Fps30];

    /// Frame labels per second (30 for 29.97 drop-frame).
    pub fn nominal_fps(self) -> u32 {
        match self {
            FrameRate::Fps24 => 24,
            FrameRate::Fps25 => 25,
            FrameRate::Fps2997Df | FrameRate::Fps30 | FrameRate::Fps2997Ndf => 30,
        }
    }

    /// Frames per wall-clock second (30000/1001 for drop-frame).
    pub fn fps(self) -> f64 {
        match self {
            FrameRate::Fps2997Df | FrameRate::Fps2997Ndf => 30_000.0 / 1_001.0,
            other => f64::from(other.nominal_fps()),
        }
    }

    /// Whether labels skip frames 0 and 1 at most minute starts.
    pub fn is_drop_frame(self) -> bool {
        self == FrameRate::Fps2997Df
    }

    /// Whether a frame lasts 1001/30000 s (29.97, drop-frame or not).
    pub fn is_ntsc(self) -> bool {
        matches!(self, FrameRate::Fps2997Df | FrameRate::Fps2997Ndf)
    }

    /// The rate to take LTC read at `self` as, when the stage declares `declared` (`None`:
    /// nothing declared, taken as read): the declared rate when it is this one, or 29.97
    /// non-drop-frame for LTC read as 30 (the same labels); `None` when the two differ.
    pub fn read_as(self, declared: Option<FrameRate>) -> Option<FrameRate> {
        match declared {
            None => Some(self),
            Some(d) if d == self || (d == FrameRate::Fps2997Ndf && self == FrameRate::Fps30) => Some(d),
            Some(_) => None,
        }
    }

    /// Frames from midnight to midnight.
    pub fn frames_per_day(self) -> u32 {
        match self {
            FrameRate::Fps2997Df => DF_FRAMES_PER_10_MIN * 6 * 24,
            other => other.nominal_fps() * 86_400,
        }
    }

    /// Frames since midnight at which `time` is labelled. `time` must be valid at this rate
    /// ([`FrameRate::check`]); an invalid one gives a meaningless count, never a panic.
    pub fn frame_count(self, time: SmpteTime) -> u32 {
        let fps = self.nominal_fps();
        let minutes = u32::from(time.hours) * 60 + u32::from(time.minutes);
        let labels = (minutes * 60 + u32::from(time.seconds)) * fps + u32::from(time.frames);
        if self.is_drop_frame() { labels.saturating_sub(2 * (minutes - minutes / 10)) } else { labels }
    }

    /// The label of frame `count` since midnight (wrapping at a day).
    pub fn from_frame_count(self, count: u32) -> SmpteTime {
        let count = count % self.frames_per_day();
        let fps = self.nominal_fps();
        let labels = if self.is_drop_frame() {
            let (tens, rest) = (count / DF_FRAMES_PER_10_MIN, count % DF_FRAMES_PER_10_MIN);
            let skipped_in_rest = if rest < 2 { 0 } else { 2 * ((rest - 2) / DF_FRAMES_PER_MIN) };
            count + 18 * tens + skipped_in_rest
        } else {
            count
        };
        let secs = labels / fps;
        SmpteTime {
            hours: (secs / 3600 % 24) as u8,
            minutes: (secs / 60 % 60) as u8,
            seconds: (secs % 60) as u8,
            frames: (labels % fps) as u8,
            drop_frame: self.is_drop_frame(),
        }
    }

    /// Checks that `time` is a label this rate produces: fields in range, frames below the
    /// rate, and at drop-frame not one of the skipped labels.
    pub fn check(self, time: SmpteTime) -> Result<(), TimecodeError> {
        time.check_fields()?;
        if u32::from(time.frames) >= self.nominal_fps() {
            return Err(TimecodeError::Range {
                field: "frames",
                value: time.frames,
                max: (self.nominal_fps() - 1) as u8,
            });
        }
        if self.is_drop_frame() && time.seconds == 0 && time.frames < 2 && !time.minutes.is_multiple_of(10) {
            return Err(TimecodeError::DroppedLabel(time));
        }
        Ok(())
    }
}

impl fmt::Display for FrameRate {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        out.write_str(match self {
            FrameRate::Fps24 => "24",
            FrameRate::Fps25 => "25",
            FrameRate::Fps2997Df => "29.97df",
            FrameRate::Fps30 => "30",
            FrameRate::Fps2997Ndf => "29.97",
        })
    }
}

/// A timecode label: hours, minutes, seconds, frames, and whether it counts drop-frame
/// (written with `;` before the frames, as SMPTE practice does).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SmpteTime {
    /// 0-23.
    pub hours: u8,
    /// 0-59.
    pub minutes: u8,
    /// 0-59.
    pub seconds: u8,
    /// Below the rate's frames per second.
    pub frames: u8,
    /// Drop-frame label (29.97).
    pub drop_frame: bool,
}

/// Frames a label may carry without a known rate (the highest LTC rate is 30; other
/// timecode, such as 60 fps or a mocap master's, stays below this).
pub const MAX_LABEL_FRAMES: u8 = 119;

/// Why a timecode label was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TimecodeError {
    /// Not `HH:MM:SS:FF` (or `HH:MM:SS;FF`).
    #[error("{0:?} is not a timecode: expected HH:MM:SS:FF, or HH:MM:SS;FF for drop-frame")]
    Syntax(String),
    /// A field past its largest value.
    #[error("timecode {field} {value} is out of range (at most {max})")]
    Range {
        /// Which field.
        field: &'static str,
        /// Its value.
        value: u8,
        /// Its largest value.
        max: u8,
    },
    /// A label drop-frame counting skips (frames 0 and 1 of a minute not a multiple of ten).
    #[error("{0} does not exist in drop-frame timecode (frames 0 and 1 are skipped in this minute)")]
    DroppedLabel(SmpteTime),
}

impl SmpteTime {
    /// Parses `HH:MM:SS:FF`, or `HH:MM:SS;FF` (also `.` or `,` before the frames, as some
    /// tools write drop-frame) for a drop-frame label. Each field is one or two digits.
    pub fn parse(text: &str) -> Result<SmpteTime, TimecodeError> {
        let syntax = || TimecodeError::Syntax(text.chars().take(32).collect());
        let bytes = text.trim().as_bytes();
        let mut fields = [0u8; 4];
        let mut drop_frame = false;
        let mut rest = bytes;
        for (i, field) in fields.iter_mut().enumerate() {
            let digits = rest.iter().take_while(|b| b.is_ascii_digit()).count();
            if !(1..=2).contains(&digits) {
                return Err(syntax());
            }
            *field = rest[..digits].iter().fold(0u8, |v, d| v * 10 + (d - b'0'));
            rest = &rest[digits..];
            match (i, rest.first()) {
                (3, None) => {}
                (0..=2, Some(b':')) => rest = &rest[1..],
                (2, Some(b';' | b'.' | b',')) => {
                    drop_frame = true;
                    rest = &rest[1..];
                }
                _ => return Err(syntax()),
            }
        }
        let [hours, minutes, seconds, frames] = fields;
        let time = SmpteTime { hours, minutes, seconds, frames, drop_frame };
        time.check_fields()?;
        Ok(time)
    }

    /// Checks hours, minutes and seconds, and frames against [`MAX_LABEL_FRAMES`].
    pub fn check_fields(&self) -> Result<(), TimecodeError> {
        for (field, value, max) in [
            ("hours", self.hours, 23),
            ("minutes", self.minutes, 59),
            ("seconds", self.seconds, 59),
            ("frames", self.frames, MAX_LABEL_FRAMES),
        ] {
            if value > max {
                return Err(TimecodeError::Range { field, value, max });
            }
        }
        Ok(())
    }
}

impl fmt::Display for SmpteTime {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sep = if self.drop_frame { ';' } else { ':' };
        write!(out, "{:02}:{:02}:{:02}{sep}{:02}", self.hours, self.minutes, self.seconds, self.frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ltc_read_at_30_is_taken_at_the_rate_a_stage_declares_when_the_labels_agree() {
        use FrameRate::*;
        assert_eq!(Fps30.read_as(None), Some(Fps30));
        assert_eq!(Fps30.read_as(Some(Fps30)), Some(Fps30));
        assert_eq!(Fps30.read_as(Some(Fps2997Ndf)), Some(Fps2997Ndf));
        assert_eq!(Fps25.read_as(Some(Fps2997Ndf)), None);
        assert_eq!(Fps2997Df.read_as(Some(Fps2997Ndf)), None, "drop-frame labels are not 29.97 non-drop");
        assert_eq!(Fps2997Df.read_as(Some(Fps30)), None);
        assert_eq!(Fps2997Ndf.to_string(), "29.97");
        assert!(
            Fps2997Ndf.is_ntsc() && Fps2997Df.is_ntsc() && !Fps30.is_ntsc() && !Fps2997Ndf.is_drop_frame()
        );
        // The labels of 30, each frame 1001/30000 s: ten minutes of wall clock is 17,982 frames,
        // 18 short of ten minutes of labels.
        assert_eq!(Fps2997Ndf.frame_count(t("00:10:00:00")), 18_000);
        assert_eq!(Fps2997Ndf.from_frame_count(17_982).to_string(), "00:09:59:12");
        assert_eq!((600.0 * Fps2997Ndf.fps()).round(), 17_982.0);
    }

    fn t(text: &str) -> SmpteTime {
        SmpteTime::parse(text).unwrap()
    }

    #[test]
    fn drop_frame_counts_worked_out_by_hand() {
        let df = FrameRate::Fps2997Df;
        // Minute 1 starts at label ;02 after 1800 frames (00:00:00;00 .. 00:00:59;29).
        assert_eq!(df.frame_count(t("00:01:00;02")), 1800);
        assert_eq!(df.from_frame_count(1799), t("00:00:59;29"));
        assert_eq!(df.from_frame_count(1800), t("00:01:00;02"));
        // Minute 10 keeps its frames 0 and 1: 17,982 frames in ten minutes.
        assert_eq!(df.from_frame_count(17_982), t("00:10:00;00"));
        assert_eq!(df.from_frame_count(17_981), t("00:09:59;29"));
        // One hour is 107,892 frames (6 * 17,982); a day is 24 of them.
        assert_eq!(df.frame_count(t("01:00:00;00")), 107_892);
        assert_eq!(df.frames_per_day(), 2_589_408);
        assert_eq!(df.from_frame_count(df.frames_per_day()), t("00:00:00;00"));
        assert!(matches!(df.check(t("00:01:00;00")), Err(TimecodeError::DroppedLabel(_))));
        assert!(df.check(t("00:10:00;00")).is_ok());
    }

    #[test]
    fn every_drop_frame_count_round_trips_and_never_lands_on_a_skipped_label() {
        let df = FrameRate::Fps2997Df;
        for n in (0..df.frames_per_day()).step_by(7).chain(0..40_000) {
            let label = df.from_frame_count(n);
            assert!(df.check(label).is_ok(), "{n} -> {label}");
            assert_eq!(df.frame_count(label), n, "{label}");
        }
    }

    #[test]
    fn non_drop_rates_count_plainly() {
        assert_eq!(FrameRate::Fps25.frame_count(t("10:00:00:00")), 900_000);
        assert_eq!(FrameRate::Fps24.from_frame_count(24 * 3661 + 5), t("01:01:01:05"));
        assert_eq!(FrameRate::Fps30.from_frame_count(30 * 86_400 + 1), t("00:00:00:01"));
        assert!(FrameRate::Fps24.check(t("00:00:00:24")).is_err());
    }

    #[test]
    fn labels_parse_and_print() {
        assert_eq!(t("01:02:03;04").to_string(), "01:02:03;04");
        assert_eq!(t("1:2:3:4").to_string(), "01:02:03:04");
        for bad in [
            "",
            "00:00:00",
            "aa:00:00:00",
            "00:00:00:000",
            "24:00:00:00",
            "00:60:00:00",
            "00;00:00:00",
            "0:0:0:0x",
        ] {
            assert!(SmpteTime::parse(bad).is_err(), "{bad:?} accepted");
        }
        assert_eq!(
            SmpteTime::parse("00:61:00:00").unwrap_err().to_string(),
            "timecode minutes 61 is out of range (at most 59)"
        );
    }
}
