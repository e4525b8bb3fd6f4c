//! End to end: `frondd --source in-process` (the built-in virtual glove) -> `frond-osc` -> a UDP
//! receiver. The OSC checks are done by an independent receiver written in Python on python-osc
//! (`osc_receiver.py`, venv at `tests/python/.venv`, made by `install-python.sh`); the values it
//! received are compared with what a `frond_sdk` subscriber got from the same daemon at the same
//! time.
//!
//! Needs `target/<profile>/frondd` (`cargo build --workspace --bins`) and, for the Python tests,
//! the venv. Missing either, a test prints why and passes as skipped, unless `CI=true` or
//! `FROND_REQUIRE_PYTHON=1`, where it fails.

use crate::support;

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use frond_osc::encode::{DEFAULT_HEIGHTS_M, unity_quat};
use frond_protocol::Pose;
use frond_protocol::convention::joint_quat;
use support::*;

#[test]
fn frond_namespace_delivers_every_frame_in_order_with_the_daemons_values() {
    let Some(frondd) = frondd() else { return skip("frondd is not built (cargo build --workspace --bins)") };
    let Some(py) = python() else {
        return skip("no python-osc venv at tests/python/.venv (run exporters/osc/tests/install-python.sh)");
    };
    let daemon = start_daemon(&frondd);
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("frames.jsonl");
    const FRAMES: usize = 1500;
    let (mut receiver, port) = start_receiver(&py, "frond", FRAMES, &out);
    let collector = Collector::start(&daemon.socket_dir);
    // A target that is down comes first: it must not hold up the live one.
    let dead = std::net::UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let live = format!("127.0.0.1:{port}");
    let osc = start_osc(&daemon.socket_dir, &["--target", &dead.to_string(), "--target", &live, "--stats"]);
    wait_receiver(&mut receiver);
    let (_, poses) = collector.finish();
    let stderr = stop_and_stderr(osc);

    let by_seq: HashMap<u32, &Pose> = poses.iter().map(|p| (p.seq as u32, p)).collect();
    let mut frames = read_jsonl(&out);
    // The names bundle: the daemon's rig and its joint names, as its hello says.
    let at = frames.iter().position(|f| f.get("names").is_some()).expect("a names bundle");
    assert_eq!(at, 0, "the names go out before the first frame");
    let names = frames.remove(at);
    assert_eq!(names["names"]["rig"], "grass", "{names}");
    assert_eq!(names["names"]["joints"], serde_json::json!(["root", "lower", "middle", "tip"]), "{names}");
    assert_eq!(frames.len(), FRAMES);
    for f in &frames {
        let seq = f["seq"].as_i64().unwrap() as u32;
        let pose = by_seq
            .get(&seq)
            .unwrap_or_else(|| panic!("OSC frame {seq} was never published to the SDK subscriber"));
        assert_eq!(f["t"].as_f64().unwrap(), pose.hand.t, "t of {seq}");
        let joints = f32s(&f["joints"]);
        assert_eq!(joints, pose.joints_deg.concat(), "joint angles of {seq}");
        assert_eq!(f["flags"].as_u64().unwrap(), u64::from(pose.flags.0), "flags of {seq}");
        for (i, q) in f["quats"].as_array().unwrap().iter().enumerate() {
            assert_eq!(f32s(q), joint_quat(pose.joints_deg[i]), "quaternion of joint {i} in {seq}");
        }
    }
    // The last stats line names the refused target with a non-zero count.
    let last = stderr.lines().rev().find(|l| l.starts_with("frond-osc stats:")).expect("a final stats line");
    let dead_part =
        last.split(" | ").find(|p| p.starts_with(&dead.to_string())).expect("dead target in stats");
    assert!(!dead_part.contains("refused=0 "), "refusals of the dead target are counted: {last}");
}

#[test]
fn vmc_mode_sends_the_rig_bones_with_unit_unity_rotations() {
    let Some(frondd) = frondd() else { return skip("frondd is not built (cargo build --workspace --bins)") };
    let Some(py) = python() else {
        return skip("no python-osc venv at tests/python/.venv (run exporters/osc/tests/install-python.sh)");
    };
    let daemon = start_daemon(&frondd);
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("vmc.jsonl");
    // Defaults: humanoid bone names, 60 Hz, timetags "immediately".
    let (mut receiver, port) = start_receiver(&py, "vmc", 150, &out);
    let collector = Collector::start(&daemon.socket_dir);
    let osc = start_osc(&daemon.socket_dir, &["--protocol", "vmc", "--target", &format!("127.0.0.1:{port}")]);
    wait_receiver(&mut receiver);
    let (_, poses) = collector.finish();
    stop_and_stderr(osc);

    // VMC carries T as f32 seconds of device time: match frames to the SDK's poses by it.
    let by_t: HashMap<u32, &Pose> = poses.iter().map(|p| ((p.hand.t as f32).to_bits(), p)).collect();
    let frames = read_jsonl(&out);
    let humanoid = ["Hips", "Spine", "Chest", "Neck"];
    let mut matched = 0;
    for f in &frames {
        assert_eq!(f["timetag"], serde_json::json!([0, 1]), "timetag 'immediately'");
        assert_eq!(f["datagrams"], 1, "one bundle per frame");
        let bones = f["bones"].as_object().unwrap();
        let mut names: Vec<&str> = bones.keys().map(String::as_str).collect();
        names.sort();
        assert_eq!(names, ["Chest", "Hips", "Neck", "Spine"], "Unity HumanBodyBones names by default");
        for (i, name) in humanoid.iter().enumerate() {
            let b = f32s(&bones[*name]);
            // Default rig heights (no --rig): local offsets straight up.
            let below = if i == 0 { 0.0 } else { DEFAULT_HEIGHTS_M[i - 1] };
            assert_eq!(b[..3], [0.0, DEFAULT_HEIGHTS_M[i] - below, 0.0], "position of {name}");
        }
        let t = f["t"].as_f64().unwrap() as f32;
        if let Some(pose) = by_t.get(&t.to_bits()) {
            matched += 1;
            for (i, name) in humanoid.iter().enumerate() {
                let rot = f32s(&bones[*name])[3..].to_vec();
                assert_eq!(rot, unity_quat(joint_quat(pose.joints_deg[i])), "rotation of {name} at t={t}");
            }
        }
    }
    assert!(
        matched >= frames.len() * 9 / 10,
        "only {matched} of {} VMC frames matched an SDK pose",
        frames.len()
    );
    // About 60 frames a second of device time, not the daemon's 1 kHz.
    let mut steps: Vec<f64> =
        frames.windows(2).map(|w| w[1]["t"].as_f64().unwrap() - w[0]["t"].as_f64().unwrap()).collect();
    steps.sort_by(f64::total_cmp);
    let median = steps[steps.len() / 2];
    assert!((0.014..0.020).contains(&median), "median step {median} s, expected about 1/60");
}

/// `--rate` through the real pipeline: strictly increasing sequence numbers (no frame sent
/// twice), at most the requested rate, each one a real daemon frame. Needs no Python.
#[test]
fn rate_resampling_never_repeats_a_frame() {
    let Some(frondd) = frondd() else { return skip("frondd is not built (cargo build --workspace --bins)") };
    let daemon = start_daemon(&frondd);
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let collector = Collector::start(&daemon.socket_dir);
    let target = sock.local_addr().unwrap().to_string();
    let osc = start_osc(&daemon.socket_dir, &["--target", &target, "--rate", "50"]);
    let started = Instant::now();
    let mut seqs = Vec::new();
    let mut buf = [0u8; 1500];
    while started.elapsed() < Duration::from_millis(1500) {
        let Ok(n) = sock.recv(&mut buf) else { continue };
        let (_, rosc::OscPacket::Bundle(b)) = rosc::decoder::decode_udp(&buf[..n]).unwrap() else {
            panic!("bundle expected")
        };
        let rosc::OscPacket::Message(m) = &b.content[0] else { panic!("message expected") };
        if m.addr == "/frond/rig" {
            continue; // the names bundle
        }
        let rosc::OscType::Int(seq) = m.args[0] else { panic!("int seq expected") };
        let joints: Vec<f32> = m.args[2..14]
            .iter()
            .map(|a| if let rosc::OscType::Float(f) = a { *f } else { panic!() })
            .collect();
        seqs.push((seq as u32, joints));
    }
    let elapsed = started.elapsed().as_secs_f64();
    let (_, poses) = collector.finish();
    stop_and_stderr(osc);
    assert!(seqs.len() >= 10, "only {} frames at 50 Hz in {elapsed:.1} s", seqs.len());
    assert!(
        (seqs.len() as f64) <= 50.0 * elapsed + 3.0,
        "{} frames in {elapsed:.2} s exceeds 50 Hz",
        seqs.len()
    );
    assert!(seqs.windows(2).all(|w| w[1].0 > w[0].0), "sequence numbers strictly increase");
    let by_seq: HashMap<u32, &Pose> = poses.iter().map(|p| (p.seq as u32, p)).collect();
    for (seq, joints) in &seqs {
        if let Some(p) = by_seq.get(seq) {
            assert_eq!(joints, &p.joints_deg.concat(), "frame {seq} is the daemon's frame");
        }
    }
}

/// `frond-osc --bench` runs and reports for 1 and 4 targets (the numbers are for issue 9's bench,
/// not asserted here).
#[test]
fn bench_reports_latency_for_one_and_four_targets() {
    let Some(frondd) = frondd() else { return skip("frondd is not built (cargo build --workspace --bins)") };
    let daemon = start_daemon(&frondd);
    let out = Command::new(frond_osc())
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .args(["--bench", "--bench-seconds", "0.5"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<serde_json::Value> =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 2);
    for (line, targets) in lines.iter().zip([1, 4]) {
        assert_eq!(line["targets"], targets);
        assert!(line["samples"].as_u64().unwrap() > 0, "{line}");
        assert!(line["p50_us"].as_f64().unwrap() <= line["p99_us"].as_f64().unwrap(), "{line}");
    }
}

/// A third-party VMC receiver (vmcp from PyPI, which parses bones as Unity HumanBodyBones as VMC
/// marionettes do) takes frond-osc's default VMC stream as it is: every frame's four humanoid
/// bones with the daemon's rotations in Unity's frame, the root, "loaded, calibrated, tracking".
/// With the daemon's own joint names (`--vmc-bones joints`, `root` among them) it refuses them.
#[test]
fn a_third_party_vmc_receiver_accepts_the_default_stream() {
    let Some(frondd) = frondd() else { return skip("frondd is not built (cargo build --workspace --bins)") };
    let Some(py) = python_with("vmcp, osc4py3") else {
        return skip("no vmcp in tests/python/.venv (run exporters/osc/tests/install-python.sh)");
    };
    let daemon = start_daemon(&frondd);
    let tmp = tempfile::tempdir().unwrap();
    let run = |extra: &[&str], count: usize, out: &Path| {
        let port = std::net::UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vmcp_receiver.py");
        let mut child = Command::new(&py)
            .arg(script)
            .args([&port.to_string(), &count.to_string()])
            .arg(out)
            .arg("30")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        assert_eq!(line.trim(), "listening");
        let mut args = vec!["--protocol", "vmc"];
        let target = format!("127.0.0.1:{port}");
        args.extend(["--target", &target]);
        args.extend(extra);
        let osc = start_osc(&daemon.socket_dir, &args);
        let status = child.wait().unwrap();
        let mut err = String::new();
        child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
        stop_and_stderr(osc);
        (status, err)
    };
    let collector = Collector::start(&daemon.socket_dir);
    let out = tmp.path().join("vmcp.jsonl");
    let (status, err) = run(&[], 60, &out);
    assert!(status.success(), "vmcp: {err}");
    let (_, poses) = collector.finish();
    let by_t: HashMap<u32, &Pose> = poses.iter().map(|p| ((p.hand.t as f32).to_bits(), p)).collect();
    let frames = read_jsonl(&out);
    assert_eq!(frames.len(), 60);
    let mut matched = 0;
    for f in &frames {
        let bones = f["bones"].as_object().unwrap();
        let mut names: Vec<&str> = bones.keys().map(String::as_str).collect();
        names.sort();
        assert_eq!(names, ["Chest", "Hips", "Neck", "Spine"], "{f}");
        assert_eq!(f["state"], serde_json::json!([1, 3, 0, 1]), "loaded, calibrated, normal, tracking");
        if let Some(pose) = by_t.get(&(f["t"].as_f64().unwrap() as f32).to_bits()) {
            matched += 1;
            for (i, name) in ["Hips", "Spine", "Chest", "Neck"].iter().enumerate() {
                let rot = f32s(&bones[*name])[3..].to_vec();
                assert_eq!(rot, unity_quat(joint_quat(pose.joints_deg[i])), "{name}");
            }
        }
    }
    assert!(matched >= frames.len() * 9 / 10, "{matched} of {} frames matched a daemon pose", frames.len());
    // The daemon's own names are no VMC bones: a strict receiver refuses them.
    let (status, err) = run(&["--vmc-bones", "joints"], 5, &tmp.path().join("joints.jsonl"));
    assert_eq!(status.code(), Some(1), "vmcp accepted the joint names: {err}");
    assert!(err.contains("BoneTransformEvent"), "{err}");
}
