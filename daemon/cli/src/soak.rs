//! `frond soak`: the whole chain under faults for a given time, then a verdict with figures.
//!
//! Scenario (the same in `tests/e2e/soak.rs`, which runs this command): `frond-vhid` at 1 kHz
//! as a FUSE hidraw node with a fault schedule (an unplug of [`UNPLUG_MS`] every
//! [`UNPLUG_EVERY_MS`], 1% corrupted reports, 200 µs jitter), `frondd --source hid --device
//! NODE` in private directories, three healthy subscribers, one deliberately slow subscriber,
//! an exporter that disconnects and reconnects in a loop, a recording for the whole run, and a
//! status poll every second that samples the daemon's RSS, threads and open files.
//!
//! On top of that ([`faults`]): the glove's clock is off for a second, the daemon is paused
//! (SIGSTOP) for a second, and the takes directory is a small tmpfs that fills part way through
//! the first take and is freed later, after which a second take is recorded to the end.
//!
//! Verdict: the daemon is still running and exits 0 on SIGTERM; healthy subscribers see no
//! sequence gap outside the unplug windows (the pause included); the device is back within
//! 500 ms of each replug; the clock jump is counted as two discontinuities and the pause skips
//! stale reports; the take cut by the full disk holds every frame up to the fault, is closed,
//! and its `record stop` reports the error; the last take is complete (contiguous frames, End
//! record); RSS grows less than 2 MiB after the warm-up; threads and open files return to their
//! idle counts once the clients are gone.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use frond_protocol::POSES_SOCKET;
use serde::Serialize;

use crate::control::Control;

mod clients;
mod faults;
mod procs;
mod schedule;
mod takes;

use crate::error::{Interrupted, usage};
use crate::signals;
pub use clients::SubscriberFigures;
use clients::{spawn_exporter, spawn_subscriber};
pub use procs::ProcSample;
use procs::{Proc, log_tail, sample_proc, settled_sample};
pub use schedule::{CORRUPT_PROB, FIRST_UNPLUG_MS, UNPLUG_EVERY_MS, UNPLUG_MS};
pub use takes::TakeFigures;
use takes::{Part, read_take};

/// Largest allowed time from a replug to the first fresh frame (issue 8).
pub const REOPEN_LIMIT_MS: f64 = 500.0;
/// Largest allowed RSS growth after the warm-up.
pub const RSS_GROWTH_LIMIT_KIB: i64 = 2048;
/// How long a SIGTERMed daemon may take to exit before it is killed.
const STOP_TIMEOUT: Duration = Duration::from_secs(5);

/// Everything `frond soak` measured, and the verdict.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SoakReport {
    pub duration_s: f64,
    pub seed: u64,
    pub unplug_ms: u64,
    pub unplug_every_ms: u64,
    pub corrupt_prob: f64,
    pub subscribers: Vec<SubscriberFigures>,
    pub exporter_restarts: u64,
    pub slow_subscriber_drops: u64,
    pub publish_drops: u64,
    pub ticks: u64,
    pub reports: u64,
    pub rejected_reports: u64,
    pub device_events: Vec<String>,
    pub reopen_ms_max: Option<f64>,
    pub take: TakeFigures,
    pub rss_kib_after_warmup: i64,
    pub rss_kib_end: i64,
    pub rss_growth_kib: i64,
    pub idle_before: ProcSample,
    pub idle_after: ProcSample,
    pub threads_max: i64,
    pub fds_max: i64,
    pub daemon_alive_at_end: bool,
    pub daemon_exit: Option<String>,
    pub daemon_stop_ms: Option<f64>,
    pub samples: Vec<ProcSample>,
    /// The time jump, the pause and the full disk, and what the daemon said of them.
    pub faults: faults::FaultFigures,
    pub failures: Vec<String>,
}

/// `frond soak --duration S [--json]`.
pub(crate) fn run(duration_s: f64, json: bool, seed: u64) -> anyhow::Result<()> {
    if !(duration_s.is_finite() && duration_s >= 20.0) {
        return usage(format!("--duration must be at least 20 seconds, got {duration_s}"));
    }
    signals::install().context("installing signal handlers")?;
    let report = soak(Duration::from_secs_f64(duration_s), seed)?;
    if json {
        frond_binmain::outln!("{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        print_human(&report)?;
    }
    if !report.failures.is_empty() {
        bail!("soak failed:\n  {}", report.failures.join("\n  "));
    }
    Ok(())
}

fn print_human(r: &SoakReport) -> Result<(), frond_binmain::StdoutError> {
    frond_binmain::outln!("soak {:.0} s, seed {:#x}", r.duration_s, r.seed)?;
    for s in &r.subscribers {
        frond_binmain::outln!(
            "  {:<10} {:>8} frames, gaps {} in / {} outside unplug windows, {} connection(s)",
            s.name,
            s.frames,
            s.gaps_in_unplug_windows,
            s.gaps_outside_unplug_windows,
            s.connections
        )?;
    }
    frond_binmain::outln!(
        "  exporter restarts {}, slow subscriber drops {}",
        r.exporter_restarts,
        r.slow_subscriber_drops
    )?;
    frond_binmain::outln!("  reports {} (rejected {}), ticks {}", r.reports, r.rejected_reports, r.ticks)?;
    frond_binmain::outln!("  reopen after replug: max {:?} ms", r.reopen_ms_max)?;
    frond_binmain::outln!(
        "  take {}: {} frames, ended {}, torn {} bytes, seq breaks {}",
        r.take.path,
        r.take.frames,
        r.take.ended,
        r.take.torn_bytes,
        r.take.seq_breaks
    )?;
    let x = &r.faults;
    frond_binmain::outln!(
        "  clock jump: {} discontinuities; pause {:?} ms: {} stale reports skipped",
        x.discontinuities,
        x.pause_ms,
        x.stale_skipped
    )?;
    frond_binmain::outln!(
        "  full disk at {:?} s ({:?}), freed at {:?} s; cut take {} frames, ended {}, breaks {}; record stop: {:?}",
        x.disk_error_at_s,
        x.disk_error,
        x.disk_freed_at_s,
        x.first_take.frames,
        x.first_take.ended,
        x.first_take.seq_breaks,
        x.first_take_stop
    )?;
    frond_binmain::outln!(
        "  RSS {} -> {} KiB (growth {} KiB), threads {} -> {}, fds {} -> {} (idle before/after)",
        r.rss_kib_after_warmup,
        r.rss_kib_end,
        r.rss_growth_kib,
        r.idle_before.threads,
        r.idle_after.threads,
        r.idle_before.fds,
        r.idle_after.fds
    )?;
    frond_binmain::outln!("  daemon exit {:?} after {:?} ms", r.daemon_exit, r.daemon_stop_ms)?;
    if r.failures.is_empty() {
        frond_binmain::outln!("PASS")?;
    } else {
        frond_binmain::outln!("FAIL:\n  {}", r.failures.join("\n  "))?;
    }
    Ok(())
}

/// Runs the scenario for `duration` and returns the figures with the verdict in `failures`.
pub fn soak(duration: Duration, seed: u64) -> anyhow::Result<SoakReport> {
    let mut r = SoakReport {
        duration_s: duration.as_secs_f64(),
        seed,
        unplug_ms: UNPLUG_MS,
        unplug_every_ms: UNPLUG_EVERY_MS,
        corrupt_prob: CORRUPT_PROB,
        ..SoakReport::default()
    };
    if !Path::new("/dev/fuse").exists() {
        bail!("the soak needs /dev/fuse (and root) for the virtual glove's hidraw node");
    }
    let (frondd, vhid) = (crate::demo::find_program("frondd")?, crate::demo::find_program("frond-vhid")?);
    let files = Files::new()?;
    // Dropped after the daemon (declared before it): the takes live on a small tmpfs.
    let _tmpfs = faults::Tmpfs::mount(&files.takes_dir)?;

    let (mut glove, node) = start_glove(&vhid, &files, seed)?;
    let glove_started = Instant::now();
    let mut daemon = start_daemon(&frondd, &files, &node)?;
    let pid = daemon.child.id();
    let t0 = Instant::now();
    let control = wait_for_daemon(&mut daemon, &files, t0)?;
    // Idle counts before any client: the daemon with its device and no connection, once the
    // counts hold still for half a second.
    drop(control);
    r.idle_before = settled_sample(pid, t0, |_| true).context("cannot read /proc of frondd")?;
    let mut control = Control::connect(&files.socket_dir)?;

    let clients = Clients::start(&files.socket_dir, seed)?;
    // The first take runs into a full disk part way through; a second one follows it.
    r.faults.disk_filler_bytes = faults::fill_disk(&files.takes_dir, duration)?;
    let first_take = format!("soak-{seed:x}");
    control.record_start(&first_take)?;

    let run =
        Run { pid, t0, duration, takes_dir: &files.takes_dir, second_take: format!("soak-{seed:x}-after") };
    let after_warmup = run_faults(&mut r, &run, &mut control, &mut daemon, &clients.stop)?;
    r.daemon_alive_at_end = daemon.alive();
    let final_sample = sample_proc(pid, t0);

    let status = if r.daemon_alive_at_end {
        let rec = control.record_stop().context("record stop")?;
        r.take.frames_reported = rec.frames;
        r.take.recorder_dropped = rec.dropped;
        r.take.path = rec.path;
        Some(control.status()?)
    } else {
        None
    };
    let exporter_figures = clients.finish(&mut r);
    if let Some(s) = &status {
        status_figures(&mut r, s);
    }
    drop(control);

    // Idle counts after every client left (writer threads and sockets need a moment to go).
    let before = r.idle_before;
    r.idle_after =
        settled_sample(pid, t0, |s| s.threads == before.threads && s.fds == before.fds).unwrap_or_default();
    stop_daemon(&mut r, &mut daemon);
    glove.stop(Duration::from_secs(3));
    let glove_elapsed = glove_started.elapsed();

    let first_take_path = files.takes_dir.join(format!("{first_take}.take"));
    let windows = figures(&mut r, &first_take_path, exporter_figures, after_warmup, final_sample);
    verdict(&mut r, windows, glove_elapsed);
    if !r.failures.is_empty() {
        frond_binmain::errln!("frondd log (last lines):\n{}", log_tail(&files.daemon_log));
        frond_binmain::errln!("frond-vhid log (last lines):\n{}", log_tail(&files.vhid_log));
    }
    Ok(r)
}

/// The soak's private directory: the daemon's sockets, the takes (a tmpfs mounted later), the
/// glove's node and both programs' logs. Removed when dropped.
struct Files {
    root: tempfile::TempDir,
    socket_dir: PathBuf,
    takes_dir: PathBuf,
    vhid_log: PathBuf,
    daemon_log: PathBuf,
}

impl Files {
    fn new() -> anyhow::Result<Files> {
        let root = tempfile::Builder::new().prefix("frond-soak-").tempdir().context("temp dir")?;
        let at = |name: &str| root.path().join(name);
        Ok(Files {
            socket_dir: at("run"),
            takes_dir: at("takes"),
            vhid_log: at("vhid.log"),
            daemon_log: at("frondd.log"),
            root,
        })
    }
}

/// Starts `frond-vhid` as a FUSE hidraw node with the soak's fault schedule; returns it and the
/// node's path, which it prints first.
fn start_glove(vhid: &Path, files: &Files, seed: u64) -> anyhow::Result<(Proc, PathBuf)> {
    let mut child = Command::new(vhid)
        .args(["--backend", "fuse", "--rate", "1000", "--jitter-us", "200"])
        .args(["--corrupt", &CORRUPT_PROB.to_string(), "--seed", &seed.to_string()])
        .args(["--unplug-at-ms", &FIRST_UNPLUG_MS.to_string(), "--unplug-ms", &UNPLUG_MS.to_string()])
        .args(["--unplug-every-ms", &UNPLUG_EVERY_MS.to_string()])
        .args(["--time-jump-at-ms", &faults::TIME_JUMP_AT_MS.to_string()])
        .args(["--time-jump-ms", &faults::TIME_JUMP_MS.to_string()])
        .args(["--time-jump-s", &faults::TIME_JUMP_S.to_string()])
        .arg("--node")
        .arg(files.root.path().join("glove").join("hidraw-frond"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(File::create(&files.vhid_log)?)
        .spawn()
        .with_context(|| format!("cannot start {}", vhid.display()))?;
    let mut line = String::new();
    BufReader::new(child.stdout.take().context("vhid stdout")?).read_line(&mut line)?;
    let proc = Proc::new(child);
    if line.trim().is_empty() {
        bail!("frond-vhid printed no node path; its log:\n{}", log_tail(&files.vhid_log));
    }
    Ok((proc, PathBuf::from(line.trim())))
}

/// Starts `frondd` on the glove's `node` in the soak's private directories.
fn start_daemon(frondd: &Path, files: &Files, node: &Path) -> anyhow::Result<Proc> {
    let child = Command::new(frondd)
        .arg("--socket-dir")
        .arg(&files.socket_dir)
        .arg("--takes-dir")
        .arg(&files.takes_dir)
        .args(["--source", "hid", "--device"])
        .arg(node)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(File::create(&files.daemon_log)?)
        .spawn()
        .with_context(|| format!("cannot start {}", frondd.display()))?;
    Ok(Proc::new(child))
}

/// A control connection once the daemon answers and its pose socket exists (at most 20 s
/// from `t0`).
fn wait_for_daemon(daemon: &mut Proc, files: &Files, t0: Instant) -> anyhow::Result<Control> {
    loop {
        if let Ok(c) = Control::connect(&files.socket_dir)
            && files.socket_dir.join(POSES_SOCKET).exists()
        {
            return Ok(c);
        }
        if !daemon.alive() || t0.elapsed() > Duration::from_secs(20) {
            bail!("frondd did not start; its log:\n{}", log_tail(&files.daemon_log));
        }
        std::thread::sleep(Duration::from_millis(25));
    }
}

/// The soak's clients: three healthy subscribers, a slow one and the reconnecting exporter,
/// all stopped by `stop`.
struct Clients {
    stop: Arc<AtomicBool>,
    subs: Vec<JoinHandle<SubscriberFigures>>,
    exporter: JoinHandle<SubscriberFigures>,
    restarts: Arc<AtomicU64>,
}

impl Clients {
    fn start(socket_dir: &Path, seed: u64) -> anyhow::Result<Clients> {
        let stop = Arc::new(AtomicBool::new(false));
        let mut subs: Vec<JoinHandle<SubscriberFigures>> = Vec::new();
        for i in 1..=3 {
            subs.push(spawn_subscriber(socket_dir, format!("healthy-{i}"), None, &stop)?);
        }
        subs.push(spawn_subscriber(socket_dir, "slow".into(), Some(Duration::from_millis(2)), &stop)?);
        let restarts = Arc::new(AtomicU64::new(0));
        let exporter = spawn_exporter(socket_dir, seed, &stop, &restarts)?;
        Ok(Clients { stop, subs, exporter, restarts })
    }

    /// Stops the clients and puts the subscribers' figures and the exporter's restarts into
    /// `r`; returns the exporter's figures.
    fn finish(self, r: &mut SoakReport) -> SubscriberFigures {
        self.stop.store(true, Relaxed);
        r.subscribers = self.subs.into_iter().map(|h| h.join().unwrap_or_default()).collect();
        let exporter_figures = self.exporter.join().unwrap_or_default();
        r.exporter_restarts = self.restarts.load(Relaxed);
        exporter_figures
    }
}

/// What the fault loop needs to know of the run.
struct Run<'a> {
    pid: u32,
    t0: Instant,
    duration: Duration,
    takes_dir: &'a Path,
    /// The take recorded once the disk has room again.
    second_take: String,
}

/// The run: one status request and one /proc sample a second, the pause and the freeing of the
/// disk on the way, until `run.duration` or the daemon's end. Returns the sample taken after
/// the warm-up.
fn run_faults(
    r: &mut SoakReport,
    run: &Run,
    control: &mut Control,
    daemon: &mut Proc,
    stop: &AtomicBool,
) -> anyhow::Result<Option<ProcSample>> {
    let (t0, duration) = (run.t0, run.duration);
    let warmup = Duration::from_secs(10).min(duration / 4);
    let mut after_warmup: Option<ProcSample> = None;
    let mut second_take_started = false;
    let (mut streaming, mut last_reports) = (false, 0u64);
    while t0.elapsed() < duration {
        if signals::interrupted() {
            stop.store(true, Relaxed);
            return Err(Interrupted.into());
        }
        std::thread::sleep(Duration::from_secs(1).min(duration.saturating_sub(t0.elapsed())));
        if !daemon.alive() {
            break;
        }
        // The pause comes once the glove is streaming (reports grew over the last second):
        // only then can the daemon find stale reports queued behind it when it resumes (on a
        // loaded machine the glove may still be unplugged, or not yet opened, at PAUSE_AT).
        if r.faults.pause_ms.is_none() && t0.elapsed() >= faults::PAUSE_AT && streaming {
            r.faults.pause_ms = Some(faults::pause(run.pid));
        }
        let status = control.status().context("status request during the soak")?;
        streaming = status.source.reports > last_reports;
        last_reports = status.source.reports;
        let at_s = t0.elapsed().as_secs_f64();
        if r.faults.disk_error.is_none()
            && let Some(e) = status.recorder_error
        {
            (r.faults.disk_error, r.faults.disk_error_at_s) = (Some(e), Some(at_s));
        }
        if r.faults.disk_freed_at_s.is_none() && at_s >= duration.as_secs_f64() * faults::DISK_FREED_AT {
            faults::free_disk(run.takes_dir)?;
            r.faults.disk_freed_at_s = Some(at_s);
        } else if !second_take_started && r.faults.disk_freed_at_s.is_some_and(|t| at_s >= t + 2.0) {
            // Room again for two seconds: the recorder has closed the cut take. Ending it
            // reports the error once; then the next take.
            r.faults.first_take_stop = Some(match control.record_stop() {
                Ok(rec) => format!("ok: {} frames", rec.frames),
                Err(e) => format!("{e:#}"),
            });
            control.record_start(&run.second_take)?;
            second_take_started = true;
        }
        if let Some(s) = sample_proc(run.pid, t0) {
            if t0.elapsed() >= warmup && after_warmup.is_none() {
                after_warmup = Some(s);
            }
            r.samples.push(s);
        }
    }
    Ok(after_warmup)
}

/// The daemon's own counts at the end of the run, from its last status.
fn status_figures(r: &mut SoakReport, s: &frond_protocol::StatusReport) {
    if let Some(h) = s.hands.first() {
        r.faults.discontinuities = h.discontinuities;
        r.faults.stale_skipped = h.stale_skipped;
    }
    r.ticks = s.ticks;
    r.reports = s.source.reports;
    r.rejected_reports = s.source.rejected;
    r.publish_drops = s.publish_drops;
    r.device_events = s.device_events.clone();
}

/// SIGTERM to the daemon; how it exited and how long it took go into `r`.
fn stop_daemon(r: &mut SoakReport, daemon: &mut Proc) {
    let stop_start = Instant::now();
    let (exit, killed) = daemon.stop(STOP_TIMEOUT);
    r.daemon_stop_ms = Some(stop_start.elapsed().as_secs_f64() * 1000.0);
    r.daemon_exit =
        exit.map(|s| if killed { format!("{s} (killed after {STOP_TIMEOUT:?})") } else { s.to_string() });
}

/// The figures read after the run: both takes against what healthy-1 saw, the reopen times,
/// the slow subscriber's drops, memory, threads and files. Returns how many device-lost
/// windows the subscribers saw.
fn figures(
    r: &mut SoakReport,
    first_take_path: &Path,
    mut exporter_figures: SubscriberFigures,
    after_warmup: Option<ProcSample>,
    final_sample: Option<ProcSample>,
) -> u64 {
    // The takes, against the recorded frames healthy-1 saw: the cut one up to its last frame
    // (no frame before the fault lost), the next one from its first.
    let seen = r.subscribers.first().map(|s| s.recorded_runs.clone()).unwrap_or_default();
    r.faults.first_take.path = first_take_path.display().to_string();
    read_take(&mut r.faults.first_take, &seen, Part::UpToItsEnd);
    if !r.take.path.is_empty() {
        read_take(&mut r.take, &seen, Part::FromItsStart);
    }
    // Reopen latency: the healthy subscribers saw the same windows; take the first one's.
    let windows = r.subscribers.first().map(|s| s.lost_windows.clone()).unwrap_or_default();
    r.reopen_ms_max = windows.iter().filter_map(|w| w.reopen_ms).reduce(f64::max);
    r.slow_subscriber_drops =
        r.subscribers.iter().filter(|s| s.name == "slow").map(|s| s.missing_frames).sum();
    exporter_figures.name = "exporter".into();
    r.subscribers.push(exporter_figures);
    r.rss_kib_after_warmup = after_warmup.map_or(0, |s| s.rss_kib);
    r.rss_kib_end = final_sample.map_or(0, |s| s.rss_kib);
    r.rss_growth_kib = r.rss_kib_end - r.rss_kib_after_warmup;
    r.threads_max = r.samples.iter().map(|s| s.threads).max().unwrap_or(0);
    r.fds_max = r.samples.iter().map(|s| s.fds).max().unwrap_or(0);
    windows.len() as u64
}

fn verdict(r: &mut SoakReport, windows: u64, glove_elapsed: Duration) {
    let mut f = Vec::new();
    if !r.daemon_alive_at_end {
        f.push("frondd was not running at the end of the soak".to_string());
    }
    match &r.daemon_exit {
        Some(s) if s == "exit status: 0" => {}
        other => f.push(format!("frondd did not exit 0 on SIGTERM: {other:?}")),
    }
    subscriber_failures(r, windows, glove_elapsed, &mut f);
    let t = &r.take;
    if let Some(e) = &t.error {
        f.push(format!("take {}: {e}", t.path));
    } else if !t.ended
        || t.torn_bytes > 0
        || t.seq_breaks > 0
        || t.frames != t.frames_reported
        || t.frames == 0
    {
        f.push(format!(
            "take incomplete: {} frames ({} reported), ended {}, torn {} bytes, {} seq breaks",
            t.frames, t.frames_reported, t.ended, t.torn_bytes, t.seq_breaks
        ));
    }
    if t.recorder_dropped > 0 {
        f.push(format!("the recorder dropped {} frames", t.recorder_dropped));
    }
    faults::verdict(&r.faults, &mut f);
    if r.rss_growth_kib >= RSS_GROWTH_LIMIT_KIB {
        f.push(format!(
            "RSS grew {} KiB after warm-up ({} -> {} KiB), limit {RSS_GROWTH_LIMIT_KIB}",
            r.rss_growth_kib, r.rss_kib_after_warmup, r.rss_kib_end
        ));
    }
    let (a, b) = (r.idle_before, r.idle_after);
    if a.threads != b.threads || a.fds != b.fds {
        f.push(format!(
            "idle counts changed: threads {} -> {}, open files {} -> {}",
            a.threads, b.threads, a.fds, b.fds
        ));
    }
    r.failures = f;
}

/// The verdict on what the subscribers saw: no gap outside the unplug windows, every unplug
/// seen, the device back within [`REOPEN_LIMIT_MS`] of each replug.
fn subscriber_failures(r: &SoakReport, windows: u64, glove_elapsed: Duration, f: &mut Vec<String>) {
    for s in &r.subscribers {
        if s.name != "slow" && s.gaps_outside_unplug_windows > 0 {
            f.push(format!(
                "{}: {} gap(s) outside the unplug windows",
                s.name, s.gaps_outside_unplug_windows
            ));
        }
        if !s.errors.is_empty() {
            f.push(format!("{}: {}", s.name, s.errors.join("; ")));
        }
        if s.frames == 0 {
            f.push(format!("{}: received no frames", s.name));
        }
    }
    // Every unplug that ended before the glove stopped shows as one lost window.
    let ms = glove_elapsed.as_millis() as u64;
    let expected = if ms > FIRST_UNPLUG_MS + UNPLUG_MS {
        1 + (ms - FIRST_UNPLUG_MS - UNPLUG_MS) / UNPLUG_EVERY_MS
    } else {
        0
    };
    if windows + 1 < expected {
        f.push(format!("{windows} device-lost window(s) seen, the glove unplugged about {expected} times"));
    }
    // A reopen time that cannot be told would make the next check pass for nothing.
    if let Some(w) = r.subscribers.first().and_then(|s| s.lost_windows.iter().find(|w| w.reopen_ms.is_none()))
    {
        f.push(format!(
            "the reopen time after the window seq {}..={} could not be told from the glove's schedule",
            w.first_seq, w.last_seq
        ));
    }
    if let Some(w) = r
        .subscribers
        .first()
        .and_then(|s| s.lost_windows.iter().find(|w| w.reopen_ms.is_some_and(|ms| ms > REOPEN_LIMIT_MS)))
    {
        f.push(format!(
            "device not back within {REOPEN_LIMIT_MS} ms of a replug: window seq {}..={} ({} frames), reopen {:?} ms",
            w.first_seq, w.last_seq, w.frames, w.reopen_ms
        ));
    }
}
