//! Counting-allocator test: the realtime read path (report parsing and `read_pending` of each
//! source) allocates nothing in steady state. Allocations are counted per thread, so the FUSE
//! server and report generator threads do not interfere.

#[path = "it/common/mod.rs"]
mod common;

use std::time::Duration;

use common::*;
use frond_alloc_count::{CountingAlloc, count_allocations};
use frond_device::{
    DeviceProfile, DeviceSample, HandSource, HidSource, ReplaySource, ReportParser, SourceKind,
};
use frond_vhid::glove::{GloveReport, encode_report};
use frond_vhid::{InProcessGlove, VirtualGloveConfig, mount_fuse};

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

/// Calls `read_pending` until `n` samples arrived; returns the allocations made by those calls.
fn count_reads(src: &mut dyn HandSource, n: usize) -> u64 {
    let mut buf = [DeviceSample::default(); 16];
    let mut got = 0;
    let mut total = 0;
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while got < n {
        assert!(std::time::Instant::now() < deadline, "only {got} samples");
        let (k, n) = count_allocations(|| src.read_pending(&mut buf).unwrap());
        total += n;
        got += k;
        if k == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    total
}

#[test]
fn the_counter_sees_allocations() {
    let (v, n) = count_allocations(|| std::hint::black_box(vec![1u8; 16]));
    assert_eq!(n, 1);
    drop(v);
}

#[test]
fn parsing_allocates_nothing() {
    let mut p = ReportParser::new(&DeviceProfile::frond_glove());
    let reports: Vec<_> = (0..1000u32)
        .map(|i| {
            let mut b =
                encode_report(&GloveReport { seq: i, device_time_us: i * 1000, ..GloveReport::default() });
            if i % 7 == 0 {
                b[20] ^= 1; // some rejected reports too
            }
            b
        })
        .collect();
    let ((), n) = count_allocations(|| {
        for r in &reports {
            let _ = p.parse(r);
            let _ = p.parse(&r[..10]);
        }
    });
    assert_eq!(n, 0);
    assert!(p.counters().snapshot().reports > 800);
}

#[test]
fn hid_source_reads_allocate_nothing_in_steady_state() {
    if !fuse_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let glove = mount_fuse(&tmp.path().join("mnt"), VirtualGloveConfig::sway(1000.0)).unwrap();
    let profile = DeviceProfile::frond_glove();
    let mut src = HidSource::open_path(&profile, glove.node_path(), SourceKind::FuseHidraw).unwrap();
    count_reads(&mut src, 20); // warm up
    assert_eq!(count_reads(&mut src, 300), 0);
}

#[test]
fn in_process_and_replay_reads_allocate_nothing() {
    let mut src = InProcessGlove::new(VirtualGloveConfig::sway(1000.0)).unwrap();
    count_reads(&mut src, 10);
    assert_eq!(count_reads(&mut src, 200), 0);

    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("hand.jsonl");
    std::fs::write(&file, hand_jsonl(200, 1000.0)).unwrap();
    let mut replay = ReplaySource::load(&file).unwrap();
    count_reads(&mut replay, 1);
    assert_eq!(count_reads(&mut replay, 199), 0);
}

/// The OSC source is read and decoded by the loop itself: single messages and bundles (some
/// larger than the caller's buffer, the rest kept for the next call) allocate nothing.
#[test]
fn osc_reads_and_decodes_allocate_nothing() {
    use rosc::{OscBundle, OscMessage, OscPacket, OscTime, OscType};
    let mut src = frond_device::OscHandSource::bind("127.0.0.1:0").unwrap();
    let to = src.local_addr();
    let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let hand = |k: usize| {
        OscPacket::Message(OscMessage {
            addr: frond_device::source::OSC_HAND_ADDRESS.into(),
            args: [k as f32 * 0.001, k as f32 % 90.0, 0.0, 0.0, 5.0, 5.0, 5.0]
                .into_iter()
                .map(OscType::Float)
                .collect(),
        })
    };
    let mut k = 0;
    let mut send = |n_in_bundle: usize| {
        let packet = if n_in_bundle == 0 {
            k += 1;
            hand(k)
        } else {
            let content = (0..n_in_bundle)
                .map(|_| {
                    k += 1;
                    hand(k)
                })
                .collect();
            OscPacket::Bundle(OscBundle { timetag: OscTime::from((0, 1)), content })
        };
        tx.send_to(&rosc::encoder::encode(&packet).unwrap(), to).unwrap();
    };
    send(0);
    count_reads(&mut src, 1);
    // 100 single messages and 5 bundles of 40 (the 16-sample read buffer overflows each time).
    for _ in 0..100 {
        send(0);
    }
    for _ in 0..5 {
        send(40);
    }
    assert_eq!(count_reads(&mut src, 300), 0);
    assert_eq!(src.counters().snapshot().reports, 301);
}

/// The webcam source's reads (issue 47): the real landmark helper (frond-hands, installed by
/// `daemon/device/tests/install-webcam.sh`) finds a hand in a photograph and its samples are
/// read from the source's queue without allocating.
#[test]
fn webcam_reads_allocate_nothing() {
    let venv = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/.venv-hands");
    let helper = venv.join("bin/frond-hands");
    assert!(helper.exists(), "no {} (run daemon/device/tests/install-webcam.sh)", helper.display());
    // SAFETY: nextest runs each test in a process of its own; nothing else reads the
    // environment while it is set, before the source starts its thread.
    unsafe { std::env::set_var("FROND_HANDS", &helper) };
    let photo = venv.join("fingerpose/package/assets/nocurl.jpg");
    let address = format!("webcam:{}?hand=left", photo.display()).parse().unwrap();
    let mut src = frond_device::WebcamSource::open(&address, None).unwrap();
    assert_eq!(src.kind(), SourceKind::Webcam);
    count_reads(&mut src, 1);
    assert_eq!(count_reads(&mut src, 10), 0, "webcam reads allocated");
}
