//! The status poller: asks the daemon's control socket for its status a few times a second and
//! publishes the reply under `.../status`. A thread of its own, so a daemon that is slow to
//! answer never holds up the poses.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use frond_protocol::{ControlReply, FrameBuf};
use frond_sdk::ControlClient;
use zenoh::Wait;
use zenoh::qos::{CongestionControl, Priority};

use crate::{BridgeError, Shared};

/// How long one status request may take.
const STATUS_TIMEOUT: Duration = Duration::from_secs(2);
/// Least time between two warnings about the control socket.
const WARN_EVERY: Duration = Duration::from_secs(30);

pub(crate) struct StatusPoller {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl StatusPoller {
    pub(crate) fn stop(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

pub(crate) fn spawn(
    socket_dir: PathBuf,
    session: zenoh::Session,
    key: String,
    interval: Duration,
    shared: Arc<Shared>,
) -> Result<StatusPoller, BridgeError> {
    let declare = |reason: String| BridgeError::Declare { what: "the status publisher".into(), reason };
    let publisher = session
        .declare_publisher(key)
        .congestion_control(CongestionControl::Drop)
        .priority(Priority::Data)
        .wait()
        .map_err(|e| declare(e.to_string()))?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let thread = std::thread::Builder::new()
        .name("frond-zenoh-status".into())
        .spawn(move || {
            let mut client: Option<ControlClient> = None;
            let mut frame = FrameBuf::with_capacity(4096);
            let mut last_warning: Option<Instant> = None;
            while !flag.load(Ordering::Relaxed) {
                let next = Instant::now() + interval;
                if client.is_none() {
                    client = ControlClient::connect_with_timeout(&socket_dir, STATUS_TIMEOUT).ok();
                }
                let report = client.as_mut().map(|c| c.status());
                match report {
                    Some(Ok(report)) => {
                        let bytes = frame.encode(&ControlReply::Status(Box::new(report))).to_vec();
                        shared.latest().status = Some(bytes.clone());
                        if !shared.standing_by() && publisher.put(bytes).wait().is_ok() {
                            shared.stats.statuses.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    failed => {
                        client = None;
                        shared.latest().status = None;
                        if last_warning.is_none_or(|t| t.elapsed() >= WARN_EVERY) {
                            last_warning = Some(Instant::now());
                            match failed {
                                Some(Err(e)) => tracing::warn!(error = %e, "daemon status"),
                                _ => tracing::warn!(dir = %socket_dir.display(), "daemon status: no control socket"),
                            }
                        }
                    }
                }
                while !flag.load(Ordering::Relaxed) && Instant::now() < next {
                    std::thread::sleep(next.saturating_duration_since(Instant::now()).min(Duration::from_millis(50)));
                }
            }
        })
        .map_err(|e| declare(format!("starting its thread: {e}")))?;
    Ok(StatusPoller { stop, thread: Some(thread) })
}
