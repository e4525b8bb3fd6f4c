//! frond's glTF baker: takes, layered takes and whole fields of plants as skinned, animated
//! glTF 2.0 files (GLB, or `.gltf` + `.bin`) that open in Blender, Maya, Houdini, Unreal, Unity
//! and three.js without fix-up.
//!
//! The document is built in memory by [`Baker`] (pure, testable without files, reusing its
//! buffers between bakes), from a rig ([`LoadedRig`]), its plant geometry
//! (`frond_motion::mesh::PlantModel`: the procedural mesh or the rig's glTF mesh, with Eq. 1
//! skinning weights from seed 000's Appendix) and a take ([`TakeInput`]); [`output::write`]
//! writes it atomically. What a file holds:
//!
//! - one mesh (stem and every secondary element instance) with normals, `JOINTS_0`/`WEIGHTS_0`
//!   and one material, stored once however many plants use it;
//! - per plant a root node, the rig's joints under it (named after the rig's joints), each
//!   secondary element instance's own 4-joint skeleton under its attach joint, a skin with
//!   inverse bind matrices, and a root-level node holding the mesh and that skin;
//! - one animation per take, named after it: LINEAR rotation channels, unit quaternions from
//!   the rotation convention of `frond_protocol::convention` (`R = R_yaw R_pitch R_roll`) kept
//!   on one hemisphere, key times in seconds from 0, every accessor with min/max;
//! - a grove ([`Baker::bake_grove`]): one plant per take on a square grid, each its own animation
//!   channels, for the walks of seed 003's instancing;
//! - `asset.generator = "frond <version>"` and extras (take, rig, capture rate, calibration id)
//!   on the asset and the animation.

#![warn(missing_docs)]

pub mod anim;
pub mod bake;
pub mod bake_live;
pub mod bench;
pub mod bind;
pub mod doc;
pub mod error;
pub mod field;
pub mod grove;
pub mod input;
pub mod live;
pub mod live_field;
pub mod output;

pub use bake::{BakeOptions, BakeStats, Baked, Baker};
pub use error::BakeError;
pub use field::Field;
pub use input::{EMBEDDED_RIGS, LoadedRig, TakeInput};
pub use output::{Format, encode_glb};

/// `asset.generator` of every file: `frond <version>`.
pub const GENERATOR: &str = concat!("frond ", env!("CARGO_PKG_VERSION"));
