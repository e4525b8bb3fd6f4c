//! `frond-gltf live` against a fake daemon speaking the real pose protocol: the file is written
//! when recording stops, with exactly the recorded frames; on Ctrl-C (SIGINT) the frames already
//! sent are kept; with no daemon, a clear error.

use crate::common;

use std::io::Write;
use std::os::unix::net::UnixListener;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use frond_protocol::frame::FrameBuf;
use frond_protocol::{ElementId, HandWire, Hello, Pose, PoseFlags, ServerMessage};

fn hello() -> ServerMessage {
    ServerMessage::Hello(Hello {
        protocol_version: frond_protocol::PROTOCOL_VERSION,
        daemon_version: "0.1.0".to_string(),
        rig_name: "grass".to_string(),
        joint_names: vec!["root".into(), "lower".into(), "middle".into(), "tip".into()],
        tick_rate_hz: 100,
        elements: Default::default(),
        next_seq: 0,
    })
}

fn pose(seq: u64, recording: bool) -> ServerMessage {
    let mut flags = PoseFlags::default();
    flags.set(PoseFlags::RECORDING, recording);
    let t = seq as f64 / 100.0;
    ServerMessage::Pose(Pose {
        seq,
        device_time_us: seq * 10_000,
        host_monotonic_ns: seq * 10_000_000,
        flags,
        element: ElementId::GLOBAL,
        joints_deg: [[seq as f32, 0.0, 0.0]; 4],
        hand: HandWire { t, ..HandWire::default() },
    })
}

fn spawn_live(socket_dir: &Path, out: &Path) -> Child {
    Command::new(bin())
        .args(["live", "--rig", "grass", "--fps", "100", "-o", out.to_str().unwrap(), "--socket-dir"])
        .arg(socket_dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn wait(child: Child, limit: Duration) -> std::process::Output {
    let start = Instant::now();
    let mut child = child;
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            panic!("frond-gltf live did not finish in {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// Keys of the first channel: (times, pitch of joint 0 recovered from the quaternion).
fn pitches(out: &Path) -> (Vec<f32>, Vec<f32>) {
    let (doc, buffers) = load(out);
    let anim = doc.animations().next().unwrap();
    let ch = anim.channels().next().unwrap();
    let r = ch.reader(|b| Some(&buffers[b.index()]));
    let times: Vec<f32> = r.read_inputs().unwrap().collect();
    let gltf::animation::util::ReadOutputs::Rotations(rot) = r.read_outputs().unwrap() else { panic!() };
    let pitch = rot.into_f32().map(|q| 2.0 * q[0].atan2(q[3]).to_degrees()).collect();
    (times, pitch)
}

#[test]
fn writes_the_recorded_frames_when_recording_stops() {
    let dir = tempfile::tempdir().unwrap();
    let listener = UnixListener::bind(dir.path().join("poses.sock")).unwrap();
    let out = dir.path().join("live.glb");
    let child = spawn_live(dir.path(), &out);
    let (mut conn, _) = listener.accept().unwrap();
    let mut buf = FrameBuf::default();
    conn.write_all(buf.encode(&hello())).unwrap();
    // 5 idle frames, 20 recorded (seq 5..=24), then idle again.
    for seq in 0..40 {
        conn.write_all(buf.encode(&pose(seq, (5..25).contains(&seq)))).unwrap();
    }
    let o = wait(child, Duration::from_secs(20));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("recording stopped after 20 frames"), "{stderr}");
    let (times, pitch) = pitches(&out);
    assert_eq!(times.len(), 20);
    assert_eq!(times[0], 0.0);
    for (k, p) in pitch.iter().enumerate() {
        assert!((p - (5 + k) as f32).abs() < 1e-3, "key {k}: {p}");
    }
    let (doc, _) = load(&out);
    assert_eq!(doc.animations().next().unwrap().name(), Some("live"));
}

#[test]
fn ctrl_c_keeps_the_frames_already_sent() {
    let dir = tempfile::tempdir().unwrap();
    let listener = UnixListener::bind(dir.path().join("poses.sock")).unwrap();
    let out = dir.path().join("cut.glb");
    let child = spawn_live(dir.path(), &out);
    let (mut conn, _) = listener.accept().unwrap();
    let mut buf = FrameBuf::default();
    conn.write_all(buf.encode(&hello())).unwrap();
    for seq in 0..30 {
        conn.write_all(buf.encode(&pose(seq, true))).unwrap();
    }
    // Recording goes on (no stop frame); the operator presses Ctrl-C.
    std::thread::sleep(Duration::from_millis(500));
    // SAFETY: kill(2) with the child's pid and a valid signal number has no memory effects.
    let rc = unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    assert_eq!(rc, 0);
    let o = wait(child, Duration::from_secs(20));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (times, pitch) = pitches(&out);
    assert_eq!(times.len(), 30, "{times:?}");
    assert!((pitch[29] - 29.0).abs() < 1e-3);
    drop(conn);
}

#[test]
fn no_daemon_is_a_clear_error_and_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.glb");
    let o = wait(spawn_live(dir.path(), &out), Duration::from_secs(20));
    assert_eq!(o.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("frond-gltf: error: live capture from"), "{stderr}");
    assert!(!out.exists());
}
