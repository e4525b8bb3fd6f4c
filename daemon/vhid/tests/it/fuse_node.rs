//! The virtual glove's FUSE hidraw node, read through hidapi exactly like a physical glove.

use crate::common;

use std::io::Read;
use std::os::unix::fs::OpenOptionsExt;
use std::time::{Duration, Instant};

use common::*;
use frond_device::jsonl::parse_hand_text;
use frond_device::{DeviceProfile, HandSource, HidSource, SourceError, SourceKind};
use frond_vhid::{FaultPlan, GloveSource, UnplugPlan, VirtualGloveConfig, mount_fuse};

fn jsonl_config(path: &std::path::Path, start_delay_ms: u64) -> VirtualGloveConfig {
    VirtualGloveConfig {
        source: GloveSource::Jsonl { path: path.to_owned(), looped: false },
        faults: FaultPlan::default(),
        start_delay_ms,
        clock: frond_vhid::DeviceClock::Schedule,
    }
}

#[test]
fn hidapi_reads_every_report_of_a_jsonl_file_bit_for_bit() {
    if !fuse_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("hand.jsonl");
    let text = hand_jsonl(120, 240.0);
    std::fs::write(&file, &text).unwrap();
    let expected = parse_hand_text(&file, &text).unwrap();

    let glove = mount_fuse(&tmp.path().join("mnt"), jsonl_config(&file, 400)).unwrap();
    assert_eq!(glove.node_path(), tmp.path().join("mnt/hidraw-frond"));
    let profile = DeviceProfile::frond_glove();
    let mut src = HidSource::open_path(&profile, glove.node_path(), SourceKind::FuseHidraw).unwrap();
    assert_eq!(src.kind().to_string(), "fuse-hidraw");
    let got = read_n(&mut src, expected.len(), Duration::from_secs(20)).unwrap();
    assert_eq!(got.len(), expected.len());
    for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
        assert_eq!(g.device_seq, i as u32);
        assert_eq!(g.raw, *e, "sample {i}: device path and JSONL text must agree exactly");
        assert_eq!(g.device_time_us, (e.t * 1e6).round() as u64);
        assert_eq!(g.status, 1);
    }
    let c = src.counters().snapshot();
    assert_eq!((c.reports, c.rejected(), c.seq_gaps), (120, 0, 0));
}

#[test]
fn nonblocking_read_returns_nothing_when_empty() {
    if !fuse_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let mut cfg = VirtualGloveConfig::sway(100.0);
    cfg.start_delay_ms = 600_000; // no report during this test
    let glove = mount_fuse(&tmp.path().join("mnt"), cfg).unwrap();
    let profile = DeviceProfile::frond_glove();
    let mut src = HidSource::open_path(&profile, glove.node_path(), SourceKind::FuseHidraw).unwrap();
    let mut buf = [frond_device::DeviceSample::default(); 8];
    let started = Instant::now();
    for _ in 0..100 {
        assert_eq!(src.read_pending(&mut buf).unwrap(), 0);
    }
    // A hang check, not a timing test: 100 empty non-blocking reads take milliseconds.
    assert!(started.elapsed() < Duration::from_secs(5));

    // A plain O_NONBLOCK read gets EAGAIN; a read with a timeout (poll) returns after it.
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(glove.node_path())
        .unwrap();
    let mut b = [0u8; 64];
    let e = f.read(&mut b).unwrap_err();
    assert_eq!(e.raw_os_error(), Some(libc::EAGAIN));
    let api = hidapi::HidApi::new().unwrap();
    let c = std::ffi::CString::new(glove.node_path().to_str().unwrap()).unwrap();
    let dev = api.open_path(&c).unwrap();
    assert_eq!(dev.read_timeout(&mut b, 50).unwrap(), 0);
}

/// The loop waits on [`HandSource::ready_fd`]: it must be hidapi's own descriptor for the node,
/// quiet while nothing is pending and readable as soon as a report is, and gone after a
/// disconnect.
#[test]
fn ready_fd_is_the_nodes_descriptor_and_polls_readable_when_a_report_is_pending() {
    if !fuse_available() {
        return;
    }
    let poll = |fd: i32, ms: i32| {
        let mut pfd = libc::pollfd { fd, events: libc::POLLIN, revents: 0 };
        // SAFETY: one valid pollfd.
        unsafe { libc::poll(&mut pfd, 1, ms) }
    };
    let tmp = tempfile::tempdir().unwrap();
    let mut cfg = VirtualGloveConfig::sway(200.0);
    cfg.start_delay_ms = 800;
    cfg.faults.unplug = Some(UnplugPlan { at_ms: 1500, duration_ms: 60_000, every_ms: None });
    let glove = mount_fuse(&tmp.path().join("mnt"), cfg).unwrap();
    let profile = DeviceProfile::frond_glove();
    let mut src = HidSource::open_path(&profile, glove.node_path(), SourceKind::FuseHidraw).unwrap();
    let fd = src.ready_fd().expect("hidapi's descriptor identified");
    // An independent check that it is the node: /proc names the file behind the descriptor.
    let target = std::fs::read_link(format!("/proc/self/fd/{fd}")).unwrap();
    assert_eq!(target, glove.node_path());
    // Before the first report: the poll times out.
    assert_eq!(poll(fd, 100), 0, "readable with nothing pending");
    // A report arrives: poll wakes (well before its 10 s timeout), and the report is read.
    assert_eq!(poll(fd, 10_000), 1);
    let mut buf = [frond_device::DeviceSample::default(); 8];
    assert!(src.read_pending(&mut buf).unwrap() >= 1);
    // After the unplug the source reports the loss and offers no descriptor.
    let e = read_until_disconnect(&mut src, Duration::from_secs(10)).expect("no disconnect");
    assert!(matches!(e, SourceError::Disconnected { .. }), "{e}");
    assert_eq!(src.ready_fd(), None);
}

#[test]
fn blocking_reads_are_parked_until_a_report_arrives() {
    if !fuse_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let mut cfg = VirtualGloveConfig::sway(200.0);
    cfg.start_delay_ms = 300;
    let glove = mount_fuse(&tmp.path().join("mnt"), cfg).unwrap();
    let mut a = std::fs::File::open(glove.node_path()).unwrap();
    let mut b = std::fs::File::open(glove.node_path()).unwrap();
    // Both handles get every report (own queues), starting with sequence 0.
    for f in [&mut a, &mut b] {
        let mut r = [0u8; 64];
        assert_eq!(f.read(&mut r).unwrap(), 64);
        assert_eq!(r[0], 1);
        assert_eq!(u32::from_le_bytes([r[1], r[2], r[3], r[4]]), 0);
        assert_eq!(frond_vhid::glove::sum8(&r), 0);
    }
}

#[test]
fn unplug_disconnects_and_reopen_works_after_replug() {
    if !fuse_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let mut cfg = VirtualGloveConfig::sway(500.0);
    cfg.start_delay_ms = 200;
    cfg.faults.unplug = Some(UnplugPlan { at_ms: 300, duration_ms: 1500, every_ms: None });
    let glove = mount_fuse(&tmp.path().join("mnt"), cfg).unwrap();
    let profile = DeviceProfile::frond_glove();
    let mut src = HidSource::open_path(&profile, glove.node_path(), SourceKind::FuseHidraw).unwrap();
    let before = read_n(&mut src, 20, Duration::from_secs(10)).unwrap();
    assert_eq!(before.len(), 20);
    let e = read_until_disconnect(&mut src, Duration::from_secs(10)).expect("no disconnect");
    assert!(matches!(e, SourceError::Disconnected { .. }), "{e}");
    // Unplugged: the node is gone and reopening fails.
    assert!(!glove.node_path().exists());
    assert!(src.reopen().is_err());
    let deadline = Instant::now() + Duration::from_secs(10);
    while src.reopen().is_err() {
        assert!(Instant::now() < deadline, "never replugged");
        std::thread::sleep(Duration::from_millis(20));
    }
    let after = read_n(&mut src, 20, Duration::from_secs(10)).unwrap();
    assert_eq!(after.len(), 20);
    // The glove kept counting while unplugged: ~750 reports lost, seen as a sequence gap.
    assert!(after[0].device_seq > before[19].device_seq + 500);
    assert!(src.counters().snapshot().seq_gaps > 500);
}

#[test]
fn dropping_the_handle_unmounts_even_with_an_open_reader() {
    if !fuse_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("mnt");
    let glove = mount_fuse(&dir, VirtualGloveConfig::sway(100.0)).unwrap();
    let dir = dir.canonicalize().unwrap();
    assert!(is_mounted(&dir));
    let profile = DeviceProfile::frond_glove();
    let mut src = HidSource::open_path(&profile, glove.node_path(), SourceKind::FuseHidraw).unwrap();
    drop(glove);
    assert!(!is_mounted(&dir));
    // The reader sees a disconnect, not a hang.
    let e = read_until_disconnect(&mut src, Duration::from_secs(5)).expect("no disconnect");
    assert!(matches!(e, SourceError::Disconnected { .. }));
}

#[test]
fn mount_refuses_a_non_empty_directory() {
    if !fuse_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("keep"), "x").unwrap();
    let e = mount_fuse(tmp.path(), VirtualGloveConfig::sway(100.0)).unwrap_err();
    assert!(e.to_string().contains("not empty"), "{e}");
}
