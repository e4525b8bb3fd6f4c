//! frond hand sources: device profiles, the profile-driven report parser, and the
//! [`HandSource`] trait with its backends (hidapi, replay, OSC, Leap). The virtual glove that
//! serves reference-glove reports for tests and demos is the `frond-vhid` crate, built on this one.

#![warn(missing_docs)]

pub mod doorbell;
pub mod join;
pub mod jsonl;
pub mod log_limit;
pub mod profile;
pub mod report;
pub mod source;

pub use profile::{ChannelId, DeviceProfile, ProfileError};
pub use report::{
    CameraCounters, CameraSnapshot, CountersSnapshot, DeviceSample, ReportError, ReportParser, SourceCounters,
};
pub use source::{
    BACKENDS, Backend, HandSource, HidSource, LeapAddress, LeapAddressError, LeapSource, OscHandSource,
    ReplaySource, SourceError, SourceKind, SourceSpec, SpecError, SpecInput, WebcamAddress, WebcamSource,
    kind_names, parse_spec,
};
