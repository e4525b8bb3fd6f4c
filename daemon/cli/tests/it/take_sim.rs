//! `frond take simulate` (issue 16, seed 003 section 4) as the real binary: the take holds the
//! static bend worked out by hand, and `--states` the node states, in equilibrium at the end.

use std::process::Command;

use serde_json::Value;

fn frond(takes: &std::path::Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_frond"));
    c.env_remove("FROND_SOCKET_DIR").env("FROND_TAKES_DIR", takes);
    c
}

/// The grass rig's nodes rest at 0, 0.08, 0.16, 0.24 and 0.30 m (joints 0..3, the top). With
/// drag c = 0.01 N s/m on each free node, a steady 0.2 m/s wind pushes each with F = 0.002 N.
/// Small-angle torques about the joints, sum of F (z_n - z_j) over the nodes above:
///   joint 0: 0.002 * (0.08 + 0.16 + 0.24 + 0.30) = 0.00156 N m
///   joint 1: 0.002 * (0.08 + 0.16 + 0.22)        = 0.00092
///   joint 2: 0.002 * (0.08 + 0.14)               = 0.00044
///   joint 3: 0.002 * 0.06                        = 0.00012
/// With stiffnesses 0.078, 0.046, 0.022, 0.006 N m/rad every joint bends 0.02 rad = 1.146 deg
/// relative to its parent, towards the wind's direction (90 deg: +Z, a positive pitch).
const SIM: &str = "[sim]\nmass_kg = [0.001, 0.001, 0.001, 0.001]\n\
    bend_stiffness_nm_per_rad = [0.078, 0.046, 0.022, 0.006]\n\
    bend_damping_nms_per_rad = [0.02, 0.01, 0.005, 0.002]\n\
    drag_ns_per_m = [0.01, 0.01, 0.01, 0.01]\n";

#[test]
fn a_steady_wind_bends_each_joint_by_the_hand_computed_angle() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim.toml");
    std::fs::write(&sim, SIM).unwrap();
    let states = dir.path().join("states.jsonl");
    let out = frond(dir.path())
        .args(["take", "simulate", "breeze", "--rig", "grass", "--sim"])
        .arg(&sim)
        .args(["--wind", "speed=0.2,dir=90,gust=0,seed=1", "--duration", "5", "--fps", "30", "--states"])
        .arg(&states)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let export = frond(dir.path()).args(["take", "export", "breeze", "--include-held"]).output().unwrap();
    assert!(export.status.success(), "{}", String::from_utf8_lossy(&export.stderr));
    let poses: Vec<Value> =
        String::from_utf8(export.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(poses.len(), 151, "5 s at 30 FPS, both ends");
    let last = &poses[150]["joints"];
    let want_deg = 0.02f64.to_degrees();
    for j in 0..4 {
        let (pitch, yaw) = (last[j][0].as_f64().unwrap(), last[j][1].as_f64().unwrap());
        assert!((pitch - want_deg).abs() < 0.02 * want_deg, "joint {j} pitch {pitch} deg, want {want_deg}");
        assert!(yaw.abs() < 0.01 * want_deg, "joint {j} bends across the wind: yaw {yaw}");
    }
    // The states: rest at first, every segment within 0.5 % of its length, the bend downwind,
    // and no net force left on any node once it has settled.
    let lines: Vec<Value> =
        std::fs::read_to_string(&states).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 151);
    let v3 = |v: &Value| -> [f64; 3] { std::array::from_fn(|k| v[k].as_f64().unwrap()) };
    let heights = [0.0, 0.08, 0.16, 0.24, 0.30];
    for (n, p) in lines[0]["positions_m"].as_array().unwrap().iter().enumerate() {
        let p = v3(p);
        // The rig's heights are f32: 0.08 reads back as 0.0799999982.
        assert!(p[0] == 0.0 && p[2] == 0.0 && (p[1] - heights[n]).abs() < 1e-6, "node {n} at rest: {p:?}");
    }
    let end = &lines[150];
    let x: Vec<[f64; 3]> = end["positions_m"].as_array().unwrap().iter().map(v3).collect();
    for s in 0..4 {
        let d = (0..3).map(|k| (x[s + 1][k] - x[s][k]).powi(2)).sum::<f64>().sqrt();
        let rest = heights[s + 1] - heights[s];
        assert!((d - rest).abs() < 0.005 * rest, "segment {s}: {d} m, rest {rest} m");
    }
    assert!(x[4][2] > 0.0 && x[4][0].abs() < 1e-6, "the top bends towards +Z: {:?}", x[4]);
    for (n, f) in end["forces_n"].as_array().unwrap().iter().enumerate() {
        let f = v3(f);
        let size = f.iter().map(|c| c * c).sum::<f64>().sqrt();
        assert!(size < 0.002 * 0.01, "node {}: net force {f:?} N after settling", n + 1);
    }
}

#[test]
fn bad_arguments_are_refused_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    for (args, needle) in [
        (vec!["--wind", "speed=fast", "--duration", "1"], "--wind"),
        (vec!["--wind", "speed=1,dir=0,gust=0,seed=1", "--duration", "-1"], "duration"),
        (vec!["--wind", "speed=1,dir=0,gust=0,seed=1", "--duration", "1e9"], "limit"),
    ] {
        let out =
            frond(dir.path()).args(["take", "simulate", "x", "--rig", "grass"]).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}
