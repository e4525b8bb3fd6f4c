//! The `[sim]` table of a rig file (seed 003, section 4.2): absent it gives the defaults for the
//! plant's geometry and is not written; given it is read, written back in full and validated
//! with every problem's path; the shipped rigs load and round-trip.

use frond_formats::rig_toml::RigText;
use frond_motion::sim::{AngularForm, SimParams};
use frond_motion::{Rig, RigError};

/// The shipped plant rigs, `(name, TOML text)` (the list `frond_formats::rig_files` builds in).
const EMBEDDED_RIGS: [(&str, &str); 3] = [
    ("grass", include_str!("../../../../../rig-files/plants/grass.toml")),
    ("flower", include_str!("../../../../../rig-files/plants/flower.toml")),
    ("shrub", include_str!("../../../../../rig-files/plants/shrub.toml")),
];

const BASE: &str = "name = \"g\"\n[[joints]]\nheight_m = 0.0\n[[joints]]\nheight_m = 0.1\n[[joints]]\nheight_m = 0.2\n[[joints]]\nheight_m = 0.3\n[mesh]\nheight_m = 0.4\n";

#[test]
fn sim_table_of_a_rig_parses_defaults_validates_and_round_trips() {
    // Absent: the defaults for the node heights 0, 0.1, 0.2, 0.3 and the mesh top 0.4.
    let rig = Rig::from_toml_str(BASE).unwrap();
    assert_eq!(rig.sim_node_heights_m(), [0.0, 0.1f32 as f64, 0.2f32 as f64, 0.3f32 as f64, 0.4f32 as f64]);
    assert_eq!(rig.sim, SimParams::defaults_for(rig.sim_node_heights_m()));
    assert!(!rig.to_toml_string().contains("[sim]"), "defaults are not written");
    // Defaults by hand: s = 0.4 / 0.3; masses [8, 4, 2, 1] g * s^3, each heavier than all above.
    let s: f64 = (0.4f32 as f64) / 0.3;
    for (m, f) in rig.sim.mass_kg.iter().zip([8.0, 4.0, 2.0, 1.0]) {
        assert!((m - f * 1e-3 * s.powi(3)).abs() < 1e-12, "{m}");
    }
    for n in 0..3 {
        assert!(rig.sim.mass_kg[n] > rig.sim.mass_kg[n + 1..].iter().sum::<f64>());
    }
    // Top joint: drag 3e-3 s^2 at 0.1 m above it, 5 m/s, 0.15 rad: k_3 = 3e-3 s^2 * 5 * 0.1 / 0.15.
    let k3 = 3e-3 * s * s * 5.0 * (0.4f32 as f64 - 0.3f32 as f64) / 0.15;
    assert!((rig.sim.bend_stiffness_nm_per_rad[3] - k3).abs() < 1e-9 * k3);
    assert_eq!(
        (rig.sim.gravity_m_s2, rig.sim.timestep_s, rig.sim.angular),
        (0.0, 0.001, AngularForm::Bending)
    );

    // Given: parsed, and written back in full.
    let text = format!(
        "{BASE}[sim]\nmass_kg = [0.4, 0.3, 0.2, 0.1]\nbend_stiffness_nm_per_rad = [1, 0.5, 0.25, 0.125]\n\
         drag_ns_per_m = [0, 0.01, 0.02, 0.03]\ngravity_m_s2 = 9.81\ntimestep_s = 0.002\nangular = \"paper\"\n"
    );
    let rig = Rig::from_toml_str(&text).unwrap();
    assert_eq!(rig.sim.mass_kg, [0.4, 0.3, 0.2, 0.1]);
    assert_eq!(rig.sim.bend_stiffness_nm_per_rad, [1.0, 0.5, 0.25, 0.125]);
    assert_eq!(rig.sim.drag_ns_per_m, [0.0, 0.01, 0.02, 0.03]);
    assert_eq!(
        (rig.sim.gravity_m_s2, rig.sim.timestep_s, rig.sim.angular),
        (9.81, 0.002, AngularForm::Paper)
    );
    // Damping not given follows the given stiffness: joint 3 carries only the top (0.1 kg at
    // 0.1 m): I = 1e-3 kg m^2, kd = 2 * 0.2 * sqrt(0.125 * 1e-3) = 4.4721e-3.
    let want = 0.4 * (0.125f64 * 0.1 * (0.4f32 as f64 - 0.3f32 as f64).powi(2)).sqrt();
    assert!((rig.sim.bend_damping_nms_per_rad[3] - want).abs() < 1e-12, "{:?}", rig.sim);
    assert!((want - 4.4721e-3).abs() < 1e-6);
    let written = rig.to_toml_string();
    assert!(written.contains("[sim]"), "{written}");
    assert_eq!(Rig::from_toml_str(&written).unwrap(), rig, "{written}");

    // Every problem with its path.
    let bad = format!(
        "{BASE}[sim]\nmass_kg = [0.4, 0.3, 0, 0.1]\nbend_stiffness_nm_per_rad = [1, 2]\n\
         drag_ns_per_m = [0, -1, 0, 1e9]\ntimestep_s = 0.5\ngravity_m_s2 = nan\nangular = \"stiff\"\n"
    );
    let Err(RigError::Invalid(p)) = Rig::from_toml_str(&bad) else { panic!("accepted") };
    let got: Vec<String> = p.0.iter().map(|x| x.to_string()).collect();
    assert_eq!(
        got,
        [
            "sim.bend_stiffness_nm_per_rad: expected 4 values, found 2",
            "sim.angular: unknown form `stiff` (expected bending or paper)",
            "sim.mass_kg[2]: a mass (kg) must be between 0.000001 and 10000, found 0",
            "sim.drag_ns_per_m[1]: a drag (N s/m) must be between 0 and 1000, found -1",
            "sim.drag_ns_per_m[3]: a drag (N s/m) must be between 0 and 1000, found 1000000000",
            "sim.gravity_m_s2: must be a finite number, found NaN",
            "sim.timestep_s: the time step (s) must be between 0.00001 and 0.05, found 0.5",
        ]
    );
    let e = Rig::from_toml_str(&format!("{BASE}[sim]\nmass = [1, 1, 1, 1]\n")).unwrap_err();
    assert!(matches!(e, RigError::Toml(_)) && e.to_string().contains("unknown field `mass`"), "{e}");
}

#[test]
fn sim_shipped_rigs_still_load_and_round_trip() {
    for (name, text) in EMBEDDED_RIGS {
        let rig = Rig::from_toml_str(text).unwrap();
        assert_eq!(rig.sim.check(), Ok(()), "{name}");
        assert_eq!(Rig::from_toml_str(&rig.to_toml_string()).unwrap(), rig, "{name}");
    }
}
