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
