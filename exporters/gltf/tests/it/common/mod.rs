//! Shared helpers of frond-gltf's integration tests: takes made with the motion codec in a temp
//! dir, running the binary, and finding the external tools (node, the venv's python).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use frond_formats::layers::TakeBytes;
use frond_motion::layers::Take;
use frond_motion::{JOINTS, PoseFrame, TakeFrame, TakeHeader};
use frond_protocol::ElementId;

/// The binary under test.
pub fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_frond-gltf"))
}

/// Runs `frond-gltf ARGS`.
pub fn run(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().expect("run frond-gltf")
}

/// Runs and asserts success; returns stderr.
pub fn run_ok(args: &[&str]) -> String {
    let out = run(args);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "frond-gltf {args:?} failed: {stderr}");
    stderr
}

pub fn header(name: &str, rig: &str) -> TakeHeader {
    TakeHeader {
        calibration_id: "cal-test-7".to_string(),
        created_unix_s: 1_700_000_000,
        ..TakeHeader::offline(name, rig, 200)
    }
}

/// A pose of a non-trivial, non-linear sway at time `t` (degrees); `phase` varies per layer.
pub fn sway(t: f64, phase: f64) -> [[f32; 3]; JOINTS] {
    std::array::from_fn(|i| {
        let k = i as f64 + 1.0;
        [
            (40.0 * (1.7 * t + phase + 0.3 * k).sin()) as f32,
            (-25.0 * (1.1 * t + phase).cos() + 5.0 * k) as f32,
            if i >= 2 { (30.0 * (2.3 * t + phase).sin()) as f32 } else { 0.0 },
        ]
    })
}

/// `seconds` of frames at `rate_hz` for one layer, starting at device time `t0`.
pub fn frames(element: u16, t0: f64, seconds: f64, rate_hz: f64, phase: f64) -> Vec<TakeFrame> {
    let n = (seconds * rate_hz).round() as usize + 1;
    (0..n)
        .map(|k| {
            let t = t0 + k as f64 / rate_hz;
            TakeFrame {
                seq: k as u64,
                device_time_us: (t * 1e6) as u64,
                element: ElementId::new(element),
                pose: PoseFrame { t, joints_deg: sway(t - t0, phase) },
                ..TakeFrame::default()
            }
        })
        .collect()
}

/// Writes a take (every frame, layer names in the header) with the motion codec.
pub fn write_take(
    dir: &Path,
    name: &str,
    rig: &str,
    frames: Vec<TakeFrame>,
    layer_names: &[&str],
) -> PathBuf {
    let mut take = Take::new(header(name, rig));
    take.frames = frames;
    take.element_names = layer_names.iter().map(|s| s.to_string()).collect();
    let path = dir.join(format!("{name}.take"));
    std::fs::write(&path, take.to_bytes()).unwrap();
    path
}

/// A simple grass take: 2 s at 200 Hz starting at device time 5 s.
pub fn grass_take(dir: &Path, name: &str) -> PathBuf {
    write_take(dir, name, "grass", frames(0, 5.0, 2.0, 200.0, 0.0), &[])
}

/// A flower take with a `leaf` layer that starts later.
pub fn layered_take(dir: &Path, name: &str) -> PathBuf {
    let mut f = frames(0, 5.0, 2.0, 200.0, 0.0);
    f.extend(frames(1, 5.5, 1.0, 200.0, 1.0));
    write_take(dir, name, "flower", f, &["leaf"])
}

/// A `field.json` (version 1, as `frond take field` writes it) of `n` plants in one row along
/// +X: plant `i` at `[0.3 i, 0.2 (i % 2)]`, delay `0.2 i` s, start frame `3 i`, scale
/// `1 + 0.1 i`, force heading `direction_deg` (authored at 0).
pub fn field_json(dir: &Path, n: usize, direction_deg: f64) -> PathBuf {
    let plants: Vec<String> = (0..n)
        .map(|i| {
            format!(
                r#"{{"id": {i}, "row": 0, "col": {i}, "position_m": [{x}, {z}], "source": 0, "delay_s": {d}, "start_frame": {s}, "scale": {sc}}}"#,
                x = i as f32 * 0.3,
                z = (i % 2) as f32 * 0.2,
                d = i as f64 * 0.2,
                s = 3 * i,
                sc = 1.0 + 0.1 * i as f32
            )
        })
        .collect();
    let path = dir.join("field.json");
    std::fs::write(
        &path,
        format!(
            r#"{{"version": 1, "take": "wind", "fps": 30.0, "frames": 61, "rows": 1, "cols": {n}, "cell_m": 0.3,
                "speed_m_s": 1.5, "direction_deg": {direction_deg}, "authored_direction_deg": 0.0, "density": 1.0,
                "seed": 3, "plants": [{}]}}"#,
            plants.join(",")
        ),
    )
    .unwrap();
    path
}

/// The rigs of rig-files/plants/.
pub fn rig_files() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/plants");
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

/// True when missing tools must fail the test instead of skipping it.
pub fn tools_required() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
        || std::env::var("FROND_REQUIRE_TOOLS").is_ok_and(|v| v == "1")
}

/// Skips (prints why, returns None) or fails when a tool is missing.
pub fn missing_tool<T>(what: &str, fix: &str) -> Option<T> {
    let msg = format!("{what} is not available; run {fix}");
    if tools_required() {
        panic!("{msg} (required: CI=true or FROND_REQUIRE_TOOLS=1)");
    }
    eprintln!("SKIPPED: {msg}");
    None
}

/// `node` and the installed validator, or a skip.
pub fn validator() -> Option<(PathBuf, PathBuf)> {
    let here = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let script = here.join("validate.mjs");
    let node_ok = Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    if !node_ok {
        return missing_tool("node", "exporters/gltf/tests/install-node.sh");
    }
    if !here.join("node_modules/gltf-validator").is_dir() {
        return missing_tool("the npm package gltf-validator", "exporters/gltf/tests/install-node.sh");
    }
    Some((PathBuf::from("node"), script))
}

/// The shared test venv's python with pygltflib, or a skip.
pub fn python() -> Option<PathBuf> {
    let py = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/.venv/bin/python");
    if !py.exists() {
        return missing_tool("the test venv tests/python/.venv", "exporters/gltf/tests/install-python.sh");
    }
    let ok = Command::new(&py).args(["-c", "import pygltflib"]).output().is_ok_and(|o| o.status.success());
    if !ok {
        return missing_tool("pygltflib in tests/python/.venv", "exporters/gltf/tests/install-python.sh");
    }
    Some(py)
}

/// Reads a .glb (or a .gltf with its .bin beside it) with the `gltf` crate.
pub fn load(path: &Path) -> (gltf::Document, Vec<Vec<u8>>) {
    let g = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let buffers = g
        .document
        .buffers()
        .map(|b| match b.source() {
            gltf::buffer::Source::Bin => g.blob.clone().unwrap(),
            gltf::buffer::Source::Uri(uri) => std::fs::read(path.parent().unwrap().join(uri)).unwrap(),
        })
        .collect();
    (g.document, buffers)
}
