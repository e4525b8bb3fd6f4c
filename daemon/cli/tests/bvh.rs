//! `frond take export --bvh` (issue 18) against the real counterpart: Blender's own BVH importer
//! (bpy from PyPI, in the tests' venv, `exporters/osc/tests/install-python.sh`), which
//! `bvh_blender.py` drives and checks against forward kinematics computed there. Without bpy the
//! test says why and passes as skipped, unless `CI=true` or `FROND_REQUIRE_PYTHON=1`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn frond(takes: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_frond"));
    c.env_remove("FROND_SOCKET_DIR").env("FROND_TAKES_DIR", takes).current_dir(takes);
    c
}

fn ok(out: &Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn required() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
        || std::env::var("FROND_REQUIRE_PYTHON").is_ok_and(|v| v == "1")
}

fn python_with_bpy() -> Option<PathBuf> {
    let py = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/.venv/bin/python");
    let ok = Command::new(&py)
        .args(["-c", "import bpy"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    ok.then_some(py)
}

/// 3 s at 100 Hz of every angle moving (roll too), imported as a pose take.
fn performed(dir: &Path) {
    let lines: String = (0..300)
        .map(|k| {
            let t = k as f64 / 100.0;
            let joints: Vec<String> = (0..4)
                .map(|j| {
                    let a = j as f64 + 1.0;
                    format!(
                        "[{:.4},{:.4},{:.4}]",
                        35.0 * (1.3 * t + a).sin(),
                        -28.0 * (0.9 * t + 0.5 * a).cos(),
                        if j == 0 { 0.0 } else { 40.0 * (1.7 * t - a).sin() }
                    )
                })
                .collect();
            format!("{{\"t\":{t},\"joints\":[{}]}}\n", joints.join(","))
        })
        .collect();
    std::fs::write(dir.join("wave.jsonl"), lines).unwrap();
    ok(&frond(dir).args(["take", "import", "wave.jsonl", "wave", "--kind", "pose"]).output().unwrap());
}

#[test]
fn blender_imports_the_bvh_and_its_bones_follow_the_take() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    performed(d);
    ok(&frond(d)
        .args(["take", "export", "wave", "--bvh", "-o", "wave.bvh", "--rig", "grass"])
        .output()
        .unwrap());
    let text = std::fs::read_to_string(d.join("wave.bvh")).unwrap();
    assert!(text.starts_with("HIERARCHY\nROOT root\n"), "{}", &text[..80]);
    assert!(text.contains("Frames: 90\nFrame Time: 0.033333333\n"), "3 s at 30 fps");
    let poses = ok(&frond(d).args(["take", "export", "wave", "--fps", "30"]).output().unwrap());
    std::fs::write(d.join("wave-30.jsonl"), &poses).unwrap();
    // A field of the same take.
    ok(&frond(d)
        .args(["take", "field", "wave", "--rows", "2", "--cols", "3", "--cell", "0.4", "--speed", "1"])
        .args(["--density", "1", "-o", "field.json"])
        .output()
        .unwrap());
    ok(&frond(d)
        .args(["take", "export", "wave", "--bvh", "-o", "field.bvh", "--rig", "grass"])
        .args(["--field", "field.json", "--duration", "2"])
        .output()
        .unwrap());
    let field: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("field.json")).unwrap()).unwrap();
    let plants: Vec<serde_json::Value> = field["plants"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            serde_json::json!({"prefix": format!("grass_{i}"), "position_m": p["position_m"], "scale": p["scale"]})
        })
        .collect();
    assert_eq!(plants.len(), 6);
    let field_text = std::fs::read_to_string(d.join("field.bvh")).unwrap();
    assert_eq!(field_text.matches("ROOT ").count(), 6);
    assert!(field_text.contains("Frames: 61\n"), "2 s at 30 fps, both ends");

    let rig = frond_motion::rig_files::load_rig("grass").unwrap().rig;
    let heights =
        frond_motion::sim::node_heights_m(std::array::from_fn(|j| rig.joints[j].height_m), &rig.mesh);
    let names: Vec<&str> = rig.joints.iter().map(|j| j.name.as_str()).collect();
    let spec = serde_json::json!({
        "bvh": d.join("wave.bvh"),
        "poses": d.join("wave-30.jsonl"),
        "names": names,
        "heights_m": heights,
        "field": {"bvh": d.join("field.bvh"), "plants": plants},
    });
    std::fs::write(d.join("spec.json"), spec.to_string()).unwrap();
    let Some(py) = python_with_bpy() else {
        let why = "no bpy in tests/python/.venv (run exporters/osc/tests/install-python.sh)";
        assert!(!required(), "{why} (required because CI=true or FROND_REQUIRE_PYTHON=1)");
        eprintln!("SKIPPED: {why}");
        return;
    };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bvh_blender.py");
    let out = Command::new(py).arg(script).arg(d.join("spec.json")).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("ok:"),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{}", stdout.lines().find(|l| l.starts_with("ok:")).unwrap_or_default());
}

#[test]
fn bad_bvh_arguments_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    performed(d);
    let code = |args: &[&str]| frond(d).args(args).output().unwrap();
    let out = code(&["take", "export", "wave", "--bvh"]);
    assert_eq!(out.status.code(), Some(2), "--bvh needs -o");
    let out = code(&["take", "export", "wave", "--bvh", "-o", "x.bvh", "--field", "f.json"]);
    assert_eq!(out.status.code(), Some(2), "--field needs --duration");
    let out = code(&["take", "export", "wave", "--bvh", "-o", "x.bvh", "--fps", "0", "--rig", "grass"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--fps must be above 0"));
    let out = code(&["take", "export", "wave", "--bvh", "-o", "x.bvh", "--rig", "nope"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("nope"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = code(&[
        "take",
        "export",
        "wave",
        "--bvh",
        "-o",
        "x.bvh",
        "--rig",
        "grass",
        "--field",
        "/dev/zero",
        "--duration",
        "1",
    ]);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("cannot read field"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!d.join("x.bvh").exists(), "nothing written on errors");
}
