//! [`WebcamSource`]: the loop's side of the webcam backend. It joins its camera's hub (which
//! runs the landmark helper) and reads the samples the hub queues; it never blocks or allocates.

use std::os::fd::RawFd;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crossbeam_channel::Receiver;
use frond_protocol::SourceKind;

use super::address::WebcamAddress;
use super::hub::{Hub, Subscriber};
use crate::doorbell::Doorbell;
use crate::report::{CameraSnapshot, DeviceSample, SourceCounters};
use crate::source::hand::{HandSource, SourceError};

/// Samples queued for the loop at most (about 17 s at 30 frames a second).
const QUEUE_LEN: usize = 512;

/// One hand of a camera, from the landmark helper.
pub struct WebcamSource {
    rx: Receiver<DeviceSample>,
    bell: Arc<Doorbell>,
    counters: Arc<SourceCounters>,
    overflow: Arc<AtomicU64>,
    hub: Arc<Hub>,
    describe: String,
}

impl WebcamSource {
    /// Joins (or starts) the helper of `address`'s camera, for its hand: `$FROND_HANDS`, or
    /// `frond-hands` on `PATH`. With `preview_dir` (the daemon's socket directory) the helper
    /// keeps the camera's preview picture there, named in the source's status.
    pub fn open(address: &WebcamAddress, preview_dir: Option<&Path>) -> Result<WebcamSource, SourceError> {
        Self::open_with_helper(address, super::hub::helper_command(), preview_dir)
    }

    /// [`WebcamSource::open`] with the helper's command given.
    pub fn open_with_helper(
        address: &WebcamAddress,
        helper: impl Into<std::ffi::OsString>,
        preview_dir: Option<&Path>,
    ) -> Result<WebcamSource, SourceError> {
        let what = format!("webcam:{}", address.input);
        let open = |reason: String| SourceError::Open { what: what.clone(), reason };
        let bell = Arc::new(Doorbell::new().map_err(|e| open(format!("eventfd: {e}")))?);
        let (tx, rx) = crossbeam_channel::bounded(QUEUE_LEN);
        let counters = Arc::new(SourceCounters::default());
        let overflow = Arc::new(AtomicU64::new(0));
        let subscriber = Subscriber {
            hand: address.hand,
            tx,
            bell: Arc::clone(&bell),
            counters: Arc::clone(&counters),
            overflow: Arc::clone(&overflow),
        };
        let hub = Hub::join(address, subscriber, helper.into(), preview_dir)
            .map_err(|e| open(format!("cannot start the webcam thread: {e}")))?;
        let kind = if address.is_camera() { "camera" } else { "video file" };
        Ok(WebcamSource {
            rx,
            bell,
            counters,
            overflow,
            hub,
            describe: format!("{kind} {}, {} hand", address.input, address.hand_name()),
        })
    }

    /// Samples lost because the loop did not keep up (queue full).
    pub fn overflow(&self) -> u64 {
        self.overflow.load(Ordering::Relaxed)
    }

    /// The camera's frame rate, latency and model time.
    pub fn stats(&self) -> CameraSnapshot {
        self.counters.camera.snapshot()
    }
}

impl HandSource for WebcamSource {
    fn kind(&self) -> SourceKind {
        SourceKind::Webcam
    }

    fn describe(&self) -> &str {
        &self.describe
    }

    fn ready_fd(&self) -> Option<RawFd> {
        Some(self.bell.fd())
    }

    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        // Drain first: a sample queued after this rings again.
        self.bell.drain();
        let mut n = 0;
        while n < out.len() {
            let Ok(s) = self.rx.try_recv() else { break };
            out[n] = s;
            n += 1;
        }
        Ok(n)
    }

    fn counters(&self) -> Arc<SourceCounters> {
        Arc::clone(&self.counters)
    }

    fn reopen(&mut self) -> Result<(), SourceError> {
        // The hub starts the helper again by itself; nothing to reopen here.
        Ok(())
    }
}

impl Drop for WebcamSource {
    fn drop(&mut self) {
        self.hub.leave(&self.bell);
    }
}
