//! Independent read-back: `readback.py` (pygltflib plus its own take parser and its own
//! implementation of the rotation convention) checks joint rotations at sampled times against
//! the take within 1e-4, and that weights sum to 1. Needs the shared venv
//! (`install-python.sh`); skips with a message without it, fails under CI=true or
//! FROND_REQUIRE_TOOLS=1.

use crate::common;

use std::path::Path;
use std::process::Command;

use common::*;

fn readback(py: &Path, glb: &Path, take: &Path) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/readback.py");
    let out = Command::new(py).arg(script).arg(glb).arg(take).output().expect("run python");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "readback.py failed for {}: {stdout}\n{}",
        glb.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&stdout).unwrap()
}

#[test]
fn python_reads_back_the_take_rotations_and_normalised_weights() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = |p: &Path| p.to_str().unwrap().to_string();

    let take = grass_take(d, "sway");
    let out = d.join("grass.glb");
    run_ok(&["bake", "--quiet", "--take", &s(&take), "--rig", "grass", "-o", &s(&out)]);
    let r = readback(&py, &out, &take);
    assert_eq!(r["animations"], 1);
    assert!(r["rotations_checked"].as_u64().unwrap() >= 4 * 6, "{r}");
    assert!(r["vertices_checked"].as_u64().unwrap() > 10, "{r}");

    // A layered take: the leaf layer (which starts 0.5 s after the plant's) on both leaves.
    let layered = layered_take(d, "layered");
    let out = d.join("flower.glb");
    run_ok(&["bake", "--quiet", "--take", &s(&layered), "--rig", "flower", "-o", &s(&out), "--fps", "25"]);
    let r = readback(&py, &out, &layered);
    assert!(r["rotations_checked"].as_u64().unwrap() >= 12 * 6, "{r}");

    // The check can fail: the same file against a different take is refused.
    let other = write_take(d, "other", "grass", frames(0, 5.0, 2.0, 200.0, 0.7), &[]);
    let bad = Command::new(&py)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/readback.py"))
        .arg(d.join("grass.glb"))
        .arg(&other)
        .output()
        .unwrap();
    assert!(!bad.status.success(), "readback accepted the wrong take");
}
