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

pub(crate) const PORT: u16 = 7447;

/// Skips (with the reason on stderr) where namespaces cannot be made.
pub(crate) fn lan(hosts: usize) -> Option<Lan> {
    if let Some(why) = netns::unavailable() {
        eprintln!("skipped: {why}");
        return None;
    }
    Some(Lan::new(hosts))
}

fn bridge(host: &Host, daemon: &Daemon, stage: &str, source: &str) -> Proc {
    start_zenoh_bridge(
        host.command(bin("frond-zenoh")),
        daemon,
        stage,
        source,
        &["--listen", &host.endpoint(PORT)],
    )
}

/// The lines a process prints on stdout, each with the time it arrived, and its stderr.
#[derive(Default)]
pub(crate) struct Tapped {
    pub(crate) lines: Vec<(Instant, String)>,
    pub(crate) stderr: Vec<String>,
}

/// Starts `cmd` and collects its stdout and stderr lines on two threads.
pub(crate) fn collect(mut cmd: Command, name: &str) -> (Proc, Arc<Mutex<Tapped>>) {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("start {name}: {e}"));
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
    (Proc { child, name: name.into() }, out)
}

/// Starts `frond [global] tap --jsonl --include-held [tap_args]` (on `host`, or here when
/// `None`) and collects its output.
pub(crate) fn tap(host: Option<&Host>, global: &[&str], tap_args: &[&str]) -> (Proc, Arc<Mutex<Tapped>>) {
    let mut cmd = match host {
        Some(h) => h.command(bin("frond")),
        None => Command::new(bin("frond")),
    };
    cmd.args(global).args(["tap", "--jsonl", "--include-held"]).args(tap_args);
    collect(cmd, "frond tap")
}

pub(crate) fn seq_of(line: &str) -> u64 {
    let v: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{line}: {e}"));
    v["seq"].as_u64().unwrap_or_else(|| panic!("no seq in {line}"))
}

pub(crate) fn lines(t: &Arc<Mutex<Tapped>>) -> usize {
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

/// Every line a remote tap printed whose frame the daemon's own host also tapped is that very
/// line, and there are more than 500 such frames.
pub(crate) fn assert_same_lines(remote: &Arc<Mutex<Tapped>>, local: &Arc<Mutex<Tapped>>, who: &str) {
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
    assert_same_lines(&remote_a, &local_a, "glove-a");
    assert_same_lines(&remote_b, &local_b, "glove-b");

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

    // Performer B's host drops off the network for 4 s, then comes back. Meanwhile its daemon
    // changes rig: the new element table and hello are published while nobody can hear them.
    let cut = Instant::now();
    b.set_link(false);
    std::thread::sleep(Duration::from_millis(500));
    daemon_b.frond_ok(&["rig", "set", "flower"]);
    std::thread::sleep(Duration::from_millis(3500));
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
    // The subscriber asked again for the table after the gap, and so learnt of the rig change it
    // missed (the link came back within Zenoh's lease: no rejoin, no new hello on its own).
    assert!(
        wait_for(Duration::from_secs(10), || remote_b
            .lock()
            .unwrap()
            .stderr
            .iter()
            .any(|l| l.contains("rig changed to flower"))),
        "the workstation never learnt of performer B's rig change: {:?}",
        remote_b.lock().unwrap().stderr
    );
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

/// The flags' names, from the README's table (independent of frond's `PoseFlags::names`).
fn flag_names(bits: u64) -> Vec<&'static str> {
    let table = [(1, "held"), (2, "device_lost"), (4, "filtered"), (8, "recording"), (16, "playback")];
    table.iter().filter(|(bit, _)| bits & bit != 0).map(|(_, name)| *name).collect()
}

/// Asserts a line of `zenoh_reader.py` (from the MessagePack frame, decoded in Python) says
/// what the daemon host's `frond tap --jsonl` line says about the same frame.
fn assert_same_frame(python: &serde_json::Value, tap: &serde_json::Value) {
    let what = format!("python {python} vs tap {tap}");
    assert_eq!(python["seq"], tap["seq"], "{what}");
    assert_eq!(python["t"].as_f64(), tap["t"].as_f64(), "{what}");
    let angles = |v: &serde_json::Value| -> Vec<f32> {
        let joints = v["joints"].as_array().unwrap_or_else(|| panic!("no joints: {what}"));
        joints.iter().flat_map(|j| j.as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32)).collect()
    };
    assert_eq!(angles(python), angles(tap), "{what}");
    assert_eq!(python["element"].as_u64().unwrap(), tap["element"].as_u64().unwrap_or(0), "{what}");
    let tap_flags: Vec<&str> =
        tap["flags"].as_array().map_or(Vec::new(), |f| f.iter().map(|n| n.as_str().unwrap()).collect());
    assert_eq!(flag_names(python["flags"].as_u64().unwrap()), tap_flags, "{what}");
}

/// Issue 20's independent reader: a Python `eclipse-zenoh` subscriber on another host decodes
/// the published frames with a plain MessagePack library; order, gaps (its link is cut for 3 s)
/// and values agree with `frond tap` on the daemon's host, while a third host subscribes and
/// never reads, which slows nobody.
#[test]
fn a_python_reader_on_another_host_agrees_with_tap_beside_a_peer_that_never_reads() {
    let Some(py) = crate::python::python_with("zenoh, msgpack") else {
        return crate::python::skip(
            "no eclipse-zenoh in tests/python/.venv (run exporters/zenoh/tests/install-python.sh)",
        );
    };
    let Some(lan) = lan(3) else { return };
    let (performer, reader_host, idle_host) = (&lan.hosts[0], &lan.hosts[1], &lan.hosts[2]);
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start_on(performer, dir.path(), &["--source", "in-process"]);
    let bridge = bridge(performer, &daemon, "stage1", "glove-a");
    let script =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../exporters/zenoh/tests/zenoh_reader.py");
    let reader_args = |host: &Host, seconds: &str, extra: &[&str]| {
        let mut cmd = host.command(&py);
        cmd.arg(&script)
            .args([
                "--connect",
                &performer.endpoint(PORT),
                "--key",
                "frond/stage1/glove-a",
                "--seconds",
                seconds,
            ])
            .args(extra);
        cmd
    };
    let (_tap, local) = tap(None, &["--socket-dir", daemon.socket_dir.to_str().unwrap()], &[]);

    // The peer that never reads subscribes first and stays for the whole run.
    let (mut idle, idle_out) = collect(reader_args(idle_host, "40", &["--never-read"]), "never-reading peer");
    assert!(
        wait_for(Duration::from_secs(20), || idle_out
            .lock()
            .unwrap()
            .stderr
            .iter()
            .any(|l| l.contains("subscribed"))),
        "the never-reading peer did not subscribe: {:?}",
        idle_out.lock().unwrap().stderr
    );
    std::thread::sleep(Duration::from_secs(1));

    let (mut reader, out) = collect(reader_args(reader_host, "14", &[]), "zenoh_reader.py");
    assert!(
        wait_for(Duration::from_secs(20), || lines(&out) > 1500),
        "the Python reader got {} frames in 20 s; stderr {:?}",
        lines(&out),
        out.lock().unwrap().stderr
    );
    let cut = Instant::now();
    reader_host.set_link(false);
    std::thread::sleep(Duration::from_secs(3));
    let restored = Instant::now();
    reader_host.set_link(true);
    let status = wait_for(Duration::from_secs(40), || reader.child.try_wait().ok().flatten().is_some());
    assert!(status, "the Python reader did not finish");
    let out = out.lock().unwrap();
    assert!(out.stderr.iter().any(|l| l.starts_with("ok:")), "the Python reader failed: {:?}", out.stderr);
    let hello = out.stderr.iter().find(|l| l.starts_with("hello:")).expect("a hello line");
    let protocol = format!("protocol={}", frond_protocol::PROTOCOL_VERSION);
    assert!(hello.contains("rate=1000") && hello.contains(&protocol), "{hello}");
    assert_eq!(
        hello.split("joints=").nth(1).unwrap().split(' ').next().unwrap().split(',').count(),
        4,
        "{hello}"
    );

    // Order and values: every frame the reader decoded that the daemon's host tapped is the same.
    let local: HashMap<u64, serde_json::Value> = local
        .lock()
        .unwrap()
        .lines
        .iter()
        .map(|(_, l)| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .map(|v| (v["seq"].as_u64().unwrap(), v))
        .collect();
    let frames: Vec<serde_json::Value> =
        out.lines.iter().map(|(_, l)| serde_json::from_str(l).unwrap()).collect();
    let common = frames.iter().filter(|f| local.contains_key(&f["seq"].as_u64().unwrap()));
    let checked = common.inspect(|f| assert_same_frame(f, &local[&f["seq"].as_u64().unwrap()])).count();
    assert!(checked > 3000, "only {checked} of the Python reader's frames matched the daemon's host");

    // Gaps: the cut lost frames, the reader said how many, and it resumed afterwards.
    let missing = missing(&out.lines);
    assert!(missing > 0, "a 3 s cut at 1 kHz lost no frame?");
    assert_eq!(missing, reported_missing(&out.stderr), "{:?}", out.stderr);
    let after = out.lines.iter().filter(|(t, _)| *t > restored + Duration::from_secs(1)).count();
    assert!(after > 1000, "the Python reader got {after} frames after the link came back");
    // The reader's stream before the cut never stalled, though one peer never read.
    let before: Vec<Instant> = out.lines.iter().map(|(t, _)| *t).filter(|t| *t < cut).collect();
    let stall = before.windows(2).map(|w| w[1] - w[0]).max().unwrap();
    assert!(stall < Duration::from_secs(1), "the reader's stream stalled for {stall:?} beside the idle peer");
    eprintln!(
        "python reader: {} frames, {checked} checked against tap, {missing} missing (reported)",
        frames.len()
    );
    // The reader reported its counts over the documented replay wire (docs/zenoh.md), last after
    // it stopped reading: the bridge lists it by its name with exactly what it counted.
    let from = format!("zenoh:frond/stage1/glove-a?connect={}", performer.endpoint(PORT));
    let status =
        reader_host.command(bin("frond")).args(["status", "--json", "--from", &from]).output().unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let report: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    let peers = report["zenoh_peers"].as_array().unwrap_or_else(|| panic!("no zenoh_peers: {report}"));
    let python = peers.iter().find(|p| p["peer"] == "zenoh_reader.py").unwrap_or_else(|| panic!("{peers:?}"));
    assert_eq!(python["frames"].as_u64(), Some(frames.len() as u64), "{python}");
    assert_eq!(python["missing"].as_u64(), Some(missing), "{python}");

    // The never-reading peer is still subscribed, and the bridge still runs.
    assert!(
        idle.child.try_wait().unwrap().is_none(),
        "the never-reading peer exited: {:?}",
        idle_out.lock().unwrap().stderr
    );
    let mut bridge = bridge;
    assert!(bridge.child.try_wait().unwrap().is_none(), "the bridge exited");
}

/// Issue 20's several performers on one timeline: performer B's host has a clock 250 ms ahead
/// (the bridge's test hook), a recorder on a third host records the whole stage, one take per
/// performer, and `frond take export --align` puts both takes on one timeline. The truth to
/// check it against is independent of frond: the namespaces share this machine's
/// `CLOCK_MONOTONIC`, so a frame's place on the timeline minus its monotonic stamp must be the
/// same for every frame of both takes, within 1 ms (without the correction it is 250 ms apart).
#[test]
fn a_remote_recorder_puts_two_performers_on_one_timeline_despite_a_clock_offset() {
    const OFFSET_NS: i64 = 250_000_000;
    let Some(lan) = lan(3) else { return };
    let (a, b, recorder) = (&lan.hosts[0], &lan.hosts[1], &lan.hosts[2]);
    let (dir_a, dir_b, takes) =
        (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let daemon_a = Daemon::start_on(a, dir_a.path(), &["--source", "in-process"]);
    let daemon_b = Daemon::start_on(b, dir_b.path(), &["--source", "in-process"]);
    let _bridge_a = bridge(a, &daemon_a, "stage1", "glove-a");
    let mut skewed = b.command(bin("frond-zenoh"));
    skewed.env("FROND_TEST_CLOCK_OFFSET_NS", OFFSET_NS.to_string());
    let _bridge_b =
        start_zenoh_bridge(skewed, &daemon_b, "stage1", "glove-b", &["--listen", &b.endpoint(PORT)]);
    // Both bridges up before the recording starts (it records whoever is on the stage).
    for (host, source) in [(a, "glove-a"), (b, "glove-b")] {
        let from = format!("zenoh:frond/stage1/{source}?connect={}", host.endpoint(PORT));
        let out = recorder
            .command(bin("frond"))
            .args(["tap", "--jsonl", "--count", "5", "--from", &from])
            .output()
            .unwrap();
        assert!(out.status.success(), "{source}: {}", String::from_utf8_lossy(&out.stderr));
    }

    let takes_dir = takes.path().to_str().unwrap();
    // The recorder's host also listens (a peer others may connect to), from a Zenoh configuration
    // file: every source's subscription shares one session, so the port is bound once.
    let zenoh_config = takes.path().join("recorder.json5");
    std::fs::write(&zenoh_config, r#"{ mode: "peer", listen: { endpoints: ["tcp/0.0.0.0:7450"] } }"#)
        .unwrap();
    let out = recorder
        .command(bin("frond"))
        .args(["--takes-dir", takes_dir, "record", "start", "take1", "--stage", "stage1"])
        .args(["--connect", &a.endpoint(PORT), "--connect", &b.endpoint(PORT), "--for", "4"])
        .arg("--zenoh-config")
        .arg(&zenoh_config)
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the stage recording failed:\n{stdout}\n{stderr}");
    eprintln!("{stdout}{stderr}");
    // The recorder measured B's clock 250 ms ahead and A's in step, each within 1 ms.
    let measured = |source: &str| -> f64 {
        let line = stdout
            .lines()
            .find(|l| l.starts_with(&format!("recording {source} ")))
            .unwrap_or_else(|| panic!("{stdout}"));
        line.split("its clock is ").nth(1).unwrap().split(" ms").next().unwrap().parse().unwrap()
    };
    assert!(measured("glove-a").abs() < 1.0, "{stdout}");
    assert!((measured("glove-b") - OFFSET_NS as f64 / 1e6).abs() < 1.0, "{stdout}");

    let out = Command::new(bin("frond"))
        .args(["--takes-dir", takes_dir, "take", "export", "--align", "take1-glove-a", "take1-glove-b"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut per_take: HashMap<String, Vec<i128>> = HashMap::new();
    let mut last_stage = 0u64;
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let stage_ns = v["stage_ns"].as_u64().unwrap();
        assert!(stage_ns >= last_stage, "aligned frames out of timeline order at {line}");
        last_stage = stage_ns;
        let d = i128::from(stage_ns) - i128::from(v["host_ns"].as_u64().unwrap());
        per_take.entry(v["take"].as_str().unwrap().to_owned()).or_default().push(d);
    }
    let (da, db) = (&per_take["take1-glove-a"], &per_take["take1-glove-b"]);
    assert!(da.len() > 2000 && db.len() > 2000, "{} and {} aligned frames", da.len(), db.len());
    let all = da.iter().chain(db.iter());
    let spread = all.clone().max().unwrap() - all.min().unwrap();
    eprintln!("aligned: {} + {} frames, timeline minus monotonic spread {spread} ns", da.len(), db.len());
    assert!(spread <= 1_000_000, "the aligned takes disagree with the shared clock by {spread} ns");
}

/// Issue 20's "selector over several sources": `frond tap --from 'zenoh:frond/stage1/*'` on the
/// workstation follows every performer of the stage, including one whose bridge joins after the
/// tap started, each line tagged with its source and otherwise the very line the performer's own
/// host prints; `frond status --from` the same selector answers for both.
#[test]
fn a_selector_follows_every_performer_including_one_that_joins_later() {
    let Some(lan) = lan(3) else { return };
    let (a, b, ws) = (&lan.hosts[0], &lan.hosts[1], &lan.hosts[2]);
    let (dir_a, dir_b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let daemon_a = Daemon::start_on(a, dir_a.path(), &["--source", "in-process"]);
    let _bridge_a = bridge(a, &daemon_a, "stage1", "glove-a");
    let selector = format!("zenoh:frond/stage1/*?connect={},{}", a.endpoint(PORT), b.endpoint(PORT));
    let (_tap, remote) = tap(Some(ws), &[], &["--from", &selector]);
    let (_tap_a, local_a) = tap(None, &["--socket-dir", daemon_a.socket_dir.to_str().unwrap()], &[]);
    let source_lines = |source: &str| {
        remote
            .lock()
            .unwrap()
            .lines
            .iter()
            .filter(|(_, l)| l.starts_with(&format!("{{\"source\":\"stage1/{source}\",")))
            .count()
    };
    assert!(
        wait_for(Duration::from_secs(30), || source_lines("glove-a") > 500),
        "no poses of glove-a through the selector: {:?}",
        remote.lock().unwrap().stderr
    );

    // Performer B joins the stage while the tap runs.
    let daemon_b = Daemon::start_on(b, dir_b.path(), &["--source", "in-process"]);
    let _bridge_b = bridge(b, &daemon_b, "stage1", "glove-b");
    let (_tap_b, local_b) = tap(None, &["--socket-dir", daemon_b.socket_dir.to_str().unwrap()], &[]);
    assert!(
        wait_for(Duration::from_secs(30), || source_lines("glove-b") > 500 && source_lines("glove-a") > 1500),
        "glove-b ({}) was not followed after it joined; stderr {:?}",
        source_lines("glove-b"),
        remote.lock().unwrap().stderr
    );

    // Each tagged line, without its tag, is the line the performer's host printed for that frame.
    for (source, local) in [("glove-a", &local_a), ("glove-b", &local_b)] {
        let tag = format!("{{\"source\":\"stage1/{source}\",");
        let untagged = Arc::new(Mutex::new(Tapped::default()));
        untagged.lock().unwrap().lines = remote
            .lock()
            .unwrap()
            .lines
            .iter()
            .filter_map(|(t, l)| l.strip_prefix(&tag).map(|rest| (*t, format!("{{{rest}"))))
            .collect();
        assert_same_lines(&untagged, local, source);
        // What it missed (if anything, on a loaded machine), it reported for that source.
        let stderr = remote.lock().unwrap().stderr.clone();
        let own: Vec<String> =
            stderr.iter().filter(|l| l.contains(&format!("stage1/{source}: gap: "))).cloned().collect();
        assert_eq!(missing(&untagged.lock().unwrap().lines), reported_missing(&own), "{source}: {stderr:?}");
    }
    let stderr = remote.lock().unwrap().stderr.join("\n");
    assert!(
        stderr.contains("following stage1/glove-a") && stderr.contains("following stage1/glove-b"),
        "{stderr}"
    );

    let out = ws.command(bin("frond")).args(["status", "--json", "--from", &selector]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let keys: Vec<&String> = v.as_object().expect("an object of reports").keys().collect();
    assert_eq!(keys, ["stage1/glove-a", "stage1/glove-b"]);
    for key in keys {
        assert_eq!(v[key]["tick_rate_hz"], 1000, "{key}: {}", v[key]);
    }
}
