//! frond's one rotation convention, used by the daemon, the motion toolkit and every exporter.
//!
//! The stem grows along +Y. A joint's `[pitch, yaw, roll]` (degrees) rotate about the joint's
//! local axes: pitch about +X, yaw about +Z, roll (twist) about +Y, composed as
//! `R = R_yaw * R_pitch * R_roll` (roll applied first), relative to the parent joint; joint 0's
//! parent is the rig's ground frame. Right-handed, as in glTF.
//!
//! Written without dependencies so that a third-party exporter gets it from the protocol crate.

/// Unit quaternion `[x, y, z, w]` of one joint's rotation, `R_yaw * R_pitch * R_roll`.
pub fn joint_quat(angles_deg: [f32; 3]) -> [f32; 4] {
    let [pitch, yaw, roll] = angles_deg.map(|a| f64::from(a).to_radians());
    let (sp, cp) = (pitch * 0.5).sin_cos();
    let (sy, cy) = (yaw * 0.5).sin_cos();
    let (sr, cr) = (roll * 0.5).sin_cos();
    let q_pitch = [sp, 0.0, 0.0, cp];
    let q_yaw = [0.0, 0.0, sy, cy];
    let q_roll = [0.0, sr, 0.0, cr];
    let q = quat_mul(quat_mul(q_yaw, q_pitch), q_roll);
    q.map(|c| c as f32)
}

/// Hamilton product `a * b` of `[x, y, z, w]` quaternions.
pub fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [ax, ay, az, aw] = a;
    let [bx, by, bz, bw] = b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

/// Row-major 3x3 rotation matrix of one joint's rotation, `R_yaw * R_pitch * R_roll`.
pub fn joint_matrix(angles_deg: [f32; 3]) -> [[f64; 3]; 3] {
    let [p, y, r] = angles_deg.map(|a| f64::from(a).to_radians());
    let rx = [[1.0, 0.0, 0.0], [0.0, p.cos(), -p.sin()], [0.0, p.sin(), p.cos()]];
    let rz = [[y.cos(), -y.sin(), 0.0], [y.sin(), y.cos(), 0.0], [0.0, 0.0, 1.0]];
    let ry = [[r.cos(), 0.0, r.sin()], [0.0, 1.0, 0.0], [-r.sin(), 0.0, r.cos()]];
    mat_mul(mat_mul(rz, rx), ry)
}

fn mat_mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            *cell = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotate_by_quat(q: [f32; 4], v: [f64; 3]) -> [f64; 3] {
        let q = q.map(f64::from);
        let conj = [-q[0], -q[1], -q[2], q[3]];
        let p = quat_mul(quat_mul(q, [v[0], v[1], v[2], 0.0]), conj);
        [p[0], p[1], p[2]]
    }

    #[test]
    fn pitch_tips_the_stem_towards_plus_z() {
        // +90 deg about +X takes +Y to +Z (right-hand rule).
        let v = rotate_by_quat(joint_quat([90.0, 0.0, 0.0]), [0.0, 1.0, 0.0]);
        assert!((v[0]).abs() < 1e-6 && (v[1]).abs() < 1e-6 && (v[2] - 1.0).abs() < 1e-6, "{v:?}");
    }

    #[test]
    fn yaw_tips_the_stem_towards_minus_x() {
        // +90 deg about +Z takes +Y to -X.
        let v = rotate_by_quat(joint_quat([0.0, 90.0, 0.0]), [0.0, 1.0, 0.0]);
        assert!((v[0] + 1.0).abs() < 1e-6 && v[1].abs() < 1e-6 && v[2].abs() < 1e-6, "{v:?}");
    }

    #[test]
    fn roll_twists_about_the_stem() {
        // Roll leaves the stem axis alone and takes +X to -Z (90 deg about +Y).
        let q = joint_quat([0.0, 0.0, 90.0]);
        let stem = rotate_by_quat(q, [0.0, 1.0, 0.0]);
        let x = rotate_by_quat(q, [1.0, 0.0, 0.0]);
        assert!((stem[1] - 1.0).abs() < 1e-6, "{stem:?}");
        assert!(x[0].abs() < 1e-6 && (x[2] + 1.0).abs() < 1e-6, "{x:?}");
    }

    #[test]
    fn quaternion_and_matrix_agree_and_roll_applies_first() {
        let angles = [23.0, -41.0, 67.0];
        let q = joint_quat(angles);
        let m = joint_matrix(angles);
        let norm: f32 = q.iter().map(|c| c * c).sum();
        assert!((norm - 1.0).abs() < 1e-6);
        for v in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.3, -0.2, 0.9]] {
            let a = rotate_by_quat(q, v);
            let b: Vec<f64> = (0..3).map(|i| (0..3).map(|k| m[i][k] * v[k]).sum()).collect();
            for i in 0..3 {
                assert!((a[i] - b[i]).abs() < 1e-5, "{a:?} vs {b:?}");
            }
        }
        // Order matters: yaw(pitch(roll(v))) differs from roll(pitch(yaw(v))).
        let v = [0.0, 0.0, 1.0];
        let a = rotate_by_quat(q, v);
        let reversed = {
            let r = joint_quat([0.0, 0.0, 67.0]);
            let p = joint_quat([23.0, 0.0, 0.0]);
            let y = joint_quat([0.0, -41.0, 0.0]);
            rotate_by_quat(r, rotate_by_quat(p, rotate_by_quat(y, v)))
        };
        assert!((a[0] - reversed[0]).abs() > 1e-3 || (a[2] - reversed[2]).abs() > 1e-3);
    }
}
