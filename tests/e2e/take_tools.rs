//! The motion toolkit end to end: record a take from the virtual glove (in-process source), then
//! run every `frond take` toolkit command on it and check what each writes.

use std::process::Output;
use std::time::Duration;

use frond_e2e::{Daemon, repo_root};
use serde_json::Value;

fn ok(out: Output, what: &str) -> String {
    assert!(out.status.success(), "{what} failed ({}): {}", out.status, String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

fn export_lines(daemon: &Daemon, name: &str) -> Vec<Value> {
    let text = ok(daemon.frond().args(["take", "export", name, "--jsonl"]).output().unwrap(), name);
    text.lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

#[test]
fn every_take_tool_runs_on_a_recorded_take() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let run = |args: &[&str]| ok(daemon.frond().args(args).output().unwrap(), &args.join(" "));

    run(&["record", "start", "sway"]);
    std::thread::sleep(Duration::from_secs(4));
    run(&["record", "stop"]);
    let recorded = export_lines(&daemon, "sway");
    assert!(recorded.len() > 100, "recorded {} frames", recorded.len());

    // Import the exported poses back, and the same as hand samples through a rig.
    let poses = dir.path().join("poses.jsonl");
    std::fs::write(&poses, run(&["take", "export", "sway", "--jsonl", "--fps", "30"])).unwrap();
    run(&["take", "import", poses.to_str().unwrap(), "imported"]);
    let imported = export_lines(&daemon, "imported");
    let at30 = run(&["take", "export", "sway", "--jsonl", "--fps", "30"]).lines().count();
    assert_eq!(imported.len(), at30);
    let hand = dir.path().join("hand.jsonl");
    std::fs::write(
        &hand,
        "{\"t\":0,\"wrist\":[10,0,0],\"thumb\":[0,0,0]}\n{\"t\":0.1,\"wrist\":[20,0,0],\"thumb\":[0,0,0]}\n",
    )
    .unwrap();
    let rig = repo_root().join("rig-files/plants/grass.toml");
    run(&[
        "take",
        "import",
        hand.to_str().unwrap(),
        "from-hand",
        "--rig",
        rig.to_str().unwrap(),
        "--filter",
        "none",
    ]);
    assert_eq!(export_lines(&daemon, "from-hand")[1]["joints"][0][0].as_f64(), Some(20.0));

    run(&["take", "resample", "sway", "--fps", "30"]);
    assert_eq!(export_lines(&daemon, "sway-resample").len(), at30);
    run(&["take", "filter", "sway", "--filter", "lowpass:cutoff_hz=3"]);
    assert_eq!(export_lines(&daemon, "sway-filter").len(), at30);

    // Loop: --explain JSON, then a 20 s seeded loop, identical for the same seed.
    let explain: Value = serde_json::from_str(
        run(&[
            "take",
            "loop",
            "sway",
            "--regions",
            "3",
            "--per-region",
            "1",
            "--window",
            "2",
            "--seed",
            "5",
            "--explain",
        ])
        .trim(),
    )
    .unwrap();
    let pivot = explain["pivot"].as_u64().unwrap() as usize;
    assert_eq!(pivot, at30 - 1 - 2);
    let tr: Vec<u64> =
        explain["transitions"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
    assert!(tr.windows(2).all(|w| w[0] < w[1]) && *tr.last().unwrap() == pivot as u64, "{tr:?}");
    let args = ["take", "loop", "sway", "--seed", "5", "--duration", "20"];
    let a = run(&[&args[..], &["--jsonl"]].concat());
    assert_eq!(a, run(&[&args[..], &["--jsonl"]].concat()));
    assert_eq!(a.lines().count(), 601);
    run(&[&args[..], &["-o", "sway-loop"]].concat());

    // Field over the looped take.
    let field = dir.path().join("field.json");
    run(&[
        "take",
        "field",
        "sway-loop",
        "--rows",
        "3",
        "--cols",
        "5",
        "--cell",
        "0.2",
        "--speed",
        "1.5",
        "--direction",
        "45",
        "--seed",
        "2",
        "-o",
        field.to_str().unwrap(),
    ]);
    let f: Value = serde_json::from_str(&std::fs::read_to_string(&field).unwrap()).unwrap();
    assert_eq!(f["plants"].as_array().unwrap().len(), 15);
    assert_eq!(f["take"], "sway-loop");

    run(&[
        "take",
        "retime",
        "sway",
        "--speed",
        "2",
        "--scale",
        "0.5",
        "--rotate",
        "90",
        "--delay",
        "0.05,0.1,0.15",
    ]);
    let retimed = export_lines(&daemon, "sway-retime").len();
    assert!(retimed.abs_diff(at30 / 2) <= 1, "{retimed} vs {at30}");
    run(&["take", "guided", "sway", "--sigma", "0.1,0.2,0.3", "--sg", "1,1,1"]);
    assert_eq!(export_lines(&daemon, "sway-guided").len(), at30);
    run(&["take", "splice", "sway", "--from", "10", "--to", "20", "--with", "sway-retime", "--blend", "3"]);
    assert_eq!(export_lines(&daemon, "sway-splice").len(), at30 - 11 + retimed);
    run(&["take", "align", "sway-loop", "sway-retime", "--window", "2", "--seed", "1"]);
    assert_eq!(export_lines(&daemon, "sway-loop-aligned").len(), 601);

    // Bad arguments and damaged takes are clear errors.
    let bad = daemon.frond().args(["take", "retime", "sway", "--delay", "1,2"]).output().unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--delay takes three comma-separated numbers"));
    std::fs::write(daemon.takes_dir.join("junk.take"), b"not a take").unwrap();
    let bad = daemon.frond().args(["take", "loop", "junk"]).output().unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("bad magic"));
}

/// Issue 44: `frond take simulate` of minutes of motion shows its progress on a terminal (here
/// a pseudo-terminal made by `script`), and never in a pipe.
#[test]
fn a_long_simulation_shows_progress_on_a_terminal_only() {
    let dir = tempfile::tempdir().unwrap();
    let frond = frond_e2e::bin("frond");
    let args = |name: &str| {
        format!("take simulate {name} --rig grass --wind speed=6,dir=0,gust=0.3,seed=1 --duration 120")
    };
    // A pipe: the take, no bar.
    let out = std::process::Command::new(&frond)
        .args(args("gusty").split(' '))
        .env("FROND_TAKES_DIR", dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!String::from_utf8_lossy(&out.stderr).contains("simulating"), "a bar in a pipe");
    // A terminal: the bar, counting the 3601 frames (120 s at 30 fps, both ends).
    let Ok(out) = std::process::Command::new("script")
        .args(["-qec", &format!("{} {}", frond.display(), args("gusty-tty")), "/dev/null"])
        .env("FROND_TAKES_DIR", dir.path())
        .output()
    else {
        eprintln!("no `script` command: the terminal half is skipped");
        return;
    };
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("simulating [") && text.contains("/3601 frames"), "{text}");
}
