//! Encoding and sending a frame allocates nothing once the buffers have grown (the exporter runs
//! at the daemon's rate, 1 kHz by default). A counting global allocator counts the allocations of
//! the test's own thread only: the test harness's threads may allocate meanwhile.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::net::UdpSocket;
use std::sync::atomic::{AtomicUsize, Ordering};

use frond_osc::encode::{ClockOffset, Datagrams, FrondEncoder, VmcEncoder, VmcRig};
use frond_osc::resample::Resampler;
use frond_osc::sender::Sender;
use frond_protocol::{Pose, PoseFlags};

struct Counting;
thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}
static ALLOCS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as ours.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as ours.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as ours.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn steady_state_frames_allocate_nothing() {
    let sink = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut sender = Sender::new(&[sink.local_addr().unwrap()], None).unwrap();
    let mut frond = FrondEncoder::new(ClockOffset::fixed(1_700_000_000_000_000_000));
    let mut vmc = VmcEncoder::new(ClockOffset::fixed(0), VmcRig::default());
    let mut resampler = Resampler::new(100.0);
    let mut out = Datagrams::new();
    let pose = |seq: u64| Pose {
        seq,
        host_monotonic_ns: seq * 1_000_000,
        flags: if seq.is_multiple_of(7) { PoseFlags::DEVICE_LOST } else { PoseFlags::default() },
        joints_deg: [[seq as f32 * 0.1, 2.0, 3.0]; 4],
        ..Pose::default()
    };
    let mut frame = |seq: u64, out: &mut Datagrams| {
        frond.encode(&pose(seq), out).unwrap();
        sender.send(out);
        vmc.encode(&pose(seq), out).unwrap();
        sender.send(out);
        resampler.push(pose(seq), seq * 1_000_000);
        resampler.poll(seq * 1_000_000, |p| assert!(p.seq <= seq));
    };
    for seq in 0..100 {
        frame(seq, &mut out);
    }
    COUNTING.with(|c| c.set(true));
    for seq in 100..1100 {
        frame(seq, &mut out);
    }
    COUNTING.with(|c| c.set(false));
    assert_eq!(ALLOCS.load(Ordering::SeqCst), 0, "allocations in 1000 steady-state frames");
}
