//! Criterion micro-benchmarks of the pose socket's framing: encoding one `Pose` into a reused
//! buffer (what each subscriber writer does per frame) and decoding it (what each subscriber
//! does). `cargo bench -p frond-protocol`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use frond_protocol::{ElementId, HandWire, Pose, PoseFlags, ServerMessage, decode_frame, encode_frame};

fn pose() -> Pose {
    Pose {
        seq: 123_456,
        device_time_us: 987_654_321,
        host_monotonic_ns: 12_345_678_901_234,
        flags: PoseFlags::FILTERED,
        element: ElementId::GLOBAL,
        joints_deg: [[12.5, -3.25, 0.0], [6.0, -1.5, 0.0], [6.0, -1.5, 4.0], [3.5, -0.5, 4.0]],
        hand: HandWire { t: 12.345, wrist_deg: [12.5, -3.25, 4.0], thumb_deg: [25.0, 30.0, 35.0] },
    }
}

fn framing(c: &mut Criterion) {
    let msg = ServerMessage::Pose(pose());
    let mut buf = Vec::with_capacity(4096);
    c.bench_function("encode_frame pose (reused buffer)", |b| {
        b.iter(|| {
            buf.clear();
            encode_frame(black_box(&msg), &mut buf);
            black_box(buf.len())
        })
    });
    let mut bytes = Vec::new();
    encode_frame(&msg, &mut bytes);
    c.bench_function("decode_frame pose", |b| {
        b.iter(|| {
            let decoded: Option<(ServerMessage, usize)> =
                decode_frame(black_box(&bytes)).expect("valid frame");
            black_box(decoded)
        })
    });
}

criterion_group!(benches, framing);
criterion_main!(benches);
