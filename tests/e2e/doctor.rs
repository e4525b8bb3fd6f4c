//! `frond doctor` beside a running daemon (issue 18): the daemon check finds it and names its
//! source; the socket directory is the daemon's.

use frond_e2e::Daemon;

#[test]
fn the_doctor_finds_the_running_daemon() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let out = daemon.frond().args(["doctor", "--json"]).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let check =
        |name: &str| v["checks"].as_array().unwrap().iter().find(|c| c["name"] == name).unwrap().clone();
    let d = check("daemon");
    assert_eq!(d["verdict"], "ok", "{d}");
    assert!(d["found"].as_str().unwrap().contains("in-process"), "{d}");
    assert_eq!(check("socket-dir")["verdict"], "ok", "{}", check("socket-dir"));
    // The rest depends on the machine; the exit status follows the verdicts.
    let healthy = v["healthy"].as_bool().unwrap();
    assert_eq!(out.status.success(), healthy);
}

/// "Exporters reachable": the doctor subscribes as the user would run an exporter, and names the
/// subscribers connected now by their process (the daemon reports each one's pid from the
/// socket). A user who may not open the pose socket is told so, with the fix.
#[test]
fn the_doctor_names_the_connected_exporters_and_whether_they_can_reach_the_daemon() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let mut tap =
        daemon.frond().args(["tap", "--jsonl"]).stdout(std::process::Stdio::null()).spawn().unwrap();
    assert!(
        frond_e2e::wait_for(std::time::Duration::from_secs(10), || !daemon.status().subscribers.is_empty()),
        "tap never subscribed"
    );
    let doctor = |cmd: &mut std::process::Command| -> serde_json::Value {
        let out = cmd.args(["doctor", "--json"]).output().unwrap();
        serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&out.stdout)))
    };
    let reach = |v: &serde_json::Value| {
        v["checks"].as_array().unwrap().iter().find(|c| c["name"] == "reach").cloned()
    };
    let v = doctor(&mut daemon.frond());
    let r = reach(&v).unwrap_or_else(|| panic!("no reach check: {v}"));
    assert_eq!(r["verdict"], "ok", "{r}");
    let found = r["found"].as_str().unwrap();
    assert!(found.contains(&format!("frond (pid {})", tap.id())), "the tap by name and pid: {found}");
    let _ = tap.kill();
    let _ = tap.wait();

    // A daemon that takes one subscriber, which the tap is: an exporter could not subscribe now.
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("frondd.toml");
    std::fs::write(&config, "[publisher]\nmax_subscribers = 1\n").unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--config", config.to_str().unwrap()]);
    let mut tap =
        daemon.frond().args(["tap", "--jsonl"]).stdout(std::process::Stdio::null()).spawn().unwrap();
    assert!(frond_e2e::wait_for(std::time::Duration::from_secs(10), || !daemon
        .status()
        .subscribers
        .is_empty()));
    let out = daemon.frond().args(["doctor", "--json"]).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let r = reach(&v).unwrap_or_else(|| panic!("no reach check: {v}"));
    assert_eq!(r["verdict"], "problem", "{r}");
    assert!(r["found"].as_str().unwrap().contains("subscriber limit"), "{r}");
    assert!(r["fix"].as_str().unwrap().contains("max_subscribers"), "{r}");
    assert!(!out.status.success(), "a problem: exit 1");
    let _ = tap.kill();
    let _ = tap.wait();
}
