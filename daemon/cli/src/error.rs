//! The errors that decide `frond`'s exit status (see the crate docs): a usage error (2), a
//! program `frond` ran that already said why it failed (its status), an interruption (130).
//! A module of its own, importing nothing of the crate, so that every command can use it.

use std::fmt;

/// An error in what the user asked for (exit status 2).
#[derive(Debug)]
pub struct UsageError(pub String);

impl fmt::Display for UsageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// Shorthand for returning a [`UsageError`].
pub(crate) fn usage<T>(msg: impl Into<String>) -> anyhow::Result<T> {
    Err(UsageError(msg.into()).into())
}

/// A program `frond` ran for the user (e.g. `frond-bench`) failed and already said why on
/// stderr: exit with its status, adding nothing.
#[derive(Debug)]
pub struct ChildFailed(pub u8);

impl fmt::Display for ChildFailed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "exit status {}", self.0)
    }
}

impl std::error::Error for ChildFailed {}

/// The user pressed Ctrl-C (or the command got SIGTERM); exit status 130.
#[derive(Debug)]
pub struct Interrupted;

impl fmt::Display for Interrupted {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("interrupted")
    }
}

impl std::error::Error for Interrupted {}
