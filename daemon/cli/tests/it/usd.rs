//! `frond take export --usd` (issue 18) against the real counterparts: Pixar's usd-core
//! (compliance checker, UsdSkel's own evaluation of the skeleton and skinning) and Blender's USD
//! importer, both driven by `usd_check.py` in the tests' venv (`daemon/cli/tests/install-python.sh`).
//! Without them the test says why and passes as skipped, unless `CI=true` or
//! `FROND_REQUIRE_PYTHON=1`.

use crate::common;

use common::{frond, ok, performed, python_check, python_with, skip};

#[test]
fn usd_core_and_blender_read_the_skeleton_and_its_animation() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    performed(d);
    let poses = ok(&frond(d).args(["take", "export", "wave", "--fps", "30"]).output().unwrap());
    std::fs::write(d.join("wave-30.jsonl"), &poses).unwrap();
    for (rig, binary) in [("grass", false), ("flower", false), ("grass", true), ("flower", true)] {
        let text_file = format!("wave-{rig}.usda");
        let file = if binary { format!("wave-{rig}.usdc") } else { text_file.clone() };
        ok(&frond(d).args(["take", "export", "wave", "--usd", "-o", &file, "--rig", rig]).output().unwrap());
        let bytes = std::fs::read(d.join(&file)).unwrap();
        if binary {
            assert!(bytes.starts_with(b"PXR-USDC"), "{:?}", &bytes[..8]);
        } else {
            let text = String::from_utf8(bytes).unwrap();
            assert!(text.starts_with("#usda 1.0\n"), "{}", &text[..40]);
            assert!(text.contains("upAxis = \"Y\"") && text.contains("timeCodesPerSecond = 30"));
        }
        let loaded = frond_formats::rig_files::load_rig(rig).unwrap().rig;
        let names: Vec<&str> = loaded.joints.iter().map(|j| j.name.as_str()).collect();
        let heights: Vec<f32> = loaded.joints.iter().map(|j| j.height_m).collect();
        let spec = serde_json::json!({
            "usd": d.join(&file), "poses": d.join("wave-30.jsonl"), "names": names,
            "heights_m": heights, "fps": 30.0,
            // The binary layer, read by usd-core, equals the text layer, read by usd-core.
            "same_as": if binary { Some(d.join(&text_file)) } else { None },
        });
        let spec_path = d.join(format!("spec-{rig}-{}.json", if binary { "usdc" } else { "usda" }));
        std::fs::write(&spec_path, spec.to_string()).unwrap();
        match python_with("pxr") {
            Some(py) => python_check(&py, "usd_check.py", &[], &spec_path),
            None => skip("no usd-core in tests/python/.venv (run daemon/cli/tests/install-python.sh)"),
        }
        match python_with("bpy") {
            Some(py) => python_check(&py, "usd_check.py", &["--blender"], &spec_path),
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
    let out = run(&["take", "export", "wave", "--usd", "-o", "x.usdz", "--rig", "grass"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains(".usdc (binary)"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run(&["take", "export", "wave", "--usd", "--bvh", "-o", "x.usda"]);
    assert_eq!(out.status.code(), Some(2), "one file format at a time");
    assert!(!d.join("x.usda").exists() && !d.join("x.usdz").exists());
}
