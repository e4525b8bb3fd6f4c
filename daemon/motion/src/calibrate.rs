//! The steps of a guided calibration (seed 000, section 5.4), shared by `frond calibrate` and
//! the console's guided calibration: what each step asks of the user, and how the samples
//! recorded during them become a [`Calibration`]. Pure: the callers poll the daemon's raw
//! samples.
//!
//! - neutral: the mean of every sample is the neutral wrist and thumb;
//! - wrist pitch, yaw, roll extremes (one step each): `[min, max]` of that axis, stored as
//!   `wrist_range_deg`. A rig with `bend_range_deg` maps the pitch and yaw extremes (their reach
//!   from the neutral) onto its root bend range (section 5.4: "map the user's comfortable ranges
//!   ... with his/her desired bending ranges of plant's joints"); roll is recorded only. The
//!   ranges are stored only when every axis moved at least 5 degrees within +-180 and pitch and
//!   yaw reach at least 5 degrees either side of the neutral;
//! - thumb: `G_R_i = max(thumb_i) - neutral_thumb_i` (the comfortable bending range of Eq. 3);
//!   a range under 5 degrees is refused, since it would blow up `G_i / G_R_i`.

use crate::calibration::MAX_WRIST_DEG;
use crate::{Calibration, Problems};

/// Smallest acceptable comfortable range, degrees.
pub const MIN_RANGE_DEG: f32 = 5.0;

/// One raw (uncalibrated) sample from the daemon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Raw {
    /// Sample time, seconds.
    pub t: f64,
    /// Wrist pitch, yaw, roll, degrees.
    pub wrist_deg: [f32; 3],
    /// Thumb joint angles, degrees.
    pub thumb_deg: [f32; 3],
}

/// What each step asks the user to do.
pub const STEPS: [(&str, &str); 5] = [
    ("neutral", "Rest your hand in its relaxed neutral pose and hold it still."),
    ("wrist pitch", "Bend your wrist up and down to its comfortable extremes, a few times."),
    ("wrist yaw", "Swing your wrist left and right to its comfortable extremes, a few times."),
    ("wrist roll", "Roll your forearm both ways as far as is comfortable, a few times."),
    ("thumb", "Bend your thumb as far as is comfortable (curl all three joints), then relax, a few times."),
];

/// The result of [`compute`].
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    /// The calibration.
    pub calibration: Calibration,
    /// What was doubtful but not fatal, in words.
    pub warnings: Vec<String>,
}

/// Why the recorded steps give no calibration ([`compute`]).
#[derive(Debug, Clone, thiserror::Error)]
pub enum CalibrateError {
    /// A step recorded no sample.
    #[error("every calibration step needs at least one sample")]
    NoSamples,
    /// Thumb joints whose comfortable range is too small: one sentence per joint, naming it and
    /// its range.
    #[error(
        "{}; bend the thumb further during the thumb step, and check that the device reports \
         the thumb (`frond tap`)",
        .0.join("; ")
    )]
    ThumbRange(Vec<String>),
    /// The measured calibration fails [`Calibration::validate`] (its problems).
    #[error("the measured calibration is invalid: {0:?}")]
    Invalid(Problems),
}

/// Turns the recorded steps into a calibration, or says why it cannot (in words).
pub fn compute(
    user: &str,
    neutral: &[Raw],
    wrist_steps: [&[Raw]; 3],
    thumb: &[Raw],
) -> Result<Measured, CalibrateError> {
    if neutral.is_empty() || thumb.is_empty() || wrist_steps.iter().any(|s| s.is_empty()) {
        return Err(CalibrateError::NoSamples);
    }
    let mut warnings = Vec::new();
    let mean = |get: &dyn Fn(&Raw) -> f32| -> f32 {
        (neutral.iter().map(|r| get(r) as f64).sum::<f64>() / neutral.len() as f64) as f32
    };
    let neutral_wrist_deg: [f32; 3] = std::array::from_fn(|k| mean(&|r| r.wrist_deg[k]));
    let neutral_thumb_deg: [f32; 3] = std::array::from_fn(|k| mean(&|r| r.thumb_deg[k]));
    // Movement during the neutral step makes the mean meaningless; say so.
    let spread = |get: &dyn Fn(&Raw) -> f32| {
        let (lo, hi) =
            neutral.iter().map(get).fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
        hi - lo
    };
    const AXES: [&str; 3] = ["pitch", "yaw", "roll"];
    for (k, axis) in AXES.iter().enumerate() {
        let w = spread(&|r| r.wrist_deg[k]);
        let g = spread(&|r| r.thumb_deg[k]);
        if w > 10.0 {
            warnings.push(format!("the wrist {axis} moved {w:.1} degrees during the neutral step"));
        }
        if g > 10.0 {
            warnings.push(format!("thumb joint g{} moved {g:.1} degrees during the neutral step", k + 1));
        }
    }

    let mut wrist_range = [[0.0f32; 2]; 3];
    let mut wrist_ok = true;
    for (k, step) in wrist_steps.iter().enumerate() {
        let (lo, hi) = step
            .iter()
            .map(|r| r.wrist_deg[k])
            .fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
        wrist_range[k] = [lo, hi];
        if lo.abs() > MAX_WRIST_DEG || hi.abs() > MAX_WRIST_DEG {
            wrist_ok = false;
            warnings.push(format!(
                "the wrist {} went from {lo:.1} to {hi:.1} degrees, past +-{MAX_WRIST_DEG}; wrist ranges are \
                 not stored (check the device profile's units)",
                AXES[k]
            ));
            continue;
        }
        if hi - lo < MIN_RANGE_DEG {
            wrist_ok = false;
            warnings.push(format!(
                "the wrist {} only moved {:.1} degrees during its step; wrist ranges are not stored",
                AXES[k],
                hi - lo
            ));
            continue;
        }
        // Pitch and yaw are mapped onto a rig's bend range from the neutral, on each side.
        let n = neutral_wrist_deg[k];
        for (side, reach) in [("below", n - lo), ("above", hi - n)] {
            if k < 2 && (reach.is_nan() || reach < MIN_RANGE_DEG) {
                wrist_ok = false;
                warnings.push(format!(
                    "the wrist {} reached only {reach:.1} degrees {side} its neutral {n:.1} (range {lo:.1} to \
                     {hi:.1}); wrist ranges are not stored, so rigs with bend_range_deg use their s_pitch/s_yaw \
                     for this user",
                    AXES[k]
                ));
            }
        }
    }

    let mut thumb_range_deg = [0.0f32; 3];
    let mut problems = Vec::new();
    for (k, range) in thumb_range_deg.iter_mut().enumerate() {
        let max = thumb.iter().map(|r| r.thumb_deg[k]).fold(f32::MIN, f32::max);
        *range = max - neutral_thumb_deg[k];
        if range.is_nan() || *range < MIN_RANGE_DEG {
            problems.push(format!(
                "thumb joint g{}: comfortable range G_R{} = {:.1} degrees (max {max:.1} - neutral {:.1}) \
                 is below {MIN_RANGE_DEG} degrees",
                k + 1,
                k + 1,
                *range,
                neutral_thumb_deg[k]
            ));
        }
    }
    if !problems.is_empty() {
        return Err(CalibrateError::ThumbRange(problems));
    }
    let calibration = Calibration {
        id: user.to_string(),
        neutral_wrist_deg,
        neutral_thumb_deg,
        thumb_range_deg,
        wrist_range_deg: wrist_ok.then_some(wrist_range),
    };
    calibration.validate().map_err(CalibrateError::Invalid)?;
    Ok(Measured { calibration, warnings })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(wrist: [f32; 3], thumb: [f32; 3]) -> Raw {
        Raw { t: 0.0, wrist_deg: wrist, thumb_deg: thumb }
    }

    fn steps() -> (Vec<Raw>, [Vec<Raw>; 3], Vec<Raw>) {
        let neutral = vec![raw([1.0, -2.0, 3.0], [4.0, 6.0, 0.0]), raw([3.0, -4.0, 5.0], [6.0, 8.0, 2.0])];
        let pitch = vec![raw([-50.0, 0.0, 0.0], [0.0; 3]), raw([60.0, 9.0, 0.0], [0.0; 3])];
        let yaw = vec![raw([0.0, -20.0, 0.0], [0.0; 3]), raw([0.0, 30.0, 0.0], [0.0; 3])];
        let roll = vec![raw([0.0, 0.0, -70.0], [0.0; 3]), raw([0.0, 0.0, 80.0], [0.0; 3])];
        let thumb = vec![raw([0.0; 3], [40.0, 10.0, 30.0]), raw([0.0; 3], [20.0, 77.0, 64.0])];
        (neutral, [pitch, yaw, roll], thumb)
    }

    #[test]
    fn neutral_is_the_mean_and_ranges_are_max_minus_neutral() {
        let (n, [p, y, r], t) = steps();
        let m = compute("alice", &n, [&p, &y, &r], &t).unwrap();
        let c = m.calibration;
        assert_eq!(c.id, "alice");
        assert_eq!(c.neutral_wrist_deg, [2.0, -3.0, 4.0]);
        assert_eq!(c.neutral_thumb_deg, [5.0, 7.0, 1.0]);
        // max g = 40, 77, 64 -> minus neutral 5, 7, 1.
        assert_eq!(c.thumb_range_deg, [35.0, 70.0, 63.0]);
        assert_eq!(c.wrist_range_deg, Some([[-50.0, 60.0], [-20.0, 30.0], [-70.0, 80.0]]));
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    }

    #[test]
    fn a_tiny_thumb_range_is_refused_naming_the_joint() {
        let (n, [p, y, r], mut t) = steps();
        for s in &mut t {
            s.thumb_deg[1] = 9.0; // neutral g2 is 7: range 2 degrees
        }
        let err = compute("bob", &n, [&p, &y, &r], &t).unwrap_err().to_string();
        assert!(err.contains("thumb joint g2"), "{err}");
        assert!(err.contains("G_R2 = 2.0 degrees"), "{err}");
        assert!(!err.contains("g1"), "{err}");
    }

    #[test]
    fn a_still_wrist_step_drops_wrist_ranges_with_a_warning() {
        let (n, [p, _, r], t) = steps();
        let still = vec![raw([0.0, 1.0, 0.0], [0.0; 3])];
        let m = compute("carol", &n, [&p, &still, &r], &t).unwrap();
        assert_eq!(m.calibration.wrist_range_deg, None);
        assert!(m.warnings.iter().any(|w| w.contains("wrist yaw")), "{:?}", m.warnings);
    }

    #[test]
    fn a_wrist_step_on_one_side_of_the_neutral_drops_wrist_ranges() {
        // Neutral pitch 2; the pitch step only bends up (0..60): 2 degrees below the neutral is
        // no comfortable range to map onto a rig's bend range.
        let (n, [_, y, r], t) = steps();
        let up_only = vec![raw([0.0, 0.0, 0.0], [0.0; 3]), raw([60.0, 0.0, 0.0], [0.0; 3])];
        let m = compute("fay", &n, [&up_only, &y, &r], &t).unwrap();
        assert_eq!(m.calibration.wrist_range_deg, None);
        assert!(
            m.warnings
                .iter()
                .any(|w| w.contains("wrist pitch reached only 2.0 degrees below its neutral 2.0")),
            "{:?}",
            m.warnings
        );
        // Extremes past +-180 (a wrong unit in the device profile) are not stored either.
        let (n, [p, y, _], t) = steps();
        let wild = vec![raw([0.0, 0.0, -200.0], [0.0; 3]), raw([0.0, 0.0, 80.0], [0.0; 3])];
        let m = compute("hal", &n, [&p, &y, &wild], &t).unwrap();
        assert_eq!(m.calibration.wrist_range_deg, None);
        assert!(
            m.warnings.iter().any(|w| w.contains("wrist roll went from -200.0 to 80.0")),
            "{:?}",
            m.warnings
        );
        // The measured ranges of `steps()` give the reach the mapping uses.
        let (n, [p, y, r], t) = steps();
        let c = compute("gus", &n, [&p, &y, &r], &t).unwrap().calibration;
        assert_eq!(c.params().wrist_reach_deg, Some([[52.0, 58.0], [17.0, 33.0]]));
    }

    #[test]
    fn moving_during_neutral_is_warned() {
        let (mut n, [p, y, r], t) = steps();
        n.push(raw([30.0, -3.0, 4.0], [5.0, 7.0, 1.0]));
        let m = compute("dan", &n, [&p, &y, &r], &t).unwrap();
        assert!(m.warnings.iter().any(|w| w.contains("wrist pitch moved")), "{:?}", m.warnings);
    }
}
