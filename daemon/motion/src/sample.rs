//! The two values that flow through frond: what the hand did, and what the plant does.

use serde::{Deserialize, Serialize};

/// Number of joints of the plant skeleton (seed 000, section 4: wrist + three thumb joints).
pub const JOINTS: usize = 4;

/// One hand measurement, in degrees. Raw from a device, or calibrated (`W`, `G` of seed 000).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct HandSample {
    /// Time in seconds (device clock for live samples, file time for recordings).
    pub t: f64,
    /// Wrist `[pitch, yaw, roll]`, degrees.
    pub wrist_deg: [f32; 3],
    /// Thumb joint bends `[g1, g2, g3]`, degrees (g1 nearest the palm).
    pub thumb_deg: [f32; 3],
}

/// One skeleton pose: per joint `[pitch, yaw, roll]` in degrees, joint 0 = root, 3 = top.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseFrame {
    /// Time in seconds.
    pub t: f64,
    /// Joint rotations relative to the parent joint, degrees.
    pub joints_deg: [[f32; 3]; JOINTS],
}

impl PoseFrame {
    /// The 12 joint angles as one vector `F` (seed 000, Eq. 5 uses its Euclidean distance).
    pub fn flat(&self) -> [f32; 3 * JOINTS] {
        let mut out = [0.0; 3 * JOINTS];
        for (i, j) in self.joints_deg.iter().enumerate() {
            out[3 * i..3 * i + 3].copy_from_slice(j);
        }
        out
    }
}
