//! Every baked file passes the Khronos glTF validator (npm `gltf-validator`, installed by
//! `install-node.sh`) with 0 errors and 0 warnings: each rig of `rig-files/plants/`, a layered
//! take, a field, and the `.gltf` + `.bin` form.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::*;

fn validate(files: &[PathBuf]) -> Option<Vec<serde_json::Value>> {
    let (node, script) = validator()?;
    let out = Command::new(node).arg(script).args(files).output().expect("run node");
    assert!(out.status.success(), "validate.mjs failed: {}", String::from_utf8_lossy(&out.stderr));
    Some(serde_json::from_slice(&out.stdout).expect("validator report JSON"))
}

fn assert_clean(reports: &[serde_json::Value]) {
    for r in reports {
        let issues = &r["issues"];
        let (errors, warnings) =
            (issues["numErrors"].as_u64().unwrap(), issues["numWarnings"].as_u64().unwrap());
        assert!(
            errors == 0 && warnings == 0,
            "{}: {errors} errors, {warnings} warnings: {:#}",
            r["file"],
            issues["messages"]
        );
        // The validator did read the animation and the skin.
        assert!(r["info"]["animationCount"].as_u64().unwrap() >= 1, "{r:#}");
        assert!(r["info"]["hasSkins"].as_bool().unwrap(), "{r:#}");
    }
}

fn bake(args: &[&str]) {
    let mut all = vec!["bake", "--quiet"];
    all.extend_from_slice(args);
    run_ok(&all);
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn every_rig_a_layered_take_and_a_field_validate_clean() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let take = grass_take(d, "sway");
    let mut files = Vec::new();
    for rig in rig_files() {
        let out = d.join(format!("{}.glb", rig.file_stem().unwrap().to_str().unwrap()));
        bake(&["--take", s(&take), "--rig", s(&rig), "-o", s(&out)]);
        files.push(out);
    }
    let layered = layered_take(d, "layered");
    let out = d.join("layered.glb");
    bake(&["--take", s(&layered), "--rig", "flower", "-o", s(&out)]);
    files.push(out);
    let field = field_json(d, 12, 30.0);
    let out = d.join("field.glb");
    bake(&[
        "--field",
        s(&field),
        "--take",
        s(&layered),
        "--rig",
        "flower",
        "--duration",
        "1.5",
        "-o",
        s(&out),
    ]);
    files.push(out);
    let other = write_take(d, "other", "flower", frames(0, 1.0, 1.0, 200.0, 2.0), &[]);
    let out = d.join("grove.glb");
    bake(&["--take", s(&layered), s(&other), s(&layered), "--rig", "flower", "-o", s(&out)]);
    files.push(out);
    let out = d.join("split.gltf");
    bake(&["--take", s(&take), "--rig", "shrub", "--gltf", "--fps", "24", "-o", s(&out)]);
    files.push(out);
    let Some(reports) = validate(&files) else { return };
    assert_eq!(reports.len(), files.len());
    assert_clean(&reports);
}
