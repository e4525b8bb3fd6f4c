//! The virtual glove: a report generator that plays a JSONL hand file or a procedural sway as
//! reference-glove reports ([`glove`]), with fault injection, served as a device node:
//!
//! - [`mount_fuse`]: a FUSE file that behaves as a hidraw node (used where `/dev/uhid` is absent,
//!   e.g. this machine and CI). Opened through the same hidapi code path as a physical glove.
//! - [`uhid::UhidGlove`]: a kernel HID device through `/dev/uhid` (a real `/dev/hidrawN`).
//! - [`InProcessGlove`]: the generator inside the daemon feeding a bounded lock-free queue, for
//!   when no node can be created; same report bytes, same parser.
//! - [`OscGlove`]: the same hands sent as `/frond/hand` OSC datagrams, a reference sender for
//!   the daemon's OSC source.
//!
//! The `frond-vhid` binary serves it from the command line. This crate depends on
//! `frond-device` (the hand-source trait, the report parser, JSONL hand files), never the other
//! way round: consumers of hand sources do not link FUSE.

#![warn(missing_docs)]

mod fuse;
mod generator;
pub mod glove;
mod inprocess;
mod osc_out;
pub mod uhid;

pub use fuse::{NODE_NAME, VirtualGloveHandle, mount_fuse, mount_fuse_node};
pub use generator::{
    DeviceClock, FaultPlan, GloveSource, MAX_RATE_HZ, TimeJump, UnplugPlan, VhidError, VhidStats,
    VirtualGloveConfig, monotonic_us_u32, sway_sample,
};
pub use inprocess::InProcessGlove;
pub use osc_out::OscGlove;
