//! The `frond-vhid` binary: node path on stdout, clean exit and unmount, clear errors.

use crate::common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use frond_device::{DeviceProfile, HidSource, SourceKind};

fn vhid() -> Command {
    Command::new(env!("CARGO_BIN_EXE_frond-vhid"))
}

/// Starts frond-vhid and returns it with the node path from its first stdout line.
fn start(args: &[&str]) -> (Child, PathBuf) {
    let mut child = vhid()
        .args(args)
        .args(["--backend", "fuse"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    assert!(!line.is_empty(), "frond-vhid printed no node path");
    (child, PathBuf::from(line.trim_end()))
}

fn wait(child: &mut Child, timeout: Duration) -> std::process::ExitStatus {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("frond-vhid did not exit");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn run_err(args: &[&str]) -> String {
    let out = vhid().args(args).args(["--backend", "fuse"]).output().unwrap();
    assert!(!out.status.success());
    assert!(out.stdout.is_empty());
    String::from_utf8(out.stderr).unwrap()
}

#[test]
fn sigterm_and_sigint_unmount_cleanly() {
    if !fuse_available() {
        return;
    }
    for sig in [libc::SIGTERM, libc::SIGINT] {
        let tmp = tempfile::tempdir().unwrap();
        let node = tmp.path().join("glove/hidraw-frond");
        let (mut child, printed) = start(&["--sway", "--rate", "250", "--node", node.to_str().unwrap()]);
        assert_eq!(printed, node);
        let dir = node.parent().unwrap().canonicalize().unwrap();
        assert!(is_mounted(&dir));
        // A reader gets reports through hidapi.
        let profile = DeviceProfile::frond_glove();
        let mut src = HidSource::open_path(&profile, &node, SourceKind::FuseHidraw).unwrap();
        assert_eq!(read_n(&mut src, 5, Duration::from_secs(10)).unwrap().len(), 5);
        // SAFETY: plain kill(2) on our own child's pid.
        assert_eq!(unsafe { libc::kill(child.id() as i32, sig) }, 0);
        let status = wait(&mut child, Duration::from_secs(10));
        assert!(status.success(), "{status:?}");
        assert!(!is_mounted(&dir), "mount left behind after signal {sig}");
        assert!(!dir.exists(), "mount directory left behind");
    }
}

#[test]
fn jsonl_playback_exits_zero_after_the_file() {
    if !fuse_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("hand.jsonl");
    std::fs::write(&file, hand_jsonl(30, 100.0)).unwrap();
    let node = tmp.path().join("g/hidraw-frond");
    let (mut child, _) = start(&[
        "--play",
        file.to_str().unwrap(),
        "--node",
        node.to_str().unwrap(),
        "--start-delay-ms",
        "300",
        "--linger-ms",
        "200",
    ]);
    let profile = DeviceProfile::frond_glove();
    let mut src = HidSource::open_path(&profile, &node, SourceKind::FuseHidraw).unwrap();
    let got = read_n(&mut src, 30, Duration::from_secs(10)).unwrap();
    assert_eq!(got.len(), 30);
    assert_eq!(got[29].device_seq, 29);
    let status = wait(&mut child, Duration::from_secs(10));
    assert!(status.success());
    assert!(!Path::new(&node).exists());
}

#[test]
fn clear_errors_for_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nope.jsonl");
    let e = run_err(&["--play", missing.to_str().unwrap()]);
    assert!(e.contains("cannot read hand file") && e.contains("nope.jsonl"), "{e}");

    let bad = tmp.path().join("bad.jsonl");
    std::fs::write(&bad, "{\"t\":0,\"wrist\":[1,2,3],\"thumb\":[4,5,6]}\nnot json\n").unwrap();
    let e = run_err(&["--play", bad.to_str().unwrap()]);
    assert!(e.contains("bad.jsonl:2:"), "{e}");

    let e = run_err(&["--sway", "--rate", "9000"]);
    assert!(e.contains("rate 9000"), "{e}");
    let e = run_err(&["--sway", "--drop", "2"]);
    assert!(e.contains("drop probability"), "{e}");

    // The mount directory must be empty; nothing is mounted over existing files.
    std::fs::write(tmp.path().join("keep"), "x").unwrap();
    let node = tmp.path().join("hidraw-frond");
    let e = run_err(&["--sway", "--node", node.to_str().unwrap()]);
    assert!(e.contains("not empty"), "{e}");
}
