//! The simulated plant of seed 003, section 4.2 ("Physically-based Tree Animation"), as pure math:
//! a mass-spring system on the rig's skeleton driven by wind, integrated with implicit Euler
//! steps solved by conjugate gradient, read back as [`PoseFrame`]s in frond's rotation
//! convention so that every exporter shows the simulation unchanged.
//!
//! - [`params`]: the rig's `[sim]` table ([`SimParams`]), its defaults and validation;
//! - [`wind`]: the wind spec `speed=S,dir=DEG,gust=G,seed=N[,until=S]` ([`WindSpec`]) and its
//!   seeded, smooth field ([`Wind`]);
//! - [`model`]: the springs (Eq. 1-3) and the implicit Euler step ([`PlantSim`]);
//! - [`solver`]: the 12 x 12 system and its conjugate gradient.
//!
//! Eq. 2 as printed has no restoring force at a straight rest angle (its gradient vanishes at
//! `α = π`), and frond's rigs rest straight, so the default angular spring is a bending form with
//! the small-angle restoring torque `k θ`; the printed form is available as `angular = "paper"`
//! (see [`AngularForm`]).

use thiserror::Error;

use crate::problems::Problems;
use crate::rig::Rig;
use crate::sample::PoseFrame;

pub mod model;
pub mod params;
pub mod solver;
pub mod wind;

pub use model::PlantSim;
pub use params::{AngularForm, FREE_NODES, NODES, SimParams, node_heights_m};
pub use wind::{Wind, WindSpec, WindSpecError};

/// Most frames [`simulate`] returns (an hour at 300 frames per second).
pub const MAX_SIM_FRAMES: u64 = 1_080_000;
/// Most integration steps [`simulate`] takes (a day at the default 1 ms step).
pub const MAX_SIM_STEPS: u64 = 86_400_000;
/// Largest output rate of [`simulate`], frames per second.
pub const MAX_SIM_FPS: f64 = 10_000.0;

/// Why a simulation could not be set up or run.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SimError {
    /// Some `[sim]` values are out of range (every problem with its path).
    #[error("sim: {0}")]
    Invalid(Problems),
    /// The node heights are not finite and strictly increasing.
    #[error("sim: node heights must be finite and strictly increasing, found {0:?}")]
    Heights([f64; NODES]),
    /// A step gave a state that is not finite (the state before it is kept).
    #[error("sim: the simulation diverged at {t_s} s")]
    Diverged {
        /// Simulated time of the step that failed, seconds.
        t_s: f64,
    },
    /// The duration or the frame rate is not a finite positive number within bounds.
    #[error("sim: {what} must be {requirement}, found {value}")]
    Argument {
        /// `duration_s` or `fps`.
        what: &'static str,
        /// The value given.
        value: f64,
        /// The rule it breaks.
        requirement: &'static str,
    },
    /// More output frames than [`MAX_SIM_FRAMES`].
    #[error("sim: {frames} frames requested, the limit is {MAX_SIM_FRAMES}")]
    TooManyFrames {
        /// Frames the duration and rate ask for.
        frames: u64,
    },
    /// More integration steps than [`MAX_SIM_STEPS`].
    #[error("sim: {steps} steps of the simulation needed, the limit is {MAX_SIM_STEPS}")]
    TooManySteps {
        /// Steps the duration and time step ask for.
        steps: u64,
    },
}

/// Simulates `rig`'s plant with the parameters `sim` in `wind` from rest for `duration_s` and
/// returns its poses at `fps`: frame `k` at `t = k / fps` for every `t <= duration_s` (frame 0
/// is the rest pose). Each frame is the state after the last step ending at or before its time
/// plus half a step (so within half a time step of it), stamped with its frame time.
pub fn simulate(
    rig: &Rig,
    sim: &SimParams,
    wind: WindSpec,
    duration_s: f64,
    fps: f64,
) -> Result<Vec<PoseFrame>, SimError> {
    let mut out = Vec::new();
    simulate_each(rig, sim, wind, duration_s, fps, &mut |_, pose| out.push(pose))?;
    Ok(out)
}

/// [`simulate`], handing each frame to `each` with the plant in that frame's state (for the
/// node positions, velocities and forces `frond take simulate --states` writes) instead of
/// collecting them. The same bounds are checked before the first step.
pub fn simulate_each(
    rig: &Rig,
    sim: &SimParams,
    wind: WindSpec,
    duration_s: f64,
    fps: f64,
    each: &mut dyn FnMut(&mut PlantSim, PoseFrame),
) -> Result<(), SimError> {
    if !(duration_s.is_finite() && duration_s >= 0.0) {
        return Err(SimError::Argument {
            what: "duration_s",
            value: duration_s,
            requirement: "finite and >= 0",
        });
    }
    if !(fps.is_finite() && fps > 0.0 && fps <= MAX_SIM_FPS) {
        return Err(SimError::Argument { what: "fps", value: fps, requirement: "above 0 and at most 10000" });
    }
    let last = (duration_s * fps + 1e-9).floor();
    let frames = last as u64 + 1;
    if last >= MAX_SIM_FRAMES as f64 {
        return Err(SimError::TooManyFrames { frames });
    }
    sim.check().map_err(SimError::Invalid)?;
    let steps = (duration_s / sim.timestep_s).ceil();
    if steps > MAX_SIM_STEPS as f64 {
        return Err(SimError::TooManySteps { steps: steps as u64 });
    }
    let mut plant = PlantSim::new(rig.sim_node_heights_m(), *sim, wind)?;
    let h = sim.timestep_s;
    for k in 0..frames {
        let t = k as f64 / fps;
        while plant.time_s() + 0.5 * h <= t {
            plant.step()?;
        }
        let pose = PoseFrame { t, ..plant.pose() };
        each(&mut plant, pose);
    }
    Ok(())
}

/// Why a `--sim` file was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SimFileError {
    /// Not TOML, no `[sim]` table, or a key of the wrong type or unknown (the toml message).
    #[error("{0}")]
    Toml(String),
    /// Some values are out of range (every problem with its path).
    #[error("{0}")]
    Invalid(Problems),
}

#[cfg(test)]
mod tests;
