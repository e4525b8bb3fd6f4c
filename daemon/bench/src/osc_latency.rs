//! Section 7: an OSC hand sample sent -> subscriber receipt through `frondd`'s OSC source (the
//! loop polls the UDP socket and decodes each datagram in place), against `frond-relay`, a
//! do-nothing relay built without frond's code that forwards each datagram unchanged to as many
//! readers over Unix sockets, measured in the same run with 1, 8 and 32 readers.
//!
//! The sender stamps each sample's `t` with the host's `CLOCK_MONOTONIC` (seconds, as a double);
//! `frondd` carries it as the pose's device time, the relay's readers read it from the datagram,
//! so both latencies are receipt time minus send time on one clock.

use std::net::UdpSocket;
use std::thread;
use std::time::Duration;

use frond_protocol::LatencySummary;
use frondd::clock::{monotonic_ns, sleep_until_ns};
use serde_json::json;

use crate::Options;
use crate::error::BenchError;
use crate::latency::Subscribers;
use crate::procs::Daemon;
use crate::relay::{Relay, against_relay};
use crate::report::Section;

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
pub fn send_for(to: std::net::SocketAddr, dur: Duration) -> Result<u64, BenchError> {
    let socket = UdpSocket::bind("127.0.0.1:0")?;
    let period = 1_000_000;
    let end = monotonic_ns() + dur.as_nanos() as u64;
    let mut deadline = monotonic_ns() + period;
    let mut sent = 0;
    while deadline < end {
        sleep_until_ns(deadline);
        deadline += period;
        let t = monotonic_ns() as f64 / 1e9;
        socket.send_to(&hand_datagram(t), to)?;
        sent += 1;
    }
    Ok(sent)
}

/// `127.0.0.1:port`.
pub fn loopback(port: u16) -> std::net::SocketAddr {
    std::net::SocketAddr::from(([127, 0, 0, 1], port))
}

/// A free UDP port on loopback (bound, read, released).
pub fn free_port() -> Result<u16, BenchError> {
    let s = UdpSocket::bind("127.0.0.1:0")?;
    Ok(s.local_addr()?.port())
}

/// The relay readers' [`crate::relay::Stamp`] of a forwarded `hand_datagram`: receipt time
/// minus the `t` it carries.
pub fn osc_stamp(datagram: &[u8]) -> Option<u64> {
    let now = monotonic_ns();
    let t = f64::from_be_bytes(datagram.get(T_OFFSET..T_OFFSET + 8)?.try_into().ok()?);
    Some(now.saturating_sub((t * 1e9) as u64))
}

/// Runs `frond-relay` with `n` readers for `dur` of samples; the readers' latencies.
fn relay_run(o: &Options, n: usize, dur: Duration) -> Result<LatencySummary, BenchError> {
    let addr = loopback(free_port()?);
    let relay = Relay::start(o, &format!("udp:{addr}"), n, osc_stamp)?;
    relay.record(true);
    send_for(addr, dur)?;
    thread::sleep(Duration::from_millis(50));
    Ok(relay.finish())
}

/// Section 7.
pub fn osc_latency(o: &Options) -> Result<Section, BenchError> {
    const TITLE: &str = "OSC hand sample sent -> subscriber receipt through frondd (1 kHz) vs frond-relay, a do-nothing relay to as many Unix socket readers";
    let dur = if o.quick { Duration::from_millis(800) } else { Duration::from_secs(5) };
    let port = free_port()?;
    let source = format!("osc://127.0.0.1:{port}");
    let daemon = Daemon::start(o, &["--source", &source, "--rate", "1000"])?;
    let to = loopback(port);
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
        let r = relay_run(o, n, dur)?;
        let f = subs.hists(i).glove_to_receipt.summary();
        measurements.extend(against_relay("osc_to_subscriber", "OSC-to-subscriber", n, &f, &r)?);
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
