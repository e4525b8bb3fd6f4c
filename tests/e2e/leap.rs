//! Leap Motion input (issue 18): `frondd --source leap://...` against a fake tracking service, a
//! WebSocket server on `/v6.json` that replays v6 frames as Ultraleap's open-source tracking
//! WebSocket server writes them, of hand poses known here. The daemon's poses must equal
//! `frond map` of the hand samples those poses are (worked out by hand from the geometry the
//! frames were built from); it reconnects when the service restarts, and holds (then flags the
//! device lost) while the hand is out of view. Then frames a real controller produced (Leap
//! Motion's own recordings, `leap_recorded/`): one hand, and a left and a right hand as two
//! sources, each sample checked against the LeapJS angles worked out here from the frame.

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

/// The fake service of the synthetic tests: every connection gets `{"version": 6}`, then the
/// frames of `script` (popped as they are sent, so a reconnection carries on where the last
/// connection stopped), then frames without hands.
fn serve(
    listener: TcpListener,
    script: Arc<Mutex<Vec<String>>>,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    fake_service(listener, "5.17.1", stop, move || {
        let script = Arc::clone(&script);
        move || script.lock().unwrap().pop()
    })
}

/// A fake Leap Motion service on `listener` until `stop`: each connection, on its own thread,
/// gets the greeting of the service `service_version`, then a frame every 5 ms: the next of
/// the script `script_for` makes for it, then frames without hands once that runs out.
fn fake_service<S>(
    listener: TcpListener,
    service_version: &'static str,
    stop: Arc<AtomicBool>,
    script_for: impl Fn() -> S + Send + 'static,
) -> std::thread::JoinHandle<()>
where
    S: FnMut() -> Option<String> + Send + 'static,
{
    listener.set_nonblocking(true).unwrap();
    std::thread::spawn(move || {
        let mut conns = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            let Ok((stream, _)) = listener.accept() else {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            };
            let (mut next, stop) = (script_for(), Arc::clone(&stop));
            conns.push(std::thread::spawn(move || {
                stream.set_nonblocking(false).unwrap();
                stream.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
                let Ok(mut ws) = tungstenite::accept(stream) else { return };
                let hello = json!({"serviceVersion": service_version, "version": 6}).to_string();
                let _ = ws.send(tungstenite::Message::text(hello));
                let mut id = 2_000_000;
                while !stop.load(Ordering::Relaxed) {
                    // The client's {"background":true} and {"focused":true}, read and ignored.
                    let _ = ws.read();
                    let text = next().unwrap_or_else(|| {
                        id += 1;
                        frame(id, None)
                    });
                    if ws.send(tungstenite::Message::text(text)).is_err() {
                        break;
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
            }));
        }
        for c in conns {
            let _ = c.join();
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

/// `frond map --filter none --rig grass` of the hand samples: the poses the daemon must publish.
fn grass_poses_of(ks: &[Known]) -> Vec<Value> {
    let out = frond_e2e::frond_map(&["--filter", "none", "--rig", "grass"], &hand_jsonl(ks));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect()
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

    let expected = grass_poses_of(&first);
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

/// Frames a real Leap Motion controller produced (`leap_recorded/README.md`), one JSON object a
/// line.
pub(crate) fn recorded(file: &str) -> Vec<Value> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("e2e/leap_recorded").join(file);
    std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The `which` hand of a recorded frame as a frond hand sample, worked out here from the JSON
/// as LeapJS defines it (a second implementation beside `frond_device::source::leap::frames`): `Hand.pitch`
/// `atan2(d.y, -d.z)`, `yaw` `atan2(d.x, -d.z)`, `roll` `atan2(n.x, -n.y)` of the palm direction
/// and normal; the thumb's bends are the angles between its successive bones' directions
/// (`Bone.direction`: the negated third row of the bone's basis).
fn sample_of(frame: &Value, which: &str) -> Known {
    let v3 = |v: &Value| -> [f64; 3] { std::array::from_fn(|i| v[i].as_f64().unwrap()) };
    let hand = frame["hands"].as_array().unwrap().iter().find(|h| h["type"] == which).expect("the hand");
    let (d, n) = (v3(&hand["direction"]), v3(&hand["palmNormal"]));
    let wrist = [d[1].atan2(-d[2]), d[0].atan2(-d[2]), n[0].atan2(-n[1])].map(f64::to_degrees);
    let thumb = frame["pointables"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["handId"] == hand["id"] && p["type"] == 0)
        .expect("the hand's thumb");
    let dirs: Vec<[f64; 3]> = (0..4).map(|b| norm(v3(&thumb["bases"][b][2]).map(|c| -c))).collect();
    let bend = |i: usize| {
        let dot: f64 = (0..3).map(|k| dirs[i][k] * dirs[i + 1][k]).sum();
        dot.clamp(-1.0, 1.0).acos().to_degrees()
    };
    Known { t: frame["timestamp"].as_f64().unwrap() / 1e6, wrist, thumb: [bend(0), bend(1), bend(2)] }
}

/// The fake service of the recorded frames: every connection gets `{"version": 6}` from the
/// service version they were recorded with, then each of `frames`, then frames without hands.
pub(crate) fn replay_to_each(
    listener: TcpListener,
    frames: Vec<String>,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    let frames = Arc::new(frames);
    fake_service(listener, "2.1.5+22699", stop, move || {
        let (frames, mut at) = (Arc::clone(&frames), 0);
        move || {
            at += 1;
            frames.get(at - 1).cloned()
        }
    })
}

fn close(got: f64, want: f64, tol: f64, what: &str) {
    assert!((got - want).abs() < tol, "{what}: {got} vs {want}");
}

/// Each fresh pose's hand sample against the sample worked out from the frame it came from.
fn check_hands(poses: &[frond_sdk::Pose], want: &[Known], what: &str) {
    assert_eq!(poses.len(), want.len(), "{what}: one fresh pose per recorded frame");
    for (p, k) in poses.iter().zip(want) {
        assert_eq!(p.hand.t, k.t, "{what}: the frame's device time");
        for i in 0..3 {
            close(
                f64::from(p.hand.wrist_deg[i]),
                k.wrist[i],
                1e-3,
                &format!("{what} wrist {i} at t={}", k.t),
            );
            close(
                f64::from(p.hand.thumb_deg[i]),
                k.thumb[i],
                1e-3,
                &format!("{what} thumb {i} at t={}", k.t),
            );
        }
    }
}

/// Recorded frames of a real controller (a right hand tapping a finger, Leap Motion's own
/// recording): the daemon's hand samples equal the LeapJS angles worked out here from each frame,
/// and its poses equal `frond map` of those samples.
#[test]
fn recorded_frames_of_a_real_controller_give_the_sdks_angles() {
    let frames = recorded("finger-tap-54fps.ndjson");
    let want: Vec<Known> = frames.iter().map(|f| sample_of(f, "right")).collect();
    let spread = |k: usize| {
        let v: Vec<f64> = want.iter().map(|w| w.thumb[k]).collect();
        v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
    };
    assert!(spread(0) > 5.0 && spread(2) > 5.0, "the recorded thumb moves");
    let dir = tempfile::tempdir().unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let source = format!("leap://127.0.0.1:{}?hand=right", listener.local_addr().unwrap().port());
    let daemon = Daemon::start(dir.path(), &["--source", &source, "--rig", "grass", "--filter", "none"]);
    let mut sub = frond_sdk::Subscriber::connect(&daemon.socket_dir).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let server = replay_to_each(listener, frames.iter().map(Value::to_string).collect(), Arc::clone(&stop));
    let fresh = frond_e2e::fresh_poses(&mut sub, want.len(), Duration::from_secs(20));
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    check_hands(&fresh, &want, "right hand");
    let expected = grass_poses_of(&want);
    assert_eq!(expected.len(), fresh.len());
    for (p, e) in fresh.iter().zip(&expected) {
        for j in 0..4 {
            for c in 0..3 {
                let want = e["joints"][j][c].as_f64().unwrap();
                close(f64::from(p.joints_deg[j][c]), want, 2e-3, &format!("joint {j}.{c} at t={}", p.hand.t));
            }
        }
    }
}

/// Both hands of one controller as two sources (`--hand` with `hand=left` and `hand=right`):
/// each recorded frame carries a real left hand (Leap Motion's 110 fps recording) beside a real
/// right hand (the 54 fps one); the left drives the flower, the right its leaves, each with its
/// own hand's angles.
#[test]
fn both_hands_of_recorded_frames_drive_two_elements() {
    let (right, left) = (recorded("finger-tap-54fps.ndjson"), recorded("finger-tap-110fps.ndjson"));
    let frames: Vec<Value> = right
        .iter()
        .zip(&left)
        .map(|(r, l)| {
            let mut f = r.clone();
            f["hands"].as_array_mut().unwrap().extend(l["hands"].as_array().unwrap().iter().cloned());
            f["pointables"]
                .as_array_mut()
                .unwrap()
                .extend(l["pointables"].as_array().unwrap().iter().cloned());
            f
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let at = format!("leap://127.0.0.1:{}", listener.local_addr().unwrap().port());
    let (left_flag, right_flag) =
        (format!("left={at}?hand=left"), format!("right={at}?hand=right,element=leaf"));
    let daemon = Daemon::start(
        dir.path(),
        &["--rig", "flower", "--filter", "none", "--hand", &left_flag, "--hand", &right_flag],
    );
    let mut sub = frond_sdk::Subscriber::connect(&daemon.socket_dir).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let server = replay_to_each(listener, frames.iter().map(Value::to_string).collect(), Arc::clone(&stop));
    let mut fresh: [Vec<frond_sdk::Pose>; 2] = [Vec::new(), Vec::new()];
    let deadline = Instant::now() + Duration::from_secs(20);
    while fresh.iter().any(|f| f.len() < frames.len()) && Instant::now() < deadline {
        if let frond_sdk::Event::Pose(p) = sub.next_event().expect("the pose stream")
            && !p.flags.contains(PoseFlags::HELD)
            && let Some(list) = fresh.get_mut(usize::from(p.element))
            && list.len() < frames.len()
        {
            list.push(p);
        }
    }
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    // The left hand's samples carry the merged frame's (the right recording's) timestamp.
    let want_left: Vec<Known> = frames.iter().map(|f| sample_of(f, "left")).collect();
    let want_right: Vec<Known> = frames.iter().map(|f| sample_of(f, "right")).collect();
    check_hands(&fresh[0], &want_left, "left hand, element 0 (the flower)");
    check_hands(&fresh[1], &want_right, "right hand, element 1 (its leaves)");
}

/// A hostile Leap service on `listener` until `stop`: every connection gets the greeting, then
/// WebSocket pings as fast as its socket takes them, and it never reads a byte after the
/// handshake (its receive buffer is made small, so the daemon's pongs fill it at once).
/// Counts the connections it took in `taken`.
fn ping_flood(
    listener: TcpListener,
    stop: Arc<AtomicBool>,
    taken: Arc<std::sync::atomic::AtomicUsize>,
) -> std::thread::JoinHandle<()> {
    use std::os::fd::AsRawFd;
    let small: libc::c_int = 4096;
    // SAFETY: a listening socket we own, and a c_int option of the right size (accepted
    // sockets inherit it).
    let set = unsafe {
        libc::setsockopt(
            listener.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&small as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    assert_eq!(set, 0, "SO_RCVBUF");
    listener.set_nonblocking(true).unwrap();
    std::thread::spawn(move || {
        let mut conns = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            let Ok((stream, _)) = listener.accept() else {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            };
            taken.fetch_add(1, Ordering::Relaxed);
            let stop = Arc::clone(&stop);
            conns.push(std::thread::spawn(move || {
                stream.set_nonblocking(false).unwrap();
                let Ok(mut ws) = tungstenite::accept(stream) else { return };
                let hello = json!({"serviceVersion": "5.17.1", "version": 6}).to_string();
                if ws.send(tungstenite::Message::text(hello)).is_err() {
                    return;
                }
                // Unmasked server pings of 125 bytes each, written raw: nothing is ever read.
                let ping: Vec<u8> = [0x89u8, 125].into_iter().chain(std::iter::repeat_n(b'p', 125)).collect();
                let burst = ping.repeat(512);
                let tcp = ws.get_mut();
                tcp.set_write_timeout(Some(Duration::from_millis(50))).unwrap();
                // Where the next write starts: a short write must not cut a ping in two.
                let mut at = 0;
                while !stop.load(Ordering::Relaxed) {
                    match std::io::Write::write(tcp, &burst[at..]) {
                        Ok(n) => at = (at + n) % burst.len(),
                        Err(e)
                            if matches!(
                                e.kind(),
                                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                            ) => {}
                        Err(_) => return, // the daemon dropped the connection
                    }
                }
            }));
        }
        for c in conns {
            let _ = c.join();
        }
    })
}

/// Issue 42: a Leap service that floods pings and never reads cannot hold the daemon. The
/// daemon's pongs fill the socket; its writes never wait, so SIGTERM still ends it at once with
/// the take finished and the sockets removed. (It hung until SIGKILL: the pong write blocked
/// the client thread, which stopping the source joined. 5 s is a hang check; the README
/// promises 1 s.)
#[test]
fn sigterm_ends_the_daemon_while_a_leap_service_floods_pings_and_never_reads() {
    let dir = tempfile::tempdir().unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let source = format!("leap://127.0.0.1:{}", listener.local_addr().unwrap().port());
    let (stop, taken) = (Arc::new(AtomicBool::new(false)), Arc::new(std::sync::atomic::AtomicUsize::new(0)));
    let server = ping_flood(listener, Arc::clone(&stop), Arc::clone(&taken));
    let mut daemon = Daemon::start(dir.path(), &["--source", &source, "--rig", "grass"]);
    assert!(matches!(
        daemon.control(&frond_protocol::ControlRequest::RecordStart { name: "flood".into() }),
        frond_protocol::ControlReply::Recording(_)
    ));
    assert!(frond_e2e::wait_for(Duration::from_secs(10), || taken.load(Ordering::Relaxed) > 0));
    // Long enough for the pongs to fill both socket buffers, short of the daemon dropping
    // the service for not reading (2 s).
    std::thread::sleep(Duration::from_millis(1500));
    let t0 = Instant::now();
    let status = daemon.proc.terminate(Duration::from_secs(5));
    let took = t0.elapsed();
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    let status = status.expect("frondd did not stop on SIGTERM while the service flooded pings");
    assert!(status.success(), "{status}");
    assert!(took < Duration::from_secs(5), "SIGTERM to exit took {took:?}");
    assert!(!daemon.socket_dir.join("control.sock").exists(), "control socket left behind");
    assert!(!daemon.socket_dir.join("poses.sock").exists(), "poses socket left behind");
    let bytes = std::fs::read(daemon.takes_dir.join("flood.take")).unwrap();
    let scan = frond_formats::take::scan_take(&bytes).unwrap();
    assert!(scan.ended, "take not finished");
    assert_eq!(scan.torn_bytes, 0);
}

/// Issue 42: a service that never reads what the daemon writes is dropped (after 2 s of
/// unread pongs), counted in status, and connected to again, at a bounded pace.
#[test]
fn a_leap_service_that_never_reads_is_dropped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let source = format!("leap://127.0.0.1:{}", listener.local_addr().unwrap().port());
    let (stop, taken) = (Arc::new(AtomicBool::new(false)), Arc::new(std::sync::atomic::AtomicUsize::new(0)));
    let server = ping_flood(listener, Arc::clone(&stop), Arc::clone(&taken));
    let daemon = Daemon::start(dir.path(), &["--source", &source, "--rig", "grass"]);
    let dropped = frond_e2e::wait_for(Duration::from_secs(20), || daemon.status().source.peers_dropped >= 1);
    let seen = daemon.status().source;
    assert!(dropped, "the service was never dropped: {seen:?}");
    assert!(
        frond_e2e::wait_for(Duration::from_secs(10), || taken.load(Ordering::Relaxed) >= 2),
        "the daemon did not connect again"
    );
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
}

/// Issue 42, bounds before work: a frame listing 5,000 hands is refused at the ninth and
/// counted (`too_many`), a message past the size limit is refused from its header
/// (`oversized`; the connection goes with it), and the good frames around them still drive
/// the plant. The refusals are said in the log by reason.
#[test]
fn a_leap_frame_of_5000_hands_and_an_oversized_message_are_refused_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let ks = knowns(1.0, 2);
    let hand = json!({"id": 1, "type": "left", "direction": [0, 0, -1], "palmNormal": [0, -1, 0]});
    let many = json!({"id": 10, "timestamp": 10, "hands": vec![hand; 5000], "pointables": []}).to_string();
    assert!(many.len() < frond_device::source::leap::MAX_MESSAGE_BYTES, "{} bytes", many.len());
    let huge = json!({"padding": "x".repeat(frond_device::source::leap::MAX_MESSAGE_BYTES)}).to_string();
    // Popped from the end: a good frame, 5,000 hands, a good frame, the huge one.
    let script = vec![huge, frame(2, Some(ks[1])), many, frame(1, Some(ks[0]))];
    let log = dir.path().join("frondd.log");
    let source = format!("leap://127.0.0.1:{port}?hand=right");
    let daemon = Daemon::start_with_stderr(
        dir.path(),
        &["--source", &source, "--rig", "grass", "--filter", "none"],
        std::fs::File::create(&log).unwrap().into(),
    );
    let stop = Arc::new(AtomicBool::new(false));
    let server = serve(listener, Arc::new(Mutex::new(script)), Arc::clone(&stop));
    let done = frond_e2e::wait_for(Duration::from_secs(20), || {
        let s = daemon.status().source;
        s.reports >= 2 && s.rejected >= 2
    });
    let status = daemon.status().source;
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    assert!(done, "the good frames did not all arrive: {status:?}");
    assert_eq!(status.reports, 2, "{status:?}");
    assert_eq!(status.rejected_by_reason.get("too_many"), Some(&1), "{status:?}");
    assert_eq!(status.rejected_by_reason.get("oversized"), Some(&1), "{status:?}");
    assert_eq!(status.rejected, 2, "{status:?}");
    // One line per hand per 10 s at most: the two reasons may be said in two.
    let said = frond_e2e::wait_for(Duration::from_secs(15), || {
        let text = std::fs::read_to_string(&log).unwrap();
        text.contains("too_many 1") && text.contains("oversized 1")
    });
    assert!(said, "refusals not logged: {}", std::fs::read_to_string(&log).unwrap());
}
