//! Leap Motion / Ultraleap hand tracking as a hand source: `leap://HOST:PORT[?hand=left|right]`.
//!
//! Files by responsibility: [`frames`] parses the service's JSON and maps a hand to a sample
//! (pure), [`address`] the kind text, `stream` the socket's budgeted reads and never-waiting
//! writes, `client` the connecting thread, `source` the loop's side ([`LeapSource`]).
//!
//! A helper thread is a WebSocket client of the tracking service (protocol v6 on `/v6.json`,
//! [`frames`] parses and maps it): it asks for frames in the background (`{"background":
//! true}`, `{"focused": true}`), turns each frame's chosen hand into a [`DeviceSample`](crate::DeviceSample) and queues
//! it for the realtime loop, ringing a [`Doorbell`](crate::doorbell::Doorbell) (the source's ready descriptor). When the
//! service is down or restarts, the thread reconnects (every half second at first, backing off to
//! 2 s) while the loop sees no samples: poses are flagged held, then device-lost, as for any
//! stalled device; a hand out of view does the same. The loop's side never blocks or allocates.
//!
//! The service is a peer, not a friend (issue 42): nothing it does can hold the daemon.
//! - Writes never wait (`stream::ServiceStream`: `MSG_DONTWAIT`, a bounded write buffer). Pongs that
//!   it does not read for `client::PEER_WRITE_DEADLINE` drop the connection (counted as
//!   `peers_dropped`); reads wait at most `client::READ_POLL` and end as soon as the source is asked
//!   to stop, even in the middle of a message trickled byte by byte.
//! - Dropping the source waits at most `source::STOP_WAIT` for the thread (a name lookup of the
//!   service's host cannot be interrupted); a thread still busy then is left to end by itself.
//! - A message longer than [`MAX_MESSAGE_BYTES`] is refused from its header (tungstenite's
//!   limit; counted as `oversized`, the connection is dropped), a frame listing more than
//!   `MAX_HANDS` hands at the first one too many (`too_many`), before the rest is parsed.
//! - Reads are paced (`stream::READ_BUDGET` per `stream::READ_WINDOW`) in bytes and in frames: each
//!   WebSocket frame costs `stream::FRAME_COST` besides its bytes, so endless empty messages or
//!   zero-length fragments cost a bounded share of a core; a service that keeps the budget spent
//!   for `client::JUNK_DEADLINE` without a message frond can use is dropped (`peers_dropped`).
//! - Connection warnings are rate-limited ([`crate::log_limit`]); refused messages are only
//!   counted here, and the daemon says their counts by reason at a bounded rate.

pub mod address;
mod client;
pub mod frames;
mod source;
mod stream;
#[cfg(test)]
mod tests;

pub use address::{LeapAddress, LeapAddressError};
pub use frames::MAX_MESSAGE_BYTES;
pub use source::LeapSource;

use super::spec::{Backend, SourceSpec, SpecError, SpecInput};

/// `leap://HOST:PORT[?hand=left|right]`: a Leap Motion / Ultraleap tracking service.
pub(crate) const BACKEND: Backend = Backend { syntax: "leap://HOST:PORT", parse };

fn parse(kind: &str, input: &SpecInput<'_>) -> Option<Result<SourceSpec, SpecError>> {
    kind.starts_with("leap://").then(|| match kind.parse::<LeapAddress>() {
        Ok(a) => Ok(SourceSpec::Leap(a)),
        Err(problem) => Err(SpecError::BadLeap { key: input.key.to_string(), problem }),
    })
}
