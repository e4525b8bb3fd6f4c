//! Issue 14, point 9: files given to the daemon or a command are opened only if they are regular
//! and small. A FIFO (which would block `open()` forever), a device (`/dev/zero`, endless) or a
//! directory is refused at once with an error naming the path and what it is, by the real
//! binaries.

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use frond_e2e::bin;

/// Runs `cmd` for at most 10 s: a refusal must come at once, never a hang.
fn run_bounded(mut cmd: Command) -> Output {
    let mut child = cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("{cmd:?} still running after 10 s: it blocked on the file");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn mkfifo(path: &std::path::Path) {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo only creates a node there.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", path.display());
}

#[test]
fn fifos_devices_and_directories_are_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("hand.fifo");
    mkfifo(&fifo);
    let fifo = fifo.to_str().unwrap().to_string();
    let run_dir = dir.path().join("run");
    let frondd = |args: &[&str]| {
        let mut c = Command::new(bin("frondd"));
        c.arg("--socket-dir").arg(&run_dir).arg("--takes-dir").arg(dir.path().join("takes")).args(args);
        run_bounded(c)
    };
    let dir_path = dir.path().to_str().unwrap().to_string();
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (vec!["--replay", &fifo], &fifo, "a FIFO, not a regular file"),
        (vec!["--rig", &fifo], &fifo, "a FIFO, not a regular file"),
        (
            vec!["--source", "in-process", "--calibration", "/dev/zero"],
            "/dev/zero",
            "a device, not a regular file",
        ),
        (vec!["--source", "hid", "--profile", "/dev/zero"], "/dev/zero", "a device, not a regular file"),
        (vec!["--config", &fifo], &fifo, "a FIFO, not a regular file"),
        (vec!["--source", "in-process", "--config", &dir_path], &dir_path, "a directory, not a regular file"),
        // Issue 14, point 13: a node that is no hidraw node is refused, not waited for.
        (vec!["--device", "/dev/null"], "/dev/null", "not a hidraw node"),
        (vec!["--device", &dir_path], &dir_path, "not a hidraw node (it is a directory)"),
    ];
    for (args, path, what) in cases {
        let out = frondd(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "frondd {args:?} started");
        assert!(err.contains(path) && err.contains(what), "frondd {args:?}: {err}");
    }

    // The operator's command reads its files the same way, before it talks to any daemon.
    let frond = |args: &[&str]| {
        let mut c = Command::new(bin("frond"));
        c.env("FROND_SOCKET_DIR", &run_dir).args(args);
        run_bounded(c)
    };
    for (args, path, what) in [
        (vec!["rig", "set", "/dev/zero"], "/dev/zero", "a device"),
        (vec!["rig", "set", fifo.as_str()], fifo.as_str(), "a FIFO"),
        (vec!["field", "start", "--take", "t", "--field", fifo.as_str()], fifo.as_str(), "a FIFO"),
    ] {
        let out = frond(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "frond {args:?} succeeded");
        assert!(err.contains(path) && err.contains(what), "frond {args:?}: {err}");
    }
}

/// Issue 42, section 5: a calibration whose id carries a line break and a fake status line is
/// refused where it enters, by the daemon's own check (a file at start-up, or a control request
/// sent past `frond`'s check), so `frond status` never prints it.
#[test]
fn a_calibration_id_that_would_draw_a_status_line_is_refused_where_it_enters() {
    let dir = tempfile::tempdir().unwrap();
    let hostile = "id = \"bob\\nPROBLEM      none\"\nneutral_wrist_deg = [0, 0, 0]\n\
                   neutral_thumb_deg = [0, 0, 0]\nthumb_range_deg = [60, 60, 60]\n";
    let file = dir.path().join("bob.toml");
    std::fs::write(&file, hostile).unwrap();
    let mut c = Command::new(bin("frondd"));
    c.arg("--socket-dir").arg(dir.path().join("run0")).arg("--takes-dir").arg(dir.path().join("takes"));
    c.args(["--source", "in-process", "--calibration"]).arg(&file);
    let out = run_bounded(c);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "frondd started with {hostile:?}");
    assert!(err.contains("id: contains the control character '\\n'; a name must be printable"), "{err}");
    // A running daemon refuses the same calibration sent as a raw request.
    let daemon = frond_e2e::Daemon::start(dir.path(), &["--source", "in-process", "--rig", "grass"]);
    let mut control = frond_sdk::control::ControlClient::connect(&daemon.socket_dir).unwrap();
    let reply = control
        .request(&frond_protocol::ControlRequest::SetCalibration { id: "bob".into(), toml: hostile.into() });
    let said = format!("{reply:?}");
    assert!(said.contains("Invalid") && said.contains("a name must be printable"), "{said}");
    let text = daemon.frond_ok(&["status"]);
    assert!(!text.lines().any(|l| l.starts_with("PROBLEM")), "{text}");
    assert!(text.contains("calibration  none\n"), "{text}");
}
