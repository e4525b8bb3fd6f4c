//! SMPTE 12M linear timecode (LTC) for frond: the stage's master clock, read from audio.
//!
//! A motion-capture stage distributes its timecode as LTC, an audio signal; every system on
//! the stage stamps its samples with it so takes line up. This crate is the pure part of
//! reading it: [`LtcDecoder`] takes mono samples (`f32` or `i16`, 8 to 192 kHz) and reports
//! [`LtcEvent`]s: each frame's label, lock, loss and jumps. It reads 24, 25, 29.97 drop-frame
//! and 30 fps, whatever the level or polarity of the signal, because it decodes biphase mark
//! code by the intervals between transitions, not by levels.
//! [`FrameRate`] and [`SmpteTime`] hold the drop-frame arithmetic (label <-> frame count);
//! [`StageClock`] gives the stage timecode at any host monotonic instant, interpolated from the
//! last frame. [`encode`] goes the other way, labels to the signal, for tests and benchmarks.
//!
//! No I/O and no allocation after [`LtcDecoder::new`]: the caller feeds samples from a
//! capture device, a file or a pipe on a helper thread (never the realtime loop) and maps
//! [`LtcFrame::end_sample`] to its monotonic clock.
//!
//! The frame layout (80 bits, BCD fields least significant bit first, drop-frame flag at
//! bit 10, sync word `0011 1111 1111 1101` at bits 64-79) is SMPTE 12M's, as tabulated from
//! ITU-R BR.780-2 in <https://en.wikipedia.org/wiki/Linear_timecode>; see the `frame` module.

#![warn(missing_docs)]

mod biphase;
mod clock;
mod decoder;
pub mod encode;
mod frame;
mod timecode;

pub use clock::{StageClock, StageTime};
pub use decoder::{
    LOCK_FRAMES, LtcCounters, LtcDecoder, LtcError, LtcEvent, LtcFrame, MAX_SAMPLE_RATE_HZ,
    MIN_SAMPLE_RATE_HZ,
};
pub use frame::{FRAME_BITS, SYNC_WORD};
pub use timecode::{FrameRate, MAX_LABEL_FRAMES, SmpteTime, TimecodeError};
