//! Encoding and sending a frame allocates nothing once the buffers have grown (the exporter runs
//! at the daemon's rate, 1 kHz by default). A counting global allocator counts the allocations of
//! the test's own thread only: the test harness's threads may allocate meanwhile.

use std::net::UdpSocket;

use frond_alloc_count::{CountingAlloc, count_allocations};
use frond_osc::encode::{ClockOffset, Datagrams, FrondEncoder, VmcEncoder, VmcRig};
use frond_osc::resample::Resampler;
use frond_osc::sender::Sender;
use frond_protocol::{Pose, PoseFlags};

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

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
    let ((), allocations) = count_allocations(|| {
        for seq in 100..1100 {
            frame(seq, &mut out);
        }
    });
    assert_eq!(allocations, 0, "allocations in 1000 steady-state frames");
}
