//! Issue 18, CLI habits, for every binary beside `frond` (whose own are in
//! `daemon/cli/tests/docs.rs`): `--man DIR` writes pages that the real `man` renders,
//! `--completions bash` is a script bash sources and that registers the binary, a bad
//! `--log-level` is a usage error (exit 2), usage errors found after parsing exit 2 and failures
//! while running exit 1, and an error is printed once, on one line.

use std::process::Command;

use frond_e2e::bin;

/// The binaries a user runs, with one option their man page must mention.
const BINARIES: [(&str, &str); 7] = [
    ("frondd", "--socket-dir"),
    ("frond-vhid", "--osc"),
    ("frond-osc", "--vmc-bones"),
    ("frond-gltf", "--man"),
    ("frond-warp", "--completions"),
    ("frond-console", "--token-file"),
    ("frond-zenoh", "--zenoh-config"),
];

fn run(name: &str, args: &[&str]) -> std::process::Output {
    Command::new(bin(name)).args(args).env("NO_COLOR", "1").output().unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn every_binary_writes_man_pages_and_bash_completions() {
    let man_here = Command::new("man").arg("--version").output().is_ok_and(|o| o.status.success());
    for (name, option) in BINARIES {
        let dir = tempfile::tempdir().unwrap();
        let out = run(name, &["--man", dir.path().to_str().unwrap()]);
        assert!(out.status.success(), "{name} --man: {}", String::from_utf8_lossy(&out.stderr));
        let page = dir.path().join(format!("{name}.1"));
        let text = std::fs::read_to_string(&page).unwrap_or_else(|e| panic!("{}: {e}", page.display()));
        assert!(text.contains(&format!(".TH {name} 1")), "{name}.1 header: {text}");
        assert!(text.contains(&option.replace('-', "\\-")), "{name}.1 lacks {option}");
        if man_here {
            let man = Command::new("man").args(["-l", "-P", "cat"]).arg(&page).output().unwrap();
            let shown = String::from_utf8_lossy(&man.stdout);
            assert!(
                man.status.success() && shown.contains("NAME") && shown.contains(option),
                "{name}: {shown}"
            );
        }

        let out = run(name, &["--completions", "bash"]);
        assert!(out.status.success(), "{name} --completions: {}", String::from_utf8_lossy(&out.stderr));
        let script = dir.path().join("completion.bash");
        std::fs::write(&script, &out.stdout).unwrap();
        let check = Command::new("bash")
            .arg("-c")
            .arg(format!("set -e; source {}; complete -p {name}", script.display()))
            .output()
            .expect("bash");
        let said = String::from_utf8_lossy(&check.stdout);
        assert!(
            check.status.success() && said.contains(name),
            "{name}: {said}{}",
            String::from_utf8_lossy(&check.stderr)
        );
        // --man takes no other argument.
        let out = run(name, &["--man", dir.path().to_str().unwrap(), "--version"]);
        assert_eq!(out.status.code(), Some(2), "{name}: --man with another argument");
    }
    if !man_here {
        eprintln!("skipped the rendering: no man here");
    }
}

#[test]
fn a_bad_log_level_is_a_usage_error_everywhere() {
    for name in ["frondd", "frond-vhid", "frond-osc", "frond-zenoh"] {
        let out = run(name, &["--log-level", "frond[{"]);
        assert_eq!(out.status.code(), Some(2), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.starts_with(&format!("{name}: error: --log-level")), "{name}: {err}");
    }
}

/// One line, the program's name once, no cause said twice (`X: X`).
fn said_once(name: &str, err: &str) {
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{name}: {err}");
    assert_eq!(err.matches(&format!("{name}:")).count(), 1, "{name}: {err}");
    let parts: Vec<&str> = lines[0].split(": ").collect();
    for w in parts.windows(2) {
        assert_ne!(w[0], w[1], "{name} repeats a cause: {err}");
    }
}

#[test]
fn usage_errors_exit_2_and_failures_exit_1_each_said_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let glb = d.join("x.glb").display().to_string();
    let png = d.join("x.gif").display().to_string();
    let unwritable = d.join("no/such/dir/x.gif").display().to_string();
    let node = d.join("g/hidraw-frond").display().to_string();
    let image = frond_e2e::repo_root().join("rig-files/images/grass.png").display().to_string();
    let mask = frond_e2e::repo_root().join("rig-files/images/grass-mask.png").display().to_string();
    // Usage errors found after clap parsed the arguments.
    let usage: [(&str, Vec<String>); 6] = [
        ("frond-vhid", ["--osc", "no-port-here"].map(String::from).to_vec()),
        // Found only when the glove's configuration is checked (was exit 1).
        ("frond-vhid", ["--osc", "127.0.0.1:9", "--rate", "0"].map(String::from).to_vec()),
        ("frond-vhid", ["--osc", "127.0.0.1:9", "--drop", "2"].map(String::from).to_vec()),
        ("frond-osc", ["--rate", "0"].map(String::from).to_vec()),
        (
            "frond-gltf",
            ["bake", "--rig", "grass", "--take", "x.take", "--fps", "0", "-o", &glb]
                .map(String::from)
                .to_vec(),
        ),
        (
            "frond-warp",
            ["render", "--image", &image, "--layer", &mask, "--frames", "0", "-o", &png]
                .map(String::from)
                .to_vec(),
        ),
    ];
    for (name, args) in &usage {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = run(name, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name} {args:?}: {err}");
    }
    // Failures while running: a file that is not there, a directory that cannot be written.
    let missing = d.join("missing.take").display().to_string();
    let failures: [(&str, Vec<String>); 3] = [
        ("frond-gltf", ["bake", "--rig", "grass", "--take", &missing, "-o", &glb].map(String::from).to_vec()),
        (
            "frond-warp",
            ["render", "--image", &image, "--layer", &mask, "--frames", "2", "-o", &unwritable]
                .map(String::from)
                .to_vec(),
        ),
        ("frond-vhid", ["--play", &missing, "--backend", "fuse", "--node", &node].map(String::from).to_vec()),
    ];
    for (name, args) in &failures {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = run(name, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name} {args:?}: {err}");
        said_once(name, &err);
    }
}

/// The exit status of `name ARGS` with its stdout and stderr sent where given.
fn run_to(
    name: &str,
    args: &[&str],
    stdout: std::process::Stdio,
    stderr: std::process::Stdio,
) -> Option<i32> {
    let mut child = Command::new(bin(name))
        .args(args)
        .env("NO_COLOR", "1")
        .stdout(stdout)
        .stderr(stderr)
        .spawn()
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    child.wait().unwrap().code()
}

/// A pipe whose reader has gone: writing to it fails with EPIPE (`frond tap | head -1`).
fn closed_pipe() -> std::process::Stdio {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    writer.into()
}

#[test]
fn unwritable_output_is_an_error_or_a_quiet_end_never_a_panic() {
    let full = || std::process::Stdio::from(std::fs::File::create("/dev/full").unwrap());
    for name in BINARIES.iter().map(|(n, _)| *n).chain(["frond"]) {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_str().unwrap();
        let man = if name == "frond" { ["man", "-o", d] } else { ["--man", d, ""] };
        let man = &man[..if name == "frond" { 3 } else { 2 }];
        // stdout on a full disk: exit 1, said on stderr (println! panicked: 101).
        let out = Command::new(bin(name)).args(man).stdout(full()).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name} --man > /dev/full: {err}");
        assert!(
            err.contains(&format!("{name}: error: cannot write to standard output: No space left on device")),
            "{name}: {err}"
        );
        assert!(!err.contains("panicked"), "{name}: {err}");
        // stdout's reader gone: a quiet end, status 0.
        let code = run_to(name, man, closed_pipe(), std::process::Stdio::null());
        assert_eq!(code, Some(0), "{name} --man | (closed)");
        // stderr's reader gone while a usage error is reported: still exit 2, not a panic's 101
        // or an abort.
        let code =
            run_to(name, &["--log-level", "no=such=filter"], std::process::Stdio::null(), closed_pipe());
        assert_eq!(code, Some(2), "{name} --log-level bad 2>(closed)");
    }
    // frondd's printed default configuration, onto a full disk.
    let out = Command::new(bin("frondd")).arg("--print-default-config").stdout(full()).output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn a_daemon_whose_log_reader_went_away_keeps_running() {
    // stderr into a pipe whose reader has gone (journald restarted, `frondd 2>&1 | head`): every
    // log line fails to write. The daemon logs as it starts, records and stops; it must do all
    // of it (tracing's own report of the failed write used to panic on the same stderr).
    let dir = tempfile::tempdir().unwrap();
    let mut daemon =
        frond_e2e::Daemon::start_with_stderr(dir.path(), &["--source", "in-process"], closed_pipe());
    daemon.frond_ok(&["record", "start", "quiet"]);
    std::thread::sleep(std::time::Duration::from_millis(300));
    daemon.frond_ok(&["record", "stop"]);
    assert!(daemon.proc.child.try_wait().unwrap().is_none(), "frondd is still running");
    assert!(daemon.takes_dir.join("quiet.take").is_file());
}

#[test]
fn an_unknown_flag_is_a_usage_error_with_the_name_in_front_everywhere() {
    // `frond-relay` parses by hand (std and libc only, the bench's baseline) and says the same.
    let others = ["frond", "frond-bench", "frond-bench-peer", "frond-relay"];
    for name in BINARIES.iter().map(|(n, _)| *n).chain(others) {
        let out = run(name, &["--no-such-flag"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name} --no-such-flag: {err}");
        assert!(err.starts_with(&format!("{name}: error:")), "{name}: {err}");
    }
}
