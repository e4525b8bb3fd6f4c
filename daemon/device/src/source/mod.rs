//! Hand sources: where the realtime loop gets [`DeviceSample`]s from.

use std::fmt;
use std::os::fd::RawFd;
use std::sync::Arc;

use crate::report::{DeviceSample, SourceCounters};

mod hid;
mod leap;
mod osc;
mod osc_wire;
mod replay;

pub use hid::HidSource;
pub use leap::{LeapAddress, LeapSource};
pub use osc::{OSC_HAND_ADDRESS, OscHandSource, decode_hand_packet};
pub use replay::ReplaySource;

/// What kind of source feeds the loop (shown by `frond status`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SourceKind {
    /// A kernel hidraw node (physical glove, or the virtual glove through UHID).
    Hidraw,
    /// The virtual glove served as a FUSE file that behaves as a hidraw node.
    FuseHidraw,
    /// The virtual glove's report generator running inside the daemon.
    InProcess,
    /// A JSONL hand recording played at its timestamps.
    Replay,
    /// `/frond/hand` OSC messages over UDP (webcam or phone hand trackers).
    Osc,
    /// A Leap Motion / Ultraleap tracking service's WebSocket (protocol v6).
    Leap,
}

impl SourceKind {
    /// Stable lower-case name.
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Hidraw => "hidraw",
            Self::FuseHidraw => "fuse-hidraw",
            Self::InProcess => "in-process",
            Self::Replay => "replay",
            Self::Osc => "osc",
            Self::Leap => "leap",
        }
    }
}

impl fmt::Display for SourceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Errors of hand sources.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The device went away; call [`HandSource::reopen`] from a helper thread.
    #[error("{what}: device disconnected: {reason}")]
    Disconnected {
        /// Path or description of the device.
        what: String,
        /// Why the device is considered gone.
        reason: String,
    },
    /// The device is not there (yet).
    #[error("{what}: device not found{}", if .reason.is_empty() { String::new() } else { format!(": {}", .reason) })]
    NotFound {
        /// Path or description of the device.
        what: String,
        /// Extra detail; empty when there is none.
        reason: String,
    },
    /// Opening failed for another reason.
    #[error("{what}: cannot open: {reason}")]
    Open {
        /// Path or description of the device (may be empty).
        what: String,
        /// Why opening failed.
        reason: String,
    },
}

/// A source of hand samples read by the realtime loop.
pub trait HandSource: Send {
    /// What kind of source this is.
    fn kind(&self) -> SourceKind;
    /// Path or description of the device.
    fn describe(&self) -> &str;
    /// Non-blocking: read every pending report, in arrival order, into `out` (up to
    /// `out.len()`). Never blocks, never allocates in steady state. Invalid reports are counted
    /// and skipped. `Err(SourceError::Disconnected { .. })` when the device is gone.
    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError>;
    /// A descriptor that polls readable when a report is pending, for the realtime loop to wait
    /// on with its next deadline as the timeout, so that a report wakes it at once instead of
    /// waiting up to a period for the next tick. `None` (the default) when the source has none:
    /// the loop then finds reports at its ticks. Valid while the source stays open; the loop
    /// asks again before every wait and never reads or closes it.
    fn ready_fd(&self) -> Option<RawFd> {
        None
    }
    /// The source's counters, shared with the status thread.
    fn counters(&self) -> Arc<SourceCounters>;
    /// Slow, may allocate/block: called from a helper thread, never from the realtime loop.
    fn reopen(&mut self) -> Result<(), SourceError>;
}
