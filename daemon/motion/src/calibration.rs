//! Per-user calibration (seed 000, section 5.4): the neutral wrist and thumb angles, the user's
//! comfortable thumb bending ranges `G_R1..G_R3`, and optionally the comfortable wrist extremes.
//!
//! `W = wrist - neutral_wrist`, `G_i = thumb_i - neutral_thumb_i` (degrees). File form (TOML):
//!
//! ```toml
//! id = "alice"
//! neutral_wrist_deg = [2.0, -5.0, 0.0]   # pitch, yaw, roll at rest
//! neutral_thumb_deg = [5.0, 3.0, 0.0]    # g1, g2, g3 at rest
//! thumb_range_deg = [55.0, 65.0, 70.0]   # G_R1..G_R3, > 0
//! wrist_range_deg = [[-60.0, 70.0], [-20.0, 30.0], [-80.0, 80.0]]  # optional, min/max per axis
//! ```
//!
//! Section 5.4 sets the scales "to map the user's comfortable ranges of bending wrist and thumb
//! joints with his/her desired bending ranges of plant's joints". The thumb is mapped by Eq. 3's
//! `G_i / G_R_i`. The wrist is mapped when the rig declares `bend_range_deg`: the pitch and yaw
//! extremes of `wrist_range_deg`, taken from the neutral ([`CalibrationParams::wrist_reach_deg`]),
//! then drive the root to exactly the rig's bend range (see `crate::mapping::root_scale`), so
//! two performers with different wrists reach the same plant extremes. Roll's range is recorded
//! but not used (twist keeps `s_roll(i) W_roll`, Eq. 4).

use serde::{Deserialize, Serialize};
use thiserror::Error;

pub use crate::mapping::CalibrationParams;
use crate::problems::Problems;
use crate::rig::Rig;

/// A validated calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// Who or what this calibration is for (`none` for the neutral default).
    pub id: String,
    /// Wrist `[pitch, yaw, roll]` at rest, degrees.
    pub neutral_wrist_deg: [f32; 3],
    /// Thumb `[g1, g2, g3]` at rest, degrees.
    pub neutral_thumb_deg: [f32; 3],
    /// Comfortable thumb bending ranges `G_R1..G_R3` (seed 000, Eq. 3), degrees, within
    /// [`crate::plausible::MIN_THUMB_RANGE_DEG`]..=[`crate::plausible::MAX_THUMB_RANGE_DEG`].
    pub thumb_range_deg: [f32; 3],
    /// Comfortable wrist extremes `[min, max]` per axis (pitch, yaw, roll), degrees, relative to
    /// the device zero, as `frond calibrate` measures them. Within +-180; the pitch and yaw
    /// ranges must reach at least [`MIN_WRIST_REACH_DEG`] below and above the neutral. Mapped
    /// onto a rig's `bend_range_deg` (pitch, yaw); roll is informational.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wrist_range_deg: Option<[[f32; 2]; 3]>,
}

/// Why a calibration file was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CalibrationError {
    /// Not TOML, or a field of the wrong type, missing or unknown (the toml message, with line).
    #[error("calibration: {0}")]
    Toml(String),
    /// Parsed, but some values are invalid; every problem is listed with its path.
    #[error("calibration: {0}")]
    Invalid(Problems),
}

const AXES: [&str; 3] = ["pitch", "yaw", "roll"];

/// Smallest comfortable wrist reach from the neutral, degrees, on either side of the pitch and
/// yaw axes: the mapping divides the rig's bend range by it.
pub const MIN_WRIST_REACH_DEG: f32 = 1.0;
/// Longest calibration id, bytes. The id is printed in `frond status`, the log and the console,
/// so it is also printable: no control characters (see [`Calibration::validate`]).
pub const MAX_CALIBRATION_ID_BYTES: usize = 128;
/// Largest magnitude of a wrist extreme, degrees.
pub const MAX_WRIST_DEG: f32 = 180.0;

impl Calibration {
    /// The calibration used when none is given: id `none`, zero neutral, the rig's thumb ranges.
    pub fn neutral_for(rig: &Rig) -> Calibration {
        Calibration {
            id: "none".to_string(),
            neutral_wrist_deg: [0.0; 3],
            neutral_thumb_deg: [0.0; 3],
            thumb_range_deg: rig.thumb_range_deg,
            wrist_range_deg: None,
        }
    }

    /// Parses and validates a calibration file.
    pub fn from_toml_str(text: &str) -> Result<Calibration, CalibrationError> {
        let c: Calibration =
            toml::from_str(text).map_err(|e| CalibrationError::Toml(e.to_string().trim_end().to_string()))?;
        c.validate().map_err(CalibrationError::Invalid)?;
        Ok(c)
    }

    /// Writes the calibration as TOML; [`Calibration::from_toml_str`] reads it back identically.
    pub fn to_toml_string(&self) -> String {
        // Serializing plain strings and f32 arrays cannot fail.
        toml::to_string(self).unwrap_or_default()
    }

    /// Checks every value, returning all problems with their paths.
    pub fn validate(&self) -> Result<(), Problems> {
        let mut p = Problems::default();
        // Not blank, bounded and printable: a line break or an escape sequence in an id would
        // draw lines of its own in status tables and logs.
        p.name("id", &self.id, MAX_CALIBRATION_ID_BYTES);
        // The limits of `crate::plausible`, shared with rigs and every hand source.
        for (k, v) in self.neutral_wrist_deg.iter().enumerate() {
            p.hand_angle(format!("neutral_wrist_deg[{k}]"), *v);
        }
        for (k, v) in self.neutral_thumb_deg.iter().enumerate() {
            p.hand_angle(format!("neutral_thumb_deg[{k}]"), *v);
        }
        for (k, v) in self.thumb_range_deg.iter().enumerate() {
            p.thumb_range(format!("thumb_range_deg[{k}]"), *v);
        }
        if let Some(r) = &self.wrist_range_deg {
            for (k, [lo, hi]) in r.iter().enumerate() {
                let bounded = |p: &mut Problems, end: usize, v: f32| {
                    let path = format!("wrist_range_deg[{k}][{end}]");
                    if !p.finite(path.clone(), v) {
                        return false;
                    }
                    if v.abs() > MAX_WRIST_DEG {
                        p.push(
                            path,
                            format!(
                                "must be between -{MAX_WRIST_DEG} and {MAX_WRIST_DEG} degrees, found {v}"
                            ),
                        );
                        return false;
                    }
                    true
                };
                let a = bounded(&mut p, 0, *lo);
                let b = bounded(&mut p, 1, *hi);
                if !(a && b) {
                    continue;
                }
                if lo >= hi {
                    p.push(
                        format!("wrist_range_deg[{k}]"),
                        format!("{} min {lo} must be below max {hi}", AXES[k]),
                    );
                    continue;
                }
                let n = self.neutral_wrist_deg[k];
                if k < 2 && n.is_finite() && !(n - lo >= MIN_WRIST_REACH_DEG && hi - n >= MIN_WRIST_REACH_DEG)
                {
                    p.push(
                        format!("wrist_range_deg[{k}]"),
                        format!(
                            "the comfortable {} range [{lo}, {hi}] must reach at least {MIN_WRIST_REACH_DEG} \
                             degree below and above the neutral {n} (neutral_wrist_deg[{k}])",
                            AXES[k]
                        ),
                    );
                }
            }
        }
        if p.is_empty() { Ok(()) } else { Err(p) }
    }

    /// The `Copy` form used by the realtime loop.
    pub fn params(&self) -> CalibrationParams {
        let n = self.neutral_wrist_deg;
        CalibrationParams {
            neutral_wrist_deg: n,
            neutral_thumb_deg: self.neutral_thumb_deg,
            thumb_range_deg: self.thumb_range_deg,
            wrist_reach_deg: self
                .wrist_range_deg
                .map(|r| std::array::from_fn(|k| [n[k] - r[k][0], r[k][1] - n[k]])),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::HandSample;

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
        assert!(
            msg.contains("wrist_range_deg[2][1]: must be between -180 and 180 degrees, found 200"),
            "{msg}"
        );
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
}
