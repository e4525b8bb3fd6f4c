//! Encoding and sending a frame allocates nothing once the buffers have grown (the exporter runs
//! at the daemon's rate, 1 kHz by default). A counting global allocator counts the allocations of
//! the test's own thread only: the test harness's threads may allocate meanwhile.

use std::net::UdpSocket;

use frond_alloc_count::{CountingAlloc, count_allocations};
use std::sync::Arc;

use frond_osc::encode::{ClockOffset, Datagrams, FrondEncoder, Timetags, VmcEncoder, VmcRig};
use frond_osc::fields::FieldSender;
use frond_osc::resample::Resampler;
use frond_osc::sender::Sender;
use frond_protocol::field::{FieldDefinition, FieldFrame, FieldLayout, StreamFrame};
use frond_protocol::{ElementId, Pose, PoseFlags};

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
    // A running field of 100,000 plants sent whole: every field frame with its entries, and
    // the layout's 2000 chunks riding 8 a frame with the first 250 (counted from frame 100).
    let mut fields = FieldSender::new(ClockOffset::fixed(0), Timetags::Publish);
    let layout = Arc::new(vec![7u8; 100_000 * 20]);
    fields.set_table(vec![frond_sdk::field::RelayedField { definition: field_definition(100_000), layout }]);
    let field_frame = |seq: u64| {
        let mut f = FieldFrame { seq, field: ElementId::new(40), produced: seq + 1, ..FieldFrame::default() };
        for k in 0..12 {
            f.entries.push(StreamFrame { index: seq.saturating_sub(k), joints_deg: [[seq as f32; 3]; 4] });
        }
        f
    };
    let mut field_out = Datagrams::new();
    let mut frame = |seq: u64, out: &mut Datagrams| {
        fields.send_frame(&field_frame(seq), &mut field_out, &mut sender).unwrap();
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
    assert_eq!(fields.frames_sent, 1100, "every field frame went out");
}

fn field_definition(plants: u32) -> FieldDefinition {
    FieldDefinition {
        id: ElementId::new(40),
        source: "field".into(),
        rig: "grass".into(),
        layout: FieldLayout {
            version: 1,
            take: "sway".into(),
            fps: 30.0,
            frames: 60,
            rows: 100,
            cols: 1000,
            cell_m: 0.2,
            speed_m_s: 1.0,
            direction_deg: 0.0,
            authored_direction_deg: 0.0,
            density: 1.0,
            seed: 1,
        },
        plants,
        stream_fps: 30.0,
        history_frames: 64,
        publish_hz: 60,
        plant_elements: vec![],
    }
}
