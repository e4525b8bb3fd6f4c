//! The 80-bit LTC frame: where each field sits, and the sync word that ends a frame.
//!
//! Layout (SMPTE 12M / ITU-R BR.780-2, as tabulated in "Linear timecode", Wikipedia,
//! <https://en.wikipedia.org/wiki/Linear_timecode>), bits numbered in transmission order,
//! every number binary-coded decimal, least significant bit first:
//!
//! | bits | field | bits | field |
//! |---|---|---|---|
//! | 0-3 | frame units | 32-35 | minute units |
//! | 4-7 | user bits 1 | 36-39 | user bits 5 |
//! | 8-9 | frame tens | 40-42 | minute tens |
//! | 10 | drop-frame flag | 43 | binary group flag (parity at 25 fps) |
//! | 11 | colour-frame flag | 44-47 | user bits 6 |
//! | 12-15 | user bits 2 | 48-51 | hour units |
//! | 16-19 | second units | 52-55 | user bits 7 |
//! | 20-23 | user bits 3 | 56-57 | hour tens |
//! | 24-26 | second tens | 58 | binary group flag 1 |
//! | 27 | polarity-correction (parity) bit, a flag at 25 fps | 59 | flag (parity at 25 fps) |
//! | 28-31 | user bits 4 | 60-63 | user bits 8 |
//!
//! Bits 64-79 are the sync word `0011 1111 1111 1101`: twelve ones in a row occur nowhere
//! else in a frame, and the `01` at its end tells the direction of play.

use crate::timecode::SmpteTime;

/// The sync word as it sits in bits 64-79 of a frame read least significant bit first:
/// bits 64-65 are 0, 66-77 are 1, 78 is 0, 79 is 1.
pub const SYNC_WORD: u16 = 0b1011_1111_1111_1100;

/// Bits in one frame.
pub const FRAME_BITS: u32 = 80;

/// One frame's fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FrameFields {
    pub(crate) time: SmpteTime,
    pub(crate) colour_frame: bool,
    pub(crate) user_bits: u32,
}

fn field(bits: u64, first: u32, width: u32) -> u8 {
    ((bits >> first) & ((1 << width) - 1)) as u8
}

fn bcd(bits: u64, units_at: u32, tens_at: u32, tens_width: u32) -> Option<u8> {
    let units = field(bits, units_at, 4);
    (units <= 9).then(|| field(bits, tens_at, tens_width) * 10 + units)
}

/// Reads bits 0-63 of a frame (bit 0 the least significant). `None` when a digit is not a
/// decimal digit or a field is out of range: no real generator sends that, noise can.
pub(crate) fn decode_fields(bits: u64) -> Option<FrameFields> {
    let time = SmpteTime {
        frames: bcd(bits, 0, 8, 2)?,
        seconds: bcd(bits, 16, 24, 3)?,
        minutes: bcd(bits, 32, 40, 3)?,
        hours: bcd(bits, 48, 56, 2)?,
        drop_frame: field(bits, 10, 1) == 1,
    };
    if time.frames > 29 || time.check_fields().is_err() {
        return None;
    }
    let user_bits = [4, 12, 20, 28, 36, 44, 52, 60]
        .iter()
        .enumerate()
        .fold(0u32, |acc, (i, &at)| acc | u32::from(field(bits, at, 4)) << (4 * i));
    Some(FrameFields { time, colour_frame: field(bits, 11, 1) == 1, user_bits })
}

/// Collects bits and finds frames by their sync word.
#[derive(Debug, Clone, Default)]
pub(crate) struct FrameAssembler {
    /// The last 80 bits, the oldest at bit 0.
    register: u128,
    /// Bits taken since the last frame (or reset), saturating.
    since_frame: u32,
}

impl FrameAssembler {
    /// Takes the next bit; returns bits 0-63 of a frame it completes.
    pub(crate) fn push(&mut self, bit: bool) -> Option<u64> {
        self.register = (self.register >> 1) | (u128::from(bit) << (FRAME_BITS - 1));
        self.since_frame = self.since_frame.saturating_add(1);
        let sync = (self.register >> 64) as u16;
        if self.since_frame >= FRAME_BITS && sync == SYNC_WORD {
            self.since_frame = 0;
            return Some(self.register as u64);
        }
        None
    }

    /// Forgets partial bits (after the bit stream lost its phase).
    pub(crate) fn reset(&mut self) {
        self.since_frame = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_of_a_frame_built_by_hand() {
        // 12:34:56:17, drop flag clear, user bits 1..8 = 1, 2, ..., 8.
        let mut bits: u64 = 0;
        let mut put = |at: u32, width: u32, v: u64| bits |= (v & ((1 << width) - 1)) << at;
        put(0, 4, 7);
        put(8, 2, 1);
        put(16, 4, 6);
        put(24, 3, 5);
        put(32, 4, 4);
        put(40, 3, 3);
        put(48, 4, 2);
        put(56, 2, 1);
        for (i, at) in [4, 12, 20, 28, 36, 44, 52, 60].into_iter().enumerate() {
            put(at, 4, i as u64 + 1);
        }
        let f = decode_fields(bits).unwrap();
        assert_eq!(f.time.to_string(), "12:34:56:17");
        assert_eq!(f.user_bits, 0x8765_4321);
        assert!(decode_fields(bits | 0xF).is_none(), "frame units 15 is no BCD digit");
    }

    #[test]
    fn a_frame_is_found_only_after_eighty_bits_ending_in_the_sync_word() {
        let mut asm = FrameAssembler::default();
        let sync: Vec<bool> = (0..16).map(|i| SYNC_WORD >> i & 1 == 1).collect();
        // The sync word alone, too early, is no frame.
        assert!(sync.iter().filter_map(|&b| asm.push(b)).next().is_none());
        let data: Vec<bool> = (0..64).map(|i| i % 3 == 0).collect();
        let found: Vec<u64> = data.iter().chain(&sync).filter_map(|&b| asm.push(b)).collect();
        let expected = (0..64).filter(|i| i % 3 == 0).fold(0u64, |acc, i| acc | 1 << i);
        assert_eq!(found, [expected]);
    }
}
