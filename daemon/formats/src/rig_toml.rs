//! The TOML files of the motion math: the `[sim]` table a `--sim FILE.toml` holds. What the
//! values mean and how they are checked is `frond_motion` ([`RawSim::validate`]); this module
//! only reads the text.

use frond_motion::problems::Problems;
use frond_motion::sim::params::RawSim;
use frond_motion::sim::{NODES, SimFileError, SimParams};

/// Reads a `--sim FILE.toml`: a document holding one `[sim]` table, as in a rig file, which
/// replaces the rig's (keys it leaves out take the defaults for the plant's `heights_m`).
pub fn sim_from_toml_str(text: &str, heights_m: [f64; NODES]) -> Result<SimParams, SimFileError> {
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        sim: RawSim,
    }
    let doc: Doc =
        toml::from_str(text).map_err(|e| SimFileError::Toml(e.to_string().trim_end().to_string()))?;
    let mut p = Problems::default();
    let sim = doc.sim.validate(&mut p, heights_m);
    if p.is_empty() { Ok(sim) } else { Err(SimFileError::Invalid(p)) }
}
