//! frond's Blender add-on's OSC side against mutated datagrams: `addon_fuzz.py` (no Blender
//! needed; python-osc makes the valid datagrams it mutates) feeds 50,000 of them to
//! `Receiver.take`, the add-on's handling of each datagram its socket receives: no exception may
//! escape, every frame taken must be finite values of the right types, every field kept within
//! its limits and evaluable. Before, a datagram of bundles nested 3,000 deep escaped as a
//! RecursionError (losing the rest of the timer's batch) and an element pose with a NaN angle
//! reached the bones.

use std::path::Path;
use std::process::Command;

use crate::support::{python_with, skip};

#[test]
fn blender_addon_takes_any_datagram_without_an_escape() {
    let Some(py) = python_with("pythonosc, numpy") else {
        skip("no python-osc and numpy in tests/python/.venv (run exporters/osc/tests/install-python.sh)");
        return;
    };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/addon_fuzz.py");
    let out = Command::new(&py).arg(&script).args(["--iterations", "50000"]).output().unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{said}{}", String::from_utf8_lossy(&out.stderr));
    assert!(said.contains("50000 mutated datagrams") && said.contains("no escape"), "{said}");
}
