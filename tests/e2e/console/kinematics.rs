//! Forward kinematics of the poses the page received, worked out here from the rig's model and
//! the protocol's rotation convention, against the bones' world positions read from the page.

use std::time::Duration;

use frond_motion::mesh::PlantModel;
use frond_protocol::convention::joint_matrix;
use frond_webdriver::{Driver, poll};
use serde_json::Value;

/// A rigid frame: rotation (row-major) and origin.
#[derive(Debug, Clone, Copy)]
pub(super) struct Frame {
    pub rot: [[f64; 3]; 3],
    pub pos: [f64; 3],
}

impl Frame {
    pub const IDENTITY: Frame =
        Frame { rot: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], pos: [0.0; 3] };

    /// `self * T(offset) * R(m)`: a child frame at `offset` in this frame, turned by `m`.
    fn child(&self, offset: [f64; 3], m: [[f64; 3]; 3]) -> Frame {
        let mut pos = self.pos;
        for (r, p) in pos.iter_mut().enumerate() {
            *p += (0..3).map(|k| self.rot[r][k] * offset[k]).sum::<f64>();
        }
        let rot =
            std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| self.rot[r][k] * m[k][c]).sum()));
        Frame { rot, pos }
    }
}

/// The rotation matrix of a unit quaternion `[x, y, z, w]`.
pub(super) fn quat_matrix([x, y, z, w]: [f32; 4]) -> [[f64; 3]; 3] {
    let (x, y, z, w) = (f64::from(x), f64::from(y), f64::from(z), f64::from(w));
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// The frames of a 4-joint chain from `base`: joint `i` sits at `heights[i] - heights[i - 1]`
/// along its parent's +Y (joint 0 at `heights[0]`), turned by `joint_matrix` of its
/// `[pitch, yaw, roll]` relative to its parent (the protocol's convention).
pub(super) fn chain(base: Frame, heights: &[f32; 4], joints_deg: &[[f32; 3]; 4]) -> [Frame; 4] {
    let mut out = [base; 4];
    let mut parent = base;
    for i in 0..4 {
        let step = f64::from(heights[i]) - if i == 0 { 0.0 } else { f64::from(heights[i - 1]) };
        out[i] = parent.child([0.0, step, 0.0], joint_matrix(joints_deg[i]));
        parent = out[i];
    }
    out
}

pub(super) fn joints_of(v: &Value) -> [[f32; 3]; 4] {
    std::array::from_fn(|i| std::array::from_fn(|k| v[i][k].as_f64().unwrap() as f32))
}

/// Reads `snapshot(element)` from the page until it has one, and checks every bone set of it
/// against forward kinematics (here, from the rig's model and the poses the page received);
/// returns the element's joints.
pub(super) fn check_bones(d: &Driver, element: u16, model: &PlantModel) -> [[f32; 3]; 4] {
    let snap = poll(&format!("a snapshot of element {element}"), Duration::from_secs(30), || {
        let v = d
            .script(&format!("return window.frondConsole ? window.frondConsole.snapshot({element}) : null;"));
        (!v.is_null()).then_some(v)
    });
    let joints = joints_of(&snap["pose"]["j"]);
    let main = chain(Frame::IDENTITY, &model.skeleton.heights_m, &joints_of(&snap["main"]["j"]));
    // The chains the element drives: the main skeleton, or each instance of a rig element
    // (its layer id is the element's index + 1), hung from its attach joint.
    let want: Vec<[Frame; 4]> = if element == 0 {
        vec![main]
    } else {
        model
            .elements
            .iter()
            .filter(|e| e.element + 1 == usize::from(element))
            .map(|e| {
                let offset = e.offset_m.map(f64::from);
                let attach = main[usize::from(e.attach_joint)].child(offset, quat_matrix(e.rotation));
                chain(attach, &e.skeleton.heights_m, &joints)
            })
            .collect()
    };
    let sets = snap["bones"].as_array().unwrap();
    assert_eq!(sets.len(), want.len(), "bone sets of element {element}");
    let tol = 1e-4 * f64::from(model.skeleton.heights_m[3]);
    for (s, (set, frames)) in sets.iter().zip(&want).enumerate() {
        for (i, f) in frames.iter().enumerate() {
            for k in 0..3 {
                let got = set[i][k].as_f64().unwrap();
                assert!(
                    (got - f.pos[k]).abs() <= tol,
                    "element {element} set {s} joint {i} axis {k}: page {got}, forward kinematics {} (pose {joints:?})",
                    f.pos[k]
                );
            }
        }
    }
    joints
}

pub(super) fn model(rig: &str) -> PlantModel {
    let loaded = frond_formats::rig_files::embedded_rig(rig).unwrap().unwrap();
    frond_formats::rig_files::plant_model(&loaded).unwrap()
}

pub(super) fn heights(d: &Driver) -> [f64; 4] {
    let h = d.async_script(
        "const done = arguments[arguments.length - 1]; fetch('/api/scene').then(r => r.json()).then(m => done(m.heights_m));",
    );
    std::array::from_fn(|i| h[i].as_f64().unwrap())
}
