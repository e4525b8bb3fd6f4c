//! frondd, the frond daemon: reads the hand device at a fixed rate, calibrates, filters and maps
//! the hand onto the plant skeleton (seed 000, Eq. 2-4) and publishes poses to subscribers.
//!
//! Threads: `frond-rt` (the realtime loop, [`engine`] paced by [`realtime`], writing to the
//! subscribers' direct [`lanes`]), `frond-accept` and `frond-publish` (the slow lane,
//! [`publisher`]), `frond-control` ([`control`]), `frond-recorder`
//! ([`recorder`]), `frond-triggers` (a mocap stage's capture triggers, [`trigger_thread`]),
//! `frond-ltc` (the stage's timecode from LTC audio, [`ltc_thread`]), and housekeeping (status
//! rate, device events, reopening a lost device,
//! dropping what the loop may not free). Data flows one way: device -> loop -> queues -> sockets.

#![warn(missing_docs)]

pub mod access;
pub mod clock;
pub mod config;
mod config_stage;
pub mod control;
mod control_conn;
mod control_stage;
mod control_state;
pub mod daemon;
pub mod engine;
pub mod error;
pub mod handoff;
pub mod lanes;
pub mod log_limit;
pub mod ltc_alsa;
pub mod ltc_input;
pub mod ltc_link;
pub mod ltc_thread;
pub mod notify;
pub mod publisher;
pub mod realtime;
/// The take writer (its own crate, shared with the stage recorder of `frond record start --stage`).
pub use frond_recorder as recorder;
pub mod source;
pub mod stage;
pub mod stats;
pub mod trigger_link;
pub mod trigger_thread;
