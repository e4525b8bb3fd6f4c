//! [`LeapSource`]: the loop's side of the Leap backend. It starts the [`Client`] thread and reads
//! the samples it queues; it never blocks or allocates.

use std::os::fd::RawFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::Receiver;
use frond_protocol::SourceKind;

use super::address::LeapAddress;
use super::client::Client;
use crate::doorbell::Doorbell;
use crate::report::{DeviceSample, SourceCounters};
use crate::source::hand::{HandSource, SourceError};

/// Samples queued for the loop at most (a second at the service's ~110 Hz, four times over).
const QUEUE_LEN: usize = 512;
/// How long dropping the source waits for its thread.
pub(super) const STOP_WAIT: Duration = Duration::from_millis(500);

/// Hand samples from the tracking service's WebSocket.
pub struct LeapSource {
    rx: Receiver<DeviceSample>,
    bell: Arc<Doorbell>,
    counters: Arc<SourceCounters>,
    overflow: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    describe: String,
}

impl LeapSource {
    /// Starts the client thread for `address` (it connects, and reconnects, on its own).
    pub fn connect(address: &LeapAddress) -> Result<LeapSource, SourceError> {
        let what = format!("leap://{}", address.host_port);
        let open = |reason: String| SourceError::Open { what: what.clone(), reason };
        let bell = Arc::new(Doorbell::new().map_err(|e| open(format!("eventfd: {e}")))?);
        let (tx, rx) = crossbeam_channel::bounded(QUEUE_LEN);
        let counters = Arc::new(SourceCounters::default());
        let overflow = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let client = Client {
            host_port: address.host_port.clone(),
            hand: address.hand,
            tx,
            bell: Arc::clone(&bell),
            counters: Arc::clone(&counters),
            overflow: Arc::clone(&overflow),
            stop: Arc::clone(&stop),
        };
        let thread = std::thread::Builder::new()
            .name("frond-leap".into())
            .spawn(move || client.run())
            .map_err(|e| open(format!("cannot start the client thread: {e}")))?;
        Ok(LeapSource {
            rx,
            bell,
            counters,
            overflow,
            stop,
            thread: Some(thread),
            describe: format!(
                "Leap Motion service at ws://{}/v6.json, {} hand",
                address.host_port,
                address.hand.as_str()
            ),
        })
    }

    /// Samples lost because the loop did not keep up (queue full).
    pub fn overflow(&self) -> u64 {
        self.overflow.load(Ordering::Relaxed)
    }
}

impl HandSource for LeapSource {
    fn kind(&self) -> SourceKind {
        SourceKind::Leap
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
        // The client thread reconnects by itself; nothing to reopen here.
        Ok(())
    }
}

impl Drop for LeapSource {
    /// Stops the client thread and waits for it at most `STOP_WAIT` (500 ms): its reads and
    /// writes end within `READ_POLL` (200 ms) of the stop; only a name lookup or a connection attempt (at most
    /// 1 s) can outlast the wait, and then the thread is left to end by itself (at the
    /// process's exit, if that comes first).
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        let Some(t) = self.thread.take() else { return };
        if crate::join::join_within(t, STOP_WAIT).is_none() {
            tracing::warn!(source = %self.describe, "the Leap Motion client thread did not stop within {} ms; leaving it", STOP_WAIT.as_millis());
        }
    }
}
