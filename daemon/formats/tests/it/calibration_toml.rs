//! Calibration files read and written by frond-formats: they round-trip, every problem is
//! listed with its path, and TOML errors are reported as toml prints them.

use frond_formats::rig_toml::CalibrationText;
use frond_motion::sample::HandSample;
use frond_motion::{Calibration, CalibrationError, CalibrationParams};

const ALICE: &str = r#"
id = "alice"
neutral_wrist_deg = [2.5, -5, 0]
neutral_thumb_deg = [5, 3, 0.1]
thumb_range_deg = [55, 65, 70]
wrist_range_deg = [[-60, 70], [-20, 30], [-80, 80]]
"#;

#[test]
fn parses_and_round_trips() {
    let c = Calibration::from_toml_str(ALICE).unwrap();
    assert_eq!(c.id, "alice");
    assert_eq!(c.neutral_wrist_deg, [2.5, -5.0, 0.0]);
    assert_eq!(c.neutral_thumb_deg, [5.0, 3.0, 0.1]);
    assert_eq!(c.wrist_range_deg.unwrap()[1], [-20.0, 30.0]);
    let text = c.to_toml_string();
    assert!(text.contains("0.1"), "{text}");
    assert_eq!(Calibration::from_toml_str(&text).unwrap(), c);
}

#[test]
fn an_id_is_printable_and_bounded() {
    let with_id = |id: &str| ALICE.replace("id = \"alice\"", &format!("id = {}", toml::Value::from(id)));
    let e = Calibration::from_toml_str(&with_id("bob\nPROBLEM      none")).unwrap_err().to_string();
    assert!(e.contains("id: contains the control character '\\n'; a name must be printable"), "{e}");
    let e = Calibration::from_toml_str(&with_id("a\u{1b}[2Kb")).unwrap_err().to_string();
    assert!(e.contains("id: contains the control character '\\u{1b}'"), "{e}");
    let e = Calibration::from_toml_str(&with_id(&"x".repeat(129))).unwrap_err().to_string();
    assert!(e.contains("id: is 129 bytes; the limit is 128"), "{e}");
    assert!(Calibration::from_toml_str(&with_id(&"x".repeat(128))).is_ok());
    assert!(Calibration::from_toml_str(&with_id("  ")).is_err(), "blank");
    assert_eq!(Calibration::from_toml_str(&with_id("pétale 2")).unwrap().id, "pétale 2");
}

#[test]
fn wrist_range_is_optional() {
    let c = Calibration::from_toml_str(
        "id = \"x\"\nneutral_wrist_deg = [0,0,0]\nneutral_thumb_deg = [0,0,0]\nthumb_range_deg = [1,2,3]\n",
    )
    .unwrap();
    assert_eq!(c.wrist_range_deg, None);
    assert!(!c.to_toml_string().contains("wrist_range_deg"));
    assert_eq!(Calibration::from_toml_str(&c.to_toml_string()).unwrap(), c);
}

#[test]
fn every_problem_is_listed_with_its_path() {
    let text = r#"
id = " "
neutral_wrist_deg = [0, nan, 0]
neutral_thumb_deg = [inf, 0, 0]
thumb_range_deg = [0, -5, 60]
wrist_range_deg = [[10, -10], [0, 0], [-1, 1]]
"#;
    let Err(CalibrationError::Invalid(p)) = Calibration::from_toml_str(text) else {
        panic!("expected validation errors");
    };
    assert_eq!(
        p.paths(),
        [
            "id",
            "neutral_wrist_deg[1]",
            "neutral_thumb_deg[0]",
            "thumb_range_deg[0]",
            "thumb_range_deg[1]",
            "wrist_range_deg[0]",
            "wrist_range_deg[1]",
        ]
    );
    let msg = p.to_string();
    assert!(
        msg.contains("thumb_range_deg[1]: a thumb range (degrees) must be between 1 and 360, found -5"),
        "{msg}"
    );
    assert!(msg.contains("wrist_range_deg[0]: pitch min 10 must be below max -10"), "{msg}");
}

/// Issue 14, point 11: well-formed but absurd values are refused with the limits every hand
/// source applies (`crate::plausible`), at the boundary and just past it.
#[test]
fn implausible_neutrals_and_thumb_ranges_are_refused() {
    let with = |neutral: f32, range: f32| {
        format!(
            "id = \"x\"\nneutral_wrist_deg = [{neutral:?}, 0, 0]\nneutral_thumb_deg = [0, {neutral:?}, 0]\n\
             thumb_range_deg = [{range:?}, 60, 60]\n"
        )
    };
    assert!(Calibration::from_toml_str(&with(-360.0, 1.0)).is_ok());
    assert!(Calibration::from_toml_str(&with(360.0, 360.0)).is_ok());
    for (neutral, range) in [(1e30, 1e-45), (360.5, 0.99), (-361.0, 361.0)] {
        let Err(CalibrationError::Invalid(p)) = Calibration::from_toml_str(&with(neutral, range)) else {
            panic!("{neutral} / {range} accepted");
        };
        assert_eq!(p.paths(), ["neutral_wrist_deg[0]", "neutral_thumb_deg[1]", "thumb_range_deg[0]"]);
    }
}

#[test]
fn params_carry_the_wrist_reach_from_the_neutral() {
    // Neutral pitch 2.5 in [-60, 70]: 62.5 below, 67.5 above; yaw -5 in [-20, 30]: 15 / 35.
    let c = Calibration::from_toml_str(ALICE).unwrap();
    assert_eq!(c.params().wrist_reach_deg, Some([[62.5, 67.5], [15.0, 35.0]]));
    let none = Calibration { wrist_range_deg: None, ..c };
    assert_eq!(none.params().wrist_reach_deg, None);
}

#[test]
fn wrist_ranges_must_surround_the_neutral_and_stay_within_180() {
    let text = r#"
id = "x"
neutral_wrist_deg = [2.5, -5, 0]
neutral_thumb_deg = [0, 0, 0]
thumb_range_deg = [60, 60, 60]
wrist_range_deg = [[10, 70], [-5.5, 30], [5, 200]]
"#;
    let Err(CalibrationError::Invalid(p)) = Calibration::from_toml_str(text) else {
        panic!("expected validation errors");
    };
    // Pitch: the neutral 2.5 is below the range; yaw: only 0.5 degree below the neutral;
    // roll: 200 is out of bounds (its neutral is not checked, roll is only recorded).
    assert_eq!(p.paths(), ["wrist_range_deg[0]", "wrist_range_deg[1]", "wrist_range_deg[2][1]"]);
    let msg = p.to_string();
    assert!(
        msg.contains(
            "wrist_range_deg[0]: the comfortable pitch range [10, 70] must reach at least 1 degree \
             below and above the neutral 2.5 (neutral_wrist_deg[0])"
        ),
        "{msg}"
    );
    assert!(msg.contains("wrist_range_deg[2][1]: must be between -180 and 180 degrees, found 200"), "{msg}");
    // Roll around a neutral outside its range is accepted; 1 degree of reach is enough.
    let ok = text.replace("[10, 70], [-5.5, 30], [5, 200]", "[1.5, 70], [-6, 30], [5, 80]");
    assert!(Calibration::from_toml_str(&ok).is_ok());
}

#[test]
fn toml_errors_are_reported() {
    let e = Calibration::from_toml_str("id = \"x\"\nneutral_wrist_deg = [0,0]\n").unwrap_err();
    assert!(matches!(e, CalibrationError::Toml(_)), "{e}");
    let e = Calibration::from_toml_str(&format!("{ALICE}\nextra = 1\n")).unwrap_err();
    assert!(e.to_string().contains("extra"), "{e}");
}

#[test]
fn apply_subtracts_neutral() {
    let c = Calibration::from_toml_str(ALICE).unwrap().params();
    let raw = HandSample { t: 3.0, wrist_deg: [12.5, -15.0, 40.0], thumb_deg: [35.0, 3.0, -9.9] };
    let w = c.apply(&raw);
    assert_eq!(w.t, 3.0);
    assert_eq!(w.wrist_deg, [10.0, -10.0, 40.0]);
    assert_eq!(w.thumb_deg, [30.0, 0.0, -9.9f32 - 0.1f32]);
    // Saturates instead of overflowing.
    let mut big = CalibrationParams::neutral([1.0; 3]);
    big.neutral_wrist_deg[0] = -f32::MAX;
    let w = big.apply(&HandSample { t: 0.0, wrist_deg: [f32::MAX, 0.0, 0.0], thumb_deg: [0.0; 3] });
    assert_eq!(w.wrist_deg[0], f32::MAX);
}
