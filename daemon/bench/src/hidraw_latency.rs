//! Section 8: a glove report written to a hidraw node -> subscriber receipt through `frondd`,
//! against `frond-relay` reading the same node (`poll` for `POLLIN`, one `read` per report) and
//! writing each report unchanged to as many readers over Unix sockets, with 1, 8 and 32 readers.
//!
//! The node is the virtual glove's FUSE node (`frond-vhid --clock monotonic --backend fuse`, in
//! its own process, as the `fuse_*` rows of `glove_latency` use), so it needs `/dev/fuse`. The
//! glove stamps each report's `u32` device time (bytes 5..9, [`frond_vhid::glove::TIME_OFFSET`])
//! with the host's `CLOCK_MONOTONIC` microseconds at the write; `frondd` carries it as the pose's
//! device time, the relay's readers read it from the forwarded report, so both latencies are
//! receipt time minus write time on one clock. Every open handle of the node has its own report
//! queue; `frondd` and the relay take turns (one stopped before the other starts), so neither
//! runs while the other is measured.

use std::io::BufReader;
use std::path::Path;
use std::process::ChildStdout;
use std::thread;
use std::time::Duration;

use frond_vhid::glove::TIME_OFFSET;
use frond_vhid::monotonic_us_u32;
use serde_json::json;

use crate::Options;
use crate::error::BenchError;
use crate::latency::Subscribers;
use crate::procs::{Daemon, Proc, start_vhid};
use crate::relay::{Relay, against_relay};
use crate::report::{Section, Status};

const TITLE: &str = "glove report written to a hidraw node (frond-vhid's FUSE node) -> subscriber receipt through frondd (1 kHz) vs frond-relay reading the same node, to as many Unix socket readers";

/// The relay readers' [`crate::relay::Stamp`] of a forwarded glove report: receipt time minus
/// the report's device time, in the wrapping `u32` microseconds of the glove's counter.
pub fn hidraw_stamp(report: &[u8]) -> Option<u64> {
    let now_us = monotonic_us_u32();
    let t = u32::from_le_bytes(report.get(TIME_OFFSET..TIME_OFFSET + 4)?.try_into().ok()?);
    Some(u64::from(now_us.wrapping_sub(t)) * 1000)
}

/// Why the glove cannot be served as a hidraw node here, if it cannot.
pub(crate) fn fuse_unavailable() -> Option<&'static str> {
    (!Path::new("/dev/fuse").exists())
        .then_some("/dev/fuse is absent, so the glove cannot be served as a hidraw node")
}

/// The virtual glove on its FUSE hidraw node in a private directory (`frond-vhid --clock
/// monotonic --backend fuse`): each report carries the host's `CLOCK_MONOTONIC` microseconds at
/// its write, which is when the node wakes its reader ([`report_written_ns`]). Stopped when
/// dropped.
pub(crate) struct FuseGlove {
    /// The node's path, for `frondd --device` and `frond-relay hidraw:`.
    pub(crate) node: String,
    _vhid: Proc,
    _out: BufReader<ChildStdout>,
    _dir: tempfile::TempDir,
}

impl FuseGlove {
    /// `frond-vhid` playing `source` (`--sway --rate HZ`, `--play FILE --loop`).
    pub(crate) fn start(o: &Options, source: &[&str]) -> Result<Self, BenchError> {
        let dir = tempfile::Builder::new().prefix("frond-bench-hidraw-").tempdir()?;
        let node = dir.path().join("glove").join(frond_vhid::NODE_NAME);
        let node_arg = node.to_string_lossy().into_owned();
        let mut args = source.to_vec();
        args.extend(["--clock", "monotonic", "--backend", "fuse", "--node", &node_arg]);
        let (vhid, node, out) = start_vhid(o, &args)?;
        Ok(FuseGlove { node: node.to_string_lossy().into_owned(), _vhid: vhid, _out: out, _dir: dir })
    }
}

/// The host `CLOCK_MONOTONIC` nanoseconds at which a report stamped `stamp_us` (the glove's
/// wrapping `u32` microseconds, the low 32 bits of a pose's `device_time_us`) was written,
/// given a time `now_ns` less than 71 minutes after the write.
pub fn report_written_ns(stamp_us: u32, now_ns: u64) -> u64 {
    let now_us = (now_ns / 1000) as u32;
    now_ns.saturating_sub(u64::from(now_us.wrapping_sub(stamp_us)) * 1000)
}

/// Section 8.
pub fn hidraw_latency(o: &Options) -> Result<Section, BenchError> {
    if let Some(why) = fuse_unavailable() {
        return Ok(Section::unavailable("hidraw_latency", TITLE, Status::NotAvailable, why));
    }
    let (warm, dur) = if o.quick {
        (Duration::from_millis(200), Duration::from_millis(800))
    } else {
        (Duration::from_secs(1), Duration::from_secs(5))
    };
    let glove = FuseGlove::start(o, &["--sway", "--rate", "1000"])?;
    let node = glove.node.clone();
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    for n in [1usize, 8, 32] {
        let daemon = Daemon::start(o, &["--device", &node, "--rate", "1000"])?;
        let mut subs = Subscribers::new(1);
        subs.grow_to(&daemon.poses_socket(), n)?;
        thread::sleep(warm);
        subs.record(Some(0));
        thread::sleep(dur);
        subs.record(None);
        let f = subs.hists(0).glove_to_receipt.summary();
        let status = daemon.status().ok();
        drop(subs);
        drop(daemon);

        let relay = Relay::start(o, &format!("hidraw:{node}"), n, hidraw_stamp)?;
        relay.wait_flowing(Duration::from_secs(10))?;
        thread::sleep(warm);
        relay.record(true);
        thread::sleep(dur);
        relay.record(false);
        let r = relay.finish();
        measurements.extend(against_relay("hidraw_to_subscriber", "hidraw-to-subscriber", n, &f, &r)?);
        details.insert(
            format!("{n}_subscribers"),
            json!({
                "frondd": f,
                "relay": r,
                "frondd_source": status.as_ref().map(|s| format!("{:?}", s.source)),
                "frondd_device_wakes": status.as_ref().map(|s| s.device_wakes),
            }),
        );
    }
    details.insert("glove_rate_hz".into(), json!(1000));
    details.insert("daemon_rate_hz".into(), json!(1000));
    details.insert(
        "node".into(),
        json!("frond-vhid --clock monotonic --backend fuse: every poll and read is a round trip to the glove's process, for frondd (through hidapi) and the relay alike"),
    );
    Ok(Section::ok("hidraw_latency", TITLE, measurements, serde_json::Value::Object(details)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_vhid::glove::{GloveReport, STATUS_TRACKING_OK, encode_report};

    #[test]
    fn the_stamp_is_receipt_minus_the_reports_device_time() {
        let hand = frond_motion::HandSample { t: 0.0, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3] };
        let written = monotonic_us_u32().wrapping_sub(1500);
        let (report, _) = GloveReport::from_degrees(7, written, &hand, [0.0; 4], STATUS_TRACKING_OK);
        let bytes = encode_report(&report);
        let ns = hidraw_stamp(&bytes).unwrap();
        assert!((1_500_000..1_500_000 + 1_000_000_000).contains(&ns), "{ns} ns");
        assert_eq!(hidraw_stamp(&bytes[..TIME_OFFSET + 3]), None, "a report too short to carry a time");
    }

    #[test]
    fn a_reports_write_time_from_its_wrapping_stamp() {
        // Now 5,000,000,123,456 ns = 5,000,000,123 us, whose low 32 bits are 5,000,000,123 -
        // 4,294,967,296 = 705,032,827; written 1,500 us before, within and across the wrap.
        let now_ns = 5_000_000_123_456;
        assert_eq!(report_written_ns(705_031_327, now_ns), 5_000_000_123_456 - 1_500_000);
        // Now 4,294,967,296,500 ns: the counter has just wrapped to 0; written at u32::MAX us.
        assert_eq!(report_written_ns(u32::MAX, 4_294_967_296_500), 4_294_967_295_500);
    }
}
