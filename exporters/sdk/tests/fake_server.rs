//! The subscriber against a fake daemon on a temporary Unix socket.

mod common;

use std::io::Write;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::thread::{self, JoinHandle};
use std::time::Duration;

use common::{frame, hello, hello_frame, pose, pose_frame};
use frond_protocol::ServerMessage;
use frond_sdk::{Event, Pose, ProtocolError, SdkError, Stats, Subscriber, SubscriberOptions};

/// A listener at `<dir>/poses.sock` that serves one connection with `serve`, then closes it and
/// removes the socket file.
fn serve_once(dir: &Path, serve: impl FnOnce(UnixStream) + Send + 'static) -> JoinHandle<()> {
    let path = dir.join("poses.sock");
    let listener = UnixListener::bind(&path).unwrap();
    thread::spawn(move || {
        let (stream, _) = listener.accept().unwrap();
        serve(stream);
        drop(listener);
        let _ = std::fs::remove_file(&path);
    })
}

/// A daemon that serves one connection with a hello (`next_seq` the first of `seqs`) and the
/// poses `seqs`, then goes away.
fn serve_poses(dir: &Path, seqs: std::ops::Range<u64>) -> JoinHandle<()> {
    serve_once(dir, move |mut s| {
        s.write_all(&hello_frame(seqs.start)).unwrap();
        for seq in seqs {
            s.write_all(&pose_frame(seq)).unwrap();
        }
    })
}

fn quick() -> SubscriberOptions {
    SubscriberOptions::new()
        .retry_interval(Duration::from_millis(10))
        .max_retry_interval(Duration::from_millis(50))
        .hello_timeout(Duration::from_secs(5))
}

fn tempdir() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().to_owned();
    (dir, path)
}

#[test]
fn hello_then_poses_in_order() {
    let (_guard, dir) = tempdir();
    let server = serve_poses(&dir, 10..13);
    let mut sub = quick().reconnect(false).connect(&dir).unwrap();
    assert_eq!(sub.hello(), &hello(10));
    assert_eq!(sub.socket_path(), dir.join("poses.sock"));
    let poses: Vec<Pose> = sub.by_ref().collect::<Result<_, _>>().unwrap();
    assert_eq!(poses, vec![pose(10), pose(11), pose(12)]);
    assert_eq!(
        sub.stats(),
        Stats { frames: 3, gaps: 0, missing: 0, reconnects: 0, disconnects: 1, rejected: 0, recovered: 0 }
    );
    assert!(matches!(sub.next_event(), Err(SdkError::Closed)));
    server.join().unwrap();
}

#[test]
fn a_gap_is_reported_before_the_pose_that_reveals_it() {
    let (_guard, dir) = tempdir();
    let server = serve_once(&dir, |mut s| {
        // The first pose is already past the hello's next_seq: 2 frames missing there too.
        let mut bytes = hello_frame(3);
        for seq in [5, 6, 9, 10] {
            bytes.extend(pose_frame(seq));
        }
        s.write_all(&bytes).unwrap();
    });
    let mut sub = quick().reconnect(false).connect(&dir).unwrap();
    let mut events = Vec::new();
    loop {
        match sub.next_event() {
            Ok(ev) => events.push(ev),
            Err(SdkError::Closed) => break,
            Err(e) => panic!("unexpected error {e}"),
        }
    }
    assert_eq!(
        events,
        vec![
            Event::Gap { expected: 3, got: 5 },
            Event::Pose(pose(5)),
            Event::Pose(pose(6)),
            Event::Gap { expected: 7, got: 9 },
            Event::Pose(pose(9)),
            Event::Pose(pose(10)),
            Event::Disconnected,
        ]
    );
    assert_eq!(
        sub.stats(),
        Stats { frames: 4, gaps: 2, missing: 4, reconnects: 0, disconnects: 1, rejected: 0, recovered: 0 }
    );
    server.join().unwrap();
}

#[test]
fn garbage_after_hello_is_a_protocol_error_not_a_panic() {
    // An HTTP request (huge length field), a frame with an undecodable body, an empty frame.
    let mut bad_body = vec![4, 0, 0, 0, frond_protocol::PROTOCOL_VERSION, 0xc1, 0xc1, 0xc1];
    bad_body.extend(pose_frame(0));
    type Check = fn(&ProtocolError) -> bool;
    let cases: Vec<(Vec<u8>, Check)> = vec![
        (b"GET / HTTP/1.1\r\n\r\n".to_vec(), |e| {
            matches!(e, ProtocolError::Frame(frond_protocol::DecodeError::TooLarge { .. }))
        }),
        (bad_body, |e| matches!(e, ProtocolError::Frame(frond_protocol::DecodeError::Malformed(_)))),
        (vec![0, 0, 0, 0], |e| matches!(e, ProtocolError::Frame(frond_protocol::DecodeError::EmptyFrame))),
    ];
    for (garbage, expected) in cases {
        let (_guard, dir) = tempdir();
        let server = serve_once(&dir, move |mut s| {
            s.write_all(&hello_frame(0)).unwrap();
            s.write_all(&pose_frame(0)).unwrap();
            s.write_all(&garbage).unwrap();
            thread::sleep(Duration::from_millis(200));
        });
        let mut sub = quick().reconnect(false).connect(&dir).unwrap();
        assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(0)));
        match sub.next_event() {
            Err(SdkError::Protocol { error, path }) => {
                assert!(expected(&error), "wrong protocol error {error:?}");
                assert_eq!(path, dir.join("poses.sock"));
            }
            other => panic!("expected a protocol error, got {other:?}"),
        }
        assert!(!sub.is_connected());
        assert!(matches!(sub.next_event(), Err(SdkError::Closed)));
        server.join().unwrap();
    }
}

#[test]
fn random_garbage_never_panics() {
    // Deterministic pseudo-random byte strings after a valid hello; each must end in a typed
    // error or a clean disconnect (never a panic or a hang).
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for round in 0..40 {
        let len = 1 + (round * 37) % 300;
        let garbage: Vec<u8> = (0..len)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        let (_guard, dir) = tempdir();
        let server = serve_once(&dir, move |mut s| {
            s.write_all(&hello_frame(0)).unwrap();
            s.write_all(&garbage).unwrap();
        });
        let mut sub = quick().reconnect(false).connect(&dir).unwrap();
        for _ in 0..1000 {
            match sub.next_event() {
                Err(SdkError::Closed) => break,
                Err(SdkError::Protocol { .. }) | Ok(_) => {}
                Err(e) => panic!("round {round}: unexpected error {e}"),
            }
        }
        assert!(!sub.is_connected());
        server.join().unwrap();
    }
}

#[test]
fn a_newer_frame_version_is_refused_clearly() {
    let (_guard, dir) = tempdir();
    let server = serve_once(&dir, |mut s| {
        let mut bytes = hello_frame(0);
        bytes[4] = frond_protocol::PROTOCOL_VERSION + 1;
        s.write_all(&bytes).unwrap();
    });
    let err = quick().connect(&dir).unwrap_err();
    let newer = frond_protocol::PROTOCOL_VERSION + 1;
    match &err {
        SdkError::Protocol { error: ProtocolError::UnsupportedVersion { got, supported }, .. } => {
            assert_eq!((*got, *supported), (newer, frond_protocol::PROTOCOL_VERSION));
        }
        other => panic!("expected UnsupportedVersion, got {other:?}"),
    }
    assert!(err.is_fatal());
    let msg = err.to_string();
    assert!(msg.contains(&format!("protocol version {newer}")), "{msg}");
    assert!(msg.contains(&format!("understands version {}", frond_protocol::PROTOCOL_VERSION)), "{msg}");
    server.join().unwrap();
}

#[test]
fn a_newer_hello_version_is_refused_clearly() {
    let (_guard, dir) = tempdir();
    let server = serve_once(&dir, |mut s| {
        let mut h = hello(0);
        h.protocol_version = 9;
        s.write_all(&frame(&ServerMessage::Hello(h))).unwrap();
    });
    let err = quick().connect(&dir).unwrap_err();
    assert!(
        matches!(err, SdkError::Protocol { error: ProtocolError::UnsupportedVersion { got: 9, .. }, .. }),
        "{err:?}"
    );
    server.join().unwrap();
}

#[test]
fn a_pose_before_the_hello_is_refused() {
    let (_guard, dir) = tempdir();
    let server = serve_once(&dir, |mut s| s.write_all(&pose_frame(0)).unwrap());
    let err = quick().connect(&dir).unwrap_err();
    assert!(matches!(err, SdkError::Protocol { error: ProtocolError::ExpectedHello, .. }), "{err:?}");
    server.join().unwrap();
}

#[test]
fn no_daemon_names_the_socket() {
    let (_guard, dir) = tempdir();
    let err = Subscriber::connect(&dir).unwrap_err();
    assert!(matches!(err, SdkError::NotRunning { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains(&dir.join("poses.sock").display().to_string()), "{msg}");
    assert!(msg.contains("not running"), "{msg}");
}

#[test]
fn a_restarted_daemon_is_a_reconnect_not_a_gap() {
    let (_guard, dir) = tempdir();
    let first = serve_poses(&dir, 100..105);
    let mut sub = quick().connect(&dir).unwrap();
    let mut events = Vec::new();
    for _ in 0..6 {
        events.push(sub.next_event().unwrap());
    }
    assert_eq!(events[5], Event::Disconnected);
    first.join().unwrap();
    // The "restarted daemon" starts numbering at 0 again.
    let dir2 = dir.clone();
    let second = thread::spawn(move || {
        thread::sleep(Duration::from_millis(150));
        serve_poses(&dir2, 0..3).join().unwrap();
    });
    let mut h = hello(0);
    h.next_seq = 0;
    assert_eq!(sub.next_event().unwrap(), Event::Reconnected(h));
    for seq in 0..3 {
        assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(seq)));
    }
    assert_eq!(
        sub.stats(),
        Stats { frames: 8, gaps: 0, missing: 0, reconnects: 1, disconnects: 1, rejected: 0, recovered: 0 }
    );
    second.join().unwrap();
}

#[test]
fn the_iterator_rides_over_a_restart() {
    let (_guard, dir) = tempdir();
    let first = serve_poses(&dir, 7..9);
    let dir2 = dir.clone();
    let second = thread::spawn(move || {
        first.join().unwrap();
        thread::sleep(Duration::from_millis(100));
        serve_poses(&dir2, 0..1).join().unwrap();
    });
    let mut sub = quick().give_up_after(Some(Duration::from_millis(400))).connect(&dir).unwrap();
    let seqs: Vec<u64> = sub.by_ref().take(3).map(|p| p.unwrap().seq).collect();
    assert_eq!(seqs, vec![7, 8, 0]);
    second.join().unwrap();
    // The second server is gone for good: the iterator yields the give-up error, then ends.
    match sub.next() {
        Some(Err(SdkError::ReconnectFailed { attempts, last, .. })) => {
            assert!(attempts >= 2, "{attempts}");
            assert!(matches!(*last, SdkError::NotRunning { .. }), "{last:?}");
        }
        other => panic!("expected ReconnectFailed, got {other:?}"),
    }
    assert!(sub.next().is_none());
    assert_eq!(sub.stats().reconnects, 1);
}

#[test]
fn a_read_timeout_keeps_a_partial_frame() {
    let (_guard, dir) = tempdir();
    let server = serve_once(&dir, |mut s| {
        s.write_all(&hello_frame(1)).unwrap();
        let bytes = pose_frame(1);
        let (a, b) = bytes.split_at(bytes.len() / 2);
        s.write_all(a).unwrap();
        thread::sleep(Duration::from_millis(300));
        s.write_all(b).unwrap();
        thread::sleep(Duration::from_millis(100));
    });
    let mut sub =
        quick().reconnect(false).read_timeout(Some(Duration::from_millis(50))).connect(&dir).unwrap();
    let mut timeouts = 0;
    let got = loop {
        match sub.next_event() {
            Err(SdkError::Timeout { timeout, .. }) => {
                assert_eq!(timeout, Duration::from_millis(50));
                timeouts += 1;
            }
            other => break other,
        }
    };
    assert_eq!(got.unwrap(), Event::Pose(pose(1)));
    assert!(timeouts >= 1);
    assert!(sub.is_connected());
    server.join().unwrap();
}

#[test]
fn a_sequence_going_backwards_is_a_protocol_error() {
    let (_guard, dir) = tempdir();
    let server = serve_once(&dir, |mut s| {
        let mut bytes = hello_frame(0);
        bytes.extend(pose_frame(4));
        bytes.extend(pose_frame(2));
        s.write_all(&bytes).unwrap();
    });
    let mut sub = quick().reconnect(false).connect(&dir).unwrap();
    assert_eq!(sub.next_event().unwrap(), Event::Gap { expected: 0, got: 4 });
    assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(4)));
    let err = sub.next_event().unwrap_err();
    assert!(
        matches!(
            err,
            SdkError::Protocol { error: ProtocolError::SeqWentBackwards { expected: 5, got: 2 }, .. }
        ),
        "{err:?}"
    );
    server.join().unwrap();
}

#[test]
fn a_table_naming_another_rig_first_is_a_rig_change() {
    use frond_protocol::{ElementTable, RigInfo};
    let (_guard, dir) = tempdir();
    let flower = RigInfo { name: "flower".into(), joint_names: vec!["a".into(), "b".into()] };
    let table = ElementTable { version: 7, rigs: vec![flower.clone()], elements: vec![] };
    let same = ElementTable { version: 8, rigs: vec![flower], elements: vec![] };
    let (t1, t2) = (table.clone(), same.clone());
    let server = serve_once(&dir, move |mut s| {
        let mut bytes = frame(&ServerMessage::Hello(hello(1)));
        bytes.extend(pose_frame(1));
        bytes.extend(frame(&ServerMessage::Elements(t1)));
        bytes.extend(frame(&ServerMessage::Elements(t2)));
        bytes.extend(pose_frame(2));
        s.write_all(&bytes).unwrap();
    });
    let mut sub = quick().reconnect(false).connect(&dir).unwrap();
    assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(1)));
    match sub.next_event().unwrap() {
        Event::RigChanged(h) => {
            assert_eq!(h.rig_name, "flower");
            assert_eq!(h.joint_names, ["a", "b"]);
            assert_eq!(h.elements, table);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(sub.next_event().unwrap(), Event::Elements(table));
    assert_eq!(sub.hello().rig_name, "flower");
    // The same rig again is only a new table.
    assert_eq!(sub.next_event().unwrap(), Event::Elements(same));
    assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(2)));
    server.join().unwrap();
}

#[test]
fn a_second_hello_is_a_rig_change() {
    let (_guard, dir) = tempdir();
    let server = serve_once(&dir, |mut s| {
        let mut h = hello(1);
        let mut bytes = frame(&ServerMessage::Hello(h.clone()));
        bytes.extend(pose_frame(1));
        h.rig_name = "flower".into();
        h.next_seq = 2;
        bytes.extend(frame(&ServerMessage::Hello(h)));
        bytes.extend(pose_frame(2));
        s.write_all(&bytes).unwrap();
    });
    let mut sub = quick().reconnect(false).connect(&dir).unwrap();
    assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(1)));
    assert!(matches!(sub.next_event().unwrap(), Event::RigChanged(h) if h.rig_name == "flower"));
    assert_eq!(sub.hello().rig_name, "flower");
    assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(2)));
    server.join().unwrap();
}

#[test]
fn a_read_timeout_returns_control_while_the_daemon_is_away() {
    let (_guard, dir) = tempdir();
    let first = serve_poses(&dir, 5..6);
    let mut sub =
        quick().give_up_after(None).read_timeout(Some(Duration::from_millis(50))).connect(&dir).unwrap();
    assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(5)));
    first.join().unwrap();
    assert_eq!(sub.next_event().unwrap(), Event::Disconnected);
    // The daemon is away and reconnection never gives up: each call still comes back, with a
    // timeout, so a caller can look at its stop flag (it used to reconnect for ever).
    let (tx, rx) = std::sync::mpsc::channel();
    let waiter = thread::spawn(move || {
        for _ in 0..5 {
            let got = sub.next_event();
            let timed_out = matches!(got, Err(SdkError::Timeout { .. }));
            tx.send(format!("{got:?}")).unwrap();
            if !timed_out {
                break;
            }
        }
        sub
    });
    for _ in 0..5 {
        let got = rx.recv_timeout(Duration::from_secs(20)).expect("next_event did not come back");
        assert!(got.starts_with("Err(Timeout"), "{got}");
    }
    let mut sub = waiter.join().unwrap();
    assert!(!sub.is_connected());
    // It comes back: a later call reconnects, and the stream goes on from the new hello.
    let second = serve_poses(&dir, 0..1);
    let mut event = None;
    for _ in 0..400 {
        match sub.next_event() {
            Err(SdkError::Timeout { .. }) => continue,
            other => {
                event = Some(other.unwrap());
                break;
            }
        }
    }
    assert_eq!(event, Some(Event::Reconnected(hello(0))));
    assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(0)));
    assert_eq!(sub.stats().reconnects, 1);
    second.join().unwrap();
}

#[test]
fn giving_up_counts_from_the_disconnection_across_timeouts() {
    let (_guard, dir) = tempdir();
    let first = serve_poses(&dir, 1..2);
    let mut sub = quick()
        .give_up_after(Some(Duration::from_millis(300)))
        .read_timeout(Some(Duration::from_millis(20)))
        .connect(&dir)
        .unwrap();
    assert_eq!(sub.next_event().unwrap(), Event::Pose(pose(1)));
    first.join().unwrap();
    assert_eq!(sub.next_event().unwrap(), Event::Disconnected);
    // Each call is shorter than the bound; were the bound counted per call, this never ends.
    let mut timeouts = 0;
    let error = loop {
        match sub.next_event() {
            Err(SdkError::Timeout { .. }) => {
                timeouts += 1;
                assert!(timeouts < 10_000, "the give-up bound never passed");
            }
            Err(e) => break e,
            Ok(event) => panic!("no daemon, yet {event:?}"),
        }
    };
    match error {
        SdkError::ReconnectFailed { attempts, last, .. } => {
            assert!(attempts >= 2, "{attempts}");
            assert!(matches!(*last, SdkError::NotRunning { .. }), "{last:?}");
        }
        other => panic!("expected ReconnectFailed, got {other:?}"),
    }
    assert!(timeouts >= 2, "control came back meanwhile: {timeouts} timeouts");
    assert!(matches!(sub.next_event(), Err(SdkError::Closed)));
}

/// Fields (protocol 3): the SDK's evaluation against the daemon's and the paper's.
#[path = "fields/agreement.rs"]
mod field_agreement;
