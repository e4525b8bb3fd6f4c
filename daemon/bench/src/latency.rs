//! Section 2: latency from the virtual glove's report write to a subscriber's receipt, across
//! processes (`frond-vhid --clock monotonic` -> FUSE hidraw node -> `frondd` -> poses.sock ->
//! subscriber threads here), against a Unix socket round trip between two threads.

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use frond_protocol::{LatencySummary, PoseFlags, ServerMessage, read_frame};
use frond_vhid::monotonic_us_u32;
use frondd::clock::{monotonic_ns, sleep_until_ns};
use frondd::stats::LatencyHistogram;
use serde_json::json;

use crate::Options;
use crate::error::BenchError;
use crate::procs::{Daemon, start_vhid};
use crate::report::{Bound, Measurement, Section};

/// No phase is being recorded.
const IDLE: usize = usize::MAX;

/// Histograms of one recording phase.
#[derive(Default)]
pub struct PhaseHists {
    /// Glove write -> receipt (needs `--clock monotonic`).
    pub glove_to_receipt: LatencyHistogram,
    /// Daemon stamp (`host_monotonic_ns`) -> receipt.
    pub publish_to_receipt: LatencyHistogram,
    /// Glove write -> daemon stamp (waiting for the tick, reading, mapping).
    pub glove_to_publish: LatencyHistogram,
}

/// Whether a read on a socket with a read timeout only timed out (nothing arrived): the reader
/// checks whether it is to stop and reads again.
pub fn timed_out(e: &std::io::Error) -> bool {
    matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut)
}

/// Subscribers reading poses.sock on their own threads, recording into the active phase.
pub struct Subscribers {
    phase: Arc<AtomicUsize>,
    hists: Arc<Vec<PhaseHists>>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    frames: Vec<Arc<AtomicU64>>,
}

impl Subscribers {
    /// Ready for `phases` recording phases.
    pub fn new(phases: usize) -> Self {
        Subscribers {
            phase: Arc::new(AtomicUsize::new(IDLE)),
            hists: Arc::new((0..phases).map(|_| PhaseHists::default()).collect()),
            stop: Arc::new(AtomicBool::new(false)),
            threads: Vec::new(),
            frames: Vec::new(),
        }
    }

    /// Connects until `n` subscribers read `socket`, and waits until each has a pose.
    pub fn grow_to(&mut self, socket: &Path, n: usize) -> Result<(), BenchError> {
        while self.threads.len() < n {
            let mut stream = UnixStream::connect(socket).map_err(BenchError::at(socket))?;
            stream.set_read_timeout(Some(Duration::from_millis(200)))?;
            let (phase, hists, stop) = (self.phase.clone(), self.hists.clone(), self.stop.clone());
            let frames = Arc::new(AtomicU64::new(0));
            self.frames.push(frames.clone());
            self.threads.push(thread::spawn(move || {
                let mut buf = Vec::new();
                while !stop.load(Relaxed) {
                    let msg = match read_frame::<ServerMessage, _>(&mut stream, &mut buf) {
                        Ok(m) => m,
                        Err(frond_protocol::ReadError::Io(e)) if timed_out(&e) => continue,
                        Err(_) => return,
                    };
                    let (now_us, now_ns) = (monotonic_us_u32(), monotonic_ns());
                    let ServerMessage::Pose(p) = msg else { continue };
                    frames.fetch_add(1, Relaxed);
                    let i = phase.load(Relaxed);
                    if i == IDLE || p.flags.contains(PoseFlags::HELD) {
                        continue;
                    }
                    let h = &hists[i];
                    let device_us = p.device_time_us as u32;
                    h.glove_to_receipt.record(u64::from(now_us.wrapping_sub(device_us)) * 1000);
                    h.publish_to_receipt.record(now_ns.saturating_sub(p.host_monotonic_ns));
                    let stamp_us = (p.host_monotonic_ns / 1000) as u32;
                    h.glove_to_publish.record(u64::from(stamp_us.wrapping_sub(device_us)) * 1000);
                }
            }));
        }
        let deadline = Instant::now() + Duration::from_secs(10);
        while self.frames.iter().any(|f| f.load(Relaxed) == 0) {
            if Instant::now() > deadline {
                return Err(BenchError::NoData(format!(
                    "not every one of {n} subscribers received a pose within 10 s"
                )));
            }
            thread::sleep(Duration::from_millis(10));
        }
        Ok(())
    }

    /// Records into phase `i` (or none with [`None`]).
    pub fn record(&self, i: Option<usize>) {
        self.phase.store(i.unwrap_or(IDLE), Relaxed);
    }

    /// Histograms of phase `i`.
    pub fn hists(&self, i: usize) -> &PhaseHists {
        &self.hists[i]
    }

    /// Poses received by all subscribers.
    pub fn frames(&self) -> u64 {
        self.frames.iter().map(|f| f.load(Relaxed)).sum()
    }
}

impl Drop for Subscribers {
    fn drop(&mut self) {
        self.stop.store(true, Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Round trips of a 64-byte message between two threads over a Unix socket pair, one every
/// millisecond (like the glove's reports) for `dur`, recorded into `hist`.
pub fn socket_round_trips(dur: Duration, hist: &LatencyHistogram) -> Result<(), BenchError> {
    let (mut a, mut b) = UnixStream::pair()?;
    let echo = thread::spawn(move || {
        let mut msg = [0u8; 64];
        while b.read_exact(&mut msg).is_ok() {
            if b.write_all(&msg).is_err() {
                return;
            }
        }
    });
    let mut msg = [0u8; 64];
    let period = 1_000_000;
    let end = monotonic_ns() + dur.as_nanos() as u64;
    let mut deadline = monotonic_ns() + period;
    while deadline < end {
        sleep_until_ns(deadline);
        deadline += period;
        let t0 = monotonic_ns();
        msg[..8].copy_from_slice(&t0.to_le_bytes());
        a.write_all(&msg)?;
        a.read_exact(&mut msg)?;
        hist.record(monotonic_ns() - t0);
    }
    drop(a);
    let _ = echo.join();
    Ok(())
}

fn summary(h: &LatencyHistogram) -> LatencySummary {
    h.summary()
}

/// How the virtual glove reaches `frondd` in a latency run.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Transport {
    /// The glove's generator inside `frondd`, ringing an eventfd per report: one wake-up per
    /// report, as a kernel hidraw node gives (the kernel wakes the reader from the device's
    /// interrupt). Carries the target.
    InProcess,
    /// `frond-vhid` serving a FUSE hidraw node in its own process, read through hidapi: every
    /// poll and read is a round trip to that process, which a kernel node does not have.
    Fuse,
}

impl Transport {
    fn prefix(self) -> &'static str {
        match self {
            Transport::InProcess => "",
            Transport::Fuse => "fuse_",
        }
    }
}

/// Section 2.
pub fn glove_latency(o: &Options) -> Result<Section, BenchError> {
    const TITLE: &str = "virtual glove report write -> subscriber receipt (glove clock = host CLOCK_MONOTONIC, frondd at 1 kHz) vs Unix socket round trip";
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    let transports: &[Transport] = if Path::new("/dev/fuse").exists() {
        &[Transport::InProcess, Transport::Fuse]
    } else {
        details.insert(
            "fuse".into(),
            json!("not measured: /dev/fuse is absent, so the glove cannot be served as a node"),
        );
        &[Transport::InProcess]
    };
    for &t in transports {
        let (m, d) = glove_latency_over(o, t)?;
        measurements.extend(m);
        details.insert(if t == Transport::Fuse { "fuse" } else { "in_process" }.into(), d);
    }
    details.insert(
        "note".into(),
        json!("glove_to_subscriber_*: the in-process glove, whose report rings the loop's ready descriptor (an eventfd) as a kernel hidraw node would; fuse_glove_to_subscriber_*: frond-vhid's FUSE node in its own process (each poll and read a round trip to it)"),
    );
    Ok(Section::ok("glove_latency", TITLE, measurements, serde_json::Value::Object(details)))
}

fn glove_latency_over(
    o: &Options,
    transport: Transport,
) -> Result<(Vec<Measurement>, serde_json::Value), BenchError> {
    let (slices, slice) =
        if o.quick { (2, Duration::from_millis(300)) } else { (10, Duration::from_secs(1)) };
    let dir = tempfile::Builder::new().prefix("frond-bench-vhid-").tempdir()?;
    let mut _vhid = None;
    let daemon = match transport {
        Transport::Fuse => {
            let node = dir.path().join("glove").join(frond_vhid::NODE_NAME);
            let node_arg = node.to_string_lossy().into_owned();
            let (vhid, node, out) = start_vhid(
                o,
                &[
                    "--sway",
                    "--rate",
                    "1000",
                    "--clock",
                    "monotonic",
                    "--backend",
                    "fuse",
                    "--node",
                    &node_arg,
                ],
            )?;
            _vhid = Some((vhid, out));
            let node = node.to_string_lossy().into_owned();
            Daemon::start(o, &["--device", &node, "--rate", "1000"])?
        }
        Transport::InProcess => {
            let config = dir.path().join("frondd.toml");
            std::fs::write(
                &config,
                "[source]\nkind = \"in-process\"\nvirtual_rate_hz = 1000\nvirtual_clock = \"monotonic\"\n",
            )
            .map_err(BenchError::at(&config))?;
            let config = config.to_string_lossy().into_owned();
            Daemon::start(o, &["--config", &config, "--rate", "1000"])?
        }
    };
    let counts = [1usize, 8, 32];
    let mut subs = Subscribers::new(counts.len());
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    for (i, &n) in counts.iter().enumerate() {
        subs.grow_to(&daemon.poses_socket(), n)?;
        thread::sleep(Duration::from_millis(200));
        let rtt = LatencyHistogram::new();
        for _ in 0..slices {
            socket_round_trips(slice, &rtt)?;
            subs.record(Some(i));
            thread::sleep(slice);
            subs.record(None);
        }
        let h = subs.hists(i);
        let (g, p, gp, r) = (
            summary(&h.glove_to_receipt),
            summary(&h.publish_to_receipt),
            summary(&h.glove_to_publish),
            summary(&rtt),
        );
        if g.samples == 0 {
            return Err(BenchError::NoData(format!("no fresh poses reached the {n} subscribers")));
        }
        measurements.extend(glove_rows(transport, n, &g, &p, &r));
        details.insert(
            format!("{n}_subscribers"),
            json!({
                "glove_to_subscriber": g,
                "glove_to_publish": gp,
                "publish_to_subscriber": p,
                "socket_round_trip": r,
            }),
        );
    }
    let status = daemon.status().ok();
    details.insert("daemon_rate_hz".into(), json!(1000));
    details.insert("glove_rate_hz".into(), json!(1000));
    details.insert("frames_received".into(), json!(subs.frames()));
    details.insert("source".into(), json!(status.as_ref().map(|s| format!("{:?}", s.source))));
    details.insert("device_wakes".into(), json!(status.as_ref().map(|s| s.device_wakes)));
    details.insert("daemon_realtime".into(), json!(status.as_ref().map(|s| s.realtime.clone())));
    Ok((measurements, serde_json::Value::Object(details)))
}

/// Section 2's rows for `n` subscribers over `transport`: glove-to-subscriber `g` at p50, p99
/// and p99.9 and publish-to-subscriber `p` at p99, each beside the socket round trip `r`.
fn glove_rows(
    transport: Transport,
    n: usize,
    g: &LatencySummary,
    p: &LatencySummary,
    r: &LatencySummary,
) -> Vec<Measurement> {
    let prefix = transport.prefix();
    let mut rows = Vec::new();
    for (q, gv, rv) in
        [("p50", g.p50_us, r.p50_us), ("p99", g.p99_us, r.p99_us), ("p999", g.p999_us, r.p999_us)]
    {
        let mut m = Measurement::new(
            format!("{prefix}glove_to_subscriber_{q}_{n}_subscribers"),
            "us",
            gv,
            format!("Unix socket round trip between two threads, {q}"),
            rv,
        );
        if q == "p99" && n == 8 && transport == Transport::InProcess {
            m = m.with_target(
                "glove-to-subscriber p99 <= 3x the raw socket round trip, 8 subscribers",
                Bound::MaxRatio,
                3.0,
            );
        }
        rows.push(m);
    }
    rows.push(Measurement::new(
        format!("{prefix}publish_to_subscriber_p99_{n}_subscribers"),
        "us",
        p.p99_us,
        "Unix socket round trip between two threads, p99",
        r.p99_us,
    ));
    rows
}
