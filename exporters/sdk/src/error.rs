//! Typed errors of the subscriber.

use std::io;
use std::path::PathBuf;
use std::time::Duration;

use frond_protocol::DecodeError;
use thiserror::Error;

/// Everything that can go wrong while subscribing to the pose stream.
#[derive(Debug, Error)]
pub enum SdkError {
    /// Nothing listens on the pose socket (no file, or a stale file from a dead daemon).
    #[error(
        "the frond daemon is not running: cannot connect to {}: {source} \
         (start it with `frondd`, or set --socket-dir / FROND_SOCKET_DIR to where it runs)",
        path.display()
    )]
    NotRunning {
        /// The pose socket path tried.
        path: PathBuf,
        /// The connect error.
        #[source]
        source: io::Error,
    },
    /// An I/O error on an established connection other than a clean close.
    #[error("i/o error on {}: {source}", path.display())]
    Io {
        /// The pose socket path.
        path: PathBuf,
        /// The error.
        #[source]
        source: io::Error,
    },
    /// The daemon sent something that is not valid frond protocol. The connection is dropped.
    #[error("protocol error on {}: {error}", path.display())]
    Protocol {
        /// The pose socket path.
        path: PathBuf,
        /// What was wrong.
        #[source]
        error: ProtocolError,
    },
    /// No message arrived within the read timeout. The connection is kept; call again to wait more.
    #[error("no message from {} within {timeout:?}", path.display())]
    Timeout {
        /// The pose socket path.
        path: PathBuf,
        /// The configured timeout.
        timeout: Duration,
    },
    /// Reconnection was enabled, but the daemon did not come back within the configured bound.
    #[error(
        "gave up reconnecting to {} after {attempts} attempts over {elapsed:?}: {last}",
        path.display()
    )]
    ReconnectFailed {
        /// The pose socket path.
        path: PathBuf,
        /// Connection attempts made.
        attempts: u32,
        /// Time spent trying.
        elapsed: Duration,
        /// The last attempt's error.
        last: Box<SdkError>,
    },
    /// The daemon refused the connection and said why (its subscriber limit is reached). Not
    /// fatal: a reconnecting subscriber keeps trying until a slot frees or it gives up.
    #[error("the frond daemon at {} refused the subscription: {reason}", path.display())]
    Refused {
        /// The pose socket path.
        path: PathBuf,
        /// The daemon's reason.
        reason: String,
    },
    /// The subscriber is finished (disconnected without reconnection, or after a fatal error).
    #[error("the subscription is closed")]
    Closed,
    /// No `frond-zenoh` bridge answered for the source within the hello timeout.
    #[error(
        "no frond-zenoh bridge answered for {source_key} within {waited:?} (is `frond-zenoh` running \
         beside the daemon with this --stage and --source, and can this host reach it? add \
         ?connect=tcp/HOST:7447 to the address when scouting cannot find it){}",
        on_the_network(present.as_deref())
    )]
    NoBridge {
        /// The source address.
        source_key: String,
        /// How long it waited.
        waited: Duration,
        /// The sources (`<stage>/<source>`) whose bridges this host does reach, when it asked:
        /// a misspelt name is then plain to see.
        present: Option<Vec<String>>,
    },
    /// A wildcard source address matches several sources; a subscription follows one.
    #[error("{selector} matches {} sources ({}); name one of them", matches.len(), matches.join(", "))]
    AmbiguousSource {
        /// The address as given.
        selector: String,
        /// The sources that answered.
        matches: Vec<String>,
    },
    /// The Zenoh session could not be set up (configuration, endpoints).
    #[error("{source_key}: {reason}")]
    Zenoh {
        /// The source address.
        source_key: String,
        /// What Zenoh said.
        reason: String,
    },
}

impl SdkError {
    /// True when retrying cannot help: a protocol version mismatch or an exhausted retry budget.
    pub fn is_fatal(&self) -> bool {
        match self {
            SdkError::Protocol { error, .. } => error.is_fatal(),
            SdkError::ReconnectFailed { .. }
            | SdkError::Closed
            | SdkError::AmbiguousSource { .. }
            | SdkError::Zenoh { .. } => true,
            _ => false,
        }
    }
}

/// Ways the daemon's byte stream can violate the protocol.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum ProtocolError {
    /// The daemon speaks a different protocol version than this SDK.
    #[error(
        "the daemon speaks protocol version {got}, this program understands version {supported}; \
         rebuild it against the frond-sdk that matches the daemon"
    )]
    UnsupportedVersion {
        /// Version announced by the daemon.
        got: u8,
        /// Version this SDK speaks.
        supported: u8,
    },
    /// A frame did not decode.
    #[error("{0}")]
    Frame(DecodeError),
    /// The first message of a connection was not a `Hello`.
    #[error("the first message on the connection was not a hello")]
    ExpectedHello,
    /// A pose's sequence number went backwards on one connection.
    #[error("sequence number went backwards: expected {expected} or later, got {got}")]
    SeqWentBackwards {
        /// The lowest acceptable sequence number.
        expected: u64,
        /// The one received.
        got: u64,
    },
}

impl ProtocolError {
    /// True for version mismatches, which no reconnection can fix.
    pub fn is_fatal(&self) -> bool {
        matches!(self, ProtocolError::UnsupportedVersion { .. })
    }
}

impl From<DecodeError> for ProtocolError {
    fn from(e: DecodeError) -> Self {
        match e {
            DecodeError::UnsupportedVersion { got, supported } => {
                ProtocolError::UnsupportedVersion { got, supported }
            }
            other => ProtocolError::Frame(other),
        }
    }
}

/// The tail of [`SdkError::NoBridge`]'s message: what is on the network instead.
fn on_the_network(present: Option<&[String]>) -> String {
    match present {
        None => String::new(),
        Some([]) => "; no frond-zenoh bridge is on the network this host reaches".into(),
        Some(names) => format!("; on the network: {}", names.join(", ")),
    }
}
