//! frond hand sources: the reference glove report, device profiles, the profile-driven report
//! parser, the [`HandSource`] trait with its hidapi, replay and in-process
//! implementations, and the virtual glove (`frond-vhid`).

#![warn(missing_docs)]

pub mod doorbell;
pub mod glove;
pub mod jsonl;
pub mod log_limit;
pub mod profile;
pub mod report;
pub mod source;
pub mod vhid;

pub use profile::{ChannelId, DeviceProfile, ProfileError};
pub use report::{CountersSnapshot, DeviceSample, ReportError, ReportParser, SourceCounters};
pub use source::{
    HandSource, HidSource, LeapAddress, LeapSource, OscHandSource, ReplaySource, SourceError, SourceKind,
};
pub use vhid::{
    DeviceClock, FaultPlan, GloveSource, InProcessGlove, UnplugPlan, VhidError, VirtualGloveConfig,
    VirtualGloveHandle, mount_fuse,
};
