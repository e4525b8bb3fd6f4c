//! Fuzzes the device side: HID input reports through `ReportParser` with the reference glove
//! profile, and device profile files (`DeviceProfile::from_toml_str`). Every profile that
//! validates is then used to parse reports, which checks the parser's reliance on the profile
//! validation ("every offset + size <= report_len") with hostile profiles.

use frond_device::profile::{CHANNEL_KEYS, FROND_GLOVE_TOML, PROFILE_KEYS};
use frond_device::{ChannelId, DeviceProfile, ProfileError, ReportError, ReportParser};
use frond_fuzz::{Rng, Target, as_text, assert_message, fuzz, toml_outcome};
use frond_vhid::glove::{GloveReport, REPORT_LEN, encode_report};

/// Sets the reference glove's checksum byte so the 8-bit sum is 0 (the inputs then reach the
/// channel range checks instead of stopping at the checksum).
fn fix_checksum(v: &mut Vec<u8>, rng: &mut Rng) {
    if rng.chance(3, 4) {
        v.resize(REPORT_LEN, 0);
    }
    if let Some((last, rest)) = v.split_last_mut() {
        *last = rest.iter().fold(0u8, |s, b| s.wrapping_sub(*b));
    }
}

fn glove_report(seq: u32, t_us: u32, wrist: [i16; 3], thumb: [i16; 3]) -> Vec<u8> {
    encode_report(&GloveReport {
        seq,
        device_time_us: t_us,
        wrist_cdeg: wrist,
        thumb_cdeg: thumb,
        flex_cdeg: [100, -200, 300, -400],
        status: 1,
    })
    .to_vec()
}

/// Checks one accepted sample against the profile's ranges.
fn check_sample(profile: &DeviceProfile, s: &frond_device::DeviceSample) {
    for c in &profile.channels {
        let v = match c.id.slot() {
            k @ 0..3 => s.raw.wrist_deg[k],
            k @ 3..6 => s.raw.thumb_deg[k - 3],
            k => s.flex_deg[k - 6],
        };
        assert!(v.is_finite(), "{} is {v}", c.id);
        let (lo, hi) = match c.unit {
            frond_device::profile::AngleUnit::Deg => (c.min, c.max),
            frond_device::profile::AngleUnit::Rad => (c.min.to_degrees(), c.max.to_degrees()),
        };
        // The f32 rounding of a value at the edge may land just outside the f64 range.
        let slack = 1e-4 * (1.0 + lo.abs().max(hi.abs()));
        assert!(
            f64::from(v) >= lo - slack && f64::from(v) <= hi + slack,
            "{} = {v} outside {lo}..={hi}",
            c.id
        );
    }
    assert!(s.raw.t.is_finite() && s.raw.t >= 0.0);
}

/// Parses `bytes` as one report and as a stream of `report_len` chunks with one parser, and
/// checks that the counters add up.
fn parse_reports(profile: &DeviceProfile, bytes: &[u8]) -> &'static str {
    let mut parser = ReportParser::new(profile);
    let mut results = vec![parser.parse(bytes)];
    for chunk in bytes.chunks(profile.report_len.max(1)) {
        results.push(parser.parse(chunk));
    }
    for r in &results {
        match r {
            Ok(s) => check_sample(profile, s),
            Err(e) => {
                assert_message(e);
                if let ReportError::Short { len, expected } | ReportError::Oversized { len, expected } = e {
                    assert_ne!(len, expected);
                }
            }
        }
    }
    let c = parser.counters().snapshot();
    let ok = results.iter().filter(|r| r.is_ok()).count() as u64;
    assert_eq!(c.reports, ok, "accepted reports miscounted");
    assert_eq!(c.rejected(), results.len() as u64 - ok, "rejected reports miscounted");
    match results[0] {
        Ok(_) => "ok",
        Err(ReportError::OutOfRange(_)) => "out of range",
        Err(ReportError::Checksum) => "checksum",
        Err(_) => "id or length",
    }
}

#[test]
fn fuzz_device_reports() {
    let profile = DeviceProfile::frond_glove();
    let seeds = vec![
        glove_report(0, 0, [0; 3], [0; 3]),
        glove_report(7, 33_300, [1234, -4500, 1], [3000, 0, -17999]),
        glove_report(u32::MAX, u32::MAX, [18000, -18000, 0], [18000, 18000, -18000]),
        [glove_report(1, 1000, [1, 2, 3], [4, 5, 6]), glove_report(2, 2000, [7, 8, 9], [10, 11, 12])]
            .concat(),
    ];
    let dict: Vec<Vec<u8>> = vec![
        vec![0x01],
        vec![0x02],
        18_000i16.to_le_bytes().to_vec(),
        18_001i16.to_le_bytes().to_vec(),
        (-18_001i16).to_le_bytes().to_vec(),
        i16::MIN.to_le_bytes().to_vec(),
        i16::MAX.to_le_bytes().to_vec(),
    ];
    let report = fuzz(
        Target::new("device-report").seeds(seeds).dict(dict).max_len(200).fixup(fix_checksum),
        move |b| parse_reports(&profile, b),
    );
    report.assert_reaches("ok", 50);
    report.assert_reaches("out of range", 10);
}

/// A small profile with every optional part, in another layout than the glove's.
const SMALL_PROFILE: &str = r#"
name = "small"
path = "/dev/hidraw9"
report_len = 16
sequence = { offset = 0, type = "u8" }
device_time = { offset = 1, type = "u16le", unit = "ms" }
checksum = { kind = "sum8", offset = 15 }
status = { offset = 14 }
[[channel]]
name = "wrist_pitch"
offset = 3
type = "i8"
unit = "rad"
scale = 0.05
min = -3.2
max = 3.2
[[channel]]
name = "wrist_yaw"
offset = 4
type = "u8"
unit = "deg"
min = 0
max = 255
[[channel]]
name = "wrist_roll"
offset = 5
type = "f32le"
unit = "deg"
min = -360
max = 360
[[channel]]
name = "thumb_g1"
offset = 9
type = "u16le"
unit = "deg"
scale = 1e-300
min = -1
max = 1
[[channel]]
name = "thumb_g2"
offset = 11
type = "i8"
unit = "deg"
min = -128
max = 127
[[channel]]
name = "thumb_g3"
offset = 12
type = "i16le"
unit = "deg"
scale = -0.5
min = -360
max = 360
"#;

#[test]
fn fuzz_device_profiles() {
    let seeds = [FROND_GLOVE_TOML, SMALL_PROFILE];
    for s in seeds {
        DeviceProfile::from_toml_str(s).expect("seed profiles are valid");
    }
    // The profile's own key lists and channel names, then the values a profile writes.
    let mut dict: Vec<String> = PROFILE_KEYS.iter().chain(CHANNEL_KEYS).map(|k| k.to_string()).collect();
    dict.extend(ChannelId::ALL.iter().map(|c| format!("\"{}\"", c.as_str())));
    dict.extend(
        [
            "[[channel]]",
            "\"u8\"",
            "\"i8\"",
            "\"u16le\"",
            "\"i16le\"",
            "\"u32le\"",
            "\"i32le\"",
            "\"f32le\"",
            "\"deg\"",
            "\"rad\"",
            "\"us\"",
            "\"ms\"",
            "\"sum8\"",
            "0xFFFF",
            "0x10000",
        ]
        .map(String::from),
    );
    let report = fuzz(Target::new("device-profile").seeds(seeds).text().dict(dict), |b| {
        toml_outcome(
            DeviceProfile::from_toml_str(&as_text(b)),
            |e| matches!(e, ProfileError::Syntax(_)),
            |profile| {
                // A profile that validates must be safe to parse any report with.
                let mut rng = Rng::new(frond_fuzz::fnv1a(b));
                let len = profile.report_len;
                let mut report: Vec<u8> = (0..len).map(|_| rng.next_u64() as u8).collect();
                if let Some(id) = profile.report_id {
                    report[0] = id;
                }
                parse_reports(&profile, &report);
                parse_reports(&profile, &vec![0xff; len]);
                parse_reports(&profile, &report[..len - 1]);
            },
        )
    });
    report.assert_reaches("ok", 50);
    report.assert_reaches("invalid", 50);
}
