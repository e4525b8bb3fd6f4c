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
