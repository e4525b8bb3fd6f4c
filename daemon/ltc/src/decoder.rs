//! The LTC reader: samples in, typed events out (frames, lock, loss, jumps).
//!
//! Lock: three frames in a row whose labels count up by one at a rate the frames' spacing
//! agrees with. Locked, every frame is checked against the one expected next; a different
//! label is a [`LtcEvent::Jump`] (the master clock was re-jammed, or the tape cued), and the
//! reader follows it. No frame for two and a half frame periods, or a frame that cannot exist
//! at the locked rate, is [`LtcEvent::Lost`]. Everything after [`LtcDecoder::new`] works in
//! place: no allocation per sample or per frame.

use crate::biphase::{BitClock, BitEvent, EdgeDetector};
use crate::frame::{FRAME_BITS, FrameAssembler, decode_fields};
use crate::timecode::{FrameRate, SmpteTime};

/// The lowest sample rate read (8 kHz: about 3.3 samples a bit at 30 fps).
pub const MIN_SAMPLE_RATE_HZ: u32 = 8_000;
/// The highest sample rate read.
pub const MAX_SAMPLE_RATE_HZ: u32 = 192_000;
/// Consecutive frames counting up by one that make a lock.
pub const LOCK_FRAMES: u32 = 3;
/// Frame periods without a frame after which a lock is lost.
const LOSS_FRAME_PERIODS: f64 = 2.5;

/// Why a decoder could not be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LtcError {
    /// A sample rate outside what the decoder reads.
    #[error("LTC is read at {MIN_SAMPLE_RATE_HZ} to {MAX_SAMPLE_RATE_HZ} Hz, not {0} Hz")]
    SampleRate(u32),
}

/// One decoded frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LtcFrame {
    /// Its label.
    pub time: SmpteTime,
    /// The rate, once the reader has seen two frames to measure it (always while locked).
    pub rate: Option<FrameRate>,
    /// The eight user-bit groups, group 1 in the lowest four bits.
    pub user_bits: u32,
    /// The colour-frame flag (bit 11).
    pub colour_frame: bool,
    /// Where the frame ended (the end of its sync word), in samples since the first sample
    /// given, fractional: the wiring maps this to the host monotonic clock.
    pub end_sample: f64,
}

/// What the reader reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LtcEvent {
    /// A frame was read. Reported for every valid frame, locked or not.
    Frame(LtcFrame),
    /// The reader locked at `rate`; the frame reported next is the first locked one.
    Locked {
        /// The rate.
        rate: FrameRate,
        /// Where, in samples.
        sample: f64,
    },
    /// The lock was lost: no frame in time, or one impossible at the locked rate.
    Lost {
        /// The last frame read while locked.
        last: SmpteTime,
        /// Where the loss was noticed, in samples.
        sample: f64,
    },
    /// While locked, a frame that is not the one expected next.
    Jump {
        /// The label expected.
        expected: SmpteTime,
        /// The label read.
        found: SmpteTime,
        /// Where, in samples.
        sample: f64,
    },
}

/// Counts for status and diagnosis.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LtcCounters {
    /// Valid frames read.
    pub frames: u64,
    /// Sync words found before fields that are not a timecode.
    pub bad_frames: u64,
    /// Intervals between transitions no LTC bit has.
    pub bit_errors: u64,
    /// Locks gained.
    pub locks: u64,
    /// Locks lost.
    pub losses: u64,
    /// Jumps while locked.
    pub jumps: u64,
}

#[derive(Debug, Clone, Copy)]
struct Seen {
    time: SmpteTime,
    end_sample: f64,
}

/// An LTC reader for one mono channel at one sample rate.
#[derive(Debug, Clone)]
pub struct LtcDecoder {
    sample_rate_hz: u32,
    edges: EdgeDetector,
    clock: BitClock,
    frames: FrameAssembler,
    last: Option<Seen>,
    frame_period: Option<f64>,
    locked: Option<FrameRate>,
    streak: u32,
    counters: LtcCounters,
}

impl LtcDecoder {
    /// A reader for mono samples at `sample_rate_hz` (8 to 192 kHz), at any of the LTC rates.
    pub fn new(sample_rate_hz: u32) -> Result<LtcDecoder, LtcError> {
        if !(MIN_SAMPLE_RATE_HZ..=MAX_SAMPLE_RATE_HZ).contains(&sample_rate_hz) {
            return Err(LtcError::SampleRate(sample_rate_hz));
        }
        let clock = BitClock::new(sample_rate_hz);
        Ok(LtcDecoder {
            sample_rate_hz,
            edges: EdgeDetector::new(clock.period()),
            clock,
            frames: FrameAssembler::default(),
            last: None,
            frame_period: None,
            locked: None,
            streak: 0,
            counters: LtcCounters::default(),
        })
    }

    /// The sample rate this reader was made for.
    pub fn sample_rate_hz(&self) -> u32 {
        self.sample_rate_hz
    }

    /// The locked rate, if locked.
    pub fn locked(&self) -> Option<FrameRate> {
        self.locked
    }

    /// Counts so far.
    pub fn counters(&self) -> LtcCounters {
        self.counters
    }

    /// Reads float samples (full scale ±1.0; any level works), calling `on_event` for each
    /// event in order.
    pub fn process_f32(&mut self, samples: &[f32], mut on_event: impl FnMut(LtcEvent)) {
        for &x in samples {
            self.sample(x, &mut on_event);
        }
    }

    /// Reads 16-bit samples, calling `on_event` for each event in order.
    pub fn process_i16(&mut self, samples: &[i16], mut on_event: impl FnMut(LtcEvent)) {
        for &x in samples {
            self.sample(f32::from(x) / 32_768.0, &mut on_event);
        }
    }

    fn sample(&mut self, x: f32, on_event: &mut impl FnMut(LtcEvent)) {
        if let Some(t) = self.edges.push(x) {
            match self.clock.edge(t) {
                BitEvent::None => {}
                BitEvent::Invalid => {
                    self.counters.bit_errors += 1;
                    self.frames.reset();
                }
                BitEvent::Bit(bit) => {
                    if let Some(bits) = self.frames.push(bit) {
                        self.frame(bits, t, on_event);
                    }
                }
            }
        }
        self.check_loss(on_event);
    }

    fn check_loss(&mut self, on_event: &mut impl FnMut(LtcEvent)) {
        let (Some(_), Some(last), Some(period)) = (self.locked, self.last, self.frame_period) else { return };
        let now = self.edges.samples() as f64;
        if now - last.end_sample > LOSS_FRAME_PERIODS * period {
            self.lose(last.time, now, on_event);
            self.last = None;
        }
    }

    fn lose(&mut self, last: SmpteTime, sample: f64, on_event: &mut impl FnMut(LtcEvent)) {
        self.locked = None;
        self.streak = 0;
        self.counters.losses += 1;
        on_event(LtcEvent::Lost { last, sample });
    }

    fn frame(&mut self, bits: u64, end_sample: f64, on_event: &mut impl FnMut(LtcEvent)) {
        let Some(fields) = decode_fields(bits) else {
            self.counters.bad_frames += 1;
            return;
        };
        self.counters.frames += 1;
        let time = fields.time;
        let previous = self.last.replace(Seen { time, end_sample });
        self.measure_period(previous, end_sample);
        let rate = self.locked.or_else(|| self.rate_estimate(time));
        match self.locked {
            Some(locked) => self.follow_locked(locked, previous, time, end_sample, on_event),
            None => self.try_lock(rate, previous, time, end_sample, on_event),
        }
        let rate = self.locked.or(rate);
        let frame = LtcFrame {
            time,
            rate,
            user_bits: fields.user_bits,
            colour_frame: fields.colour_frame,
            end_sample,
        };
        on_event(LtcEvent::Frame(frame));
    }

    /// Follows the spacing of consecutive frames (one frame apart: 80 bits at the bit clock).
    fn measure_period(&mut self, previous: Option<Seen>, end_sample: f64) {
        let expected = self.clock.period() * f64::from(FRAME_BITS);
        let Some(previous) = previous else { return };
        let spacing = end_sample - previous.end_sample;
        if (spacing - expected).abs() > 0.1 * expected {
            return; // not adjacent frames (a dropout between them)
        }
        self.frame_period = Some(match self.frame_period {
            Some(p) if (p - spacing).abs() < 0.05 * p => p + 0.2 * (spacing - p),
            _ => spacing,
        });
    }

    /// The rate the frames' spacing and drop-frame flag point to, if any is close enough.
    fn rate_estimate(&self, time: SmpteTime) -> Option<FrameRate> {
        let fps = f64::from(self.sample_rate_hz) / self.frame_period?;
        let candidates: &[FrameRate] = if time.drop_frame {
            &[FrameRate::Fps2997Df]
        } else {
            &[FrameRate::Fps24, FrameRate::Fps25, FrameRate::Fps30]
        };
        candidates.iter().copied().find(|r| (fps / r.fps() - 1.0).abs() < 0.015)
    }

    fn try_lock(
        &mut self,
        rate: Option<FrameRate>,
        previous: Option<Seen>,
        time: SmpteTime,
        sample: f64,
        on_event: &mut impl FnMut(LtcEvent),
    ) {
        let follows = match (rate, previous) {
            (Some(rate), Some(prev)) => rate.check(time).is_ok() && next_label(rate, prev.time) == time,
            _ => false,
        };
        self.streak = if follows { self.streak + 1 } else { 0 };
        if let (Some(rate), true) = (rate, self.streak + 1 >= LOCK_FRAMES) {
            self.locked = Some(rate);
            self.counters.locks += 1;
            on_event(LtcEvent::Locked { rate, sample });
        }
    }

    fn follow_locked(
        &mut self,
        rate: FrameRate,
        previous: Option<Seen>,
        time: SmpteTime,
        sample: f64,
        on_event: &mut impl FnMut(LtcEvent),
    ) {
        let Some(previous) = previous else { return };
        if rate.check(time).is_err() || time.drop_frame != rate.is_drop_frame() {
            self.lose(previous.time, sample, on_event);
            return;
        }
        let expected = next_label(rate, previous.time);
        if expected != time {
            self.counters.jumps += 1;
            on_event(LtcEvent::Jump { expected, found: time, sample });
        }
    }
}

/// The label after `time` at `rate`.
fn next_label(rate: FrameRate, time: SmpteTime) -> SmpteTime {
    rate.from_frame_count(rate.frame_count(time) + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_rates_outside_the_range_are_refused() {
        assert_eq!(LtcDecoder::new(7_999).unwrap_err(), LtcError::SampleRate(7_999));
        assert!(LtcDecoder::new(192_001).is_err());
        assert!(LtcDecoder::new(8_000).is_ok() && LtcDecoder::new(192_000).is_ok());
    }

    #[test]
    fn silence_and_garbage_make_no_frames() {
        let mut d = LtcDecoder::new(48_000).unwrap();
        let mut events = 0;
        d.process_f32(&[0.0; 48_000], |_| events += 1);
        d.process_f32(&[f32::NAN, f32::INFINITY, -1e30, 1e30], |_| events += 1);
        let noise: Vec<i16> = (0..48_000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 16) as i16).collect();
        d.process_i16(&noise, |_| events += 1);
        assert_eq!(events, 0);
        assert_eq!(d.counters().frames, 0);
    }
}
