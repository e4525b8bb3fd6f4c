//! One measured run of `frondd` at 1 kHz with 4 subscribers (section 5 and the stage-sync rows
//! beside it): its CPU and memory, and over the same window the machine's floor for the job (a
//! bare loop and a minimal publisher).

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::thread;
use std::time::Duration;

use frondd::clock::{NS_PER_S, monotonic_ns, sleep_until_ns};
use serde_json::json;

use crate::Options;
use crate::error::BenchError;
use crate::latency::Subscribers;
use crate::procs::{Daemon, process_cpu_ns, status_kb};

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

/// The minimal publisher: a bare 1 kHz absolute-deadline loop writing a `frame_len`-byte frame
/// to `subscribers` sockets, each drained by a blocking reader thread, until `stop`. Returns the
/// writing thread's (CPU ns, wall ns).
fn fanout_floor_cpu(
    subscribers: usize,
    frame_len: usize,
    stop: Arc<AtomicBool>,
) -> thread::JoinHandle<(u64, u64)> {
    thread::spawn(move || {
        let mut writers = Vec::new();
        let mut readers = Vec::new();
        for _ in 0..subscribers {
            let Ok((w, mut r)) = UnixStream::pair() else { continue };
            writers.push(w);
            readers.push(thread::spawn(move || {
                let mut buf = [0u8; 4096];
                while matches!(r.read(&mut buf), Ok(n) if n > 0) {}
            }));
        }
        let frame = vec![0x5au8; frame_len];
        let (cpu0, wall0) = (thread_cpu_ns(), monotonic_ns());
        let mut deadline = wall0 + 1_000_000;
        while !stop.load(Relaxed) {
            sleep_until_ns(deadline);
            deadline += 1_000_000;
            for w in &mut writers {
                let _ = w.write_all(&frame);
            }
        }
        let result = (thread_cpu_ns() - cpu0, monotonic_ns() - wall0);
        drop(writers);
        for r in readers {
            let _ = r.join();
        }
        result
    })
}

/// What one run of `frondd` cost.
pub(crate) struct DaemonRun {
    /// Its CPU, fraction of one core.
    pub(crate) cpu: f64,
    /// The minimal publisher's CPU over the same window.
    pub(crate) floor: f64,
    /// A bare 1 kHz loop's CPU over the same window.
    pub(crate) bare: f64,
    /// Resident memory at the end, bytes.
    pub(crate) rss: u64,
    /// Peak resident memory, bytes.
    pub(crate) hwm: u64,
    frames_per_s: f64,
    window_s: f64,
    /// Its status at the end of the window.
    pub(crate) status: Option<frond_protocol::StatusReport>,
}

/// Runs `frondd` with `args` at 1 kHz with 4 subscribers; measures it, the fan-out floor and a
/// bare loop over the same window.
pub(crate) fn measure_daemon(
    o: &Options,
    args: &[&str],
    warm: Duration,
    window: Duration,
) -> Result<DaemonRun, BenchError> {
    let mut args = args.to_vec();
    args.extend(["--rate", "1000"]);
    let daemon = Daemon::start(o, &args)?;
    let mut subs = Subscribers::new(1);
    subs.grow_to(&daemon.poses_socket(), 4)?;
    thread::sleep(warm);
    let pid = daemon.proc.pid();
    let stop = Arc::new(AtomicBool::new(false));
    let bare = bare_loop_cpu(stop.clone());
    let floor = fanout_floor_cpu(4, 230, stop.clone());
    let (cpu0, wall0, frames0) = (process_cpu_ns(pid)?, monotonic_ns(), subs.frames());
    thread::sleep(window);
    let (cpu1, wall1, frames1) = (process_cpu_ns(pid)?, monotonic_ns(), subs.frames());
    stop.store(true, Relaxed);
    let (bare_cpu, bare_wall) = bare.join().map_err(|_| BenchError::Panicked("the bare loop thread"))?;
    let (floor_cpu, floor_wall) =
        floor.join().map_err(|_| BenchError::Panicked("the fan-out floor thread"))?;
    let wall = (wall1 - wall0) as f64;
    Ok(DaemonRun {
        cpu: (cpu1 - cpu0) as f64 / wall,
        floor: floor_cpu as f64 / floor_wall as f64,
        bare: bare_cpu as f64 / bare_wall as f64,
        rss: status_kb(pid, "VmRSS")?,
        hwm: status_kb(pid, "VmHWM")?,
        frames_per_s: (frames1 - frames0) as f64 / (wall / 1e9),
        window_s: wall / 1e9,
        status: daemon.status().ok(),
    })
}

pub(crate) fn run_json(r: &DaemonRun) -> serde_json::Value {
    json!({
        "window_s": r.window_s,
        "cpu_fraction": r.cpu,
        "fanout_floor_cpu_fraction": r.floor,
        "bare_loop_cpu_fraction": r.bare,
        "rss_peak_bytes": r.hwm,
        "subscriber_frames_per_s": r.frames_per_s,
        "daemon_achieved_rate_hz": r.status.as_ref().map(|s| s.achieved_rate_hz),
        "daemon_device_wakes": r.status.as_ref().map(|s| s.device_wakes),
        "daemon_realtime": r.status.as_ref().map(|s| s.realtime.clone()),
    })
}
