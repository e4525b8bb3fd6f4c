//! Round trip: `frond-gltf bake`, then read back with the `gltf` crate (a second reader) and
//! compare with expectations computed here from the take, the rig and the rotation convention.

mod common;

use common::*;
use frond_protocol::convention::joint_quat;
use glam::{Mat4, Quat, Vec3};

fn close_quat(a: [f32; 4], b: [f32; 4], tol: f32) -> bool {
    let dot: f32 = (0..4).map(|i| a[i] * b[i]).sum();
    (dot.abs() - 1.0).abs() < tol && (0..4).all(|i| (a[i] - b[i]).abs() < tol || (a[i] + b[i]).abs() < tol)
}

/// Linear interpolation of the raw take poses of one layer at time `t` since `t0`.
fn expected_angles(
    frames: &[frond_motion::TakeFrame],
    element: u16,
    t0: f64,
    t: f64,
    joint: usize,
) -> [f32; 3] {
    let layer: Vec<_> = frames.iter().filter(|f| f.element == element).collect();
    let t = t0 + t;
    if t <= layer[0].pose.t {
        return layer[0].pose.joints_deg[joint];
    }
    for w in layer.windows(2) {
        if t <= w[1].pose.t {
            let u = ((t - w[0].pose.t) / (w[1].pose.t - w[0].pose.t)) as f32;
            let (a, b) = (w[0].pose.joints_deg[joint], w[1].pose.joints_deg[joint]);
            return std::array::from_fn(|c| a[c] + u * (b[c] - a[c]));
        }
    }
    layer[layer.len() - 1].pose.joints_deg[joint]
}

fn node_global(doc: &gltf::Document, target: usize) -> Mat4 {
    fn walk(node: gltf::Node, parent: Mat4, target: usize) -> Option<Mat4> {
        let m = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if node.index() == target {
            return Some(m);
        }
        node.children().find_map(|c| walk(c, m, target))
    }
    doc.default_scene().unwrap().nodes().find_map(|n| walk(n, Mat4::IDENTITY, target)).unwrap()
}

#[test]
fn grass_take_round_trips_through_the_gltf_crate() {
    let dir = tempfile::tempdir().unwrap();
    let take = grass_take(dir.path(), "sway1");
    let out = dir.path().join("out.glb");
    run_ok(&[
        "bake",
        "--take",
        take.to_str().unwrap(),
        "--rig",
        "grass",
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let (doc, buffers) = load(&out);

    // Asset and traceability.
    assert_eq!(doc.as_json().asset.generator.as_deref(), Some(concat!("frond ", env!("CARGO_PKG_VERSION"))));
    let extras: serde_json::Value =
        serde_json::from_str(doc.as_json().asset.extras.as_ref().unwrap().get()).unwrap();
    assert_eq!(extras["take"], "sway1");
    assert_eq!(extras["rig"], "grass");
    assert_eq!(extras["capture_rate_hz"], 200);
    assert_eq!(extras["calibration_id"], "cal-test-7");

    // Skin: joints named after the rig, joint 0 under the plant's root node.
    let skin = doc.skins().next().unwrap();
    let names: Vec<_> = skin.joints().map(|n| n.name().unwrap().to_string()).collect();
    assert_eq!(names, ["root", "lower", "middle", "tip"]);
    let plant_root = skin.skeleton().unwrap();
    assert_eq!(plant_root.name(), Some("grass"));
    assert_eq!(plant_root.children().next().unwrap().index(), skin.joints().next().unwrap().index());

    // Inverse bind matrices undo the joints' rest transforms.
    let ibms: Vec<[[f32; 4]; 4]> =
        skin.reader(|b| Some(&buffers[b.index()])).read_inverse_bind_matrices().unwrap().collect();
    for (j, ibm) in skin.joints().zip(&ibms) {
        let m = node_global(&doc, j.index()) * Mat4::from_cols_array_2d(ibm);
        assert!(m.abs_diff_eq(Mat4::IDENTITY, 1e-6), "{:?}: {m:?}", j.name());
    }
    let heights = [0.0, 0.08, 0.16, 0.24];
    for (j, h) in skin.joints().zip(heights) {
        let p = node_global(&doc, j.index()).transform_point3(Vec3::ZERO);
        assert!((p - Vec3::new(0.0, h, 0.0)).length() < 1e-6, "{:?} at {p:?}", j.name());
    }

    // The mesh: weights sum to 1 and joints index the skin.
    let mesh_node = doc.nodes().find(|n| n.mesh().is_some()).unwrap();
    assert_eq!(mesh_node.skin().unwrap().index(), skin.index());
    let prim = mesh_node.mesh().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let weights: Vec<[f32; 4]> = reader.read_weights(0).unwrap().into_f32().collect();
    let joints: Vec<[u16; 4]> = reader.read_joints(0).unwrap().into_u16().collect();
    assert!(reader.read_normals().is_some());
    assert!(!weights.is_empty());
    for (w, j) in weights.iter().zip(&joints) {
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6, "{w:?}");
        assert!(j.iter().all(|&j| j < 4));
    }

    // One animation named after the take, 4 LINEAR rotation channels, keys at 30 FPS from 0.
    assert_eq!(doc.animations().count(), 1);
    let anim = doc.animations().next().unwrap();
    assert_eq!(anim.name(), Some("sway1"));
    assert_eq!(anim.channels().count(), 4);
    let frames = frond_motion::scan_take(&std::fs::read(&take).unwrap()).unwrap().frames;
    for ch in anim.channels() {
        assert_eq!(ch.sampler().interpolation(), gltf::animation::Interpolation::Linear);
        assert_eq!(ch.target().property(), gltf::animation::Property::Rotation);
        let joint = names.iter().position(|n| Some(n.as_str()) == ch.target().node().name()).unwrap();
        let r = ch.reader(|b| Some(&buffers[b.index()]));
        let times: Vec<f32> = r.read_inputs().unwrap().collect();
        assert_eq!(times.len(), 61); // 2 s at 30 FPS
        for (k, t) in times.iter().enumerate() {
            assert!((t - k as f32 / 30.0).abs() < 1e-6);
        }
        let gltf::animation::util::ReadOutputs::Rotations(rot) = r.read_outputs().unwrap() else {
            panic!("not rotations")
        };
        let quats: Vec<[f32; 4]> = rot.into_f32().collect();
        for (k, q) in quats.iter().enumerate() {
            let want = joint_quat(expected_angles(&frames, 0, 5.0, k as f64 / 30.0, joint));
            assert!(close_quat(*q, want, 1e-5), "joint {joint} key {k}: {q:?} vs {want:?}");
            assert!((Quat::from_array(*q).length() - 1.0).abs() < 1e-6);
        }
        for w in quats.windows(2) {
            assert!(Quat::from_array(w[0]).dot(Quat::from_array(w[1])) >= 0.0);
        }
    }
}
