//! Counting-allocator test: once made, the decoder allocates nothing per sample or per frame,
//! through lock, frames, a jump and a loss.

use frond_alloc_count::{CountingAlloc, count_allocations};
use frond_ltc::encode::{edges, labels, render};
use frond_ltc::{FrameRate, LtcDecoder, LtcEvent};

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

#[test]
fn decoding_allocates_nothing() {
    let rate = FrameRate::Fps2997Df;
    let mut sent = labels(rate, 1_790, 20);
    sent.extend(labels(rate, 9_000, 20));
    let with_user: Vec<_> = sent.iter().map(|&t| (t, 0xABCD)).collect();
    let mut samples = render(&edges(rate, &with_user), 48_000, 40.5 / rate.fps(), 0.5);
    samples.extend(std::iter::repeat_n(0.0, 48_000 / 5));
    let mut decoder = LtcDecoder::new(48_000).unwrap();
    let mut kinds = [0u32; 4];
    let ((), allocations) = count_allocations(|| {
        decoder.process_f32(&samples, |e| {
            let k = match e {
                LtcEvent::Frame(_) => 0,
                LtcEvent::Locked { .. } => 1,
                LtcEvent::Jump { .. } => 2,
                LtcEvent::Lost { .. } => 3,
            };
            kinds[k] += 1;
        })
    });
    assert_eq!(allocations, 0);
    assert_eq!(kinds[1..], [1, 1, 1], "one lock, one jump, one loss");
    assert!(kinds[0] >= 38, "{} frames", kinds[0]);
}
