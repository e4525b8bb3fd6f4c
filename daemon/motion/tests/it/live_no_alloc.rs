//! The live building blocks the daemon may call on its realtime loop allocate nothing once built:
//! loop `Playback`, `DelayLine`, `GuidedLive`, `SwipeDetector` and a 1000-plant `FieldPlayer`.
//! Only allocations made by the test's own thread are counted (the harness's threads may
//! allocate at any time).

use frond_motion::clip::{Clip, DelayLine};
use frond_motion::controls::{ControlKey, FieldControls, SwipeDetector, SwipeParams};
use frond_motion::field_player::bench_field_1000;
use frond_motion::guided::{GuidedLive, GuidedParams};
use frond_motion::looping::{LoopParams, Playback, PlaybackParams, find_transitions};
use frond_motion::{HandSample, PoseFrame};

use crate::common;

#[test]
fn live_building_blocks_do_not_allocate_per_tick() {
    let clip = Clip::from_joints(
        (0..120).map(|k| {
            let s = (k as f32 * 0.2).sin() * 15.0;
            [[s, -s, 0.0], [s, 0.0, 0.0], [0.0, s, 2.0], [1.0, 2.0, 3.0]]
        }),
        30.0,
    );
    let t = find_transitions(&clip, &LoopParams::default()).unwrap();
    let mut playback = Playback::new(clip, &t, 3, PlaybackParams::default(), 0);
    let mut line = DelayLine::new(DelayLine::capacity_for(0.5, 1000.0));
    let mut guided =
        GuidedLive::new(GuidedParams { sigma_s: [0.1, 0.2, 0.3], s_g: [1.0; 3], g3_range_deg: 60.0 }, 1000.0);
    let mut swipe = SwipeDetector::new(SwipeParams::default());
    let (mut field, mut out) = bench_field_1000();
    let mut controls = FieldControls::default();
    field.frame(0.0, &mut out);

    let mut sink = 0.0f32;
    let ((), allocations) = common::allocations_in(|| {
        for tick in 0..5000u32 {
            let ts = tick as f64 / 1000.0;
            let j = playback.pose_at(ts);
            let pose = PoseFrame { t: ts, joints_deg: j };
            line.push(pose);
            sink += line.at_time(ts - 0.25).unwrap()[0][0];
            let hand = HandSample { t: ts, wrist_deg: [j[0][0], j[0][1], 0.0], thumb_deg: [0.0, 0.0, 30.0] };
            sink += guided.apply(&pose, &hand).joints_deg[3][0];
            if swipe.push(&hand).is_some() {
                sink += 1.0;
            }
            if tick % 33 == 0 {
                controls.key(if tick % 2 == 0 { ControlKey::Stronger } else { ControlKey::Weaker });
                field.set_controls(controls);
                field.frame(ts, &mut out);
                sink += out[999][3][0];
            }
        }
    });
    assert!(sink.is_finite());
    assert_eq!(allocations, 0, "allocations on the live path");
}
