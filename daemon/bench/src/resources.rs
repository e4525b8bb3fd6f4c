//! Section 5: CPU use of `frondd` at 1 kHz with 4 subscribers as a fraction of one core, and its
//! resident memory, against a bare 1 kHz `clock_nanosleep` loop's CPU measured over the same
//! window and the resident memory of an idle `sleep` process.

use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::thread;
use std::time::Duration;

use frondd::clock::{NS_PER_S, monotonic_ns, sleep_until_ns};
use serde_json::json;

use crate::Options;
use crate::latency::Subscribers;
use crate::procs::{Daemon, Proc, process_cpu_ns, start_vhid, status_kb};
use crate::report::{Bound, Measurement, Section};

fn thread_cpu_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as u64 * NS_PER_S + ts.tv_nsec as u64
}

/// A bare 1 kHz absolute-deadline loop until `stop`; returns (its CPU ns, wall ns).
fn bare_loop_cpu(stop: Arc<AtomicBool>) -> thread::JoinHandle<(u64, u64)> {
    thread::spawn(move || {
        let (cpu0, wall0) = (thread_cpu_ns(), monotonic_ns());
        let mut deadline = wall0 + 1_000_000;
        while !stop.load(Relaxed) {
            sleep_until_ns(deadline);
            deadline += 1_000_000;
        }
        (thread_cpu_ns() - cpu0, monotonic_ns() - wall0)
    })
}

/// Section 5.
pub fn daemon_resources(o: &Options) -> Result<Section, String> {
    let (warm, window) = if o.quick {
        (Duration::from_millis(500), Duration::from_secs(2))
    } else {
        (Duration::from_secs(2), Duration::from_secs(20))
    };
    let dir = tempfile::Builder::new().prefix("frond-bench-vhid-").tempdir().map_err(|e| e.to_string())?;
    // The glove in its own process where a node can be served (as a physical glove would be);
    // otherwise frondd's in-process virtual glove (its generator thread then counts as frondd's).
    let (_vhid, source_args, source) = if Path::new("/dev/fuse").exists() {
        let node = dir.path().join("glove").join(frond_device::vhid::NODE_NAME);
        let node_arg = node.to_string_lossy().into_owned();
        let (vhid, node, out) =
            start_vhid(o, &["--sway", "--rate", "1000", "--backend", "fuse", "--node", &node_arg])?;
        let node = node.to_string_lossy().into_owned();
        (
            Some((vhid, out)),
            vec!["--device".to_string(), node],
            "frond-vhid FUSE hidraw node (separate process)",
        )
    } else {
        (
            None,
            vec!["--source".to_string(), "in-process".to_string()],
            "in-process virtual glove (its thread counts)",
        )
    };
    let mut args: Vec<&str> = source_args.iter().map(String::as_str).collect();
    args.extend(["--rate", "1000"]);
    let daemon = Daemon::start(o, &args)?;
    let mut subs = Subscribers::new(1);
    subs.grow_to(&daemon.poses_socket(), 4)?;
    thread::sleep(warm);
    let pid = daemon.proc.pid();

    let stop = Arc::new(AtomicBool::new(false));
    let bare = bare_loop_cpu(stop.clone());
    let (cpu0, wall0, frames0) = (process_cpu_ns(pid)?, monotonic_ns(), subs.frames());
    thread::sleep(window);
    let (cpu1, wall1, frames1) = (process_cpu_ns(pid)?, monotonic_ns(), subs.frames());
    stop.store(true, Relaxed);
    let (bare_cpu, bare_wall) = bare.join().map_err(|_| "the bare loop thread panicked")?;
    let rss = status_kb(pid, "VmRSS")?;
    let hwm = status_kb(pid, "VmHWM")?;
    let status = daemon.status().ok();

    // An idle process's resident memory: the floor any daemon starts from.
    let sleeper = Command::new("sleep")
        .arg("30")
        .stdout(Stdio::null())
        .spawn()
        .map_err(|e| format!("cannot start `sleep` for the memory baseline: {e}"))?;
    let sleeper = Proc { child: sleeper };
    thread::sleep(Duration::from_millis(100));
    let idle_rss = status_kb(sleeper.pid(), "VmRSS")?;
    drop(sleeper);

    let wall = (wall1 - wall0) as f64;
    let cpu = (cpu1 - cpu0) as f64 / wall;
    let bare_cpu = bare_cpu as f64 / bare_wall as f64;
    let measurements = vec![
        Measurement::new(
            "frondd_cpu_1000hz_4_subscribers",
            "fraction_of_core",
            cpu,
            "bare 1 kHz clock_nanosleep loop's CPU, same window",
            bare_cpu,
        )
        .with_target(
            "frondd under 3% of one core at 1 kHz with 4 subscribers",
            Bound::MaxMeasured,
            0.03,
        ),
        Measurement::new(
            "frondd_rss",
            "bytes",
            rss as f64,
            "resident memory of an idle `sleep` process",
            idle_rss as f64,
        )
        .with_target("frondd under 16 MiB RSS", Bound::MaxMeasured, 16.0 * 1024.0 * 1024.0),
    ];
    Ok(Section::ok(
        "daemon_resources",
        "frondd CPU (fraction of one core) and resident memory at 1 kHz with 4 subscribers",
        measurements,
        json!({
            "source": source,
            "window_s": wall / 1e9,
            "cpu_ns": cpu1 - cpu0,
            "rss_peak_bytes": hwm,
            "subscriber_frames_per_s": (frames1 - frames0) as f64 / (wall / 1e9),
            "daemon_achieved_rate_hz": status.as_ref().map(|s| s.achieved_rate_hz),
            "daemon_lateness": status.as_ref().map(|s| s.lateness),
            "daemon_realtime": status.as_ref().map(|s| s.realtime.clone()),
        }),
    ))
}
