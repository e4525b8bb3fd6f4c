//! Seed 000, Eq. 2-4, against values worked out by hand (in the comments), through `map_pose`
//! and through `Mapper::process` with a calibration offset.

use frond_formats::rig_toml::{CalibrationText, RigText};
use frond_motion::{
    Calibration, CalibrationParams, FilterSpec, HandSample, Mapper, MappingParams, Rig, map_pose,
};

fn hand(t: f64, wrist: [f32; 3], thumb: [f32; 3]) -> HandSample {
    HandSample { t, wrist_deg: wrist, thumb_deg: thumb }
}

// Non-default per-joint scales [s_pitch, s_yaw, s_roll], ranges G_R = [40, 80, 50],
// calibrated hand W = [-30, 12, -20], G = [20, -40, 25]. All values are exact binary fractions.
const SCALE: [[f32; 3]; 4] = [[0.5, 2.0, 1.5], [1.0, 0.5, 3.0], [2.0, 1.0, 0.25], [0.25, 4.0, 2.0]];
const RANGE: [f32; 3] = [40.0, 80.0, 50.0];
const W: [f32; 3] = [-30.0, 12.0, -20.0];
const G: [f32; 3] = [20.0, -40.0, 25.0];

// Eq. 2: P_pitch(0) = 0.5 * -30 = -15; P_yaw(0) = 2 * 12 = 24.
// G_i / G_R_i = 20/40 = 0.5, -40/80 = -0.5, 25/50 = 0.5.
// Eq. 3: joint 1: pitch 1.0 * -15 * 0.5 = -7.5,   yaw 0.5 * 24 * 0.5 = 6
//        joint 2: pitch 2.0 * -15 * -0.5 = 15,    yaw 1.0 * 24 * -0.5 = -12
//        joint 3: pitch 0.25 * -15 * 0.5 = -1.875, yaw 4.0 * 24 * 0.5 = 48
// Eq. 4 with W_roll = -20: roll(1) = 3.0 * -20 = -60, roll(2) = 0.25 * -20 = -5,
//        roll(3) = 2.0 * -20 = -40, applied only to joints i > 3 - tau.
const PITCH_YAW: [[f32; 2]; 4] = [[-15.0, 24.0], [-7.5, 6.0], [15.0, -12.0], [-1.875, 48.0]];
const ROLL_IF_TWISTING: [f32; 4] = [-30.0, -60.0, -5.0, -40.0];

fn expected(tau: u8) -> [[f32; 3]; 4] {
    let mut out = [[0.0; 3]; 4];
    for i in 0..4 {
        out[i][0] = PITCH_YAW[i][0];
        out[i][1] = PITCH_YAW[i][1];
        // Eq. 4: P_roll(i) = 0 for i <= 3 - tau.
        out[i][2] = if i as i32 > 3 - tau as i32 { ROLL_IF_TWISTING[i] } else { 0.0 };
    }
    out
}

#[test]
fn eq_2_to_4_tau_0_to_3() {
    let tables = [
        // tau 0: no joint twists.
        [[-15.0, 24.0, 0.0], [-7.5, 6.0, 0.0], [15.0, -12.0, 0.0], [-1.875, 48.0, 0.0]],
        // tau 1: only the top joint.
        [[-15.0, 24.0, 0.0], [-7.5, 6.0, 0.0], [15.0, -12.0, 0.0], [-1.875, 48.0, -40.0]],
        // tau 2: joints 2 and 3.
        [[-15.0, 24.0, 0.0], [-7.5, 6.0, 0.0], [15.0, -12.0, -5.0], [-1.875, 48.0, -40.0]],
        // tau 3: joints 1..3; the root never twists.
        [[-15.0, 24.0, 0.0], [-7.5, 6.0, -60.0], [15.0, -12.0, -5.0], [-1.875, 48.0, -40.0]],
    ];
    for (tau, want) in tables.iter().enumerate() {
        let params = MappingParams { scale: SCALE, tau: tau as u8, bend_range_deg: None };
        let p = map_pose(&params, &CalibrationParams::neutral(RANGE), &hand(2.5, W, G));
        assert_eq!(p.t, 2.5);
        assert_eq!(&p.joints_deg, want, "tau {tau}");
        // The table and the formula-driven expectation agree.
        assert_eq!(&expected(tau as u8), want);
    }
}

#[test]
fn calibration_offset_through_the_mapper() {
    // Neutral wrist [5, -3, 10], neutral thumb [10, 5, -5], G_R [60, 70, 60], unit scales, tau 2.
    // Raw wrist [35, -33, -50], thumb [40, 40, 10]
    //   -> W = [30, -30, -60], G = [30, 35, 15], G/G_R = 0.5, 0.5, 0.25.
    // Eq. 2: P0 = (30, -30). Eq. 3: P1 = P2 = (15, -15), P3 = (7.5, -7.5).
    // Eq. 4 (tau 2): roll = 0, 0, -60, -60.
    let cal = CalibrationParams {
        neutral_wrist_deg: [5.0, -3.0, 10.0],
        neutral_thumb_deg: [10.0, 5.0, -5.0],
        thumb_range_deg: [60.0, 70.0, 60.0],
        wrist_reach_deg: None,
    };
    let mut m = Mapper::new(MappingParams::default(), cal, FilterSpec::None);
    let (calibrated, pose) = m.process(&hand(0.04, [35.0, -33.0, -50.0], [40.0, 40.0, 10.0]));
    assert_eq!(calibrated, hand(0.04, [30.0, -30.0, -60.0], [30.0, 35.0, 15.0]));
    assert_eq!(pose.t, 0.04);
    assert_eq!(
        pose.joints_deg,
        [[30.0, -30.0, 0.0], [15.0, -15.0, 0.0], [15.0, -15.0, -60.0], [7.5, -7.5, -60.0]]
    );
}

#[test]
fn shipped_shrub_by_hand() {
    // shrub.toml: s_pitch = s_yaw = 0.2, 0.4, 0.5, 0.6; s_roll = 0.3 everywhere; tau 1;
    // G_R = [60, 70, 60]. W = [50, -25, 40], G = [30, 35, 60] -> ratios 0.5, 0.5, 1.
    // Eq. 2: P0 = (0.2*50, 0.2*-25) = (10, -5).
    // Eq. 3: P1 = 0.4*(10,-5)*0.5 = (2, -1); P2 = 0.5*(10,-5)*0.5 = (2.5, -1.25);
    //        P3 = 0.6*(10,-5)*1 = (6, -3).
    // Eq. 4 (tau 1; equal s_roll so it is the seed's s_roll(0) * W_roll): roll(3) = 0.3*40 = 12.
    let rig = Rig::from_toml_str(include_str!("../../../../rig-files/plants/shrub.toml")).unwrap();
    let cal = Calibration::neutral_for(&rig);
    let mut m = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    let (_, p) = m.process(&hand(1.0, [50.0, -25.0, 40.0], [30.0, 35.0, 60.0]));
    let want = [[10.0, -5.0, 0.0], [2.0, -1.0, 0.0], [2.5, -1.25, 0.0], [6.0, -3.0, 12.0]];
    for (g, w) in p.joints_deg.iter().flatten().zip(want.iter().flatten()) {
        // The decimal scales (0.2, 0.3, ...) are not exact in binary.
        assert!((g - w).abs() < 1e-5, "{:?}", p.joints_deg);
    }
}

#[test]
fn upper_joints_follow_the_root_direction() {
    // Eq. 3 multiplies by P(0): with the wrist straight the upper joints do not bend at all,
    // however far the thumb bends.
    let p = map_pose(
        &MappingParams::default(),
        &CalibrationParams::neutral(RANGE),
        &hand(0.0, [0.0, 0.0, 0.0], [40.0, 80.0, 50.0]),
    );
    assert_eq!(p.joints_deg, [[0.0; 3]; 4]);
    // Negative wrist pitch with a full thumb: every joint bends the same (negative) way.
    let p = map_pose(
        &MappingParams::default(),
        &CalibrationParams::neutral(RANGE),
        &hand(0.0, [-10.0, 0.0, 0.0], [40.0, 80.0, 50.0]),
    );
    assert_eq!(p.joints_deg.map(|j| j[0]), [-10.0, -10.0, -10.0, -10.0]);
}

#[test]
fn filter_none_is_the_identity_in_the_mapper() {
    let cal = CalibrationParams::neutral([60.0, 70.0, 60.0]);
    let mut m = Mapper::new(MappingParams::default(), cal, FilterSpec::None);
    for k in 0..100 {
        let x = (k as f32 * 0.37).sin() * 40.0;
        let s = hand(k as f64 / 1000.0, [x, -x, 0.5 * x], [x.abs(), 3.0, -x]);
        let (c, p) = m.process(&s);
        assert_eq!(c, s);
        assert_eq!(p, map_pose(&MappingParams::default(), &cal, &s));
    }
}

#[test]
fn set_filter_resets_and_set_calibration_applies() {
    let cal = CalibrationParams::neutral([60.0, 70.0, 60.0]);
    let mut m = Mapper::new(MappingParams::default(), cal, FilterSpec::LOWPASS_DEFAULT);
    m.process(&hand(0.0, [0.0; 3], [0.0; 3]));
    let (c, _) = m.process(&hand(0.01, [10.0; 3], [0.0; 3]));
    assert!(c.wrist_deg[0] > 0.0 && c.wrist_deg[0] < 10.0); // smoothed
    m.set_filter(FilterSpec::ONE_EURO_DEFAULT);
    assert_eq!(m.filter_spec(), FilterSpec::ONE_EURO_DEFAULT);
    let (c, _) = m.process(&hand(0.02, [10.0; 3], [0.0; 3]));
    assert_eq!(c.wrist_deg, [10.0; 3]); // fresh filter: first sample passes
    m.set_filter(FilterSpec::None);
    m.set_calibration(CalibrationParams { neutral_wrist_deg: [1.0, 2.0, 3.0], ..cal });
    let (c, _) = m.process(&hand(0.03, [10.0; 3], [0.0; 3]));
    assert_eq!(c.wrist_deg, [9.0, 8.0, 7.0]);
}

// Two performers with different neutrals and comfortable ranges (seed 000, section 5.4).
// Alice: wrist pitch -56..64 around 4 (reach 60 / 60), yaw -23..27 around -3 (20 / 30).
// Bob:   wrist pitch -40..20 around -10 (30 / 30), yaw -14..46 around 6 (20 / 40).
const ALICE: &str = r#"
id = "alice"
neutral_wrist_deg = [4, -3, 2]
neutral_thumb_deg = [8, 5, 3]
thumb_range_deg = [45, 60, 75]
wrist_range_deg = [[-56, 64], [-23, 27], [-75, 85]]
"#;
const BOB: &str = r#"
id = "bob"
neutral_wrist_deg = [-10, 6, 0]
neutral_thumb_deg = [0, 0, 0]
thumb_range_deg = [60, 70, 60]
wrist_range_deg = [[-40, 20], [-14, 46], [-50, 50]]
"#;

/// A raw sample at the performer's comfortable extremes: pitch at `pitch_end` (0 = min,
/// 1 = max), yaw at the other end, roll at neutral, every thumb joint bent through its range.
fn at_extremes(cal: &Calibration, pitch_end: usize) -> HandSample {
    let r = cal.wrist_range_deg.unwrap();
    let n = cal.neutral_wrist_deg;
    hand(
        1.0,
        [r[0][pitch_end], r[1][1 - pitch_end], n[2]],
        std::array::from_fn(|i| cal.neutral_thumb_deg[i] + cal.thumb_range_deg[i]),
    )
}

#[test]
fn two_performers_drive_the_shrub_to_the_same_extremes() {
    // shrub.toml: bend_range_deg = [12, 12]; s_pitch = s_yaw = 0.2, 0.4, 0.5, 0.6; tau 1.
    // At the extremes, with G_i = G_R_i (ratio 1):
    //   pitch max / yaw min: P0 = (12, -12); Eq. 3: P1 = 0.4 P0 = (4.8, -4.8),
    //   P2 = 0.5 P0 = (6, -6), P3 = 0.6 P0 = (7.2, -7.2); roll at neutral: 0.
    //   pitch min / yaw max: the negatives.
    let rig = Rig::from_toml_str(include_str!("../../../../rig-files/plants/shrub.toml")).unwrap();
    assert_eq!(rig.bend_range_deg, Some([12.0, 12.0]));
    let (alice, bob) = (Calibration::from_toml_str(ALICE).unwrap(), Calibration::from_toml_str(BOB).unwrap());
    let want = [[12.0, -12.0, 0.0], [4.8, -4.8, 0.0], [6.0, -6.0, 0.0], [7.2, -7.2, 0.0]];
    let close = |a: &[[f32; 3]; 4], b: &[[f32; 3]; 4]| {
        a.iter().flatten().zip(b.iter().flatten()).all(|(x, y)| (x - y).abs() < 1e-4)
    };
    for (end, sign) in [(1, 1.0f32), (0, -1.0)] {
        let want = want.map(|j| j.map(|v| sign * v));
        for cal in [&alice, &bob] {
            let mut m = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
            let (_, p) = m.process(&at_extremes(cal, end));
            assert!(close(&p.joints_deg, &want), "{} end {end}: {:?}", cal.id, p.joints_deg);
        }
    }
    // Half way to the extreme is half the bend for both: Alice +30 of 60, Bob +15 of 30 -> 6.
    let mut m = Mapper::new(rig.mapping(), alice.params(), FilterSpec::None);
    let (_, a) = m.process(&hand(2.0, [4.0 + 30.0, -3.0, 2.0], [8.0, 5.0, 3.0]));
    // The live path swaps the calibration in place (frond calibration apply).
    m.set_calibration(bob.params());
    let (_, b) = m.process(&hand(2.0, [-10.0 + 15.0, 6.0, 0.0], [0.0; 3]));
    assert!(
        (a.joints_deg[0][0] - 6.0).abs() < 1e-5 && (b.joints_deg[0][0] - 6.0).abs() < 1e-5,
        "{a:?} {b:?}"
    );

    // Without the rig's bend range, Eq. 2 with s_pitch(0) = 0.2: Alice's +60 bends 12, Bob's +30
    // only 6 (the behaviour before calibration mapped the wrist).
    let plain = MappingParams { bend_range_deg: None, ..rig.mapping() };
    let root = |cal: &Calibration| {
        let mut m = Mapper::new(plain, cal.params(), FilterSpec::None);
        m.process(&at_extremes(cal, 1)).1.joints_deg[0][0]
    };
    assert!((root(&alice) - 12.0).abs() < 1e-4 && (root(&bob) - 6.0).abs() < 1e-4);
    // A calibration that did not measure the wrist keeps s_pitch(0) too: +30 -> 6.
    let no_wrist = Calibration { wrist_range_deg: None, ..bob.clone() };
    let mut m = Mapper::new(rig.mapping(), no_wrist.params(), FilterSpec::None);
    let (_, p) = m.process(&hand(0.0, [-10.0 + 30.0, 6.0, 0.0], [0.0; 3]));
    assert!((p.joints_deg[0][0] - 6.0).abs() < 1e-5, "{p:?}");
}
