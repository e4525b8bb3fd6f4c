//! The soak's child processes (the glove, the daemon) and the daemon's figures read from
//! `/proc`: resident memory, threads and open files.

use std::path::Path;
use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

use serde::Serialize;

/// One sample of the daemon process.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct ProcSample {
    pub t_s: f64,
    pub rss_kib: i64,
    pub threads: i64,
    pub fds: i64,
}

/// A child process stopped (SIGTERM, then SIGKILL) on drop.
pub(super) struct Proc {
    pub(super) child: Child,
    exited: Option<ExitStatus>,
}

impl Proc {
    /// `child`, running.
    pub(super) fn new(child: Child) -> Proc {
        Proc { child, exited: None }
    }

    /// Whether the process still runs (its status is kept once it exits).
    pub(super) fn alive(&mut self) -> bool {
        if self.exited.is_none() {
            self.exited = self.child.try_wait().ok().flatten();
        }
        self.exited.is_none()
    }

    /// SIGTERM, wait up to `timeout`, then SIGKILL; returns the status and whether it needed
    /// the kill.
    pub(super) fn stop(&mut self, timeout: Duration) -> (Option<ExitStatus>, bool) {
        if !self.alive() {
            return (self.exited, false);
        }
        // SAFETY: kill(2) on our own unreaped child (alive() just saw it running).
        unsafe { libc::kill(self.child.id() as libc::pid_t, libc::SIGTERM) };
        let start = Instant::now();
        while start.elapsed() < timeout {
            if !self.alive() {
                return (self.exited, false);
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let _ = self.child.kill();
        self.exited = self.child.wait().ok();
        (self.exited, true)
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.stop(Duration::from_secs(3));
    }
}

/// The last 15 lines of the log at `path`, indented, for a failure message.
pub(super) fn log_tail(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(15)..].iter().map(|l| format!("    {l}\n")).collect()
}

/// Reads RSS, threads and open files of `pid`.
pub(super) fn sample_proc(pid: u32, t0: Instant) -> Option<ProcSample> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let field = |key: &str| -> Option<i64> {
        let line = status.lines().find(|l| l.starts_with(key))?;
        line[key.len()..].split_whitespace().next()?.parse().ok()
    };
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd")).ok()?.count() as i64;
    Some(ProcSample {
        t_s: t0.elapsed().as_secs_f64(),
        rss_kib: field("VmRSS:")?,
        threads: field("Threads:")?,
        fds,
    })
}

/// A sample once threads and open files held still for 500 ms and `done` holds (at most 5 s).
pub(super) fn settled_sample(
    pid: u32,
    t0: Instant,
    done: impl Fn(&ProcSample) -> bool,
) -> Option<ProcSample> {
    let start = Instant::now();
    let mut last = sample_proc(pid, t0)?;
    let mut still_since = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(50));
        let s = sample_proc(pid, t0)?;
        if (s.threads, s.fds) != (last.threads, last.fds) {
            still_since = Instant::now();
        }
        last = s;
        let still = still_since.elapsed() >= Duration::from_millis(500);
        if (still && done(&s)) || start.elapsed() > Duration::from_secs(5) {
            return Some(s);
        }
    }
}
