//! Round trip: `frond-gltf bake`, then read back with the `gltf` crate (a second reader) and
//! compare with expectations computed here from the take, the rig and the rotation convention.

use crate::common;

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
    let layer: Vec<_> = frames.iter().filter(|f| f.element.get() == element).collect();
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
    let frames = frond_formats::scan_take(&std::fs::read(&take).unwrap()).unwrap().frames;
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

fn rotations(ch: &gltf::animation::Channel, buffers: &[Vec<u8>]) -> (Vec<f32>, Vec<[f32; 4]>) {
    let r = ch.reader(|b| Some(&buffers[b.index()]));
    let times = r.read_inputs().unwrap().collect();
    let gltf::animation::util::ReadOutputs::Rotations(rot) = r.read_outputs().unwrap() else {
        panic!("not rotations")
    };
    (times, rot.into_f32().collect())
}

#[test]
fn layered_take_animates_each_leaf_skeleton_with_its_layer() {
    let dir = tempfile::tempdir().unwrap();
    let take = layered_take(dir.path(), "lay");
    let out = dir.path().join("flower.glb");
    run_ok(&["bake", "-q", "--take", take.to_str().unwrap(), "--rig", "flower", "-o", out.to_str().unwrap()]);
    let (doc, buffers) = load(&out);
    let skin = doc.skins().next().unwrap();
    let names: Vec<String> = skin.joints().map(|n| n.name().unwrap().to_string()).collect();
    assert_eq!(names.len(), 12);
    assert_eq!(&names[..4], ["root", "stem_low", "stem_high", "head"]);
    assert_eq!(names[4], "leaf0_joint0");
    assert_eq!(names[11], "leaf1_joint3");
    // Leaves hang from their attach joint (stem_low, joint 1) through an attach node.
    let stem_low = skin.joints().nth(1).unwrap();
    let attach: Vec<_> = stem_low.children().filter(|c| c.name().unwrap().starts_with("leaf")).collect();
    assert_eq!(attach.iter().map(|n| n.name().unwrap()).collect::<Vec<_>>(), ["leaf0", "leaf1"]);
    // Every joint's IBM undoes its rest transform, leaves included.
    let ibms: Vec<[[f32; 4]; 4]> =
        skin.reader(|b| Some(&buffers[b.index()])).read_inverse_bind_matrices().unwrap().collect();
    for (j, ibm) in skin.joints().zip(&ibms) {
        let m = node_global(&doc, j.index()) * Mat4::from_cols_array_2d(ibm);
        assert!(m.abs_diff_eq(Mat4::IDENTITY, 1e-5), "{:?}", j.name());
    }
    // Leaf vertices are skinned to leaf joints only; stem vertices to stem joints only.
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let joints: Vec<[u16; 4]> = reader.read_joints(0).unwrap().into_u16().collect();
    let weights: Vec<[f32; 4]> = reader.read_weights(0).unwrap().into_f32().collect();
    let leafy = joints.iter().zip(&weights).filter(|(j, w)| (0..4).any(|c| w[c] > 0.0 && j[c] >= 4)).count();
    assert!(leafy > 0);
    for (j, w) in joints.iter().zip(&weights) {
        let used: Vec<u16> = (0..4).filter(|&c| w[c] > 0.0).map(|c| j[c]).collect();
        assert!(used.iter().all(|&x| x < 4) || used.iter().all(|&x| x >= 4), "{j:?} {w:?}");
        for c in 0..4 {
            assert!(w[c] > 0.0 || j[c] == 0, "zero weight on joint {}", j[c]);
        }
    }
    // 12 channels; leaf joints follow layer 1 (held at its first pose before it starts at +0.5 s).
    let frames = frond_formats::scan_take(&std::fs::read(&take).unwrap()).unwrap().frames;
    let anim = doc.animations().next().unwrap();
    assert_eq!(anim.channels().count(), 12);
    for ch in anim.channels() {
        let slot = names.iter().position(|n| Some(n.as_str()) == ch.target().node().name()).unwrap();
        let (layer, joint) = if slot < 4 { (0, slot) } else { (1, slot % 4) };
        let (times, quats) = rotations(&ch, &buffers);
        assert_eq!(times.len(), 61);
        for (k, q) in quats.iter().enumerate() {
            let want = joint_quat(expected_angles(&frames, layer, 5.0, k as f64 / 30.0, joint));
            assert!(close_quat(*q, want, 1e-5), "{} key {k}", names[slot]);
        }
    }
}

#[test]
fn field_shares_one_mesh_and_delays_each_plant() {
    let dir = tempfile::tempdir().unwrap();
    let take = grass_take(dir.path(), "wind");
    let field = field_json(dir.path(), 5, 90.0);
    let out = dir.path().join("field.glb");
    run_ok(&[
        "bake",
        "-q",
        "--field",
        field.to_str().unwrap(),
        "--take",
        take.to_str().unwrap(),
        "--rig",
        "grass",
        "--duration",
        "3",
        "-o",
        out.to_str().unwrap(),
    ]);
    let (doc, buffers) = load(&out);
    assert_eq!(doc.meshes().count(), 1);
    assert_eq!(doc.skins().count(), 5);
    let mesh_nodes: Vec<_> = doc.nodes().filter(|n| n.mesh().is_some()).collect();
    assert_eq!(mesh_nodes.len(), 5);
    assert!(mesh_nodes.iter().all(|n| n.mesh().unwrap().index() == 0 && n.skin().is_some()));
    let ibm0 = doc.skins().next().unwrap().inverse_bind_matrices().unwrap().index();
    assert!(doc.skins().all(|s| s.inverse_bind_matrices().unwrap().index() == ibm0));
    assert_eq!(doc.animations().count(), 1);

    // Clip of the take at the field's 30 FPS, from the raw frames.
    let frames = frond_formats::scan_take(&std::fs::read(&take).unwrap()).unwrap().frames;
    let clip_len = 61;
    let anim = doc.animations().next().unwrap();
    assert_eq!(anim.channels().count(), 20);
    for (i, skin) in doc.skins().enumerate() {
        let root = skin.skeleton().unwrap();
        let (t, _, s) = root.transform().decomposed();
        assert_eq!(t, [i as f32 * 0.3, 0.0, (i % 2) as f32 * 0.2], "plant {i}");
        assert!((s[0] - (1.0 + 0.1 * i as f32)).abs() < 1e-6);
        for (j, joint) in skin.joints().enumerate() {
            let ch = anim.channels().find(|c| c.target().node().index() == joint.index()).unwrap();
            let (times, quats) = rotations(&ch, &buffers);
            assert_eq!(times.len(), 91);
            for (k, q) in quats.iter().enumerate() {
                // start 3i, delay 0.2 i s = 6i frames: frame k - 3i, clamped to the clip; the
                // force heads 90 degrees from the authored direction: (p, y) -> (y, -p).
                let f = (k as i64 - 3 * i as i64).clamp(0, clip_len - 1) as f64;
                let [p, y, r] = expected_angles(&frames, 0, 5.0, f / 30.0, j);
                let want = joint_quat([y, -p, r]);
                assert!(close_quat(*q, want, 1e-5), "plant {i} joint {j} key {k}");
            }
        }
    }
}

#[test]
fn grove_gives_each_plant_its_own_take_on_a_grid() {
    let dir = tempfile::tempdir().unwrap();
    // Three different motions; the third take is half as long and holds its last pose after.
    let a = write_take(dir.path(), "walk", "grass", frames(0, 5.0, 2.0, 200.0, 0.0), &[]);
    let b = write_take(dir.path(), "walk-plant1", "grass", frames(0, 1.0, 2.0, 200.0, 1.3), &[]);
    let c = write_take(dir.path(), "walk-plant2", "grass", frames(0, 0.0, 1.0, 200.0, 2.6), &[]);
    let out = dir.path().join("grove.glb");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    run_ok(&[
        "bake",
        "-q",
        "--take",
        &s(&a),
        &s(&b),
        "--take",
        &s(&c),
        "--rig",
        "grass",
        "--spacing",
        "0.5",
        "-o",
        &s(&out),
    ]);
    let (doc, buffers) = load(&out);
    assert_eq!(doc.meshes().count(), 1);
    assert_eq!(doc.skins().count(), 3);
    let anim = doc.animations().next().unwrap();
    assert_eq!(anim.name(), Some("grove"));
    assert_eq!(anim.channels().count(), 12);
    let extras: serde_json::Value =
        serde_json::from_str(doc.as_json().asset.extras.as_ref().unwrap().get()).unwrap();
    assert_eq!(extras["grove"]["takes"], serde_json::json!(["walk", "walk-plant1", "walk-plant2"]));
    // 3 plants: 2 columns, 2 rows, 0.5 m apart, centred: worked out by hand.
    let at = [[-0.25, 0.0, -0.25], [0.25, 0.0, -0.25], [-0.25, 0.0, 0.25]];
    let takes = [(&a, 5.0), (&b, 1.0), (&c, 0.0)];
    for (i, skin) in doc.skins().enumerate() {
        let root = skin.skeleton().unwrap();
        assert_eq!(root.name(), Some(format!("grass_{i}").as_str()));
        assert_eq!(root.transform().decomposed().0, at[i], "plant {i}");
        let frames = frond_formats::scan_take(&std::fs::read(takes[i].0).unwrap()).unwrap().frames;
        for (j, joint) in skin.joints().enumerate() {
            let ch = anim.channels().find(|c| c.target().node().index() == joint.index()).unwrap();
            let (times, quats) = rotations(&ch, &buffers);
            assert_eq!(times.len(), 61, "the longest take sets the length");
            for (k, q) in quats.iter().enumerate() {
                let want = joint_quat(expected_angles(&frames, 0, takes[i].1, k as f64 / 30.0, j));
                assert!(close_quat(*q, want, 1e-5), "plant {i} joint {j} key {k}");
            }
        }
    }
}

#[test]
fn gltf_output_is_a_json_file_and_a_bin_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    let take = grass_take(dir.path(), "split");
    let glb = dir.path().join("a.glb");
    let gltf_path = dir.path().join("b.gltf");
    run_ok(&["bake", "-q", "--take", take.to_str().unwrap(), "--rig", "shrub", "-o", glb.to_str().unwrap()]);
    run_ok(&[
        "bake",
        "-q",
        "--take",
        take.to_str().unwrap(),
        "--rig",
        "shrub",
        "--gltf",
        "-o",
        gltf_path.to_str().unwrap(),
    ]);
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&gltf_path).unwrap()).unwrap();
    assert_eq!(json["buffers"][0]["uri"], "b.bin");
    assert!(dir.path().join("b.bin").is_file());
    let (a, abuf) = load(&glb);
    let (b, bbuf) = load(&gltf_path);
    let keys = |doc: &gltf::Document, bufs: &[Vec<u8>]| {
        doc.animations().next().unwrap().channels().map(|c| rotations(&c, bufs)).collect::<Vec<_>>()
    };
    assert_eq!(keys(&a, &abuf), keys(&b, &bbuf));
    // Files get ordinary permissions (0666 less the umask), not a temporary file's 0600.
    use std::os::unix::fs::PermissionsExt;
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let umask = status
        .lines()
        .find_map(|l| l.strip_prefix("Umask:"))
        .map(|v| u32::from_str_radix(v.trim(), 8).unwrap());
    let umask = umask.unwrap();
    for f in ["a.glb", "b.gltf", "b.bin"] {
        let mode = std::fs::metadata(dir.path().join(f)).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o666 & !umask, "{f}");
    }
    // Nothing else in the directory: no temporary files left.
    let mut names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    names.sort();
    assert_eq!(names, ["a.glb", "b.bin", "b.gltf", "split.take"]);
}
