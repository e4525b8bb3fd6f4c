//! The simulated plant checked against hand-computed physics (values worked out in the comments,
//! independent of the code). The `[sim]` table of rig files is tested with their reader, in
//! frond-formats (`tests/it/rig_toml/sim.rs`); the shipped rigs' defaults in `tests/it/rig_files.rs`.

use glam::{DVec3, Vec3};

use super::*;
use crate::rig::{MeshShape, MeshSpec, Rig};
use crate::skeleton::Skeleton;

const HEIGHTS: [f64; NODES] = [0.0, 0.1, 0.2, 0.3, 0.4];

fn params(heights: [f64; NODES]) -> SimParams {
    SimParams::defaults_for(heights)
}

fn settle(sim: &mut PlantSim, seconds: f64) {
    let steps = (seconds / sim.params().timestep_s).round() as usize;
    for _ in 0..steps {
        sim.step().unwrap();
    }
}

#[test]
fn sim_static_bend_under_a_steady_wind_matches_small_angle_statics() {
    // Nodes at 0.1, 0.2, 0.3 (joints 1..3) and 0.4 m (top), each with drag 0.01 N s/m, in a
    // steady 1 m/s wind: at rest every node feels F = 0.01 N along the wind. Small angles: joint
    // j bends by the torque of the forces above it over its stiffness:
    //   tau_0 = 0.01 (0.1 + 0.2 + 0.3 + 0.4) = 0.010 N m, k_0 = 0.5  -> 0.0200 rad
    //   tau_1 = 0.01 (0.1 + 0.2 + 0.3)       = 0.006 N m, k_1 = 0.6  -> 0.0100 rad
    //   tau_2 = 0.01 (0.1 + 0.2)             = 0.003 N m, k_2 = 0.6  -> 0.0050 rad
    //   tau_3 = 0.01 (0.1)                   = 0.001 N m, k_3 = 0.4  -> 0.0025 rad
    // The top is then displaced along the wind by sum L_i sin(theta_0 + .. + theta_i), small angles
    // 0.1 (0.02 + 0.03 + 0.035 + 0.0375) = 0.01225 m.
    let want_rad = [0.02, 0.01, 0.005, 0.0025];
    let mut p = params(HEIGHTS);
    p.drag_ns_per_m = [0.01; 4];
    p.bend_stiffness_nm_per_rad = [0.5, 0.6, 0.6, 0.4];
    p.bend_damping_nms_per_rad = [0.02, 0.01, 0.005, 0.002];
    p.timestep_s = 0.01;
    // Wind towards +X (dir 0): frond's yaw 90 takes +Y to -X, so the bend is a negative yaw.
    // Wind towards +Z (dir 90): pitch 90 takes +Y to +Z, a positive pitch.
    for (dir, axis, sign) in [(0.0, 1, -1.0), (90.0, 0, 1.0)] {
        let mut sim = PlantSim::new(HEIGHTS, p, WindSpec::steady(1.0, dir)).unwrap();
        settle(&mut sim, 30.0);
        let pose = sim.pose();
        for (j, (angles, want)) in pose.joints_deg.iter().zip(want_rad).enumerate() {
            let got = f64::from(angles[axis]).to_radians() * sign;
            let other = angles[1 - axis];
            // Within 0.5 %: the lever arms shorten by cos(0.0375) ~ 0.9993 at most, and
            // k sin(theta) differs from k theta by theta^2 / 6 < 1e-4.
            assert!((got - want).abs() < 0.005 * want, "dir {dir} joint {j}: {got} vs {want}");
            assert!(other.abs() < 1e-4, "dir {dir} joint {j}: no bend across the wind, found {other}");
        }
        let top = sim.positions_m()[4];
        let along = if dir == 0.0 { top.x } else { top.z };
        assert!((along - 0.01225).abs() < 0.005 * 0.01225, "dir {dir}: top at {top}");
        assert!(sim.velocities_m_s().iter().all(|v| v.length() < 1e-6), "settled");
    }
}

#[test]
fn sim_single_segment_period_is_two_pi_sqrt_i_over_k() {
    // Joints 0..2 nearly rigid (1000 N m/rad), the top segment (joint 3 at 0.3 m, top at 0.5 m,
    // L = 0.2 m) carries m = 0.01 kg at its end with k = 0.004 N m/rad and no damping or drag.
    // A point mass: I = m L^2 = 0.01 * 0.04 = 4e-4 kg m^2; omega = sqrt(k / I) = sqrt(10)
    // = 3.16228 rad/s; T = 2 pi / omega = 1.98692 s.
    let heights = [0.0, 0.1, 0.2, 0.3, 0.5];
    let mut p = params(heights);
    p.mass_kg = [4.0, 2.0, 1.0, 0.01];
    p.bend_stiffness_nm_per_rad = [1000.0, 1000.0, 1000.0, 0.004];
    p.bend_damping_nms_per_rad = [10.0, 10.0, 10.0, 0.0];
    p.drag_ns_per_m = [0.0; 4];
    p.timestep_s = 0.001;
    let mut sim = PlantSim::new(heights, p, WindSpec::CALM).unwrap();
    sim.set_pose(&[[0.0; 3], [0.0; 3], [0.0; 3], [0.0, 2.0, 0.0]]);
    // Upward zero crossings of joint 3's yaw (it starts at +2 degrees, at rest).
    let mut crossings = Vec::new();
    let mut prev = sim.pose().joints_deg[3][1];
    while sim.time_s() < 7.0 {
        sim.step().unwrap();
        let now = sim.pose().joints_deg[3][1];
        if prev < 0.0 && now >= 0.0 {
            // Linear interpolation of the crossing time within the step.
            let h = sim.params().timestep_s;
            crossings.push(sim.time_s() - h * f64::from(now / (now - prev)));
        }
        prev = now;
    }
    assert!(crossings.len() >= 3, "{crossings:?}");
    let periods = crossings.len() - 1;
    let period = (crossings[periods] - crossings[0]) / periods as f64;
    // Implicit Euler lengthens the period by about (omega h)^2 / 3 = 3e-6; the stiff lower
    // joints give way by k / 1000 relative: 0.1 % is ample.
    assert!((period - 1.98692).abs() < 0.001 * 1.98692, "period {period} s, want 1.98692 s");
}

#[test]
fn sim_bend_damping_decays_a_single_segment_at_kd_over_2i() {
    // The segment of the period test (I = 4e-4 kg m^2, k = 0.004 N m/rad, omega = sqrt(10))
    // with damping ratio 0.05: kd = 2 * 0.05 * sqrt(k I) = 2 * 0.05 * 1.26491e-3
    // = 1.26491e-4 N m s/rad. The amplitude decays at sigma = kd / (2 I) = 0.158114 /s; the
    // damped period is T_d = 1.98692 / sqrt(1 - 0.05^2) = 1.98941 s, so successive peaks are
    // in the ratio exp(-sigma T_d) = exp(-0.314553) = 0.730116. Implicit Euler adds its own
    // damping, exp(-omega^2 h T_d / 2) = exp(-0.0099470) = 0.990102 per period: 0.722889.
    let heights = [0.0, 0.1, 0.2, 0.3, 0.5];
    let mut p = params(heights);
    p.mass_kg = [4.0, 2.0, 1.0, 0.01];
    p.bend_stiffness_nm_per_rad = [1000.0, 1000.0, 1000.0, 0.004];
    p.bend_damping_nms_per_rad = [10.0, 10.0, 10.0, 1.26491e-4];
    p.drag_ns_per_m = [0.0; 4];
    let mut sim = PlantSim::new(heights, p, WindSpec::CALM).unwrap();
    sim.set_pose(&[[0.0; 3], [0.0; 3], [0.0; 3], [0.0, 2.0, 0.0]]);
    let mut peaks = Vec::new();
    let (mut a, mut b) = (f32::MIN, sim.pose().joints_deg[3][1]);
    while sim.time_s() < 6.5 {
        sim.step().unwrap();
        let c = sim.pose().joints_deg[3][1];
        if b > a && b >= c && b > 0.0 {
            peaks.push(f64::from(b));
        }
        (a, b) = (b, c);
    }
    assert!(peaks.len() >= 3, "{peaks:?}");
    for w in peaks.windows(2) {
        let ratio = w[1] / w[0];
        assert!((ratio - 0.722889).abs() < 0.001, "peak ratio {ratio}, want 0.722889 ({peaks:?})");
    }
}

fn bent_sim(p: SimParams) -> PlantSim {
    let mut sim = PlantSim::new(HEIGHTS, p, WindSpec::CALM).unwrap();
    sim.set_pose(&[[10.0, -20.0, 0.0], [-15.0, 5.0, 0.0], [25.0, 30.0, 0.0], [-30.0, 10.0, 0.0]]);
    sim.set_velocity(4, DVec3::new(0.3, 0.0, -0.2));
    sim
}

#[test]
fn sim_energy_never_grows_without_wind() {
    // No wind and no damping at all: the exact motion keeps its energy, and implicit Euler may
    // only lose some. With gravity and damping it must lose energy too.
    for (gravity, damped, angular) in [
        (0.0, false, AngularForm::Bending),
        (9.81, false, AngularForm::Bending),
        (9.81, true, AngularForm::Bending),
        (0.0, false, AngularForm::Paper),
    ] {
        for dt in [0.001, 0.02] {
            let mut p = params(HEIGHTS);
            p.gravity_m_s2 = gravity;
            p.timestep_s = dt;
            p.angular = angular;
            if !damped {
                p.bend_damping_nms_per_rad = [0.0; 4];
                p.stretch_damping_ns_per_m = [0.0; 4];
                p.drag_ns_per_m = [0.0; 4];
            }
            let mut sim = bent_sim(p);
            let e0 = sim.energy_j();
            assert!(e0 > 0.0);
            let mut prev = e0;
            for k in 0..(5.0 / dt) as usize {
                sim.step().unwrap();
                let e = sim.energy_j();
                assert!(
                    e <= prev + 1e-9 * e0.abs(),
                    "g {gravity} damped {damped} {angular:?} dt {dt}: energy grew at step {k}: {prev} -> {e}"
                );
                prev = e;
            }
        }
    }
}

#[test]
fn sim_is_stable_at_large_steps_and_stiff_springs() {
    // The largest step and the stiffest springs allowed, light masses and a strong gusty wind:
    // explicit Euler would blow up (omega h = sqrt(1e9 / 1e-3) * 0.05 ~ 5e4); implicit Euler
    // must stay finite, keep the segments at their lengths and never bend past the wind.
    let mut p = params(HEIGHTS);
    p.timestep_s = 0.05;
    p.mass_kg = [1e-3; 4];
    p.stretch_stiffness_n_per_m = [1e9; 4];
    p.stretch_damping_ns_per_m = [0.0; 4];
    p.bend_stiffness_nm_per_rad = [1e3; 4];
    p.bend_damping_nms_per_rad = [0.0; 4];
    p.gravity_m_s2 = 9.81;
    let wind: WindSpec = "speed=40,dir=45,gust=1,seed=9".parse().unwrap();
    let mut sim = PlantSim::new(HEIGHTS, p, wind).unwrap();
    for _ in 0..2000 {
        sim.step().unwrap();
        assert!(sim.max_strain() < 0.005, "strain {}", sim.max_strain());
        assert!(sim.positions_m().iter().all(|x| x.is_finite() && x.length() < 1.0));
    }
    // Without wind afterwards, stiff or soft, it comes back to rest.
    let mut p2 = params(HEIGHTS);
    p2.timestep_s = 0.05;
    p2.stretch_stiffness_n_per_m = [1e9; 4];
    let mut sim = bent_sim(p2);
    settle(&mut sim, 60.0);
    let rest = sim.pose();
    for j in 0..4 {
        assert!(rest.joints_deg[j].iter().all(|a| a.abs() < 0.01), "{rest:?}");
    }
}

#[test]
fn sim_paper_form_has_no_first_order_restoring_torque_at_straight_rest() {
    // Bend only joint 3 (0.1 m below the top, rest straight) by theta with k = 0.1 N m/rad.
    // Bending form: E = k (1 - cos theta) ~ k theta^2 / 2: 5.0e-6 J at 0.01 rad, 4x at 0.02.
    // Paper form (Eq. 2, alpha = pi): C = |a||b| (1 - cos theta), k_s = k / (|a|^2 |b|^2), so
    // E = k (1 - cos theta)^2 / 2 ~ k theta^4 / 8: 1.25e-10 J at 0.01 rad, 16x at 0.02.
    let energy = |angular, theta_deg: f32| {
        let mut p = params(HEIGHTS);
        p.bend_stiffness_nm_per_rad[3] = 0.1;
        p.angular = angular;
        let mut sim = PlantSim::new(HEIGHTS, p, WindSpec::CALM).unwrap();
        sim.set_pose(&[[0.0; 3], [0.0; 3], [0.0; 3], [theta_deg, 0.0, 0.0]]);
        sim.energy_j()
    };
    let one = 0.01f32.to_degrees();
    let two = 0.02f32.to_degrees();
    let (b1, b2) = (energy(AngularForm::Bending, one), energy(AngularForm::Bending, two));
    let (p1, p2) = (energy(AngularForm::Paper, one), energy(AngularForm::Paper, two));
    assert!((b1 - 5.0e-6).abs() < 1e-3 * 5.0e-6, "{b1}");
    assert!((b2 / b1 - 4.0).abs() < 1e-3, "{}", b2 / b1);
    assert!((p1 - 1.25e-10).abs() < 1e-3 * 1.25e-10, "{p1}");
    assert!((p2 / p1 - 16.0).abs() < 1e-2, "{}", p2 / p1);
    // So the same wind bends the paper form's plant much further.
    let bend = |angular| {
        let mut p = params(HEIGHTS);
        p.angular = angular;
        p.timestep_s = 0.01;
        let mut sim = PlantSim::new(HEIGHTS, p, WindSpec::steady(1.0, 0.0)).unwrap();
        settle(&mut sim, 20.0);
        sim.positions_m()[4].x
    };
    let (b, p) = (bend(AngularForm::Bending), bend(AngularForm::Paper));
    assert!(b > 0.0 && p > 3.0 * b, "bending {b} m, paper {p} m");
}

#[test]
fn sim_read_back_pose_reproduces_the_node_directions_by_forward_kinematics() {
    // A gusty wind from an oblique direction bends the plant in 3D; at every sampled moment the
    // skeleton's forward kinematics of the read-back pose (rest lengths) must point each segment
    // where the simulation's nodes do: joint origins for segments 0..2, joint 3's +Y for the top.
    let wind: WindSpec = "speed=12,dir=-60,gust=1,seed=5".parse().unwrap();
    let mut sim = PlantSim::new(HEIGHTS, params(HEIGHTS), wind).unwrap();
    let skeleton = Skeleton { heights_m: [0.0, 0.1, 0.2, 0.3] };
    let mut largest_bend: f32 = 0.0;
    for k in 0..4000 {
        sim.step().unwrap();
        if k % 100 != 0 {
            continue;
        }
        let pose = sim.pose();
        assert!(pose.joints_deg.iter().all(|a| a[2] == 0.0), "roll 0");
        largest_bend = pose.joints_deg.iter().flatten().fold(largest_bend, |m, a| m.max(a.abs()));
        let world = skeleton.joint_matrices(&pose.joints_deg);
        let x = sim.positions_m();
        for i in 0..4 {
            let want = (x[i + 1] - x[i]).normalize().as_vec3();
            let got = if i < 3 {
                (world[i + 1].transform_point3(Vec3::ZERO) - world[i].transform_point3(Vec3::ZERO))
                    .normalize()
            } else {
                world[3].transform_vector3(Vec3::Y).normalize()
            };
            assert!((got - want).length() < 1e-5, "step {k} segment {i}: {got} vs {want}");
        }
    }
    assert!(largest_bend > 5.0, "the test must bend the plant: {largest_bend}");
}

#[test]
fn sim_set_pose_then_read_back_gives_the_pose() {
    // With roll 0 the read-back angles are the pose's own (pitch within ±90).
    let joints = [[10.0, -20.0, 0.0], [-15.0, 5.0, 0.0], [25.0, 30.0, 0.0], [-30.0, 10.0, 0.0]];
    let mut sim = PlantSim::new(HEIGHTS, params(HEIGHTS), WindSpec::CALM).unwrap();
    sim.set_pose(&joints);
    let got = sim.pose().joints_deg;
    for j in 0..4 {
        for a in 0..3 {
            assert!((got[j][a] - joints[j][a]).abs() < 1e-4, "{got:?}");
        }
    }
    assert!(sim.max_strain() < 1e-12);
}

#[test]
fn sim_is_deterministic_for_a_seed() {
    let run = |seed| {
        let wind = WindSpec { speed_m_s: 8.0, dir_deg: 10.0, gust: 0.8, seed, until_s: Some(1.0) };
        let mut sim = PlantSim::new(HEIGHTS, params(HEIGHTS), wind).unwrap();
        settle(&mut sim, 1.5);
        sim.pose()
    };
    assert_eq!(run(1), run(1));
    assert_ne!(run(1), run(2));
}

#[test]
fn sim_refuses_bad_parameters_and_heights() {
    let mut p = params(HEIGHTS);
    p.mass_kg[2] = -1.0;
    p.timestep_s = 1.0;
    p.drag_ns_per_m[0] = f64::NAN;
    let Err(SimError::Invalid(problems)) = PlantSim::new(HEIGHTS, p, WindSpec::CALM) else { panic!() };
    assert_eq!(problems.paths(), ["sim.mass_kg[2]", "sim.drag_ns_per_m[0]", "sim.timestep_s"]);
    let e = PlantSim::new([0.0, 0.1, 0.1, 0.3, 0.4], params(HEIGHTS), WindSpec::CALM).unwrap_err();
    assert!(matches!(e, SimError::Heights(_)), "{e}");
}

#[test]
fn sim_simulate_gives_the_frames_asked_for_and_refuses_too_many() {
    // Joints at 0, 0.1, 0.2 and 0.3 m, the mesh's top at 0.4 m, no `[sim]` table.
    let mesh = MeshSpec::Procedural { shape: MeshShape::Blade, width_m: 0.012, height_m: Some(0.4) };
    let rig = Rig::for_tests("g", [0.0, 0.1, 0.2, 0.3], mesh);
    let wind: WindSpec = "speed=6,dir=0,gust=0.5,seed=1,until=0.5".parse().unwrap();
    let frames = simulate(&rig, &rig.sim, wind, 1.0, 30.0).unwrap();
    // t = 0, 1/30, ..., 30/30: 31 frames, the first at rest.
    assert_eq!(frames.len(), 31);
    assert_eq!(frames[0].joints_deg, [[0.0; 3]; 4]);
    for (k, f) in frames.iter().enumerate() {
        assert_eq!(f.t, k as f64 / 30.0);
    }
    assert!(frames[15].joints_deg[0][1] < -1.0, "bent by the wind: {:?}", frames[15]);
    // The same as stepping by hand (0.001 s steps; frame 15 at t = 0.5 s is after 500 steps).
    let mut sim = PlantSim::from_rig(&rig, wind).unwrap();
    for _ in 0..500 {
        sim.step().unwrap();
    }
    assert_eq!(sim.pose().joints_deg, frames[15].joints_deg);

    assert_eq!(
        simulate(&rig, &rig.sim, wind, 3600.0, 300.0).unwrap_err(),
        SimError::TooManyFrames { frames: 1_080_001 }
    );
    assert!(matches!(
        simulate(&rig, &rig.sim, wind, -1.0, 30.0),
        Err(SimError::Argument { what: "duration_s", .. })
    ));
    assert!(matches!(simulate(&rig, &rig.sim, wind, 1.0, 0.0), Err(SimError::Argument { what: "fps", .. })));
    let mut p = rig.sim;
    p.timestep_s = 1e-5;
    assert!(matches!(simulate(&rig, &p, wind, 3000.0, 1.0), Err(SimError::TooManySteps { .. })));
    p.timestep_s = 0.0;
    assert!(matches!(simulate(&rig, &p, wind, 1.0, 1.0), Err(SimError::Invalid(_))));
}
