//! Section 7: an OSC hand sample sent -> subscriber receipt through `frondd`'s OSC source (the
//! loop polls the UDP socket and decodes each datagram in place), against `frond-relay`, a
//! do-nothing relay built without frond's code that forwards each datagram unchanged to as many
//! readers over Unix sockets, measured in the same run with 1, 8 and 32 readers.
//!
//! The sender stamps each sample's `t` with the host's `CLOCK_MONOTONIC` (seconds, as a double);
//! `frondd` carries it as the pose's device time, the relay's readers read it from the datagram,
//! so both latencies are receipt time minus send time on one clock.

use std::io::{BufRead, BufReader, Read};
use std::net::UdpSocket;
use std::os::unix::net::UnixStream;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::thread;
use std::time::Duration;

use frondd::clock::{monotonic_ns, sleep_until_ns};
use frondd::stats::LatencyHistogram;
use serde_json::json;

use crate::Options;
use crate::latency::Subscribers;
use crate::procs::{Daemon, Proc, find_bin};
use crate::report::{Bound, Measurement, Section};

/// Byte offset of `t` (the first double) in [`hand_datagram`]: the 12-byte address and the
/// 12-byte type tag string come first.
const T_OFFSET: usize = 24;

/// `/frond/hand ,ddddddd` with `t` in seconds and a fixed hand, encoded by hand (OSC 1.0).
fn hand_datagram(t_s: f64) -> [u8; 80] {
    let mut b = [0u8; 80];
    b[..12].copy_from_slice(b"/frond/hand\0");
    b[12..24].copy_from_slice(b",ddddddd\0\0\0\0");
    for (i, v) in [t_s, 10.0, -5.0, 3.0, 20.0, 30.0, 40.0].into_iter().enumerate() {
        b[T_OFFSET + 8 * i..T_OFFSET + 8 * i + 8].copy_from_slice(&v.to_be_bytes());
    }
    b
}

/// Sends a sample to `to` every millisecond for `dur`, stamped with the send time.
fn send_for(to: std::net::SocketAddr, dur: Duration) -> Result<u64, String> {
    let socket = UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let period = 1_000_000;
    let end = monotonic_ns() + dur.as_nanos() as u64;
    let mut deadline = monotonic_ns() + period;
    let mut sent = 0;
    while deadline < end {
        sleep_until_ns(deadline);
        deadline += period;
        let t = monotonic_ns() as f64 / 1e9;
        socket.send_to(&hand_datagram(t), to).map_err(|e| e.to_string())?;
        sent += 1;
    }
    Ok(sent)
}

/// A free UDP port on loopback (bound, read, released).
fn free_port() -> Result<u16, String> {
    let s = UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    Ok(s.local_addr().map_err(|e| e.to_string())?.port())
}

/// Runs `frond-relay` with `n` readers for `dur` of samples; the readers' latencies.
fn relay_run(o: &Options, n: usize, dur: Duration) -> Result<LatencyHistogram, String> {
    let dir = tempfile::Builder::new().prefix("frond-bench-relay-").tempdir().map_err(|e| e.to_string())?;
    let path = dir.path().join("relay.sock");
    let port = free_port()?;
    let addr = format!("127.0.0.1:{port}");
    let mut child = Command::new(find_bin(o, "frond-relay")?)
        .args([&addr, &path.to_string_lossy().into_owned(), &n.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|e| format!("cannot start frond-relay: {e}"))?;
    let mut out = BufReader::new(child.stdout.take().ok_or("frond-relay has no stdout")?);
    let _relay = Proc { child };
    let mut line = String::new();
    out.read_line(&mut line).map_err(|e| e.to_string())?;
    if line.trim() != "listening" {
        return Err(format!("frond-relay said {line:?} instead of listening"));
    }
    let hist = Arc::new(LatencyHistogram::new());
    let stop = Arc::new(AtomicBool::new(false));
    let mut readers = Vec::new();
    for _ in 0..n {
        let mut s = UnixStream::connect(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        s.set_read_timeout(Some(Duration::from_millis(200))).map_err(|e| e.to_string())?;
        let (hist, stop) = (hist.clone(), stop.clone());
        readers.push(thread::spawn(move || {
            let mut buf = vec![0u8; 65_536];
            while !stop.load(Relaxed) {
                let mut len = [0u8; 4];
                match s.read_exact(&mut len) {
                    Ok(()) => {}
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) =>
                    {
                        continue;
                    }
                    Err(_) => return,
                }
                let len = (u32::from_le_bytes(len) as usize).min(buf.len());
                if s.read_exact(&mut buf[..len]).is_err() {
                    return;
                }
                let now = monotonic_ns();
                if let Some(t) = buf.get(T_OFFSET..T_OFFSET + 8) {
                    let sent = (f64::from_be_bytes(t.try_into().unwrap_or_default()) * 1e9) as u64;
                    hist.record(now.saturating_sub(sent));
                }
            }
        }));
    }
    line.clear();
    out.read_line(&mut line).map_err(|e| e.to_string())?;
    if line.trim() != "ready" {
        return Err(format!("frond-relay said {line:?} instead of ready"));
    }
    send_for(addr.parse().map_err(|_| "bad relay address")?, dur)?;
    thread::sleep(Duration::from_millis(50));
    stop.store(true, Relaxed);
    for r in readers {
        let _ = r.join();
    }
    Arc::try_unwrap(hist).map_err(|_| "a relay reader is still running".to_string())
}

/// Section 7.
pub fn osc_latency(o: &Options) -> Result<Section, String> {
    const TITLE: &str = "OSC hand sample sent -> subscriber receipt through frondd (1 kHz) vs frond-relay, a do-nothing relay to as many Unix socket readers";
    let dur = if o.quick { Duration::from_millis(800) } else { Duration::from_secs(5) };
    let port = free_port()?;
    let source = format!("osc://127.0.0.1:{port}");
    let daemon = Daemon::start(o, &["--source", &source, "--rate", "1000"])?;
    let to: std::net::SocketAddr = format!("127.0.0.1:{port}").parse().map_err(|_| "bad address")?;
    let counts = [1usize, 8, 32];
    let mut subs = Subscribers::new(counts.len());
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    for (i, &n) in counts.iter().enumerate() {
        subs.grow_to(&daemon.poses_socket(), n)?;
        thread::sleep(Duration::from_millis(100));
        subs.record(Some(i));
        let sent = send_for(to, dur)?;
        thread::sleep(Duration::from_millis(50));
        subs.record(None);
        let relay = relay_run(o, n, dur)?;
        let (f, r) = (subs.hists(i).glove_to_receipt.summary(), relay.summary());
        if f.samples == 0 || r.samples == 0 {
            return Err(format!("no samples with {n} readers (frondd {}, relay {})", f.samples, r.samples));
        }
        for (q, fv, rv, limit) in [("p50", f.p50_us, r.p50_us, 1.3), ("p99", f.p99_us, r.p99_us, 2.0)] {
            measurements.push(
                Measurement::new(
                    format!("osc_to_subscriber_{q}_{n}_subscribers"),
                    "us",
                    fv,
                    format!("frond-relay to {n} readers, {q}"),
                    rv,
                )
                .with_target(
                    format!("OSC-to-subscriber {q} <= {limit}x the relay's, {n} subscribers"),
                    Bound::MaxRatio,
                    limit,
                ),
            );
        }
        details.insert(format!("{n}_subscribers"), json!({ "frondd": f, "relay": r, "sent": sent }));
    }
    let status = daemon.status().ok();
    details.insert("source".into(), json!(status.as_ref().map(|s| format!("{:?}", s.source))));
    details.insert("device_wakes".into(), json!(status.as_ref().map(|s| s.device_wakes)));
    Ok(Section::ok("osc_latency", TITLE, measurements, serde_json::Value::Object(details)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_datagram_is_the_osc_message_the_daemon_decodes() {
        let d = hand_datagram(12.5);
        let got = frond_device::source::decode_hand_packet(&d);
        let want =
            frond_motion::HandSample { t: 12.5, wrist_deg: [10.0, -5.0, 3.0], thumb_deg: [20.0, 30.0, 40.0] };
        assert_eq!(got, vec![Ok(want)]);
        assert_eq!(f64::from_be_bytes(d[T_OFFSET..T_OFFSET + 8].try_into().unwrap()), 12.5);
    }
}
