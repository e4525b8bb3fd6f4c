//! `frond graph play|goal|stop` (issue 16, seed 003 section 6 live): plants walking the motion
//! graph of a simulated take in the real daemon, announced as elements, directed live, with the
//! goal and the transitions taken in `frond status`.

use std::collections::HashMap;
use std::time::Duration;

use frond_e2e::{Daemon, wait_for};
use frond_protocol::{ElementId, ElementKind};
use frond_sdk::{Event, Subscriber};

fn mode(daemon: &Daemon) -> String {
    daemon.status().modes.into_iter().find(|m| m.contains("graph walk")).unwrap_or_default()
}

#[test]
fn walkers_play_live_and_follow_their_goal() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    daemon.frond_ok(&[
        "take",
        "simulate",
        "breeze",
        "--rig",
        "grass",
        "--duration",
        "60",
        "--wind",
        "speed=3,dir=0,gust=0.8,seed=4",
    ]);
    daemon.frond_ok(&["take", "graph", "breeze"]);
    assert!(daemon.takes_dir.join("breeze.graph.json").is_file(), "the graph goes beside its take");
    // The take's range of angles: walking can only show poses between the take's.
    let export = daemon.frond_ok(&["take", "export", "breeze", "--include-held"]);
    let mut max_deg: f64 = 0.0;
    for l in export.lines() {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        for j in 0..4 {
            for c in 0..2 {
                max_deg = max_deg.max(v["joints"][j][c].as_f64().unwrap().abs());
            }
        }
    }

    let out = daemon.frond_ok(&["graph", "play", "breeze", "--plants", "4", "--seed", "3"]);
    assert!(out.contains("4 plants walking"), "{out}");
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let table = sub.elements().clone();
    let walkers: HashMap<ElementId, String> = (0..200u16)
        .map(ElementId::new)
        .filter_map(|id| {
            table.get(id).filter(|e| e.kind == ElementKind::FieldPlant).map(|e| (id, e.name.clone()))
        })
        .collect();
    let mut names: Vec<&String> = walkers.values().collect();
    names.sort();
    assert_eq!(names, ["walker0", "walker1", "walker2", "walker3"]);
    // Two seconds of frames: every walker moves, within the take's range.
    let mut seen: HashMap<ElementId, Vec<[[f32; 3]; 4]>> = HashMap::new();
    let deadline = std::time::Instant::now() + Duration::from_secs(2);
    while std::time::Instant::now() < deadline {
        if let Event::Pose(p) = sub.next_event().unwrap()
            && walkers.contains_key(&p.element)
        {
            seen.entry(p.element).or_default().push(p.joints_deg);
        }
    }
    assert_eq!(seen.len(), 4, "frames of every walker");
    for (id, frames) in &seen {
        assert!(frames.len() >= 60, "walker {id}: {} frames in 2 s at 60 Hz", frames.len());
        assert!(frames.windows(2).any(|w| w[0] != w[1]), "walker {id} does not move");
        for f in frames {
            for j in f {
                assert!(
                    (j[0] as f64).abs() <= max_deg + 1.0 && (j[1] as f64).abs() <= max_deg + 1.0,
                    "{j:?} beyond {max_deg}"
                );
            }
        }
    }
    assert_ne!(seen.values().next(), seen.values().nth(1), "each walker walks its own way");

    // `frond tap` names the element of every line and can follow one of them.
    let walker1 = *walkers.iter().find(|(_, n)| n.as_str() == "walker1").unwrap().0;
    let tapped = daemon.frond_ok(&["tap", "--jsonl", "--element", "walker1", "--count", "3"]);
    let lines: Vec<serde_json::Value> = tapped.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 3);
    assert!(lines.iter().all(|l| l["element"] == walker1.get()), "{tapped}");
    let human = daemon.frond_ok(&["tap", "--element", &walker1.to_string(), "--count", "2"]);
    assert!(human.lines().all(|l| l.starts_with("[walker1] #")), "{human}");
    let out = daemon.frond().args(["tap", "--element", "nobody", "--count", "1"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no such element"));

    // Goals, as status shows them.
    let out = daemon.frond_ok(&["graph", "goal", "dir", "90"]);
    assert!(out.contains("goal direction 90 deg"), "{out}");
    daemon.frond_ok(&["graph", "goal", "pose", "frame=900"]);
    assert!(
        wait_for(Duration::from_secs(3), || {
            let m = mode(&daemon);
            m.contains("goal pose of frame 900") && !m.contains("planning")
        }),
        "{}",
        mode(&daemon)
    );
    // A pose by its 12 angles: those of a node's frame (read from the graph file and the take's
    // export), so the nearest node is that very frame.
    let graph: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(daemon.takes_dir.join("breeze.graph.json")).unwrap())
            .unwrap();
    let nodes = graph["nodes"].as_array().unwrap();
    let frame = nodes[nodes.len() / 3]["frame"].as_u64().unwrap() as usize;
    let line: serde_json::Value = serde_json::from_str(export.lines().nth(frame).unwrap()).unwrap();
    let angles: Vec<String> = (0..12).map(|i| line["joints"][i / 3][i % 3].to_string()).collect();
    daemon.frond_ok(&["graph", "goal", "pose", &angles.join(",")]);
    assert!(
        wait_for(Duration::from_secs(3), || mode(&daemon)
            .contains(&format!("goal pose given by its angles, nearest frame {frame};"))),
        "frame {frame}: {}",
        mode(&daemon)
    );
    let out = daemon.frond().args(["graph", "goal", "pose", "1,2,3"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("12 finite angles"));
    daemon.frond_ok(&["graph", "goal", "hand"]);
    assert!(mode(&daemon).contains("goal from the hand"), "{}", mode(&daemon));
    let taken = |m: &str| -> u64 {
        m.split("; ").find_map(|p| p.strip_suffix(" transitions taken")?.parse().ok()).unwrap_or(0)
    };
    let before = taken(&mode(&daemon));
    assert!(wait_for(Duration::from_secs(5), || taken(&mode(&daemon)) > before), "{}", mode(&daemon));
    daemon.frond_ok(&["graph", "goal", "off"]);
    assert!(mode(&daemon).contains("random walks"));

    // Bad goals and graphs are refused by name; stop ends it.
    let out = daemon.frond().args(["graph", "goal", "north"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown goal"));
    daemon.frond_ok(&["graph", "stop"]);
    assert!(daemon.status().modes.is_empty(), "{:?}", daemon.status().modes);
    let out = daemon.frond().args(["graph", "play", "breeze", "--graph", "nope"]).output().unwrap();
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("cannot read graph \"nope\""),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(daemon.takes_dir.join("cut.graph.json"), "{\"version\": 1").unwrap();
    let out = daemon.frond().args(["graph", "play", "breeze", "--graph", "cut"]).output().unwrap();
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("not a motion graph file"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A graph given by its file in the takes directory; one elsewhere is refused with the reason.
    let file = daemon.takes_dir.join("breeze.graph.json");
    let out =
        daemon.frond_ok(&["graph", "play", "breeze", "--plants", "2", "--graph", file.to_str().unwrap()]);
    assert!(out.contains("2 plants walking"), "{out}");
    daemon.frond_ok(&["graph", "stop"]);
    let copy = dir.path().join("breeze.graph.json");
    std::fs::copy(&file, &copy).unwrap();
    let out =
        daemon.frond().args(["graph", "play", "breeze", "--graph", copy.to_str().unwrap()]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("only from its takes directory"));
}

#[test]
fn the_simulated_plant_runs_live_and_the_hand_blows_it() {
    use frond_protocol::PoseFlags;
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    let bad = daemon.frond().args(["sim", "start", "--wind", "speed=fast"]).output().unwrap();
    assert_eq!(bad.status.code(), Some(2), "{}", String::from_utf8_lossy(&bad.stderr));
    // Issue 42: a time step whose steps do not fit in the tick is refused with the reason (it
    // was accepted, and the plant ran at half speed). 1 ms over 10 us is 100 steps a tick; a
    // stage's share of a 1 kHz tick (62.5 us) holds 2 steps of 30 us.
    let rig = dir.path().join("fine.toml");
    let grass = std::fs::read_to_string(frond_e2e::repo_root().join("rig-files/plants/grass.toml")).unwrap();
    std::fs::write(&rig, format!("{grass}\n[sim]\ntimestep_s = 0.00001\n")).unwrap();
    let out = daemon.frond().args(["sim", "start", "--rig"]).arg(&rig).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("sim.timestep_s = 0.00001 s asks for 100 simulation steps per tick at 1000 Hz")
            && err.contains("at most 2")
            && err.contains("at least 0.0005 s"),
        "{err}"
    );
    assert!(daemon.status().modes.is_empty(), "nothing started: {:?}", daemon.status().modes);
    daemon.frond_ok(&["sim", "start", "--wind", "speed=3,dir=90,gust=0,seed=1"]);
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let mut sim_frames = Vec::new();
    while sim_frames.len() < 1500 {
        if let Event::Pose(p) = sub.next_event().unwrap()
            && p.element.is_global()
            && p.flags.contains(PoseFlags::PLAYBACK)
        {
            sim_frames.push(p.joints_deg);
        }
    }
    assert!(sim_frames.windows(2).any(|w| w[0] != w[1]), "the simulated plant does not move");
    assert!(sim_frames.iter().all(|f| f.iter().flatten().all(|a| a.is_finite() && a.abs() < 90.0)));
    // The virtual glove bends the wrist: its bend turns the wind away from the spec's.
    let winds: std::collections::HashSet<String> = (0..40)
        .filter_map(|_| {
            std::thread::sleep(Duration::from_millis(50));
            let m = daemon.status().modes.into_iter().find(|m| m.contains("simulated plant"))?;
            Some(m.split(": ").nth(1)?.split(" at ").next()?.to_string())
        })
        .collect();
    assert!(winds.len() > 1, "the hand never changed the wind: {winds:?}");
    daemon.frond_ok(&["sim", "stop"]);
    assert!(daemon.status().modes.is_empty(), "{:?}", daemon.status().modes);
}

#[test]
fn plants_walk_several_takes_live_each_on_its_own_graph() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    for (name, wind) in
        [("breeze", "speed=3,dir=0,gust=0.8,seed=4"), ("gale", "speed=5,dir=90,gust=0.6,seed=9")]
    {
        daemon.frond_ok(&["take", "simulate", name, "--rig", "grass", "--duration", "40", "--wind", wind]);
    }
    daemon.frond_ok(&["take", "graph", "breeze", "--control", "top"]);
    daemon.frond_ok(&["take", "graph", "gale", "--control", "joint2"]);
    let nodes = |graph: &str| -> usize {
        let text = std::fs::read_to_string(daemon.takes_dir.join(format!("{graph}.graph.json"))).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()["nodes"].as_array().unwrap().len()
    };
    let out = daemon.frond_ok(&["graph", "play", "breeze", "gale", "--plants", "4"]);
    assert!(out.contains("4 plants walking the graphs of breeze, gale"), "{out}");
    let total = nodes("breeze") + nodes("gale");
    assert!(
        mode(&daemon).contains(&format!("graph walk of breeze, gale: 4 plants on {total} nodes")),
        "{} (expected {total} nodes)",
        mode(&daemon)
    );
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let walkers: Vec<ElementId> = (0..200u16)
        .map(ElementId::new)
        .filter(|&id| sub.elements().get(id).is_some_and(|e| e.kind == ElementKind::FieldPlant))
        .collect();
    assert_eq!(walkers.len(), 4);
    // A frame goal is a frame of each plant's own take; it gets planned on both graphs.
    daemon.frond_ok(&["graph", "goal", "pose", "frame=600"]);
    assert!(
        wait_for(Duration::from_secs(3), || {
            let m = mode(&daemon);
            m.contains("goal pose of frame 600") && !m.contains("planning")
        }),
        "{}",
        mode(&daemon)
    );
    let mut moved = HashMap::new();
    let deadline = std::time::Instant::now() + Duration::from_secs(1);
    while std::time::Instant::now() < deadline {
        if let Event::Pose(p) = sub.next_event().unwrap()
            && walkers.contains(&p.element)
        {
            moved.entry(p.element).or_insert_with(Vec::new).push(p.joints_deg);
        }
    }
    assert_eq!(moved.len(), 4, "every walker publishes");
    daemon.frond_ok(&["graph", "stop"]);
    // Graphs of one walk share a frame rate; the number of graphs matches the takes.
    let gale60 = daemon.takes_dir.join("gale60.graph.json");
    daemon.frond_ok(&["take", "graph", "gale", "--fps", "60", "-o", gale60.to_str().unwrap()]);
    let out = daemon
        .frond()
        .args(["graph", "play", "breeze", "gale", "--graph", "breeze", "--graph", "gale60"])
        .output()
        .unwrap();
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("share one frame rate"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = daemon.frond().args(["graph", "play", "breeze", "gale", "--graph", "breeze"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("one --graph per take"));
}
