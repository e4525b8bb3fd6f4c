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
