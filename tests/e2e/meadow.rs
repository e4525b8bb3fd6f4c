//! A live field of ten thousand plants (protocol 3; seed 000, section 6.2-6.3) through the real
//! daemon and `frond`: what the daemon publishes per field frame does not grow with the field,
//! the SDK evaluates every plant, the announced plants still arrive as poses, and a key
//! changes the controls the frames carry.

use std::io::Read;
use std::os::unix::net::UnixStream;
use std::time::{Duration, Instant};

use frond_e2e::Daemon;
use frond_motion::field::{FieldParams, make_field};
use frond_protocol::field::FieldMessage;
use frond_protocol::{ElementKind, ServerMessage, decode_frame};
use frond_sdk::{Event, Subscriber};

/// A field.json of `rows x cols` plants over take `take` without its plants (readers make them
/// from the parameters, so it fits in a control request whatever its size).
pub(crate) fn compact_field(daemon: &Daemon, take: &str, rows: usize, cols: usize) -> std::path::PathBuf {
    compact_field_seeded(daemon, take, rows, cols, 3)
}

/// [`compact_field`] with the layout's seed `seed` (two fields of one grid and two seeds
/// interleave: each cell holds a plant of each, placed apart).
pub(crate) fn compact_field_seeded(
    daemon: &Daemon,
    take: &str,
    rows: usize,
    cols: usize,
    seed: u64,
) -> std::path::PathBuf {
    let p = FieldParams { rows, cols, cell_m: 0.2, speed_m_s: 1.5, direction_deg: 0.0, density: 1.0, seed };
    let field = make_field(&p, take, 60, 30.0).unwrap();
    let mut json: serde_json::Value = serde_json::to_value(&field).unwrap();
    json.as_object_mut().unwrap().remove("plants");
    let path = daemon.takes_dir.with_file_name(format!("field-{rows}x{cols}-{seed}.json"));
    std::fs::write(&path, json.to_string()).unwrap();
    path
}

/// A daemon on the in-process glove with the grass rig and a take `sway` of it, `record`
/// long.
pub(crate) fn daemon_with_sway(dir: &std::path::Path, record: Duration) -> Daemon {
    let daemon = Daemon::start(dir, &["--source", "in-process", "--rig", "grass"]);
    daemon.frond_ok(&["record", "start", "sway"]);
    std::thread::sleep(record);
    daemon.frond_ok(&["record", "stop"]);
    daemon
}

/// The largest field frame (encoded bytes) and how many arrived in `window` on a raw socket.
fn field_frames(daemon: &Daemon, window: Duration) -> (usize, usize) {
    let mut s = UnixStream::connect(daemon.socket_dir.join("poses.sock")).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let (mut buf, mut chunk) = (Vec::new(), [0u8; 65536]);
    let (mut largest, mut count) = (0, 0);
    let start = Instant::now();
    while start.elapsed() < window {
        if let Ok(n) = s.read(&mut chunk) {
            buf.extend_from_slice(&chunk[..n]);
        }
        while let Ok(Some((msg, used))) = decode_frame::<ServerMessage>(&buf) {
            if let ServerMessage::Field(FieldMessage::Frame(_)) = msg {
                largest = largest.max(used);
                count += 1;
            }
            buf.drain(..used);
        }
    }
    (largest, count)
}

#[test]
fn ten_thousand_plants_live_cost_what_twelve_do() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = daemon_with_sway(dir.path(), Duration::from_secs(2));

    // A field of rows x cols plants started (4 announced), and its field frames over 0.8 s.
    let frames_of = |rows: usize, cols: usize| {
        let field = compact_field(&daemon, "sway", rows, cols);
        let field = field.to_str().unwrap();
        daemon.frond_ok(&["field", "start", "--take", "sway", "--field", field, "--plants", "4"]);
        field_frames(&daemon, Duration::from_millis(800))
    };
    let (small_bytes, small_count) = frames_of(3, 4);
    let (big_bytes, big_count) = frames_of(100, 100);
    // 60 field frames a second either way, each the same size within a few bytes (the numbers
    // in it), under 2 KiB: nothing per plant.
    assert!(small_count >= 30 && big_count >= 30, "{small_count} and {big_count} field frames in 0.8 s");
    assert!(big_bytes < 2048 && big_bytes <= small_bytes + 64, "{big_bytes} bytes vs {small_bytes}");

    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let announced: Vec<_> = sub.elements().of_kind(ElementKind::FieldPlant).map(|e| e.id).collect();
    assert_eq!(announced.len(), 4, "{:?}", sub.elements());
    let (mut plant_poses, mut evaluated, mut events) = (0, 0, 0u64);
    let deadline = Instant::now() + Duration::from_secs(15);
    while Instant::now() < deadline && (plant_poses < 40 || evaluated < 10_000) {
        let Event::Pose(p) = sub.next_event().unwrap() else { continue };
        if announced.contains(&p.element) {
            plant_poses += 1;
        }
        events += 1;
        // Every plant, now and then: once the history has arrived, all of them.
        let Some(field) = sub.fields().by_source("field").filter(|_| events % 500 == 0) else { continue };
        assert_eq!(field.plants(), 10_000);
        let tau = field.tau_s();
        let finite = |j: [[f32; 3]; 4]| j.iter().flatten().all(|x| x.is_finite());
        evaluated = (0..10_000).filter(|&i| field.plant_pose(i, tau).is_some_and(finite)).count();
    }
    assert!(plant_poses >= 40, "{plant_poses} poses of announced plants");
    assert_eq!(evaluated, 10_000, "plants the SDK evaluates");

    // A key changes the controls the field frames carry.
    daemon.frond_ok(&["field", "key", "left"]);
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        sub.next_event().unwrap();
        let c = sub.fields().by_source("field").map(|f| f.state().controls().direction_deg);
        if c == Some(180.0) {
            break;
        }
        assert!(Instant::now() < deadline, "the key did not reach the field frames: {c:?}");
    }
    daemon.frond_ok(&["field", "stop"]);
}

/// A meadow from the command line: `frond take field` of 10,000 plants is too large for `frond
/// field start`, which says to write it with `--compact`; the compact file starts the field.
#[test]
fn a_meadow_too_large_to_start_says_compact_and_the_compact_file_starts() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    daemon.frond_ok(&["record", "start", "sway"]);
    std::thread::sleep(Duration::from_millis(1500));
    daemon.frond_ok(&["record", "stop"]);
    let field = |extra: &[&str], out: &str| {
        let mut args = vec!["take", "field", "sway", "--rows", "100", "--cols", "100", "--cell", "0.2"];
        args.extend(["--speed", "1.5", "-o", out]);
        args.extend(extra);
        daemon.frond_ok(&args)
    };
    let big = dir.path().join("meadow.json");
    let small = dir.path().join("meadow-compact.json");
    field(&[], big.to_str().unwrap());
    let said = field(&["--compact"], small.to_str().unwrap());
    assert!(said.contains("(10000 plants, left out"), "{said}");
    let start = |file: &std::path::Path| {
        daemon
            .frond()
            .args(["field", "start", "--take", "sway", "--field", file.to_str().unwrap()])
            .output()
            .unwrap()
    };
    let out = start(&big);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("frond take field --compact"), "{err}");
    let out = start(&small);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(daemon.status().modes.iter().any(|m| m.contains("field")), "{:?}", daemon.status().modes);
}

/// A meadow of two rigs from the command line: a field of flowers (`--rig flower --name
/// flowers`) beside the grass field of the active rig; the element table, the field definition
/// and status name each field's rig; one `frond field key` steers both and `frond field stop`
/// stops both. Rigs and names a field cannot take are refused saying why.
#[test]
fn a_field_of_flowers_beside_the_grass_names_its_rig_and_one_key_steers_both() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = daemon_with_sway(dir.path(), Duration::from_millis(1000));
    let field = compact_field(&daemon, "sway", 10, 10);
    let field = field.to_str().unwrap();
    let start = |extra: &[&str]| {
        let mut args = vec!["field", "start", "--take", "sway", "--field", field];
        args.extend(extra);
        daemon.frond().args(&args).output().unwrap()
    };
    // Refused, each saying why: exit 2 for a usage error, 1 for what the daemon or a file refused.
    let not_grass = dir.path().join("grass2.toml");
    let grass = std::fs::read_to_string(frond_e2e::repo_root().join("rig-files/plants/grass.toml")).unwrap();
    std::fs::write(&not_grass, grass.replace("name = \"tip\"", "name = \"blade_tip\"")).unwrap();
    for (extra, code, want) in [
        (&["--name", "a b"][..], 2, "--name \"a b\": a stage name is 1 to 32 letters"),
        (&["--rig", "no-such-rig"], 1, "no-such-rig"),
        (&["--rig", not_grass.to_str().unwrap()], 1, "differs from the active rig of that name: rename it"),
    ] {
        let out = start(extra);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{extra:?}: {err}");
        assert!(err.contains(want), "{extra:?}: {err}");
    }
    assert!(daemon.status().stages.is_empty(), "nothing started: {:?}", daemon.status().stages);

    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    for (extra, said) in [
        (&["--plants", "2"][..], "field of take sway playing"),
        (
            &["--plants", "2", "--rig", "flower", "--name", "flowers"],
            "field flowers of take sway of rig flower playing",
        ),
    ] {
        let out = start(extra);
        assert!(out.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(String::from_utf8_lossy(&out.stdout).starts_with(said), "{extra:?}: {out:?}");
    }
    let states: Vec<(String, String)> =
        daemon.status().stages.iter().map(|s| (s.name.clone(), s.state.clone())).collect();
    assert_eq!(states.len(), 2, "{states:?}");
    assert!(
        states.iter().any(|(n, s)| n == "flowers" && s.contains("100 plants (rig flower)")),
        "{states:?}"
    );
    assert!(states.iter().any(|(n, s)| n == "field" && !s.contains("(rig")), "{states:?}");
    // What a subscriber sees: each field's definition, its announced plants and the table's
    // rigs name the field's rig.
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        sub.next_event().unwrap();
        let rigs: Vec<(String, String)> = sub
            .fields()
            .iter()
            .map(|f| (f.definition().source.clone(), f.definition().rig.clone()))
            .collect();
        if rigs.len() == 2 {
            assert!(rigs.contains(&("flowers".into(), "flower".into())), "{rigs:?}");
            assert!(rigs.contains(&("field".into(), "grass".into())), "{rigs:?}");
            break;
        }
        assert!(Instant::now() < deadline, "both fields in the SDK: {rigs:?}");
    }
    let table = sub.elements().clone();
    let table_rigs: Vec<&str> = table.rigs.iter().map(|r| r.name.as_str()).collect();
    assert_eq!(table_rigs, ["grass", "flower"]);
    let plants: Vec<(&str, &str)> = table
        .elements
        .iter()
        .filter(|e| e.kind == ElementKind::FieldPlant)
        .map(|e| (e.source.as_str(), e.rig.as_str()))
        .collect();
    assert_eq!(
        plants,
        [("field", "grass"), ("field", "grass"), ("flowers", "flower"), ("flowers", "flower")]
    );

    // One key, both fields; one stop, both stopped.
    daemon.frond_ok(&["field", "key", "left"]);
    for s in daemon.status().stages {
        assert!(s.state.contains("direction 180 deg"), "the key reached {}: {}", s.name, s.state);
    }
    daemon.frond_ok(&["field", "key", "right", "--name", "flowers"]);
    let direction = |name: &str| daemon.status().stages.into_iter().find(|s| s.name == name).unwrap().state;
    assert!(direction("flowers").contains("direction 0 deg"), "{}", direction("flowers"));
    assert!(
        direction("field").contains("direction 180 deg"),
        "--name keys one field: {}",
        direction("field")
    );
    let said = daemon.frond_ok(&["field", "stop"]);
    assert_eq!(said, "field playback stopped\nfield flowers stopped\n");
    assert!(daemon.status().stages.is_empty(), "{:?}", daemon.status().stages);
}
