//! The realtime rule, traced: with a take recording, a field playing, a looped take, guided
//! motion and 4 subscribers, the daemon's loop thread (`frond-rt`) makes no `futex` call: it
//! never takes a contended lock and never wakes a parked thread. `strace` (installed by
//! `scripts/test`) is attached to the running thread for a few seconds; the recorder thread is
//! traced beside it as the control that the trace sees futex calls where they happen (it parks
//! between polls).

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use frond_e2e::{Daemon, fuse_available};
use frond_motion::field::FieldParams;
use frond_sdk::Subscriber;

/// The id of `pid`'s thread named `name`.
fn thread_id(pid: u32, name: &str) -> u32 {
    for entry in std::fs::read_dir(format!("/proc/{pid}/task")).unwrap() {
        let entry = entry.unwrap();
        let comm = std::fs::read_to_string(entry.path().join("comm")).unwrap_or_default();
        if comm.trim() == name {
            return entry.file_name().to_string_lossy().parse().unwrap();
        }
    }
    panic!("frondd has no thread named {name}");
}

/// System call names in one `strace -o` file (one call a line: `name(args) = ret`).
fn calls(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines()
        .filter_map(|l| {
            let l = l.trim_start_matches("<... ");
            let end = l.find(['(', ' '])?;
            Some(l[..end].to_string())
        })
        .filter(|c| !c.is_empty() && c.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '_'))
        .collect()
}

#[test]
fn the_loop_thread_makes_no_futex_call_with_every_stage_running() {
    let dir = tempfile::tempdir().unwrap();
    let source = if fuse_available() { "virtual" } else { "in-process" };
    let daemon = Daemon::start(dir.path(), &["--source", source, "--rig", "flower", "--rate", "1000"]);

    // A short global take to loop and to make a field of.
    daemon.frond_ok(&["record", "start", "global"]);
    std::thread::sleep(Duration::from_millis(1500));
    daemon.frond_ok(&["record", "stop"]);
    daemon.start_field(
        "global",
        &FieldParams {
            rows: 4,
            cols: 4,
            cell_m: 0.5,
            speed_m_s: 1.0,
            direction_deg: 0.0,
            density: 1.0,
            seed: 1,
        },
        45,
        16,
    );
    daemon.frond_ok(&["guided", "sigma=0.1,0.2,0.3"]);
    daemon.frond_ok(&["record", "layer", "leafy", "--layer", "leaf", "--over", "global"]);
    let status = daemon.status();
    let kinds: Vec<&str> = status.stages.iter().map(|s| s.kind.as_str()).collect();
    for kind in ["field", "guided", "layer", "playback"] {
        assert!(kinds.contains(&kind), "{kind} is not running: {kinds:?}");
    }

    // Four subscribers reading everything.
    let readers: Vec<_> = (0..4)
        .map(|_| {
            let mut sub = Subscriber::options().reconnect(false).connect(&daemon.socket_dir).unwrap();
            std::thread::spawn(move || {
                let mut n = 0u64;
                for pose in sub.by_ref() {
                    if pose.is_err() {
                        break;
                    }
                    n += 1;
                }
                n
            })
        })
        .collect();
    assert!(frond_e2e::wait_for(Duration::from_secs(5), || daemon.status().subscribers.len() == 4));

    let pid = daemon.proc.child.id();
    let (rt, recorder) = (thread_id(pid, "frond-rt"), thread_id(pid, "frond-recorder"));
    // One strace per thread (`-f` would attach every thread of the process).
    let trace = |tid: u32| dir.path().join(format!("trace.{tid}"));
    let mut tracers: Vec<_> = [rt, recorder]
        .iter()
        .map(|&tid| {
            Command::new("strace")
                .args(["-qq", "-o"])
                .arg(trace(tid))
                .args(["-p", &tid.to_string()])
                .stdout(Stdio::null())
                .stderr(Stdio::inherit())
                .spawn()
                .expect("strace is missing: scripts/test installs it (apt-get install strace)")
        })
        .collect();
    std::thread::sleep(Duration::from_secs(3));
    for t in &mut tracers {
        // SAFETY: kill(2) on our own child; SIGINT makes strace detach and flush its file.
        unsafe { libc::kill(t.id() as i32, libc::SIGINT) };
        let exit = t.wait().unwrap();
        assert!(exit.success() || exit.code() == Some(130) || exit.code().is_none(), "strace: {exit}");
    }

    let rt_calls = calls(&trace(rt));
    let recorder_calls = calls(&trace(recorder));
    fn count(calls: &[String]) -> std::collections::BTreeMap<&str, usize> {
        let mut counts = std::collections::BTreeMap::new();
        for c in calls {
            *counts.entry(c.as_str()).or_default() += 1;
        }
        counts
    }
    // The trace saw the loop at work: it sends to subscribers and reads the device. (It may
    // hardly wait at all: under ptrace every call is slow and the loop runs behind.)
    let sends = rt_calls.iter().filter(|c| c.starts_with("send")).count();
    let reads = rt_calls.iter().filter(|c| ["read", "recvfrom", "ioctl"].contains(&c.as_str())).count();
    assert!(sends > 1000 && reads > 100, "the trace of frond-rt saw {:?}", count(&rt_calls));
    // The control: the recorder parks between polls, and the trace shows it.
    assert!(
        recorder_calls.iter().any(|c| c == "futex"),
        "no futex call in the recorder's trace: {recorder_calls:?}"
    );
    let futexes = rt_calls.iter().filter(|c| *c == "futex").count();
    assert_eq!(futexes, 0, "frond-rt made {futexes} futex calls in 3 s: {:?}", {
        let mut seen: Vec<&String> = rt_calls.iter().collect();
        seen.dedup();
        seen
    });

    // Still healthy afterwards: the take records and every subscriber is still there.
    daemon.frond_ok(&["record", "stop"]);
    assert_eq!(daemon.status().subscribers.len(), 4);
    drop(daemon);
    for r in readers {
        assert!(r.join().unwrap() > 1000);
    }
}
