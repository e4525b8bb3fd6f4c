//! Device profile parsing: every problem reported with its path, never a panic.

use frond_device::profile::{AngleUnit, FieldType, TimeUnit};
use frond_device::{ChannelId, DeviceProfile, ProfileError};
use proptest::prelude::*;

fn problems(text: &str) -> Vec<String> {
    match DeviceProfile::from_toml_str(text) {
        Err(ProfileError::Invalid(p)) => p.iter().map(ToString::to_string).collect(),
        other => panic!("expected Invalid, got {other:?}"),
    }
}

const CHANNELS: &str = r#"
[[channel]]
name = "wrist_pitch"
offset = 1
type = "i16le"
scale = 0.01
unit = "deg"
min = -180
max = 180
[[channel]]
name = "wrist_yaw"
offset = 3
type = "i16le"
unit = "deg"
min = -180
max = 180
[[channel]]
name = "wrist_roll"
offset = 5
type = "f32le"
unit = "rad"
min = -3.2
max = 3.2
[[channel]]
name = "thumb_g1"
offset = 9
type = "u8"
unit = "deg"
min = 0
max = 255
[[channel]]
name = "thumb_g2"
offset = 10
type = "i8"
unit = "deg"
min = -128
max = 127
[[channel]]
name = "thumb_g3"
offset = 11
type = "u16le"
scale = 0.1
unit = "deg"
min = 0
max = 200
"#;

#[test]
fn shipped_profile_file_matches_the_embedded_one() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../rig-files/devices/frond-glove.toml");
    let p = DeviceProfile::load(std::path::Path::new(path)).unwrap();
    assert_eq!(p, DeviceProfile::frond_glove());
    assert_eq!(p.device_time.unwrap().unit, TimeUnit::Us);
}

#[test]
fn a_minimal_path_profile_parses() {
    let text = format!("name = \"g\"\npath = \"/dev/hidraw9\"\nreport_len = 13\n{CHANNELS}");
    let p = DeviceProfile::from_toml_str(&text).unwrap();
    assert_eq!(p.path.as_deref(), Some(std::path::Path::new("/dev/hidraw9")));
    assert_eq!(p.report_id, None);
    let roll = p.channel(ChannelId::WristRoll).unwrap();
    assert_eq!((roll.ty, roll.unit, roll.scale), (FieldType::F32Le, AngleUnit::Rad, 1.0));
}

#[test]
fn every_problem_is_listed_with_its_path() {
    let text = r#"
vendor_id = 0x12345
report_id = 1
report_len = 64
colour = "red"
sequence = { offset = 62, type = "u32le" }
device_time = { offset = 5, type = "i32le", unit = "ns" }
checksum = { kind = "crc", offset = 64 }

[[channel]]
name = "wrist_pitch"
offset = 0
type = "i16le"
unit = "deg"
min = 0
max = 10

[[channel]]
name = "wrist_pitch"
offset = 9
type = "i24"
unit = "grad"
min = 10
max = 5

[[channel]]
name = "pinky"
offset = 11
type = "u8"
scale = 0
unit = "deg"
min = 0
max = 1

[[channel]]
name = "thumb_g1"
offset = 70
type = "i16le"
unit = "deg"
min = 0
max = 1
"#;
    let p = problems(text);
    let expect = [
        "name: missing",
        "vendor_id: 74565 is out of range 0..=65535",
        "product_id: missing (vendor_id is set)",
        "colour: unknown key",
        "sequence.offset: a 4-byte field at 62 runs past report_len 64",
        "device_time.type: must be an unsigned integer type (u8, u16le, u32le)",
        "device_time.unit: unknown unit \"ns\" (expected us or ms)",
        "checksum.kind: unknown checksum \"crc\" (expected sum8)",
        "checksum.offset: 64 is past report_len 64",
        "channel[0].offset: 0 overlaps the report id byte",
        "channel[1].name: wrist_pitch is defined more than once",
        "channel[1].type: unknown type \"i24\"",
        "channel[1].unit: unknown unit \"grad\" (expected deg or rad)",
        "channel[1].max: 5 must be greater than min 10",
        "channel[2].name: unknown channel \"pinky\"",
        "channel[2].scale: must not be zero",
        "channel[3].offset: 70 is past report_len 64",
        "channel: required channel wrist_yaw is missing",
        "channel: required channel thumb_g3 is missing",
    ];
    for e in expect {
        assert!(p.iter().any(|x| x.starts_with(e)), "missing {e:?} in:\n{}", p.join("\n"));
    }
    // The error message lists them all.
    let msg = DeviceProfile::from_toml_str(text).unwrap_err().to_string();
    assert!(msg.contains("channel[3].offset: 70 is past report_len 64"), "{msg}");
}

#[test]
fn syntax_errors_and_missing_files_are_typed() {
    assert!(matches!(DeviceProfile::from_toml_str("name = "), Err(ProfileError::Syntax(_))));
    assert!(matches!(
        DeviceProfile::load(std::path::Path::new("/nonexistent/x.toml")),
        Err(ProfileError::Io { .. })
    ));
    let p = problems("name = 3\nreport_len = \"64\"\nchannel = 1\n");
    assert!(p.iter().any(|x| x == "name: expected a string, got integer"), "{p:?}");
    assert!(p.iter().any(|x| x == "report_len: expected an integer, got string"), "{p:?}");
    assert!(p.iter().any(|x| x.starts_with("channel: expected an array of tables")), "{p:?}");
    assert!(p.iter().any(|x| x.starts_with("vendor_id: missing: give vendor_id")), "{p:?}");
}

proptest! {
    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,400}") {
        let _ = DeviceProfile::from_toml_str(&text);
    }

    #[test]
    fn mutated_reference_profile_never_panics(
        at in 0usize..2000,
        replacement in "[-0-9a-z_\\[\\]=\". \n]{0,12}",
    ) {
        let base = frond_device::profile::FROND_GLOVE_TOML;
        let at = at.min(base.len());
        let at = (0..=at).rev().find(|i| base.is_char_boundary(*i)).unwrap_or(0);
        let text = format!("{}{}{}", &base[..at], replacement, &base[at..]);
        let _ = DeviceProfile::from_toml_str(&text);
    }
}
