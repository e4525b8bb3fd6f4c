//! Fuzzes the parsers of frond-motion (rigs, calibrations, filter specs) and frond-formats (JSONL
//! hand and pose lines, take files). Accepted inputs must survive the format's own writer: writing
//! the parsed value and parsing it again gives the same value (the writers document this round
//! trip).

use frond_formats::rig_toml::{CalibrationText, RigText};
use frond_formats::take::{MAGIC, RECORD_HEAD_LEN, encode_file_start, encode_record};
use frond_formats::{
    JsonlError, TakeError, TakeRecord, parse_hand_line, parse_pose_line, scan_take, write_hand_line,
    write_pose_line,
};
use frond_fuzz::{Rng, Target, as_text, assert_message, assert_round_trip, fuzz, toml_outcome};
use frond_motion::{
    Calibration, CalibrationError, FilterSpec, HandSample, PoseFrame, Rig, RigError, TakeFrame, TakeHeader,
};
use frond_protocol::ElementId;

const RIGS: [&str; 3] = [
    include_str!("../../../rig-files/plants/grass.toml"),
    include_str!("../../../rig-files/plants/flower.toml"),
    include_str!("../../../rig-files/plants/shrub.toml"),
];

const RIG_TOKENS: &[&str] = &[
    "name",
    "description",
    "tau",
    "thumb_range_deg",
    "bend_range_deg",
    "bend_range_deg = [12.0, 12.0]",
    "filter",
    "[[joints]]",
    "height_m",
    "s_pitch",
    "s_yaw",
    "s_roll",
    "[[elements]]",
    "attach_joint",
    "count",
    "length_m",
    "[mesh]",
    "shape",
    "width_m",
    "file",
    "\"blade\"",
    "\"flower\"",
    "\"shrub\"",
    "\"lowpass:cutoff_hz=8\"",
    "\"one-euro\"",
    "joints = []",
    "elements = [{ name = \"leaf\", attach_joint = 2, length_m = 0.05 }]",
];

#[test]
fn fuzz_rigs() {
    let minimal = "name = \"m\"\njoints = [{ height_m = 0.0 }, { height_m = 0.1 }, { height_m = 0.2 }, \
                   { height_m = 0.3 }]\n";
    let seeds = [RIGS[0], RIGS[1], RIGS[2], minimal];
    for s in seeds {
        Rig::from_toml_str(s).expect("seed rigs are valid");
    }
    let report = fuzz(Target::new("rig").seeds(seeds).text().dict(RIG_TOKENS).max_len(6000), |b| {
        toml_outcome(
            Rig::from_toml_str(&as_text(b)),
            |e| matches!(e, RigError::Toml(_)),
            |rig| assert_round_trip("rig", &rig, &rig.to_toml_string(), Rig::from_toml_str),
        )
    });
    report.assert_reaches("ok", 50);
    report.assert_reaches("invalid", 50);
}

#[test]
fn fuzz_calibrations() {
    let seeds = [
        include_str!("../../../rig-files/calibrations/default.toml"),
        include_str!("../../../rig-files/calibrations/example-user.toml"),
    ];
    for s in seeds {
        Calibration::from_toml_str(s).expect("seed calibrations are valid");
    }
    let dict = [
        "id",
        "neutral_wrist_deg",
        "neutral_thumb_deg",
        "thumb_range_deg",
        "wrist_range_deg",
        "[1.0, 2.0]",
        "[[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]",
        "[0.0, 0.0, 0.0]",
    ];
    let report = fuzz(Target::new("calibration").seeds(seeds).text().dict(dict), |b| {
        toml_outcome(
            Calibration::from_toml_str(&as_text(b)),
            |e| matches!(e, CalibrationError::Toml(_)),
            |c| assert_round_trip("calibration", &c, &c.to_toml_string(), Calibration::from_toml_str),
        )
    });
    report.assert_reaches("ok", 50);
    report.assert_reaches("invalid", 20);
}

#[test]
fn fuzz_filter_specs() {
    let seeds = [
        "none",
        "lowpass",
        "lowpass:cutoff_hz=8",
        "one-euro",
        "one-euro:min_cutoff=1.0,beta=0.007,d_cutoff=1.0",
        " one-euro : beta = 0 , d_cutoff=2 ",
    ];
    for s in seeds {
        s.parse::<FilterSpec>().expect("seed specs are valid");
    }
    let dict = ["none", "lowpass", "one-euro", "cutoff_hz", "min_cutoff", "beta", "d_cutoff", "=", ",", ":"];
    let report = fuzz(Target::new("filter-spec").seeds(seeds).text().dict(dict).max_len(256), |b| {
        match as_text(b).parse::<FilterSpec>() {
            Ok(spec) => {
                spec.validate().unwrap_or_else(|e| panic!("parsed spec {spec:?} does not validate: {e}"));
                let text = spec.to_string();
                assert_eq!(
                    text.parse::<FilterSpec>(),
                    Ok(spec),
                    "spec changed through its text form {text:?}"
                );
                "ok"
            }
            Err(e) => {
                assert_message(&e);
                "refused"
            }
        }
    });
    report.assert_reaches("ok", 50);
}

const JSON_TOKENS: &[&str] = &[
    "{",
    "}",
    "[",
    "]",
    ",",
    ":",
    "\"t\"",
    "\"wrist\"",
    "\"thumb\"",
    "\"seq\"",
    "\"joints\"",
    "null",
    "true",
    "[1,2,3]",
    "[[1,2,3],[4,5,6],[7,8,9],[10,11,12]]",
    "1e39",
    "-1e39",
    "3.4028236e38",
    "1e400",
    "\"\\ud800\"",
    "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[",
];

/// The `f64` time survives writing and reading back to within one unit in the last place.
///
/// Not exactly: serde_json without its `float_roundtrip` feature parses some decimals one ulp
/// off the nearest `f64` (`"t":1e-45` reads as `1.0000000000000001e-45`, which is then written
/// as such), so `write_pose_line`'s "identical frame" promise holds only within 1 ulp for `t`.
/// Found by this fuzzer; the inputs are in `corpus/jsonl-*/crash-*`.
fn assert_time_close(a: f64, b: f64, line: &str) {
    let ulps = (a.to_bits() as i64).wrapping_sub(b.to_bits() as i64).unsigned_abs();
    assert!(
        a == b || (a.signum() == b.signum() && ulps <= 1),
        "t changed from {b:e} to {a:e} through {line}"
    );
}

fn jsonl_label(e: &JsonlError) -> &'static str {
    match e {
        JsonlError::NotJson(_) => "json",
        _ => "fields",
    }
}

#[test]
fn fuzz_jsonl_hand_lines() {
    let seeds = [
        r#"{"t":0.0333,"wrist":[10,-20.5,3],"thumb":[1,2,3.25]}"#,
        r#"{"t":0,"wrist":[0,0,0],"thumb":[0,0,0],"extra":{"a":[1,2]}}"#,
        r#"{"thumb":[-180,180,0.01],"wrist":[1e-7,-0.0,359.99],"t":1e9}"#,
    ];
    for s in seeds {
        parse_hand_line(s).expect("seed lines are valid");
    }
    let report = fuzz(Target::new("jsonl-hand").seeds(seeds).text().dict(JSON_TOKENS).max_len(1024), |b| {
        match parse_hand_line(&as_text(b)) {
            Ok(h) => {
                assert!(h.t.is_finite());
                assert!(h.wrist_deg.iter().chain(&h.thumb_deg).all(|v| v.is_finite()));
                let mut line = String::new();
                write_hand_line(&h, &mut line);
                let again: HandSample = parse_hand_line(&line).expect("own line parses");
                assert_eq!(
                    (again.wrist_deg, again.thumb_deg),
                    (h.wrist_deg, h.thumb_deg),
                    "angles changed: {line}"
                );
                assert_time_close(again.t, h.t, &line);
                "ok"
            }
            Err(e) => {
                assert_message(&e);
                jsonl_label(&e)
            }
        }
    });
    report.assert_reaches("ok", 50);
    report.assert_reaches("fields", 20);
}

#[test]
fn fuzz_jsonl_pose_lines() {
    let seeds = [
        r#"{"seq":7,"t":0.5,"joints":[[1,2,3],[4,5,6],[7,8,9],[10,11,12]]}"#,
        r#"{"t":0,"joints":[[0,0,0],[0,0,0],[0,0,0],[0,0,0]],"flags":["held"]}"#,
        r#"{"seq":18446744073709551615,"t":-1.5e3,"joints":[[-180,180,0.5],[1e-3,2,3],[4,5,6],[7,8,9]]}"#,
    ];
    for s in seeds {
        parse_pose_line(s).expect("seed lines are valid");
    }
    let report = fuzz(Target::new("jsonl-pose").seeds(seeds).text().dict(JSON_TOKENS).max_len(1024), |b| {
        match frond_formats::jsonl::parse_pose_line_with_seq(&as_text(b)) {
            Ok((seq, p)) => {
                assert!(p.t.is_finite());
                assert!(p.joints_deg.iter().flatten().all(|v| v.is_finite()));
                let mut line = String::new();
                write_pose_line(&p, seq, &mut line);
                let (seq2, again) =
                    frond_formats::jsonl::parse_pose_line_with_seq(&line).expect("own line parses");
                assert_eq!((seq2, again.joints_deg), (seq, p.joints_deg), "pose changed through {line}");
                assert_time_close(again.t, p.t, &line);
                assert_eq!(parse_pose_line(&as_text(b)).map(|q| q.joints_deg), Ok(p.joints_deg));
                "ok"
            }
            Err(e) => {
                assert_message(&e);
                assert!(parse_pose_line(&as_text(b)).is_err());
                jsonl_label(&e)
            }
        }
    });
    report.assert_reaches("ok", 50);
    report.assert_reaches("fields", 20);
}

fn take_frame(seq: u64, flags: u32) -> TakeFrame {
    TakeFrame {
        seq,
        device_time_us: seq * 1000,
        host_ns: 5_000_000_000 + seq * 1_000_000,
        flags,
        element: ElementId::GLOBAL,
        pose: PoseFrame { t: seq as f64 / 1000.0, joints_deg: [[1.0, 2.0, 3.0]; 4] },
        hand: HandSample { t: seq as f64 / 1000.0, wrist_deg: [4.0, 5.0, 6.0], thumb_deg: [7.0, 8.0, 9.0] },
    }
}

fn take_bytes(frames: u64, marker: bool, end: bool) -> Vec<u8> {
    let mut out = Vec::new();
    encode_file_start(&mut out);
    encode_record(
        &TakeRecord::Header(TakeHeader {
            created_unix_s: 1_700_000_000,
            joint_names: ["a", "b", "c", "d"].map(String::from).to_vec(),
            ..TakeHeader::offline("t", "grass", 1000)
        }),
        &mut out,
    );
    for s in 0..frames {
        encode_record(&TakeRecord::Frame(take_frame(s, (s % 3) as u32)), &mut out);
        if marker && s == 1 {
            encode_record(&TakeRecord::Marker { seq: s, label: "cue".into() }, &mut out);
        }
    }
    if end {
        encode_record(&TakeRecord::End { frames }, &mut out);
    }
    out
}

/// Restores the magic (usually) and recomputes every record's CRC that a plausible length lets
/// it find, so that mutations reach the payload decoders and the structure checks.
#[allow(clippy::ptr_arg)] // the signature of `Target::fixup`
fn fix_take(v: &mut Vec<u8>, rng: &mut Rng) {
    if v.len() >= MAGIC.len() && rng.chance(7, 8) {
        v[..MAGIC.len()].copy_from_slice(MAGIC);
    }
    let mut at = MAGIC.len();
    while at + RECORD_HEAD_LEN < v.len() {
        let len = u32::from_le_bytes([v[at], v[at + 1], v[at + 2], v[at + 3]]) as usize;
        let end = at + RECORD_HEAD_LEN + len;
        if len == 0 || end > v.len() {
            break;
        }
        let crc = crc32(&v[at + RECORD_HEAD_LEN..end]);
        v[at + 4..at + 8].copy_from_slice(&crc.to_le_bytes());
        at = end;
    }
}

/// CRC-32 (IEEE), bitwise: a second implementation, independent of the codec's crc32fast.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

#[test]
fn fuzz_take_files() {
    let seeds = vec![take_bytes(0, false, true), take_bytes(3, true, true), take_bytes(5, false, false), {
        let mut torn = take_bytes(4, false, false);
        torn.extend_from_slice(&[40, 0, 0, 0, 1, 2]);
        torn
    }];
    assert!(scan_take(&seeds[1]).expect("seed take").ended);
    let dict: Vec<Vec<u8>> =
        vec![MAGIC.to_vec(), vec![1], vec![2], vec![3], vec![4], vec![5], 119u32.to_le_bytes().to_vec()];
    let report =
        fuzz(
            Target::new("take").seeds(seeds).dict(dict).max_len(4096).fixup(fix_take),
            |b| match scan_take(b) {
                Ok(scan) => {
                    assert_eq!(
                        scan.valid_len + scan.torn_bytes,
                        b.len() as u64,
                        "valid + torn must cover the file"
                    );
                    if scan.ended {
                        assert!(scan.header.is_some() || scan.valid_len > MAGIC.len() as u64);
                    }
                    // The part before the torn tail scans to the same result with no tail.
                    let head = scan_take(&b[..scan.valid_len as usize]).expect("the valid part scans");
                    // Compared as encoded bytes: frames may hold NaN, which is not equal to itself.
                    let enc = |frames: &[TakeFrame]| {
                        let mut out = Vec::new();
                        frames.iter().for_each(|f| encode_record(&TakeRecord::Frame(*f), &mut out));
                        out
                    };
                    assert_eq!(enc(&head.frames), enc(&scan.frames));
                    assert_eq!(head.markers, scan.markers);
                    assert_eq!(head.ended, scan.ended);
                    assert_eq!(head.torn_bytes, 0);
                    if scan.ended { "ended" } else { "open or torn" }
                }
                Err(e) => {
                    assert_message(&e);
                    match e {
                        TakeError::BadMagic { .. } => "bad magic",
                        TakeError::Corrupt { .. } => "corrupt",
                        _ => "bad record or structure",
                    }
                }
            },
        );
    report.assert_reaches("ended", 20);
    report.assert_reaches("open or torn", 50);
    report.assert_reaches("bad record or structure", 20);
}
