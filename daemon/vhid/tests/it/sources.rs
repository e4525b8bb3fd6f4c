//! Replay and in-process sources.

use crate::common;

use std::time::Duration;

use common::*;
use frond_device::jsonl::parse_hand_text;
use frond_device::{HandSource, ReplaySource, SourceError};
use frond_vhid::{FaultPlan, GloveSource, InProcessGlove, UnplugPlan, VirtualGloveConfig};

#[test]
fn replay_delivers_the_file_in_order_then_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("hand.jsonl");
    let text = hand_jsonl(40, 400.0);
    std::fs::write(&file, &text).unwrap();
    let expected = parse_hand_text(&file, &text).unwrap();
    let mut src = ReplaySource::load(&file).unwrap();
    assert_eq!(src.kind().to_string(), "replay");
    let got = read_n(&mut src, 40, Duration::from_secs(10)).unwrap();
    assert_eq!(got.iter().map(|s| s.raw).collect::<Vec<_>>(), expected);
    assert!(src.finished());
    let mut buf = [frond_device::DeviceSample::default(); 4];
    assert_eq!(src.read_pending(&mut buf).unwrap(), 0);
}

#[test]
fn replay_plays_through_untrusted_times_without_stalling_or_bursting() {
    // A jump of 1e15 s (the old pacing waited that long: frondd only logged "device stalled"),
    // a repeat, and a step back; each is a break in the timeline.
    let times = [0.0, 0.01, 0.02, 1e15, 1e15, 1e15 + 0.125, 0.5, 0.51, 0.52];
    let breaks_before = [3, 4, 6];
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("hand.jsonl");
    let text: String =
        times.iter().map(|t| format!("{{\"t\":{t},\"wrist\":[1,2,3],\"thumb\":[4,5,6]}}\n")).collect();
    std::fs::write(&file, &text).unwrap();
    let mut src = ReplaySource::load(&file).unwrap();
    // Read as the realtime loop does, and keep each read's batch.
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    let mut batches: Vec<Vec<usize>> = Vec::new();
    let mut buf = [frond_device::DeviceSample::default(); 16];
    while !src.finished() && std::time::Instant::now() < deadline {
        let n = src.read_pending(&mut buf).unwrap();
        if n > 0 {
            batches.push(buf[..n].iter().map(|s| s.device_seq as usize).collect());
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let got: Vec<usize> = batches.iter().flatten().copied().collect();
    assert_eq!(got, (0..times.len()).collect::<Vec<_>>(), "every sample, in file order: {batches:?}");
    // No burst: a sample after a break is the first of its read, never taken with the one before.
    for b in breaks_before {
        assert!(batches.iter().any(|batch| batch[0] == b), "{b} shares a read: {batches:?}");
    }
}

#[test]
fn in_process_glove_parses_the_same_reports_and_unplugs() {
    let cfg = VirtualGloveConfig {
        source: GloveSource::Sway { rate_hz: 500.0 },
        faults: FaultPlan {
            unplug: Some(UnplugPlan { at_ms: 200, duration_ms: 500, every_ms: None }),
            ..FaultPlan::default()
        },
        start_delay_ms: 0,
        clock: frond_vhid::DeviceClock::Schedule,
    };
    let mut src = InProcessGlove::new(cfg).unwrap();
    assert_eq!(src.kind().to_string(), "in-process");
    let first = read_n(&mut src, 10, Duration::from_secs(10)).unwrap();
    assert_eq!(first.len(), 10);
    for (i, s) in first.iter().enumerate() {
        assert_eq!(s.device_seq, i as u32);
        assert_eq!(s.device_time_us, i as u64 * 2000);
        let (hand, _) = frond_vhid::sway_sample(i as f64 / 500.0);
        for (got, want) in s.raw.wrist_deg.iter().zip(hand.wrist_deg) {
            assert!((got - want).abs() <= 0.005 + 1e-5, "{got} vs {want}");
        }
    }
    let e = read_until_disconnect(&mut src, Duration::from_secs(10)).expect("no disconnect");
    assert!(matches!(e, SourceError::Disconnected { .. }));
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while src.reopen().is_err() {
        assert!(std::time::Instant::now() < deadline);
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(read_n(&mut src, 10, Duration::from_secs(10)).unwrap().len(), 10);
    assert!(src.counters().snapshot().seq_gaps > 0);
}

#[test]
fn faults_are_counted_by_the_parser() {
    let cfg = VirtualGloveConfig {
        source: GloveSource::Sway { rate_hz: 2000.0 },
        faults: FaultPlan { drop_prob: 0.2, corrupt_prob: 0.2, ..FaultPlan::default() },
        start_delay_ms: 0,
        clock: frond_vhid::DeviceClock::Schedule,
    };
    let mut src = InProcessGlove::new(cfg).unwrap();
    let got = read_n(&mut src, 400, Duration::from_secs(20)).unwrap();
    assert!(got.len() >= 400);
    let c = src.counters().snapshot();
    let stats = src.stats();
    let corrupted = stats.corrupted.load(std::sync::atomic::Ordering::Relaxed);
    assert!(c.checksum > 0 && c.seq_gaps > 0, "{c:?}");
    // Every corrupted report the parser saw was rejected (one was maybe still queued).
    assert!(c.checksum + c.wrong_id <= corrupted, "{c:?} vs {corrupted}");
    assert!(got.windows(2).all(|w| w[1].device_seq > w[0].device_seq));
}

fn poll_readable(fd: i32, timeout_ms: i32) -> bool {
    let mut pfd = libc::pollfd { fd, events: libc::POLLIN, revents: 0 };
    // SAFETY: one valid pollfd.
    unsafe { libc::poll(&mut pfd, 1, timeout_ms) == 1 }
}

/// The loop waits on the in-process glove's ready descriptor: quiet until a report is queued,
/// readable once one is, quiet again once `read_pending` took it, readable at an unplug, and
/// absent while disconnected.
#[test]
fn in_process_glove_rings_its_ready_descriptor_per_report_and_at_unplug() {
    let cfg = VirtualGloveConfig {
        source: GloveSource::Sway { rate_hz: 2.0 },
        faults: FaultPlan {
            unplug: Some(UnplugPlan { at_ms: 1200, duration_ms: 60_000, every_ms: None }),
            ..FaultPlan::default()
        },
        start_delay_ms: 300,
        clock: frond_vhid::DeviceClock::Schedule,
    };
    let mut src = InProcessGlove::new(cfg).unwrap();
    let fd = src.ready_fd().expect("an eventfd");
    assert!(!poll_readable(fd, 50), "readable before any report");
    // The first report (at 300 ms) wakes a poll with a far longer timeout.
    assert!(poll_readable(fd, 10_000));
    let mut buf = [frond_device::DeviceSample::default(); 4];
    assert_eq!(src.read_pending(&mut buf).unwrap(), 1);
    // Taken: quiet until the next report, 500 ms later at 2 Hz.
    assert!(!poll_readable(fd, 100), "still readable after the report was read");
    assert!(poll_readable(fd, 10_000));
    assert_eq!(src.read_pending(&mut buf).unwrap(), 1);
    // The unplug (at 1200 ms, before the next report) wakes the poll as well.
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    let err = loop {
        assert!(poll_readable(fd, 10_000), "neither a report nor the unplug woke the poll");
        match src.read_pending(&mut buf) {
            Ok(_) => assert!(std::time::Instant::now() < deadline, "no unplug"),
            Err(e) => break e,
        }
    };
    assert!(matches!(err, SourceError::Disconnected { .. }), "{err}");
    assert_eq!(src.ready_fd(), None);
}
