//! frond-warp: a live, hand-driven picture of vegetation in the wind (seed 001).
//!
//! Pipeline per frame: user or hand forces -> [`fluid`] (stable-fluids wind, Eq. 1-2) -> per
//! layer [`wave`] (vegetation velocity, Eq. 3-4) -> [`warp`] (grid-based inverse warping, Eq. 5-8)
//! -> [`compose`] over the background ([`inpaint`]ed when absent).

#![warn(missing_docs)]

pub mod compose;
pub mod fluid;
pub mod inpaint;
pub mod layers;
pub mod params;
pub mod warp;
pub mod wave;
pub mod wind;

pub use compose::Animator;
pub use layers::{LayerInput, Rgba, Scene, SceneError};
pub use params::{FluidParams, Horizon, InvalidParams, LayerParams, SceneParams, WindParams, WindSource};
pub mod bench;
pub mod cage_skin;
pub mod cages;
pub mod cli;
pub mod morph;
pub mod morph_frames;
pub mod render;
pub mod samples;
pub mod serve;
pub mod serve_cage;
