//! frond's OSC/VMC exporter: subscribes to the daemon's pose stream (`frond_sdk`) and sends every
//! frame as OSC bundles over UDP to one or more targets, in frond's own namespace or as the VMC
//! protocol that Unity, Unreal, Blender and VTuber tools receive.
//!
//! - [`encode`]: pure functions from a `Pose` to OSC datagrams in reusable buffers; the namespace
//!   and the timetag derivation are documented there.
//! - [`sender`]: non-blocking UDP to several targets; a target that is down never blocks the
//!   others.
//! - [`resample`]: `--rate` resampling that never replays a stale frame as new.
//! - [`fields`]: running fields sent whole (definition, layout, every field frame), so that a
//!   receiver evaluates every plant itself (the Blender add-on does).
//! - [`bridge`]: the loop that ties them to a subscriber, with counters.
//! - [`bench`](mod@bench): daemon-to-receiver latency percentiles with 1 and N targets.
//! - [`rig`]: what VMC needs from a rig (joint heights, bone names), loaded with `frond_motion`.

#![warn(missing_docs)]

pub mod bench;
pub mod bridge;
pub mod encode;
pub mod fields;
pub mod resample;
pub mod rig;
pub mod sender;

pub use bridge::{Bridge, BridgeConfig, BridgeError, BridgeStats, Protocol};

/// Default UDP port of the `frond` namespace.
pub const DEFAULT_FROND_PORT: u16 = 9000;
/// Default UDP port of VMC receivers (the VMC protocol's performer-to-marionette port).
pub const DEFAULT_VMC_PORT: u16 = 39539;
/// VMC's default output rate, Hz: what VMC performers send and receivers expect (about 60).
pub const DEFAULT_VMC_RATE_HZ: f64 = 60.0;
