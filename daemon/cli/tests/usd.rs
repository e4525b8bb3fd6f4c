//! `frond take export --usd` (issue 18) against the real counterparts: Pixar's usd-core
//! (compliance checker, UsdSkel's own evaluation of the skeleton and skinning) and Blender's USD
//! importer, both driven by `usd_check.py` in the tests' venv (`daemon/cli/tests/install-python.sh`).
//! Without them the test says why and passes as skipped, unless `CI=true` or
//! `FROND_REQUIRE_PYTHON=1`.

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

fn python_with(module: &str) -> Option<PathBuf> {
    let py = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/.venv/bin/python");
    let ok = Command::new(&py)
        .args(["-c", &format!("import {module}")])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    ok.then_some(py)
}

fn skip(why: &str) {
    assert!(!required(), "{why} (required because CI=true or FROND_REQUIRE_PYTHON=1)");
    eprintln!("SKIPPED: {why}");
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

fn check(py: &Path, args: &[&str], spec: &Path) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/usd_check.py");
    let out = Command::new(py).arg(script).args(args).arg(spec).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("ok:"),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{}", stdout.lines().find(|l| l.starts_with("ok:")).unwrap_or_default());
}

#[test]
fn usd_core_and_blender_read_the_skeleton_and_its_animation() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    performed(d);
    let poses = ok(&frond(d).args(["take", "export", "wave", "--fps", "30"]).output().unwrap());
    std::fs::write(d.join("wave-30.jsonl"), &poses).unwrap();
    for rig in ["grass", "flower"] {
        let file = format!("wave-{rig}.usda");
        ok(&frond(d).args(["take", "export", "wave", "--usd", "-o", &file, "--rig", rig]).output().unwrap());
        let text = std::fs::read_to_string(d.join(&file)).unwrap();
        assert!(text.starts_with("#usda 1.0\n"), "{}", &text[..40]);
        assert!(text.contains("upAxis = \"Y\"") && text.contains("timeCodesPerSecond = 30"));
        let loaded = frond_motion::rig_files::load_rig(rig).unwrap().rig;
        let names: Vec<&str> = loaded.joints.iter().map(|j| j.name.as_str()).collect();
        let heights: Vec<f32> = loaded.joints.iter().map(|j| j.height_m).collect();
        let spec = serde_json::json!({
            "usd": d.join(&file), "poses": d.join("wave-30.jsonl"), "names": names,
            "heights_m": heights, "fps": 30.0,
        });
        let spec_path = d.join(format!("spec-{rig}.json"));
        std::fs::write(&spec_path, spec.to_string()).unwrap();
        match python_with("pxr") {
            Some(py) => check(&py, &[], &spec_path),
            None => skip("no usd-core in tests/python/.venv (run daemon/cli/tests/install-python.sh)"),
        }
        match python_with("bpy") {
            Some(py) => check(&py, &["--blender"], &spec_path),
            None => skip("no bpy in tests/python/.venv (run exporters/osc/tests/install-python.sh)"),
        }
    }
}

#[test]
fn bad_usd_arguments_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    performed(d);
    let run = |args: &[&str]| frond(d).args(args).output().unwrap();
    let out = run(&["take", "export", "wave", "--usd"]);
    assert_eq!(out.status.code(), Some(2), "--usd needs -o");
    let out = run(&["take", "export", "wave", "--usd", "-o", "x.usdc", "--rig", "grass"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("usdcat"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run(&["take", "export", "wave", "--usd", "--bvh", "-o", "x.usda"]);
    assert_eq!(out.status.code(), Some(2), "one file format at a time");
    assert!(!d.join("x.usda").exists() && !d.join("x.usdc").exists());
}
