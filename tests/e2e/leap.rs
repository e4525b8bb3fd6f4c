//! Leap Motion input (issue 18): `frondd --source leap://...` against a fake tracking service, a
//! WebSocket server on `/v6.json` that replays v6 frames as Ultraleap's open-source tracking
//! WebSocket server writes them, of hand poses known here. The daemon's poses must equal
//! `frond map` of the hand samples those poses are (worked out by hand from the geometry the
//! frames were built from); it reconnects when the service restarts, and holds (then flags the
//! device lost) while the hand is out of view.

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::process::Stdio;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use frond_e2e::Daemon;
use frond_protocol::PoseFlags;
use serde_json::{Value, json};

/// A hand pose as frond's hand sample: wrist pitch, yaw, roll and thumb bends, degrees.
#[derive(Clone, Copy)]
struct Known {
    t: f64,
    wrist: [f64; 3],
    thumb: [f64; 3],
}

fn norm(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / n)
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// A v6 frame (every field the Ultraleap server writes) whose right hand is `k`: the palm
/// direction `(tan yaw, tan pitch, -1)` normalised has Leap's pitch `atan2(d.y, -d.z)` and yaw
/// `atan2(d.x, -d.z)`; the normal `(sin roll, -cos roll, z)` made perpendicular to it has roll
/// `atan2(n.x, -n.y)`; the thumb's bones turn about the palm's side axis by the bend angles, one
/// after the other, so the angles between successive bone directions are the bends.
fn frame(id: i64, k: Option<Known>) -> String {
    let Some(k) = k else {
        return json!({"currentFrameRate": 110.0, "devices": [], "id": id, "timestamp": id * 9000,
                      "hands": [], "pointables": []})
        .to_string();
    };
    let [p, y, r] = k.wrist.map(f64::to_radians);
    let d = norm([y.tan(), p.tan(), -1.0]);
    let (nx, ny) = (r.sin(), -r.cos());
    let n = norm([nx, ny, -(nx * d[0] + ny * d[1]) / d[2]]);
    let side = norm(cross(d, n));
    // Rodrigues: `v` turned about unit `axis` by `a` radians.
    let turn = |v: [f64; 3], a: f64| {
        let (s, c) = a.sin_cos();
        let kxv = cross(side, v);
        let kv: f64 = (0..3).map(|i| side[i] * v[i]).sum();
        std::array::from_fn::<f64, 3, _>(|i| v[i] * c + kxv[i] * s + side[i] * kv * (1.0 - c))
    };
    let mut dir = d;
    let mut bases = Vec::new();
    for bend in [0.0, k.thumb[0], k.thumb[1], k.thumb[2]] {
        dir = turn(dir, bend.to_radians());
        let z = dir.map(|c| -c);
        let x = side;
        bases.push(vec![x, cross(z, x), z]);
    }
    let ts = (k.t * 1e6).round() as i64;
    let hand = json!({"armBasis": [[1,0,0],[0,1,0],[0,0,1]], "armWidth": 60.0, "confidence": 1.0,
        "direction": d, "elbow": [0.0, 150.0, 250.0], "grabAngle": 0.2, "grabStrength": 0.0, "id": 12,
        "palmNormal": n, "palmPosition": [10.0, 200.0, 5.0], "palmVelocity": [0.0, 0.0, 0.0],
        "palmWidth": 80.0, "pinchDistance": 40.0, "pinchStrength": 0.0, "timeVisible": k.t,
        "type": "right", "wrist": [10.0, 190.0, 60.0]});
    let thumb = json!({"bases": bases, "btipPosition": [0,0,0], "carpPosition": [0,0,0],
        "dipPosition": [0,0,0], "mcpPosition": [0,0,0], "pipPosition": [0,0,0], "tipPosition": [0,0,0],
        "direction": dir, "extended": true, "handId": 12, "id": 120, "length": 50.0, "type": 0, "width": 18.0});
    let identity = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    let index = json!({"bases": [identity, identity, identity, identity], "btipPosition": [0,0,0],
        "carpPosition": [0,0,0], "dipPosition": [0,0,0], "mcpPosition": [0,0,0], "pipPosition": [0,0,0],
        "tipPosition": [0,0,0], "direction": [0,0,-1], "extended": true, "handId": 12, "id": 121,
        "length": 60.0, "type": 1, "width": 17.0});
    json!({"currentFrameRate": 110.0, "devices": [], "id": id, "timestamp": ts, "hands": [hand],
           "pointables": [thumb, index]})
    .to_string()
}

/// The fake service: accepts connections on `listener`; each gets `{"version": 6}`, then the
/// frames of `script` (taken as they are sent), 5 ms apart, then frames without hands.
fn serve(
    listener: TcpListener,
    script: Arc<Mutex<Vec<String>>>,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    listener.set_nonblocking(true).unwrap();
    std::thread::spawn(move || {
        while !stop.load(Ordering::Relaxed) {
            let Ok((stream, _)) = listener.accept() else {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            };
            stream.set_nonblocking(false).unwrap();
            stream.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
            let Ok(mut ws) = tungstenite::accept(stream) else { continue };
            let _ = ws.send(tungstenite::Message::text(r#"{"serviceVersion":"5.17.1","version":6}"#));
            let mut id = 1_000;
            while !stop.load(Ordering::Relaxed) {
                // The client's {"background":true} and {"focused":true}, read and ignored.
                let _ = ws.read();
                let next = script.lock().unwrap().pop();
                let text = next.unwrap_or_else(|| frame(id, None));
                id += 1;
                if ws.send(tungstenite::Message::text(text)).is_err() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    })
}

fn knowns(t0: f64, n: usize) -> Vec<Known> {
    let q = |v: f64| (v * 100.0).round() / 100.0;
    (0..n)
        .map(|i| {
            let t = t0 + i as f64 * 0.01;
            let s = i as f64 / n as f64;
            Known {
                t,
                wrist: [q(25.0 * s - 5.0), q(-15.0 + 20.0 * s), q(30.0 * (3.0 * s).sin())],
                thumb: [q(5.0 + 30.0 * s), q(10.0 + 20.0 * s), q(40.0 - 25.0 * s)],
            }
        })
        .collect()
}

fn hand_jsonl(ks: &[Known]) -> String {
    ks.iter()
        .map(|k| {
            format!(
                "{{\"t\":{},\"wrist\":[{},{},{}],\"thumb\":[{},{},{}]}}\n",
                k.t, k.wrist[0], k.wrist[1], k.wrist[2], k.thumb[0], k.thumb[1], k.thumb[2]
            )
        })
        .collect()
}

#[test]
fn leap_frames_drive_the_daemon_like_frond_map_and_it_reconnects() {
    let dir = tempfile::tempdir().unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let first = knowns(1.0, 40);
    // Frames are popped from the end: reversed, then the frame ids count up.
    let script = Arc::new(Mutex::new(
        first.iter().enumerate().rev().map(|(i, k)| frame(i as i64, Some(*k))).collect::<Vec<_>>(),
    ));
    let stop = Arc::new(AtomicBool::new(false));
    // The daemon connects first, the frames wait in the script.
    let source = format!("leap://127.0.0.1:{port}?hand=right");
    let daemon = Daemon::start(dir.path(), &["--source", &source, "--rig", "grass", "--filter", "none"]);
    assert_eq!(daemon.status().source.kind, "leap");
    let mut tap = daemon.frond().args(["tap", "--jsonl"]).stdout(Stdio::piped()).spawn().unwrap();
    let lines = BufReader::new(tap.stdout.take().unwrap()).lines();
    std::thread::sleep(Duration::from_millis(300)); // let tap subscribe
    let server = serve(listener, Arc::clone(&script), Arc::clone(&stop));

    let expected = frond_e2e::frond_map(&["--filter", "none", "--rig", "grass"], &hand_jsonl(&first));
    assert!(expected.status.success(), "{}", String::from_utf8_lossy(&expected.stderr));
    let expected: Vec<Value> = String::from_utf8(expected.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in lines {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut got: Vec<Value> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    while got.len() < first.len() {
        let left = deadline.saturating_duration_since(Instant::now());
        let Ok(line) = rx.recv_timeout(left) else { break };
        got.push(serde_json::from_str(&line).unwrap());
    }
    let _ = tap.kill();
    let _ = tap.wait();
    assert_eq!(got.len(), first.len(), "one pose per frame with the hand in view");
    for (g, e) in got.iter().zip(&expected) {
        for j in 0..4 {
            for c in 0..3 {
                let (a, b) = (g["joints"][j][c].as_f64().unwrap(), e["joints"][j][c].as_f64().unwrap());
                assert!((a - b).abs() < 2e-3, "live {g} != frond map {e}");
            }
        }
    }
    assert_eq!(daemon.status().source.reports, first.len() as u64);

    // Out of view (frames without hands): held, then the device is lost.
    let mut sub = frond_sdk::Subscriber::connect(&daemon.socket_dir).unwrap();
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut lost = false;
    while !lost && Instant::now() < deadline {
        if let Ok(frond_sdk::Event::Pose(p)) = sub.next_event() {
            lost = p.flags.contains(PoseFlags::DEVICE_LOST);
        }
    }
    assert!(lost, "no device-lost pose while the hand is out of view");

    // The service restarts on the same port: the daemon reconnects and the hand comes back.
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    std::thread::sleep(Duration::from_millis(700));
    let listener = TcpListener::bind(("127.0.0.1", port)).unwrap();
    let again = knowns(5.0, 30);
    *script.lock().unwrap() =
        again.iter().enumerate().rev().map(|(i, k)| frame(100 + i as i64, Some(*k))).collect();
    drop(sub);
    let mut sub = frond_sdk::Subscriber::connect(&daemon.socket_dir).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let server = serve(listener, Arc::clone(&script), Arc::clone(&stop));
    let fresh = frond_e2e::fresh_poses(&mut sub, again.len(), Duration::from_secs(10));
    assert_eq!(fresh.len(), again.len(), "fresh poses after the restart: {:?}", daemon.status().source);
    assert_eq!(fresh[0].hand.t, again[0].t, "the first frame after the restart");
    assert_eq!(daemon.status().source.reports, (first.len() + again.len()) as u64);
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
}

#[test]
fn bad_leap_addresses_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(frond_e2e::bin("frondd"))
        .args(["--source", "leap://127.0.0.1:6437?hand=both", "--socket-dir"])
        .arg(dir.path().join("run"))
        .arg("--takes-dir")
        .arg(dir.path().join("takes"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("hand=both") && err.contains("hand=left or hand=right"), "{err}");
}
