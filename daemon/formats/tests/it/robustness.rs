//! `Mapper::process` and the parsers never panic, and finite input never gives NaN or infinity.

use frond_formats::jsonl::{parse_hand_line, parse_pose_line};
use frond_formats::rig_toml::{CalibrationText, RigText};
use frond_motion::{CalibrationParams, FilterSpec, HandSample, Mapper, MappingParams, Rig};
use proptest::prelude::*;

fn finite() -> impl Strategy<Value = f32> {
    prop_oneof![
        -1000.0f32..1000.0,
        prop::num::f32::NORMAL | prop::num::f32::SUBNORMAL | prop::num::f32::ZERO,
        Just(f32::MAX),
        Just(-f32::MAX),
    ]
}

fn positive() -> impl Strategy<Value = f32> {
    prop_oneof![
        0.1f32..500.0,
        prop::num::f32::POSITIVE.prop_filter("finite > 0", |v| v.is_finite() && *v > 0.0)
    ]
}

fn spec() -> impl Strategy<Value = FilterSpec> {
    prop_oneof![
        Just(FilterSpec::None),
        positive().prop_map(|cutoff_hz| FilterSpec::LowPass { cutoff_hz }),
        (positive(), prop_oneof![Just(0.0f32), positive()], positive())
            .prop_map(|(min_cutoff, beta, d_cutoff)| FilterSpec::OneEuro { min_cutoff, beta, d_cutoff }),
    ]
}

fn sample() -> impl Strategy<Value = HandSample> {
    (
        prop_oneof![-1e6f64..1e6, any::<f64>().prop_filter("finite", |t| t.is_finite())],
        [finite(), finite(), finite()],
        [finite(), finite(), finite()],
    )
        .prop_map(|(t, wrist_deg, thumb_deg)| HandSample { t, wrist_deg, thumb_deg })
}

fn all_finite(s: &HandSample, p: &frond_motion::PoseFrame) -> bool {
    s.wrist_deg.iter().chain(&s.thumb_deg).all(|v| v.is_finite())
        && p.joints_deg.iter().flatten().all(|v| v.is_finite())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn finite_input_gives_finite_output(
        scale in prop::array::uniform4([finite(), finite(), finite()]),
        tau in 0u8..=3,
        neutral_w in [finite(), finite(), finite()],
        neutral_g in [finite(), finite(), finite()],
        range in [positive(), positive(), positive()],
        bend in prop::option::of([positive(), positive()]),
        reach in prop::option::of([[positive(), positive()], [positive(), positive()]]),
        filter in spec(),
        samples in prop::collection::vec(sample(), 1..40),
    ) {
        let cal = CalibrationParams {
            neutral_wrist_deg: neutral_w,
            neutral_thumb_deg: neutral_g,
            thumb_range_deg: range,
            wrist_reach_deg: reach,
        };
        let mut m = Mapper::new(MappingParams { scale, tau, bend_range_deg: bend }, cal, filter);
        for s in &samples {
            let (c, p) = m.process(s);
            prop_assert!(all_finite(&c, &p), "{s:?} -> {c:?} {p:?}");
            prop_assert_eq!(p.t, s.t);
        }
    }

    #[test]
    fn any_input_never_panics(
        bits in prop::collection::vec((any::<u64>(), any::<[u32; 6]>()), 1..30),
        filter in spec(),
    ) {
        let mut m = Mapper::new(MappingParams::default(), CalibrationParams::neutral([60.0, 70.0, 60.0]), filter);
        for (t, v) in bits {
            let s = HandSample {
                t: f64::from_bits(t),
                wrist_deg: [f32::from_bits(v[0]), f32::from_bits(v[1]), f32::from_bits(v[2])],
                thumb_deg: [f32::from_bits(v[3]), f32::from_bits(v[4]), f32::from_bits(v[5])],
            };
            let _ = m.process(&s);
        }
    }

    #[test]
    fn non_finite_samples_do_not_poison_active_filters(
        filter in spec().prop_filter("active", |s| *s != FilterSpec::None),
        bad in prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY)],
    ) {
        let mut m = Mapper::new(MappingParams::default(), CalibrationParams::neutral([60.0, 70.0, 60.0]), filter);
        m.process(&HandSample { t: 0.0, wrist_deg: [1.0; 3], thumb_deg: [1.0; 3] });
        m.process(&HandSample { t: 0.001, wrist_deg: [bad; 3], thumb_deg: [bad; 3] });
        let (c, p) = m.process(&HandSample { t: 0.002, wrist_deg: [2.0; 3], thumb_deg: [2.0; 3] });
        prop_assert!(all_finite(&c, &p), "{c:?} {p:?}");
    }

    #[test]
    fn parsers_never_panic(s in ".{0,200}") {
        let _ = parse_hand_line(&s);
        let _ = parse_pose_line(&s);
        let _ = s.parse::<FilterSpec>();
        let _ = Rig::from_toml_str(&s);
        let _ = frond_motion::Calibration::from_toml_str(&s);
    }

    #[test]
    fn json_like_lines_never_panic(
        t in prop_oneof![Just("0".to_string()), Just("1e400".to_string()), Just("\"x\"".to_string()), Just("null".to_string()), "-?[0-9]{1,40}(\\.[0-9]{1,20})?(e-?[0-9]{1,3})?"],
        n in 0usize..6,
        v in "-?[0-9]{1,45}(\\.[0-9]{0,5})?",
    ) {
        let arr = vec![v.clone(); n].join(",");
        let line = format!(r#"{{"t":{t},"wrist":[{arr}],"thumb":[{arr}]}}"#);
        if let Ok(h) = parse_hand_line(&line) {
            prop_assert!(h.wrist_deg.iter().chain(&h.thumb_deg).all(|x| x.is_finite()));
            prop_assert!(h.t.is_finite());
        }
    }
}
