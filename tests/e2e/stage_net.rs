//! A stage across machines: three "hosts" (network namespaces on one switch), two performers
//! (a daemon and its `frond-zenoh` bridge on each of two hosts) and an artist's workstation on
//! the third, which taps both sources and drives an OSC receiver with a remote `frond-osc`.
//! Then the second performer's link goes down and comes back: the first keeps streaming, the
//! second's subscriber reports what it missed and resumes, and nothing is restarted.

use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use frond_e2e::netns::{self, Host, Lan};
use frond_e2e::{Daemon, Proc, bin, start_zenoh_bridge, wait_for};

const PORT: u16 = 7447;

/// Skips (with the reason on stderr) where namespaces cannot be made.
fn lan(hosts: usize) -> Option<Lan> {
    if let Some(why) = netns::unavailable() {
        eprintln!("skipped: {why}");
        return None;
    }
    Some(Lan::new(hosts))
}

fn bridge(host: &Host, daemon: &Daemon, stage: &str, source: &str) -> Proc {
    start_zenoh_bridge(host.command(bin("frond-zenoh")), daemon, stage, source, &host.endpoint(PORT))
}

/// The lines a `frond tap --jsonl` prints, each with the time it arrived, and its stderr.
#[derive(Default)]
struct Tapped {
    lines: Vec<(Instant, String)>,
    stderr: Vec<String>,
}

/// Starts `frond [global] tap --jsonl --include-held [tap_args]` (on `host`, or here when
/// `None`) and collects its output on two threads.
fn tap(host: Option<&Host>, global: &[&str], tap_args: &[&str]) -> (Proc, Arc<Mutex<Tapped>>) {
    let mut cmd = match host {
        Some(h) => h.command(bin("frond")),
        None => Command::new(bin("frond")),
    };
    let mut child = cmd
        .args(global)
        .args(["tap", "--jsonl", "--include-held"])
        .args(tap_args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start frond tap");
    let out = Arc::new(Mutex::new(Tapped::default()));
    let (stdout, stderr) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
    let o = out.clone();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            o.lock().unwrap().lines.push((Instant::now(), line));
        }
    });
    let o = out.clone();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            o.lock().unwrap().stderr.push(line);
        }
    });
    (Proc { child, name: "frond tap".into() }, out)
}

fn seq_of(line: &str) -> u64 {
    let v: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{line}: {e}"));
    v["seq"].as_u64().unwrap_or_else(|| panic!("no seq in {line}"))
}

fn lines(t: &Arc<Mutex<Tapped>>) -> usize {
    t.lock().unwrap().lines.len()
}

/// The frames missing between consecutive lines (sequence numbers that never arrived).
fn missing(lines: &[(Instant, String)]) -> u64 {
    let seqs: Vec<u64> = lines.iter().map(|(_, l)| seq_of(l)).collect();
    assert!(seqs.windows(2).all(|w| w[1] > w[0]), "sequence numbers out of order");
    seqs.windows(2).map(|w| w[1] - w[0] - 1).sum()
}

/// Frames missing according to `frond tap`'s "gap: N frames missing" lines.
fn reported_missing(stderr: &[String]) -> u64 {
    stderr.iter().filter_map(|l| l.split("gap: ").nth(1)?.split(' ').next()?.parse::<u64>().ok()).sum()
}

#[test]
fn two_performers_one_workstation_and_a_link_that_goes_down_and_up() {
    let Some(lan) = lan(3) else { return };
    let (a, b, ws) = (&lan.hosts[0], &lan.hosts[1], &lan.hosts[2]);
    let stage = "stage1";
    let (dir_a, dir_b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let daemon_a = Daemon::start_on(a, dir_a.path(), &["--source", "in-process"]);
    let daemon_b = Daemon::start_on(b, dir_b.path(), &["--source", "in-process"]);
    let _bridge_a = bridge(a, &daemon_a, stage, "glove-a");
    let _bridge_b = bridge(b, &daemon_b, stage, "glove-b");
    let from_a = format!("zenoh:frond/{stage}/glove-a?connect={}", a.endpoint(PORT));
    let from_b = format!("zenoh:frond/{stage}/glove-b?connect={}", b.endpoint(PORT));

    // The workstation taps both performers; performer A's own host taps its socket.
    let socket_a = daemon_a.socket_dir.to_str().unwrap().to_string();
    let (_tap_local_a, local_a) = tap(None, &["--socket-dir", &socket_a], &[]);
    let (_tap_a, remote_a) = tap(Some(ws), &[], &["--from", &from_a]);
    let (_tap_b, remote_b) = tap(Some(ws), &[], &["--from", &from_b]);

    // A remote frond-osc on the workstation drives a receiver there from performer B.
    let receiver = ws.run_inside(|| std::net::UdpSocket::bind("127.0.0.1:0").unwrap());
    let receiver = receiver.join().unwrap();
    receiver.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let target = format!("127.0.0.1:{}", receiver.local_addr().unwrap().port());
    let _osc = Proc {
        child: ws
            .command(bin("frond-osc"))
            .args(["--from", &from_b, "--target", &target, "--log-level", "warn"])
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start frond-osc"),
        name: "frond-osc".into(),
    };
    let (_tap_local_b, local_b) = tap(None, &["--socket-dir", daemon_b.socket_dir.to_str().unwrap()], &[]);

    assert!(
        wait_for(Duration::from_secs(30), || lines(&remote_a) > 1000 && lines(&remote_b) > 1000),
        "the workstation did not get 1000 poses of each performer within 30 s: {} and {}; stderr: {:?} {:?}",
        lines(&remote_a),
        lines(&remote_b),
        remote_a.lock().unwrap().stderr,
        remote_b.lock().unwrap().stderr
    );

    // Over Zenoh, the very lines the daemon's own host prints, where their frames overlap.
    for (remote, local, who) in [(&remote_a, &local_a, "glove-a"), (&remote_b, &local_b, "glove-b")] {
        let local: HashMap<u64, String> =
            local.lock().unwrap().lines.iter().map(|(_, l)| (seq_of(l), l.clone())).collect();
        let remote = remote.lock().unwrap();
        let common: Vec<&String> =
            remote.lines.iter().map(|(_, l)| l).filter(|l| local.contains_key(&seq_of(l))).collect();
        assert!(common.len() > 500, "{who}: only {} frames in common with the daemon's host", common.len());
        for l in common {
            assert_eq!(l, &local[&seq_of(l)], "{who}: a frame differs between the hosts");
        }
    }

    // The OSC receiver on the workstation gets performer B's frames, with the values its host sees.
    let osc = receive_osc_poses(&receiver, 200);
    let local: HashMap<u64, String> =
        local_b.lock().unwrap().lines.iter().map(|(_, l)| (seq_of(l), l.clone())).collect();
    let checked = osc
        .iter()
        .filter_map(|(seq, joints)| local.get(&(*seq as u64)).map(|l| (joints, l)))
        .inspect(|(joints, l)| assert_eq!(**joints, joints_of(l), "an OSC frame differs from {l}"))
        .count();
    assert!(checked > 50, "only {checked} OSC frames matched the daemon's host");

    // Performer B's host drops off the network for 4 s, then comes back.
    let cut = Instant::now();
    b.set_link(false);
    std::thread::sleep(Duration::from_secs(4));
    let restored = Instant::now();
    b.set_link(true);

    // Performer A streamed throughout, without a stall.
    let during: Vec<Instant> = remote_a
        .lock()
        .unwrap()
        .lines
        .iter()
        .map(|(t, _)| *t)
        .filter(|t| *t > cut && *t < restored)
        .collect();
    assert!(during.len() > 1000, "only {} of performer A's frames arrived during B's outage", during.len());
    let stall = during.windows(2).map(|w| w[1] - w[0]).max().unwrap();
    assert!(stall < Duration::from_secs(1), "performer A's stream stalled for {stall:?} during B's outage");

    // Performer B's subscriber resumes, and what it lost it reported, frame for frame.
    let before = lines(&remote_b);
    assert!(
        wait_for(Duration::from_secs(40), || remote_b
            .lock()
            .unwrap()
            .lines
            .iter()
            .filter(|(t, _)| *t > restored + Duration::from_secs(1))
            .count()
            > 500),
        "performer B's stream did not resume within 40 s of the link coming back ({} lines before, {} now; stderr {:?})",
        before,
        lines(&remote_b),
        remote_b.lock().unwrap().stderr
    );
    let t = remote_b.lock().unwrap();
    let b_during = t.lines.iter().filter(|(at, _)| *at > cut && *at < restored).count();
    eprintln!(
        "performer B: {} frames missing, {b_during} arrived during the outage; stderr {:?}",
        missing(&t.lines),
        t.stderr
    );
    assert_eq!(
        missing(&t.lines),
        reported_missing(&t.stderr),
        "the frames missing from the stream are not the frames the subscriber reported: {:?}",
        t.stderr
    );
    drop(t);
    // The OSC receiver gets frames again too.
    assert!(!receive_osc_poses(&receiver, 50).is_empty());
}

/// Reads `/frond/pose` messages (seq, t, 12 angles) until `n` arrived or 10 s passed.
fn receive_osc_poses(socket: &std::net::UdpSocket, n: usize) -> Vec<(i32, Vec<f32>)> {
    let mut out = Vec::new();
    let mut buf = vec![0u8; 65536];
    let deadline = Instant::now() + Duration::from_secs(10);
    while out.len() < n && Instant::now() < deadline {
        let Ok(len) = socket.recv(&mut buf) else { continue };
        let (_, packet) = rosc::decoder::decode_udp(&buf[..len]).expect("an OSC packet");
        collect_poses(&packet, &mut out);
    }
    out
}

fn collect_poses(packet: &rosc::OscPacket, out: &mut Vec<(i32, Vec<f32>)>) {
    match packet {
        rosc::OscPacket::Bundle(b) => b.content.iter().for_each(|p| collect_poses(p, out)),
        rosc::OscPacket::Message(m) if m.addr == "/frond/pose" => {
            let Some(rosc::OscType::Int(seq)) = m.args.first() else {
                panic!("/frond/pose without seq: {m:?}")
            };
            let joints = m.args[2..].iter().map(|a| a.clone().float().expect("float angle")).collect();
            out.push((*seq, joints));
        }
        rosc::OscPacket::Message(_) => {}
    }
}

fn joints_of(line: &str) -> Vec<f32> {
    let v: serde_json::Value = serde_json::from_str(line).unwrap();
    v["joints"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|j| j.as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32))
        .collect()
}
