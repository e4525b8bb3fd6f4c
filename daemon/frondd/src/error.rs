//! Why the daemon could not start or reload: one enum, each variant naming the problem.

use std::path::PathBuf;

use frond_formats::rig_files::{FileError, RigFileError};
use frond_motion::{CalibrationError, FilterSpecError};

/// What stopped `frondd` from starting (or a reload from applying).
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    /// The rig could not be found, read or validated.
    #[error(transparent)]
    Rig(#[from] RigFileError),
    /// The calibration file could not be read.
    #[error("cannot read the calibration: {0}")]
    CalibrationFile(#[source] FileError),
    /// The calibration file is not valid.
    #[error("{}: {source}", path.display())]
    Calibration {
        /// The file.
        path: PathBuf,
        /// Every problem with its key.
        #[source]
        source: CalibrationError,
    },
    /// The filter spec is not valid.
    #[error("filter {spec:?}: {source}")]
    Filter {
        /// The spec text.
        spec: String,
        /// What is wrong with it.
        #[source]
        source: FilterSpecError,
    },
    /// A file-system operation on the socket directory failed.
    #[error("{what} {}: {source}", path.display())]
    Io {
        /// What was being done (`cannot bind`, ...).
        what: &'static str,
        /// On which path.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Another daemon answers on the socket directory.
    #[error("another frondd is already running with socket directory {}", .0.display())]
    AlreadyRunning(PathBuf),
    /// The hand source could not be opened.
    #[error("{0}")]
    Source(String),
    /// A hand of the configuration cannot be set up (its element, its rig).
    #[error("hand {hand:?}: {message}")]
    Hand {
        /// The hand's name.
        hand: String,
        /// What is wrong.
        message: String,
    },
    /// A daemon thread could not be started.
    #[error("cannot start a daemon thread: {0}")]
    Thread(#[from] std::io::Error),
    /// The rig, calibration and filter could not be put in force.
    #[error("{0}")]
    Setup(String),
    /// The capture-trigger socket (`triggers.listen`, or the one `triggers.lead` sends from)
    /// could not be bound.
    #[error("triggers: cannot bind UDP {addr}: {source}{hint}")]
    Triggers {
        /// The address.
        addr: std::net::SocketAddr,
        /// The OS error.
        #[source]
        source: std::io::Error,
        /// What to do about it, if known (a port below 1024 needs privileges).
        hint: &'static str,
    },
    /// The LTC input (`ltc.input`, `--ltc`) cannot be read: absent, not a file or FIFO, or a
    /// WAV file frond does not read.
    #[error(transparent)]
    Ltc(#[from] crate::ltc_input::LtcInputError),
    /// The realtime loop thread panicked.
    #[error("the realtime loop panicked")]
    LoopPanicked,
}

impl DaemonError {
    /// An I/O error doing `what` on `path`.
    pub fn io(what: &'static str, path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> DaemonError {
        let path = path.into();
        move |source| DaemonError::Io { what, path, source }
    }
}
