//! Daemon-to-receiver latency: how long after the daemon stamped a frame (`host_monotonic_ns`) a
//! UDP receiver on this host has it, through the whole path (pose socket, SDK, queue, encoding,
//! UDP). The receivers recover the frame's host time from the bundle timetag (the inverse of
//! [`crate::encode::timetag`] with the same clock offset), so they measure what any OSC receiver
//! could measure.

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use frond_motion::quantile::nearest_rank;
use rosc::OscPacket;

use crate::bridge::{Bridge, BridgeConfig, BridgeError, Protocol};
use crate::encode::{ClockOffset, IMMEDIATELY, monotonic_ns};

/// Latency percentiles for one number of targets.
#[derive(Debug, Clone, PartialEq)]
pub struct LatencyReport {
    /// Number of UDP targets (each with its own receiver).
    pub targets: usize,
    /// Frames received over all receivers.
    pub samples: usize,
    /// Frames the bridge received from the daemon per second (the daemon's rate).
    pub input_rate_hz: f64,
    /// Median latency, microseconds.
    pub p50_us: f64,
    /// 99th percentile latency, microseconds.
    pub p99_us: f64,
    /// Largest latency, microseconds.
    pub max_us: f64,
}

impl LatencyReport {
    /// One JSON object (no dependencies needed for this flat shape).
    pub fn to_json(&self) -> String {
        format!(
            r#"{{"targets":{},"samples":{},"input_rate_hz":{:.1},"p50_us":{:.1},"p99_us":{:.1},"max_us":{:.1}}}"#,
            self.targets, self.samples, self.input_rate_hz, self.p50_us, self.p99_us, self.max_us
        )
    }
}

/// Streams from the daemon at `socket_dir` to `targets` loopback receivers for `duration` and
/// reports the latency percentiles.
pub fn run(socket_dir: &Path, targets: usize, duration: Duration) -> Result<LatencyReport, BridgeError> {
    let offset = ClockOffset::measure();
    let stop = Arc::new(AtomicBool::new(false));
    let mut addrs = Vec::new();
    let mut receivers = Vec::new();
    for _ in 0..targets.max(1) {
        let socket = UdpSocket::bind("127.0.0.1:0").map_err(|source| {
            let any: SocketAddr = "127.0.0.1:0".parse().expect("literal");
            crate::sender::SenderError::Socket { target: any, bind: any, source }
        })?;
        addrs.push(socket.local_addr().expect("bound socket has an address"));
        let stop = Arc::clone(&stop);
        receivers.push(std::thread::spawn(move || receive(&socket, offset, &stop)));
    }
    let mut config =
        BridgeConfig::new(frond_sdk::Source::Socket(socket_dir.to_path_buf()), Protocol::Frond, addrs);
    config.clock_offset = offset;
    let mut bridge = Bridge::connect(&config)?;
    let started = Instant::now();
    let bridge_stop = AtomicBool::new(false);
    let result = std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(duration);
            bridge_stop.store(true, Ordering::Relaxed);
        });
        bridge.run(&bridge_stop, None, |_| {})
    });
    let elapsed = started.elapsed().as_secs_f64();
    // Let the last datagrams land, then stop the receivers.
    std::thread::sleep(Duration::from_millis(50));
    stop.store(true, Ordering::Relaxed);
    let mut all: Vec<u64> = receivers.into_iter().flat_map(|h| h.join().unwrap_or_default()).collect();
    result?;
    all.sort_unstable();
    let us = |ns: u64| ns as f64 / 1000.0;
    Ok(LatencyReport {
        targets: targets.max(1),
        samples: all.len(),
        input_rate_hz: bridge.stats().received as f64 / elapsed.max(1e-9),
        p50_us: us(nearest_rank(&all, 0.50)),
        p99_us: us(nearest_rank(&all, 0.99)),
        max_us: us(all.last().copied().unwrap_or(0)),
    })
}

fn receive(socket: &UdpSocket, offset: ClockOffset, stop: &AtomicBool) -> Vec<u64> {
    let _ = socket.set_read_timeout(Some(Duration::from_millis(20)));
    let mut buf = [0u8; 2048];
    let mut out = Vec::with_capacity(16_384);
    while !stop.load(Ordering::Relaxed) {
        let Ok(n) = socket.recv(&mut buf) else { continue };
        let now = i128::from(monotonic_ns());
        // Frames carry their publish time; the names bundle (timetag "immediately") carries none.
        if let Ok((_, OscPacket::Bundle(b))) = rosc::decoder::decode_udp(&buf[..n])
            && b.timetag != IMMEDIATELY
        {
            let sent = offset.monotonic_ns_of(b.timetag);
            out.push((now - sent).max(0) as u64);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_json() {
        let r = LatencyReport {
            targets: 4,
            samples: 10,
            input_rate_hz: 1000.0,
            p50_us: 80.5,
            p99_us: 300.0,
            max_us: 1000.0,
        };
        assert_eq!(
            r.to_json(),
            r#"{"targets":4,"samples":10,"input_rate_hz":1000.0,"p50_us":80.5,"p99_us":300.0,"max_us":1000.0}"#
        );
    }
}
