//! Report parser properties: arbitrary bytes never panic; encode -> parse round-trips.

use frond_device::{DeviceProfile, ReportError, ReportParser};
use frond_vhid::glove::{GloveReport, REPORT_LEN, encode_report};
use proptest::prelude::*;

fn in_range_cdeg() -> impl Strategy<Value = i16> {
    -18_000i16..=18_000
}

proptest! {
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let mut p = ReportParser::new(&DeviceProfile::frond_glove());
        let r = p.parse(&bytes);
        let c = p.counters().snapshot();
        // Exactly one counter moved.
        prop_assert_eq!(c.reports + c.rejected(), 1);
        if bytes.len() != REPORT_LEN {
            prop_assert!(r.is_err());
        }
    }

    #[test]
    fn encode_parse_round_trip(
        seq in any::<u32>(),
        time in any::<u32>(),
        wrist in proptest::array::uniform3(in_range_cdeg()),
        thumb in proptest::array::uniform3(in_range_cdeg()),
        flex in proptest::array::uniform4(in_range_cdeg()),
        status in any::<u8>(),
    ) {
        let r = GloveReport { seq, device_time_us: time, wrist_cdeg: wrist, thumb_cdeg: thumb, flex_cdeg: flex, status };
        let mut p = ReportParser::new(&DeviceProfile::frond_glove());
        let s = p.parse(&encode_report(&r)).unwrap();
        prop_assert_eq!(s.device_seq, seq);
        prop_assert_eq!(s.device_time_us, u64::from(time));
        prop_assert_eq!(s.raw.t, f64::from(time) / 1e6);
        prop_assert_eq!(s.status, status);
        // Independent expectation: the decimal text "<cdeg/100>" parsed as f32.
        let text = |c: i16| -> f32 {
            let sign = if c < 0 { "-" } else { "" };
            let a = c.unsigned_abs();
            format!("{sign}{}.{:02}", a / 100, a % 100).parse().unwrap()
        };
        prop_assert_eq!(s.raw.wrist_deg, wrist.map(text));
        prop_assert_eq!(s.raw.thumb_deg, thumb.map(text));
        prop_assert_eq!(s.flex_deg, flex.map(text));
        // And re-encoding the parsed degrees gives the same bytes.
        let (again, clamped) = GloveReport::from_degrees(seq, time, &s.raw, s.flex_deg, status);
        prop_assert!(!clamped);
        prop_assert_eq!(again, r);
    }

    #[test]
    fn any_single_byte_corruption_is_caught(
        wrist in proptest::array::uniform3(in_range_cdeg()),
        at in 0usize..REPORT_LEN,
        flip in 1u8..=255,
    ) {
        let r = GloveReport { seq: 1, device_time_us: 2, wrist_cdeg: wrist, thumb_cdeg: [0; 3], flex_cdeg: [0; 4], status: 1 };
        let mut b = encode_report(&r);
        b[at] ^= flip;
        let mut p = ReportParser::new(&DeviceProfile::frond_glove());
        let e = p.parse(&b).unwrap_err();
        if at == 0 {
            prop_assert!(matches!(e, ReportError::WrongId { .. }), "{:?}", e);
        } else {
            prop_assert_eq!(e, ReportError::Checksum);
        }
    }
}
