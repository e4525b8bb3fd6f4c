//! OSC hand input: `frondd --source osc://...` maps `/frond/hand` messages exactly as `frond map`
//! maps the same samples, and counts and drops malformed or out-of-range messages.

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use frond_e2e::{Daemon, bin, repo_root, wait_for};
use rosc::{OscMessage, OscPacket, OscType};
use serde_json::Value;

#[test]
fn osc_hand_messages_drive_the_daemon_like_frond_map() {
    let dir = tempfile::tempdir().unwrap();
    let port = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let rig = repo_root().join("rig-files/plants/flower.toml");
    let source = format!("osc://127.0.0.1:{port}");
    let daemon =
        Daemon::start(dir.path(), &["--source", &source, "--rig", rig.to_str().unwrap(), "--filter", "none"]);
    assert_eq!(daemon.status().source.kind, "osc");

    // 50 samples on the 0.01 degree grid.
    let samples: Vec<[f64; 7]> = (0..50)
        .map(|k| {
            let t = k as f64 * 0.02;
            let q = |v: f64| (v * 100.0).round() / 100.0;
            [t, q(20.0 * t.sin()), q(-7.5 * t), q(33.3), q(12.0 + t), q(40.0 - 3.0 * t), q(-5.25)]
        })
        .collect();
    let hand_jsonl: String = samples
        .iter()
        .map(|s| {
            format!(
                "{{\"t\":{},\"wrist\":[{},{},{}],\"thumb\":[{},{},{}]}}\n",
                s[0], s[1], s[2], s[3], s[4], s[5], s[6]
            )
        })
        .collect();
    let map = Command::new(bin("frond"))
        .args(["map", "--filter", "none", "--rig"])
        .arg(&rig)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    map.stdin.as_ref().unwrap().write_all(hand_jsonl.as_bytes()).unwrap();
    let expected = map.wait_with_output().unwrap();
    assert!(expected.status.success());
    let expected: Vec<Value> = String::from_utf8(expected.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();

    let mut tap = daemon.frond().args(["tap", "--jsonl"]).stdout(Stdio::piped()).spawn().unwrap();
    let lines = BufReader::new(tap.stdout.take().unwrap()).lines();
    std::thread::sleep(Duration::from_millis(300)); // let tap subscribe
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    let send = |p: &OscPacket| tx.send_to(&rosc::encoder::encode(p).unwrap(), ("127.0.0.1", port)).unwrap();
    for (k, s) in samples.iter().enumerate() {
        let mut args = vec![OscType::Double(s[0])];
        args.extend(s[1..].iter().map(|v| OscType::Float(*v as f32)));
        send(&OscPacket::Message(OscMessage { addr: "/frond/hand".into(), args }));
        if k % 10 == 0 {
            // Hostile neighbours: garbage, wrong arity, out of range, another address.
            tx.send_to(b"\xff\xfe not osc", ("127.0.0.1", port)).unwrap();
            send(&OscPacket::Message(OscMessage { addr: "/frond/hand".into(), args: vec![OscType::Int(1)] }));
            let mut wild = vec![OscType::Double(s[0]), OscType::Float(9999.0)];
            wild.extend([0.0f32; 5].map(OscType::Float));
            send(&OscPacket::Message(OscMessage { addr: "/frond/hand".into(), args: wild }));
            send(&OscPacket::Message(OscMessage { addr: "/other".into(), args: vec![] }));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    for line in lines {
        got.push(serde_json::from_str::<Value>(&line.unwrap()).unwrap());
        if got.len() == samples.len() || Instant::now() > deadline {
            break;
        }
    }
    let _ = tap.kill();
    let _ = tap.wait();
    assert_eq!(got.len(), samples.len());
    for (g, e) in got.iter().zip(&expected) {
        assert_eq!(g["joints"], e["joints"], "live {g} != offline {e}");
    }
    assert!(
        wait_for(Duration::from_secs(2), || daemon.status().source.rejected == 20),
        "{:?}",
        daemon.status()
    );
    assert_eq!(daemon.status().source.reports, 50);
}

/// Issue 18: `frond-vhid --osc HOST:PORT` is the reference sender for the OSC input. It drives a
/// daemon's `osc://` source like a tracker bridge would: every sample a report, each published
/// fresh, with the glove's faults carried over (a corrupted report arrives as bytes that are not
/// OSC and is counted as rejected, never mapped).
#[test]
fn the_reference_osc_sender_drives_the_osc_source() {
    let dir = tempfile::tempdir().unwrap();
    let port = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let source = format!("osc://127.0.0.1:{port}");
    let daemon = Daemon::start(dir.path(), &["--source", &source]);
    let target = format!("127.0.0.1:{port}");
    let (mut glove, first_line, _out) =
        frond_e2e::start_vhid(&["--osc", &target, "--rate", "500", "--corrupt", "0.1", "--seed", "7"]);
    assert_eq!(first_line.to_str(), Some(format!("osc://{target}").as_str()));
    assert!(
        wait_for(Duration::from_secs(10), || {
            let s = daemon.status().source;
            s.reports > 500 && s.rejected > 20
        }),
        "{:?}",
        daemon.status().source
    );
    let s = daemon.status().source;
    assert_eq!(s.kind, "osc");
    // About one in ten reports corrupted: rejected, the rest mapped.
    let share = s.rejected as f64 / (s.reports + s.rejected) as f64;
    assert!((0.04..0.2).contains(&share), "{} of {} rejected", s.rejected, s.reports + s.rejected);
    let mut sub = frond_sdk::Subscriber::connect(&daemon.socket_dir).unwrap();
    let fresh = frond_e2e::fresh_poses(&mut sub, 50, Duration::from_secs(5));
    assert_eq!(fresh.len(), 50, "fresh poses from the OSC sender");
    // The sway moves: the poses are not all one.
    assert!(fresh.windows(2).any(|w| w[0].joints_deg != w[1].joints_deg));
    let _ = glove.terminate(Duration::from_secs(5));
}

/// Issue 42: what a hostile sender's datagrams cost the OSC source is counted by reason in
/// status (`frond status --json`), and said in the log at a bounded rate: thousands of refused
/// datagrams make one line (per hand and 10 s), not thousands.
#[test]
fn refused_osc_datagrams_are_counted_by_reason_and_logged_at_a_bounded_rate() {
    let dir = tempfile::tempdir().unwrap();
    let port = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let source = format!("osc://127.0.0.1:{port}");
    let log = dir.path().join("frondd.log");
    let daemon = Daemon::start_with_stderr(
        dir.path(),
        &["--source", &source, "--rig", "grass"],
        std::fs::File::create(&log).unwrap().into(),
    );
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    let message = |addr: &str, args: Vec<f32>| {
        rosc::encoder::encode(&OscPacket::Message(OscMessage {
            addr: addr.into(),
            args: args.into_iter().map(OscType::Float).collect(),
        }))
        .unwrap()
    };
    let other = message("/not/frond", vec![0.0; 7]);
    let wild = message("/frond/hand", vec![0.0, 1000.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let (garbage, others, wilds) = (300u64, 200u64, 100u64);
    // Paced, so that the kernel drops none of them.
    for k in 0..(garbage + others + wilds) {
        let bytes: &[u8] = if k < garbage {
            b"\xffnot osc at all"
        } else if k < garbage + others {
            &other
        } else {
            &wild
        };
        tx.send_to(bytes, ("127.0.0.1", port)).unwrap();
        if k % 10 == 0 {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    let counted =
        wait_for(Duration::from_secs(10), || daemon.status().source.rejected >= garbage + others + wilds);
    let status = daemon.status().source;
    assert!(counted, "{status:?}");
    let by: Vec<(&str, u64)> = status.rejected_by_reason.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    assert_eq!(by, [("malformed", garbage), ("out_of_range", wilds), ("wrong_id", others)], "{status:?}");
    // The same counts in `frond status --json`.
    let json: Value = serde_json::from_str(&daemon.frond_ok(&["status", "--json"])).unwrap();
    let shown = &json["hands"][0]["source"]["rejected_by_reason"];
    assert_eq!(shown["malformed"], garbage, "{json}");
    // Said once, with every reason, in the second after.
    let said = wait_for(Duration::from_secs(5), || {
        std::fs::read_to_string(&log).unwrap().contains("refused 600 reports")
    });
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(said, "{text}");
    assert!(
        text.contains("malformed 300") && text.contains("wrong_id 200") && text.contains("out_of_range 100"),
        "{text}"
    );
    assert_eq!(text.matches("refused").count(), 1, "{text}");
}
