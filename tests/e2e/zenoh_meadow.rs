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
use frond_sdk::field::LiveFields;
use frond_sdk::{Relayed, Subscriber};

use crate::meadow::compact_field;
use crate::stage_net::{PORT, Tapped, collect, lan, lines};

/// The field's tables and frames as the daemon sent them, in order, read on its socket.
fn record_field(daemon: &Daemon, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<Vec<FieldMessage>> {
    let mut sub = Subscriber::options()
        .read_timeout(Some(Duration::from_millis(200)))
        .connect(&daemon.socket_dir)
        .expect("subscribe on the daemon's socket");
    std::thread::spawn(move || {
        let mut got = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            if let Ok(Relayed::Field(msg)) = sub.next_relayed() {
                got.push(msg);
            }
        }
        got
    })
}

/// Checks one line of `field_plants`: every plant of the field at the line's frame, against
/// `messages` played up to that frame into a field of the SDK's here.
fn check_line(line: &str, messages: &[FieldMessage], who: &str) {
    let v: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{who}: {e}"));
    let seq = v["seq"].as_u64().expect("seq");
    assert_eq!(v["plants"], 10_000, "{who}");
    let mut fields = LiveFields::keeping(0);
    let mut applied = false;
    for msg in messages {
        match msg {
            FieldMessage::Table(t) => assert!(fields.on_table(t.clone()).is_empty(), "{who}"),
            FieldMessage::Frame(f) => {
                fields.on_frame(f);
                if f.seq == seq {
                    applied = true;
                    break;
                }
            }
        }
    }
    assert!(applied, "{who}: frame {seq} never reached the daemon's socket subscriber");
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
    let recorder = record_field(&daemon, stop.clone());
    let (_early, early) = field_plants(b, &from, 2, "field_plants (early)");
    std::thread::sleep(Duration::from_secs(2));
    let field = compact_field(&daemon, "sway", 100, 100);
    daemon.frond_ok(&[
        "field",
        "start",
        "--take",
        "sway",
        "--field",
        field.to_str().unwrap(),
        "--plants",
        "4",
    ]);

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
