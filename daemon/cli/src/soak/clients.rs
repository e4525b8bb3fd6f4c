//! The soak's clients: healthy, slow and reconnecting pose subscribers, and what they saw
//! (sequence gaps, device-lost windows, the reopen time after each replug, recorded frames).

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, bail};
use frond_protocol::{CONTROL_SOCKET, PoseFlags};
use frond_sdk::{Event, Subscriber};
use serde::Serialize;

use super::schedule::{FIRST_UNPLUG_MS, UNPLUG_EVERY_MS, UNPLUG_MS};

/// One lost-device window as a healthy subscriber saw it.
#[derive(Debug, Clone, Serialize)]
pub struct LostWindow {
    /// Sequence numbers of the first and last frame flagged `device_lost`.
    pub first_seq: u64,
    pub last_seq: u64,
    /// Frames flagged `device_lost` (one per tick).
    pub frames: u64,
    /// Time from the glove's replug (its schedule, mapped to host time through the last fresh
    /// report before the window) to the first fresh frame after it, milliseconds.
    pub reopen_ms: Option<f64>,
}

/// What one subscriber saw.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SubscriberFigures {
    pub name: String,
    pub frames: u64,
    /// Gaps (missing sequence numbers) next to a `device_lost` frame.
    pub gaps_in_unplug_windows: u64,
    /// Gaps anywhere else.
    pub gaps_outside_unplug_windows: u64,
    pub missing_frames: u64,
    /// Connections (more than one only for the reconnecting exporter).
    pub connections: u64,
    /// Unexpected disconnects or errors, with what happened.
    pub errors: Vec<String>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub lost_windows: Vec<LostWindow>,
    /// Fresh frames flagged `recording`, as runs of consecutive sequence numbers (healthy-1).
    #[serde(skip)]
    pub recorded_runs: Vec<(u64, u64)>,
}

/// Appends `seq` to runs of consecutive numbers.
pub(super) fn push_run(runs: &mut Vec<(u64, u64)>, seq: u64) {
    match runs.last_mut() {
        Some((start, len)) if *start + *len == seq => *len += 1,
        _ => runs.push((seq, 1)),
    }
}

/// Per-connection state of a subscriber: lost windows and the last fresh frame before them.
#[derive(Default)]
struct Tracker {
    last: Option<frond_sdk::Pose>,
    /// Last frame that carried a new report: (host ns, device µs).
    last_fresh: Option<(u64, u64)>,
    open: Option<(LostWindow, Option<(u64, u64)>)>,
}

impl Tracker {
    fn on_pose(&mut self, p: &frond_sdk::Pose, fig: &mut SubscriberFigures, track_windows: bool) {
        let lost = p.flags.contains(PoseFlags::DEVICE_LOST);
        if track_windows && p.flags.contains(PoseFlags::RECORDING) && !p.flags.contains(PoseFlags::HELD) {
            push_run(&mut fig.recorded_runs, p.seq);
        }
        if lost {
            match &mut self.open {
                Some((w, _)) => {
                    w.last_seq = p.seq;
                    w.frames += 1;
                }
                None => {
                    let w = LostWindow { first_seq: p.seq, last_seq: p.seq, frames: 1, reopen_ms: None };
                    self.open = Some((w, self.last_fresh));
                }
            }
        } else if !p.flags.contains(PoseFlags::HELD) {
            if let Some((mut w, before)) = self.open.take() {
                w.reopen_ms =
                    before.and_then(|(host_ns, dev_us)| reopen_ms(host_ns, dev_us, p.host_monotonic_ns));
                if track_windows {
                    fig.lost_windows.push(w);
                }
            }
            self.last_fresh = Some((p.host_monotonic_ns, p.device_time_us));
        }
        self.last = Some(*p);
    }

    fn on_gap(&self, missing: u64, fig: &mut SubscriberFigures) {
        fig.missing_frames += missing;
        let near_lost =
            self.open.is_some() || self.last.is_some_and(|p| p.flags.contains(PoseFlags::DEVICE_LOST));
        if near_lost {
            fig.gaps_in_unplug_windows += 1;
        } else {
            fig.gaps_outside_unplug_windows += 1;
        }
    }
}

/// Milliseconds from the glove's next scheduled replug after the report with device time
/// `dev_us` (published at host time `host_ns`) to `fresh_ns`, the first fresh frame after the
/// window. The glove's clock counts its reports (1 kHz sway: one per ms from its first report),
/// and its unplug windows are scheduled on that clock: they end at `FIRST + k * EVERY + UNPLUG`
/// ms. `None` when the estimate is meaningless (the daemon's unwrapped device time no longer
/// matches the glove's schedule, e.g. after the 32-bit µs clock wrapped, past 71 minutes).
fn reopen_ms(host_ns: u64, dev_us: u64, fresh_ns: u64) -> Option<f64> {
    // The glove's counter is 32 bits of microseconds. The daemon unwraps it, and reads the
    // soak's clock jump back (`faults::TIME_JUMP_S`) as a wrap: modulo 2^32 it is the glove's
    // schedule again (for the first 71 minutes).
    let dev_us = dev_us % (1 << 32);
    let dev_ms = dev_us / 1000;
    let first_end = FIRST_UNPLUG_MS + UNPLUG_MS;
    let k = if dev_ms < first_end { 0 } else { (dev_ms - first_end) / UNPLUG_EVERY_MS + 1 };
    let replug_us = (first_end + k * UNPLUG_EVERY_MS) * 1000;
    let replug_host_ns = host_ns as f64 + (replug_us - dev_us) as f64 * 1000.0;
    let ms = (fresh_ns as f64 - replug_host_ns) / 1e6;
    (ms > -50.0 && ms < 10_000.0).then_some(ms)
}

pub(super) fn spawn_subscriber(
    dir: &Path,
    name: String,
    per_frame_delay: Option<Duration>,
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<JoinHandle<SubscriberFigures>> {
    let mut sub = Subscriber::options()
        .reconnect(false)
        .read_timeout(Some(Duration::from_secs(2)))
        .connect(dir)
        .with_context(|| format!("subscriber {name}"))?;
    let stop = Arc::clone(stop);
    let track = name == "healthy-1";
    Ok(std::thread::spawn(move || {
        let mut fig = SubscriberFigures { name, connections: 1, ..Default::default() };
        let mut tr = Tracker::default();
        while !stop.load(Relaxed) {
            match sub.next_event() {
                Ok(Event::Pose(p)) => {
                    fig.frames += 1;
                    tr.on_pose(&p, &mut fig, track);
                    if let Some(d) = per_frame_delay {
                        std::thread::sleep(d);
                    }
                }
                Ok(Event::Gap { expected, got }) => tr.on_gap(got - expected, &mut fig),
                Ok(Event::RigChanged(_)) => {}
                Ok(other) => {
                    fig.errors.push(format!("unexpected {other:?}"));
                    break;
                }
                Err(e) => {
                    fig.errors.push(e.to_string());
                    break;
                }
            }
        }
        fig
    }))
}

/// An exporter that connects, reads a few hundred frames, disconnects and starts over.
pub(super) fn spawn_exporter(
    dir: &Path,
    seed: u64,
    stop: &Arc<AtomicBool>,
    restarts: &Arc<AtomicU64>,
) -> anyhow::Result<JoinHandle<SubscriberFigures>> {
    let (dir, stop, restarts) = (dir.to_path_buf(), Arc::clone(stop), Arc::clone(restarts));
    if !dir.join(CONTROL_SOCKET).exists() {
        bail!("no control socket in {}", dir.display());
    }
    Ok(std::thread::spawn(move || {
        let mut fig = SubscriberFigures::default();
        let mut x = seed | 1;
        while !stop.load(Relaxed) {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let frames = 20 + x % 600;
            let sub = Subscriber::options()
                .reconnect(false)
                .read_timeout(Some(Duration::from_secs(2)))
                .connect(&dir);
            let mut sub = match sub {
                Ok(s) => s,
                Err(e) => {
                    fig.errors.push(format!("connect: {e}"));
                    break;
                }
            };
            fig.connections += 1;
            let mut tr = Tracker::default();
            let mut n = 0;
            while n < frames && !stop.load(Relaxed) {
                match sub.next_event() {
                    Ok(Event::Pose(p)) => {
                        n += 1;
                        fig.frames += 1;
                        tr.on_pose(&p, &mut fig, false);
                    }
                    Ok(Event::Gap { expected, got }) => tr.on_gap(got - expected, &mut fig),
                    Ok(_) => {}
                    Err(e) => {
                        fig.errors.push(e.to_string());
                        break;
                    }
                }
            }
            drop(sub);
            restarts.fetch_add(1, Relaxed);
            std::thread::sleep(Duration::from_millis(x % 50));
        }
        fig
    }))
}
