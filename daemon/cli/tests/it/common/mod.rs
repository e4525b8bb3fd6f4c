//! Helpers shared by the CLI's integration tests: the real `frond` binary on a takes directory,
//! outcome checks, a performed take, and the tests' Python venv.
#![allow(dead_code)] // each test binary uses its own part

use std::path::Path;
use std::process::{Command, Output};

/// `frond` with `takes` as its takes directory (and working directory), no daemon.
pub fn frond(takes: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_frond"));
    c.env_remove("FROND_SOCKET_DIR").env("FROND_TAKES_DIR", takes).current_dir(takes);
    c
}

/// Asserts success; returns stdout.
pub fn ok(out: &Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Asserts exit status `code` and a stderr that names `needle` (and no panic).
pub fn failed(out: &Output, code: i32, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{err}");
    assert!(err.contains(needle), "stderr lacks {needle:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[path = "../../../../../tests/support/python.rs"]
mod python;
#[allow(unused_imports)] // each test binary uses its own part
pub use python::{python_with, required, skip};

/// Runs `tests/SCRIPT ARGS SPEC` with `py`; asserts it printed `ok:` and exited 0.
pub fn python_check(py: &Path, script: &str, args: &[&str], spec: &Path) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join(script);
    let mut all: Vec<&str> = args.to_vec();
    all.push(spec.to_str().expect("a UTF-8 path"));
    python::python_check(py, &script, &all);
}

/// A take `wave` in `dir`: 3 s at 100 Hz of every angle moving (roll too), imported as poses.
pub fn performed(dir: &Path) {
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
