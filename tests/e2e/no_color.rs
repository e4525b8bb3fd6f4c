//! Issue 18, CLI habits: `NO_COLOR` (no-color.org) is honoured. The binaries that log
//! (frondd, frond-vhid, frond-osc, frond-zenoh) colour it only on a terminal; under a pseudo-terminal (util-linux `script`) they colour their log
//! lines, and with `NO_COLOR=1` they do not. The first run is the positive control: a test
//! that found no escape code in either would prove nothing.

use std::process::Command;

use frond_e2e::{bin, fuse_available};

/// Runs `cmd` under a pseudo-terminal for about a second and returns what it printed, or
/// `None` when `script` cannot run here.
fn under_a_terminal(cmd: &str, no_color: bool) -> Option<String> {
    let env = if no_color { "NO_COLOR=1" } else { "NO_COLOR=" };
    let out = Command::new("script")
        .args(["-qec", &format!("env {env} timeout -s INT 1.5 {cmd}"), "/dev/null"])
        .output()
        .ok()?;
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

#[test]
fn no_color_turns_off_the_log_colours() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display();
    let mut cases = vec![format!(
        "{} --socket-dir {d}/run --takes-dir {d}/takes --source in-process",
        bin("frondd").display()
    )];
    if fuse_available() {
        cases.push(format!("{} --backend fuse --node {d}/glove/hidraw-frond", bin("frond-vhid").display()));
    }
    // The exporters that log, beside a daemon: frond-osc and frond-zenoh (frond-binmain's logging).
    let daemon = frond_e2e::Daemon::start(&dir.path().join("daemon"), &["--source", "in-process"]);
    let sock = daemon.socket_dir.display();
    cases.push(format!("{} --socket-dir {sock} --target 127.0.0.1:9", bin("frond-osc").display()));
    cases.push(format!(
        "{} --socket-dir {sock} --stage nocolor --source a --listen tcp/127.0.0.1:0",
        bin("frond-zenoh").display()
    ));
    for cmd in cases {
        let Some(coloured) = under_a_terminal(&cmd, false) else {
            eprintln!("skipped: util-linux script cannot run here");
            return;
        };
        assert!(coloured.contains('\u{1b}'), "no colour even on a terminal (the control): {coloured}");
        let plain = under_a_terminal(&cmd, true).unwrap();
        assert!(!plain.is_empty(), "{cmd} printed nothing");
        assert!(!plain.contains('\u{1b}'), "NO_COLOR=1 still coloured: {plain:?}");
    }
}
