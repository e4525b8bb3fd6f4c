//! Why a measurement could not be made. A section that fails is reported, not fatal: its
//! error's text becomes the section's `reason` in `frond bench --json` and the table, so every
//! variant says in words what went wrong and where (the texts are part of the report's output
//! and stay as they are).

use std::path::PathBuf;
use std::process::ExitStatus;

/// What stopped a measurement.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A socket, a scratch directory or a thread could not be set up; the system's own words.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A file, socket, directory or address could not be used (`path`: where it is, or what
    /// it is in words when it has none yet: "a scratch directory").
    #[error("{}: {source}", path.display())]
    Path {
        /// What could not be used.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A program could not be started (`what`: its name, and where it runs).
    #[error("cannot start {what}: {source}")]
    Start {
        /// The program, as the report names it.
        what: String,
        /// Why the start failed.
        #[source]
        source: std::io::Error,
    },
    /// One of the workspace's binaries is not built where the bench looks
    /// ([`crate::procs::bin_dir`]).
    #[error(
        "{} not found (build it: cargo build --release -p frond-cli -p frondd -p frond-device, or set FROND_BIN_DIR)",
        .0.display()
    )]
    NotBuilt(PathBuf),
    /// A child process was started without the pipe the bench reads or writes (`what` names it).
    #[error("{0}")]
    NoPipe(&'static str),
    /// A child process could not be read: `what` was being read.
    #[error("reading {what}: {source}")]
    Read {
        /// What was being read.
        what: &'static str,
        /// Why it failed.
        #[source]
        source: std::io::Error,
    },
    /// A helper thread of the bench panicked (`0` names it: "the loop thread").
    #[error("{0} panicked")]
    Panicked(&'static str),
    /// A daemon's control socket answered with a frame the bench could not read.
    #[error(transparent)]
    Control(#[from] frond_protocol::ReadError),
    /// A daemon answered a status request with something else.
    #[error("unexpected status reply {0}")]
    UnexpectedReply(String),
    /// `frondd` exited before its control socket answered.
    #[error("frondd exited during start-up: {0}")]
    DaemonExited(ExitStatus),
    /// `frondd` did not answer on its control socket in time.
    #[error("frondd did not answer on its control socket within 20 s")]
    DaemonSilent,
    /// `frond-vhid` did not print the node it serves (it failed; its error is on stderr).
    #[error("frond-vhid printed no node path (see its error above)")]
    NoNodePath,
    /// A child process said something other than what the bench waits for, or nothing in time,
    /// or ended; the text names the process and what it said.
    #[error("{0}")]
    Peer(String),
    /// Data that should flow did not: subscribers that received nothing, a histogram without
    /// samples; the text says which and how many.
    #[error("{0}")]
    NoData(String),
    /// A `kB` field is missing from `/proc/PID/status`.
    #[error("{path}: no {field}")]
    ProcField {
        /// The status file.
        path: String,
        /// The field looked for (`VmRSS`).
        field: String,
    },
    /// The engine's command queue closed before the bench could add its subscribers.
    #[error("the engine's command queue is closed")]
    EngineGone,
    /// The engine was lost to a loop run that failed earlier.
    #[error("the engine was lost")]
    EngineLost,
    /// SCHED_FIFO was not asked for (priority 0).
    #[error("not asked")]
    FifoNotAsked,
    /// The motion toolkit refused the bench's own clip (a looping search that found nothing).
    #[error(transparent)]
    Loop(#[from] frond_motion::looping::LoopError),
    /// The motion toolkit refused the bench's own field parameters.
    #[error(transparent)]
    Field(#[from] frond_motion::field::FieldError),
}

impl BenchError {
    /// [`BenchError::Path`] for `path`, as a `map_err` closure.
    pub fn at(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> BenchError {
        let path = path.into();
        move |source| BenchError::Path { path, source }
    }

    /// [`BenchError::Start`] for the program `what`, as a `map_err` closure.
    pub fn start(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> BenchError {
        let what = what.into();
        move |source| BenchError::Start { what, source }
    }
}
