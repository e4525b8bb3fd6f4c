//! Remote control across hosts: a daemon and its bridge with an allow-list (`--control FILE`)
//! on one namespace, operators on another. The right key records, marks and asks status; an
//! independent Python client (signing from the documented envelope) changes the filter and has
//! its replayed query refused; a wrong key, an unknown principal and a principal asking for
//! more than it may are refused, counted, and each logged once however often it retries. A
//! bridge without `--control` answers no control request at all.

use std::process::{Command, Output};
use std::time::Duration;

use frond_e2e::{Daemon, bin, wait_for};

use crate::stage_net::{PORT, collect, lan};

const DIRECTOR_KEY: &str = "d1d2d3d4d5d6d7d8d9dadbdcdddedfe0e1e2e3e4e5e6e7e8e9eaebecedeeeff0f1";
const VIEWER_KEY: &str = "0f0e0d0c0b0a09080706050403020100f0e0d0c0b0a090807060504030201000";
const WRONG_KEY: &str = "d1d2d3d4d5d6d7d8d9dadbdcdddedfe0e1e2e3e4e5e6e7e8e9eaebecedeeeff0f2";

/// Writes `text` to `dir/name`, readable by its owner only.
fn secret(dir: &std::path::Path, name: &str, text: &str) -> String {
    use std::os::unix::fs::PermissionsExt;
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
    path.to_str().unwrap().to_owned()
}

fn json(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!("{e}: {}\n{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
    })
}

fn ok(out: Output, what: &str) -> Output {
    assert!(out.status.success(), "{what}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

/// The refusal a failed `frond` printed, asserting it failed with exit status 1.
fn refused(out: Output, what: &str) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{what} should be refused: {stderr}");
    stderr
}

#[test]
fn remote_control_answers_the_allow_list_and_refuses_counts_and_logs_the_rest_once() {
    let Some(lan) = lan(2) else { return };
    let (stage_host, operator) = (&lan.hosts[0], &lan.hosts[1]);
    let dir = tempfile::tempdir().unwrap();
    let keys = tempfile::tempdir().unwrap();
    let daemon = Daemon::start_on(stage_host, dir.path(), &["--source", "in-process"]);
    let policy = secret(
        dir.path(),
        "control.toml",
        &format!(
            "[[principal]]\nname = \"director\"\nkey = \"{DIRECTOR_KEY}\"\n\n\
             [[principal]]\nname = \"viewer\"\nkey = \"{VIEWER_KEY}\"\nallow = [\"read\"]\n"
        ),
    );
    let mut cmd = stage_host.command(bin("frond-zenoh"));
    cmd.args(["--stage", "stage1", "--source", "glove-a", "--listen", &stage_host.endpoint(PORT)])
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .args(["--log-level", "warn", "--control", &policy]);
    let (mut bridge, bridge_out) = collect(cmd, "frond-zenoh --control");
    // The same daemon once more as another source, by a bridge without --control.
    let plain_port = PORT + 1;
    let mut cmd = stage_host.command(bin("frond-zenoh"));
    cmd.args(["--stage", "stage1", "--source", "glove-plain", "--listen", &stage_host.endpoint(plain_port)])
        .arg("--socket-dir")
        .arg(&daemon.socket_dir)
        .args(["--log-level", "warn"]);
    let (_plain, _) = collect(cmd, "frond-zenoh");

    let director = secret(keys.path(), "director.key", &format!("{DIRECTOR_KEY}\n"));
    let viewer = secret(keys.path(), "viewer.key", VIEWER_KEY);
    let wrong = secret(keys.path(), "wrong.key", WRONG_KEY);
    let address = format!("zenoh:frond/stage1/glove-a?connect={}", stage_host.endpoint(PORT));
    let remote = |principal: &str, key: &str, args: &[&str]| -> Output {
        operator
            .command(bin("frond"))
            .args(["--remote", &address, "--as", principal, "--key-file", key])
            .args(args)
            .output()
            .unwrap()
    };
    let local_status = || -> serde_json::Value {
        json(&ok(
            Command::new(bin("frond"))
                .arg("--socket-dir")
                .arg(&daemon.socket_dir)
                .args(["status", "--json"])
                .output()
                .unwrap(),
            "local status",
        ))
    };

    // The director records a take with a marker from the other host.
    ok(remote("director", &director, &["record", "start", "remote1"]), "remote record start");
    ok(remote("director", &director, &["mark", "cue 1"]), "remote mark");
    let status = json(&ok(remote("director", &director, &["status", "--json"]), "remote status"));
    assert_eq!(status["recording"]["name"], "remote1", "{status}");
    // ... and the daemon's own socket agrees.
    assert_eq!(local_status()["recording"]["name"], "remote1");
    ok(remote("director", &director, &["record", "stop"]), "remote record stop");
    assert!(local_status()["recording"].is_null() || local_status()["recording"]["active"] == false);
    let take = std::fs::read_dir(&daemon.takes_dir)
        .unwrap()
        .filter_map(Result::ok)
        .find(|e| e.file_name().to_string_lossy().starts_with("remote1"))
        .unwrap_or_else(|| panic!("no take remote1 in {}", daemon.takes_dir.display()));
    assert!(take.metadata().unwrap().len() > 0, "the remote take is empty");

    // An independent client, written from the documented envelope, sets the filter; its
    // replayed query is refused.
    match crate::python::python_with("zenoh, msgpack") {
        None => crate::python::skip(
            "no eclipse-zenoh in tests/python/.venv (run exporters/zenoh/tests/install-python.sh)",
        ),
        Some(py) => {
            let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../exporters/zenoh/tests/control_client.py");
            let out = ok(
                operator
                    .command(&py)
                    .arg(&script)
                    .args(["--connect", &stage_host.endpoint(PORT), "--key", "frond/stage1/glove-a"])
                    .args(["--as", "director", "--key-hex", DIRECTOR_KEY, "--replay"])
                    .args(["--request", r#"{"SetFilter": {"spec": "lowpass:cutoff_hz=5"}}"#])
                    .output()
                    .unwrap(),
                "control_client.py",
            );
            let replies: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
                .lines()
                .map(|l| serde_json::from_str(l).unwrap())
                .collect();
            assert_eq!(replies.len(), 2, "{replies:?}");
            assert!(replies[0] == "Ok" || replies[0] == serde_json::json!({"Ok": null}), "{replies:?}");
            assert_eq!(replies[1]["Error"]["kind"], "PermissionDenied", "{replies:?}");
            assert!(replies[1]["Error"]["message"].as_str().unwrap().contains("replayed"), "{replies:?}");
            let filter = local_status()["filter"].as_str().unwrap().to_owned();
            assert!(filter.contains("lowpass") && filter.contains('5'), "the filter is {filter}");
        }
    }

    // Refusals: a wrong key (three times), an unknown principal, a viewer asking to record.
    for _ in 0..3 {
        let e = refused(remote("director", &wrong, &["status"]), "a wrong key");
        assert!(e.contains("not authenticated"), "{e}");
    }
    let e = refused(remote("mallory", &director, &["record", "start", "evil"]), "an unknown principal");
    assert!(e.contains("not authenticated"), "{e}");
    ok(remote("viewer", &viewer, &["status"]), "the viewer reads");
    let e = refused(remote("viewer", &viewer, &["record", "start", "sneaky"]), "a viewer recording");
    assert!(e.contains("may not send record-start"), "{e}");
    assert!(local_status()["recording"].is_null() || local_status()["recording"]["active"] == false);

    // A bridge without --control takes no control request.
    let plain = format!("zenoh:frond/stage1/glove-plain?connect={}", stage_host.endpoint(plain_port));
    let out = operator
        .command(bin("frond"))
        .args(["--remote", &plain, "--as", "director", "--key-file", &director, "status"])
        .output()
        .unwrap();
    let e = refused(out, "a bridge without --control");
    assert!(e.contains("does not take remote control"), "{e}");

    // Counted, and each kind logged once.
    assert!(bridge.terminate(Duration::from_secs(5)).is_some(), "the bridge did not stop");
    wait_for(Duration::from_secs(5), || {
        bridge_out.lock().unwrap().stderr.iter().any(|l| l.starts_with("frond-zenoh stats:"))
    });
    let stderr = bridge_out.lock().unwrap().stderr.clone();
    let stats = stderr.iter().rev().find(|l| l.starts_with("frond-zenoh stats:")).unwrap();
    let python_ran = crate::python::python_with("zenoh, msgpack").is_some();
    let (answered, refusals) = if python_ran { (6, 6) } else { (5, 5) };
    assert!(stats.contains(&format!("control_answered={answered} ")), "{stats}");
    assert!(stats.contains(&format!("control_refused={refusals} ")), "{stats}");
    let logged: Vec<&String> =
        stderr.iter().filter(|l| l.contains("remote control request refused")).collect();
    let expected = if python_ran { 4 } else { 3 };
    assert_eq!(logged.len(), expected, "one line per principal and reason:\n{logged:#?}");
    for (principal, reason) in
        [("director", "BadSignature"), ("mallory", "UnknownPrincipal"), ("viewer", "NotAllowed")]
    {
        assert!(
            logged.iter().any(|l| l.contains(&format!("principal={principal}")) && l.contains(reason)),
            "no log of {principal} {reason}:\n{logged:#?}"
        );
    }
}
