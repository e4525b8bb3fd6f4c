//! Rig files read and written by frond-formats: defaults, per-joint scales, unknown keys refused,
//! every problem listed with its path, and a round trip through the text.

use frond_formats::rig_toml::RigText;
use frond_motion::{FilterSpec, MappingParams, Rig, RigError};

const MINIMAL: &str = r#"
name = "blade"
joints = [
  { height_m = 0.0 },
  { height_m = 0.1 },
  { height_m = 0.2 },
  { height_m = 0.3 },
]
"#;

#[test]
fn defaults() {
    let r = Rig::from_toml_str(MINIMAL).unwrap();
    assert_eq!(r.name, "blade");
    assert_eq!(r.description, "");
    assert_eq!(r.tau, 2);
    assert_eq!(r.thumb_range_deg, [60.0, 70.0, 60.0]);
    assert_eq!(r.filter, FilterSpec::None);
    assert!(r.elements.is_empty());
    assert_eq!(r.joint_names(), ["joint0", "joint1", "joint2", "joint3"]);
    assert_eq!(r.mapping(), MappingParams::default());
}

#[test]
fn mapping_takes_per_joint_scales() {
    let text = r#"
name = "x"
tau = 3
joints = [
  { height_m = 0.0, s_pitch = 0.5, s_yaw = 0.25, s_roll = 2 },
  { height_m = 0.1, s_pitch = 1.5 },
  { height_m = 0.2, s_yaw = -1 },
  { height_m = 0.3, s_roll = 0 },
]
"#;
    let m = Rig::from_toml_str(text).unwrap().mapping();
    assert_eq!(m.tau, 3);
    assert_eq!(m.scale, [[0.5, 0.25, 2.0], [1.5, 1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 0.0]]);
}

#[test]
fn unknown_fields_are_refused() {
    let e = Rig::from_toml_str(&MINIMAL.replace("name = \"blade\"", "name = \"b\"\ntwist = 1")).unwrap_err();
    assert!(matches!(e, RigError::Toml(_)));
    assert!(e.to_string().contains("twist"), "{e}");
    let e = Rig::from_toml_str(&MINIMAL.replace("{ height_m = 0.2 }", "{ height_m = 0.2, s_pich = 1 }"))
        .unwrap_err();
    assert!(e.to_string().contains("s_pich"), "{e}");
}

#[test]
fn every_problem_is_listed_with_its_path() {
    let text = r#"
name = ""
tau = 4
thumb_range_deg = [60, 0, -1]
filter = "lowpass:cutoff_hz=-2"
joints = [
  { name = "base", height_m = -0.1, s_pitch = inf },
  { name = "base", height_m = 0.3 },
  { height_m = 0.3, s_roll = nan },
  { name = "", height_m = 0.2 },
]
[[elements]]
name = "leaf"
attach_joint = 4
count = 0
length_m = 0
tau = -1
[[elements]]
name = "leaf"
attach_joint = 1
length_m = 0.05
"#;
    let Err(RigError::Invalid(p)) = Rig::from_toml_str(text) else {
        panic!("expected validation errors");
    };
    let msg = p.to_string();
    let want = [
        "name: must not be empty",
        "tau: 4 is out of range 0..=3",
        "thumb_range_deg[1]: a thumb range (degrees) must be between 1 and 360, found 0",
        "thumb_range_deg[2]: a thumb range (degrees) must be between 1 and 360, found -1",
        "filter: parameter `cutoff_hz`: -2 must be a finite number > 0",
        "joints[0].height_m: the root must not be below ground, found -0.1",
        "joints[0].s_pitch: must be a finite number, found inf",
        "joints[1].name: `base` is already the name of joints[0]",
        "joints[2].height_m: 0.3 must be above joints[1].height_m (0.3)",
        "joints[2].s_roll: must be a finite number, found NaN",
        "joints[3].name: must not be empty",
        "joints[3].height_m: 0.2 must be above joints[2].height_m (0.3)",
        "elements[0].attach_joint: 4 is out of range 0..=3",
        "elements[0].count: 0 must be between 1 and 256",
        "elements[0].length_m: must be greater than 0, found 0",
        "elements[0].tau: -1 is out of range 0..=3",
        "elements[1].name: `leaf` is already the name of elements[0]",
    ];
    let got: Vec<String> = p.0.iter().map(|x| x.to_string()).collect();
    assert_eq!(got, want, "{msg}");
    assert!(msg.starts_with("17 problems:"), "{msg}");
}

/// Issue 14, point 11: well-formed but absurd sizes and scales are refused with the limits
/// of `frond_motion::plausible`; the limits themselves are accepted.
#[test]
fn implausible_scales_sizes_and_counts_are_refused() {
    let rig = |scale: &str, top_m: &str, count: &str, length_m: &str, range: &str| {
        format!(
            "name = \"x\"\nthumb_range_deg = [{range}, 60, 60]\njoints = [\n\
             {{ height_m = 0.0, s_pitch = {scale} }}, {{ height_m = 0.1 }}, {{ height_m = 0.2 }}, \
             {{ height_m = {top_m}, s_roll = -{scale} }},\n]\n\
             [[elements]]\nname = \"leaf\"\nattach_joint = 1\ncount = {count}\nlength_m = {length_m}\n"
        )
    };
    assert!(Rig::from_toml_str(&rig("20", "1000", "256", "1000", "1")).is_ok());
    let Err(RigError::Invalid(p)) = Rig::from_toml_str(&rig("1e30", "1001", "1000000", "2000", "1e-45"))
    else {
        panic!("absurd rig accepted");
    };
    let got: Vec<String> = p.0.iter().map(|x| x.to_string()).collect();
    assert_eq!(
        got,
        [
            "thumb_range_deg[0]: a thumb range (degrees) must be between 1 and 360, found \
             0.000000000000000000000000000000000000000000001",
            "joints[0].s_pitch: a joint scale must be between -20 and 20, found 1000000000000000000000000000000",
            "joints[3].height_m: a height (metres) must be between -1000 and 1000, found 1001",
            "joints[3].s_roll: a joint scale must be between -20 and 20, found -1000000000000000000000000000000",
            "elements[0].count: 1000000 must be between 1 and 256",
            "elements[0].length_m: must be at most 1000 metres, found 2000",
        ]
    );
}

#[test]
fn wrong_joint_count() {
    let text = "name = \"x\"\njoints = [{ height_m = 0.0 }, { height_m = 1.0 }]\n";
    let Err(RigError::Invalid(p)) = Rig::from_toml_str(text) else {
        panic!("expected validation errors");
    };
    assert_eq!(p.to_string(), "1 problem:\n  joints: expected 4 joints, found 2");
}

#[test]
fn round_trips_through_toml() {
    let text = r#"
name = "flower"
description = "stem with \"leaves\""
tau = 1
thumb_range_deg = [55.5, 1.5, 80]
filter = "one-euro:beta=0.01"
joints = [
  { name = "root", height_m = 0.0, s_pitch = 0.3, s_yaw = 0.3, s_roll = 0.7 },
  { name = "lower", height_m = 0.1, s_pitch = 0.6 },
  { name = "upper", height_m = 0.2 },
  { name = "head", height_m = 0.35, s_pitch = 1.2, s_yaw = 1.2 },
]
[[elements]]
name = "leaf"
attach_joint = 1
count = 3
length_m = 0.08
tau = 1
"#;
    let r = Rig::from_toml_str(text).unwrap();
    let again = Rig::from_toml_str(&r.to_toml_string()).unwrap();
    assert_eq!(again, r, "{}", r.to_toml_string());
    assert_eq!(r.elements[0].count, 3);
}
