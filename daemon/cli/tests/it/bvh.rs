//! `frond take export --bvh` (issue 18) against the real counterpart: Blender's own BVH importer
//! (bpy from PyPI, in the tests' venv, `exporters/osc/tests/install-python.sh`), which
//! `bvh_blender.py` drives and checks against forward kinematics computed there. Without bpy the
//! test says why and passes as skipped, unless `CI=true` or `FROND_REQUIRE_PYTHON=1`.

use crate::common;

use common::{frond, ok, performed, python_check, python_with, skip};

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
            serde_json::json!({"prefix": format!("grass_{i}"), "position_m": p["position_m"], "scale": p["scale"],
                               "start_frame": p["start_frame"], "delay_s": p["delay_s"]})
        })
        .collect();
    assert_eq!(plants.len(), 6);
    // The layout's direction is the take's: plants bend as the take does (no rotation to check).
    assert_eq!(field["direction_deg"], field["authored_direction_deg"]);
    assert!(plants.iter().any(|p| p["delay_s"].as_f64().unwrap() > 0.0), "some plant is delayed");
    let field_text = std::fs::read_to_string(d.join("field.bvh")).unwrap();
    assert_eq!(field_text.matches("ROOT ").count(), 6);
    assert!(field_text.contains("Frames: 61\n"), "2 s at 30 fps, both ends");

    let rig = frond_formats::rig_files::load_rig("grass").unwrap().rig;
    let heights =
        frond_motion::sim::node_heights_m(std::array::from_fn(|j| rig.joints[j].height_m), &rig.mesh);
    let names: Vec<&str> = rig.joints.iter().map(|j| j.name.as_str()).collect();
    let spec = serde_json::json!({
        "bvh": d.join("wave.bvh"),
        "poses": d.join("wave-30.jsonl"),
        "names": names,
        "heights_m": heights,
        "field": {"bvh": d.join("field.bvh"), "plants": plants, "fps": field["fps"], "frames": 61},
    });
    std::fs::write(d.join("spec.json"), spec.to_string()).unwrap();
    match python_with("bpy") {
        Some(py) => python_check(&py, "bvh_blender.py", &[], &d.join("spec.json")),
        None => skip("no bpy in tests/python/.venv (run exporters/osc/tests/install-python.sh)"),
    }
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
    for tc in [&["--timecode-start", "01:00:00:00"][..], &["--timecode"][..]] {
        let out = code(&[&["take", "export", "wave", "--bvh", "-o", "x.bvh"][..], tc].concat());
        assert_eq!(out.status.code(), Some(2), "{tc:?} with --bvh");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("cannot be used with") && err.contains("'--bvh'"), "{tc:?}: {err}");
    }
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
