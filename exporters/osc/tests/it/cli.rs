//! `frond-osc`'s command line: arguments that parse but are wrong are all reported at once,
//! each once, with exit status 2 like clap's own usage errors (issue 18, CLI habits).

use std::process::Command;

fn frond_osc(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_frond-osc")).args(args).output().expect("run frond-osc")
}

#[test]
fn invalid_arguments_exit_2_naming_each_problem_once() {
    let out = frond_osc(&[
        "--vmc-bones",
        "a,b",
        "--rig",
        "/nonexistent/rig.toml",
        "--rate",
        "0",
        "--timetag",
        "later",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.starts_with("frond-osc: error: invalid arguments:"), "{err}");
    for problem in [
        "--vmc-bones: expected `humanoid`, `joints` or 4",
        "cannot read rig /nonexistent/rig.toml",
        "--rate 0: must be `every` or",
        "--timetag later: expected `immediately` or `publish`",
    ] {
        assert_eq!(err.matches(problem).count(), 1, "{problem:?} in:\n{err}");
    }
    assert_eq!(err.matches("No such file").count(), 1, "the OS error once:\n{err}");

    let out = frond_osc(&["--log-level", "no=such=filter"]);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    let out = frond_osc(&["--no-such-flag"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn from_is_not_refused_because_the_environment_names_a_socket_directory() {
    // The README has operators export FROND_SOCKET_DIR; --from must still be usable. The bad
    // --rate keeps the run short: it is reported instead of clap's conflict.
    let out = Command::new(env!("CARGO_BIN_EXE_frond-osc"))
        .env("FROND_SOCKET_DIR", "/nonexistent/frond")
        .args(["--from", "zenoh:frond/stage1/glove-a", "--rate", "0"])
        .output()
        .expect("run frond-osc");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(!err.contains("cannot be used with"), "{err}");
    assert!(err.contains("--rate 0: must be `every` or"), "{err}");
    // An explicit --socket-dir with --from is still a contradiction.
    let out = frond_osc(&["--from", "zenoh:frond/stage1/glove-a", "--socket-dir", "/x"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot be used with"));
}
