//! The shipped rig and calibration files parse, validate and say what their comments say, and
//! the plants they describe behave (meshes, the simulated plant's defaults).

use frond_formats::rig_toml::{CalibrationText, RigText};
use frond_motion::{Calibration, FilterSpec, Rig};

const GRASS: &str = include_str!("../../../../rig-files/plants/grass.toml");
const FLOWER: &str = include_str!("../../../../rig-files/plants/flower.toml");
const SHRUB: &str = include_str!("../../../../rig-files/plants/shrub.toml");
const DEFAULT_CAL: &str = include_str!("../../../../rig-files/calibrations/default.toml");
const EXAMPLE_CAL: &str = include_str!("../../../../rig-files/calibrations/example-user.toml");

#[test]
fn grass_is_a_single_blade_with_tau_2() {
    let r = Rig::from_toml_str(GRASS).unwrap();
    assert_eq!(r.name, "grass");
    assert_eq!(r.tau, 2);
    assert!(r.elements.is_empty());
    assert!(matches!(r.filter, FilterSpec::OneEuro { .. }));
}

#[test]
fn flower_has_a_leaf_and_a_stiffer_root() {
    let f = Rig::from_toml_str(FLOWER).unwrap();
    let g = Rig::from_toml_str(GRASS).unwrap();
    assert_eq!(f.name, "flower");
    assert_eq!(f.elements.len(), 1);
    assert_eq!(f.elements[0].name, "leaf");
    assert!(f.joints[0].s_pitch < g.joints[0].s_pitch);
    assert!(f.joints[0].s_yaw < g.joints[0].s_yaw);
}

#[test]
fn shrub_is_stiff_with_tau_1() {
    let s = Rig::from_toml_str(SHRUB).unwrap();
    let g = Rig::from_toml_str(GRASS).unwrap();
    assert_eq!(s.tau, 1);
    for (a, b) in s.joints.iter().zip(&g.joints) {
        assert!(a.s_pitch < b.s_pitch && a.s_yaw < b.s_yaw && a.s_roll < b.s_roll);
    }
}

#[test]
fn shipped_rigs_round_trip() {
    for text in [GRASS, FLOWER, SHRUB] {
        let r = Rig::from_toml_str(text).unwrap();
        assert_eq!(Rig::from_toml_str(&r.to_toml_string()).unwrap(), r);
    }
}

#[test]
fn calibrations_parse_and_round_trip() {
    let d = Calibration::from_toml_str(DEFAULT_CAL).unwrap();
    assert_eq!(d.neutral_wrist_deg, [0.0; 3]);
    assert_eq!(d.neutral_thumb_deg, [0.0; 3]);
    let g = Rig::from_toml_str(GRASS).unwrap();
    // The default file agrees with what `--calibration` omitted means for the shipped rigs.
    assert_eq!(d.params(), Calibration::neutral_for(&g).params());
    let e = Calibration::from_toml_str(EXAMPLE_CAL).unwrap();
    assert_eq!(e.id, "example-user");
    assert!(e.wrist_range_deg.is_some());
    for c in [d, e] {
        assert_eq!(Calibration::from_toml_str(&c.to_toml_string()).unwrap(), c);
    }
}

#[test]
fn shipped_rigs_have_well_formed_procedural_meshes() {
    use frond_motion::mesh::procedural_model;
    use frond_motion::rig::{MeshShape, MeshSpec};
    for (text, shape, leaves) in
        [(GRASS, MeshShape::Blade, 0), (FLOWER, MeshShape::Flower, 2), (SHRUB, MeshShape::Shrub, 0)]
    {
        let r = Rig::from_toml_str(text).unwrap();
        assert!(matches!(r.mesh, MeshSpec::Procedural { shape: s, .. } if s == shape), "{}", r.name);
        let m = procedural_model(&r).unwrap();
        m.stem.check().unwrap();
        assert_eq!(m.elements.len(), leaves, "{}", r.name);
    }
    let g = procedural_model(&Rig::from_toml_str(GRASS).unwrap()).unwrap();
    let top = g.stem.positions.iter().map(|p| p[1]).fold(f32::MIN, f32::max);
    assert!((top - 0.30).abs() < 1e-6, "grass is 30 cm tall, found {top}");
}

/// The simulated plant (seed 003, section 4.2) with the defaults of each shipped rig's geometry.
#[test]
fn sim_defaults_keep_stretch_below_half_a_percent_and_bend_plausibly() {
    use frond_motion::sim::{PlantSim, WindSpec};
    // Every shipped rig without a [sim] table, in a strong gusty wind with gravity: the linear
    // springs keep every segment within 0.5 % of its rest length.
    let wind: WindSpec = "speed=25,dir=200,gust=1,seed=3".parse().unwrap();
    for (name, text) in [("grass", GRASS), ("flower", FLOWER), ("shrub", SHRUB)] {
        let rig = Rig::from_toml_str(text).unwrap();
        let mut p = rig.sim;
        p.gravity_m_s2 = 9.81;
        let mut sim = PlantSim::new(rig.sim_node_heights_m(), p, wind).unwrap();
        let mut worst: f64 = 0.0;
        for _ in 0..10_000 {
            sim.step().unwrap();
            worst = worst.max(sim.max_strain());
        }
        assert!(worst < 0.005, "{name}: stretch {worst}");
        assert!(worst > 0.0, "{name}: the springs do stretch a little");
        // A steady 5 m/s wind bends every joint by about 0.15 rad (the defaults' design, small
        // angles); the accumulated bend shortens the lever arms, so a little less.
        let mut sim = PlantSim::from_rig(&rig, WindSpec::steady(5.0, 0.0)).unwrap();
        let steps = (20.0 / sim.params().timestep_s).round() as usize;
        for _ in 0..steps {
            sim.step().unwrap();
        }
        for (j, a) in sim.pose().joints_deg.iter().enumerate() {
            let bend = -f64::from(a[1]).to_radians();
            assert!((0.1..=0.16).contains(&bend), "{name} joint {j}: {bend} rad");
        }
    }
}
