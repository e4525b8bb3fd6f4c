//! The frond reference glove: its 64-byte HID input report and report descriptor.
//!
//! This is the layout `frond-vhid` emits and `rig-files/devices/frond-glove.toml` describes.
//! All multi-byte fields are little-endian; angles are signed centidegrees (`i16`, so the range is
//! -327.68..=327.67 degrees).
//!
//! | bytes   | field                                                                  |
//! |---------|------------------------------------------------------------------------|
//! | 0       | report id, always `0x01`                                               |
//! | 1..5    | `u32` report sequence (increments by one per generated report, wraps)  |
//! | 5..9    | `u32` device time in microseconds (wraps after ~71.6 minutes)          |
//! | 9..21   | six `i16` centidegrees: wrist pitch, yaw, roll, thumb g1, g2, g3       |
//! | 21..29  | four `i16` centidegrees: flex of index, middle, ring, little finger    |
//! | 29      | `u8` status: bit 0 = tracking ok, other bits reserved (0)              |
//! | 30..63  | zero                                                                   |
//! | 63      | checksum: chosen so the 8-bit sum of all 64 bytes is 0                 |
//!
//! The checksum lets the daemon tell corrupted reports from valid ones and count them.
//!
//! Exactness: a JSONL hand file whose angles have at most two decimals and whose times have at
//! most six (whole microseconds) travels through this report unchanged: the parser yields the
//! very same `f32` angles and `f64` time as parsing the file's text (see [`deg_to_cdeg`] and
//! `ReportParser`). Finer values are rounded to 0.01 degree and 1 microsecond.

use frond_motion::HandSample;

/// Report id of the glove's only input report.
pub const REPORT_ID: u8 = 0x01;
/// Length of the input report in bytes, report id included.
pub const REPORT_LEN: usize = 64;
/// USB vendor id used by the reference glove (pid.codes open-source vendor id).
pub const VENDOR_ID: u16 = 0x1209;
/// USB product id of the reference glove.
pub const PRODUCT_ID: u16 = 0xF0D1;
/// Byte offset of the `u32` sequence.
pub const SEQ_OFFSET: usize = 1;
/// Byte offset of the `u32` device time in microseconds.
pub const TIME_OFFSET: usize = 5;
/// Byte offset of the six hand angles (wrist pitch, yaw, roll, thumb g1, g2, g3).
pub const HAND_OFFSET: usize = 9;
/// Byte offset of the four finger flex angles (index, middle, ring, little).
pub const FLEX_OFFSET: usize = 21;
/// Byte offset of the status byte.
pub const STATUS_OFFSET: usize = 29;
/// Byte offset of the checksum byte.
pub const CHECKSUM_OFFSET: usize = 63;
/// Status bit 0: the glove is tracking the hand.
pub const STATUS_TRACKING_OK: u8 = 0x01;

/// HID report descriptor of the glove: vendor page 0xFF00, one input report with id 1 carrying
/// 63 opaque bytes (64 with the id byte).
pub const REPORT_DESCRIPTOR: [u8; 23] = [
    0x06, 0x00, 0xFF, // Usage Page (Vendor Defined 0xFF00)
    0x09, 0x01, // Usage (0x01)
    0xA1, 0x01, // Collection (Application)
    0x85, REPORT_ID, //   Report ID (1)
    0x09, 0x02, //   Usage (0x02)
    0x15, 0x00, //   Logical Minimum (0)
    0x26, 0xFF, 0x00, //   Logical Maximum (255)
    0x75, 0x08, //   Report Size (8 bits)
    0x95, 0x3F, //   Report Count (63)
    0x81, 0x02, //   Input (Data, Variable, Absolute)
    0xC0, // End Collection
];

/// The values carried by one glove report, in wire units.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GloveReport {
    /// Report sequence number.
    pub seq: u32,
    /// Device time in microseconds (wrapping counter).
    pub device_time_us: u32,
    /// Wrist pitch, yaw, roll in centidegrees.
    pub wrist_cdeg: [i16; 3],
    /// Thumb g1, g2, g3 in centidegrees.
    pub thumb_cdeg: [i16; 3],
    /// Flex of index, middle, ring and little finger in centidegrees.
    pub flex_cdeg: [i16; 4],
    /// Status byte (bit 0 = tracking ok).
    pub status: u8,
}

/// Degrees to centidegrees, rounded to nearest and clamped to the `i16` range.
///
/// Rounding is done in `f64` so a value read from text (`12.34`) becomes exactly `1234`, and the
/// parser's `(1234 as f64 / 100.0) as f32` gives back the same `f32` as parsing `"12.34"`.
/// Returns the value and whether it had to be clamped (or was NaN).
pub fn deg_to_cdeg(deg: f32) -> (i16, bool) {
    let c = (f64::from(deg) * 100.0).round();
    if c.is_nan() {
        return (0, true);
    }
    if c > f64::from(i16::MAX) {
        return (i16::MAX, true);
    }
    if c < f64::from(i16::MIN) {
        return (i16::MIN, true);
    }
    (c as i16, false)
}

impl GloveReport {
    /// Builds a report from a hand sample in degrees. Angles outside the `i16` centidegree range
    /// are clamped; the returned flag says whether any value was clamped.
    pub fn from_degrees(
        seq: u32,
        device_time_us: u32,
        hand: &HandSample,
        flex_deg: [f32; 4],
        status: u8,
    ) -> (Self, bool) {
        let mut clamped = false;
        let mut conv = |d: f32| {
            let (c, k) = deg_to_cdeg(d);
            clamped |= k;
            c
        };
        let report = Self {
            seq,
            device_time_us,
            wrist_cdeg: hand.wrist_deg.map(&mut conv),
            thumb_cdeg: hand.thumb_deg.map(&mut conv),
            flex_cdeg: flex_deg.map(&mut conv),
            status,
        };
        (report, clamped)
    }
}

/// Encodes a report in the layout documented at the top of this module.
pub fn encode_report(report: &GloveReport) -> [u8; REPORT_LEN] {
    let mut b = [0u8; REPORT_LEN];
    b[0] = REPORT_ID;
    b[SEQ_OFFSET..SEQ_OFFSET + 4].copy_from_slice(&report.seq.to_le_bytes());
    b[TIME_OFFSET..TIME_OFFSET + 4].copy_from_slice(&report.device_time_us.to_le_bytes());
    let angles = report.wrist_cdeg.iter().chain(report.thumb_cdeg.iter()).chain(report.flex_cdeg.iter());
    for (i, v) in angles.enumerate() {
        let at = HAND_OFFSET + 2 * i;
        b[at..at + 2].copy_from_slice(&v.to_le_bytes());
    }
    b[STATUS_OFFSET] = report.status;
    b[CHECKSUM_OFFSET] = checksum_byte(&b[..CHECKSUM_OFFSET]);
    b
}

/// The byte that makes the 8-bit sum of `bytes` plus itself zero.
pub fn checksum_byte(bytes: &[u8]) -> u8 {
    sum8(bytes).wrapping_neg()
}

/// 8-bit wrapping sum of `bytes` (the parser's check, defined beside it in `frond-device`).
pub use frond_device::report::sum8;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_matches_hand_written_bytes() {
        let r = GloveReport {
            seq: 0x0403_0201,
            device_time_us: 33_300,
            wrist_cdeg: [1234, -1, 0],
            thumb_cdeg: [100, 200, -300],
            flex_cdeg: [1, 2, 3, 4],
            status: 1,
        };
        let b = encode_report(&r);
        assert_eq!(b[0], 0x01);
        assert_eq!(&b[1..5], &[1, 2, 3, 4]);
        // 33300 = 0x8214
        assert_eq!(&b[5..9], &[0x14, 0x82, 0, 0]);
        // 1234 = 0x04D2, -1 = 0xFFFF
        assert_eq!(&b[9..15], &[0xD2, 0x04, 0xFF, 0xFF, 0, 0]);
        // -300 = 0xFED4
        assert_eq!(&b[15..21], &[100, 0, 200, 0, 0xD4, 0xFE]);
        assert_eq!(&b[21..29], &[1, 0, 2, 0, 3, 0, 4, 0]);
        assert_eq!(b[29], 1);
        assert!(b[30..63].iter().all(|&x| x == 0));
        let total: u32 = b.iter().map(|&x| u32::from(x)).sum();
        assert_eq!(total % 256, 0);
    }

    #[test]
    fn degrees_round_to_centidegrees_and_clamp() {
        assert_eq!(deg_to_cdeg(12.34), (1234, false));
        assert_eq!(deg_to_cdeg(-0.006), (-1, false));
        assert_eq!(deg_to_cdeg(-0.004), (0, false));
        assert_eq!(deg_to_cdeg(400.0), (i16::MAX, true));
        assert_eq!(deg_to_cdeg(-400.0), (i16::MIN, true));
        assert_eq!(deg_to_cdeg(f32::NAN), (0, true));
    }

    #[test]
    fn descriptor_declares_63_input_bytes_with_id_1() {
        let d = REPORT_DESCRIPTOR;
        assert_eq!(&d[..3], &[0x06, 0x00, 0xFF]);
        let id = d.windows(2).position(|w| w[0] == 0x85).unwrap();
        assert_eq!(d[id + 1], 1);
        let count = d.windows(2).position(|w| w[0] == 0x95).unwrap();
        assert_eq!(d[count + 1], 63);
        assert_eq!(*d.last().unwrap(), 0xC0);
    }
}
