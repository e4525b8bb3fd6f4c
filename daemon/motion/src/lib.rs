//! Pure motion math for frond, with no I/O and no file formats: hand samples, rigs, calibration,
//! jitter filters, the hand-to-plant mapping of seed 000 (Eq. 2-4), and takes as data. Reading
//! and writing files and their text (rig and calibration TOML, takes, JSONL, BVH, USD, glTF
//! meshes, graph files) is `frond_formats`; the types here keep their serde definitions and
//! validate what a reader gives them. A test (`tests/it/pure.rs`) keeps file access and format
//! crates out of this crate.
//!
//! The path from a raw hand sample to a pose is [`Mapper::process`]: calibrate
//! ([`CalibrationParams::apply`]), filter ([`HandFilter`]), map ([`map_pose`]). The realtime loop
//! and the offline `frond map` both use it, so live and offline poses are identical.
//!
//! The motion toolkit of seed 000, sections 4 and 6: [`skeleton`] (rotation convention, forward
//! kinematics, procedural weights, Eq. 1 skinning), [`mesh`] (geometry), [`layers`] (layered
//! takes), [`edit`] (resample, post-filter, splice), [`clip`] (clips and the delayed lookup),
//! [`looping`] (Eq. 5), [`field`] (Eq. 6-7, `field.json`), [`controls`] (section 6.3),
//! [`guided`] (Eq. 8) and [`align`] (section 6.5). Randomness comes from [`rng::SeededRng`] only.
//!
//! [`sim`] is the simulated plant of seed 003, section 4.2: a mass-spring skeleton in wind, read
//! back as poses.

#![warn(missing_docs)]

pub mod align;
pub mod calibrate;
pub mod calibration;
pub mod clip;
pub mod controls;
pub mod edit;
pub mod field;
pub mod field_eval;
pub mod field_player;
pub mod field_wire;
pub mod filter;
pub mod graph;
pub mod guided;
pub mod hand_landmarks;
pub mod layers;
pub mod looping;
pub mod mapping;
pub mod mesh;
pub mod plausible;
pub mod problems;
pub mod quantile;
pub mod resample;
pub mod rig;
mod rig_mesh;
pub mod rng;
pub mod sample;
pub mod sim;
pub mod skeleton;
pub mod take;
pub mod timecode;
pub mod timeline;

pub use calibration::{Calibration, CalibrationError, CalibrationParams};
pub use filter::{FilterSpec, FilterSpecError, HandFilter, LowPass, OneEuro};
pub use mapping::{Mapper, MappingParams, map_pose};
pub use plausible::Implausible;
pub use problems::{Problem, Problems};
pub use rig::{ElementSpec, GuidedSpec, JointSpec, Rig, RigError};
pub use sample::{HandSample, JOINTS, PoseFrame};
pub use take::{
    ResamplePlan, Skipped, TakeFrame, TakeHeader, TakeScan, TooManyFrames, resample, resample_across_gaps,
    resample_plan,
};
