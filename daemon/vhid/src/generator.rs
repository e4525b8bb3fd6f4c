//! The virtual glove's report generator and its settings: what it plays ([`GloveSource`]), the
//! faults it injects ([`FaultPlan`]), its device clock, and the thread that produces
//! reference-glove reports on schedule into a [`ReportSink`] (a FUSE node, `/dev/uhid`, an
//! in-process queue or OSC datagrams).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use frond_motion::HandSample;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::glove::{GloveReport, REPORT_LEN, STATUS_TRACKING_OK, encode_report};
use frond_device::jsonl::{HandFileError, load_hand_file};

/// Highest report rate of the virtual glove.
pub const MAX_RATE_HZ: f64 = 8000.0;

/// What the virtual glove plays.
#[derive(Debug, Clone, PartialEq)]
pub enum GloveSource {
    /// The built-in procedural sway (a plant in the wind) at `rate_hz` reports per second.
    Sway {
        /// Report rate in hertz, within 1..=[`MAX_RATE_HZ`].
        rate_hz: f64,
    },
    /// A JSONL hand file played at its timestamps; `looped` starts over at the end.
    Jsonl {
        /// The JSONL hand file.
        path: PathBuf,
        /// Whether playback starts over at the end of the file.
        looped: bool,
    },
}

/// Periodic or one-off unplugging.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnplugPlan {
    /// First unplug, milliseconds after the first report.
    pub at_ms: u64,
    /// How long the device stays unplugged.
    pub duration_ms: u64,
    /// Repeat every this many milliseconds (`None`: once).
    pub every_ms: Option<u64>,
}

impl UnplugPlan {
    /// Whether the device is unplugged `elapsed_ms` after the first report.
    pub fn unplugged_at(&self, elapsed_ms: u64) -> bool {
        if elapsed_ms < self.at_ms {
            return false;
        }
        let since = elapsed_ms - self.at_ms;
        let phase = match self.every_ms {
            Some(every) if every > 0 => since % every,
            _ => since,
        };
        phase < self.duration_ms
    }
}

/// A stretch of time in which the glove's clock is off (a firmware glitch, a tracker that
/// restarted its counter): from `at_ms` for `duration_ms` each report's device time is shifted by
/// `by_us` (wrapping, as the 32-bit counter does), then it is right again. The daemon must start
/// a new timeline at both ends (issue 14, point 6), neither freezing nor bursting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TimeJump {
    /// Start, milliseconds after the first report.
    pub at_ms: u64,
    /// How long the clock stays off.
    pub duration_ms: u64,
    /// The shift, microseconds (negative: the clock went back).
    pub by_us: i64,
}

impl TimeJump {
    /// The device time reported for schedule time `time_us` at `elapsed_ms`.
    pub fn apply(&self, elapsed_ms: u64, time_us: u64) -> u64 {
        if (self.at_ms..self.at_ms.saturating_add(self.duration_ms)).contains(&elapsed_ms) {
            time_us.wrapping_add_signed(self.by_us)
        } else {
            time_us
        }
    }
}

/// Faults to inject.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultPlan {
    /// Probability that a report is dropped (its sequence number is still used up).
    pub drop_prob: f64,
    /// Probability that one byte of a report is corrupted (the checksum then fails).
    pub corrupt_prob: f64,
    /// Unplugging schedule.
    pub unplug: Option<UnplugPlan>,
    /// Stall schedule: the glove stays plugged in but sends nothing in these windows (a
    /// firmware hang or a tracker that lost the hand), which the daemon must detect without a
    /// disconnect.
    pub stall: Option<UnplugPlan>,
    /// A stretch in which the glove's clock is off.
    pub time_jump: Option<TimeJump>,
    /// Each report is delayed by a uniform random 0..=`jitter_us` microseconds (device time is
    /// not affected: it is when the glove sampled the hand).
    pub jitter_us: u32,
    /// Seed of the fault generator (reproducible runs).
    pub seed: u64,
}

impl Default for FaultPlan {
    fn default() -> Self {
        Self {
            drop_prob: 0.0,
            corrupt_prob: 0.0,
            unplug: None,
            stall: None,
            time_jump: None,
            jitter_us: 0,
            seed: 0x5EED_F20D,
        }
    }
}

/// What the report's device-time field carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DeviceClock {
    /// The glove's own microsecond counter: the sample's time on the played schedule (starts at
    /// the file's first timestamp, or 0 for the sway). The default.
    #[default]
    Schedule,
    /// The host's `CLOCK_MONOTONIC` in microseconds (truncated to `u32`), read just before the
    /// report is written to the node or queue. A subscriber in another process subtracts it
    /// from its own `CLOCK_MONOTONIC` to measure glove-write -> receipt latency (`frond bench`).
    /// A real device's counter advances between reports, so this one does too: a report
    /// written within the microsecond of the one before (the reports a late wake-up owes go
    /// out back to back) is stamped one microsecond after it. Stamped with
    /// the clock alone, 0.7-1.5 % of the reports repeated a time, and frondd rightly took each
    /// as a new timeline and reset its filter.
    Monotonic,
}

/// Virtual glove configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct VirtualGloveConfig {
    /// What the glove plays.
    pub source: GloveSource,
    /// Faults to inject into the reports.
    pub faults: FaultPlan,
    /// Wait this long after the node is ready before the first report.
    pub start_delay_ms: u64,
    /// What the device-time field carries.
    pub clock: DeviceClock,
}

impl VirtualGloveConfig {
    /// The built-in sway at `rate_hz`, no faults.
    pub fn sway(rate_hz: f64) -> Self {
        Self {
            source: GloveSource::Sway { rate_hz },
            faults: FaultPlan::default(),
            start_delay_ms: 0,
            clock: DeviceClock::Schedule,
        }
    }
}

/// `now_us` on a wrapping microsecond counter, or one microsecond after `previous_us` when
/// `now_us` is not later than it (the same microsecond, or a read that went back).
pub(crate) fn advancing_us(now_us: u32, previous_us: Option<u32>) -> u32 {
    match previous_us {
        // Later on the wrapping counter: 1 to half its range ahead.
        Some(p) if !(1..=u32::MAX / 2).contains(&now_us.wrapping_sub(p)) => p.wrapping_add(1),
        _ => now_us,
    }
}

/// Host `CLOCK_MONOTONIC` in microseconds, truncated to the report's wrapping `u32` counter.
pub fn monotonic_us_u32() -> u32 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    (ts.tv_sec as u64).wrapping_mul(1_000_000).wrapping_add(ts.tv_nsec as u64 / 1000) as u32
}

/// Errors of the virtual glove.
#[derive(Debug, thiserror::Error)]
pub enum VhidError {
    /// The JSONL hand file to play could not be loaded.
    #[error(transparent)]
    HandFile(#[from] HandFileError),
    /// The configuration is invalid (probability, unplug/stall timing, rate or node path).
    #[error("invalid virtual glove configuration: {0}")]
    Config(String),
    /// FUSE is unavailable (no `/dev/fuse`, or mounting is not permitted).
    #[error("cannot use FUSE: {0}")]
    NoFuse(String),
    /// The mount directory has entries that the mount would hide.
    #[error("mount directory {0} is not empty (mounting would hide its contents)")]
    MountDirNotEmpty(PathBuf),
    /// Creating the mount directory or mounting the FUSE file system failed.
    #[error("cannot mount the virtual glove at {dir}: {source}")]
    Mount {
        /// The mount directory.
        dir: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// Unmounting the FUSE file system failed.
    #[error("cannot unmount {dir}: {source}")]
    Unmount {
        /// The mount directory.
        dir: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// Creating the kernel HID device through `/dev/uhid` failed.
    #[error("uhid: {0}")]
    Uhid(String),
    /// The report generator thread could not be spawned.
    #[error("cannot start the report thread: {0}")]
    Thread(std::io::Error),
    /// The in-process glove's eventfd doorbell could not be created.
    #[error("cannot create the in-process glove's eventfd: {0}")]
    EventFd(std::io::Error),
}

/// What the generator did (shared, readable while it runs).
#[derive(Debug, Default)]
pub struct VhidStats {
    /// Reports handed to the node or queue.
    pub sent: AtomicU64,
    /// Reports dropped by fault injection.
    pub dropped: AtomicU64,
    /// Reports corrupted by fault injection.
    pub corrupted: AtomicU64,
    /// Reports lost because the device was unplugged.
    pub unplugged_lost: AtomicU64,
    /// Reports with an angle clamped to the i16 centidegree range.
    pub clamped: AtomicU64,
    /// Number of unplug events.
    pub unplugs: AtomicU64,
    /// Reports not sent during stall windows.
    pub stalled: AtomicU64,
    /// Reports not sent because they were already stale when their time came (the glove was
    /// paused, SIGSTOP, an overloaded host): a glove samples the present, so it skips them and
    /// resumes at the present (the device sequence numbers show the gap).
    pub late_skipped: AtomicU64,
    /// Set once a non-looping JSONL file has been played to the end.
    pub finished: AtomicBool,
}

/// Where generated reports go.
pub(crate) trait ReportSink: Send {
    fn send(&mut self, report: &[u8; REPORT_LEN]);
    fn set_plugged(&mut self, plugged: bool);
}

#[derive(Debug)]
enum Prepared {
    Sway { rate_hz: f64 },
    Samples { samples: Vec<HandSample>, looped: bool, period_s: f64 },
}

/// A configured generator with its file loaded (errors surface before any node is created).
#[derive(Debug)]
pub(crate) struct Generator {
    prepared: Prepared,
    faults: FaultPlan,
    start_delay: Duration,
    clock: DeviceClock,
}

/// The procedural sway: a few incommensurate sines on wrist and thumb (degrees).
pub fn sway_sample(t: f64) -> (HandSample, [f32; 4]) {
    use std::f64::consts::TAU;
    let s = |f: f64, ph: f64| (TAU * f * t + ph).sin();
    let wrist = [
        12.0 * s(0.31, 0.0) + 5.0 * s(0.73, 1.3) + 1.5 * s(2.9, 0.2),
        8.0 * s(0.23, 0.5) + 3.0 * s(1.07, 0.0),
        6.0 * s(0.17, 2.0) + 2.0 * s(0.61, 0.9),
    ];
    let thumb = [0.0, 1.0, 2.0]
        .map(|i: f64| 25.0 + 15.0 * s(0.41, 0.7 * i) + 4.0 * s(1.31, i) + 1.0 * s(3.7, 0.3 * i));
    let flex = [0.0, 1.0, 2.0, 3.0].map(|i: f64| (20.0 + 10.0 * s(0.19 + 0.03 * i, i)) as f32);
    (HandSample { t, wrist_deg: wrist.map(|v| v as f32), thumb_deg: thumb.map(|v| v as f32) }, flex)
}

impl Generator {
    pub(crate) fn prepare(config: &VirtualGloveConfig) -> Result<Self, VhidError> {
        let f = &config.faults;
        for (name, p) in [("drop", f.drop_prob), ("corrupt", f.corrupt_prob)] {
            if !(0.0..=1.0).contains(&p) {
                return Err(VhidError::Config(format!("{name} probability {p} is not within 0..=1")));
            }
        }
        for (name, plan) in [("unplug", f.unplug), ("stall", f.stall)] {
            let Some(u) = plan else { continue };
            if u.duration_ms == 0 {
                return Err(VhidError::Config(format!("{name} duration must be > 0 ms")));
            }
            if u.every_ms.is_some_and(|e| e <= u.duration_ms) {
                return Err(VhidError::Config(format!(
                    "{name} period must be longer than the {name} duration"
                )));
            }
        }
        let prepared = match &config.source {
            GloveSource::Sway { rate_hz } => {
                if !(rate_hz.is_finite() && *rate_hz >= 1.0 && *rate_hz <= MAX_RATE_HZ) {
                    return Err(VhidError::Config(format!(
                        "rate {rate_hz} Hz is not within 1..={MAX_RATE_HZ}"
                    )));
                }
                Prepared::Sway { rate_hz: *rate_hz }
            }
            GloveSource::Jsonl { path, looped } => {
                let samples = load_hand_file(path)?;
                let span = samples[samples.len() - 1].t - samples[0].t;
                let mean_dt = if samples.len() > 1 { span / (samples.len() - 1) as f64 } else { 1.0 / 30.0 };
                if samples[0].t < 0.0 {
                    return Err(VhidError::Config(format!(
                        "{}: negative times cannot be sent as device time",
                        path.display()
                    )));
                }
                Prepared::Samples { samples, looped: *looped, period_s: span + mean_dt.max(1e-6) }
            }
        };
        Ok(Self {
            prepared,
            faults: config.faults,
            start_delay: Duration::from_millis(config.start_delay_ms),
            clock: config.clock,
        })
    }

    /// Item `n`: (host offset from the first report in seconds, device time µs, hand, flex),
    /// or `None` when the source is exhausted.
    fn item(&self, n: u64) -> Option<(f64, u64, HandSample, [f32; 4])> {
        match &self.prepared {
            Prepared::Sway { rate_hz } => {
                let t = n as f64 / rate_hz;
                let us = (n as f64 * 1e6 / rate_hz).round() as u64;
                let (hand, flex) = sway_sample(t);
                Some((t, us, hand, flex))
            }
            Prepared::Samples { samples, looped, period_s } => {
                let len = samples.len() as u64;
                let (k, i) = (n / len, (n % len) as usize);
                if k > 0 && !looped {
                    return None;
                }
                let s = samples[i];
                let t_dev = s.t + k as f64 * period_s;
                let us = (t_dev * 1e6).round() as u64;
                Some((t_dev - samples[0].t, us, s, [0.0; 4]))
            }
        }
    }

    /// Runs until the source ends or `stop` is set.
    pub(crate) fn run(self, sink: &mut dyn ReportSink, stop: &AtomicBool, stats: &VhidStats) {
        let mut rng = SmallRng::seed_from_u64(self.faults.seed);
        if !sleep_until(Instant::now() + self.start_delay, stop) {
            return;
        }
        let start = Instant::now();
        let mut plugged = true;
        let mut seq: u32 = 0;
        let mut n: u64 = 0;
        let mut last_monotonic_us = None;
        while let Some((offset_s, time_us, hand, flex)) = self.item(n) {
            n += 1;
            let jitter =
                if self.faults.jitter_us > 0 { rng.random_range(0..=self.faults.jitter_us) } else { 0 };
            let due = start + Duration::from_secs_f64(offset_s) + Duration::from_micros(u64::from(jitter));
            if !sleep_until(due, stop) {
                return;
            }
            let this_seq = seq;
            if Instant::now().saturating_duration_since(due) > LATE_LIMIT {
                seq = seq.wrapping_add(1);
                stats.late_skipped.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            seq = seq.wrapping_add(1);
            if let Some(u) = self.faults.unplug {
                let now_unplugged = u.unplugged_at((offset_s * 1000.0) as u64);
                if now_unplugged == plugged {
                    plugged = !now_unplugged;
                    if !plugged {
                        stats.unplugs.fetch_add(1, Ordering::Relaxed);
                    }
                    sink.set_plugged(plugged);
                }
            }
            if !plugged {
                stats.unplugged_lost.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            if self.faults.stall.is_some_and(|s| s.unplugged_at((offset_s * 1000.0) as u64)) {
                stats.stalled.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            if self.faults.drop_prob > 0.0 && rng.random_bool(self.faults.drop_prob) {
                stats.dropped.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            let device_time_us = match self.clock {
                // The device's microsecond counter wraps.
                DeviceClock::Schedule => match self.faults.time_jump {
                    Some(j) => j.apply((offset_s * 1000.0) as u64, time_us) as u32,
                    None => time_us as u32,
                },
                DeviceClock::Monotonic => {
                    let t = advancing_us(monotonic_us_u32(), last_monotonic_us);
                    last_monotonic_us = Some(t);
                    t
                }
            };
            let (report, clamped) =
                GloveReport::from_degrees(this_seq, device_time_us, &hand, flex, STATUS_TRACKING_OK);
            if clamped {
                stats.clamped.fetch_add(1, Ordering::Relaxed);
            }
            let mut bytes = encode_report(&report);
            if self.faults.corrupt_prob > 0.0 && rng.random_bool(self.faults.corrupt_prob) {
                let at = rng.random_range(0..REPORT_LEN);
                bytes[at] ^= rng.random_range(1..=255u8);
                stats.corrupted.fetch_add(1, Ordering::Relaxed);
            }
            sink.send(&bytes);
            stats.sent.fetch_add(1, Ordering::Relaxed);
        }
        if !plugged {
            sink.set_plugged(true);
        }
        stats.finished.store(true, Ordering::Release);
    }
}

/// How late a report may be sent: later than this it is stale and skipped (no burst of old
/// reports after a pause).
const LATE_LIMIT: Duration = Duration::from_millis(100);

/// Sleeps until `due`, waking at least every 20 ms to check `stop`. Returns false if stopped.
fn sleep_until(due: Instant, stop: &AtomicBool) -> bool {
    loop {
        if stop.load(Ordering::Acquire) {
            return false;
        }
        let now = Instant::now();
        if now >= due {
            return true;
        }
        std::thread::sleep((due - now).min(Duration::from_millis(20)));
    }
}

/// Spawns the generator on its own thread.
pub(crate) fn spawn_generator(
    generator: Generator,
    mut sink: Box<dyn ReportSink>,
    stop: Arc<AtomicBool>,
    stats: Arc<VhidStats>,
) -> Result<std::thread::JoinHandle<()>, VhidError> {
    std::thread::Builder::new()
        .name("frond-vhid-reports".into())
        .spawn(move || generator.run(sink.as_mut(), &stop, &stats))
        .map_err(VhidError::Thread)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unplug_windows() {
        let once = UnplugPlan { at_ms: 100, duration_ms: 50, every_ms: None };
        assert!(!once.unplugged_at(99));
        assert!(once.unplugged_at(100));
        assert!(once.unplugged_at(149));
        assert!(!once.unplugged_at(150));
        assert!(!once.unplugged_at(1100));
        let periodic = UnplugPlan { every_ms: Some(1000), ..once };
        assert!(periodic.unplugged_at(1120));
        assert!(!periodic.unplugged_at(1150));
    }

    #[test]
    fn a_time_jump_shifts_the_clock_inside_its_window_only() {
        let forward = TimeJump { at_ms: 100, duration_ms: 50, by_us: 1_000_000_000 };
        assert_eq!(forward.apply(99, 99_000), 99_000);
        assert_eq!(forward.apply(100, 100_000), 1_000_100_000);
        assert_eq!(forward.apply(149, 149_000), 1_000_149_000);
        assert_eq!(forward.apply(150, 150_000), 150_000);
        // Back past zero: wraps, as the device's counter does (the daemon sees a jump either way).
        let back = TimeJump { by_us: -200_000, ..forward };
        assert_eq!(back.apply(120, 120_000) as u32, (120_000u64.wrapping_sub(200_000)) as u32);
    }

    #[test]
    fn sway_stays_inside_the_glove_range() {
        for n in 0..20_000 {
            let (h, f) = sway_sample(n as f64 * 0.01);
            for v in h.wrist_deg.iter().chain(&h.thumb_deg).chain(&f) {
                assert!(v.abs() < 60.0, "{v}");
            }
        }
    }

    /// Keeps every report with the host time just before and just after it was handed over.
    struct Capture(Vec<([u8; REPORT_LEN], u32)>);

    impl ReportSink for Capture {
        fn send(&mut self, report: &[u8; REPORT_LEN]) {
            let after = monotonic_us_u32();
            self.0.push((*report, after));
        }
        fn set_plugged(&mut self, _plugged: bool) {}
    }

    fn report_time(bytes: &[u8; REPORT_LEN]) -> u32 {
        let at = crate::glove::TIME_OFFSET;
        u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
    }

    fn play(clock: DeviceClock, rate_hz: f64, reports: usize) -> (u32, Vec<([u8; REPORT_LEN], u32)>) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("hand.jsonl");
        let lines: String = (0..reports)
            .map(|i| format!("{{\"t\":{},\"wrist\":[1,2,3],\"thumb\":[4,5,6]}}\n", 1.0 + i as f64 / rate_hz))
            .collect();
        std::fs::write(&path, lines).unwrap();
        let config = VirtualGloveConfig {
            source: GloveSource::Jsonl { path, looped: false },
            clock,
            ..VirtualGloveConfig::sway(rate_hz)
        };
        let generator = Generator::prepare(&config).unwrap();
        let mut sink = Capture(Vec::new());
        let before = monotonic_us_u32();
        generator.run(&mut sink, &AtomicBool::new(false), &VhidStats::default());
        (before, sink.0)
    }

    #[test]
    fn a_stamp_advances_past_the_one_before() {
        assert_eq!(advancing_us(500, None), 500);
        assert_eq!(advancing_us(501, Some(500)), 501);
        assert_eq!(advancing_us(500, Some(500)), 501);
        assert_eq!(advancing_us(499, Some(500)), 501);
        // Across the counter's wrap: 3 is 5 us after u32::MAX - 1; u32::MAX is not after 2.
        assert_eq!(advancing_us(3, Some(u32::MAX - 1)), 3);
        assert_eq!(advancing_us(u32::MAX, Some(2)), 3);
        assert_eq!(advancing_us(0, Some(u32::MAX)), 0);
        assert_eq!(advancing_us(u32::MAX, Some(u32::MAX)), 0);
    }

    #[test]
    fn monotonic_stamps_advance_through_a_burst() {
        // A report every microsecond: the generator writes them back to back, many within one
        // microsecond of the clock, and every stamp is still later than the one before.
        let (_, got) = play(DeviceClock::Monotonic, 1_000_000.0, 3_000);
        assert!(got.len() > 100, "{} reports", got.len());
        let stamps: Vec<u32> = got.iter().map(|(bytes, _)| report_time(bytes)).collect();
        for w in stamps.windows(2) {
            assert!(
                w[1].wrapping_sub(w[0]) >= 1 && w[1].wrapping_sub(w[0]) < 1_000_000,
                "{} then {}",
                w[0],
                w[1]
            );
        }
    }

    #[test]
    fn monotonic_clock_stamps_the_host_time_of_the_write() {
        let (start, got) = play(DeviceClock::Monotonic, 500.0, 20);
        assert_eq!(got.len(), 20);
        let mut previous = start;
        for (bytes, after) in &got {
            let t = report_time(bytes);
            // Read after the previous report was handed over and before this one was: the
            // wrapping difference is small and non-negative on both sides.
            assert!(t.wrapping_sub(previous) < 1_000_000, "stamp {t} before {previous}");
            assert!(after.wrapping_sub(t) < 1_000_000, "stamp {t} after the write at {after}");
            previous = t;
        }
        // The reports went out 2 ms apart, and the stamps say so (not the file's 1.0 s + i/500).
        let span = report_time(&got[19].0).wrapping_sub(report_time(&got[0].0));
        assert!((38_000..1_000_000).contains(&span), "span {span} us");
    }

    #[test]
    fn schedule_clock_is_the_default_and_carries_the_file_time() {
        assert_eq!(VirtualGloveConfig::sway(100.0).clock, DeviceClock::Schedule);
        let (_, got) = play(DeviceClock::Schedule, 500.0, 5);
        let times: Vec<u32> = got.iter().map(|(b, _)| report_time(b)).collect();
        assert_eq!(times, vec![1_000_000, 1_002_000, 1_004_000, 1_006_000, 1_008_000]);
    }

    #[test]
    fn bad_configs_are_refused() {
        let mut c = VirtualGloveConfig::sway(9000.0);
        assert!(matches!(Generator::prepare(&c), Err(VhidError::Config(_))));
        c = VirtualGloveConfig::sway(100.0);
        c.faults.drop_prob = 1.5;
        assert!(matches!(Generator::prepare(&c), Err(VhidError::Config(_))));
    }
}
