//! The plant skeleton in 3D: the rotation convention, forward kinematics, procedural skinning
//! weights and linear blend skinning (seed 000, section 4, Eq. 1 and the Appendix).
//!
//! Convention (the same as `frond_protocol::convention`, which exporters without glam use): the
//! stem grows along +Y; a joint's `[pitch, yaw, roll]` (degrees) rotate about its local +X, +Z and
//! +Y, composed `R = R_yaw * R_pitch * R_roll`, relative to the parent joint; joint 0's parent is
//! the rig's ground frame (y = 0 is the ground). In the bind (rest) pose every angle is zero and
//! joint `i` sits at `(0, height_m(i), 0)`.

use glam::{Mat4, Quat, Vec3};

use crate::rig::Rig;
use crate::sample::JOINTS;

/// A joint's rotation `R_yaw * R_pitch * R_roll` from `[pitch, yaw, roll]` in degrees.
pub fn joint_rotation(angles_deg: [f32; 3]) -> Quat {
    let [pitch, yaw, roll] = angles_deg.map(f32::to_radians);
    Quat::from_rotation_z(yaw) * Quat::from_rotation_x(pitch) * Quat::from_rotation_y(roll)
}

/// Procedural skinning weights of a vertex at height `y_m` (seed 000, Appendix, Algorithm 1,
/// derived cleanly): weights are hat functions of height over the joint heights `h_0 < h_1 < h_2
/// < h_3`:
///
/// - `y <= h_0` (including everything below the ground): joint 0 only;
/// - `h_i <= y < h_(i+1)`: `w_i = 1 - T`, `w_(i+1) = T` with `T = (y - h_i) / (h_(i+1) - h_i)`;
/// - `y >= h_3`: joint 3 only.
///
/// The printed algorithm blends between neighbouring joints by height too, but its formula is
/// garbled (it divides by `J_(i-2)` and can give negative weights); this version keeps the intent
/// and is non-negative, sums to 1 and is continuous in `y` (at `y = h_i` it is joint `i` alone
/// from both sides). A NaN height gets joint 0. Heights that are not strictly increasing (never
/// from a validated rig) fall back to the lower joint of a degenerate interval.
pub fn procedural_weights(heights_m: [f32; JOINTS], y_m: f32) -> [f32; JOINTS] {
    let mut w = [0.0; JOINTS];
    if y_m.is_nan() || y_m <= heights_m[0] {
        w[0] = 1.0;
        return w;
    }
    for i in 0..JOINTS - 1 {
        if y_m < heights_m[i + 1] {
            let span = heights_m[i + 1] - heights_m[i];
            let t = if span > 0.0 { ((y_m - heights_m[i]) / span).clamp(0.0, 1.0) } else { 0.0 };
            w[i] = 1.0 - t;
            w[i + 1] = t;
            return w;
        }
    }
    w[JOINTS - 1] = 1.0;
    w
}

/// The rest geometry of a 4-joint skeleton: the joint heights, root first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Skeleton {
    /// Height of each joint above the ground in the bind pose, metres, strictly increasing.
    pub heights_m: [f32; JOINTS],
}

impl Skeleton {
    /// The skeleton of a rig.
    pub fn from_rig(rig: &Rig) -> Self {
        Skeleton { heights_m: std::array::from_fn(|i| rig.joints[i].height_m) }
    }

    /// A skeleton of length `length_m` with evenly spaced joints from 0 (secondary elements).
    pub fn even(length_m: f32) -> Self {
        Skeleton { heights_m: std::array::from_fn(|i| length_m * i as f32 / JOINTS as f32) }
    }

    /// Procedural weights over this skeleton (see [`procedural_weights`]).
    pub fn weights_at(&self, y_m: f32) -> [f32; JOINTS] {
        procedural_weights(self.heights_m, y_m)
    }

    /// Joint world matrices in the bind pose: translations to `(0, h_i, 0)`.
    pub fn bind_matrices(&self) -> [Mat4; JOINTS] {
        self.heights_m.map(|h| Mat4::from_translation(Vec3::new(0.0, h, 0.0)))
    }

    /// Forward kinematics: each joint's world matrix for a pose (per joint `[pitch, yaw, roll]`
    /// in degrees, relative to the parent). `world_0 = T(0, h_0, 0) R_0`,
    /// `world_i = world_(i-1) T(0, h_i - h_(i-1), 0) R_i`. All zeros give [`Self::bind_matrices`].
    pub fn joint_matrices(&self, joints_deg: &[[f32; 3]; JOINTS]) -> [Mat4; JOINTS] {
        let mut out = [Mat4::IDENTITY; JOINTS];
        let mut parent = Mat4::IDENTITY;
        let mut parent_h = 0.0;
        for i in 0..JOINTS {
            let local = Mat4::from_rotation_translation(
                joint_rotation(joints_deg[i]),
                Vec3::new(0.0, self.heights_m[i] - parent_h, 0.0),
            );
            parent *= local;
            parent_h = self.heights_m[i];
            out[i] = parent;
        }
        out
    }

    /// The `M_i` of seed 000, Eq. 1: `world_i * bind_i^-1`, taking a vertex given in the rest
    /// (skin) space to its posed world position under joint `i` alone.
    pub fn skinning_matrices(&self, joints_deg: &[[f32; 3]; JOINTS]) -> [Mat4; JOINTS] {
        let world = self.joint_matrices(joints_deg);
        std::array::from_fn(|i| world[i] * Mat4::from_translation(Vec3::new(0.0, -self.heights_m[i], 0.0)))
    }
}

/// Linear blend skinning, seed 000, Eq. 1: `v' = (sum_i w_i M_i) v`.
pub fn skin_point(m: &[Mat4; JOINTS], weights: &[f32; JOINTS], v: Vec3) -> Vec3 {
    blend(m, weights).transform_point3(v)
}

/// Skins a normal with the same blended matrix (its linear part), renormalised. Exact for rigid
/// (single-joint) vertices; the usual LBS approximation elsewhere.
pub fn skin_normal(m: &[Mat4; JOINTS], weights: &[f32; JOINTS], n: Vec3) -> Vec3 {
    blend(m, weights).transform_vector3(n).normalize_or_zero()
}

fn blend(m: &[Mat4; JOINTS], weights: &[f32; JOINTS]) -> Mat4 {
    let mut sum = Mat4::ZERO;
    for (mi, &w) in m.iter().zip(weights) {
        sum += *mi * w;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn rotation_agrees_with_the_protocol_convention() {
        for angles in [[0.0, 0.0, 0.0], [90.0, 0.0, 0.0], [23.0, -41.0, 67.0], [-170.0, 35.5, -12.0]] {
            let q = joint_rotation(angles);
            let p = frond_protocol::convention::joint_quat(angles);
            let m = frond_protocol::convention::joint_matrix(angles);
            // Same rotation (q and -q are the same rotation).
            let dot = q.x * p[0] + q.y * p[1] + q.z * p[2] + q.w * p[3];
            assert!((dot.abs() - 1.0).abs() < 1e-5, "{angles:?}: {q:?} vs {p:?}");
            for v in [Vec3::X, Vec3::Y, Vec3::new(0.3, -0.2, 0.9)] {
                let a = q * v;
                let b = Vec3::new(
                    (m[0][0] * v.x as f64 + m[0][1] * v.y as f64 + m[0][2] * v.z as f64) as f32,
                    (m[1][0] * v.x as f64 + m[1][1] * v.y as f64 + m[1][2] * v.z as f64) as f32,
                    (m[2][0] * v.x as f64 + m[2][1] * v.y as f64 + m[2][2] * v.z as f64) as f32,
                );
                assert!(close(a, b), "{angles:?} {v:?}: {a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn procedural_weights_by_hand() {
        let h = [0.0, 1.0, 2.0, 3.0];
        assert_eq!(procedural_weights(h, -0.5), [1.0, 0.0, 0.0, 0.0]); // below ground
        assert_eq!(procedural_weights(h, 0.0), [1.0, 0.0, 0.0, 0.0]);
        assert_eq!(procedural_weights(h, 0.25), [0.75, 0.25, 0.0, 0.0]);
        assert_eq!(procedural_weights(h, 1.0), [0.0, 1.0, 0.0, 0.0]);
        assert_eq!(procedural_weights(h, 1.5), [0.0, 0.5, 0.5, 0.0]);
        assert_eq!(procedural_weights(h, 2.75), [0.0, 0.0, 0.25, 0.75]);
        assert_eq!(procedural_weights(h, 3.0), [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(procedural_weights(h, 9.0), [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(procedural_weights(h, f32::NAN), [1.0, 0.0, 0.0, 0.0]);
        // A raised root: everything up to it belongs to joint 0.
        assert_eq!(procedural_weights([0.5, 1.0, 2.0, 3.0], 0.3), [1.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn bind_pose_is_translation_only() {
        let s = Skeleton { heights_m: [0.0, 0.1, 0.25, 0.4] };
        assert_eq!(s.joint_matrices(&[[0.0; 3]; 4]), s.bind_matrices());
        for m in s.skinning_matrices(&[[0.0; 3]; 4]) {
            assert!(m.abs_diff_eq(Mat4::IDENTITY, 1e-7));
        }
    }

    #[test]
    fn forward_kinematics_by_hand() {
        // Heights 0, 1, 2, 3; root pitch 90 (+Y -> +Z): joint 1 at (0, 0, 1), joint 3 at (0, 0, 3).
        let s = Skeleton { heights_m: [0.0, 1.0, 2.0, 3.0] };
        let w = s.joint_matrices(&[[90.0, 0.0, 0.0], [0.0; 3], [0.0; 3], [0.0; 3]]);
        assert!(close(w[1].transform_point3(Vec3::ZERO), Vec3::new(0.0, 0.0, 1.0)));
        assert!(close(w[3].transform_point3(Vec3::ZERO), Vec3::new(0.0, 0.0, 3.0)));
        // Joint 1 yaw 90 (+Y -> -X): joint 2 at (-1, 1, 0), joint 3 at (-2, 1, 0).
        let w = s.joint_matrices(&[[0.0; 3], [0.0, 90.0, 0.0], [0.0; 3], [0.0; 3]]);
        assert!(close(w[2].transform_point3(Vec3::ZERO), Vec3::new(-1.0, 1.0, 0.0)));
        assert!(close(w[3].transform_point3(Vec3::ZERO), Vec3::new(-2.0, 1.0, 0.0)));
    }

    #[test]
    fn eq1_skinning_by_hand() {
        // Heights 0, 1, 2, 3. Root pitch 90: every joint follows, so any vertex rotates about the
        // origin: (0.1, 0.2, 0) -> (0.1, 0, 0.2) whatever its weights.
        let s = Skeleton { heights_m: [0.0, 1.0, 2.0, 3.0] };
        let m = s.skinning_matrices(&[[90.0, 0.0, 0.0], [0.0; 3], [0.0; 3], [0.0; 3]]);
        let v = Vec3::new(0.1, 0.2, 0.0);
        assert!(close(skin_point(&m, &[0.3, 0.3, 0.2, 0.2], v), Vec3::new(0.1, 0.0, 0.2)));

        // Joint 1 pitch 90, joint 2 yaw 90; v = (0, 1.5, 0) has weights 0.5 / 0.5 on joints 1, 2.
        // M_1 v = T(0,1,0) R_x90 (0, 0.5, 0) = (0, 1, 0.5).
        // M_2 v = T(0,1,0) R_x90 [(0,1,0) + R_z90 (0,-0.5,0)] = T(0,1,0) R_x90 (0.5, 1, 0)
        //       = (0,1,0) + (0.5, 0, 1) = (0.5, 1, 1).
        // Eq. 1: v' = 0.5 (0, 1, 0.5) + 0.5 (0.5, 1, 1) = (0.25, 1, 0.75).
        let m = s.skinning_matrices(&[[0.0; 3], [90.0, 0.0, 0.0], [0.0, 90.0, 0.0], [0.0; 3]]);
        let v = Vec3::new(0.0, 1.5, 0.0);
        let w = s.weights_at(v.y);
        assert_eq!(w, [0.0, 0.5, 0.5, 0.0]);
        assert!(close(m[1].transform_point3(v), Vec3::new(0.0, 1.0, 0.5)));
        assert!(close(m[2].transform_point3(v), Vec3::new(0.5, 1.0, 1.0)));
        let got = skin_point(&m, &w, v);
        assert!(close(got, Vec3::new(0.25, 1.0, 0.75)), "{got:?}");
        // A rigid normal follows its joint: +Z under joint 1 (pitch 90) becomes -Y.
        let n = skin_normal(&m, &[0.0, 1.0, 0.0, 0.0], Vec3::Z);
        assert!(close(n, -Vec3::Y), "{n:?}");
    }

    proptest! {
        #[test]
        fn weights_are_a_partition_of_unity_and_continuous(
            h0 in 0.0f32..0.5, d1 in 0.01f32..1.0, d2 in 0.01f32..1.0, d3 in 0.01f32..1.0,
            y in -1.0f32..4.0,
        ) {
            let h = [h0, h0 + d1, h0 + d1 + d2, h0 + d1 + d2 + d3];
            let w = procedural_weights(h, y);
            prop_assert!(w.iter().all(|&x| x >= 0.0));
            prop_assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6, "{w:?}");
            // At most two neighbouring joints are used.
            let used: Vec<usize> = (0..4).filter(|&i| w[i] > 0.0).collect();
            prop_assert!(used.len() <= 2 && (used.len() < 2 || used[1] == used[0] + 1));
            // Continuity: a tiny step in height moves the weights a little.
            let eps = 1e-4;
            let w2 = procedural_weights(h, y + eps);
            let dmax = (0..4).map(|i| (w[i] - w2[i]).abs()).fold(0.0, f32::max);
            prop_assert!(dmax <= eps / d1.min(d2).min(d3) + 1e-4, "{w:?} {w2:?}");
        }
    }
}
