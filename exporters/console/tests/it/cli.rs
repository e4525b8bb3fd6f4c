//! `frond-console`'s arguments that name files are checked before it serves anything: a rig it
//! cannot show and a token file others may read are refused at start, as usage errors (exit 2,
//! as `frond-osc --rig` and `frond-zenoh --control` refuse theirs), naming the file and the
//! problem.

use std::io::{BufRead, BufReader};
use std::os::unix::fs::PermissionsExt;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// `frond-console` on a free loopback port with `args`, beside no daemon.
fn console(dir: &tempfile::TempDir, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_frond-console"))
        .args(["--listen", "127.0.0.1:0", "--no-warp", "--socket-dir"])
        .arg(dir.path().join("sockets"))
        .arg("--takes-dir")
        .arg(dir.path().join("takes"))
        .args(args)
        .env("NO_COLOR", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start frond-console")
}

/// The exit status and stderr of a console that must refuse to start. One that is still
/// serving after a minute is killed and the test fails.
fn refused(dir: &tempfile::TempDir, args: &[&str]) -> (Option<i32>, String) {
    let mut child = console(dir, args);
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("frond-console {args:?} started instead of refusing");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    (status.code(), stderr)
}

#[test]
fn a_rig_that_cannot_be_shown_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "name = [").unwrap();
    let bad = bad.to_str().unwrap();
    // The reasons, each beyond the `--rig RIG: ` that names the option and the rig (so that
    // the check cannot pass on the rig's name alone): a device is not a regular file; a name
    // that is neither an embedded rig nor a file; a file whose TOML does not parse (the
    // unclosed array on its line 1).
    for (rig, problems) in [
        ("/dev/zero", &["it is a device, not a regular file"][..]),
        ("no-such-rig", &["not found: not an embedded rig (grass, flower, shrub) and no such file"][..]),
        (bad, &[&format!("{bad}: rig: "), "line 1"][..]),
    ] {
        let (code, stderr) = refused(&dir, &["--rig", rig]);
        assert_eq!(code, Some(2), "--rig {rig}: {stderr}");
        let prefix = format!("--rig {rig}: ");
        let at = stderr.find(&prefix).unwrap_or_else(|| panic!("names the option and the rig: {stderr}"));
        let reason = &stderr[at + prefix.len()..];
        for problem in problems {
            assert!(reason.contains(problem), "--rig {rig}: {problem:?} not in {reason:?}");
        }
    }
}

#[test]
fn a_token_file_others_may_read_is_refused_with_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("token");
    std::fs::write(&path, "tok-0123456789abcdef\n").unwrap();
    let file = path.to_str().unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
    let (code, stderr) = refused(&dir, &["--token-file", file]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains(&format!("--token-file {file}: mode 644")), "{stderr}");
    assert!(stderr.contains(&format!("chmod 600 {file}")), "{stderr}");
    // Both problems at once.
    let (code, stderr) = refused(&dir, &["--token-file", file, "--rig", "/dev/zero"]);
    assert_eq!(code, Some(2));
    assert!(stderr.contains("--token-file") && stderr.contains("--rig"), "{stderr}");

    // Its owner's alone, it is taken: the console starts and says where it listens.
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
    let mut child = console(&dir, &["--token-file", file, "--rig", "grass"]);
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let _ = child.kill();
    let _ = child.wait();
    assert!(line.starts_with("frond-console: http://127.0.0.1:"), "{line:?}");
}

#[test]
fn the_log_level_is_checked_as_frondd_checks_it() {
    let dir = tempfile::tempdir().unwrap();
    // A level that does not parse is a usage error naming the option and the value.
    let (code, stderr) = refused(&dir, &["--log-level", "frond=loud"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.starts_with("frond-console: error: --log-level \"frond=loud\": "), "{stderr}");
    // A level and a filter are taken: the console starts and says where it listens.
    for level in ["debug", "warn,frond_sdk=trace"] {
        let mut child = console(&dir, &["--log-level", level]);
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let _ = child.kill();
        let _ = child.wait();
        assert!(line.starts_with("frond-console: http://127.0.0.1:"), "--log-level {level}: {line:?}");
    }
}

#[test]
fn a_full_stdout_ends_the_console_with_an_error_not_a_panic() {
    // The URL line to a full disk (/dev/full): an error like any other, exit 1; `println!`
    // panicked (exit 101).
    let dir = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_frond-console"))
        .args(["--listen", "127.0.0.1:0", "--no-warp", "--socket-dir"])
        .arg(dir.path().join("sockets"))
        .arg("--takes-dir")
        .arg(dir.path().join("takes"))
        .env("NO_COLOR", "1")
        .stdout(std::fs::File::create("/dev/full").unwrap())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot write to standard output") && !stderr.contains("panicked"), "{stderr}");
}
