//! One set of plausibility limits for what a hand, a rig and a calibration may say, used by every
//! path that lets such a value in: the live OSC and HID sources, hand files (`--replay`, `frond
//! map`, `frond take import`), pose files (`frond take import`), rig and calibration files
//! (daemon, `frond`, exporters) and device profiles. A value a live source would refuse is
//! refused offline too, with the same limit.
//!
//! The limits are wide enough for any real hand or plant and narrow enough that the mapping
//! (seed 000, Eq. 2-4) cannot overflow: a hand angle within ±[`MAX_HAND_ANGLE_DEG`] minus a
//! neutral within the same bound, divided by a thumb range of at least [`MIN_THUMB_RANGE_DEG`]
//! and scaled by at most [`MAX_JOINT_SCALE`], stays far inside `f32`.

use thiserror::Error;

use crate::problems::Problems;
use crate::sample::{HandSample, JOINTS, PoseFrame};

/// Largest magnitude of a hand angle (wrist pitch, yaw, roll; thumb g1..g3), and of a
/// calibration's neutral angles, degrees. A source reporting more is broken or hostile.
pub const MAX_HAND_ANGLE_DEG: f32 = 360.0;
/// Largest magnitude of a pose joint angle read from a file (`frond take import`), degrees. Not
/// the hand's ±[`MAX_HAND_ANGLE_DEG`]: Eq. 2-3 scale a hand angle by up to
/// [`MAX_JOINT_SCALE`] and by thumb ratios, so a take made live on an extreme (but accepted)
/// rig holds poses of thousands of degrees, and its export must import again. A million degrees
/// is far past any of those, and small enough that interpolation and filters stay exact to
/// 0.1 degree in `f32`; what it refuses (1e30, 3e38) is no rotation anyone meant.
pub const MAX_POSE_ANGLE_DEG: f32 = 1.0e6;
/// Smallest comfortable thumb range `G_R_i` (seed 000, Eq. 3 divides by it), degrees.
pub const MIN_THUMB_RANGE_DEG: f32 = 1.0;
/// Largest comfortable thumb range `G_R_i`, degrees.
pub const MAX_THUMB_RANGE_DEG: f32 = 360.0;
/// Largest magnitude of a joint's bend or twist scale `s_pitch(i)`, `s_yaw(i)`, `s_roll(i)`
/// (seed 000, Eq. 2-4).
pub const MAX_JOINT_SCALE: f32 = 20.0;
/// Largest joint height or element length of a rig, metres.
pub const MAX_RIG_SIZE_M: f32 = 1000.0;
/// Most instances of one secondary element (`count`): each gets its own joints in a bake.
pub const MAX_ELEMENT_COUNT: u32 = 256;

/// Why a hand sample is not plausible. `Copy`, built without allocating, so the realtime loop can
/// use it.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum Implausible {
    /// The time is not a finite number of seconds at or after 0.
    #[error("`t`: {0} is not a finite time at or after 0 s")]
    Time(f64),
    /// An angle is not finite or beyond ±[`MAX_HAND_ANGLE_DEG`].
    #[error("`{field}`: {value} degrees is not a hand angle (finite, within ±{MAX_HAND_ANGLE_DEG})")]
    Angle {
        /// Which angle, as in the hand file format: `wrist[0]` .. `thumb[2]`.
        field: &'static str,
        /// The value found.
        value: f32,
    },
    /// A pose joint angle is not finite or beyond ±[`MAX_POSE_ANGLE_DEG`].
    #[error("`{field}`: {value} degrees is not a joint angle (finite, within ±{MAX_POSE_ANGLE_DEG})")]
    JointAngle {
        /// Which angle, as in the pose file format: `joints[0][0]` .. `joints[3][2]`.
        field: &'static str,
        /// The value found.
        value: f32,
    },
}

const ANGLE_FIELDS: [&str; 6] = ["wrist[0]", "wrist[1]", "wrist[2]", "thumb[0]", "thumb[1]", "thumb[2]"];

/// True when `v` is a plausible hand angle.
pub fn is_hand_angle(v: f32) -> bool {
    v.is_finite() && v.abs() <= MAX_HAND_ANGLE_DEG
}

impl HandSample {
    /// Checks the sample against the hand limits: `t` finite and not negative, every angle
    /// finite and within ±[`MAX_HAND_ANGLE_DEG`]. Names the first value out of bounds.
    pub fn check_plausible(&self) -> Result<(), Implausible> {
        if !(self.t.is_finite() && self.t >= 0.0) {
            return Err(Implausible::Time(self.t));
        }
        let angles = self.wrist_deg.iter().chain(&self.thumb_deg);
        for (field, &value) in ANGLE_FIELDS.iter().zip(angles) {
            if !is_hand_angle(value) {
                return Err(Implausible::Angle { field, value });
            }
        }
        Ok(())
    }
}

const JOINT_FIELDS: [[&str; 3]; JOINTS] = [
    ["joints[0][0]", "joints[0][1]", "joints[0][2]"],
    ["joints[1][0]", "joints[1][1]", "joints[1][2]"],
    ["joints[2][0]", "joints[2][1]", "joints[2][2]"],
    ["joints[3][0]", "joints[3][1]", "joints[3][2]"],
];

impl PoseFrame {
    /// Checks a pose read from outside (a pose file for `frond take import`): every angle finite
    /// and within ±[`MAX_POSE_ANGLE_DEG`]; an angle like 1e30 degrees would flow on into
    /// resampling, filters and exporters. Names the first value out of bounds. The time is not
    /// checked here (the importer checks its order).
    pub fn check_plausible(&self) -> Result<(), Implausible> {
        for (fields, joint) in JOINT_FIELDS.iter().zip(&self.joints_deg) {
            for (&field, &value) in fields.iter().zip(joint) {
                if !(value.is_finite() && value.abs() <= MAX_POSE_ANGLE_DEG) {
                    return Err(Implausible::JointAngle { field, value });
                }
            }
        }
        Ok(())
    }
}

impl Problems {
    /// Checks that `v` lies in `lo..=hi` (and is finite); `what` names the quantity.
    pub(crate) fn within(&mut self, path: impl Into<String>, v: f32, lo: f32, hi: f32, what: &str) -> bool {
        let path = path.into();
        if !self.finite(path.clone(), v) {
            return false;
        }
        if (lo..=hi).contains(&v) {
            true
        } else {
            self.push(path, format!("{what} must be between {lo} and {hi}, found {v}"));
            false
        }
    }

    /// A hand angle or a neutral angle: within ±[`MAX_HAND_ANGLE_DEG`].
    pub(crate) fn hand_angle(&mut self, path: impl Into<String>, v: f32) -> bool {
        self.within(path, v, -MAX_HAND_ANGLE_DEG, MAX_HAND_ANGLE_DEG, "a hand angle (degrees)")
    }

    /// A comfortable thumb range `G_R_i`: within [`MIN_THUMB_RANGE_DEG`]..=[`MAX_THUMB_RANGE_DEG`].
    pub(crate) fn thumb_range(&mut self, path: impl Into<String>, v: f32) -> bool {
        self.within(path, v, MIN_THUMB_RANGE_DEG, MAX_THUMB_RANGE_DEG, "a thumb range (degrees)")
    }

    /// A joint scale `s_pitch`/`s_yaw`/`s_roll`: within ±[`MAX_JOINT_SCALE`].
    pub(crate) fn joint_scale(&mut self, path: impl Into<String>, v: f32) -> bool {
        self.within(path, v, -MAX_JOINT_SCALE, MAX_JOINT_SCALE, "a joint scale")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hand(wrist: [f32; 3], thumb: [f32; 3]) -> HandSample {
        HandSample { t: 1.0, wrist_deg: wrist, thumb_deg: thumb }
    }

    #[test]
    fn the_limits_are_inclusive_and_name_the_field() {
        assert_eq!(hand([360.0, -360.0, 0.0], [0.0, 0.0, -360.0]).check_plausible(), Ok(()));
        assert_eq!(
            hand([0.0, 400.0, 0.0], [0.0; 3]).check_plausible(),
            Err(Implausible::Angle { field: "wrist[1]", value: 400.0 })
        );
        assert_eq!(
            hand([0.0; 3], [0.0, 0.0, 1e30]).check_plausible(),
            Err(Implausible::Angle { field: "thumb[2]", value: 1e30 })
        );
        let e = hand([f32::NAN, 0.0, 0.0], [0.0; 3]).check_plausible().unwrap_err();
        assert!(matches!(e, Implausible::Angle { field: "wrist[0]", value } if value.is_nan()));
        for t in [-1e-9, f64::NAN, f64::INFINITY] {
            let s = HandSample { t, ..HandSample::default() };
            assert!(matches!(s.check_plausible(), Err(Implausible::Time(_))), "{t}");
        }
        assert_eq!(
            Implausible::Angle { field: "wrist[0]", value: 400.0 }.to_string(),
            "`wrist[0]`: 400 degrees is not a hand angle (finite, within ±360)"
        );
    }

    #[test]
    fn pose_angles_are_bounded_like_hand_angles_and_named() {
        let pose = |j: usize, c: usize, v: f32| {
            let mut joints_deg = [[0.0; 3]; JOINTS];
            joints_deg[j][c] = v;
            PoseFrame { t: 2.0, joints_deg }
        };
        assert_eq!(pose(0, 0, 360.0).check_plausible(), Ok(()));
        // A pose past a hand's ±360 (joint scale 20 on a 90 degree wrist) imports again.
        assert_eq!(pose(0, 0, 1800.0).check_plausible(), Ok(()));
        assert_eq!(pose(3, 2, -1.0e6).check_plausible(), Ok(()));
        assert_eq!(
            pose(1, 0, 1e30).check_plausible(),
            Err(Implausible::JointAngle { field: "joints[1][0]", value: 1e30 })
        );
        assert_eq!(
            pose(3, 2, -1.5e6).check_plausible(),
            Err(Implausible::JointAngle { field: "joints[3][2]", value: -1.5e6 })
        );
        assert_eq!(
            pose(2, 1, f32::INFINITY).check_plausible(),
            Err(Implausible::JointAngle { field: "joints[2][1]", value: f32::INFINITY })
        );
        let e = pose(0, 2, f32::NAN).check_plausible().unwrap_err();
        assert!(matches!(e, Implausible::JointAngle { field: "joints[0][2]", value } if value.is_nan()));
        assert_eq!(
            Implausible::JointAngle { field: "joints[1][0]", value: 2e6 }.to_string(),
            "`joints[1][0]`: 2000000 degrees is not a joint angle (finite, within ±1000000)"
        );
    }
}
