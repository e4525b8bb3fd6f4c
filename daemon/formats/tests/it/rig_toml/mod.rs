//! The motion math's TOML files read as before: rig files (`rig`, their `[vmc]`, `[guided]` and
//! names in `guided`, their `[sim]` table in `sim`), a filter in the text form, and a `--sim`
//! file, one `[sim]` table as in a rig; everything else is refused with a clear message.

use frond_formats::rig_toml::sim_from_toml_str;
use frond_motion::FilterSpec;
use frond_motion::sim::{SimFileError, SimParams};
use serde::{Deserialize, Serialize};

mod guided;
mod rig;
mod sim;

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

/// A filter is written in its text form (`one-euro:beta=0.01`), as in a rig's `filter` key.
#[test]
fn serde_uses_the_text_form() {
    #[derive(Serialize, Deserialize, PartialEq, Debug)]
    struct Doc {
        filter: FilterSpec,
    }
    let d: Doc = toml::from_str("filter = \"one-euro:beta=0.01\"").unwrap();
    assert_eq!(d.filter, FilterSpec::OneEuro { min_cutoff: 1.0, beta: 0.01, d_cutoff: 1.0 });
    let text = toml::to_string(&d).unwrap();
    assert_eq!(toml::from_str::<Doc>(&text).unwrap(), d);
    let e = toml::from_str::<Doc>("filter = \"lowpass:cutoff_hz=-1\"").unwrap_err();
    assert!(e.to_string().contains("cutoff_hz"), "{e}");
}
