//! The tests' Python venv (tests/python/.venv, made by the install scripts `scripts/test` runs),
//! shared by the crates whose tests check frond's output with real Python tools. Included with
//! `#[path = ".../tests/support/python.rs"] mod python;` from a crate's `tests/`.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Whether a missing tool fails the test instead of skipping it (CI, or FROND_REQUIRE_PYTHON=1).
pub fn required() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
        || std::env::var("FROND_REQUIRE_PYTHON").is_ok_and(|v| v == "1")
}

/// Says why a check is skipped, or fails when the environment demands it.
pub fn skip(why: &str) {
    assert!(!required(), "{why} (required because CI=true or FROND_REQUIRE_PYTHON=1)");
    eprintln!("SKIPPED: {why}");
}

/// The venv's python.
pub fn venv_python() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|d| d.join("tests/python/venv.sh").exists())
        .expect("the workspace root holds tests/python")
        .join("tests/python/.venv/bin/python")
}

/// The venv's python when it can import every one of `modules` (comma-separated).
pub fn python_with(modules: &str) -> Option<PathBuf> {
    let py = venv_python();
    let ok = Command::new(&py)
        .args(["-c", &format!("import {modules}")])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    ok.then_some(py)
}

/// Runs `script ARGS` with `py`; asserts it printed `ok:` and exited 0, and echoes that line.
pub fn python_check(py: &Path, script: &Path, args: &[&str]) {
    let out = Command::new(py).arg(script).args(args).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("ok:"),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{}", stdout.lines().find(|l| l.starts_with("ok:")).unwrap_or_default());
}
