//! A larger stage through a Zenoh router (issue 20): the documented router configuration
//! (`exporters/zenoh/config/router.json5`) runs, unchanged, in Zenoh's own runtime (eclipse-zenoh,
//! the runtime `zenohd` wraps) on a host of its own; a performer's bridge and a workstation's tap
//! are its clients (`client.json5`), so every pose goes through the router. The workstation sees
//! the frames the daemon's host sees. When the router's host drops off the network, the stream
//! stops and the tap reports the disconnect once the configured lease (3 s) runs out; when it
//! comes back, the stream resumes. The same when the router process stops and a new one starts on
//! the same address. No frond process is restarted.

use std::path::PathBuf;
use std::process::Stdio;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use frond_e2e::netns::Host;
use frond_e2e::{Daemon, Proc, bin, start_zenoh_bridge, wait_for};

use crate::stage_net::{PORT, Tapped, assert_same_lines, collect, lan, lines, tap};

fn config(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../exporters/zenoh/config").join(name)
}

/// Starts the router on `host` from the documented file and waits until it routes.
fn start_router(py: &std::path::Path, host: &Host) -> Proc {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../exporters/zenoh/tests/zenoh_router.py");
    let mut cmd = host.command(py);
    // Its standard input stays open (held by the child handle) for as long as it is to route.
    cmd.arg(script).arg(config("router.json5")).stdin(Stdio::piped());
    let (proc, out) = collect(cmd, "zenoh router");
    assert!(
        wait_for(Duration::from_secs(20), || out
            .lock()
            .unwrap()
            .lines
            .iter()
            .any(|(_, l)| l.starts_with("routing"))),
        "the router did not start: {:?}",
        out.lock().unwrap().stderr
    );
    proc
}

#[test]
fn a_stage_through_the_documented_router_survives_the_router_going_and_coming_back() {
    let Some(py) = crate::python::python_with("zenoh") else {
        return crate::python::skip(
            "no eclipse-zenoh in tests/python/.venv (run exporters/zenoh/tests/install-python.sh)",
        );
    };
    let Some(lan) = lan(3) else { return };
    let (router_host, performer, ws) = (&lan.hosts[0], &lan.hosts[1], &lan.hosts[2]);
    let router = router_host.endpoint(PORT);
    let client = config("client.json5");
    let mut router_proc = start_router(&py, router_host);

    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start_on(performer, dir.path(), &["--source", "in-process"]);
    let client_file = client.to_str().unwrap();
    let network = ["--connect", router.as_str(), "--zenoh-config", client_file];
    let mut bridge =
        start_zenoh_bridge(performer.command(bin("frond-zenoh")), &daemon, "stage1", "glove-a", &network);
    let from = format!("zenoh:frond/stage1/glove-a?connect={router}&config={}", client.display());
    let (_local_tap, local) = tap(None, &["--socket-dir", daemon.socket_dir.to_str().unwrap()], &[]);
    let (mut remote_tap, remote) = tap(Some(ws), &[], &["--from", &from]);

    assert!(
        wait_for(Duration::from_secs(30), || lines(&remote) > 1000),
        "the workstation got {} poses through the router in 30 s; stderr {:?}",
        lines(&remote),
        remote.lock().unwrap().stderr
    );
    assert_same_lines(&remote, &local, "through the router");

    // The router's host drops off the network without a word: the clients cannot reach each
    // other without it, so the stream stops, and the tap reports the disconnect once the lease
    // client.json5 and router.json5 set (3 s) runs out, well before Zenoh's default 10 s.
    let disconnects = |t: &Arc<Mutex<Tapped>>| {
        t.lock().unwrap().stderr.iter().filter(|l| l.contains("closed the stream")).count()
    };
    let reconnects = |t: &Arc<Mutex<Tapped>>| {
        t.lock().unwrap().stderr.iter().filter(|l| l.contains("reconnected")).count()
    };
    let cut = Instant::now();
    router_host.set_link(false);
    assert!(
        wait_for(Duration::from_secs(8), || disconnects(&remote) == 1),
        "the tap did not report the disconnect within 8 s of the router's host vanishing: {:?}",
        remote.lock().unwrap().stderr
    );
    let lease_noticed = cut.elapsed();
    assert!(
        lease_noticed >= Duration::from_millis(1500),
        "disconnect after {lease_noticed:?}: before any lease ran out?"
    );
    let during =
        remote.lock().unwrap().lines.iter().filter(|(t, _)| *t > cut + Duration::from_millis(500)).count();
    assert_eq!(
        during, 0,
        "{during} poses arrived with the router cut off: the clients did not go through it"
    );
    let restored = Instant::now();
    router_host.set_link(true);
    let resumed_since =
        |at: Instant, n: usize| remote.lock().unwrap().lines.iter().filter(|(t, _)| *t > at).count() > n;
    assert!(
        wait_for(Duration::from_secs(40), || resumed_since(restored, 1000)),
        "the stream did not resume within 40 s of the router's link coming back; stderr {:?}",
        remote.lock().unwrap().stderr
    );
    assert_eq!(reconnects(&remote), 1, "{:?}", remote.lock().unwrap().stderr);

    // The router process goes (its links close at once), and a new one starts on the same address.
    router_proc.child.kill().unwrap();
    router_proc.child.wait().unwrap();
    let gone = Instant::now();
    assert!(
        wait_for(Duration::from_secs(8), || disconnects(&remote) == 2),
        "the tap did not report the disconnect within 8 s of the router stopping: {:?}",
        remote.lock().unwrap().stderr
    );
    let stop_noticed = gone.elapsed();
    // A router comes back on the same address: the bridge and the tap reconnect by themselves.
    let back = Instant::now();
    let _router_again = start_router(&py, router_host);
    assert!(
        wait_for(Duration::from_secs(40), || resumed_since(back, 1000)),
        "the stream did not resume within 40 s of the router coming back; stderr {:?}",
        remote.lock().unwrap().stderr
    );
    assert_eq!(reconnects(&remote), 2, "{:?}", remote.lock().unwrap().stderr);
    assert_same_lines(&remote, &local, "through the router, after it came back");
    assert!(bridge.child.try_wait().unwrap().is_none(), "the bridge exited");
    assert!(remote_tap.child.try_wait().unwrap().is_none(), "the tap exited");
    eprintln!(
        "router cut off: disconnect reported after {lease_noticed:?}; router stopped: after {stop_noticed:?}; \
         resumed both times"
    );
}
