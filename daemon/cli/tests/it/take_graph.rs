//! `frond take graph` and `frond take walk` (issue 16, seed 003 sections 5 and 6) as the real
//! binary, on a take `frond take simulate` wrote: the graph file as documented, walks that are
//! deterministic, directed walks that lean towards their goal, and clear errors.

use crate::common;

use std::path::Path;

use frond_protocol::ElementId;

use common::{failed, frond, ok};
use frond_formats::layers::TakeBytes;
use serde_json::Value;

/// A minute of gusty wind on the grass rig, then its graph.
fn simulated(dir: &Path) {
    ok(&frond(dir)
        .args(["take", "simulate", "breeze", "--rig", "grass", "--duration", "60"])
        .args(["--wind", "speed=3,dir=0,gust=0.8,seed=4"])
        .output()
        .unwrap());
    ok(&frond(dir).args(["take", "graph", "breeze", "--control", "top"]).output().unwrap());
}

fn walk_poses(dir: &Path, extra: &[&str]) -> Vec<[[f64; 3]; 4]> {
    let out = frond(dir)
        .args(["take", "walk", "breeze", "--graph", "breeze.graph.json", "--jsonl", "--duration", "60"])
        .args(extra)
        .output()
        .unwrap();
    ok(&out)
        .lines()
        .map(|l| {
            let v: Value = serde_json::from_str(l).unwrap();
            std::array::from_fn(|j| std::array::from_fn(|c| v["joints"][j][c].as_f64().unwrap()))
        })
        .collect()
}

#[test]
fn the_graph_file_is_as_documented_and_closed() {
    let dir = tempfile::tempdir().unwrap();
    simulated(dir.path());
    let text = std::fs::read_to_string(dir.path().join("breeze.graph.json")).unwrap();
    let g: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(g["version"], 1);
    assert_eq!(g["take"], "breeze");
    assert_eq!(g["fps"], 30.0);
    assert_eq!(g["control"], "top");
    assert_eq!(g["take_frames"], 1801);
    let nodes = g["nodes"].as_array().unwrap();
    let edges = g["edges"].as_array().unwrap();
    let mut out_degree = vec![0; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        assert_eq!(n["id"], i);
        // The grass top is 0.30 m up: every position is within that of the root.
        let p: Vec<f64> = n["position_m"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        let r = p.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((r - 0.30).abs() < 0.01, "node {i} at {r} m from the root");
    }
    let mut transitions = 0;
    for e in edges {
        out_degree[e["from"].as_u64().unwrap() as usize] += 1;
        match e["kind"].as_str().unwrap() {
            "backbone" => assert_eq!(e["inbetweens"], 0),
            "transition" => {
                transitions += 1;
                assert!(e["inbetweens"].as_u64().unwrap() >= 3, "k = 2: at least 3 in-betweens");
            }
            other => panic!("edge kind {other}"),
        }
    }
    assert!(out_degree.iter().all(|&d| d >= 1), "a node dead-ends");
    assert!(transitions > 100, "{transitions} transitions");
    assert!(g["pruned"]["dead_end_frames"].is_array());
}

#[test]
fn walks_are_deterministic_and_directed_walks_lean_towards_their_goal() {
    let dir = tempfile::tempdir().unwrap();
    simulated(dir.path());
    let a = walk_poses(dir.path(), &["--seed", "5"]);
    assert_eq!(a.len(), 1800);
    assert_eq!(a, walk_poses(dir.path(), &["--seed", "5"]), "same seed, same walk");
    assert_ne!(a, walk_poses(dir.path(), &["--seed", "6"]));
    // The plant leans towards +Z (90 deg) when joint 0 pitches positive (R_x takes +Y to +Z),
    // towards -Z at 270 deg: the goal-directed walks must spend clearly more time leaning their
    // way than the random walk does.
    let lean = |w: &[[[f64; 3]; 4]], sign: f64| {
        w.iter().filter(|p| sign * p[0][0] > 0.0).count() as f64 / w.len() as f64
    };
    let random = lean(&a, 1.0);
    let towards = lean(&walk_poses(dir.path(), &["--seed", "5", "--goal-dir", "90"]), 1.0);
    let away = lean(&walk_poses(dir.path(), &["--seed", "5", "--goal-dir", "270"]), 1.0);
    assert!(towards > random + 0.1, "towards +Z {towards:.2}, random {random:.2}");
    assert!(away < random - 0.1, "towards -Z leaves {away:.2} leaning +Z, random {random:.2}");
}

#[test]
fn a_walk_writes_one_take_per_plant_and_explains_itself() {
    let dir = tempfile::tempdir().unwrap();
    simulated(dir.path());
    let out = frond(dir.path())
        .args(["take", "walk", "breeze", "--graph", "breeze.graph.json", "--duration", "10"])
        .args(["--plants", "3", "--seed", "2", "--explain"])
        .output()
        .unwrap();
    let stdout = ok(&out);
    for name in ["breeze-walk.take", "breeze-walk-plant1.take", "breeze-walk-plant2.take"] {
        assert!(stdout.contains(&format!("{name} (300 frames, 1 layers)")), "{stdout}");
    }
    let explain: Value = serde_json::from_str(String::from_utf8_lossy(&out.stderr).trim()).unwrap();
    let plants = explain["plants"].as_array().unwrap();
    assert_eq!(plants.len(), 3);
    for (i, p) in plants.iter().enumerate() {
        assert_eq!(p["seed"], 2 + i as u64);
        assert!(p["transitions_taken"].as_u64().unwrap() > 0);
        assert_eq!(
            p["transitions"].as_array().unwrap().len() as u64,
            p["transitions_taken"].as_u64().unwrap()
        );
    }
    // Each plant walks its own way.
    let poses = |name: &str| {
        let bytes = std::fs::read(dir.path().join(format!("{name}.take"))).unwrap();
        let (take, damage) = frond_motion::layers::Take::from_bytes_noting_damage(&bytes).unwrap();
        assert_eq!(damage, None);
        assert_eq!(take.layer_ids(), vec![ElementId::GLOBAL]);
        take.layer(ElementId::GLOBAL, true).iter().map(|f| f.pose).collect::<Vec<_>>()
    };
    assert_ne!(poses("breeze-walk-plant1"), poses("breeze-walk-plant2"));
    // Names are checked before anything is written.
    let again = frond(dir.path())
        .args(["take", "walk", "breeze", "--graph", "breeze.graph.json", "--duration", "10", "--plants", "3"])
        .output()
        .unwrap();
    failed(&again, 2, "exists; use --force");
}

#[test]
fn a_walk_counts_its_frames_before_making_them() {
    // The promise for every take tool (docs/security-and-limits.md, "Time"): more than 1,080,000
    // frames only with --force, never more than 16,777,216, counted before anything is walked or
    // written.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    simulated(d);
    let walk = ["take", "walk", "breeze", "--graph", "breeze.graph.json", "--duration", "3600"];
    // An hour at the graph's 30 fps is 108,000 frames a plant: 11 plants make 1,188,000.
    let out = frond(d).args(walk).args(["--plants", "11"]).output().unwrap();
    failed(
        &out,
        1,
        "the walk of 11 plants for 3600 s makes 1188000 frames in all, more than 1080000; pass --force to go past it",
    );
    // 156 plants make 16,848,000, past 16,777,216 (2^24) even with --force.
    let out = frond(d).args(walk).args(["--plants", "156", "--force"]).output().unwrap();
    failed(
        &out,
        1,
        "the walk of 156 plants for 3600 s makes 16848000 frames in all, more than the 16777216 any output may have",
    );
    let written: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.contains("walk"))
        .collect();
    assert!(written.is_empty(), "nothing is written: {written:?}");
    // 10 plants (1,080,000) are within the limit: a shorter walk of as many plants is made.
    ok(&frond(d).args(&walk[..5]).args(["--duration", "2", "--plants", "10"]).output().unwrap());
    assert!(d.join("breeze-walk-plant9.take").is_file());
}

#[test]
fn a_pose_goal_is_reached() {
    let dir = tempfile::tempdir().unwrap();
    simulated(dir.path());
    let out = frond(dir.path())
        .args(["take", "walk", "breeze", "--graph", "breeze.graph.json", "--duration", "30"])
        .args(["--goal-pose", "frame=900", "--explain", "--jsonl"])
        .output()
        .unwrap();
    ok(&out);
    let explain: Value = serde_json::from_str(String::from_utf8_lossy(&out.stderr).trim()).unwrap();
    let reached = explain["plants"][0]["transitions"]
        .as_array()
        .unwrap()
        .iter()
        .any(|t| t["to_frame"].as_u64().unwrap() <= 900 && t["to_frame"].as_u64().unwrap() + 60 >= 900);
    assert!(reached, "no transition lands near frame 900: {explain}");
}

#[test]
fn bad_arguments_and_damaged_files_get_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    simulated(d);
    let run = |args: &[&str]| frond(d).args(args).output().unwrap();
    failed(
        &run(&["take", "graph", "breeze", "--control", "hand", "-o", "x.json"]),
        2,
        "unknown control point",
    );
    failed(
        &run(&["take", "graph", "breeze", "--extend", "999", "-o", "x.json"]),
        2,
        "extend must be at most 64",
    );
    failed(&run(&["take", "graph", "breeze"]), 2, "exists; use --force");
    failed(&run(&["take", "graph", "nope"]), 1, "no take named");
    let walk = ["take", "walk", "breeze", "--graph", "breeze.graph.json"];
    failed(&run(&[&walk[..], &["--duration", "-1"]].concat()), 2, "--duration");
    failed(&run(&[&walk[..], &["--duration", "1", "--plants", "0"]].concat()), 2, "--plants");
    failed(&run(&[&walk[..], &["--duration", "1", "--goal-pose", "1,2"]].concat()), 2, "12 finite angles");
    failed(
        &run(&[&walk[..], &["--duration", "1", "--goal-pose", "frame=99999"]].concat()),
        2,
        "frames at the graph's rate",
    );
    failed(&run(&[&walk[..], &["--duration", "1", "--goal-dir", "nan"]].concat()), 2, "--goal-dir");
    // A straight sweep: no usable transition.
    std::fs::write(
        d.join("sweep.jsonl"),
        (0..200)
            .map(|i| {
                format!(
                    "{{\"t\":{},\"joints\":[[{},0,0],[0,0,0],[0,0,0],[0,0,0]]}}\n",
                    i as f64 / 30.0,
                    -30.0 + 0.3 * i as f64
                )
            })
            .collect::<String>(),
    )
    .unwrap();
    ok(&run(&["take", "import", "sweep.jsonl", "sweep", "--kind", "pose"]));
    failed(&run(&["take", "graph", "sweep", "--rig", "grass"]), 1, "no usable transition");
    // Damaged graph files and a graph of another take.
    let text = std::fs::read_to_string(d.join("breeze.graph.json")).unwrap();
    std::fs::write(d.join("cut.json"), &text[..text.len() / 2]).unwrap();
    failed(
        &run(&["take", "walk", "breeze", "--graph", "cut.json", "--duration", "1"]),
        1,
        "not a motion graph file",
    );
    std::fs::write(d.join("bad.json"), text.replacen("\"to\": 1,", "\"to\": 99999999,", 1)).unwrap();
    failed(&run(&["take", "walk", "breeze", "--graph", "bad.json", "--duration", "1"]), 1, "edges[0]");
    ok(&run(&[
        "take",
        "simulate",
        "other",
        "--rig",
        "grass",
        "--duration",
        "60",
        "--wind",
        "speed=3,dir=0,gust=0.8,seed=5",
    ]));
    failed(
        &run(&["take", "walk", "other", "--graph", "breeze.graph.json", "--duration", "1"]),
        1,
        "rebuild it",
    );
    failed(&run(&["take", "walk", "breeze", "--graph", "/dev/zero", "--duration", "1"]), 1, "cannot read");
}

#[test]
fn instanced_plants_walk_their_own_takes_and_control_points() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    simulated(d);
    // A second take, in another wind, with its graph on another control point.
    ok(&frond(d)
        .args(["take", "simulate", "gale", "--rig", "grass", "--duration", "60"])
        .args(["--wind", "speed=5,dir=90,gust=0.6,seed=9"])
        .output()
        .unwrap());
    ok(&frond(d).args(["take", "graph", "gale", "--control", "joint2"]).output().unwrap());
    let out = frond(d)
        .args(["take", "walk", "breeze", "gale", "--plants", "3", "--duration", "5", "--seed", "1"])
        .args(["-o", "grove", "--explain"])
        .output()
        .unwrap();
    ok(&out);
    let explain: Value = serde_json::from_str(String::from_utf8_lossy(&out.stderr).trim()).unwrap();
    let take_of = |name: &str| {
        let bytes = std::fs::read(d.join(format!("{name}.take"))).unwrap();
        frond_motion::layers::Take::from_bytes_noting_damage(&bytes).unwrap().0
    };
    for (i, (name, source)) in
        [("grove", "breeze"), ("grove-plant1", "gale"), ("grove-plant2", "breeze")].into_iter().enumerate()
    {
        let plant = &explain["plants"][i];
        assert_eq!(plant["take"], source);
        assert_eq!(plant["seed"], 1 + i as u64);
        let walked = take_of(name);
        assert_eq!(walked.header.filter, format!("walk of {source} seed={} goal=random", 1 + i));
        // The walk starts on its own take's pose at the start node's frame.
        let src = take_of(source);
        let start = plant["start_frame"].as_u64().unwrap() as usize;
        let want = src.layer(ElementId::GLOBAL, true)[start].pose.joints_deg;
        let got = walked.layer(ElementId::GLOBAL, true)[0].pose.joints_deg;
        for j in 0..4 {
            for c in 0..3 {
                assert!((want[j][c] - got[j][c]).abs() < 1e-3, "{name} joint {j}: {got:?} vs {want:?}");
            }
        }
    }
    failed(
        &frond(d)
            .args(["take", "walk", "breeze", "gale", "--graph", "breeze.graph.json", "--duration", "1"])
            .output()
            .unwrap(),
        2,
        "give one --graph per take (2 takes, 1 graphs)",
    );
}
