//! Beside section 5 (issue 46): the realtime loop's wake-up lateness and frondd's CPU with a
//! mocap stage's capture triggers and LTC running, against the same daemon without them, each
//! over a window of the same length, one after the other.
//!
//! The stage: frondd follows capture triggers on a loopback port, which a sender here floods
//! with 100 datagrams a second (half of them not trigger messages, half `CaptureStop`s for a
//! take it is not recording: read, parsed, counted, harmless), and reads 25 fps LTC from a file
//! of raw samples made by `frond_ltc::encode`, which it plays in real time and decodes sample
//! by sample. Both run on their own threads; neither may disturb the loop, so the target holds
//! the loop's p99 lateness with them within 1.5x of the plain daemon's.
//!
//! Both daemons replay the same 1 kHz recording (`--replay`), which has no ready descriptor, so
//! the loop wakes on its deadline every period and every tick's lateness is recorded. (With a
//! source that has a descriptor, such as the in-process glove, a report covers most ticks and
//! they record no lateness: a quick run could end with none at all, and a p99 of nothing.)

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::thread;
use std::time::{Duration, Instant};

use frond_ltc::FrameRate;
use serde_json::{Value, json};

use crate::Options;
use crate::daemon_run::{DaemonRun, measure_daemon, run_json};
use crate::error::BenchError;
use crate::osc_latency::{free_port, loopback};
use crate::report::{Bound, Measurement};

/// LTC sample rate of the file, Hz.
const RATE_HZ: u32 = 48_000;

/// Writes `seconds` of 25 fps LTC from 10:00:00:00 as raw s16le mono samples at [`RATE_HZ`].
fn ltc_file(path: &Path, seconds: u32) -> Result<(), BenchError> {
    let rate = FrameRate::Fps25;
    let first = rate.frame_count(frond_ltc::SmpteTime {
        hours: 10,
        minutes: 0,
        seconds: 0,
        frames: 0,
        drop_frame: false,
    });
    let frames: Vec<_> =
        frond_ltc::encode::labels(rate, first, seconds * 25).into_iter().map(|t| (t, 0)).collect();
    let edges = frond_ltc::encode::edges(rate, &frames);
    let samples = frond_ltc::encode::render(&edges, RATE_HZ, f64::from(seconds), 0.5);
    let bytes: Vec<u8> =
        samples.iter().flat_map(|s| ((s * f32::from(i16::MAX)) as i16).to_le_bytes()).collect();
    std::fs::write(path, bytes).map_err(BenchError::at(path))
}

/// Sends 100 datagrams a second to `to` until `stop`: every other one a `CaptureStop` for a
/// take frondd is not recording, the rest not trigger messages at all.
fn trigger_flood(to: SocketAddr, stop: Arc<AtomicBool>) -> thread::JoinHandle<Result<u64, BenchError>> {
    thread::spawn(move || {
        let socket = UdpSocket::bind("127.0.0.1:0")?;
        let mut leader = frond_triggers::Leader::new(std::process::id(), 1);
        let mut sent = 0u64;
        let start = Instant::now();
        while !stop.load(Relaxed) {
            const NOT_A_TRIGGER: &[u8] = b"<?xml version=\"1.0\"?><NotATrigger/>\0";
            let datagram = if sent.is_multiple_of(2) {
                leader.stop("bench_no_such_take", None).unwrap_or(NOT_A_TRIGGER)
            } else {
                NOT_A_TRIGGER
            };
            socket.send_to(datagram, to)?;
            sent += 1;
            let due = start + Duration::from_millis(10 * sent);
            thread::sleep(due.saturating_duration_since(Instant::now()));
        }
        Ok(sent)
    })
}

/// The daemon following triggers and reading LTC while it replays `hand`, against `plain`, the
/// same daemon replaying the same file without them (section 5's own run, measured over a
/// window of the same length just before): the rows (lateness p99 with a target, p50 and CPU
/// without) and the details.
pub(crate) fn measure(
    o: &Options,
    dir: &Path,
    hand: &Path,
    plain: &DaemonRun,
    warm: Duration,
    window: Duration,
) -> Result<(Vec<Measurement>, Value), BenchError> {
    let ltc = dir.join("ltc-25fps.raw");
    ltc_file(&ltc, (warm + window).as_secs() as u32 + 5)?;
    let listen = loopback(free_port()?);
    let stop = Arc::new(AtomicBool::new(false));
    let flood = trigger_flood(listen, stop.clone());
    let (listen_arg, ltc_arg) = (listen.to_string(), ltc.to_string_lossy().into_owned());
    let hand_arg = hand.to_string_lossy();
    let synced = measure_daemon(
        o,
        &["--replay", &hand_arg, "--triggers", &listen_arg, "--ltc", &ltc_arg],
        warm,
        window,
    );
    stop.store(true, Relaxed);
    let sent = flood.join().map_err(|_| BenchError::Panicked("the trigger sender"))??;
    let synced = synced?;
    let heard = synced.status.as_ref().and_then(|s| s.triggers.as_ref()).map_or(0, |t| t.received);
    let ltc_state = synced.status.as_ref().and_then(|s| s.ltc.as_ref()).map(|l| l.state.clone());
    if heard == 0 || ltc_state.as_deref() != Some("locked") {
        return Err(BenchError::NoData(format!(
            "the stage did not run: frondd heard {heard} of {sent} trigger datagrams and its LTC is {ltc_state:?}, not locked"
        )));
    }
    let lateness = |r: &DaemonRun, p99: bool| {
        r.status.as_ref().map_or(f64::NAN, |s| if p99 { s.lateness.p99_us } else { s.lateness.p50_us })
    };
    const BASE: &str = "the same daemon (replaying the same 1 kHz recording, 4 subscribers) without triggers or LTC, same window length";
    let rows = vec![
        Measurement::new("stage_sync_lateness_p99_1000hz", "us", lateness(&synced, true), BASE, lateness(plain, true))
            .with_target(
                "loop p99 lateness with capture triggers (100 datagrams/s) and LTC (25 fps) running <= 1.5x without",
                Bound::MaxRatio,
                1.5,
            ),
        Measurement::new("stage_sync_lateness_p50_1000hz", "us", lateness(&synced, false), BASE, lateness(plain, false)),
        Measurement::new("stage_sync_cpu_1000hz", "fraction_of_core", synced.cpu, BASE, plain.cpu),
    ];
    let details = json!({
        "plain": run_json(plain),
        "with_triggers_and_ltc": run_json(&synced),
        "trigger_datagrams": { "sent": sent, "received": heard },
        "ltc": "25 fps from a raw 48 kHz file played in real time by frondd (frond_ltc::encode)",
    });
    Ok((rows, details))
}
