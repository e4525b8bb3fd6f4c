//! Per-user calibration (seed 000, section 5.4): the neutral wrist and thumb angles, and the
//! user's comfortable thumb bending ranges `G_R1..G_R3`.
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

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::problems::Problems;
use crate::rig::Rig;
use crate::sample::HandSample;

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
    /// Comfortable thumb bending ranges `G_R1..G_R3` (seed 000, Eq. 3), degrees, > 0.
    pub thumb_range_deg: [f32; 3],
    /// Comfortable wrist extremes `[min, max]` per axis, degrees, relative to the device zero.
    /// Informational (recorded by `frond calibrate`); not used by the mapping.
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
        if self.id.trim().is_empty() {
            p.push("id", "must not be empty");
        }
        for (k, v) in self.neutral_wrist_deg.iter().enumerate() {
            p.finite(format!("neutral_wrist_deg[{k}]"), *v);
        }
        for (k, v) in self.neutral_thumb_deg.iter().enumerate() {
            p.finite(format!("neutral_thumb_deg[{k}]"), *v);
        }
        for (k, v) in self.thumb_range_deg.iter().enumerate() {
            p.positive(format!("thumb_range_deg[{k}]"), *v);
        }
        if let Some(r) = &self.wrist_range_deg {
            for (k, [lo, hi]) in r.iter().enumerate() {
                let a = p.finite(format!("wrist_range_deg[{k}][0]"), *lo);
                let b = p.finite(format!("wrist_range_deg[{k}][1]"), *hi);
                if a && b && lo >= hi {
                    p.push(
                        format!("wrist_range_deg[{k}]"),
                        format!("{} min {lo} must be below max {hi}", AXES[k]),
                    );
                }
            }
        }
        if p.is_empty() { Ok(()) } else { Err(p) }
    }

    /// The `Copy` form used by the realtime loop.
    pub fn params(&self) -> CalibrationParams {
        CalibrationParams {
            neutral_wrist_deg: self.neutral_wrist_deg,
            neutral_thumb_deg: self.neutral_thumb_deg,
            thumb_range_deg: self.thumb_range_deg,
        }
    }
}

/// What the mapping needs from a calibration. `Copy`, no heap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationParams {
    /// Wrist neutral `[pitch, yaw, roll]`, degrees.
    pub neutral_wrist_deg: [f32; 3],
    /// Thumb neutral `[g1, g2, g3]`, degrees.
    pub neutral_thumb_deg: [f32; 3],
    /// `G_R1..G_R3` (seed 000, Eq. 3), degrees.
    pub thumb_range_deg: [f32; 3],
}

impl CalibrationParams {
    /// Zero neutral with the given thumb ranges.
    pub fn neutral(thumb_range_deg: [f32; 3]) -> Self {
        CalibrationParams { neutral_wrist_deg: [0.0; 3], neutral_thumb_deg: [0.0; 3], thumb_range_deg }
    }

    /// `W = wrist - neutral`, `G_i = thumb_i - neutral_i`; `t` unchanged. Differences of finite
    /// values saturate at `±f32::MAX` instead of overflowing to infinity.
    pub fn apply(&self, raw: &HandSample) -> HandSample {
        let sub = |a: f32, b: f32| ((a as f64 - b as f64) as f32).clamp(-f32::MAX, f32::MAX);
        let mut out = *raw;
        for k in 0..3 {
            out.wrist_deg[k] = sub(raw.wrist_deg[k], self.neutral_wrist_deg[k]);
            out.thumb_deg[k] = sub(raw.thumb_deg[k], self.neutral_thumb_deg[k]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(msg.contains("thumb_range_deg[1]: must be greater than 0, found -5"), "{msg}");
        assert!(msg.contains("wrist_range_deg[0]: pitch min 10 must be below max -10"), "{msg}");
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
