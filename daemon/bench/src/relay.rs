//! The baseline that `osc_latency`, `hidraw_latency` and `daemon_resources` hold `frondd` to:
//! `frond-relay` (a do-nothing relay built without frond's code, `src/bin/frond-relay.rs`) fed the
//! same input as `frondd`, forwarding each datagram or report unchanged to as many readers as
//! `frondd` has subscribers. The readers are threads of this process, each on its own Unix
//! socket, as [`crate::latency::Subscribers`] are for `frondd`; each turns the bytes it receives
//! into a latency with a [`Stamp`], reading the clock at receipt.

use std::io::{BufRead, BufReader, Read};
use std::os::unix::net::UnixStream;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use frond_protocol::LatencySummary;
use frondd::stats::LatencyHistogram;

use crate::Options;
use crate::error::BenchError;
use crate::latency::timed_out;
use crate::procs::{Proc, find_bin};
use crate::report::{Bound, Measurement};

/// The latency (ns) of the forwarded bytes at the moment they were received: receipt time minus
/// the send time the bytes carry, on one clock; `None` if the bytes carry none.
pub type Stamp = fn(&[u8]) -> Option<u64>;

/// A running `frond-relay` and its readers.
pub struct Relay {
    proc: Proc,
    recording: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    hist: Arc<LatencyHistogram>,
    frames: Vec<Arc<AtomicU64>>,
    readers: Vec<JoinHandle<()>>,
    _dir: tempfile::TempDir,
}

impl Relay {
    /// Starts `frond-relay SOURCE` (`udp:ADDR` or `hidraw:PATH`) with `n` readers and waits
    /// until they are all connected. Nothing is recorded until [`Relay::record`].
    pub fn start(o: &Options, source: &str, n: usize, stamp: Stamp) -> Result<Relay, BenchError> {
        let dir = tempfile::Builder::new().prefix("frond-bench-relay-").tempdir()?;
        let path = dir.path().join("relay.sock");
        let mut child = Command::new(find_bin(o, "frond-relay")?)
            .arg(source)
            .arg(&path)
            .arg(n.to_string())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(BenchError::start("frond-relay"))?;
        let mut out =
            BufReader::new(child.stdout.take().ok_or(BenchError::NoPipe("frond-relay has no stdout"))?);
        let mut relay = Relay {
            proc: Proc { child },
            recording: Arc::new(AtomicBool::new(false)),
            stop: Arc::new(AtomicBool::new(false)),
            hist: Arc::new(LatencyHistogram::new()),
            frames: Vec::new(),
            readers: Vec::new(),
            _dir: dir,
        };
        let mut line = String::new();
        out.read_line(&mut line)?;
        if line.trim() != "listening" {
            return Err(BenchError::Peer(format!(
                "frond-relay {source} said {line:?} instead of listening (see its error above)"
            )));
        }
        for _ in 0..n {
            let s = UnixStream::connect(&path).map_err(BenchError::at(&path))?;
            relay.spawn_reader(s, stamp)?;
        }
        line.clear();
        out.read_line(&mut line)?;
        if line.trim() != "ready" {
            return Err(BenchError::Peer(format!("frond-relay said {line:?} instead of ready")));
        }
        Ok(relay)
    }

    fn spawn_reader(&mut self, mut s: UnixStream, stamp: Stamp) -> Result<(), BenchError> {
        s.set_read_timeout(Some(Duration::from_millis(200)))?;
        let (hist, stop, recording) = (self.hist.clone(), self.stop.clone(), self.recording.clone());
        let frames = Arc::new(AtomicU64::new(0));
        self.frames.push(frames.clone());
        self.readers.push(thread::spawn(move || {
            let mut buf = vec![0u8; 65_536];
            while !stop.load(Relaxed) {
                let mut len = [0u8; 4];
                match s.read_exact(&mut len) {
                    Ok(()) => {}
                    Err(e) if timed_out(&e) => continue,
                    Err(_) => return,
                }
                let len = (u32::from_le_bytes(len) as usize).min(buf.len());
                if s.read_exact(&mut buf[..len]).is_err() {
                    return;
                }
                let latency = stamp(&buf[..len]);
                frames.fetch_add(1, Relaxed);
                if let Some(ns) = latency.filter(|_| recording.load(Relaxed)) {
                    hist.record(ns);
                }
            }
        }));
        Ok(())
    }

    /// The relay's pid.
    pub fn pid(&self) -> u32 {
        self.proc.pid()
    }

    /// Starts or stops recording latencies.
    pub fn record(&self, on: bool) {
        self.recording.store(on, Relaxed);
    }

    /// Waits until every reader has received something (the input is flowing).
    pub fn wait_flowing(&self, within: Duration) -> Result<(), BenchError> {
        let deadline = Instant::now() + within;
        while self.frames.iter().any(|f| f.load(Relaxed) == 0) {
            if Instant::now() > deadline {
                return Err(BenchError::NoData(format!(
                    "not every one of frond-relay's {} readers received a report within {within:?}",
                    self.frames.len()
                )));
            }
            thread::sleep(Duration::from_millis(10));
        }
        Ok(())
    }

    /// Stops the readers; the latencies they recorded.
    pub fn finish(mut self) -> LatencySummary {
        self.stop_readers();
        self.hist.summary()
    }

    fn stop_readers(&mut self) {
        self.stop.store(true, Relaxed);
        for r in self.readers.drain(..) {
            let _ = r.join();
        }
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop_readers();
    }
}

/// The rows of a latency section held to the relay: `frondd`'s p50 and p99 beside the relay's
/// with as many readers, with the targets (p50 within 1.3x, p99 within 2x). `name` is the
/// rows' stem (`osc_to_subscriber`), `what` the path in words (`OSC-to-subscriber`).
pub fn against_relay(
    name: &str,
    what: &str,
    n: usize,
    frondd: &LatencySummary,
    relay: &LatencySummary,
) -> Result<Vec<Measurement>, BenchError> {
    if frondd.samples == 0 || relay.samples == 0 {
        return Err(BenchError::NoData(format!(
            "{what}: no samples with {n} readers (frondd {}, relay {})",
            frondd.samples, relay.samples
        )));
    }
    let rows = [("p50", frondd.p50_us, relay.p50_us, 1.3), ("p99", frondd.p99_us, relay.p99_us, 2.0)];
    Ok(rows
        .into_iter()
        .map(|(q, fv, rv, limit)| {
            Measurement::new(
                format!("{name}_{q}_{n}_subscribers"),
                "us",
                fv,
                format!("frond-relay to {n} readers, {q}"),
                rv,
            )
            .with_target(
                format!("{what} {q} <= {limit}x the relay's, {n} subscribers"),
                Bound::MaxRatio,
                limit,
            )
        })
        .collect())
}
