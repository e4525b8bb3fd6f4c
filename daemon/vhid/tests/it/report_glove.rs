//! The profile-driven report parser against the reference glove's encoder: hand-computed
//! values, one counter per rejection, sequence gaps and device-time unwrapping. (These lived
//! beside `ReportParser` until the glove's encoder moved to this crate.)

use frond_device::{ChannelId, DeviceProfile, ReportError, ReportParser};
use frond_vhid::glove::{GloveReport, encode_report};

fn glove() -> ReportParser {
    ReportParser::new(&DeviceProfile::frond_glove())
}

fn report(seq: u32, t_us: u32) -> GloveReport {
    GloveReport {
        seq,
        device_time_us: t_us,
        wrist_cdeg: [1234, -4500, 1],
        thumb_cdeg: [3000, 0, -17999],
        flex_cdeg: [10, 20, 30, 40],
        status: 1,
    }
}

#[test]
fn parses_hand_computed_values() {
    let mut p = glove();
    let s = p.parse(&encode_report(&report(7, 33_300))).unwrap();
    assert_eq!(s.device_seq, 7);
    assert_eq!(s.device_time_us, 33_300);
    assert_eq!(s.raw.t, 0.0333);
    // Same f32 as parsing the decimal text.
    assert_eq!(s.raw.wrist_deg, [12.34, -45.0, 0.01]);
    assert_eq!(s.raw.thumb_deg, [30.0, 0.0, -179.99]);
    assert_eq!(s.flex_deg, [0.1, 0.2, 0.3, 0.4]);
    assert_eq!(s.status, 1);
    assert_eq!(p.counters().snapshot().reports, 1);
}

#[test]
fn each_rejection_has_its_own_counter() {
    let mut p = glove();
    let good = encode_report(&report(1, 0));
    let mut wrong_id = good;
    wrong_id[0] = 2;
    assert!(matches!(p.parse(&wrong_id), Err(ReportError::WrongId { got: 2, .. })));
    assert!(matches!(p.parse(&good[..10]), Err(ReportError::Short { len: 10, .. })));
    assert!(matches!(p.parse(&[]), Err(ReportError::Short { len: 0, .. })));
    let mut long = [0u8; 65];
    long[..64].copy_from_slice(&good);
    assert!(matches!(p.parse(&long), Err(ReportError::Oversized { len: 65, .. })));
    let mut bad = good;
    bad[10] ^= 0x40;
    assert_eq!(p.parse(&bad), Err(ReportError::Checksum));
    let mut r = report(2, 0);
    r.thumb_cdeg[1] = 18_001; // 180.01 > max 180
    assert_eq!(p.parse(&encode_report(&r)), Err(ReportError::OutOfRange(ChannelId::ThumbG2)));
    let c = p.counters().snapshot();
    assert_eq!((c.wrong_id, c.short, c.oversized, c.checksum, c.out_of_range, c.reports), (1, 2, 1, 1, 1, 0));
}

#[test]
fn sequence_gaps_count_missing_reports_and_time_unwraps() {
    let mut p = glove();
    p.parse(&encode_report(&report(10, u32::MAX - 99))).unwrap();
    p.parse(&encode_report(&report(11, u32::MAX))).unwrap();
    let s = p.parse(&encode_report(&report(15, 100))).unwrap(); // 3 missing
    assert_eq!(s.device_time_us, u64::from(u32::MAX) + 101);
    assert_eq!(p.counters().snapshot().seq_gaps, 3);
    p.parse(&encode_report(&report(2, 200))).unwrap(); // restart, not a gap
    p.parse(&encode_report(&report(3, 300))).unwrap();
    assert_eq!(p.counters().snapshot().seq_gaps, 3);
    // Sequence wrap is not a gap either.
    p.parse(&encode_report(&report(u32::MAX, 400))).unwrap();
    p.parse(&encode_report(&report(0, 500))).unwrap();
    assert_eq!(p.counters().snapshot().seq_gaps, 3);
}
