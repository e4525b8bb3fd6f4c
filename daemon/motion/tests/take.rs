//! Take codec: round trips, torn tails, corruption, and property tests over arbitrary bytes and
//! every prefix of valid files.

use frond_motion::take::{
    MAGIC, RECORD_HEAD_LEN, TakeError, TakeFrame, TakeHeader, TakeRecord, encode_file_start, encode_record,
    scan_take,
};
use frond_motion::{HandSample, PoseFrame};
use proptest::prelude::*;

fn header() -> TakeHeader {
    TakeHeader {
        name: "sway-01".into(),
        rig_name: "grass".into(),
        calibration_id: "none".into(),
        filter: "none".into(),
        tick_rate_hz: 1000,
        created_unix_s: 1_700_000_000,
        daemon_version: "0.1.0".into(),
        joint_names: vec!["root".into(), "lower".into(), "middle".into(), "tip".into()],
    }
}

fn frame(seq: u64) -> TakeFrame {
    let v = seq as f32;
    TakeFrame {
        seq,
        device_time_us: seq * 1000,
        host_ns: 5_000_000 + seq * 1_000_000,
        flags: (seq % 3) as u32,
        element: 0,
        pose: PoseFrame { t: seq as f64 * 0.001, joints_deg: [[v, -v, 0.5 * v]; 4] },
        hand: HandSample { t: seq as f64 * 0.001, wrist_deg: [v, 1.0, 2.0], thumb_deg: [3.0, 4.0, v] },
    }
}

/// Encodes a file, returning it and the end offset of every record.
fn encode(records: &[TakeRecord]) -> (Vec<u8>, Vec<usize>) {
    let mut out = Vec::new();
    encode_file_start(&mut out);
    let mut ends = Vec::new();
    for r in records {
        encode_record(r, &mut out);
        ends.push(out.len());
    }
    (out, ends)
}

fn sample_records(frames: u64, end: bool) -> Vec<TakeRecord> {
    let mut r = vec![TakeRecord::Header(header())];
    for s in 0..frames {
        r.push(TakeRecord::Frame(frame(s)));
        if s == 2 {
            r.push(TakeRecord::Marker { seq: 2, label: "gust ✓".into() });
        }
    }
    if end {
        r.push(TakeRecord::End { frames });
    }
    r
}

#[test]
fn round_trip() {
    let records = sample_records(10, true);
    let (bytes, _) = encode(&records);
    let scan = scan_take(&bytes).unwrap();
    assert_eq!(scan.header, Some(header()));
    assert_eq!(scan.frames, (0..10).map(frame).collect::<Vec<_>>());
    assert_eq!(scan.markers, vec![(2, "gust ✓".to_string())]);
    assert!(scan.ended);
    assert_eq!(scan.valid_len, bytes.len() as u64);
    assert_eq!(scan.torn_bytes, 0);
    assert_eq!(scan.poses().len(), 10);
}

#[test]
fn frame_encoding_does_not_allocate_with_capacity() {
    let mut out = Vec::with_capacity(4096);
    let ptr = out.as_ptr();
    for s in 0..20 {
        encode_record(&TakeRecord::Frame(frame(s)), &mut out);
    }
    // No reallocation: same buffer, and every byte fits in the original capacity.
    assert_eq!(out.as_ptr(), ptr);
    assert_eq!(out.capacity(), 4096);
}

#[test]
fn torn_tail_is_not_an_error() {
    let (bytes, ends) = encode(&sample_records(5, false));
    // Cut 10 bytes into the last frame.
    let cut = ends[ends.len() - 2] + 10;
    let scan = scan_take(&bytes[..cut]).unwrap();
    assert_eq!(scan.frames.len(), 4);
    assert!(!scan.ended);
    assert_eq!(scan.valid_len, ends[ends.len() - 2] as u64);
    assert_eq!(scan.torn_bytes, 10);
}

#[test]
fn zero_filled_tail_after_a_crash_is_torn() {
    let (mut bytes, _) = encode(&sample_records(3, false));
    let valid = bytes.len();
    bytes.extend_from_slice(&[0; 4096]);
    let scan = scan_take(&bytes).unwrap();
    assert_eq!(scan.frames.len(), 3);
    assert_eq!(scan.valid_len, valid as u64);
    assert_eq!(scan.torn_bytes, 4096);
}

#[test]
fn damaged_last_record_is_a_torn_tail() {
    // Records: header, f0, f1, f2, marker. Damage the marker's last byte.
    let (mut bytes, ends) = encode(&sample_records(3, false));
    let last = bytes.len() - 1;
    bytes[last] ^= 0xff;
    let scan = scan_take(&bytes).unwrap();
    assert_eq!(scan.frames.len(), 3);
    assert!(scan.markers.is_empty());
    assert_eq!(scan.torn_bytes, (ends[4] - ends[3]) as u64);
    assert_eq!(scan.valid_len, ends[ends.len() - 2] as u64);
}

#[test]
fn corruption_in_the_middle_names_the_offset() {
    let (mut bytes, ends) = encode(&sample_records(6, true));
    // Records: header, f0, f1, f2, marker, f3, f4, f5, end. Damage f1's payload.
    let f1_start = ends[1];
    bytes[f1_start + RECORD_HEAD_LEN + 20] ^= 0x01;
    let err = scan_take(&bytes).unwrap_err();
    assert_eq!(
        err,
        TakeError::Corrupt {
            offset: f1_start as u64,
            reason: "checksum mismatch".into(),
            resumes_at: ends[2] as u64,
        }
    );
    assert!(err.to_string().contains(&format!("offset {f1_start}")), "{err}");

    // A damaged length field is caught too.
    let (mut bytes, ends) = encode(&sample_records(6, true));
    bytes[ends[3] + 3] = 0x7f;
    let err = scan_take(&bytes).unwrap_err();
    assert!(matches!(err, TakeError::Corrupt { offset, .. } if offset == ends[3] as u64), "{err}");
}

#[test]
fn bad_magic() {
    let err = scan_take(b"FRONDTK2rest").unwrap_err();
    assert!(matches!(err, TakeError::BadMagic { .. }));
    assert!(err.to_string().contains("offset 0"), "{err}");
    assert!(scan_take(b"PNG").is_err());
    // A prefix of the magic is an (empty) take still being created.
    let scan = scan_take(&MAGIC[..5]).unwrap();
    assert_eq!((scan.valid_len, scan.torn_bytes), (0, 5));
    assert_eq!(scan_take(b"").unwrap().torn_bytes, 0);
}

/// Appends a record with arbitrary kind and payload but a correct length and checksum.
fn raw_record(out: &mut Vec<u8>, kind: u8, payload: &[u8]) {
    let mut body = vec![kind];
    body.extend_from_slice(payload);
    out.extend_from_slice(&(body.len() as u32).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
    out.extend_from_slice(&body);
}

#[test]
fn unknown_kind_names_the_offset() {
    let (mut bytes, _) = encode(&sample_records(2, false));
    let at = bytes.len();
    raw_record(&mut bytes, 9, b"future");
    let err = scan_take(&bytes).unwrap_err();
    assert_eq!(err, TakeError::UnknownKind { offset: at as u64, kind: 9 });
}

#[test]
fn malformed_payloads_are_errors() {
    let cases: [(u8, &[u8], &str); 5] = [
        (2, &[0; 10], "bad frame record"),
        (1, b"{not json", "bad header record"),
        (3, &[1, 2, 3], "bad marker record"),
        (3, &[0, 0, 0, 0, 0, 0, 0, 0, 0xff], "label is not UTF-8"),
        (4, &[1, 2], "bad end record"),
    ];
    for (kind, payload, want) in cases {
        let mut bytes = Vec::new();
        encode_file_start(&mut bytes);
        raw_record(&mut bytes, kind, payload);
        let err = scan_take(&bytes).unwrap_err().to_string();
        assert!(err.contains(want) && err.contains("offset 8"), "{err}");
    }
}

#[test]
fn structure_errors() {
    // End with the wrong count.
    let mut records = sample_records(3, false);
    records.push(TakeRecord::End { frames: 4 });
    let err = scan_take(&encode(&records).0).unwrap_err().to_string();
    assert!(err.contains("End record says 4 frames, the take has 3"), "{err}");
    // A record after End.
    let mut records = sample_records(3, true);
    records.push(TakeRecord::Frame(frame(9)));
    let err = scan_take(&encode(&records).0).unwrap_err().to_string();
    assert!(err.contains("record after the End record"), "{err}");
    // A second header.
    let mut records = sample_records(1, false);
    records.push(TakeRecord::Header(header()));
    let err = scan_take(&encode(&records).0).unwrap_err().to_string();
    assert!(err.contains("a Header may only be the first record"), "{err}");
}

fn arb_frame() -> impl Strategy<Value = TakeFrame> {
    (
        any::<u64>(),
        any::<u64>(),
        any::<u64>(),
        any::<u32>(),
        any::<u16>(),
        any::<[f32; 12]>(),
        any::<[f32; 6]>(),
        any::<f64>(),
    )
        .prop_map(|(seq, dev, host, flags, element, j, h, t)| TakeFrame {
            seq,
            device_time_us: dev,
            host_ns: host,
            flags,
            element,
            pose: PoseFrame {
                t,
                joints_deg: [
                    [j[0], j[1], j[2]],
                    [j[3], j[4], j[5]],
                    [j[6], j[7], j[8]],
                    [j[9], j[10], j[11]],
                ],
            },
            hand: HandSample { t, wrist_deg: [h[0], h[1], h[2]], thumb_deg: [h[3], h[4], h[5]] },
        })
}

fn arb_records() -> impl Strategy<Value = Vec<TakeRecord>> {
    (
        prop::collection::vec(
            prop_oneof![
                4 => arb_frame().prop_map(TakeRecord::Frame),
                1 => (any::<u64>(), ".{0,20}").prop_map(|(seq, label)| TakeRecord::Marker { seq, label }),
            ],
            0..12,
        ),
        any::<bool>(),
    )
        .prop_map(|(body, end)| {
            let mut r = vec![TakeRecord::Header(header())];
            let frames = body.iter().filter(|r| matches!(r, TakeRecord::Frame(_))).count() as u64;
            r.extend(body);
            if end {
                r.push(TakeRecord::End { frames });
            }
            r
        })
}

/// Compares frames bit for bit (NaN payloads included).
fn frame_bits(f: &TakeFrame) -> Vec<u8> {
    let mut out = Vec::new();
    encode_record(&TakeRecord::Frame(*f), &mut out);
    out
}

fn frames_of(records: &[TakeRecord]) -> Vec<Vec<u8>> {
    records
        .iter()
        .filter_map(|r| match r {
            TakeRecord::Frame(f) => Some(frame_bits(f)),
            _ => None,
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let _ = scan_take(&bytes);
        let mut with_magic = MAGIC.to_vec();
        with_magic.extend_from_slice(&bytes);
        if let Ok(scan) = scan_take(&with_magic) {
            prop_assert_eq!(scan.valid_len + scan.torn_bytes, with_magic.len() as u64);
        }
    }

    #[test]
    fn round_trip_arbitrary(records in arb_records()) {
        let (bytes, _) = encode(&records);
        let scan = scan_take(&bytes).unwrap();
        prop_assert_eq!(scan.frames.iter().map(frame_bits).collect::<Vec<_>>(), frames_of(&records));
        let markers: Vec<(u64, String)> = records.iter().filter_map(|r| match r {
            TakeRecord::Marker { seq, label } => Some((*seq, label.clone())),
            _ => None,
        }).collect();
        prop_assert_eq!(scan.markers, markers);
        prop_assert_eq!(scan.ended, matches!(records.last(), Some(TakeRecord::End { .. })));
        prop_assert_eq!(scan.torn_bytes, 0);
    }

    #[test]
    fn every_prefix_scans_to_a_prefix(records in arb_records(), cut_frac in 0.0f64..=1.0) {
        let (bytes, ends) = encode(&records);
        let cut = ((bytes.len() as f64) * cut_frac) as usize;
        let scan = scan_take(&bytes[..cut]).unwrap();
        // The complete records in the prefix are exactly those ending at or before the cut.
        let complete = ends.iter().take_while(|&&e| e <= cut).count();
        let want_valid = if complete == 0 { if cut >= MAGIC.len() { MAGIC.len() } else { 0 } } else { ends[complete - 1] };
        prop_assert_eq!(scan.valid_len, want_valid as u64);
        prop_assert_eq!(scan.torn_bytes, (cut - want_valid) as u64);
        prop_assert_eq!(scan.header.is_some(), complete >= 1);
        let all = frames_of(&records);
        let got: Vec<Vec<u8>> = scan.frames.iter().map(frame_bits).collect();
        prop_assert_eq!(&got[..], &all[..got.len()]);
        prop_assert_eq!(got.len(), frames_of(&records[..complete]).len());
    }

    #[test]
    fn flipped_bytes_never_panic(records in arb_records(), at in any::<prop::sample::Index>(), bit in 0u8..8) {
        let (mut bytes, _) = encode(&records);
        let i = at.index(bytes.len());
        bytes[i] ^= 1 << bit;
        if let Ok(scan) = scan_take(&bytes) {
            // Whatever is accepted is a prefix of the original frames (a flip can only shorten).
            let all = frames_of(&records);
            let got: Vec<Vec<u8>> = scan.frames.iter().map(frame_bits).collect();
            prop_assert!(got.len() <= all.len());
            prop_assert_eq!(&got[..], &all[..got.len()]);
        }
    }
}
