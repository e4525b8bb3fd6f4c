//! The skin of every shipped rig as `frond-gltf bake` writes it, read back with the `gltf` crate:
//! the main skeleton's vertices carry the documented height rule at their rest height, and
//! vertices that touch at rest stay together when the file's own joints, inverse bind matrices
//! and weights are posed by hand at a strongly bent pose (seed 000, Eq. 1, as a glTF viewer
//! computes it).

use crate::common;

use std::collections::HashMap;

use common::*;
use frond_formats::rig_toml::RigText;
use glam::{Mat4, Quat, Vec3};

/// The README's height rule over joint heights `h`.
fn height_rule(h: [f32; 4], y: f32) -> [f32; 4] {
    if y <= h[0] {
        return [1.0, 0.0, 0.0, 0.0];
    }
    if y >= h[3] {
        return [0.0, 0.0, 0.0, 1.0];
    }
    let i = (0..3).find(|&i| y < h[i + 1]).unwrap();
    let t = (y - h[i]) / (h[i + 1] - h[i]);
    let mut w = [0.0; 4];
    w[i] = 1.0 - t;
    w[i + 1] = t;
    w
}

/// Global matrices of every node, with `rotation(node index)` replacing the rotation of the
/// nodes it names.
fn globals(doc: &gltf::Document, rotation: &dyn Fn(usize) -> Option<Quat>) -> HashMap<usize, Mat4> {
    fn walk(
        node: gltf::Node,
        parent: Mat4,
        rotation: &dyn Fn(usize) -> Option<Quat>,
        out: &mut HashMap<usize, Mat4>,
    ) {
        let (t, r, s) = node.transform().decomposed();
        let r = rotation(node.index()).unwrap_or(Quat::from_array(r));
        let m = parent * Mat4::from_scale_rotation_translation(Vec3::from(s), r, Vec3::from(t));
        out.insert(node.index(), m);
        for c in node.children() {
            walk(c, m, rotation, out);
        }
    }
    let mut out = HashMap::new();
    for n in doc.default_scene().unwrap().nodes() {
        walk(n, Mat4::IDENTITY, rotation, &mut out);
    }
    out
}

/// A strong bend (pitch, yaw, roll in degrees, `R = R_yaw R_pitch R_roll`) for skin joint `k`.
fn bent(k: usize) -> Quat {
    let [p, y, r] = [[55.0f32, 30.0, 0.0], [45.0, -35.0, 25.0], [50.0, 40.0, -30.0], [60.0, 25.0, 40.0]]
        [k % 4]
        .map(f32::to_radians);
    Quat::from_rotation_z(y) * Quat::from_rotation_x(p) * Quat::from_rotation_y(r)
}

#[test]
fn every_baked_rig_is_skinned_by_height_and_does_not_tear_when_bent() {
    let dir = tempfile::tempdir().unwrap();
    let take = grass_take(dir.path(), "sway");
    for rig_path in rig_files() {
        let rig = frond_motion::Rig::from_toml_str(&std::fs::read_to_string(&rig_path).unwrap()).unwrap();
        let out = dir.path().join(format!("{}.glb", rig.name));
        run_ok(&[
            "bake",
            "-q",
            "--take",
            take.to_str().unwrap(),
            "--rig",
            rig_path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        let (doc, buffers) = load(&out);
        let skin = doc.skins().next().unwrap();
        let joints: Vec<usize> = skin.joints().map(|n| n.index()).collect();
        let names: Vec<String> = skin.joints().map(|n| n.name().unwrap().to_string()).collect();
        let ibms: Vec<Mat4> = skin
            .reader(|b| Some(&buffers[b.index()]))
            .read_inverse_bind_matrices()
            .unwrap()
            .map(|m| Mat4::from_cols_array_2d(&m))
            .collect();
        // Skin joint -> rig joint for the main skeleton (by name).
        let main: Vec<Option<usize>> =
            names.iter().map(|n| rig.joints.iter().position(|j| &j.name == n)).collect();
        assert_eq!(main.iter().flatten().count(), 4, "{}: {names:?}", rig.name);
        let heights: [f32; 4] = std::array::from_fn(|i| rig.joints[i].height_m);

        let mut positions = Vec::new();
        let mut weights = Vec::new();
        for mesh_node in doc.nodes().filter(|n| n.mesh().is_some()) {
            assert_eq!(mesh_node.skin().unwrap().index(), skin.index());
            for prim in mesh_node.mesh().unwrap().primitives() {
                let r = prim.reader(|b| Some(&buffers[b.index()]));
                let js: Vec<[u16; 4]> = r.read_joints(0).unwrap().into_u16().collect();
                let ws: Vec<[f32; 4]> = r.read_weights(0).unwrap().into_f32().collect();
                for ((p, j), w) in r.read_positions().unwrap().zip(js).zip(ws) {
                    positions.push(Vec3::from(p));
                    weights.push((0..4).map(|c| (j[c] as usize, w[c])).collect::<Vec<_>>());
                }
            }
        }

        // Height rule for every vertex of the main skeleton.
        let mut checked = 0;
        for (k, (p, w)) in positions.iter().zip(&weights).enumerate() {
            if w.iter().any(|&(j, x)| x > 0.0 && main[j].is_none()) {
                continue; // an element (leaf) vertex, on the element's own skeleton
            }
            let mut got = [0.0f32; 4];
            for &(j, x) in w {
                if let Some(i) = main[j] {
                    got[i] += x;
                }
            }
            let want = height_rule(heights, p.y);
            assert!(
                (0..4).all(|i| (got[i] - want[i]).abs() < 1e-5),
                "{}: vertex {k} at {p:?} has weights {got:?}, the height rule at y = {} gives {want:?}",
                rig.name,
                p.y
            );
            checked += 1;
        }
        assert!(checked > 0, "{}", rig.name);

        // Eq. 1 with the file's data at a strongly bent pose.
        let slot: HashMap<usize, usize> = joints.iter().enumerate().map(|(k, &n)| (n, k)).collect();
        let g = globals(&doc, &|node| slot.get(&node).map(|&k| bent(k)));
        let m: Vec<Mat4> = joints.iter().zip(&ibms).map(|(n, ibm)| g[n] * *ibm).collect();
        let posed: Vec<Vec3> = positions
            .iter()
            .zip(&weights)
            .map(|(p, w)| w.iter().map(|&(j, x)| m[j].transform_point3(*p) * x).sum())
            .collect();
        let mut worst = (0.0f32, String::new());
        for a in 0..positions.len() {
            for b in a + 1..positions.len() {
                let rest = positions[a].distance(positions[b]);
                if rest <= 0.005 {
                    let stretch = posed[a].distance(posed[b]) - rest;
                    if stretch > worst.0 {
                        worst = (
                            stretch,
                            format!("vertices {a} at {:?} and {b} at {:?}", positions[a], positions[b]),
                        );
                    }
                }
            }
        }
        assert!(
            worst.0 <= 0.004,
            "{}: {} touch at rest and move {:.1} mm apart at the bent pose",
            rig.name,
            worst.1,
            worst.0 * 1e3
        );
    }
}
