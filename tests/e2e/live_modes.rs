//! The daemon's live modes from the motion toolkit: a looped global take on the stream while a
//! secondary layer is recorded (seed 000, section 5.3), field playback steered by keys (6.2-6.3),
//! and guided motion (6.4).

use std::collections::HashSet;
use std::time::Duration;

use frond_e2e::{Daemon, wait_for};
use frond_formats::layers::TakeBytes;
use frond_motion::field::FieldParams;
use frond_protocol::{ElementId, ElementKind, PoseFlags};
use frond_sdk::{Event, Subscriber};

/// Elements seen (with their flags) in the next `n` poses.
fn elements(sub: &mut Subscriber, n: usize) -> Vec<(u16, PoseFlags)> {
    let mut out = Vec::new();
    while out.len() < n {
        if let Event::Pose(p) = sub.next_event().unwrap() {
            out.push((p.element.get(), p.flags));
        }
    }
    out
}

#[test]
fn layer_over_a_looped_take_then_a_steered_field_and_guided_motion() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "flower"]);

    // A 2 s global take.
    daemon.frond_ok(&["record", "start", "global"]);
    std::thread::sleep(Duration::from_secs(2));
    daemon.frond_ok(&["record", "stop"]);

    // Looping it puts element-0 playback frames on the stream beside the hand's.
    daemon.frond_ok(&["play", "global"]);
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let seen = elements(&mut sub, 400);
    assert!(seen.iter().any(|(e, f)| *e == 0 && f.contains(PoseFlags::PLAYBACK)), "no playback frames");
    assert!(seen.iter().any(|(e, f)| *e == 0 && !f.contains(PoseFlags::PLAYBACK)), "no hand frames");
    daemon.frond_ok(&["play", "--stop"]);

    // A leaf layer over the looped global take: the hand's frames become element 1 (leaf).
    let rig_elements = daemon.status();
    assert_eq!(rig_elements.rig_name, "flower");
    daemon.frond_ok(&["record", "layer", "leaf1", "--layer", "leaf", "--over", "global"]);
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let seen = elements(&mut sub, 600);
    assert!(seen.iter().any(|(e, f)| *e == 1 && f.contains(PoseFlags::RECORDING)), "no leaf frames");
    assert!(seen.iter().any(|(e, f)| *e == 0 && f.contains(PoseFlags::PLAYBACK)), "global take not looping");
    assert!(
        daemon.status().modes.iter().any(|m| m.contains("recording layer leaf")),
        "{:?}",
        daemon.status().modes
    );
    std::thread::sleep(Duration::from_millis(500));
    daemon.frond_ok(&["record", "stop"]);
    assert!(daemon.status().modes.is_empty(), "{:?}", daemon.status().modes);
    let bytes = std::fs::read(daemon.takes_dir.join("leaf1.take")).unwrap();
    let take = frond_motion::layers::Take::from_bytes(&bytes).unwrap();
    assert_eq!(take.element_names, ["leaf"]);
    assert!(
        !take.frames.is_empty() && take.frames.iter().all(|f| f.element == ElementId::FIRST_LAYER),
        "layer frames"
    );
    // An unknown layer is refused with the rig's elements named.
    let out = daemon.frond().args(["record", "layer", "x", "--layer", "petal"]).output().unwrap();
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("leaf"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // A 3x4 field of the global take, steered by keys.
    daemon.start_field(
        "global",
        &FieldParams {
            rows: 3,
            cols: 4,
            cell_m: 1.0,
            speed_m_s: 2.0,
            direction_deg: 0.0,
            density: 1.0,
            seed: 7,
        },
        60,
        5,
    );
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    // Plants are announced elements: their ids come from the table, not from a number range.
    let table = sub.elements().clone();
    let plant_of = |id: u16| {
        let e = table.get(ElementId::new(id))?;
        (e.kind == ElementKind::FieldPlant).then(|| e.name.strip_prefix("plant")?.parse::<u16>().ok())?
    };
    let plants: HashSet<u16> =
        elements(&mut sub, 1500).into_iter().filter_map(|(e, _)| plant_of(e)).collect();
    assert_eq!(plants, (0..5).collect(), "published plants");
    let out = daemon.frond_ok(&["field", "key", "left"]);
    assert!(out.contains("direction 180"), "{out}");
    daemon.frond_ok(&["field", "key", "+"]);
    assert!(
        wait_for(Duration::from_secs(2), || daemon
            .status()
            .modes
            .iter()
            .any(|m| m.contains("propagation 2.50 m/s"))),
        "{:?}",
        daemon.status().modes
    );
    daemon.frond_ok(&["field", "stop"]);

    // Guided motion switches on and off, and bad specs are refused.
    daemon.frond_ok(&["guided", "sigma=0.1,0.2,0.3;sg=1,1,1"]);
    assert!(daemon.status().modes.iter().any(|m| m.contains("guided motion")));
    assert!(!daemon.frond().args(["guided", "sigma=1"]).output().unwrap().status.success());
    daemon.frond_ok(&["guided", "off"]);
    assert!(daemon.status().modes.is_empty());

    // Guided motion as a rig option: a rig with a [guided] table switches it on when applied.
    let rig = std::fs::read_to_string(frond_e2e::repo_root().join("rig-files/plants/grass.toml")).unwrap();
    let guided_rig = dir.path().join("grass-guided.toml");
    std::fs::write(
        &guided_rig,
        format!("{rig}\n[guided]\nsigma_s = [0.1, 0.2, 0.4]\ns_g = [1.0, 1.0, 2.0]\n"),
    )
    .unwrap();
    daemon.frond_ok(&["rig", "set", guided_rig.to_str().unwrap()]);
    let modes = daemon.status().modes;
    assert!(modes.iter().any(|m| m.contains("guided motion sigma=0.1,0.2,0.4;sg=1,1,2")), "{modes:?}");
}

#[test]
fn a_rig_set_live_reaches_a_subscriber_as_a_rig_change_with_the_new_joint_names() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    assert_eq!(sub.hello().rig_name, "grass");
    daemon.frond_ok(&["rig", "set", "shrub"]);
    // The joint names of rig-files/plants/shrub.toml, read from the file, not from frond.
    let shrub = std::fs::read_to_string(frond_e2e::repo_root().join("rig-files/plants/shrub.toml")).unwrap();
    let expected: Vec<String> = shrub
        .lines()
        .skip_while(|l| !l.starts_with("[[joints]]"))
        .filter_map(|l| l.strip_prefix("name = \""))
        .map(|n| n.trim_end_matches('"').to_string())
        .collect();
    assert_eq!(expected.len(), 4, "{expected:?}");
    let mut changed = None;
    for _ in 0..20_000 {
        if let Event::RigChanged(h) = sub.next_event().unwrap() {
            changed = Some(h);
            break;
        }
    }
    let hello = changed.expect("no RigChanged after frond rig set");
    assert_eq!(hello.rig_name, "shrub");
    assert_eq!(hello.joint_names, expected);
    assert_eq!(sub.hello().joint_names, expected);
}

/// Issue 44: a take of `frond record layer` holds only its layer's frames (element 1 for the
/// flower's leaf). Every take tool must read it: `take list` counts the frames `record stop`
/// reported, `take export` prints its poses, `frond-gltf bake` bakes it (the leaf moving on a
/// plant at rest) and `take align` aligns it with the global take.
#[test]
fn a_recorded_layer_take_is_listable_exportable_bakeable_and_alignable() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "flower"]);
    daemon.frond_ok(&["record", "start", "global"]);
    std::thread::sleep(Duration::from_secs(2));
    daemon.frond_ok(&["record", "stop"]);
    daemon.frond_ok(&["record", "layer", "leafy", "--layer", "leaf", "--over", "global"]);
    std::thread::sleep(Duration::from_millis(1500));
    let stopped = daemon.frond_ok(&["record", "stop"]);
    // "stopped leafy: N frames in PATH"
    let reported: u64 = stopped
        .split_whitespace()
        .skip_while(|w| *w != "leafy:")
        .nth(1)
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no frame count in {stopped:?}"));
    assert!(reported > 500, "1.5 s at 1 kHz: {stopped}");

    // Listed with the frames record stop reported and about 1.5 s.
    let list: serde_json::Value =
        serde_json::from_str(&daemon.frond_ok(&["take", "list", "--json"])).unwrap();
    let row = list.as_array().unwrap().iter().find(|r| r["name"] == "leafy").expect("leafy listed");
    assert_eq!(row["frames"].as_u64(), Some(reported), "{row}");
    let duration = row["duration_s"].as_f64().unwrap();
    assert!((1.0..3.0).contains(&duration), "{row}");

    // Exported: one line per kept frame (the virtual glove reports every tick, held ones are few).
    let out = daemon.frond().args(["take", "export", "leafy"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines = String::from_utf8_lossy(&out.stdout).lines().count() as u64;
    assert!(lines > reported / 2 && lines <= reported, "{lines} of {reported}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("layer take"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // Baked on the flower.
    let glb = dir.path().join("leafy.glb");
    let take = daemon.takes_dir.join("leafy.take");
    let out = std::process::Command::new(frond_e2e::bin("frond-gltf"))
        .args(["bake", "--rig", "flower", "--take"])
        .arg(&take)
        .arg("-o")
        .arg(&glb)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::metadata(&glb).unwrap().len() > 1000);

    // Aligned as the secondary of the global take: the written take has both layers.
    daemon.frond_ok(&["take", "align", "global", "leafy", "--layer", "leaf", "-o", "aligned"]);
    let bytes = std::fs::read(daemon.takes_dir.join("aligned.take")).unwrap();
    let aligned = frond_motion::layers::Take::from_bytes(&bytes).unwrap();
    assert_eq!(aligned.layer_ids(), [ElementId::GLOBAL, ElementId::FIRST_LAYER]);
    assert!(aligned.layer(ElementId::FIRST_LAYER, true).len() > 10);
    // And on the recording timeline beside the global take.
    let out = daemon.frond_ok(&["take", "export", "global", "leafy", "--align"]);
    assert!(out.lines().any(|l| l.contains("\"take\":\"leafy\"")), "no leafy frames aligned");
}
