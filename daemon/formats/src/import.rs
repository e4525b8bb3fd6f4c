//! Importing a JSON Lines file as a take's global-layer frames (`frond take import`, seed 000,
//! section 6.3): hand samples mapped through the live code path, or poses taken as they are.

use frond_motion::mapping::Mapper;
use frond_motion::sample::HandSample;
use frond_motion::take::TakeFrame;
use thiserror::Error;

use crate::jsonl::{JsonlError, parse_hand_line, parse_pose_line};

/// Why an import was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ImportError {
    /// A JSONL line could not be read.
    #[error("line {line}: {error}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        error: JsonlError,
    },
    /// A line's time is earlier than the previous line's.
    #[error("line {line}: time {t} goes backwards (previous line has {prev})")]
    Backwards {
        /// 1-based line number.
        line: usize,
        /// Its time.
        t: f64,
        /// The previous time.
        prev: f64,
    },
    /// A JSONL line is neither a hand sample nor a pose.
    #[error("line {line}: neither a hand sample (`wrist`, `thumb`) nor a pose (`joints`)")]
    UnknownLine {
        /// 1-based line number.
        line: usize,
    },
    /// Nothing to import.
    #[error("no samples or poses in the input")]
    Empty,
}

/// What a JSONL file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImportKind {
    /// Decide from the first line: `wrist` means hand samples, `joints` poses.
    Auto,
    /// Hand samples `{"t","wrist","thumb"}`, mapped with a rig (seed 000, Eq. 2-4).
    Hand,
    /// Poses `{"t","joints"}` as written by `frond take export --jsonl`.
    Pose,
}

/// Imports a JSONL file as global-layer frames. Hand samples go through `mapper` (calibrate,
/// filter, map: the live code path) and are kept as the frames' hand samples; poses are taken
/// as they are once every joint angle is within the limit of [`frond_motion::PoseFrame::check_plausible`]
/// (±[`frond_motion::plausible::MAX_POSE_ANGLE_DEG`]). Blank lines are skipped; times must not go
/// backwards.
pub fn import_jsonl(
    text: &str,
    kind: ImportKind,
    mapper: &mut Mapper,
) -> Result<Vec<TakeFrame>, ImportError> {
    let mut out = Vec::new();
    let mut kind = kind;
    let mut prev_t = f64::NEG_INFINITY;
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        if kind == ImportKind::Auto {
            kind = if line.contains("\"wrist\"") {
                ImportKind::Hand
            } else if line.contains("\"joints\"") {
                ImportKind::Pose
            } else {
                return Err(ImportError::UnknownLine { line: n });
            };
        }
        let (pose, hand) = match kind {
            ImportKind::Hand => {
                let raw = parse_hand_line(line).map_err(|error| ImportError::Line { line: n, error })?;
                let (hand, pose) = mapper.process(&raw);
                (pose, hand)
            }
            _ => {
                let pose = parse_pose_line(line).map_err(|error| ImportError::Line { line: n, error })?;
                pose.check_plausible()
                    .map_err(|e| ImportError::Line { line: n, error: JsonlError::Implausible(e) })?;
                (pose, HandSample { t: pose.t, ..Default::default() })
            }
        };
        if pose.t < prev_t {
            return Err(ImportError::Backwards { line: n, t: pose.t, prev: prev_t });
        }
        prev_t = pose.t;
        out.push(TakeFrame {
            seq: out.len() as u64,
            device_time_us: (pose.t * 1e6).round().max(0.0) as u64,
            pose,
            hand,
            ..Default::default()
        });
    }
    if out.is_empty() {
        return Err(ImportError::Empty);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_motion::FilterSpec;
    use frond_motion::calibration::CalibrationParams;
    use frond_motion::mapping::MappingParams;

    fn mapper() -> Mapper {
        Mapper::new(
            MappingParams::default(),
            CalibrationParams::neutral([60.0, 70.0, 60.0]),
            FilterSpec::None,
        )
    }

    #[test]
    fn import_hand_and_pose_lines() {
        let hand = "{\"t\":0,\"wrist\":[20,-10,30],\"thumb\":[30,35,15]}\n\n{\"t\":0.1,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n";
        let f = import_jsonl(hand, ImportKind::Auto, &mut mapper()).unwrap();
        assert_eq!(f.len(), 2);
        // Eq. 2-4 by hand (see mapping tests): tau 2, unit scales.
        assert_eq!(
            f[0].pose.joints_deg,
            [[20.0, -10.0, 0.0], [10.0, -5.0, 0.0], [10.0, -5.0, 30.0], [5.0, -2.5, 30.0]]
        );
        assert_eq!(f[0].hand.wrist_deg, [20.0, -10.0, 30.0]);
        assert_eq!(f[1].device_time_us, 100_000);
        let pose = "{\"t\":1.5,\"joints\":[[1,2,3],[4,5,6],[7,8,9],[10,11,12]]}\n";
        let f = import_jsonl(pose, ImportKind::Auto, &mut mapper()).unwrap();
        assert_eq!(f[0].pose.joints_deg[3], [10.0, 11.0, 12.0]);
    }

    #[test]
    fn import_errors_name_the_line() {
        let m = &mut mapper();
        let e = import_jsonl(
            "{\"t\":0,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n{\"t\":1,\"wrist\":[0,0],\"thumb\":[0,0,0]}",
            ImportKind::Auto,
            m,
        );
        assert_eq!(e.unwrap_err().to_string(), "line 2: field `wrist`: expected 3 elements, found 2");
        let e = import_jsonl(
            "{\"t\":1,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n{\"t\":0.5,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}",
            ImportKind::Hand,
            m,
        );
        assert_eq!(e.unwrap_err().to_string(), "line 2: time 0.5 goes backwards (previous line has 1)");
        assert_eq!(
            import_jsonl("{\"x\":1}", ImportKind::Auto, m).unwrap_err().to_string(),
            "line 1: neither a hand sample (`wrist`, `thumb`) nor a pose (`joints`)"
        );
        assert_eq!(import_jsonl("\n\n", ImportKind::Auto, m).unwrap_err(), ImportError::Empty);
        // Pose angles are bounded: ±360 passes (so does a pose of thousands of degrees), 1e30 and
        // 3e38 are refused.
        let ok = "{\"t\":0,\"joints\":[[360,-360,0],[0,0,0],[0,0,0],[0,0,0]]}\n";
        assert_eq!(
            import_jsonl(ok, ImportKind::Auto, m).unwrap()[0].pose.joints_deg[0],
            [360.0, -360.0, 0.0]
        );
        let e = import_jsonl(
            &format!("{ok}\n{{\"t\":0.1,\"joints\":[[0,0,0],[1e30,0,0],[0,0,0],[0,0,0]]}}"),
            ImportKind::Auto,
            m,
        );
        assert_eq!(
            e.unwrap_err().to_string(),
            "line 3: `joints[1][0]`: 1000000000000000000000000000000 degrees is not a joint angle (finite, within ±1000000)"
        );
        let e =
            import_jsonl("{\"t\":0,\"joints\":[[0,0,0],[0,0,0],[0,0,0],[0,0,-3e38]]}", ImportKind::Pose, m);
        assert_eq!(
            e.unwrap_err(),
            ImportError::Line {
                line: 1,
                error: JsonlError::Implausible(frond_motion::plausible::Implausible::JointAngle {
                    field: "joints[3][2]",
                    value: -3e38
                })
            }
        );
        assert!(
            import_jsonl("nope", ImportKind::Pose, m)
                .unwrap_err()
                .to_string()
                .starts_with("line 1: not JSON")
        );
    }
}
