//! Client of the daemon's control socket (`control.sock`): one connection carries any number of
//! request/reply pairs ([`ControlRequest`] / [`ControlReply`], the same framing as the pose
//! stream). The daemon decides who may send what (its allow-list of uids and gids); a refusal is
//! [`ControlClientError::Refused`] with the daemon's own words. `frond` and `frond-console` both
//! act through it.
//!
//! ```no_run
//! use frond_protocol::ControlRequest;
//! use frond_sdk::ControlClient;
//!
//! let mut daemon = ControlClient::connect(&frond_protocol::paths::socket_dir(None))?;
//! let status = daemon.status()?;
//! println!("{} at {:.0} Hz", status.rig_name, status.achieved_rate_hz);
//! daemon.request(&ControlRequest::RecordStart { name: "take-1".into() })?;
//! # Ok::<(), frond_sdk::ControlClientError>(())
//! ```

use std::io;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::Duration;

use frond_protocol::{
    CONTROL_SOCKET, ControlErrorKind, ControlReply, ControlRequest, FrameBuf, ReadError, StatusReport,
    read_frame, write_frame,
};
use thiserror::Error;

/// How long to wait for one reply by default.
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(10);

/// What can go wrong talking to the control socket.
#[derive(Debug, Error)]
pub enum ControlClientError {
    /// Nothing to connect to (no socket, or one left behind by a daemon that exited).
    #[error("{}", not_running_message(path, source))]
    NotRunning {
        /// The control socket path tried.
        path: PathBuf,
        /// The connect error.
        #[source]
        source: io::Error,
    },
    /// The socket exists but this user may not connect to it.
    #[error("permission denied connecting to {} (is the daemon run by another user?)", path.display())]
    PermissionDenied {
        /// The control socket path.
        path: PathBuf,
    },
    /// The request could not be written.
    #[error("sending a request to {}: {source}", path.display())]
    Send {
        /// The control socket path.
        path: PathBuf,
        /// The write error.
        #[source]
        source: io::Error,
    },
    /// No reply within the timeout.
    #[error("the daemon did not answer within {timeout:?} on {}", path.display())]
    Timeout {
        /// The control socket path.
        path: PathBuf,
        /// The reply timeout.
        timeout: Duration,
    },
    /// The daemon closed the connection without a reply.
    #[error("the daemon closed {} without answering", path.display())]
    Closed {
        /// The control socket path.
        path: PathBuf,
    },
    /// The reply did not decode.
    #[error("bad reply on {}: {reason}", path.display())]
    BadReply {
        /// The control socket path.
        path: PathBuf,
        /// What was wrong.
        reason: String,
    },
    /// The daemon answered with a refusal.
    #[error("the daemon refused: {message} ({kind:?})")]
    Refused {
        /// The daemon's kind of refusal.
        kind: ControlErrorKind,
        /// The daemon's explanation.
        message: String,
    },
    /// A remote daemon (over Zenoh, through its bridge) could not be asked.
    #[error("remote control of {key}: {reason}")]
    Remote {
        /// The source's key expression.
        key: String,
        /// What went wrong.
        reason: String,
    },
    /// The daemon answered, but not with the kind of reply the request calls for.
    #[error("the daemon gave an unexpected reply ({got}); is it a different frond version?")]
    Unexpected {
        /// The reply's kind.
        got: &'static str,
    },
}

/// The explanation given when the daemon cannot be reached.
pub fn not_running_message(path: &Path, err: &io::Error) -> String {
    let why = match err.kind() {
        io::ErrorKind::NotFound => format!("no control socket at {}", path.display()),
        io::ErrorKind::ConnectionRefused => {
            format!("nothing listens on {} (left behind by a daemon that exited)", path.display())
        }
        _ => format!("cannot connect to {}: {err}", path.display()),
    };
    format!(
        "the frond daemon is not running: {why}. Start it with `frondd --socket-dir {}`, or try \
         `frond demo`; the system service (`systemctl start frondd`, systemd/frondd.service) \
         listens in /run/frond (set FROND_SOCKET_DIR=/run/frond); if it runs elsewhere, pass \
         --socket-dir or set FROND_SOCKET_DIR",
        path.parent().unwrap_or(Path::new(".")).display()
    )
}

/// The name of a reply's kind, for messages.
pub fn reply_kind(reply: &ControlReply) -> &'static str {
    match reply {
        ControlReply::Ok => "Ok",
        ControlReply::Status(_) => "Status",
        ControlReply::Recording(_) => "Recording",
        ControlReply::RawSample { .. } => "RawSample",
        ControlReply::Error(_) => "Error",
    }
}

/// One connection to `control.sock`.
#[derive(Debug)]
pub struct ControlClient {
    path: PathBuf,
    stream: UnixStream,
    out: FrameBuf,
    scratch: Vec<u8>,
    timeout: Duration,
}

impl ControlClient {
    /// Connects to the control socket of the daemon in `socket_dir`, with [`REPLY_TIMEOUT`].
    pub fn connect(socket_dir: &Path) -> Result<ControlClient, ControlClientError> {
        Self::connect_with_timeout(socket_dir, REPLY_TIMEOUT)
    }

    /// Connects, waiting at most `timeout` for each reply (and each write).
    pub fn connect_with_timeout(
        socket_dir: &Path,
        timeout: Duration,
    ) -> Result<ControlClient, ControlClientError> {
        let path = socket_dir.join(CONTROL_SOCKET);
        let stream = match UnixStream::connect(&path) {
            Ok(s) => s,
            Err(e) if e.kind() == io::ErrorKind::PermissionDenied => {
                return Err(ControlClientError::PermissionDenied { path });
            }
            Err(source) => return Err(ControlClientError::NotRunning { path, source }),
        };
        let timeouts = stream.set_read_timeout(Some(timeout)).and(stream.set_write_timeout(Some(timeout)));
        if let Err(source) = timeouts {
            return Err(ControlClientError::Send { path, source });
        }
        Ok(ControlClient { path, stream, out: FrameBuf::default(), scratch: Vec::new(), timeout })
    }

    /// The control socket's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Sends `req` and returns the daemon's reply; a refusal is [`ControlClientError::Refused`].
    pub fn request(&mut self, req: &ControlRequest) -> Result<ControlReply, ControlClientError> {
        if let Err(source) = write_frame(&mut self.stream, &mut self.out, req) {
            // The daemon answers a client it does not allow at once and closes, possibly before
            // the request is written: its refusal is still there to read.
            if let Ok(ControlReply::Error(err)) = read_frame(&mut self.stream, &mut self.scratch) {
                return Err(ControlClientError::Refused { kind: err.kind, message: err.message });
            }
            return Err(ControlClientError::Send { path: self.path.clone(), source });
        }
        let reply: ControlReply = read_frame(&mut self.stream, &mut self.scratch).map_err(|e| match e {
            ReadError::Io(io) if matches!(io.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                ControlClientError::Timeout { path: self.path.clone(), timeout: self.timeout }
            }
            ReadError::Closed => ControlClientError::Closed { path: self.path.clone() },
            other => ControlClientError::BadReply { path: self.path.clone(), reason: other.to_string() },
        })?;
        match reply {
            ControlReply::Error(err) => {
                Err(ControlClientError::Refused { kind: err.kind, message: err.message })
            }
            other => Ok(other),
        }
    }

    /// Sends `req` and expects a plain `Ok`.
    pub fn expect_ok(&mut self, req: &ControlRequest) -> Result<(), ControlClientError> {
        match self.request(req)? {
            ControlReply::Ok => Ok(()),
            other => Err(ControlClientError::Unexpected { got: reply_kind(&other) }),
        }
    }

    /// Asks for the daemon's status.
    pub fn status(&mut self) -> Result<StatusReport, ControlClientError> {
        match self.request(&ControlRequest::Status)? {
            ControlReply::Status(s) => Ok(*s),
            other => Err(ControlClientError::Unexpected { got: reply_kind(&other) }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_socket_is_not_running_with_the_fix() {
        let dir = tempfile::tempdir().unwrap();
        let e = ControlClient::connect(dir.path()).unwrap_err();
        assert!(matches!(e, ControlClientError::NotRunning { .. }), "{e:?}");
        let m = e.to_string();
        assert!(m.contains("no control socket at") && m.contains("frondd --socket-dir"), "{m}");
    }
}
