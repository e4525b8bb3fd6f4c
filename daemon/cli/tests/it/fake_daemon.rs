//! Live commands (`status`, `tap`, `record`, `mark`, `filter`, `rig set`, `calibration apply`,
//! `calibrate`) against a fake daemon serving the real protocol on temporary sockets.

use std::io::{BufRead, BufReader};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use frond_formats::rig_toml::CalibrationText;
use frond_motion::Calibration;
use frond_protocol::{
    ControlReply, ControlRequest, ElementId, FrameBuf, HandWire, Hello, LatencySummary, Pose, PoseFlags,
    RecordingStatus, ServerMessage, SourceStatus, StatusReport, SubscriberStatus, read_frame, write_frame,
};

/// How the fake answers `RawSample`.
#[derive(Clone, Copy)]
enum Raw {
    /// Always the same fresh sample.
    Constant,
    /// Never fresh (device missing).
    Stale,
    /// Thumb joints sweep 0..45 degrees in a 10-request cycle; wrist sweeps too.
    Sweep,
}

struct Fake {
    _dir: tempfile::TempDir,
    sockets: PathBuf,
    requests: Arc<Mutex<Vec<ControlRequest>>>,
}

fn status_report() -> StatusReport {
    StatusReport {
        daemon_version: "9.9.9-fake".into(),
        uptime_s: 12.5,
        source: SourceStatus {
            kind: "in-process".into(),
            path: "virtual glove (sway)".into(),
            connected: true,
            reports: 777,
            rejected: 2,
            device_seq_gaps: 0,
            rejected_by_reason: Default::default(),
            peers_dropped: 0,
            camera: None,
        },
        rig_name: "grass".into(),
        calibration_id: "none".into(),
        filter: "none".into(),
        tick_rate_hz: 1000,
        achieved_rate_hz: 1000.2,
        ticks: 12500,
        held_ticks: 3,
        device_wakes: 0,
        publish_drops: 0,
        lateness: LatencySummary { p50_us: 8.0, p99_us: 31.0, p999_us: 52.0, max_us: 70.0, samples: 1000 },
        subscribers: vec![SubscriberStatus { id: 3, connected_s: 2.0, sent: 2000, dropped: 1, pid: 0 }],
        recording: None,
        device_events: vec!["opened virtual glove".into()],
        realtime: "normal".into(),
        modes: vec![],
        stages: vec![],
        elements: vec![],
        hands: vec![],
        problems: vec![],
        recorder_error: None,
        lateness_histogram: Vec::new(),
        triggers: None,
        ltc: None,
    }
}

fn reply_to(req: &ControlRequest, n: u64, raw: Raw) -> ControlReply {
    match req {
        ControlRequest::Status => ControlReply::Status(Box::new(status_report())),
        ControlRequest::RecordStart { name } => ControlReply::Recording(RecordingStatus {
            name: name.clone(),
            path: format!("/takes/{name}.take"),
            frames: 0,
            dropped: 0,
            active: true,
        }),
        ControlRequest::RecordStop => ControlReply::Recording(RecordingStatus {
            name: "t1".into(),
            path: "/takes/t1.take".into(),
            frames: 4242,
            dropped: 0,
            active: false,
        }),
        ControlRequest::RawSample => {
            let t = n as f64 * 0.001;
            match raw {
                Raw::Constant => ControlReply::RawSample {
                    t,
                    wrist_deg: [1.0, 2.0, 3.0],
                    thumb_deg: [4.0, 5.0, 6.0],
                    fresh: true,
                },
                Raw::Stale => {
                    ControlReply::RawSample { t, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3], fresh: false }
                }
                Raw::Sweep => {
                    let x = (n % 10) as f32 * 5.0;
                    ControlReply::RawSample {
                        t,
                        wrist_deg: [x * 2.0, x, -x],
                        thumb_deg: [x, x, x],
                        fresh: true,
                    }
                }
            }
        }
        ControlRequest::Mark { label } if label.starts_with("refuse") => {
            ControlReply::Error(frond_protocol::ControlError {
                kind: frond_protocol::ControlErrorKind::WrongState,
                message: "not recording".into(),
            })
        }
        _ => ControlReply::Ok,
    }
}

fn pose(seq: u64, flags: PoseFlags) -> Pose {
    let a = seq as f32 * 0.5;
    Pose {
        seq,
        device_time_us: 1000 * seq,
        host_monotonic_ns: seq,
        flags,
        element: ElementId::GLOBAL,
        joints_deg: [[a, -a, 0.0], [a / 2.0, 0.0, 0.0], [0.0, 0.0, 0.25], [0.0, 0.0, 0.25]],
        hand: HandWire { t: seq as f64 / 1000.0, wrist_deg: [a, -a, 0.25], thumb_deg: [0.0; 3] },
    }
}

fn hello(next_seq: u64) -> Hello {
    Hello {
        protocol_version: frond_protocol::PROTOCOL_VERSION,
        daemon_version: "9.9.9-fake".into(),
        rig_name: "grass".into(),
        joint_names: ["root", "lower", "middle", "tip"].map(String::from).to_vec(),
        tick_rate_hz: 1000,
        elements: Default::default(),
        next_seq,
    }
}

/// Starts the fake. `poses` are sent after the hello to each subscriber, then the connection is
/// held open; with `endless` poses keep coming after them until the subscriber leaves.
fn start(poses: Vec<Pose>, endless: bool, raw: Raw) -> Fake {
    let dir = tempfile::tempdir().unwrap();
    let sockets = dir.path().join("run");
    std::fs::create_dir(&sockets).unwrap();
    let requests = Arc::new(Mutex::new(Vec::new()));

    let control = UnixListener::bind(sockets.join("control.sock")).unwrap();
    let log = requests.clone();
    thread::spawn(move || {
        for stream in control.incoming() {
            let Ok(mut stream) = stream else { return };
            let log = log.clone();
            thread::spawn(move || {
                let mut scratch = Vec::new();
                let mut out = FrameBuf::default();
                let mut n = 0;
                while let Ok(req) = read_frame::<ControlRequest, _>(&mut stream, &mut scratch) {
                    n += 1;
                    let reply = reply_to(&req, n, raw);
                    log.lock().unwrap().push(req);
                    if write_frame(&mut stream, &mut out, &reply).is_err() {
                        return;
                    }
                }
            });
        }
    });

    let pose_listener = UnixListener::bind(sockets.join("poses.sock")).unwrap();
    thread::spawn(move || {
        for stream in pose_listener.incoming() {
            let Ok(stream) = stream else { return };
            let poses = poses.clone();
            thread::spawn(move || serve_poses(stream, poses, endless));
        }
    });
    Fake { _dir: dir, sockets, requests }
}

fn serve_poses(mut s: UnixStream, poses: Vec<Pose>, endless: bool) {
    let mut out = FrameBuf::default();
    let first = poses.first().map_or(0, |p| p.seq);
    if write_frame(&mut s, &mut out, &ServerMessage::Hello(hello(first))).is_err() {
        return;
    }
    for p in &poses {
        if write_frame(&mut s, &mut out, &ServerMessage::Pose(*p)).is_err() {
            return;
        }
    }
    let mut seq = poses.last().map_or(0, |p| p.seq + 1);
    for _ in 0..20_000 {
        if endless {
            if write_frame(&mut s, &mut out, &ServerMessage::Pose(pose(seq, PoseFlags::default()))).is_err() {
                return;
            }
            seq += 1;
            thread::sleep(Duration::from_micros(200));
        } else {
            thread::sleep(Duration::from_millis(1));
        }
    }
}

impl Fake {
    fn frond(&self) -> Command {
        let mut c = Command::new(env!("CARGO_BIN_EXE_frond"));
        c.env("FROND_SOCKET_DIR", &self.sockets).env_remove("FROND_TAKES_DIR");
        c
    }
    fn requests(&self) -> Vec<ControlRequest> {
        self.requests.lock().unwrap().clone()
    }
    fn root(&self) -> &Path {
        self.sockets.parent().unwrap()
    }
}

fn text(b: &[u8]) -> String {
    String::from_utf8(b.to_vec()).unwrap()
}

fn ok(out: Output) -> String {
    assert!(out.status.success(), "status {:?}, stderr {}", out.status, text(&out.stderr));
    text(&out.stdout)
}

#[test]
fn status_table_and_json() {
    let fake = start(vec![], false, Raw::Constant);
    let table = ok(fake.frond().arg("status").output().unwrap());
    assert!(table.contains("frondd 9.9.9-fake"), "{table}");
    assert!(table.contains("in-process virtual glove (sway) (connected; 777 reports, 2 rejected"), "{table}");
    assert!(table.contains("1000 Hz nominal, 1000.2 Hz achieved"), "{table}");
    assert!(table.contains("p99 31.0 us"), "{table}");
    assert!(table.contains("recording    no"), "{table}");
    let json = ok(fake.frond().args(["status", "--json"]).output().unwrap());
    let back: StatusReport = serde_json::from_str(&json).unwrap();
    assert_eq!(back, status_report());
}

#[test]
fn tap_prints_new_samples_and_skips_held_frames() {
    let poses = vec![
        pose(5, PoseFlags::FILTERED),
        pose(6, PoseFlags::HELD),
        pose(9, PoseFlags::default()), // 7 and 8 missing
        pose(10, PoseFlags::HELD | PoseFlags::RECORDING),
        pose(11, PoseFlags::default()),
    ];
    let fake = start(poses, false, Raw::Constant);
    let out = fake.frond().args(["tap", "--jsonl", "--count", "3"]).output().unwrap();
    let stdout = ok(out.clone());
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(
        lines,
        [
            r#"{"seq":5,"t":0.005,"joints":[[2.5,-2.5,0.0],[1.25,0.0,0.0],[0.0,0.0,0.25],[0.0,0.0,0.25]],"flags":["filtered"]}"#,
            r#"{"seq":9,"t":0.009,"joints":[[4.5,-4.5,0.0],[2.25,0.0,0.0],[0.0,0.0,0.25],[0.0,0.0,0.25]]}"#,
            r#"{"seq":11,"t":0.011,"joints":[[5.5,-5.5,0.0],[2.75,0.0,0.0],[0.0,0.0,0.25],[0.0,0.0,0.25]]}"#,
        ]
    );
    assert!(text(&out.stderr).contains("gap: 2 frames missing (seq 7..8)"), "{}", text(&out.stderr));

    let all = ok(fake.frond().args(["tap", "--jsonl", "--count", "5", "--include-held"]).output().unwrap());
    let seqs: Vec<u64> = all
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["seq"].as_u64().unwrap())
        .collect();
    assert_eq!(seqs, [5, 6, 9, 10, 11]);
    assert!(all.lines().nth(3).unwrap().ends_with(r#""flags":["held","recording"]}"#), "{all}");

    let human = ok(fake.frond().args(["tap", "--count", "1"]).output().unwrap());
    assert!(human.starts_with("#5 ") && human.contains("root [   2.50   -2.50    0.00]"), "{human}");
}

#[test]
fn tap_into_a_closed_pipe_ends_quietly() {
    let fake = start(vec![pose(0, PoseFlags::default())], true, Raw::Constant);
    let mut child =
        fake.frond().args(["tap", "--jsonl"]).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut reader = BufReader::new(child.stdout.take().unwrap());
    let mut first = String::new();
    reader.read_line(&mut first).unwrap();
    assert!(first.starts_with(r#"{"seq":0,"#), "{first}");
    drop(reader); // like `| head -1`
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(text(&out.stderr), "");
}

#[test]
fn one_shot_control_commands_send_the_right_requests() {
    let fake = start(vec![], false, Raw::Constant);
    let rig = fake.root().join("grass-stiff.toml");
    let rig_text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../rig-files/plants/grass.toml"))
            .unwrap();
    std::fs::write(&rig, &rig_text).unwrap();
    let cal = concat!(env!("CARGO_MANIFEST_DIR"), "/../../rig-files/calibrations/example-user.toml");
    let cal_text = std::fs::read_to_string(cal).unwrap();

    assert!(ok(fake.frond().args(["record", "start", "t1"]).output().unwrap()).contains("/takes/t1.take"));
    ok(fake.frond().args(["mark", "gust starts"]).output().unwrap());
    let stop = ok(fake.frond().args(["record", "stop"]).output().unwrap());
    assert!(stop.contains("4242 frames") && stop.contains("/takes/t1.take"), "{stop}");
    ok(fake.frond().args(["filter", "lowpass"]).output().unwrap());
    // The reply names the rig as the daemon will (the file's own name), not the file's stem.
    let set = ok(fake.frond().arg("rig").arg("set").arg(&rig).output().unwrap());
    assert!(set.starts_with("rig set to grass ("), "{set}");
    ok(fake.frond().args(["calibration", "apply", cal]).output().unwrap());

    let reqs = fake.requests();
    assert_eq!(reqs[0], ControlRequest::RecordStart { name: "t1".into() });
    assert_eq!(reqs[1], ControlRequest::Mark { label: "gust starts".into() });
    assert_eq!(reqs[2], ControlRequest::RecordStop);
    let ControlRequest::SetFilter { spec } = &reqs[3] else { panic!("{:?}", reqs[3]) };
    assert!(spec.starts_with("lowpass:cutoff_hz="), "{spec}");
    assert_eq!(reqs[4], ControlRequest::SetRig { name: "grass".into(), toml: rig_text });
    assert_eq!(reqs[5], ControlRequest::SetCalibration { id: "example-user".into(), toml: cal_text });
    assert_eq!(reqs.len(), 6);
}

#[test]
fn a_refusal_from_the_daemon_is_a_failure_with_its_message() {
    let fake = start(vec![], false, Raw::Constant);
    let out = fake.frond().args(["mark", "refuse-me"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert_eq!(err, "frond: error: the daemon refused: not recording (WrongState)\n");
}

#[test]
fn an_unreadable_file_sends_nothing() {
    let fake = start(vec![], false, Raw::Constant);
    let out = fake.frond().args(["calibration", "apply", "/nonexistent/cal.toml"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("cannot read calibration file /nonexistent/cal.toml"));
    assert!(fake.requests().is_empty(), "nothing is sent for a file that cannot be read");
}

#[test]
fn calibrate_writes_and_applies_a_measured_calibration() {
    let fake = start(vec![], false, Raw::Sweep);
    let file = fake.root().join("cal/zoe.toml");
    // -o into a directory that does not exist is refused before the steps, not made.
    let out = fake.frond().args(["calibrate", "--user", "zoe", "--yes", "-o"]).arg(&file).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("cal does not exist"), "{}", text(&out.stderr));
    assert!(fake.requests().is_empty() && !file.parent().unwrap().exists());
    std::fs::create_dir(file.parent().unwrap()).unwrap();
    let out = fake
        .frond()
        .args(["calibrate", "--user", "zoe", "--yes", "--seconds-per-step", "0.6", "--apply", "-o"])
        .arg(&file)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let stdout = ok(out);
    assert!(stdout.contains(&format!("wrote {}", file.display())), "{stdout}");
    let written = std::fs::read_to_string(&file).unwrap();
    let cal = Calibration::from_toml_str(&written).unwrap();
    assert_eq!(cal.id, "zoe");
    // The sweep covers 0..45 degrees on every thumb joint; the neutral is its mean (near 22.5),
    // so each range is 45 minus that mean.
    for k in 0..3 {
        let r = cal.thumb_range_deg[k];
        assert!((r - (45.0 - cal.neutral_thumb_deg[k])).abs() < 1e-3, "{cal:?}");
        assert!(r > 15.0 && r < 30.0, "{cal:?}");
    }
    let ranges = cal.wrist_range_deg.expect("wrist ranges");
    assert_eq!(ranges, [[0.0, 90.0], [0.0, 45.0], [-45.0, 0.0]]);
    let applied: Vec<ControlRequest> =
        fake.requests().into_iter().filter(|r| !matches!(r, ControlRequest::RawSample)).collect();
    assert_eq!(applied, vec![ControlRequest::SetCalibration { id: "zoe".into(), toml: written }]);
}

#[test]
fn calibrate_refuses_a_thumb_that_does_not_bend() {
    let fake = start(vec![], false, Raw::Constant);
    let file = fake.root().join("still.toml");
    let out = fake
        .frond()
        .args(["calibrate", "--user", "still", "--yes", "--seconds-per-step", "0.2", "-o"])
        .arg(&file)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.contains("thumb joint g1") && err.contains("below 5 degrees"), "{err}");
    assert!(!file.exists());
}

#[test]
fn calibrate_without_a_device_says_so() {
    let fake = start(vec![], false, Raw::Stale);
    let out = fake
        .frond()
        .args(["calibrate", "--user", "nobody", "--yes", "--seconds-per-step", "0.2", "-o"])
        .arg(fake.root().join("x.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.contains("step neutral: no fresh samples"), "{err}");
}

#[test]
fn calibrate_without_yes_and_no_stdin_asks_for_yes() {
    let fake = start(vec![], false, Raw::Constant);
    let out = fake
        .frond()
        .args(["calibrate", "--user", "a", "-o"])
        .arg(fake.root().join("a.toml"))
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("use --yes"), "{}", text(&out.stderr));
}

/// A daemon that refuses a client on sight (SO_PEERCRED) answers and closes at once, often
/// before the client has written its request: the client's write then fails with EPIPE. The
/// refusal must still be reported, never a silent success (EPIPE on stdout is one; on the
/// control socket it is not).
#[test]
fn a_refusal_sent_before_the_request_is_read_is_still_reported() {
    let dir = tempfile::tempdir().unwrap();
    let listener = UnixListener::bind(dir.path().join("control.sock")).unwrap();
    const RUNS: usize = 20;
    let server = thread::spawn(move || {
        for _ in 0..RUNS {
            let (mut s, _) = listener.accept().unwrap();
            let refusal = ControlReply::Error(frond_protocol::ControlError {
                kind: frond_protocol::ControlErrorKind::PermissionDenied,
                message: "uid 65534 is not allowed".into(),
            });
            write_frame(&mut s, &mut FrameBuf::default(), &refusal).unwrap();
            drop(s);
        }
    });
    for _ in 0..RUNS {
        let out = Command::new(env!("CARGO_BIN_EXE_frond"))
            .args(["status", "--json"])
            .env("FROND_SOCKET_DIR", dir.path())
            .output()
            .unwrap();
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "stdout {:?}, stderr {err:?}", text(&out.stdout));
        assert!(err.contains("uid 65534 is not allowed (PermissionDenied)"), "{err}");
    }
    server.join().unwrap();
}
