//! `ZENOH_RUNTIME` checked against Zenoh itself: for each value, this test runs a child (this
//! test binary again, its ignored test `open_a_raw_zenoh_session`) that opens a Zenoh session
//! directly with the value in its environment, and [`check_value`]'s verdict must be Zenoh's:
//! accepted values open, refused ones make Zenoh panic.

#![cfg(feature = "zenoh")]

use std::process::Command;

use frond_sdk::zenoh_runtime_env::{VAR, check_value};
use zenoh::Wait;

#[test]
#[ignore = "run by zenoh_itself_agrees_with_the_check, in a child with ZENOH_RUNTIME set"]
fn open_a_raw_zenoh_session() {
    let mut config = zenoh::Config::default();
    config.insert_json5("scouting/multicast/enabled", "false").unwrap();
    config.insert_json5("listen/endpoints", "[]").unwrap();
    let session = zenoh::open(config).wait().expect("open");
    session.close().wait().expect("close");
}

#[test]
fn zenoh_itself_agrees_with_the_check() {
    let values = [
        "()",
        "(\n  rx: (handover: app),\n  acc: (handover: app),\n  app: (worker_threads: 2),\n  tx: (max_blocking_threads: 1)\n)",
        "(rx: (worker_threads: 1))",
        "AbstractRuntimeParam(net: (handover: tx))",
        "(rx: RuntimeParamHelper(worker_threads: 1))",
        "",
        "garbage",
        "(rx: (workers: 1))",
        "(gpu: ())",
        "(rx: (handover: disk))",
        "(rx: (worker_threads: -1))",
        "(rx: Some((worker_threads: 1)))",
        "(rx: (worker_threads: Some(1)))",
        "RuntimeParam(rx: ())",
    ];
    let me = std::env::current_exe().unwrap();
    for value in values {
        let out = Command::new(&me)
            .args(["--ignored", "--exact", "open_a_raw_zenoh_session", "--test-threads", "1"])
            .env(VAR, value)
            .env("RUST_BACKTRACE", "0")
            .output()
            .unwrap();
        let ours = check_value(value);
        assert_eq!(
            out.status.success(),
            ours.is_ok(),
            "ZENOH_RUNTIME={value:?}: we say {ours:?}, Zenoh {}:\n{}",
            out.status,
            String::from_utf8_lossy(&out.stdout)
        );
    }
}
