//! A live field of ten thousand plants (protocol 3; seed 000, section 6.2-6.3) through the real
//! daemon and `frond`: what the daemon publishes per field frame does not grow with the field,
//! the SDK evaluates every plant, the announced plants still arrive as poses, and a key
//! changes the controls the frames carry.

use std::io::Read;
use std::os::unix::net::UnixStream;
use std::time::{Duration, Instant};

use frond_e2e::Daemon;
use frond_motion::field::{FieldParams, make_field};
use frond_protocol::field::FieldMessage;
use frond_protocol::{ElementKind, ServerMessage, decode_frame};
use frond_sdk::{Event, Subscriber};

/// A field.json of `rows x cols` plants over take `take` without its plants (readers make them
/// from the parameters, so it fits in a control request whatever its size).
pub(crate) fn compact_field(daemon: &Daemon, take: &str, rows: usize, cols: usize) -> std::path::PathBuf {
    let p =
        FieldParams { rows, cols, cell_m: 0.2, speed_m_s: 1.5, direction_deg: 0.0, density: 1.0, seed: 3 };
    let field = make_field(&p, take, 60, 30.0).unwrap();
    let mut json: serde_json::Value = serde_json::to_value(&field).unwrap();
    json.as_object_mut().unwrap().remove("plants");
    let path = daemon.takes_dir.with_file_name(format!("field-{rows}x{cols}.json"));
    std::fs::write(&path, json.to_string()).unwrap();
    path
}

/// A daemon on the in-process glove with the grass rig and a take `sway` of it, `record`
/// long.
pub(crate) fn daemon_with_sway(dir: &std::path::Path, record: Duration) -> Daemon {
    let daemon = Daemon::start(dir, &["--source", "in-process", "--rig", "grass"]);
    daemon.frond_ok(&["record", "start", "sway"]);
    std::thread::sleep(record);
    daemon.frond_ok(&["record", "stop"]);
    daemon
}

/// The largest field frame (encoded bytes) and how many arrived in `window` on a raw socket.
fn field_frames(daemon: &Daemon, window: Duration) -> (usize, usize) {
    let mut s = UnixStream::connect(daemon.socket_dir.join("poses.sock")).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let (mut buf, mut chunk) = (Vec::new(), [0u8; 65536]);
    let (mut largest, mut count) = (0, 0);
    let start = Instant::now();
    while start.elapsed() < window {
        if let Ok(n) = s.read(&mut chunk) {
            buf.extend_from_slice(&chunk[..n]);
        }
        while let Ok(Some((msg, used))) = decode_frame::<ServerMessage>(&buf) {
            if let ServerMessage::Field(FieldMessage::Frame(_)) = msg {
                largest = largest.max(used);
                count += 1;
            }
            buf.drain(..used);
        }
    }
    (largest, count)
}

#[test]
fn ten_thousand_plants_live_cost_what_twelve_do() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = daemon_with_sway(dir.path(), Duration::from_secs(2));

    // A field of rows x cols plants started (4 announced), and its field frames over 0.8 s.
    let frames_of = |rows: usize, cols: usize| {
        let field = compact_field(&daemon, "sway", rows, cols);
        let field = field.to_str().unwrap();
        daemon.frond_ok(&["field", "start", "--take", "sway", "--field", field, "--plants", "4"]);
        field_frames(&daemon, Duration::from_millis(800))
    };
    let (small_bytes, small_count) = frames_of(3, 4);
    let (big_bytes, big_count) = frames_of(100, 100);
    // 60 field frames a second either way, each the same size within a few bytes (the numbers
    // in it), under 2 KiB: nothing per plant.
    assert!(small_count >= 30 && big_count >= 30, "{small_count} and {big_count} field frames in 0.8 s");
    assert!(big_bytes < 2048 && big_bytes <= small_bytes + 64, "{big_bytes} bytes vs {small_bytes}");

    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let announced: Vec<_> = sub.elements().of_kind(ElementKind::FieldPlant).map(|e| e.id).collect();
    assert_eq!(announced.len(), 4, "{:?}", sub.elements());
    let (mut plant_poses, mut evaluated, mut events) = (0, 0, 0u64);
    let deadline = Instant::now() + Duration::from_secs(15);
    while Instant::now() < deadline && (plant_poses < 40 || evaluated < 10_000) {
        let Event::Pose(p) = sub.next_event().unwrap() else { continue };
        if announced.contains(&p.element) {
            plant_poses += 1;
        }
        events += 1;
        // Every plant, now and then: once the history has arrived, all of them.
        let Some(field) = sub.fields().by_source("field").filter(|_| events % 500 == 0) else { continue };
        assert_eq!(field.plants(), 10_000);
        let tau = field.tau_s();
        let finite = |j: [[f32; 3]; 4]| j.iter().flatten().all(|x| x.is_finite());
        evaluated = (0..10_000).filter(|&i| field.plant_pose(i, tau).is_some_and(finite)).count();
    }
    assert!(plant_poses >= 40, "{plant_poses} poses of announced plants");
    assert_eq!(evaluated, 10_000, "plants the SDK evaluates");

    // A key changes the controls the field frames carry.
    daemon.frond_ok(&["field", "key", "left"]);
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        sub.next_event().unwrap();
        let c = sub.fields().by_source("field").map(|f| f.state().controls().direction_deg);
        if c == Some(180.0) {
            break;
        }
        assert!(Instant::now() < deadline, "the key did not reach the field frames: {c:?}");
    }
    daemon.frond_ok(&["field", "stop"]);
}

/// A meadow from the command line: `frond take field` of 10,000 plants is too large for `frond
/// field start`, which says to write it with `--compact`; the compact file starts the field.
#[test]
fn a_meadow_too_large_to_start_says_compact_and_the_compact_file_starts() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    daemon.frond_ok(&["record", "start", "sway"]);
    std::thread::sleep(Duration::from_millis(1500));
    daemon.frond_ok(&["record", "stop"]);
    let field = |extra: &[&str], out: &str| {
        let mut args = vec!["take", "field", "sway", "--rows", "100", "--cols", "100", "--cell", "0.2"];
        args.extend(["--speed", "1.5", "-o", out]);
        args.extend(extra);
        daemon.frond_ok(&args)
    };
    let big = dir.path().join("meadow.json");
    let small = dir.path().join("meadow-compact.json");
    field(&[], big.to_str().unwrap());
    let said = field(&["--compact"], small.to_str().unwrap());
    assert!(said.contains("(10000 plants, left out"), "{said}");
    let start = |file: &std::path::Path| {
        daemon
            .frond()
            .args(["field", "start", "--take", "sway", "--field", file.to_str().unwrap()])
            .output()
            .unwrap()
    };
    let out = start(&big);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("frond take field --compact"), "{err}");
    let out = start(&small);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(daemon.status().modes.iter().any(|m| m.contains("field")), "{:?}", daemon.status().modes);
}
