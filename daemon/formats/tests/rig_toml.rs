//! The motion math's TOML files read as before: a `--sim` file is one `[sim]` table, as in a rig,
//! and everything else is refused with a clear message.

use frond_formats::rig_toml::sim_from_toml_str;
use frond_motion::sim::{SimFileError, SimParams};

/// `--sim FILE`: one `[sim]` table, as in a rig; everything else refused with a clear message.
#[test]
fn sim_files_are_read_like_the_rigs_table() {
    let heights = [0.0, 0.08, 0.16, 0.24, 0.30];
    let s = sim_from_toml_str("[sim]\ntimestep_s = 0.002\n", heights).unwrap();
    assert_eq!(s.timestep_s, 0.002);
    assert_eq!(s.mass_kg, SimParams::defaults_for(heights).mass_kg, "the rest take the defaults");
    let e = sim_from_toml_str("timestep_s = 0.002\n", heights).unwrap_err();
    assert!(matches!(e, SimFileError::Toml(ref m) if m.contains("sim")), "{e}");
    let e = sim_from_toml_str("[sim]\nspeed = 3\n", heights).unwrap_err();
    assert!(matches!(e, SimFileError::Toml(ref m) if m.contains("speed")), "{e}");
    let e = sim_from_toml_str("[sim]\nmass_kg = [1, 2]\n", heights).unwrap_err();
    assert!(e.to_string().contains("sim.mass_kg: expected 4 values, found 2"), "{e}");
}
