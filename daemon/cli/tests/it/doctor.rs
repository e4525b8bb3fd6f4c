//! `frond doctor` (issue 18): every check is reported with a verdict, problems with a fix, and the
//! exit status says whether something needs fixing. With no daemon at the socket directory the
//! daemon check is a problem whose fix says how to start one.

use crate::common;

use common::frond;

#[test]
fn without_a_daemon_the_doctor_names_the_problem_and_its_fix() {
    let dir = tempfile::tempdir().unwrap();
    let out = frond(dir.path())
        .env("FROND_SOCKET_DIR", dir.path().join("run"))
        .args(["doctor", "--json"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["healthy"], false);
    let checks = v["checks"].as_array().unwrap();
    let names: Vec<&str> = checks.iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        ["daemon", "socket-dir", "glove", "udev", "group", "fuse", "realtime", "service", "exporters"]
    );
    for c in checks {
        let verdict = c["verdict"].as_str().unwrap();
        assert!(["ok", "warn", "problem"].contains(&verdict), "{c}");
        assert!(!c["found"].as_str().unwrap().is_empty(), "{c}");
        if verdict == "problem" {
            assert!(c["fix"].as_str().is_some_and(|f| !f.is_empty()), "a problem without a fix: {c}");
        }
    }
    let daemon = &checks[0];
    assert_eq!(daemon["verdict"], "problem");
    assert!(daemon["fix"].as_str().unwrap().contains("frondd"), "{daemon}");
    // The text form says the same, one line per check.
    let out =
        frond(dir.path()).env("FROND_SOCKET_DIR", dir.path().join("run")).arg("doctor").output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("PROBLEM daemon") && text.contains("fix:"), "{text}");
    assert_eq!(out.status.code(), Some(1));
}
