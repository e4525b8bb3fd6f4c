//! The console's connections to the daemon's control socket: however many pages poll status and
//! however many actions arrive together, the console holds at most two of the daemon's
//! control slots (one for status, one for actions), so `frond` on the operator's terminal always
//! finds one free.
//!
//! - Status is read at most every [`STATUS_FRESH`]; every page's poll in between is answered
//!   from that one report.
//! - Actions go one at a time over one connection.
//!
//! A connection idle for [`IDLE_REUSE`] is opened anew before use (the daemon closes idle ones),
//! and a status read that fails on a kept connection is tried once more on a fresh one; an
//! action is never sent twice.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use frond_protocol::{ControlReply, ControlRequest, StatusReport};
use frond_sdk::{ControlClient, ControlClientError};

/// How long one status report answers every page's poll.
pub const STATUS_FRESH: Duration = Duration::from_millis(250);
/// A kept connection idle longer than this is opened anew (the daemon closes them at 30 s).
const IDLE_REUSE: Duration = Duration::from_secs(20);
/// How long a status read may wait for the daemon.
const STATUS_TIMEOUT: Duration = Duration::from_secs(2);

/// One kept connection.
#[derive(Default)]
struct Kept {
    client: Option<(ControlClient, Instant)>,
}

impl Kept {
    /// The kept connection, or a new one when there is none or it has idled too long.
    fn client(
        &mut self,
        socket_dir: &Path,
        timeout: Option<Duration>,
    ) -> Result<&mut ControlClient, ControlClientError> {
        if self.client.as_ref().is_none_or(|(_, used)| used.elapsed() > IDLE_REUSE) {
            let c = match timeout {
                Some(t) => ControlClient::connect_with_timeout(socket_dir, t)?,
                None => ControlClient::connect(socket_dir)?,
            };
            self.client = Some((c, Instant::now()));
        }
        let (c, used) = self.client.as_mut().expect("set above");
        *used = Instant::now();
        Ok(c)
    }
}

/// The last status read and when.
struct Cached {
    at: Instant,
    report: Result<StatusReport, Arc<ControlClientError>>,
}

/// The console's link to the daemon.
pub(crate) struct DaemonLink {
    socket_dir: PathBuf,
    status: Mutex<(Kept, Option<Cached>)>,
    actions: Mutex<Kept>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl DaemonLink {
    pub(crate) fn new(socket_dir: PathBuf) -> DaemonLink {
        DaemonLink { socket_dir, status: Mutex::default(), actions: Mutex::default() }
    }

    /// The daemon's status, at most [`STATUS_FRESH`] old (the error, shared with the requests
    /// answered from the same cache, when it cannot be read).
    pub(crate) fn status(&self) -> Result<StatusReport, Arc<ControlClientError>> {
        let mut guard = lock(&self.status);
        let (kept, cached) = &mut *guard;
        if let Some(c) = cached.as_ref().filter(|c| c.at.elapsed() < STATUS_FRESH) {
            return c.report.clone();
        }
        let fresh = kept.client.is_none();
        let mut report = read_again(kept, &self.socket_dir);
        if report.is_err() && !fresh {
            // The kept connection may have been closed by the daemon: once more, anew.
            report = read_again(kept, &self.socket_dir);
        }
        let report = report.map_err(Arc::new);
        *cached = Some(Cached { at: Instant::now(), report: report.clone() });
        report
    }

    /// Sends one action and returns the daemon's answer (never sent twice).
    pub(crate) fn request(&self, request: &ControlRequest) -> Result<ControlReply, ControlClientError> {
        let mut kept = lock(&self.actions);
        let answer = kept.client(&self.socket_dir, None)?.request(request);
        if matches!(answer, Err(ref e) if !matches!(e, ControlClientError::Refused { .. })) {
            kept.client = None;
        }
        answer
    }
}

/// A status read on a fresh connection.
fn read_again(kept: &mut Kept, socket_dir: &Path) -> Result<StatusReport, ControlClientError> {
    let report = kept.client(socket_dir, Some(STATUS_TIMEOUT))?.status();
    if report.is_err() {
        kept.client = None;
    }
    report
}
