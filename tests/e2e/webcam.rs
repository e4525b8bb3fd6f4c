//! Issue 47: a webcam is a hand. The real model (MediaPipe Hands 0.10.21 through frond-hands,
//! installed by daemon/device/tests/install-webcam.sh) runs offline on a real photograph of a
//! hand (fingerpose 0.1.0's `nocurl.jpg`, MIT) and on an empty scene; the landmarks it finds
//! drive `frondd --source webcam:FILE` end to end, and the daemon's hand angles and poses are
//! those a second implementation in this test computes from the same landmarks, mapped by
//! `frond map`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use frond_e2e::{Daemon, repo_root, wait_for};
use frond_protocol::PoseFlags;
use serde_json::Value;

pub(crate) fn hands_venv() -> PathBuf {
    repo_root().join("tests/python/.venv-hands")
}

/// The installed helper, or a panic saying how to install it.
pub(crate) fn helper() -> PathBuf {
    let helper = hands_venv().join("bin/frond-hands");
    assert!(helper.exists(), "no {} (run daemon/device/tests/install-webcam.sh)", helper.display());
    helper
}

pub(crate) fn photo() -> PathBuf {
    hands_venv().join("fingerpose/package/assets/nocurl.jpg")
}

/// An empty scene: the wall above the hand in the photograph (its top 90 rows), scaled to
/// 640x480 by OpenCV.
fn empty_scene(dir: &Path) -> PathBuf {
    let out = dir.join("wall.png");
    let code = format!(
        "import cv2; im = cv2.imread({:?}); cv2.imwrite({:?}, cv2.resize(im[:90], (640, 480)))",
        photo().to_str().unwrap(),
        out.to_str().unwrap()
    );
    let ok = Command::new(hands_venv().join("bin/python")).args(["-c", &code]).status().unwrap();
    assert!(ok.success());
    out
}

/// Runs the helper on `file` for `frames` frames without a network (a network namespace of its
/// own: a model it tried to download would not come), every frame found anew; its lines.
pub(crate) fn run_offline(file: &Path, frames: u32) -> Vec<Value> {
    let out = Command::new("unshare")
        .args(["--net", "--"])
        .arg(helper())
        .args(["--static", "--fps", "20", "--frames", &frames.to_string(), "--file"])
        .arg(file)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}\n{}", String::from_utf8_lossy(&out.stderr));
    text.lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

/// The hand sample of 21 world landmarks (selfie view: +x the user's right, +y down, +z away
/// from the camera), written here from the documented definitions (docs/hand-sources.md):
/// pitch `atan2(d.z, -d.y)`, yaw `atan2(d.x, -d.y)` of the palm's direction `d` (wrist to
/// middle knuckle), roll `atan2(n.x, -n.z)` of the palm's normal `n` (out of the palm), the
/// thumb's bends the angles between the successive segments wrist, CMC, MCP, IP, tip.
pub(crate) fn expected_sample(world: &[f64], left: bool) -> [f64; 6] {
    let p = |i: usize| [world[3 * i], world[3 * i + 1], world[3 * i + 2]];
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let norm = |a: [f64; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|c| c / l)
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    };
    let d = norm(sub(p(9), p(0)));
    let across = sub(p(5), p(17));
    let n = norm(if left { cross(across, d) } else { cross(d, across) });
    let bend = |a: [f64; 3], b: [f64; 3]| {
        let (a, b) = (norm(a), norm(b));
        (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0).acos().to_degrees()
    };
    let seg = |i: usize| sub(p(i + 1), p(i));
    [
        d[2].atan2(-d[1]).to_degrees(),
        d[0].atan2(-d[1]).to_degrees(),
        n[0].atan2(-n[2]).to_degrees(),
        bend(seg(0), seg(1)),
        bend(seg(1), seg(2)),
        bend(seg(2), seg(3)),
    ]
}

/// The first hand's 63 world landmarks in a helper's frame line.
pub(crate) fn world_of(frame: &Value) -> Vec<f64> {
    frame["hands"][0]["world"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
}

/// Has frondd start the helper (`$FROND_HANDS`) through a launcher in `dir` that finds the
/// hands anew each frame (`--static`), so the daemon's landmarks are [`run_offline`]'s.
pub(crate) fn use_static_helper(dir: &Path) {
    let launcher = dir.join("frond-hands");
    std::fs::write(&launcher, format!("#!/bin/sh\nexec {:?} --static \"$@\"\n", helper().to_str().unwrap()))
        .unwrap();
    std::process::Command::new("chmod").arg("+x").arg(&launcher).status().unwrap();
    // SAFETY: nextest runs each test in a process of its own, and no thread of this one reads
    // the environment while it is set, before the daemon is started.
    unsafe { std::env::set_var("FROND_HANDS", &launcher) };
}

#[test]
fn the_model_finds_a_real_hand_offline_and_none_in_an_empty_scene() {
    let lines = run_offline(&photo(), 3);
    assert_eq!(lines[0]["hello"], "frond-hands", "{}", lines[0]);
    assert!(lines[0]["model"].as_str().unwrap().starts_with("mediapipe 0.10.21"), "{}", lines[0]);
    let frames = &lines[1..];
    assert_eq!(frames.len(), 3);
    for f in frames {
        let hands = f["hands"].as_array().unwrap();
        assert_eq!(hands.len(), 1, "one hand in the photograph: {f}");
        // A left hand held up, palm to the camera (the photographer's phone in the other).
        assert_eq!(hands[0]["side"], "left");
        assert_eq!(hands[0]["world"].as_array().unwrap().len(), 63);
        // Found anew each frame, the same image gives the same landmarks.
        assert_eq!(hands[0]["world"], frames[0]["hands"][0]["world"]);
    }
    let dir = tempfile::tempdir().unwrap();
    for f in &run_offline(&empty_scene(dir.path()), 3)[1..] {
        assert_eq!(f["hands"], serde_json::json!([]), "no hand on a bare wall: {f}");
    }
}

#[test]
fn a_hand_in_front_of_the_camera_drives_the_daemon_and_an_empty_scene_is_no_hand() {
    let found = run_offline(&photo(), 1);
    let want = expected_sample(&world_of(&found[1]), true);
    // The index finger points up, palm to the camera: an upright wrist.
    assert!(want[0].abs() < 60.0 && want[1].abs() < 45.0, "{want:?}");

    let dir = tempfile::tempdir().unwrap();
    use_static_helper(dir.path());
    let source = format!("webcam:{}?hand=left", photo().to_str().unwrap());
    let daemon = Daemon::start(dir.path(), &["--source", &source, "--rig", "flower", "--filter", "none"]);
    assert!(
        wait_for(Duration::from_secs(30), || daemon.status().source.reports >= 5),
        "{:?}",
        daemon.status().source
    );
    let status = daemon.status().source;
    assert_eq!((status.kind.as_str(), status.rejected), ("webcam", 0), "{status:?}");
    // Status says the camera's rate and latency (the clip plays at 30 frames a second).
    let camera = status.camera.expect("camera figures in status");
    assert!(camera.frames >= 5 && camera.empty_frames == 0 && camera.helper_starts == 1, "{camera:?}");
    assert!(camera.latency_ms > 0.0 && camera.latency_ms < 2000.0 && camera.model_ms > 0.0, "{camera:?}");
    let text = daemon.frond_ok(&["status"]);
    assert!(text.contains("; camera ") && text.contains("frames without a hand"), "{text}");
    let mut sub = frond_sdk::Subscriber::connect(&daemon.socket_dir).unwrap();
    let fresh = frond_e2e::fresh_poses(&mut sub, 3, Duration::from_secs(10));
    assert_eq!(fresh.len(), 3);
    let sample = format!(
        "{{\"t\":0,\"wrist\":[{},{},{}],\"thumb\":[{},{},{}]}}\n",
        want[0], want[1], want[2], want[3], want[4], want[5]
    );
    let mapped = frond_e2e::frond_map(&["--filter", "none", "--rig", "flower"], &sample);
    assert!(mapped.status.success(), "{}", String::from_utf8_lossy(&mapped.stderr));
    let mapped: Value = serde_json::from_slice(&mapped.stdout).unwrap();
    for pose in &fresh {
        let got = pose.hand.wrist_deg.iter().chain(&pose.hand.thumb_deg);
        for (g, w) in got.zip(want) {
            assert!((f64::from(*g) - w).abs() < 0.01, "daemon {:?} != expected {want:?}", pose.hand);
        }
        for (j, joint) in pose.joints_deg.iter().enumerate() {
            for (k, g) in joint.iter().enumerate() {
                let w = mapped["joints"][j][k].as_f64().unwrap();
                assert!(
                    (f64::from(*g) - w).abs() < 0.01,
                    "joint {j}: {:?} != frond map's {mapped}",
                    pose.joints_deg
                );
            }
        }
    }
    drop(sub);
    drop(daemon);

    // A bare wall: the helper runs, no hand is found, the hand is lost.
    let wall = empty_scene(dir.path());
    let empty = tempfile::tempdir().unwrap();
    let source = format!("webcam:{}?hand=left", wall.to_str().unwrap());
    let daemon = Daemon::start(empty.path(), &["--source", &source, "--rig", "flower"]);
    let mut sub = frond_sdk::Subscriber::connect(&daemon.socket_dir).unwrap();
    assert!(
        wait_for(Duration::from_secs(20), || {
            daemon.status().source.camera.is_some_and(|c| c.empty_frames >= 5 && c.frames == c.empty_frames)
        }),
        "the helper's frames, none with a hand: {:?}",
        daemon.status().source
    );
    assert!(
        wait_for(Duration::from_secs(5), || {
            matches!(sub.next_event(), Ok(frond_sdk::Event::Pose(p)) if p.flags.contains(PoseFlags::DEVICE_LOST))
        }),
        "frames flagged device_lost"
    );
    let status = daemon.status().source;
    assert_eq!((status.reports, status.rejected), (0, 0), "{status:?}");
}

/// A clip that shows the hand for half a second, then the bare wall for half a second (MJPG,
/// 30 frames a second, made by OpenCV from the photograph).
fn hand_then_wall(dir: &Path) -> PathBuf {
    let out = dir.join("hand-then-wall.avi");
    let code = format!(
        "import cv2\n\
         hand = cv2.resize(cv2.imread({p:?}), (480, 640))\n\
         wall = cv2.resize(hand[:90], (480, 640))\n\
         w = cv2.VideoWriter({o:?}, cv2.VideoWriter_fourcc(*'MJPG'), 30, (480, 640))\n\
         for frame in [hand] * 15 + [wall] * 15:\n    w.write(frame)\n\
         w.release()\n",
        p = photo().to_str().unwrap(),
        o = out.to_str().unwrap()
    );
    let ok = Command::new(hands_venv().join("bin/python")).args(["-c", &code]).status().unwrap();
    assert!(ok.success());
    out
}

/// The helpers running for `input` (read from /proc).
fn helpers_for(input: &Path) -> usize {
    let want = input.to_str().unwrap();
    std::fs::read_dir("/proc")
        .unwrap()
        .filter_map(|e| std::fs::read(e.ok()?.path().join("cmdline")).ok())
        .filter(|c| {
            let args: Vec<&[u8]> = c.split(|&b| b == 0).collect();
            args.iter().any(|a| a.ends_with(b"frond_hands.py")) && args.contains(&want.as_bytes())
        })
        .count()
}

#[test]
fn both_hands_of_a_camera_share_its_helper_and_a_hand_that_leaves_comes_back() {
    helper();
    let dir = tempfile::tempdir().unwrap();
    let clip = hand_then_wall(dir.path());
    // SAFETY: nextest runs each test in a process of its own, and no thread of this one reads
    // the environment while it is set, before the daemon is started.
    unsafe { std::env::set_var("FROND_HANDS", helper()) };
    let left = format!("left=webcam:{}?hand=left", clip.to_str().unwrap());
    let right = format!("right=webcam:{}?hand=right,element=leaf", clip.to_str().unwrap());
    let daemon = Daemon::start(dir.path(), &["--rig", "flower", "--hand", &left, "--hand", &right]);
    assert!(
        wait_for(Duration::from_secs(30), || daemon.status().hands[0].source.reports >= 10),
        "{:?}",
        daemon.status()
    );
    assert_eq!(helpers_for(&clip), 1, "one helper for the camera's two hands");
    // The left hand comes and goes with the clip: fresh poses, then none (held, lost), then
    // fresh again. The right hand is never in it.
    let mut sub = frond_sdk::Subscriber::connect(&daemon.socket_dir).unwrap();
    let (mut seen_gone, mut came_back) = (false, false);
    let global = daemon.status().hands[0].element;
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while !came_back && std::time::Instant::now() < deadline {
        if let frond_sdk::Event::Pose(p) = sub.next_event().unwrap()
            && p.element == global
        {
            let gone = p.flags.contains(PoseFlags::HELD) || p.flags.contains(PoseFlags::DEVICE_LOST);
            came_back |= seen_gone && !gone;
            seen_gone |= p.flags.contains(PoseFlags::DEVICE_LOST);
        }
    }
    assert!(came_back, "the hand was lost (device_lost: {seen_gone}) and did not come back");
    let status = daemon.status();
    assert!(status.hands[0].lost_events >= 1, "{:?}", status.hands[0]);
    assert_eq!((status.hands[1].source.kind.as_str(), status.hands[1].source.reports), ("webcam", 0));
    drop(sub);
    drop(daemon);
    assert!(wait_for(Duration::from_secs(5), || helpers_for(&clip) == 0), "the helper ends with the daemon");
}
