//! Section 10's part `page_hand`: a hand sample to the first plant moving on the page (issue
//! 48). The virtual glove plays scripted wrist swipes through its FUSE hidraw node
//! (`FuseGlove`, as section 8 reads it), `frondd` reads it at 1 kHz and plays a field of 1,000,
//! 10,000 and (not in quick mode) 100,000 plants that the swipes steer (seed 000, section 6.3:
//! each swipe sets the field's heading, speed and scale), `frond-console` passes the field on
//! and headless Chromium draws it, as part `page` ([`crate::field_page`]) does.
//!
//! For each swipe: t0 is when the glove wrote the report that completed it (the report's
//! `CLOCK_MONOTONIC` stamp; the node wakes `frondd`'s poll with it, section 8 measures that
//! hop); the report is found by running the daemon's swipe detector (`SwipeDetector` with its
//! default thresholds, as the field stage runs it) over the calibrated hand samples the daemon
//! published, one pose per report in its order, and checked against the field frames: the first
//! frame published after it must carry the heading the swipe set, changed from the frame before.
//! t1 is the wall-clock time of the first page frame drawn (its pixels read back) with a field
//! frame carrying those controls. Also reported: the daemon's share, t0 to that field frame's
//! publish (`host_monotonic_ns`), which is mostly the wait for the next of the field's 60 frames a
//! second.

use std::io::Write;
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use frond_motion::HandSample;
use frond_motion::controls::{SwipeDetector, SwipeParams};
use frond_protocol::field::FieldMessage;
use frond_protocol::{ControlRequest, PoseFlags, ServerMessage, read_frame};
use frond_webdriver::Driver;
use frondd::clock::monotonic_ns;
use serde_json::{Value, json};

use crate::Options;
use crate::error::BenchError;
use crate::field_page::{
    Failed, Missing, PartError, SIZES, TAKE, browser, expect_ok, open_page, percentile, start_console,
    start_field, wait_for_field, wall_minus_monotonic_ns,
};
use crate::hidraw_latency::{FuseGlove, fuse_unavailable, report_written_ns};
use crate::latency::timed_out;
use crate::procs::Daemon;
use crate::report::{Bound, Measurement, Section, Status};

/// The part's title.
pub const TITLE: &str = "hand sample (a wrist swipe's last report on the FUSE hidraw glove) -> first plant moving on the console page (software WebGL), and the daemon's share";

/// The glove's report rate, Hz.
const RATE_HZ: f64 = 1000.0;
/// Yaw swept by one swipe, degrees (from `+AMPLITUDE/2` to `-AMPLITUDE/2` and back).
const AMPLITUDE_DEG: f32 = 50.0;
/// How long the wrist moves in one swipe, seconds.
const FLICK_S: f64 = 0.1;

/// One cycle of the glove's script at `RATE_HZ`: a swipe of the wrist's yaw from `+25` to
/// `-25` degrees in `FLICK_S`, held still until `period_s`, then back, held until
/// `2 period_s`. Worked out from [`SwipeParams::default`]: 50 degrees in 0.1 s is 500 deg/s,
/// well over the 150 deg/s that starts a swipe (the speed smoothed at 15 Hz, about 0.09 of the
/// way a sample at 1 kHz, passes it in 4 samples); once the wrist stops the smoothed speed falls
/// under 50 deg/s in about 26 samples, so the swipe ends 26 ms after the flick, 50 degrees long
/// (over the 20 minimum) in about 0.13 s (under the 0.6 s maximum). A yaw falling is a bend
/// towards +X, heading 0; rising, heading 180: every swipe changes the field's heading.
/// `period_s` must leave the swipe time to end (over 0.2 s).
pub fn swipe_script(period_s: f64) -> Vec<HandSample> {
    let n = (2.0 * period_s * RATE_HZ).round() as usize;
    let half = AMPLITUDE_DEG / 2.0;
    (0..n)
        .map(|k| {
            let t = k as f64 / RATE_HZ;
            let (from, local) = if t < period_s { (half, t) } else { (-half, t - period_s) };
            let u = (local / FLICK_S).clamp(0.0, 1.0) as f32;
            HandSample { t, wrist_deg: [0.0, from - 2.0 * from * u, 0.0], thumb_deg: [0.0; 3] }
        })
        .collect()
}

/// A swipe the daemon's detector completed: when the glove wrote its last report, and the
/// heading it set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Completed {
    /// `CLOCK_MONOTONIC` ns of the report's write.
    pub written_ns: u64,
    /// The heading the swipe set, degrees.
    pub direction_deg: f64,
}

/// The swipes [`SwipeDetector`] (default thresholds, as the field stage runs it) completes over
/// `hands`, (write time ns, calibrated sample) in the daemon's order.
pub fn completed_swipes(hands: &[(u64, HandSample)]) -> Vec<Completed> {
    let mut detector = SwipeDetector::new(SwipeParams::default());
    hands
        .iter()
        .filter_map(|(ns, h)| {
            detector.push(h).map(|s| Completed { written_ns: *ns, direction_deg: s.direction_deg })
        })
        .collect()
}

/// A field frame as a subscriber received it: its publish time and the heading in force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameSeen {
    /// `host_monotonic_ns`.
    pub host_ns: u64,
    /// `controls.direction_deg`.
    pub direction_deg: f64,
}

/// What became of one swipe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// No field frame after the report carried the heading the swipe set as a change.
    NotPublished,
    /// Published (the daemon's share, ms) but the page drew no frame with those controls.
    NotShown {
        /// Report write -> field frame published, ms.
        daemon_ms: f64,
    },
    /// Drawn.
    Shown {
        /// Report write -> field frame published, ms.
        daemon_ms: f64,
        /// Report write -> first page frame drawn with the new controls, ms.
        total_ms: f64,
    },
}

/// Pairs each swipe with the field frame that published it and the first page frame drawn with
/// its controls. `frames`: the field frames seen (any order); `drawn`: the page's `[field frame's
/// host_ns, wall-clock ms it was first drawn]` (any order); `wall_minus_mono_ns`: the page's clock
/// minus `CLOCK_MONOTONIC`. A swipe's controls are in force from the first frame after its
/// report carrying its heading (the frame before it carrying another) up to the next frame
/// carrying another heading, or, for the last, up to the last frame seen (later frames' controls
/// are not known).
pub fn hand_to_plant(
    swipes: &[Completed],
    frames: &[FrameSeen],
    drawn: &[(u64, f64)],
    wall_minus_mono_ns: f64,
) -> Vec<Outcome> {
    let mut frames = frames.to_vec();
    frames.sort_by_key(|f| f.host_ns);
    swipes
        .iter()
        .map(|s| {
            let after = frames.partition_point(|f| f.host_ns < s.written_ns);
            // The report is stamped at its write, a little before the loop reads it: one frame
            // published in between keeps the old heading; the next must carry the new one.
            let Some(old) = after.checked_sub(1).map(|k| frames[k].direction_deg) else {
                return Outcome::NotPublished;
            };
            let Some(i) = (after..frames.len().min(after + 2)).find(|&k| frames[k].direction_deg != old)
            else {
                return Outcome::NotPublished;
            };
            if frames[i].direction_deg != s.direction_deg {
                return Outcome::NotPublished;
            }
            let from = frames[i].host_ns;
            let until = (i..frames.len())
                .find(|&k| frames[k].direction_deg != s.direction_deg)
                .map_or(frames[frames.len() - 1].host_ns, |k| frames[k].host_ns - 1);
            let daemon_ms = (from - s.written_ns) as f64 / 1e6;
            let first = drawn
                .iter()
                .filter(|(ns, _)| (from..=until).contains(ns))
                .map(|&(_, wall_ms)| wall_ms)
                .min_by(f64::total_cmp);
            match first {
                None => Outcome::NotShown { daemon_ms },
                Some(wall_ms) => Outcome::Shown {
                    daemon_ms,
                    total_ms: wall_ms - (s.written_ns as f64 + wall_minus_mono_ns) / 1e6,
                },
            }
        })
        .collect()
}

/// What the bench's subscriber keeps while recording: each hand report's write time and
/// calibrated sample, and each field frame.
#[derive(Default)]
struct Seen {
    hands: Vec<(u64, HandSample)>,
    frames: Vec<FrameSeen>,
}

/// A subscriber of poses.sock on its own thread, keeping what it reads while `recording`.
struct Recorder {
    seen: Arc<Mutex<Seen>>,
    recording: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Recorder {
    fn start(socket: &Path) -> Result<Self, BenchError> {
        let mut stream = UnixStream::connect(socket).map_err(BenchError::at(socket))?;
        stream.set_read_timeout(Some(Duration::from_millis(200)))?;
        let (seen, recording, stop) = (
            Arc::new(Mutex::new(Seen::default())),
            Arc::new(AtomicBool::new(false)),
            Arc::new(AtomicBool::new(false)),
        );
        let (s, r, st) = (seen.clone(), recording.clone(), stop.clone());
        let thread = thread::spawn(move || {
            let mut buf = Vec::new();
            while !st.load(Relaxed) {
                let msg = match read_frame::<ServerMessage, _>(&mut stream, &mut buf) {
                    Ok(m) => m,
                    Err(frond_protocol::ReadError::Io(e)) if timed_out(&e) => continue,
                    Err(_) => return,
                };
                if !r.load(Relaxed) {
                    continue;
                }
                let now = monotonic_ns();
                let mut seen = s.lock().unwrap_or_else(|p| p.into_inner());
                match msg {
                    ServerMessage::Pose(p)
                        if !p.flags.contains(PoseFlags::HELD) && !p.flags.contains(PoseFlags::PLAYBACK) =>
                    {
                        let h = HandSample {
                            t: p.hand.t,
                            wrist_deg: p.hand.wrist_deg,
                            thumb_deg: p.hand.thumb_deg,
                        };
                        seen.hands.push((report_written_ns(p.device_time_us as u32, now), h));
                    }
                    ServerMessage::Field(FieldMessage::Frame(f)) => seen.frames.push(FrameSeen {
                        host_ns: f.host_monotonic_ns,
                        direction_deg: f.controls.direction_deg,
                    }),
                    _ => {}
                }
            }
        });
        Ok(Recorder { seen, recording, stop, thread: Some(thread) })
    }

    /// Starts keeping what comes (forgetting what was kept), or stops.
    fn record(&self, on: bool) {
        if on {
            *self.seen.lock().unwrap_or_else(|p| p.into_inner()) = Seen::default();
        }
        self.recording.store(on, Relaxed);
    }

    fn take(&self) -> Seen {
        std::mem::take(&mut *self.seen.lock().unwrap_or_else(|p| p.into_inner()))
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.stop.store(true, Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The part (see the module docs).
pub fn field_hand(o: &Options) -> Section {
    let started = Instant::now();
    let mut section = match measure(o) {
        Ok(s) => s,
        Err(Missing(why)) => Section::unavailable("page_hand", TITLE, Status::NotAvailable, why),
        Err(Failed(e)) => Section::unavailable("page_hand", TITLE, Status::Error, e.to_string()),
    };
    section.seconds = started.elapsed().as_secs_f64();
    section
}

/// One size's swipes: the daemon's share and the whole, ms, sorted, and the counts.
struct SizeRun {
    daemon: Vec<f64>,
    total: Vec<f64>,
    details: Value,
}

fn measure(o: &Options) -> Result<Section, PartError> {
    if let Some(why) = fuse_unavailable() {
        return Err(Missing(why.into()));
    }
    let browser = browser()?;
    // A swipe every `period` s: long enough for the page to draw a frame or two with each one
    // (10,000 plants: 150-400 ms a frame in software here; 100,000: 500+ ms), and not a whole
    // number of the field's 60 frames a second (24.36, 60.36), so that the swipes land at every
    // phase of its publish ticks rather than at one (the daemon's share would be that phase's).
    let (period, swipes) = if o.quick { (0.406, 20) } else { (1.006, 40) };
    let started = Instant::now();
    let scratch = tempfile::Builder::new().prefix("frond-bench-hand-").tempdir().map_err(BenchError::from)?;
    let script = scratch.path().join("swipes.jsonl");
    write_script(&script, &swipe_script(period))?;
    let script_arg = script.to_string_lossy().into_owned();
    let glove = FuseGlove::start(o, &["--play", &script_arg, "--loop"])?;
    let daemon = Daemon::start(o, &["--device", &glove.node, "--rate", "1000", "--rig", "grass"])?;
    // The fields play a take of the glove's own swipes (part `page` records the sway).
    expect_ok(&daemon, &ControlRequest::RecordStart { name: TAKE.into() })?;
    thread::sleep(Duration::from_secs_f64(3.0 * period));
    expect_ok(&daemon, &ControlRequest::RecordStop)?;
    let (_console, url) = start_console(o, &daemon.socket_dir, scratch.path())?;
    let d = open_page(&browser, scratch.path(), &url)?;
    let recorder = Recorder::start(&daemon.poses_socket())?;
    let setup_s = started.elapsed().as_secs_f64();
    let sizes = if o.quick { &SIZES[..2] } else { &SIZES[..] };
    let (mut ms, mut rows) = (Vec::new(), Vec::new());
    let mut first: Option<[f64; 4]> = None;
    for &(r, c) in sizes {
        let n = r * c;
        let field_started = Instant::now();
        start_field(&daemon, r, c, None)?;
        wait_for_field(&d, n, 1, if o.quick { 20 } else { 90 })?;
        let field_ready_s = field_started.elapsed().as_secs_f64();
        let run = measure_size(&d, &recorder, period, swipes)?;
        let fig = [
            percentile(&run.total, 0.5),
            percentile(&run.total, 0.99),
            percentile(&run.daemon, 0.5),
            percentile(&run.daemon, 0.99),
        ];
        match first {
            None => {
                first = Some(fig);
                for (q, k) in [("p50", 0), ("p99", 1)] {
                    ms.push(Measurement::new(
                        format!("page_hand_to_plant_{q}_ms_{n}"),
                        "ms",
                        fig[k],
                        format!(
                            "the daemon's share {q} (report written -> field frame published), {n} plants"
                        ),
                        fig[k + 2],
                    ));
                }
            }
            Some(base) => {
                for (q, k) in [("p50", 0), ("p99", 1)] {
                    ms.push(Measurement::new(
                        format!("page_hand_to_plant_{q}_ms_{n}"),
                        "ms",
                        fig[k],
                        "the same at 1,000 plants",
                        base[k],
                    ));
                }
                let daemon = Measurement::new(
                    format!("page_hand_daemon_p50_ms_{n}"),
                    "ms",
                    fig[2],
                    "the daemon's share at 1,000 plants",
                    base[2],
                );
                ms.push(daemon.with_target(
                    "the daemon's share does not grow with the plants (within 2x of 1,000: the wait for \
                     the next of 60 field frames a second dominates it)",
                    Bound::MaxRatio,
                    2.0,
                ));
                ms.push(Measurement::new(
                    format!("page_hand_daemon_p99_ms_{n}"),
                    "ms",
                    fig[3],
                    "the daemon's share at 1,000 plants",
                    base[3],
                ));
            }
        }
        let mut row = run.details;
        row["plants"] = json!(n);
        row["field_ready_s"] = json!(field_ready_s);
        row["hand_to_plant_ms"] = json!({ "p50": fig[0], "p99": fig[1] });
        row["daemon_ms"] = json!({ "p50": fig[2], "p99": fig[3] });
        rows.push(row);
    }
    let details = json!({
        "sizes": rows, "swipe_period_s": period, "swipes_each": swipes, "glove_rate_hz": RATE_HZ,
        "swipe": { "yaw_deg": AMPLITUDE_DEG, "flick_s": FLICK_S }, "rig": "grass",
        "take": format!("{TAKE} (recorded from the glove's swipes)"),
        "setup_s": setup_s,
    });
    Ok(Section::ok("page_hand", TITLE, ms, details))
}

/// Writes `samples` as a JSONL hand file.
fn write_script(path: &Path, samples: &[HandSample]) -> Result<(), BenchError> {
    let mut text = String::with_capacity(samples.len() * 64);
    for s in samples {
        let line = json!({ "t": s.t, "wrist": s.wrist_deg, "thumb": s.thumb_deg });
        text.push_str(&line.to_string());
        text.push('\n');
    }
    std::fs::File::create(path).and_then(|mut f| f.write_all(text.as_bytes())).map_err(BenchError::at(path))
}

/// Records `swipes` swipes (`period` s apart) and pairs them with the page's frames.
fn measure_size(d: &Driver, recorder: &Recorder, period: f64, swipes: usize) -> Result<SizeRun, BenchError> {
    d.script("globalThis.frondMeadow.latency = []; return 0;");
    recorder.record(true);
    // The detector run here starts at rest: a swipe it sees completing in the first 0.3 s may
    // have begun before (a flick and its end take 0.13 s), where the daemon's detector had
    // moved already; after 0.3 s both have been at rest through a hold.
    let warm = Duration::from_millis(300);
    let window = Duration::from_secs_f64(period * swipes as f64);
    let from = monotonic_ns() + warm.as_nanos() as u64;
    let cutoff = from + window.as_nanos() as u64;
    thread::sleep(warm + window);
    // Only swipes completed within the window count; the page and the field frames are watched
    // until the page has drawn a field frame published a period after it (it draws the newest
    // frame it has, never an older one after a newer), so that the last of them have been drawn
    // or passed over; at most 10 periods (100,000 plants: the page draws every 2-3 s here).
    let tail = Instant::now();
    let shown_after = (cutoff + (period * 1e9) as u64) as f64;
    while tail.elapsed() < Duration::from_secs_f64(10.0 * period) {
        let newest = d.script(
            "const l = globalThis.frondMeadow.latency; return l.reduce((a, p) => Math.max(a, p[0]), 0);",
        );
        if newest.as_f64().is_some_and(|ns| ns >= shown_after) {
            break;
        }
        thread::sleep(Duration::from_millis(100));
    }
    let tail_s = tail.elapsed().as_secs_f64();
    recorder.record(false);
    let got = d.script("const m = globalThis.frondMeadow, l = m.latency; m.latency = null; return l;");
    let offset = wall_minus_monotonic_ns();
    let seen = recorder.take();
    let drawn: Vec<(u64, f64)> = got
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|p| Some((p[0].as_f64()? as u64, p[1].as_f64()?)))
        .collect();
    let completed: Vec<Completed> = completed_swipes(&seen.hands)
        .into_iter()
        .filter(|c| (from..=cutoff).contains(&c.written_ns))
        .collect();
    let outcomes = hand_to_plant(&completed, &seen.frames, &drawn, offset);
    let (mut daemon, mut total, mut not_published, mut not_shown) = (Vec::new(), Vec::new(), 0, 0);
    for o in &outcomes {
        match *o {
            Outcome::NotPublished => not_published += 1,
            Outcome::NotShown { daemon_ms } => {
                not_shown += 1;
                daemon.push(daemon_ms);
            }
            Outcome::Shown { daemon_ms, total_ms } => {
                daemon.push(daemon_ms);
                total.push(total_ms);
            }
        }
    }
    if total.len() < 3 {
        return Err(BenchError::NoData(format!(
            "of {} swipes completed ({} hand reports, {} field frames), {} were drawn, {not_published} \
             not published, {not_shown} not drawn",
            completed.len(),
            seen.hands.len(),
            seen.frames.len(),
            total.len()
        )));
    }
    daemon.sort_by(f64::total_cmp);
    total.sort_by(f64::total_cmp);
    // Reports whose device time (the glove's write stamp) did not advance on the one before:
    // frondd counts each as a discontinuity (a new timeline; its filter is reset).
    let repeated = seen.hands.windows(2).filter(|w| w[1].1.t <= w[0].1.t).count();
    let details = json!({
        "swipes_completed": completed.len(), "drawn": total.len(), "not_published": not_published,
        "not_drawn": not_shown, "hand_reports": seen.hands.len(),
        "hand_reports_time_not_advancing": repeated, "field_frames": seen.frames.len(),
        "page_frames_with_a_new_field_frame": drawn.len(), "watched_after_s": tail_s,
    });
    Ok(SizeRun { daemon, total, details })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_script_makes_one_swipe_per_flick_alternating_heading() {
        // Three cycles of the quick script (six flicks) on the glove's clock.
        let cycle = swipe_script(0.4);
        assert_eq!(cycle.len(), 800);
        let hands: Vec<(u64, HandSample)> = (0..3)
            .flat_map(|k| cycle.iter().map(move |h| (k, *h)))
            .enumerate()
            .map(|(i, (k, h))| (i as u64 * 1_000_000, HandSample { t: h.t + 0.8 * k as f64, ..h }))
            .collect();
        let got = completed_swipes(&hands);
        // The first flick starts from rest at +25 (the detector's first sample): all six count.
        let headings: Vec<f64> = got.iter().map(|c| c.direction_deg).collect();
        assert_eq!(headings, [0.0, 180.0, 0.0, 180.0, 0.0, 180.0], "{got:?}");
        // Each ends after its flick (0.1 s) and before the hold is out: 100-200 ms into its period.
        for (k, c) in got.iter().enumerate() {
            let into_ms = c.written_ns / 1_000_000 - 400 * k as u64;
            assert!((100..200).contains(&into_ms), "swipe {k} ended {into_ms} ms into its period");
        }
    }

    #[test]
    fn swipes_paired_with_frames_and_drawn_frames_by_hand() {
        // Field frames every 10 ms (host ns = ms * 1e6), heading 0 until 30, 180 from 40 to 60,
        // 0 again from 70; the first two listed out of order.
        let f = |ms: u64, d: f64| FrameSeen { host_ns: ms * 1_000_000, direction_deg: d };
        let frames = [
            f(20, 0.0),
            f(10, 0.0),
            f(30, 0.0),
            f(40, 180.0),
            f(50, 180.0),
            f(60, 180.0),
            f(70, 0.0),
            f(80, 0.0),
            f(90, 0.0),
        ];
        let c = |ms: u64, d: f64| Completed { written_ns: ms * 1_000_000, direction_deg: d };
        let swipes = [
            // Written at 25: frame 30 was published before the loop read it (old heading), frame
            // 40 carries 180 -> daemon 15 ms.
            c(25, 180.0),
            // Written at 62: frame 70 carries 0 -> 8 ms; but the page drew nothing of 70..=90.
            c(62, 0.0),
            // Written at 5: no frame before it to show that it changed anything.
            c(5, 180.0),
            // Written at 45: frames 50 and 60 keep 180; the change at 70 is not this report's.
            c(45, 0.0),
            // Written at 85, heading 180: no later frame changes to it.
            c(85, 180.0),
        ];
        // The page's clock is CLOCK_MONOTONIC + 1,000,000 ms. It drew frame 50 at 1,000,120 ms,
        // frame 40 at 1,000,100 (listed after 50: reordered), frame 30 (the old heading) at
        // 1,000,060, and nothing later. The first swipe shows at 1,000,100: 75 ms after
        // 1,000,025.
        let drawn = [(50_000_000, 1_000_120.0), (40_000_000, 1_000_100.0), (30_000_000, 1_000_060.0)];
        let got = hand_to_plant(&swipes, &frames, &drawn, 1e12);
        assert_eq!(
            got,
            [
                Outcome::Shown { daemon_ms: 15.0, total_ms: 75.0 },
                Outcome::NotShown { daemon_ms: 8.0 },
                Outcome::NotPublished,
                Outcome::NotPublished,
                Outcome::NotPublished,
            ]
        );
    }
}
