//! The per-tick work the realtime loop borrows from this crate allocates nothing: `Mapper::process`
//! for every filter kind, and encoding a Frame record into a buffer with room.
//! Only the test's own thread is counted: the test harness's threads may allocate meanwhile.

use frond_formats::take::{TakeRecord, encode_record};
use frond_motion::take::TakeFrame;
use frond_motion::{CalibrationParams, FilterSpec, HandSample, Mapper, MappingParams};
use frond_protocol::ElementId;

use crate::common;

#[test]
fn per_tick_work_does_not_allocate() {
    let specs = [FilterSpec::None, FilterSpec::LOWPASS_DEFAULT, FilterSpec::ONE_EURO_DEFAULT];
    let mut mappers = specs
        .map(|s| Mapper::new(MappingParams::default(), CalibrationParams::neutral([60.0, 70.0, 60.0]), s));
    let mut buf: Vec<u8> = Vec::with_capacity(128 * 1024); // room for 600 frames of 127 bytes
    let mut samples = [HandSample::default(); 200];
    for (k, s) in samples.iter_mut().enumerate() {
        let x = (k as f32 * 0.1).sin() * 30.0;
        *s = HandSample { t: k as f64 * 0.001, wrist_deg: [x, -x, x], thumb_deg: [x.abs(); 3] };
    }

    let ((), allocations) = common::allocations_in(|| {
        for s in &samples {
            for m in &mut mappers {
                let (hand, pose) = m.process(s);
                let frame = TakeFrame {
                    seq: 1,
                    device_time_us: 2,
                    host_ns: 3,
                    flags: 0,
                    element: ElementId::GLOBAL,
                    pose,
                    hand,
                };
                encode_record(&TakeRecord::Frame(frame), &mut buf);
            }
            m_set_filter_is_heap_free(&mut mappers[0]);
        }
    });
    assert_eq!(allocations, 0, "allocations during {} ticks", samples.len());
    assert!(!buf.is_empty());
}

/// Control-plane swaps the loop applies between ticks must not allocate either.
fn m_set_filter_is_heap_free(m: &mut Mapper) {
    m.set_filter(FilterSpec::None);
    m.set_mapping(MappingParams::default());
    m.set_calibration(CalibrationParams::neutral([60.0, 70.0, 60.0]));
}
