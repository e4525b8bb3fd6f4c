//! Take codec: round trips, torn tails, corruption, and property tests over arbitrary bytes and
//! every prefix of valid files.

use frond_formats::take::{
    MAGIC, RECORD_HEAD_LEN, TakeError, TakeRecord, encode_file_start, encode_record, scan_take,
    scan_take_salvaging,
};
use frond_motion::take::{Skipped, TakeFrame, TakeHeader};
use frond_motion::{HandSample, PoseFrame};
use frond_protocol::ElementId;
use proptest::prelude::*;

fn header() -> TakeHeader {
    TakeHeader {
        created_unix_s: 1_700_000_000,
        joint_names: vec!["root".into(), "lower".into(), "middle".into(), "tip".into()],
        ..TakeHeader::offline("sway-01", "grass", 1000)
    }
}

fn frame(seq: u64) -> TakeFrame {
    let v = seq as f32;
    TakeFrame {
        seq,
        device_time_us: seq * 1000,
        host_ns: 5_000_000 + seq * 1_000_000,
        flags: (seq % 3) as u32,
        element: ElementId::GLOBAL,
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

/// Issue 46: the stage clock anchor is an optional header field: a take with it round-trips,
/// and a header written before it existed (no `stage_clock` key) reads as it always did.
#[test]
fn the_stage_clock_anchor_round_trips_and_old_headers_read_without_it() {
    use frond_motion::take::{StageAnchor, TakeClock};
    let anchor = StageAnchor {
        host_ns: 7_000_000_000,
        label: "10:00:00:00".into(),
        frame_count: 900_000,
        nominal_fps: 25,
        drop_frame: false,
        ntsc: false,
    };
    let staged = TakeHeader { stage_clock: Some(anchor.clone()), ..header() };
    let (bytes, _) = encode(&[TakeRecord::Header(staged.clone()), TakeRecord::End { frames: 0 }]);
    assert_eq!(scan_take(&bytes).unwrap().header, Some(staged));
    // `ntsc` is written only when true (a 29.97 stage), so other anchors read as before.
    assert!(!String::from_utf8_lossy(&bytes).contains("ntsc"));
    let ntsc = StageAnchor { nominal_fps: 30, frame_count: 1_080_000, ntsc: true, ..anchor };
    let staged = TakeHeader { stage_clock: Some(ntsc), ..header() };
    let (bytes, _) = encode(&[TakeRecord::Header(staged.clone()), TakeRecord::End { frames: 0 }]);
    assert!(String::from_utf8_lossy(&bytes).contains("\"ntsc\":true"));
    assert_eq!(scan_take(&bytes).unwrap().header, Some(staged));
    let old = r#"{"name":"sway-01","rig_name":"grass","calibration_id":"none","filter":"none",
        "tick_rate_hz":1000,"created_unix_s":1700000000,"daemon_version":"frond 0.1.0",
        "joint_names":[],"clock":{"unix_ns":1764683110500000000,"host_ns":5000000000}}"#;
    let old: TakeHeader = serde_json::from_str(old).unwrap();
    assert_eq!(old.stage_clock, None);
    assert_eq!(old.clock, Some(TakeClock { unix_ns: 1_764_683_110_500_000_000, host_ns: 5_000_000_000 }));
    assert_eq!(old.timecode_of(5_000_000_000, 30.0).unwrap().to_string(), "13:45:10:15");
    let mut json = Vec::new();
    serde_json::to_writer(&mut json, &header()).unwrap();
    assert!(!String::from_utf8(json).unwrap().contains("stage_clock"), "absent, not null");
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
fn damage_in_the_middle_is_skipped_and_reported() {
    let (mut bytes, ends) = encode(&sample_records(6, true));
    // Records: header, f0, f1, f2, marker, f3, f4, f5, end. Damage f1's payload.
    let f1_start = ends[1];
    bytes[f1_start + RECORD_HEAD_LEN + 20] ^= 0x01;
    let scan = scan_take(&bytes).unwrap();
    let seqs: Vec<u64> = scan.frames.iter().map(|f| f.seq).collect();
    assert_eq!(seqs, [0, 2, 3, 4, 5]);
    assert_eq!(
        scan.skipped,
        [Skipped {
            offset: f1_start as u64,
            len: (ends[2] - ends[1]) as u64,
            reason: "checksum mismatch".into(),
            frames: 0
        }]
    );
    assert!(scan.ended && scan.header.is_some());
    assert_eq!(scan.markers.len(), 1);
    assert_eq!((scan.end_frames, scan.missing_frames()), (Some(6), 1));
    assert_eq!(
        scan.damage().unwrap(),
        format!(
            "1 damaged stretch skipped (127 bytes; 127 bytes at offset {f1_start} (checksum mismatch)), 1 frame lost"
        )
    );
    assert_eq!(scan.valid_len, bytes.len() as u64);

    // A damaged length field is caught too, and the reader resumes at the next record.
    let (mut bytes, ends) = encode(&sample_records(6, true));
    bytes[ends[3] + 3] = 0x7f;
    let scan = scan_take(&bytes).unwrap();
    assert_eq!(scan.skipped.len(), 1, "{:?}", scan.skipped);
    assert_eq!(scan.skipped[0].offset, ends[3] as u64);
    assert_eq!(scan.skipped[0].offset + scan.skipped[0].len, ends[4] as u64);
    assert!(scan.skipped[0].reason.contains("implausible record length"), "{:?}", scan.skipped);
    assert!(scan.markers.is_empty(), "the marker was the damaged record");
    assert_eq!(scan.frames.len(), 6);
}

#[test]
fn non_finite_frames_are_refused_by_frame_and_skipped_when_salvaging() {
    for (bad, field, value) in [
        (f32::NAN, "pose joint 2", "NaN"),
        (f32::INFINITY, "pose joint 2", "inf"),
        (f32::NEG_INFINITY, "pose joint 2", "-inf"),
    ] {
        let mut records = sample_records(4, true);
        // Records: header, f0, f1, f2, marker, f3, end: frame 3 is records[5].
        let TakeRecord::Frame(f) = &mut records[5] else { panic!() };
        f.pose.joints_deg[2][1] = bad;
        let (bytes, ends) = encode(&records);
        let err = scan_take(&bytes).unwrap_err();
        assert_eq!(
            err,
            TakeError::NonFinite { frame: 3, seq: 3, offset: ends[4] as u64, field, value: value.into() }
        );
        assert!(err.to_string().starts_with("frame 3 (seq 3"), "{err}");
        let scan = scan_take_salvaging(&bytes).unwrap();
        assert_eq!(scan.frames.iter().map(|f| f.seq).collect::<Vec<_>>(), [0, 1, 2]);
        assert_eq!(scan.skipped.len(), 1);
        assert_eq!((scan.skipped[0].offset, scan.skipped[0].frames), (ends[4] as u64, 1));
        assert!(scan.ended);
    }
    // The hand sample and the times are checked too.
    let mut records = sample_records(1, false);
    let TakeRecord::Frame(f) = &mut records[1] else { panic!() };
    f.hand.t = f64::INFINITY;
    let err = scan_take(&encode(&records).0).unwrap_err().to_string();
    assert!(err.contains("frame 0 (seq 0") && err.contains("hand.t"), "{err}");
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
        prop::array::uniform12(-1e30f32..1e30),
        prop::array::uniform6(-1e30f32..1e30),
        -1e12f64..1e12,
    )
        .prop_map(|(seq, dev, host, flags, element, j, h, t)| TakeFrame {
            seq,
            device_time_us: dev,
            host_ns: host,
            flags,
            element: ElementId::new(element),
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
    fn a_flipped_bit_costs_at_most_the_record_it_hits(
        records in arb_records(), at in any::<prop::sample::Index>(), bit in 0u8..8,
    ) {
        let (mut bytes, ends) = encode(&records);
        let i = at.index(bytes.len());
        bytes[i] ^= 1 << bit;
        if i < MAGIC.len() {
            let bad_magic = matches!(scan_take(&bytes), Err(TakeError::BadMagic { .. }));
            prop_assert!(bad_magic);
            return Ok(());
        }
        // The record the flip landed in (CRC-32 catches every single-bit error).
        let hit = ends.iter().position(|&e| i < e).unwrap();
        let scan = scan_take(&bytes).unwrap();
        let mut want = records.clone();
        want.remove(hit);
        prop_assert_eq!(scan.frames.iter().map(frame_bits).collect::<Vec<_>>(), frames_of(&want));
        let start = if hit == 0 { MAGIC.len() } else { ends[hit - 1] };
        if hit + 1 == records.len() {
            // The last record: a torn tail, nothing after it to resynchronise on.
            prop_assert!(scan.skipped.is_empty());
            prop_assert_eq!(scan.valid_len, start as u64);
        } else {
            prop_assert_eq!(scan.skipped.len(), 1);
            prop_assert_eq!(scan.skipped[0].offset, start as u64);
            prop_assert_eq!(scan.skipped[0].len, (ends[hit] - start) as u64);
            prop_assert_eq!(scan.valid_len, bytes.len() as u64);
        }
    }

    #[test]
    fn the_reader_resynchronises_after_garbage(
        records in arb_records(),
        at in any::<prop::sample::Index>(),
        garbage in prop::collection::vec(any::<u8>(), 1..300),
    ) {
        // Garbage inserted between two records (a torn write in the middle, a stray block):
        // every record is still read and the garbage is reported exactly.
        let (bytes, ends) = encode(&records);
        // Before any record but the last (the header included).
        let starts: Vec<usize> = std::iter::once(MAGIC.len()).chain(ends[..ends.len() - 1].iter().copied()).collect();
        let cut = starts[at.index(starts.len())];
        let mut damaged = bytes[..cut].to_vec();
        damaged.extend_from_slice(&garbage);
        damaged.extend_from_slice(&bytes[cut..]);
        let scan = scan_take(&damaged).unwrap();
        prop_assert_eq!(scan.frames.iter().map(frame_bits).collect::<Vec<_>>(), frames_of(&records));
        prop_assert!(scan.header.is_some());
        // Garbage could only pass for a whole record by a 2^-32 checksum accident.
        prop_assert_eq!(scan.skipped.len(), 1);
        prop_assert_eq!(scan.skipped[0].offset, cut as u64);
        prop_assert_eq!(scan.skipped_bytes(), garbage.len() as u64);
    }
}

/// Time steps as a tracker or a damaged take may give them: small, repeated, backwards, huge,
/// not finite.
fn arb_step() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => 0.0f64..0.05,
        1 => Just(0.0),
        1 => -10.0f64..0.0,
        1 => 1.0f64..1e12,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Issue 14, point 7: resampling is bounded by the input, never by its time span. With every
    /// step longer than `MAX_INTERPOLATED_GAP_S` (or backwards, or not finite) collapsed to one
    /// output frame, `n` input frames at `fps` give at most `(n - 1) * max(gap * fps, 1) + 1`
    /// frames (plus the one-twentieth tolerance), whatever the times say; the plan counts
    /// exactly what `resample` then gives, before anything is allocated.
    #[test]
    fn resampling_is_bounded_by_the_input_not_its_time_span(
        steps in prop::collection::vec(arb_step(), 0..60),
        fps in prop_oneof![Just(30.0f64), Just(1000.0), 1.0f64..240.0],
    ) {
        use frond_motion::take::{MAX_INTERPOLATED_GAP_S, resample, resample_plan};
        let mut t = 0.0f64;
        let mut frames = vec![PoseFrame { t, joints_deg: [[0.0; 3]; 4] }];
        for (k, dt) in steps.iter().enumerate() {
            t = if dt.is_finite() { t + dt } else { *dt };
            frames.push(PoseFrame { t, joints_deg: [[k as f32; 3]; 4] });
            if !t.is_finite() {
                t = 0.0;
            }
        }
        let plan = resample_plan(&frames, fps);
        let out = resample(&frames, fps);
        prop_assert_eq!(plan.frames, out.len() as u64);
        let per_step = (MAX_INTERPOLATED_GAP_S * fps).max(1.0);
        let bound = (frames.len() - 1) as f64 * per_step + 1.05 + 1.0;
        prop_assert!((out.len() as f64) <= bound, "{} frames from {} inputs at {fps}", out.len(), frames.len());
        prop_assert!(out.iter().all(|p| p.t.is_finite()));
    }
}
