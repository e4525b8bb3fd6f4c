//! frond-osc into Blender (`bpy` from PyPI, headless) onto the armature a user has: the GLB
//! frond-gltf bakes for the daemon's rig, imported by Blender's own glTF importer. Two receivers:
//! frond's add-on (`blender/frond_receiver.py`, checked by `blender_check.py`) on the `frond`
//! namespace, and a third-party VMC receiver, the VMC4B add-on (vendored unchanged in
//! `third_party/VMC4B`, driven by `vmc4b_check.py`) on frond-osc's default VMC stream. Bone world
//! positions are compared with forward kinematics of the poses a `frond_sdk` subscriber got from
//! the same daemon.
//!
//! Needs `target/<profile>/frondd` and `frond-gltf` (`cargo build --workspace --bins`) and bpy in
//! the venv (`install-python.sh`); missing one, a test skips, unless `CI=true` or
//! `FROND_REQUIRE_PYTHON=1`, where it fails.

use crate::support;

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use frond_formats::layers::TakeBytes;
use frond_motion::rig::Rig;
use frond_protocol::ElementId;
use frond_protocol::Pose;
use support::*;

/// Writes a take of `rig` named `name` into `dir`: `frames` frames at 30 FPS of each joint
/// swaying on all three axes (`joints_deg(t)`), or the rest pose.
pub(crate) fn write_take(dir: &Path, name: &str, rig: &str, frames: usize, sway: bool) -> PathBuf {
    let mut take = frond_motion::layers::Take::new(frond_motion::take::TakeHeader::offline(name, rig, 30));
    let pose = |t: f64| -> [[f32; 3]; 4] {
        std::array::from_fn(|j| {
            let phase = t * std::f64::consts::TAU * 0.7 + j as f64;
            [25.0 * phase.sin(), 15.0 * phase.cos(), 10.0 * (2.0 * phase).sin()].map(|a| a as f32)
        })
    };
    let frames: Vec<frond_motion::PoseFrame> = (0..frames)
        .map(|k| {
            let t = k as f64 / 30.0;
            frond_motion::PoseFrame { t, joints_deg: if sway { pose(t) } else { [[0.0; 3]; 4] } }
        })
        .collect();
    let clip = frond_motion::clip::Clip { fps: 30.0, frames };
    take.set_layer(
        ElementId::GLOBAL,
        None,
        frond_motion::layers::frames_from_clip(&clip, ElementId::GLOBAL, 0, None),
    );
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{name}.take"));
    std::fs::write(&path, take.to_bytes()).unwrap();
    path
}

/// Bakes a three-frame rest take of `rig` with frond-gltf into `dir/<rig>.glb` (only its armature
/// and mesh matter to the receivers).
fn bake_rest_glb(gltf: &Path, rig: &str, dir: &Path) -> PathBuf {
    let take_path = write_take(dir, &format!("{rig}-rest"), rig, 3, false);
    let glb = dir.join(format!("{rig}.glb"));
    let baked = Command::new(gltf)
        .args(["bake", "-q", "--rig", rig, "--take"])
        .arg(&take_path)
        .arg("-o")
        .arg(&glb)
        .output()
        .unwrap();
    assert!(baked.status.success(), "{}", String::from_utf8_lossy(&baked.stderr));
    glb
}

/// Forward kinematics of a pose in frond's convention (stem +Y, each joint's matrix chained root
/// to top, joints at the rig's heights), in Blender's Z-up world ((x, y, z) -> (x, -z, y)): each
/// joint's head and the direction its bone points.
pub(crate) fn blender_fk(joints_deg: [[f32; 3]; 4], rig: &Rig) -> ([[f64; 3]; 4], [[f64; 3]; 4]) {
    let to_blender = |v: [f64; 3]| [v[0], -v[2], v[1]];
    let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0f64]];
    let mut p = [0.0, f64::from(rig.joints[0].height_m), 0.0];
    let mut heads = [[0.0; 3]; 4];
    let mut dirs = [[0.0; 3]; 4];
    for i in 0..4 {
        heads[i] = to_blender(p);
        let m = frond_protocol::convention::joint_matrix(joints_deg[i]);
        r = std::array::from_fn(|a| std::array::from_fn(|b| (0..3).map(|k| r[a][k] * m[k][b]).sum()));
        // R (0, 1, 0): the second column.
        let stem = [r[0][1], r[1][1], r[2][1]];
        dirs[i] = to_blender(stem);
        if i + 1 < 4 {
            let seg = f64::from(rig.joints[i + 1].height_m - rig.joints[i].height_m);
            p = std::array::from_fn(|a| p[a] + stem[a] * seg);
        }
    }
    (heads, dirs)
}

/// What every test here needs: frondd, frond-gltf (beside it) and the venv's python with bpy;
/// `None` after saying why the test is skipped.
pub(crate) fn blender_tools() -> Option<(PathBuf, PathBuf, PathBuf)> {
    let Some(frondd) = frondd() else {
        skip("frondd is not built (cargo build --workspace --bins)");
        return None;
    };
    let Some(py) = python_with("bpy") else {
        skip("no bpy in tests/python/.venv (run exporters/osc/tests/install-python.sh)");
        return None;
    };
    let gltf = frondd.with_file_name("frond-gltf");
    if !gltf.exists() {
        skip("frond-gltf is not built (cargo build --workspace --bins)");
        return None;
    }
    Some((frondd, py, gltf))
}

/// Starts `tests/SCRIPT ARGS` with `py` and reads its stdout until a line starting with
/// `ready` (Blender's importer logs on stdout too); returns the process and the rest of that
/// line (`port N` gives `N`).
pub(crate) fn start_script(
    py: &Path,
    script: &str,
    args: &[&std::ffi::OsStr],
    ready: &str,
) -> (Proc, String) {
    // In a Proc at once: dropped (on a panic below too), it is killed and reaped.
    let mut proc = Proc(
        Command::new(py)
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join(script))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("start {script}: {e}")),
    );
    let mut reader = BufReader::new(proc.0.stdout.take().unwrap());
    let mut line = String::new();
    loop {
        line.clear();
        if reader.read_line(&mut line).unwrap_or_else(|e| panic!("{script}'s output: {e}")) == 0 {
            let mut err = String::new();
            proc.0.stderr.take().unwrap().read_to_string(&mut err).unwrap();
            panic!("{script} ended before printing `{ready}`: {err}");
        }
        if let Some(rest) = line.trim().strip_prefix(ready) {
            return (proc, rest.trim().to_string());
        }
    }
}

/// `OsStr` arguments for [`start_script`].
/// Runs `frond ARGS` (the `frond` beside `frondd`) against `daemon`; it must succeed.
pub(crate) fn run_frond(frond: &Path, daemon: &Daemon, args: &[&str]) {
    let out = Command::new(frond)
        .args(args)
        .env("FROND_SOCKET_DIR", &daemon.socket_dir)
        .env("FROND_TAKES_DIR", &daemon.takes_dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "frond {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// A field file of take `sway` (`frond take field`, `[rows, cols, cell]`, speed 2) in `dir`,
/// and frond-gltf's bake of it on `take` for `duration` seconds: the GLB Blender imports.
pub(crate) fn field_with_glb(
    frond: &Path,
    gltf: &Path,
    daemon: &Daemon,
    take: &Path,
    dir: &Path,
    [rows, cols, cell]: [&str; 3],
    duration: &str,
) -> (PathBuf, PathBuf) {
    let field = dir.join("field.json");
    let field_s = field.to_str().unwrap();
    run_frond(
        frond,
        daemon,
        &[
            "take", "field", "sway", "--rows", rows, "--cols", cols, "--cell", cell, "--speed", "2", "-o",
            field_s,
        ],
    );
    let glb = dir.join("field.glb");
    let baked = Command::new(gltf)
        .args(["bake", "-q", "--rig", "grass", "--take"])
        .arg(take)
        .args(["--field", field_s, "--duration", duration, "-o"])
        .arg(&glb)
        .output()
        .unwrap();
    assert!(baked.status.success(), "{}", String::from_utf8_lossy(&baked.stderr));
    (field, glb)
}

pub(crate) fn os<'a>(args: &[&'a str]) -> Vec<&'a std::ffi::OsStr> {
    args.iter().map(|a| std::ffi::OsStr::new(*a)).collect()
}

pub(crate) fn close(got: &[f64], want: &[f64; 3], tol: f64, what: &str) {
    assert_eq!(got.len(), 3, "{what}: {got:?}");
    assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < tol), "{what}: {got:?} vs {want:?}");
}

pub(crate) fn f64s(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().expect("array").iter().map(|x| x.as_f64().expect("number")).collect()
}

/// The Blender add-on, headless (bpy from PyPI): frond-osc drives its armature; the bone
/// rotations Blender reports equal the daemon's joints in frond's convention, and Record keys the
/// frames into an action (`blender_check.py` checks geometry and keys itself).
#[test]
fn blender_addon_drives_the_armature_and_records() {
    let Some((frondd, py, gltf)) = blender_tools() else { return };
    let daemon = start_daemon(&frondd);
    let tmp = tempfile::tempdir().unwrap();
    // The armature a user has: frond-gltf's GLB of the daemon's rig (grass), imported by Blender.
    let rig = frond_formats::rig_files::load_rig("grass").unwrap().rig;
    let glb = bake_rest_glb(&gltf, "grass", tmp.path());
    let flower = bake_rest_glb(&gltf, "flower", tmp.path());
    let heights: Vec<String> = rig.joints.iter().map(|j| j.height_m.to_string()).collect();
    let heights = heights.join(",");
    let out = tmp.path().join("blender.jsonl");
    let args = ["--frames", "300", "--record", "200", "--timeout", "90", "--heights", &heights, "--out"];
    let mut args = os(&args);
    args.extend([
        out.as_os_str(),
        "--glb".as_ref(),
        glb.as_os_str(),
        "--flower-glb".as_ref(),
        flower.as_os_str(),
    ]);
    let (mut blender, port) = start_script(&py, "blender_check.py", &args, "port ");
    let collector = Collector::start(&daemon.socket_dir);
    let osc = start_osc(&daemon.socket_dir, &["--target", &format!("127.0.0.1:{port}")]);
    wait_receiver(&mut blender);
    let (_, poses) = collector.finish();
    stop_and_stderr(osc);

    let by_seq: HashMap<u32, &Pose> = poses.iter().map(|p| (p.seq as u32, p)).collect();
    let frames = read_jsonl(&out);
    assert!(!frames.is_empty());
    for f in &frames {
        let seq = f["seq"].as_i64().unwrap() as u32;
        let pose = by_seq.get(&seq).unwrap_or_else(|| panic!("frame {seq} unknown to the SDK subscriber"));
        let (want, _) = blender_fk(pose.joints_deg, &rig);
        for (i, head) in f["heads"].as_array().unwrap().iter().enumerate() {
            let got: Vec<f64> = head.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            close(&got, &want[i], 1e-4, &format!("Blender's head of joint {i} at {seq}"));
        }
    }
}

/// A third-party VMC receiver in Blender: VMC4B, set up as its README and frond-osc's README say
/// (target armature = the grass GLB as imported, humanoid bones Hips/Spine/Chest/Neck mapped to
/// `root/lower/middle/tip`, its Connect button), receives frond-osc's VMC stream with every
/// default (60 Hz, humanoid names, timetags "immediately", no `--rig`). The four bones' world heads
/// and directions, as Blender computes them after VMC4B applied a frame, equal forward kinematics
/// of the daemon's pose at that frame's device time; the virtual glove moves enough that a
/// receiver ignoring a bone would fail.
#[test]
fn vmc4b_in_blender_drives_the_imported_armature_from_the_default_stream() {
    let Some((frondd, py, gltf)) = blender_tools() else { return };
    let daemon = start_daemon(&frondd);
    let tmp = tempfile::tempdir().unwrap();
    let rig = frond_formats::rig_files::load_rig("grass").unwrap().rig;
    let glb = bake_rest_glb(&gltf, "grass", tmp.path());
    let bones: Vec<String> = ["Hips", "Spine", "Chest", "Neck"]
        .iter()
        .zip(&rig.joints)
        .map(|(humanoid, joint)| format!("{humanoid}={}", joint.name))
        .collect();
    let (bones, port) =
        (bones.join(","), std::net::UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port());
    let port_s = port.to_string();
    let out = tmp.path().join("vmc4b.jsonl");
    let args = ["--port", &port_s, "--bones", &bones, "--frames", "120", "--timeout", "60", "--out"];
    let mut args = os(&args);
    args.extend([out.as_os_str(), "--glb".as_ref(), glb.as_os_str()]);
    // VMC4B listens once `listening` is printed.
    let (mut blender, _) = start_script(&py, "vmc4b_check.py", &args, "listening");
    let collector = Collector::start(&daemon.socket_dir);
    let osc = start_osc(&daemon.socket_dir, &["--protocol", "vmc", "--target", &format!("127.0.0.1:{port}")]);
    wait_receiver(&mut blender);
    let (_, poses) = collector.finish();
    stop_and_stderr(osc);

    // VMC carries T as f32 seconds of device time: frames are matched to the SDK's poses by it.
    let by_t: HashMap<u32, &Pose> = poses.iter().map(|p| ((p.hand.t as f32).to_bits(), p)).collect();
    let frames = read_jsonl(&out);
    assert_eq!(frames.len(), 120);
    let (mut matched, mut bent) = (0, 0);
    for f in &frames {
        let t = f["t"].as_f64().unwrap() as f32;
        let Some(pose) = by_t.get(&t.to_bits()) else { continue };
        matched += 1;
        let (heads, dirs) = blender_fk(pose.joints_deg, &rig);
        for i in 0..4 {
            let name = &rig.joints[i].name;
            close(&f64s(&f["heads"][i]), &heads[i], 1e-4, &format!("world head of {name} at t={t}"));
            close(&f64s(&f["dirs"][i]), &dirs[i], 1e-4, &format!("world direction of {name} at t={t}"));
        }
        // The top bone leaning more than 5 degrees off the rest pose's vertical.
        if dirs[3][2] < 5f64.to_radians().cos() {
            bent += 1;
        }
    }
    assert!(
        matched >= frames.len() * 9 / 10,
        "only {matched} of {} frames matched an SDK pose",
        frames.len()
    );
    assert!(
        bent >= matched / 4,
        "only {bent} of {matched} frames bend the plant: the check would not see a bone ignored"
    );
}

/// A live field into Blender: `frond field start` plays a known take (each joint swaying) on four
/// plants of a field; frond-gltf bakes the same field file; Blender imports it (one armature per
/// plant) and frond's add-on, with no armature picked, drives each plant's armature from its
/// `plant<i>` element. Every reported plant pose (bone heads and directions in its armature's
/// space) equals forward kinematics of the daemon's pose of that element and sequence number, all
/// four plants are driven, and Record gives each plant its own action.
#[test]
fn blender_addon_drives_the_plants_of_a_live_field() {
    let Some((frondd, py, gltf)) = blender_tools() else { return };
    let frond = frondd.with_file_name("frond");
    let daemon = start_daemon(&frondd);
    let tmp = tempfile::tempdir().unwrap();
    let rig = frond_formats::rig_files::load_rig("grass").unwrap().rig;
    let take = write_take(&daemon.takes_dir, "sway", "grass", 150, true);
    let run_frond = |args: &[&str]| run_frond(&frond, &daemon, args);
    let (field, glb) = field_with_glb(&frond, &gltf, &daemon, &take, tmp.path(), ["2", "2", "1"], "1");
    let field_s = field.to_str().unwrap();
    let out = tmp.path().join("field.jsonl");
    let args = ["--plants", "4", "--frames", "200", "--record", "120", "--timeout", "60", "--out"];
    let mut args = os(&args);
    args.extend([out.as_os_str(), "--glb".as_ref(), glb.as_os_str()]);
    let (mut blender, port) = start_script(&py, "blender_field_check.py", &args, "port ");
    let collector = Collector::start(&daemon.socket_dir);
    run_frond(&["field", "start", "--take", "sway", "--field", field_s, "--plants", "4"]);
    let osc = start_osc(&daemon.socket_dir, &["--target", &format!("127.0.0.1:{port}")]);
    wait_receiver(&mut blender);
    let (_, poses) = collector.finish();
    stop_and_stderr(osc);

    let by_key: HashMap<(u16, u32), &Pose> =
        poses.iter().map(|p| ((p.element.get(), p.seq as u32), p)).collect();
    let frames = read_jsonl(&out);
    // The script stops at 200 lines or just past them: it writes one per plant a batch moved,
    // and a subscriber that joined a running field gets some plants before others while the
    // stream frames they read arrive (protocol 3), so a batch may move fewer than 4.
    assert!((200..204).contains(&frames.len()), "{} plant frames", frames.len());
    let mut armatures = std::collections::BTreeMap::new();
    let mut moving = 0;
    for f in &frames {
        let (element, seq) = (f["element"].as_u64().unwrap() as u16, f["seq"].as_u64().unwrap() as u32);
        let name = f["name"].as_str().unwrap();
        let pose =
            by_key.get(&(element, seq)).unwrap_or_else(|| panic!("{name} frame {seq} unknown to the SDK"));
        // plant<i> drives grass_<i>, whatever its element id.
        let i: usize = name.strip_prefix("plant").unwrap().parse().unwrap();
        let armature = f["armature"].as_str().unwrap();
        assert_eq!(armature.strip_prefix("grass_").map(|d| d.parse::<usize>().unwrap()), Some(i), "{name}");
        armatures.insert(armature.to_string(), ());
        let (heads, dirs) = blender_fk(pose.joints_deg, &rig);
        for j in 0..4 {
            close(&f64s(&f["heads"][j]), &heads[j], 1e-4, &format!("{name} head of joint {j} at {seq}"));
            close(&f64s(&f["dirs"][j]), &dirs[j], 1e-4, &format!("{name} direction of joint {j} at {seq}"));
        }
        if dirs[3][2] < 5f64.to_radians().cos() {
            moving += 1;
        }
    }
    assert_eq!(armatures.len(), 4, "every plant's armature driven: {armatures:?}");
    assert!(moving >= frames.len() / 4, "only {moving} of {} plant frames bend the plant", frames.len());
}

/// A live layer into Blender through frond-osc: the flower's second hand drives its `leaf`
/// element (announced as a layer); frond's add-on, with the flower GLB's armature picked, turns
/// both leaf instances (`leaf0_joint*`, `leaf1_joint*`) by each frame of that element. Every
/// reported leaf bone's rotation equals the daemon's pose of that sequence number in frond's
/// convention (the bone frames of frond-gltf's GLB are the joints' own).
#[test]
fn blender_addon_drives_the_leaves_from_a_live_layer() {
    let Some((frondd, py, gltf)) = blender_tools() else { return };
    let daemon = start_daemon_with(
        &frondd,
        &["--rig", "flower", "--hand", "stem=in-process", "--hand", "leaf=in-process,element=leaf"],
    );
    let tmp = tempfile::tempdir().unwrap();
    let glb = bake_rest_glb(&gltf, "flower", tmp.path());
    let out = tmp.path().join("layer.jsonl");
    let args = ["--frames", "100", "--timeout", "60", "--out"];
    let mut args = os(&args);
    args.extend([out.as_os_str(), "--glb".as_ref(), glb.as_os_str()]);
    let (mut blender, port) = start_script(&py, "blender_layer_check.py", &args, "port ");
    let collector = Collector::start(&daemon.socket_dir);
    let osc = start_osc(&daemon.socket_dir, &["--target", &format!("127.0.0.1:{port}")]);
    wait_receiver(&mut blender);
    let (hello, poses) = collector.finish();
    stop_and_stderr(osc);

    let layer =
        hello.elements.elements.iter().find(|e| e.name == "leaf").expect("the leaf element announced");
    let by_seq: HashMap<u32, &Pose> =
        poses.iter().filter(|p| p.element == layer.id).map(|p| (p.seq as u32, p)).collect();
    let frames = read_jsonl(&out);
    assert_eq!(frames.len(), 100);
    let mut bent = 0;
    for f in &frames {
        assert_eq!(f["element"].as_u64(), Some(u64::from(layer.id.get())));
        let seq = f["seq"].as_u64().unwrap() as u32;
        let pose = by_seq.get(&seq).unwrap_or_else(|| panic!("layer frame {seq} unknown to the SDK"));
        for (k, instance) in f["quats"].as_array().unwrap().iter().enumerate() {
            for (j, q) in instance.as_array().unwrap().iter().enumerate() {
                let [x, y, z, w] = frond_protocol::convention::joint_quat(pose.joints_deg[j]).map(f64::from);
                let got = f64s(q);
                // q and -q are one rotation.
                let sign = if (got[0] - w).abs() < (got[0] + w).abs() { 1.0 } else { -1.0 };
                close(
                    &got[1..],
                    &[sign * x, sign * y, sign * z],
                    1e-5,
                    &format!("leaf{k}_joint{j} at {seq}"),
                );
                assert!((got[0] - sign * w).abs() < 1e-5, "leaf{k}_joint{j} at {seq}: {got:?}");
            }
        }
        if pose.joints_deg.iter().flatten().any(|a| a.abs() > 1.0) {
            bent += 1;
        }
    }
    let most = by_seq.values().flat_map(|p| p.joints_deg.iter().flatten()).fold(0f32, |m, a| m.max(a.abs()));
    assert!(
        bent >= frames.len() / 4,
        "only {bent} of {} layer frames bend a leaf (largest angle {most})",
        frames.len()
    );
}
