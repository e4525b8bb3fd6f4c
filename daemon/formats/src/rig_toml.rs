//! The TOML files of the motion math: rig files ([`RigText`]), calibration files
//! ([`CalibrationText`]) and the `[sim]` table a `--sim FILE.toml` holds. What the values mean
//! and how they are checked is `frond_motion` ([`RawRig::validate`], [`Calibration::validate`],
//! [`RawSim::validate`]); this module only reads and writes the text.

use frond_motion::calibration::{Calibration, CalibrationError};
use frond_motion::problems::Problems;
use frond_motion::rig::{RawRig, Rig, RigError};
use frond_motion::sim::params::RawSim;
use frond_motion::sim::{NODES, SimFileError, SimParams};

/// A rig file: `use frond_formats::rig_toml::RigText;` and call `Rig::from_toml_str(text)` /
/// `rig.to_toml_string()`.
pub trait RigText: Sized {
    /// Parses a rig file and validates it, reporting every problem with its path.
    fn from_toml_str(text: &str) -> Result<Self, RigError>;
    /// Writes the rig as TOML (no comments); [`RigText::from_toml_str`] reads it back identically.
    fn to_toml_string(&self) -> String;
}

impl RigText for Rig {
    fn from_toml_str(text: &str) -> Result<Rig, RigError> {
        let raw: RawRig =
            toml::from_str(text).map_err(|e| RigError::Toml(e.to_string().trim_end().to_string()))?;
        raw.validate().map_err(RigError::Invalid)
    }

    fn to_toml_string(&self) -> String {
        // Plain strings, integers and f32 values always serialize.
        toml::to_string(&RawRig::from_rig(self)).unwrap_or_default()
    }
}

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

/// A calibration file: `use frond_formats::rig_toml::CalibrationText;` and call
/// `Calibration::from_toml_str(text)` / `calibration.to_toml_string()`.
pub trait CalibrationText: Sized {
    /// Parses and validates a calibration file.
    fn from_toml_str(text: &str) -> Result<Self, CalibrationError>;
    /// Writes the calibration as TOML; [`CalibrationText::from_toml_str`] reads it back identically.
    fn to_toml_string(&self) -> String;
}

impl CalibrationText for Calibration {
    fn from_toml_str(text: &str) -> Result<Calibration, CalibrationError> {
        let c: Calibration =
            toml::from_str(text).map_err(|e| CalibrationError::Toml(e.to_string().trim_end().to_string()))?;
        c.validate().map_err(CalibrationError::Invalid)?;
        Ok(c)
    }

    fn to_toml_string(&self) -> String {
        // Serializing plain strings and f32 arrays cannot fail.
        toml::to_string(self).unwrap_or_default()
    }
}
