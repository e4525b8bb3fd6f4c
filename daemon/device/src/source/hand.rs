//! The [`HandSource`] trait every backend implements, and its [`SourceError`].

use std::os::fd::RawFd;
use std::sync::Arc;

use frond_protocol::SourceKind;

use crate::report::{DeviceSample, SourceCounters};

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
