//! Paced loops: the machine's limit (a bare `clock_nanosleep(TIMER_ABSTIME)` loop), the naive
//! `std::thread::sleep` loop, and frondd's full loop (engine + publisher + subscribers)
//! in-process, each recording wake-up lateness into frondd's own histogram.

use std::io::Read;
use std::os::unix::net::{UnixListener, UnixStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use frond_protocol::{Hello, LatencySummary, PROTOCOL_VERSION};
use frondd::clock::{NS_PER_S, monotonic_ns, sleep_until_ns};
use frondd::engine::{Engine, EngineEnds};
use frondd::publisher::{PublisherConfig, SubscriberRegistry, spawn_acceptor, spawn_publisher};
use frondd::realtime::spawn_loop;
use frondd::stats::{LatencyHistogram, LoopStats};
use serde::Serialize;

use crate::error::BenchError;
use crate::rig::{TickGlove, grass, mapper};

/// SCHED_FIFO priority the bench's loops ask for (when the machine grants it).
pub const BENCH_PRIORITY: u8 = 50;

/// Outcome of running a paced loop.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct LoopRun {
    /// Asked rate.
    pub rate_hz: f64,
    /// Ticks run.
    pub ticks: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// `ticks / seconds`.
    pub achieved_hz: f64,
    /// Wake-up lateness percentiles.
    pub lateness: LatencySummary,
    /// Ticks that ended more than a period behind (full loop: frondd's own overrun count).
    pub overruns: u64,
}

impl LoopRun {
    /// Sustainable: the loop keeps its rate and p99 lateness stays under one period.
    pub fn sustainable(&self) -> bool {
        let period_us = 1e6 / self.rate_hz;
        self.achieved_hz >= 0.98 * self.rate_hz && self.lateness.p99_us < period_us
    }

    fn merge(runs: &[(u64, f64)], hist: &LatencyHistogram, rate_hz: f64, overruns: u64) -> LoopRun {
        let ticks: u64 = runs.iter().map(|r| r.0).sum();
        let seconds: f64 = runs.iter().map(|r| r.1).sum();
        LoopRun {
            rate_hz,
            ticks,
            seconds,
            achieved_hz: ticks as f64 / seconds.max(1e-9),
            lateness: hist.summary(),
            overruns,
        }
    }
}

/// Asks for SCHED_FIFO on the calling thread; returns what was obtained.
pub fn set_fifo(priority: u8) -> Result<(), BenchError> {
    if priority == 0 {
        return Err(BenchError::FifoNotAsked);
    }
    let param = libc::sched_param { sched_priority: i32::from(priority) };
    // SAFETY: `param` is a valid sched_param; pid 0 is the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 { Ok(()) } else { Err(std::io::Error::last_os_error().into()) }
}

/// Whether this process may use SCHED_FIFO (probed on a short-lived thread).
pub fn probe_fifo(priority: u8) -> Result<(), BenchError> {
    thread::spawn(move || set_fifo(priority)).join().unwrap_or(Err(BenchError::Panicked("probe thread")))
}

/// Which loop to pace.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// `clock_nanosleep(TIMER_ABSTIME)` on absolute deadlines, no work: the machine's limit.
    Bare,
    /// `std::thread::sleep(period)` after each tick: the naive loop. Lateness is the oversleep
    /// of each sleep; its drift shows in the achieved rate.
    NaiveSleep,
}

/// One slice of a bare or naive loop on a fresh thread; records into `hist`. Returns
/// `(ticks, seconds)`.
fn pace_slice(
    pacing: Pacing,
    rate_hz: f64,
    dur: Duration,
    priority: u8,
    stats: Arc<LoopStats>,
) -> (u64, f64) {
    thread::Builder::new()
        .name("bench-loop".into())
        .spawn(move || {
            let _ = set_fifo(priority);
            let period = (NS_PER_S as f64 / rate_hz) as u64;
            let start = monotonic_ns();
            let end = start + dur.as_nanos() as u64;
            let mut ticks = 0u64;
            let mut deadline = start + period;
            let mut now = start;
            while now < end {
                match pacing {
                    Pacing::Bare => {
                        sleep_until_ns(deadline);
                        now = monotonic_ns();
                        stats.lateness.record(now.saturating_sub(deadline));
                        deadline += period;
                        if now >= deadline + period {
                            deadline += (now - deadline) / period * period;
                            stats.overruns.fetch_add(1, Relaxed);
                        }
                    }
                    Pacing::NaiveSleep => {
                        let before = monotonic_ns();
                        thread::sleep(Duration::from_nanos(period));
                        now = monotonic_ns();
                        stats.lateness.record(now.saturating_sub(before + period));
                    }
                }
                ticks += 1;
            }
            (ticks, (monotonic_ns() - start) as f64 / 1e9)
        })
        .expect("spawn a bench loop thread")
        .join()
        .expect("bench loop thread")
}

/// Accumulates slices of one loop kind (lateness and overruns in frondd's [`LoopStats`]).
pub struct Accum {
    stats: Arc<LoopStats>,
    slices: Vec<(u64, f64)>,
    rate_hz: f64,
}

impl Accum {
    /// Empty, for loops at `rate_hz`.
    pub fn new(rate_hz: f64) -> Self {
        Accum { stats: Arc::new(LoopStats::default()), slices: Vec::new(), rate_hz }
    }

    /// Runs one slice of a bare or naive loop.
    pub fn pace(&mut self, pacing: Pacing, dur: Duration, priority: u8) {
        let s = pace_slice(pacing, self.rate_hz, dur, priority, self.stats.clone());
        self.slices.push(s);
    }

    /// Runs one slice of the full loop.
    pub fn full(&mut self, full: &mut FullLoop, dur: Duration, priority: u8) -> Result<(), BenchError> {
        let slice = full.run(self.rate_hz, dur, priority, &self.stats)?;
        self.slices.push(slice);
        Ok(())
    }

    /// The merged result.
    pub fn result(&self) -> LoopRun {
        LoopRun::merge(&self.slices, &self.stats.lateness, self.rate_hz, self.stats.overruns.load(Relaxed))
    }
}

/// frondd's full loop in this process: the engine (read, calibrate, filter, map, publish) paced
/// by frondd's own `spawn_loop`, publishing to `subscribers` Unix-socket clients that read every
/// byte, on frondd's direct lanes (with its publisher thread behind them for a slow subscriber).
pub struct FullLoop {
    engine: Option<Engine>,
    publisher: Option<thread::JoinHandle<()>>,
    _dir: tempfile::TempDir,
    stop_all: Arc<AtomicBool>,
    acceptor: Option<JoinHandle<()>>,
    clients: Vec<JoinHandle<()>>,
    received: Arc<AtomicU64>,
    _ends: EngineEnds,
    registry: Arc<SubscriberRegistry>,
}

impl FullLoop {
    /// Builds the engine, publisher and `subscribers` connected clients.
    pub fn new(subscribers: usize) -> Result<FullLoop, BenchError> {
        let dir = tempfile::Builder::new().prefix("frond-bench-").tempdir()?;
        let (engine, mut ends) = Engine::with_channels(
            mapper(),
            Some(Box::new(TickGlove::new())),
            250_000_000,
            frondd::publisher::PUBLISH_QUEUE_FRAMES,
            16,
        );
        let publish_rx = std::mem::replace(&mut ends.frames, crossbeam_channel::never());
        let slow_rx = std::mem::replace(&mut ends.slow, crossbeam_channel::never());
        let path = dir.path().join(frond_protocol::POSES_SOCKET);
        let listener = UnixListener::bind(&path).map_err(BenchError::at(&path))?;
        let stop_all = Arc::new(AtomicBool::new(false));
        let registry = Arc::new(SubscriberRegistry::default());
        let rig = grass();
        let hello = Hello {
            protocol_version: PROTOCOL_VERSION,
            daemon_version: env!("CARGO_PKG_VERSION").into(),
            rig_name: "grass".into(),
            joint_names: rig.joint_names(),
            tick_rate_hz: 1000,
            elements: Default::default(),
            next_seq: 0,
        };
        let config = PublisherConfig {
            queue_frames: 1024,
            write_timeout: Duration::from_secs(2),
            max_subscribers: 64,
        };
        let publisher =
            spawn_publisher(publish_rx, ends.publish_wake.clone(), slow_rx, Default::default(), config)?;
        let acceptor = spawn_acceptor(
            listener,
            config,
            ends.commands.clone(),
            Arc::new(move || hello.clone()),
            registry.clone(),
            stop_all.clone(),
        )?;
        let received = Arc::new(AtomicU64::new(0));
        let mut clients = Vec::new();
        for _ in 0..subscribers {
            let stream = UnixStream::connect(&path).map_err(BenchError::at(&path))?;
            let received = received.clone();
            clients.push(thread::spawn(move || drain(stream, &received)));
        }
        let mut full = FullLoop {
            engine: Some(engine),
            _dir: dir,
            stop_all,
            acceptor: Some(acceptor),
            publisher: Some(publisher),
            clients,
            received,
            _ends: ends,
            registry,
        };
        // Warm up until every subscriber is registered and receiving.
        let deadline = Instant::now() + Duration::from_secs(10);
        let warm = Arc::new(LoopStats::default());
        while full.registry.snapshot().iter().filter(|s| s.sent > 0).count() < subscribers {
            if Instant::now() > deadline {
                return Err(BenchError::NoData(format!(
                    "only {} of {subscribers} subscribers connected",
                    full.registry.snapshot().len()
                )));
            }
            full.run(1000.0, Duration::from_millis(50), 0, &warm)?;
        }
        Ok(full)
    }

    /// Bytes the clients have read.
    pub fn received_bytes(&self) -> u64 {
        self.received.load(Relaxed)
    }

    /// Runs frondd's loop thread at `rate_hz` for `dur`, recording lateness and overruns into
    /// `stats`. Returns `(ticks, seconds)`.
    pub fn run(
        &mut self,
        rate_hz: f64,
        dur: Duration,
        priority: u8,
        stats: &Arc<LoopStats>,
    ) -> Result<(u64, f64), BenchError> {
        let engine = self.engine.take().ok_or(BenchError::EngineLost)?;
        let ticks_before = stats.lateness.count();
        let stop = Arc::new(AtomicBool::new(false));
        let start = monotonic_ns();
        let (handle, _report) =
            spawn_loop(engine, rate_hz.round() as u32, priority, stats.clone(), stop.clone())?;
        thread::sleep(dur);
        stop.store(true, Relaxed);
        let engine = handle.join().map_err(|_| BenchError::Panicked("the loop thread"))?;
        let seconds = (monotonic_ns() - start) as f64 / 1e9;
        self.engine = Some(engine);
        Ok((stats.lateness.count() - ticks_before, seconds))
    }
}

impl Drop for FullLoop {
    fn drop(&mut self) {
        self.stop_all.store(true, Relaxed);
        // Wake the acceptor, which otherwise looks at `stop_all` only every `STOP_POLL`.
        let _ = UnixStream::connect(self._dir.path().join(frond_protocol::POSES_SOCKET));
        // Dropping the engine closes the publisher's queue: it ends and closes the sockets, and
        // the clients see end-of-file.
        self.engine = None;
        if let Some(p) = self.publisher.take() {
            let _ = p.join();
        }
        if let Some(a) = self.acceptor.take() {
            let _ = a.join();
        }
        for c in self.clients.drain(..) {
            let _ = c.join();
        }
    }
}

fn drain(mut stream: UnixStream, received: &AtomicU64) {
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => {
                received.fetch_add(n as u64, Relaxed);
            }
        }
    }
}
