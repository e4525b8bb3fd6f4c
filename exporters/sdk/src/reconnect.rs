//! Reconnecting after [`Event::Disconnected`], with exponential backoff. A reconnection that
//! outlasts the subscriber's read timeout returns [`SdkError::Timeout`] and carries on at the
//! next call, so a caller that polls a stop flag between calls (every exporter does, on
//! SIGTERM) regains control while its daemon or bridge is away; the backoff and the
//! `give_up_after` bound count from the disconnection, across calls.

use std::time::{Duration, Instant};

use crate::{Event, SdkError, State, Subscriber, open_wire};

/// Shortest wait for a hello an attempt is given when the read deadline is nearer: a Zenoh
/// query needs a moment to reach the bridge and come back.
const MIN_ATTEMPT: Duration = Duration::from_millis(100);

/// A reconnection under way.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Retry {
    /// When the first attempt was made (what `give_up_after` counts from).
    since: Instant,
    /// When the next attempt is due.
    next_at: Instant,
    /// The backoff after the next failure.
    delay: Duration,
    attempts: u32,
}

impl Subscriber {
    /// Tries to connect again, waiting between attempts; returns [`Event::Reconnected`], a
    /// fatal error, [`SdkError::ReconnectFailed`] past `give_up_after`, or, when a read timeout
    /// is set and runs out first, [`SdkError::Timeout`] with the state kept for the next call.
    pub(crate) fn reconnect(&mut self) -> Result<Event, SdkError> {
        let deadline = self.opts.read_timeout.map(|t| Instant::now() + t);
        let mut kept = match std::mem::replace(&mut self.state, State::Disconnected(None)) {
            State::Disconnected(kept) => kept,
            _ => None,
        };
        let mut retry = self.retry.take().unwrap_or_else(|| {
            let now = Instant::now();
            Retry { since: now, next_at: now, delay: self.opts.retry_interval, attempts: 0 }
        });
        loop {
            if let Some(deadline) = deadline
                && retry.next_at > deadline
            {
                std::thread::sleep(deadline.saturating_duration_since(Instant::now()));
                self.state = State::Disconnected(kept);
                self.retry = Some(retry);
                return Err(SdkError::Timeout {
                    path: self.path.clone(),
                    timeout: self.opts.read_timeout.unwrap_or_default(),
                });
            }
            std::thread::sleep(retry.next_at.saturating_duration_since(Instant::now()));
            retry.attempts += 1;
            // An attempt waits for a hello no longer than the caller waits for an event.
            let mut opts = self.opts.clone();
            if let Some(deadline) = deadline {
                let left = deadline.saturating_duration_since(Instant::now()).max(MIN_ATTEMPT);
                opts.hello_timeout = opts.hello_timeout.min(left);
            }
            match open_wire(&self.source, &opts, &mut kept) {
                Ok((wire, hello)) => {
                    tracing::info!(path = %self.path.display(), attempts = retry.attempts, "reconnected");
                    self.state = State::Connected(wire);
                    self.expected_seq = hello.next_seq;
                    self.hello = hello.clone();
                    self.elements = hello.elements.clone();
                    self.stats.reconnects += 1;
                    return Ok(Event::Reconnected(hello));
                }
                Err(e) if e.is_fatal() => {
                    self.state = State::Finished;
                    return Err(e);
                }
                Err(e) => {
                    let elapsed = retry.since.elapsed();
                    if self.opts.give_up_after.is_some_and(|limit| elapsed + retry.delay > limit) {
                        self.state = State::Finished;
                        return Err(SdkError::ReconnectFailed {
                            path: self.path.clone(),
                            attempts: retry.attempts,
                            elapsed,
                            last: Box::new(e),
                        });
                    }
                    tracing::debug!(error = %e, delay = ?retry.delay, "reconnect attempt failed");
                    retry.next_at = Instant::now() + retry.delay;
                    retry.delay = (retry.delay * 2).min(self.opts.max_retry_interval);
                }
            }
        }
    }
}
