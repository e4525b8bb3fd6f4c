//! frond on Zenoh, on one host (loopback): a `frond-zenoh` bridge beside the daemon, and a
//! subscriber that reads the same poses over Zenoh as a socket subscriber reads from the daemon,
//! sees the daemon stop as a disconnect and its return as a reconnection.

use std::collections::HashMap;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use frond_e2e::{Daemon, Proc, bin, start_zenoh_bridge, wait_for};
use frond_sdk::{Event, Pose, Source, Subscriber};

/// A loopback port free now, below Linux's ephemeral range (32768 and up): a port the kernel
/// handed out for `:0` is free only until it hands it out again, and the Zenoh sessions of the
/// tests running beside this one open outgoing connections from that range all the time.
pub(crate) fn free_port() -> u16 {
    use std::sync::atomic::{AtomicU16, Ordering};
    static NEXT: AtomicU16 = AtomicU16::new(0);
    let spread = (std::process::id() % 1000) as u16 * 12;
    loop {
        let port = 20_000 + (spread + NEXT.fetch_add(1, Ordering::Relaxed)) % 12_000;
        if std::net::TcpListener::bind(("127.0.0.1", port)).is_ok() {
            return port;
        }
    }
}

/// `frond-zenoh` for `daemon` as `frond/<stage>/<source>`, listening on loopback `port`.
fn start_bridge(daemon: &Daemon, stage: &str, source: &str, port: u16) -> Proc {
    start_zenoh_bridge(
        Command::new(bin("frond-zenoh")),
        daemon,
        stage,
        source,
        &["--listen", &format!("tcp/127.0.0.1:{port}")],
    )
}

fn poses(sub: &mut Subscriber, n: usize) -> Vec<Pose> {
    let mut out = Vec::new();
    while out.len() < n {
        if let Event::Pose(p) = sub.next_event().expect("pose stream") {
            out.push(p);
        }
    }
    out
}

#[test]
fn a_zenoh_subscriber_reads_the_sockets_poses_and_follows_a_daemon_restart() {
    let dir = tempfile::tempdir().unwrap();
    let mut daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let port = free_port();
    let stage = format!("e2e{}", std::process::id());
    let _bridge = start_bridge(&daemon, &stage, "glove-a", port);
    let source: Source = format!("zenoh:frond/{stage}/glove-a?connect=tcp/127.0.0.1:{port}").parse().unwrap();
    let opts = || Subscriber::options().hello_timeout(Duration::from_secs(10));
    let mut remote = opts().subscribe(&source).expect("subscribe over Zenoh");
    let mut local = Subscriber::connect(&daemon.socket_dir).unwrap();
    assert_eq!(remote.hello().rig_name, local.hello().rig_name);
    assert_eq!(remote.hello().joint_names, local.hello().joint_names);
    assert_eq!(remote.elements(), local.elements());

    // The same frames, byte for byte in value, where their sequence numbers overlap.
    let remote_poses = poses(&mut remote, 500);
    let local_poses: HashMap<u64, Pose> = poses(&mut local, 1500).into_iter().map(|p| (p.seq, p)).collect();
    let common: Vec<&Pose> = remote_poses.iter().filter(|p| local_poses.contains_key(&p.seq)).collect();
    assert!(common.len() > 100, "only {} poses in common", common.len());
    for p in common {
        assert_eq!(*p, local_poses[&p.seq], "pose {} differs over Zenoh", p.seq);
    }
    assert!(remote_poses.windows(2).all(|w| w[1].seq > w[0].seq), "out of order over Zenoh");

    // The daemon stops: the bridge withdraws its token and the subscriber sees a disconnect;
    // a new daemon on the same sockets is a reconnection, with its poses after it.
    daemon.proc.terminate(Duration::from_secs(5)).expect("frondd exits on SIGTERM");
    let deadline = Instant::now() + Duration::from_secs(15);
    loop {
        match remote.next_event().expect("event") {
            Event::Disconnected => break,
            _ => assert!(Instant::now() < deadline, "no disconnect within 15 s of the daemon stopping"),
        }
    }
    let again = Daemon::start(dir.path(), &["--source", "in-process"]);
    match remote.next_event().expect("reconnect") {
        Event::Reconnected(hello) => assert_eq!(hello.rig_name, again_rig(&again)),
        other => panic!("expected a reconnection, got {other:?}"),
    }
    assert_eq!(poses(&mut remote, 50).len(), 50);
    assert_eq!((remote.stats().disconnects, remote.stats().reconnects), (1, 1));

    // `frond tap` and `frond status` take the same address.
    let tap = Command::new(bin("frond"))
        .args(["tap", "--count", "3", "--include-held", "--from", &source.to_string()])
        .output()
        .unwrap();
    assert!(tap.status.success(), "{}", String::from_utf8_lossy(&tap.stderr));
    assert_eq!(String::from_utf8_lossy(&tap.stdout).lines().count(), 3);
    let status = Command::new(bin("frond"))
        .args(["status", "--json", "--from", &source.to_string()])
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let report: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    assert_eq!(report["rig_name"].as_str(), Some(again.status().rig_name.as_str()), "{report}");
    assert!(report["ticks"].as_u64().is_some_and(|t| t > 0), "{report}");
    // With the bridge's subscribers as it counts them (issue 43): `remote` above has reported
    // the poses it passed on since the reconnection (at least the 50 read), and missed none.
    let peers = report["zenoh_peers"].as_array().unwrap_or_else(|| panic!("no zenoh_peers: {report}"));
    assert!(
        peers.iter().any(|p| p["frames"].as_u64().is_some_and(|f| f >= 50) && p["missing"] == 0),
        "{peers:?}"
    );
    let table = Command::new(bin("frond")).args(["status", "--from", &source.to_string()]).output().unwrap();
    let table = String::from_utf8_lossy(&table.stdout);
    assert!(table.contains(&format!("zenoh peers  {} reporting\n", peers.len())), "{table}");
    assert!(table.contains(" missing, 0 recovered (0 replayed), "), "{table}");

    // A source nobody publishes is a clear error, not a hang.
    let missing: Source = format!("zenoh:frond/{stage}/nobody?connect=tcp/127.0.0.1:{port}").parse().unwrap();
    let err = Subscriber::options().hello_timeout(Duration::from_secs(2)).subscribe(&missing).unwrap_err();
    assert!(err.to_string().contains("no frond-zenoh bridge answered"), "{err}");
    // It names what is there instead, so that a misspelt name is plain to see.
    let there = err.to_string().split_once("; on the network: ").map(|(_, names)| names.to_owned());
    assert!(there.is_some_and(|names| names.split(", ").any(|n| n == format!("{stage}/glove-a"))), "{err}");
}

fn again_rig(daemon: &Daemon) -> String {
    Subscriber::connect(&daemon.socket_dir).unwrap().hello().rig_name.clone()
}

/// A performer who leaves for good: its daemon stops and does not come back. Its bridge still
/// stops on SIGTERM, and a stage recording that was following it still ends on time with both
/// takes closed. Both used to wait for ever: the SDK's reconnection never gave control back
/// to a caller watching its stop flag, even with a read timeout.
#[test]
fn a_performer_who_leaves_for_good_holds_up_neither_its_bridge_nor_the_stage_recording() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;

    let stage = format!("leave{}", std::process::id());
    let (dir_a, dir_b, takes) =
        (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let daemon_a = Daemon::start(dir_a.path(), &["--source", "in-process"]);
    let mut daemon_b = Daemon::start(dir_b.path(), &["--source", "in-process"]);
    let port_a = free_port();
    let port_b = std::iter::repeat_with(free_port).find(|&p| p != port_a).unwrap();
    let _bridge_a = start_bridge(&daemon_a, &stage, "glove-a", port_a);
    let mut bridge_b = start_bridge(&daemon_b, &stage, "glove-b", port_b);
    let connect = |port: u16| format!("tcp/127.0.0.1:{port}");
    let child = Command::new(bin("frond"))
        .arg("--takes-dir")
        .arg(takes.path())
        .args(["record", "start", "take1", "--stage", &stage, "--for", "8"])
        .args(["--connect", &connect(port_a), "--connect", &connect(port_b)])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    // Killed when dropped, so a recording that hangs fails the test instead of outliving it.
    let mut recorder = Proc { child, name: "frond record --stage".into() };
    let (tx, lines) = std::sync::mpsc::channel();
    let stdout = BufReader::new(recorder.child.stdout.take().unwrap());
    std::thread::spawn(move || {
        for line in stdout.lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let mut out = Vec::new();
    while out.iter().filter(|l: &&String| l.starts_with("recording ")).count() < 2 {
        let line = lines.recv_timeout(Duration::from_secs(30)).expect("the recorder found both performers");
        out.push(line);
    }
    std::thread::sleep(Duration::from_secs(1));

    // Performer B leaves: its daemon stops for good, then its bridge is told to stop.
    daemon_b.proc.terminate(Duration::from_secs(5)).expect("frondd exits on SIGTERM");
    std::thread::sleep(Duration::from_secs(1));
    let status = bridge_b
        .terminate(Duration::from_secs(10))
        .expect("frond-zenoh stops on SIGTERM while its daemon is away");
    assert!(status.success(), "frond-zenoh: {status}");

    // The recording ends at --for and closes both takes.
    let deadline = Instant::now() + Duration::from_secs(40);
    let status = loop {
        if let Some(status) = recorder.child.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "the stage recording did not end; said so far: {out:?}");
        std::thread::sleep(Duration::from_millis(100));
    };
    out.extend(lines.try_iter());
    assert!(status.success(), "the stage recording failed: {out:?}");
    for source in ["glove-a", "glove-b"] {
        let line = out
            .iter()
            .find(|l| l.contains(&format!("take1-{source}.take: ")))
            .unwrap_or_else(|| panic!("no summary of {source}'s take: {out:?}"));
        let frames: u64 = line.split(": ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
        assert!(frames > 500, "{line}");
    }
}

/// Zenoh panics on a `ZENOH_RUNTIME` it cannot parse (even an empty one) or on a pool of no
/// threads; every frond program that opens Zenoh says what is wrong with it instead, and exits 1.
#[test]
fn a_bad_zenoh_runtime_variable_is_an_error_naming_it_in_every_program() {
    let dir = tempfile::tempdir().unwrap();
    let from = "zenoh:frond/nowhere/nobody";
    let out = dir.path().join("x.glb");
    let runs: [(&str, Vec<&str>); 5] = [
        (
            "frond-zenoh",
            vec!["--stage", "nowhere", "--source", "nobody", "--socket-dir", dir.path().to_str().unwrap()],
        ),
        ("frond", vec!["tap", "--count", "1", "--from", from]),
        ("frond", vec!["status", "--from", from]),
        ("frond-osc", vec!["--from", from]),
        ("frond-gltf", vec!["live", "--rig", "grass", "--from", from, "-o", out.to_str().unwrap()]),
    ];
    for value in ["", "(rx: (worker_threads: 0))"] {
        for (program, args) in &runs {
            let run = Command::new(bin(program)).args(args).env("ZENOH_RUNTIME", value).output().unwrap();
            let stderr = String::from_utf8_lossy(&run.stderr);
            assert_eq!(
                run.status.code(),
                Some(1),
                "{program} {args:?} with ZENOH_RUNTIME={value:?}: {stderr}"
            );
            assert!(!stderr.contains("panicked"), "{program}: {stderr}");
            assert!(
                stderr.contains(&format!("ZENOH_RUNTIME={value:?}")) && stderr.contains("unset it"),
                "{program} {args:?}: {stderr}"
            );
        }
    }
}

/// `frond-zenoh` for `daemon` as `frond/<stage>/same`, on loopback `port` (and connected to
/// `peer`), its log (info and up) going to the file `log`.
fn start_logged_bridge(daemon: &Daemon, stage: &str, port: u16, peer: Option<u16>, log: &Path) -> Proc {
    let mut cmd = Command::new(bin("frond-zenoh"));
    cmd.args(["--stage", stage, "--source", "same", "--log-level", "info"])
        .args(["--listen", &format!("tcp/127.0.0.1:{port}")])
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(log).unwrap());
    if let Some(peer) = peer {
        cmd.args(["--connect", &format!("tcp/127.0.0.1:{peer}")]);
    }
    Proc { child: cmd.spawn().expect("start frond-zenoh"), name: "frond-zenoh same".into() }
}

/// Waits up to 15 s for `log` to hold `words`.
fn log_says(log: &Path, words: &str) -> bool {
    wait_for(Duration::from_secs(15), || std::fs::read_to_string(log).unwrap_or_default().contains(words))
}

/// Two bridges started under one name (two daemons on one host, both taking the host's name
/// when `--source` is left out): every subscriber used to get both daemons' poses interleaved
/// under one key and stop on "sequence number went backwards". The elder bridge publishes; the
/// younger one says so and stands by, publishing nothing, and takes over when the elder stops.
#[test]
fn a_second_bridge_under_a_taken_name_stands_by_and_takes_over_when_the_first_stops() {
    let (dir_a, dir_b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let daemon_a = Daemon::start(dir_a.path(), &["--source", "in-process", "--rig", "grass"]);
    let daemon_b = Daemon::start(dir_b.path(), &["--source", "in-process", "--rig", "flower"]);
    let stage = format!("clash{}", std::process::id());
    let (port_a, port_b) = (free_port(), free_port());
    let (log_a, log_b) = (dir_a.path().join("bridge.log"), dir_b.path().join("bridge.log"));
    let mut bridge_a = start_logged_bridge(&daemon_a, &stage, port_a, None, &log_a);
    let via = |port: u16| -> Source {
        format!("zenoh:frond/{stage}/same?connect=tcp/127.0.0.1:{port}").parse().unwrap()
    };
    let opts = || Subscriber::options().hello_timeout(Duration::from_secs(10));
    let mut first = opts().subscribe(&via(port_a)).expect("subscribe to the first bridge");
    assert_eq!(first.hello().rig_name, "grass");

    let _bridge_b = start_logged_bridge(&daemon_b, &stage, port_b, Some(port_a), &log_b);
    assert!(
        log_says(&log_b, "another frond-zenoh already publishes under this name: this one stands by"),
        "the second bridge never said it stands by: {}",
        std::fs::read_to_string(&log_b).unwrap_or_default()
    );
    assert!(
        log_says(&log_a, "a second frond-zenoh started under this name"),
        "the first bridge was not told"
    );

    // Through either bridge's endpoint, one daemon's poses: the numbers never step back (two
    // daemons' streams under one key would, and the SDK would stop on it). A gap may happen:
    // Zenoh drops poses when this loaded machine's path is congested.
    let mut second = opts().subscribe(&via(port_b)).expect("subscribe through the second bridge");
    assert_eq!(second.hello().rig_name, "grass", "the bridge standing by answered the hello");
    for sub in [&mut first, &mut second] {
        let got = poses(sub, 1000);
        assert!(got.windows(2).all(|w| w[1].seq > w[0].seq), "a step back");
    }

    // The first bridge stops: the second takes over, and a subscriber follows it to its daemon.
    bridge_a.terminate(Duration::from_secs(5)).expect("the first bridge exits on SIGTERM");
    assert!(log_says(&log_b, "under this name is gone: publishing"), "the second bridge did not take over");
    let deadline = Instant::now() + Duration::from_secs(15);
    loop {
        assert!(Instant::now() < deadline, "no hello of the second daemon within 15 s");
        match second.next_event().expect("event") {
            Event::Reconnected(hello) | Event::RigChanged(hello) if hello.rig_name == "flower" => break,
            _ => {}
        }
    }
    let got = poses(&mut second, 300);
    assert!(got.windows(2).all(|w| w[1].seq > w[0].seq), "out of order after the takeover");
    let mut local_b = Subscriber::connect(&daemon_b.socket_dir).unwrap();
    let now_b = poses(&mut local_b, 1)[0].seq;
    assert!(got.last().unwrap().seq.abs_diff(now_b) < 5_000, "not the second daemon's poses");
}

const DIRECTOR_KEY: &str = "d1d2d3d4d5d6d7d8d9dadbdcdddedfe0e1e2e3e4e5e6e7e8e9eaebecedeeeff0f1";
const VIEWER_KEY: &str = "0f0e0d0c0b0a09080706050403020100f0e0d0c0b0a090807060504030201000";

/// Remote control, end to end on loopback: one principal spending its whole rate budget leaves
/// another's requests served (the bridge's nonces were one store for everybody, so a flood by
/// one principal made every request "busy"), and each principal's requests give their pending
/// slot back when answered. An allow-list its group may read is refused at start, with the mode
/// and the fix and without a key.
#[test]
fn one_remote_principal_spending_its_budget_leaves_another_served() {
    use std::os::unix::fs::PermissionsExt;

    use frond_protocol::{ControlReply, ControlRequest};
    use frond_sdk::ControlClientError;
    use frond_sdk::control_auth::ControlKey;
    use frond_sdk::zenoh_control::RemoteControl;

    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let policy = dir.path().join("control.toml");
    std::fs::write(
        &policy,
        format!(
            "[[principal]]\nname = \"director\"\nkey = \"{DIRECTOR_KEY}\"\n\n\
             [[principal]]\nname = \"viewer\"\nkey = \"{VIEWER_KEY}\"\nallow = [\"read\"]\n"
        ),
    )
    .unwrap();
    let policy_arg = policy.to_str().unwrap();
    let stage = format!("ctl{}", std::process::id());

    std::fs::set_permissions(&policy, std::fs::Permissions::from_mode(0o640)).unwrap();
    // Killed when dropped: a bridge that takes the file runs on, and must not hang the test.
    let mut refused = Proc {
        child: Command::new(bin("frond-zenoh"))
            .args(["--stage", &stage, "--source", "glove-a", "--control", policy_arg])
            .arg("--socket-dir")
            .arg(&daemon.socket_dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
        name: "frond-zenoh --control (mode 640)".into(),
    };
    let exited = wait_for(Duration::from_secs(10), || refused.child.try_wait().unwrap().is_some());
    assert!(exited, "frond-zenoh took an allow-list its group may read");
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut refused.child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(refused.child.wait().unwrap().code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!("{policy_arg}: mode 640: its group may read it"))
            && stderr.contains(&format!("chmod 600 {policy_arg}")),
        "{stderr}"
    );
    assert!(!stderr.contains(&DIRECTOR_KEY[..8]) && !stderr.contains(&VIEWER_KEY[..8]), "{stderr}");

    std::fs::set_permissions(&policy, std::fs::Permissions::from_mode(0o600)).unwrap();
    let port = free_port();
    let _bridge = start_zenoh_bridge(
        Command::new(bin("frond-zenoh")),
        &daemon,
        &stage,
        "glove-a",
        &["--listen", &format!("tcp/127.0.0.1:{port}"), "--control", policy_arg],
    );
    let Source::Zenoh(addr) =
        format!("zenoh:frond/{stage}/glove-a?connect=tcp/127.0.0.1:{port}").parse::<Source>().unwrap()
    else {
        panic!("not a Zenoh address")
    };
    let open = |name: &str, key: &str| {
        let mut c = RemoteControl::open(&addr, name, ControlKey::from_hex(key).unwrap()).unwrap();
        c.set_timeout(Duration::from_secs(15));
        c
    };
    let (mut director, mut viewer) = (open("director", DIRECTOR_KEY), open("viewer", VIEWER_KEY));
    let status = |c: &mut RemoteControl| c.request(&ControlRequest::Status);
    assert!(matches!(status(&mut viewer), Ok(ControlReply::Status(_))), "the viewer reads");

    // The director asks for status, one request after another, until the bridge says its
    // budget is spent: past its 4 pending slots (each given back when answered) and its burst
    // of 20, and long before the old shared store of 4096 nonces filled.
    let mut served = 0;
    let refusal = loop {
        match status(&mut director) {
            Ok(ControlReply::Status(_)) => served += 1,
            Err(ControlClientError::Refused { message, .. }) => break message,
            other => panic!("after {served} requests: {other:?}"),
        }
        assert!(served < 1000, "1000 requests in a row and no rate limit");
    };
    assert!(served >= 20, "only {served} served before: {refusal}");
    assert!(refusal.contains("\"director\" sent more than 20 requests at once"), "{refusal}");
    // The viewer is served all the same.
    assert!(
        matches!(status(&mut viewer), Ok(ControlReply::Status(_))),
        "the viewer after the director's flood"
    );
}

/// Issue 43's callback-driven subscription (`frond_sdk::zenoh_callback`): poses handed to a
/// closure on Zenoh's thread are the daemon socket's very poses, in order, numbered from the
/// hello; the subscription reports its counts to the bridge like a `Subscriber`; and after it is
/// dropped its closure is called no more.
#[test]
fn a_callback_subscription_hands_over_the_sockets_poses_on_zenohs_thread() {
    use std::sync::{Arc, Mutex};
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let port = free_port();
    let stage = format!("e2ecb{}", std::process::id());
    let _bridge = start_bridge(&daemon, &stage, "glove-a", port);
    let source: Source = format!("zenoh:frond/{stage}/glove-a?connect=tcp/127.0.0.1:{port}").parse().unwrap();
    let Source::Zenoh(addr) = &source else { unreachable!() };
    let got: Arc<Mutex<Vec<Event>>> = Arc::default();
    let sink = got.clone();
    let sub = frond_sdk::zenoh_callback::subscribe(
        addr,
        &Subscriber::options().hello_timeout(Duration::from_secs(10)),
        move |e| sink.lock().unwrap().push(e),
    )
    .expect("a callback subscription");
    assert_eq!(sub.hello().rig_name, again_rig(&daemon));
    let mut local = Subscriber::connect(&daemon.socket_dir).unwrap();
    let local: HashMap<u64, Pose> = poses(&mut local, 1500).into_iter().map(|p| (p.seq, p)).collect();
    let events = std::mem::take(&mut *got.lock().unwrap());
    let remote: Vec<&Pose> =
        events.iter().filter_map(|e| if let Event::Pose(p) = e { Some(p) } else { None }).collect();
    assert!(remote.first().is_some_and(|p| p.seq >= sub.hello().next_seq), "a pose from before the hello");
    assert!(remote.windows(2).all(|w| w[1].seq > w[0].seq), "out of order");
    let common: Vec<&&Pose> = remote.iter().filter(|p| local.contains_key(&p.seq)).collect();
    assert!(common.len() > 100, "only {} poses in common of {}", common.len(), remote.len());
    for p in common {
        assert_eq!(**p, local[&p.seq], "pose {} differs", p.seq);
    }
    // Loopback at 1 kHz loses nothing: no gap, and the counts are the poses handed over.
    assert!(!events.iter().any(|e| matches!(e, Event::Gap { .. })), "a gap on loopback");
    assert!(sub.stats().frames >= remote.len() as u64 && sub.stats().missing == 0, "{:?}", sub.stats());

    // Its counts reach the bridge (once a second), as frond status lists them.
    let reported = wait_for(Duration::from_secs(10), || {
        let out = Command::new(bin("frond"))
            .args(["status", "--json", "--from", &source.to_string()])
            .output()
            .unwrap();
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
        report["zenoh_peers"].as_array().is_some_and(|peers| {
            peers.iter().any(|p| p["frames"].as_u64().is_some_and(|f| f >= 1000) && p["missing"] == 0)
        })
    });
    assert!(reported, "the bridge never listed the callback subscription's counts");

    drop(sub);
    let after = got.lock().unwrap().len();
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(got.lock().unwrap().len(), after, "the closure ran after the subscription was dropped");
}
