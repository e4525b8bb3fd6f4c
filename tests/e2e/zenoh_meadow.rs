//! A meadow across machines (issue 48, over issue 43's bridge): a daemon on host 0 plays a live
//! field of 10,000 plants, `frond-zenoh` passes it on as the daemon publishes it (its
//! definition and its frames, not a pose stream per plant), and the SDK's example
//! `field_plants` on host 1 evaluates every plant over `zenoh:`. Every angle it prints agrees
//! within 1e-4 degrees with the same field frame evaluated here from the daemon's own socket
//! (the frames and tables as the daemon sent them, played into a field of the SDK's); once for
//! a subscriber that was there when the field started, once for one that joined late and got
//! the field's table from the bridge's queryable. Beside them, issue 43's independent Python
//! reader, which is not on the SDK, reads the same `poses` key while the field runs: it skips
//! the field frames as docs/protocol.md says a reader may, and loses no number.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use frond_e2e::netns::Host;
use frond_e2e::{Daemon, Proc, bin, start_zenoh_bridge, wait_for};
use frond_protocol::field::FieldMessage;
use frond_sdk::Source;
use frond_sdk::Subscriber;
use std::process::Command;

use crate::field_socket::{played_to, record_field};
use crate::meadow::{compact_field, daemon_with_sway};
use crate::stage_net::{PORT, Tapped, collect, lan, lines};
use crate::zenoh::free_port;

/// Checks one line of `field_plants`: every plant of the field at the line's frame, against
/// `messages` played up to that frame into a field of the SDK's here.
fn check_line(line: &str, messages: &[FieldMessage], who: &str) {
    let v: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{who}: {e}"));
    let seq = v["seq"].as_u64().expect("seq");
    assert_eq!(v["plants"], 10_000, "{who}");
    let fields = played_to(messages, seq, who);
    let field = fields.by_source("field").expect("the field runs");
    assert!(field.history_complete(), "{who}: the socket subscriber has the whole history at {seq}");
    let tau = field.tau_s();
    assert_eq!(v["tau_s"].as_f64(), Some(tau), "{who}: frame {seq}'s stream time");
    let remote = v["joints_deg"].as_array().expect("joints_deg");
    assert_eq!(remote.len(), 10_000, "{who}");
    let mut worst = 0.0_f64;
    for (i, plant) in remote.iter().enumerate() {
        let here = field.plant_pose(i, tau).unwrap_or_else(|| panic!("{who}: plant {i} here"));
        let there: Vec<f64> = plant
            .as_array()
            .unwrap_or_else(|| panic!("{who}: plant {i} not evaluated there: {plant}"))
            .iter()
            .flat_map(|j| j.as_array().expect("a joint").iter().map(|a| a.as_f64().expect("an angle")))
            .collect();
        assert_eq!(there.len(), 12, "{who}: plant {i}");
        for (a, b) in here.iter().flatten().zip(&there) {
            worst = worst.max((f64::from(*a) - b).abs());
        }
    }
    assert!(worst <= 1e-4, "{who}: frame {seq}: an angle differs by {worst} degrees");
}

/// Plays take `sway` as a field of `rows` x `cols` plants, `plants` of them announced.
pub(crate) fn start_field(daemon: &Daemon, rows: usize, cols: usize, plants: &str) {
    let field = compact_field(daemon, "sway", rows, cols);
    daemon.frond_ok(&[
        "field",
        "start",
        "--take",
        "sway",
        "--field",
        field.to_str().unwrap(),
        "--plants",
        plants,
    ]);
}

/// The SDK's example `field_plants` on `host`, printing `frames` field frames from `from`.
fn field_plants(host: &Host, from: &str, frames: usize, name: &str) -> (Proc, Arc<Mutex<Tapped>>) {
    let mut cmd = host.command(bin("examples/field_plants"));
    cmd.arg(from).env("FIELD_FRAMES", frames.to_string());
    collect(cmd, name)
}

#[test]
fn a_remote_sdk_subscriber_evaluates_ten_thousand_plants_as_the_daemons_host_does() {
    let Some(lan) = lan(2) else { return };
    let (a, b) = (&lan.hosts[0], &lan.hosts[1]);
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start_on(a, dir.path(), &["--source", "in-process", "--rig", "grass"]);
    daemon.frond_ok(&["record", "start", "sway"]);
    std::thread::sleep(Duration::from_secs(2));
    daemon.frond_ok(&["record", "stop"]);
    let stage = format!("meadow{}", std::process::id());
    let _bridge = start_zenoh_bridge(
        a.command(bin("frond-zenoh")),
        &daemon,
        &stage,
        "glove",
        &["--listen", &a.endpoint(PORT)],
    );
    let from = format!("zenoh:frond/{stage}/glove?connect={}", a.endpoint(PORT));

    // Here, the daemon's own stream; on host 1, a subscriber there before the field starts.
    let stop = Arc::new(AtomicBool::new(false));
    let recorder = record_field(&daemon.socket_dir, stop.clone());
    let (_early, early) = field_plants(b, &from, 2, "field_plants (early)");
    std::thread::sleep(Duration::from_secs(2));
    start_field(&daemon, 100, 100, "4");

    // The independent reader (no frond code) on host 1, for 6 s of the running field.
    let python = crate::python::python_with("zenoh, msgpack").map(|py| {
        let script =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../exporters/zenoh/tests/zenoh_reader.py");
        let mut cmd = b.command(py);
        cmd.arg(script).args(["--connect", &a.endpoint(PORT), "--key", &format!("frond/{stage}/glove")]);
        cmd.args(["--seconds", "6"]);
        collect(cmd, "zenoh_reader.py")
    });

    let printed = |t: &Arc<Mutex<Tapped>>, n| {
        wait_for(Duration::from_secs(40), || {
            lines(t) >= n || t.lock().unwrap().stderr.iter().any(|l| l.contains("Error"))
        })
    };
    assert!(printed(&early, 1), "no plants from host 1: {:?}", early.lock().unwrap().stderr);
    // The field's table was put once, long ago: a subscriber that joins now asks for it.
    let (_late, late) = field_plants(b, &from, 1, "field_plants (late)");
    assert!(printed(&early, 2) && printed(&late, 1), "late: {:?}", late.lock().unwrap().stderr);
    let python = python.map(|(mut reader, out)| {
        let done = wait_for(Duration::from_secs(40), || reader.child.try_wait().ok().flatten().is_some());
        assert!(done, "the Python reader did not finish");
        out
    });
    stop.store(true, Ordering::Relaxed);
    let messages = recorder.join().unwrap();
    match python {
        Some(out) => check_python_reader(&out.lock().unwrap(), &messages),
        None => crate::python::skip("no eclipse-zenoh in tests/python/.venv: the Python reader's part"),
    }
    for (who, out) in [("early", &early), ("late", &late)] {
        let out = out.lock().unwrap();
        assert!(!out.lines.is_empty(), "{who}: {:?}", out.stderr);
        for (_, line) in &out.lines {
            check_line(line, &messages, who);
        }
    }
}

/// What the stage subscriber's fields gave at one field frame: its source, number, stream time
/// and three plants' poses.
type Seen = (String, u64, f64, Vec<[[f32; 3]; 4]>);

/// A field of each of two performers' daemons, read by one `StageSubscriber` over the stage's
/// selector (loopback): `StageFields` keeps each source's field apart, and at every field frame
/// it took, plants of each (the first, one inside, the last) are what that source's daemon
/// socket gives for the same frame, played into a field here. The announced plants of each
/// source arrive as poses too, tagged with their source.
#[test]
fn a_stage_subscriber_keeps_each_sources_field_as_its_daemon_sends_it() {
    use frond_sdk::zenoh_many::{StageEvent, StageFields, StageSubscriber};
    let (dir_a, dir_b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let daemons = [
        daemon_with_sway(dir_a.path(), Duration::from_secs(2)),
        daemon_with_sway(dir_b.path(), Duration::from_secs(2)),
    ];
    let stage = format!("fields{}", std::process::id());
    let ports = [free_port(), free_port()];
    let endpoint = |port: u16| format!("tcp/127.0.0.1:{port}");
    let _bridges: Vec<Proc> = ["a", "b"]
        .iter()
        .zip(&daemons)
        .zip(ports)
        .map(|((name, d), port)| {
            start_zenoh_bridge(
                Command::new(bin("frond-zenoh")),
                d,
                &stage,
                name,
                &["--listen", &endpoint(port)],
            )
        })
        .collect();
    let stop = Arc::new(AtomicBool::new(false));
    let recorders: Vec<_> = daemons.iter().map(|d| record_field(&d.socket_dir, stop.clone())).collect();
    // Two sizes, so that a field taken for the other source's shows.
    let sizes = [(10, 20), (15, 15)];
    for (d, &(rows, cols)) in daemons.iter().zip(&sizes) {
        start_field(d, rows, cols, "2");
    }
    let from = format!("zenoh:frond/{stage}/*?connect={},{}", endpoint(ports[0]), endpoint(ports[1]));
    let Ok(Source::Zenoh(addr)) = from.parse::<Source>() else { panic!("{from}") };
    let sub =
        StageSubscriber::open(&addr, Subscriber::options().hello_timeout(Duration::from_secs(10))).unwrap();
    let mut fields = StageFields::new();
    // (source, frame, stream time, plants 0 / 57 / last) at each frame taken with the history whole.
    let mut seen: Vec<Seen> = Vec::new();
    let mut plant_poses: HashMap<String, usize> = HashMap::new();
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    let enough = |seen: &[Seen], s: &str| seen.iter().filter(|x| x.0 == s).count() >= 30;
    while !(enough(&seen, &format!("{stage}/a")) && enough(&seen, &format!("{stage}/b"))) {
        assert!(
            std::time::Instant::now() < deadline,
            "30 frames of each field within 60 s: {:?}",
            seen.iter().map(|x| &x.0).collect::<std::collections::BTreeSet<_>>()
        );
        let Some(item) = sub.next_event(Some(Duration::from_secs(1))).unwrap() else { continue };
        if let StageEvent::Event { source, event: frond_sdk::Event::Pose(p) } = &item
            && p.element.get() != 0
        {
            *plant_poses.entry(source.clone()).or_default() += 1;
        }
        let frame = match &item {
            StageEvent::Field { message, .. } => match &**message {
                FieldMessage::Frame(f) => Some(f.seq),
                FieldMessage::Table(_) => None,
            },
            _ => None,
        };
        let Some((source, live)) = fields.on_event(&item) else { continue };
        let Some(seq) = frame else { continue };
        let live: Vec<_> = live.iter().collect();
        assert_eq!(live.len(), 1, "{source}: one field per source");
        let field = live[0];
        if !field.history_complete() {
            continue;
        }
        let n = field.plants();
        let tau = field.tau_s();
        let poses = [0, 57, n - 1].iter().map(|&i| field.plant_pose(i, tau).expect("evaluable")).collect();
        seen.push((source.to_owned(), seq, tau, poses));
    }
    stop.store(true, Ordering::Relaxed);
    let sent: Vec<Vec<FieldMessage>> = recorders.into_iter().map(|r| r.join().unwrap()).collect();
    for (source, seq, tau, poses) in &seen {
        let k = usize::from(source.ends_with("/b"));
        let who = format!("{source} frame {seq}");
        let here = played_to(&sent[k], *seq, &who);
        let field = here.by_source("field").expect("the field runs");
        assert_eq!(field.plants(), sizes[k].0 * sizes[k].1, "{who}");
        assert_eq!(field.tau_s(), *tau, "{who}");
        for (&i, got) in [0, 57, field.plants() - 1].iter().zip(poses) {
            let want = field.plant_pose(i, *tau).unwrap();
            let worst = want
                .iter()
                .flatten()
                .zip(got.iter().flatten())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f32::max);
            assert!(worst <= 1e-4, "{who}: plant {i} differs by {worst} degrees");
        }
    }
    for s in ["a", "b"] {
        let n = plant_poses.get(&format!("{stage}/{s}")).copied().unwrap_or(0);
        assert!(n > 20, "{s}: {n} announced plants' poses");
    }
}

/// Issue 43's independent reader beside a field: it decoded every frame (no error, no gap), the
/// field frames it printed are the daemon's (number, announced poses, stream time, as read on
/// the daemon's socket), and its poses and field frames' spans cover every sequence number
/// from its first line to its last (`seq + max(poses, 1)` follows a field frame).
fn check_python_reader(out: &Tapped, messages: &[FieldMessage]) {
    let ok = out.stderr.iter().find(|l| l.starts_with("ok:"));
    let ok = ok.unwrap_or_else(|| panic!("the Python reader failed: {:?}", out.stderr));
    assert!(ok.ends_with(", 0 gaps (0 missing)"), "{ok}");
    let frames: HashMap<u64, &frond_protocol::field::FieldFrame> = messages
        .iter()
        .filter_map(|m| if let FieldMessage::Frame(f) = m { Some((f.seq, f)) } else { None })
        .collect();
    let lines: Vec<serde_json::Value> =
        out.lines.iter().map(|(_, l)| serde_json::from_str(l).unwrap()).collect();
    let mut next: Option<u64> = None;
    let mut fields = 0;
    for v in &lines {
        let seq = v["seq"].as_u64().unwrap_or_else(|| panic!("no seq: {v}"));
        if let Some(n) = next {
            assert_eq!(seq, n, "the Python reader's line after number {} is {v}", n - 1);
        }
        let covers = match v.get("field") {
            None => 1,
            Some(_) => {
                fields += 1;
                let daemon =
                    frames.get(&seq).unwrap_or_else(|| panic!("{v}: not a field frame of the daemon's"));
                assert_eq!(v["poses"].as_u64(), Some(u64::from(daemon.poses)), "{v}");
                assert_eq!(v["tau_s"].as_f64(), Some(daemon.tau_s), "{v}");
                assert_eq!(v["field"].as_u64(), Some(u64::from(daemon.field.get())), "{v}");
                u64::from(daemon.poses).max(1)
            }
        };
        next = Some(seq + covers);
    }
    // 6 s at 60 field frames a second, among 1,000 poses a second.
    assert!(fields > 200 && lines.len() > 4000, "{fields} field frames in {} lines", lines.len());
    assert!(ok.contains(&format!("({fields} field frames)")), "{ok}");
}
