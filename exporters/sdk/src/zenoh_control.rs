//! Remote control of a daemon on another host, through its bridge's `.../control` queryable
//! (`frond-zenoh --control FILE`): the same [`ControlRequest`] / [`ControlReply`] as the control
//! socket, each request signed as a principal of the bridge's allow-list
//! ([`crate::control_auth`]).

use std::time::{Duration, Instant};

use ::zenoh::Wait;
use frond_protocol::{ControlReply, ControlRequest, FrameBuf, decode_frame};

use crate::control::{ControlClientError, REPLY_TIMEOUT};
use crate::control_auth::{ControlKey, Envelope, new_nonce};
use crate::source::ZenohAddr;
use crate::stage_time::realtime_ns;
use crate::zenoh::{keys, open_addr_session};

/// A Zenoh session that sends signed control requests to one source.
pub struct RemoteControl {
    session: ::zenoh::Session,
    /// `frond/<stage>/<source>`.
    source_key: String,
    principal: String,
    key: ControlKey,
    timeout: Duration,
    frame: FrameBuf,
}

impl RemoteControl {
    /// Opens a session reaching the network as `addr` says; requests go to `addr`'s source
    /// (which must be one source, no wildcard) signed as `principal` with `key`.
    pub fn open(
        addr: &ZenohAddr,
        principal: &str,
        key: ControlKey,
    ) -> Result<RemoteControl, ControlClientError> {
        let remote = |reason: String| ControlClientError::Remote { key: addr.key.clone(), reason };
        if addr.key.contains('*') {
            return Err(remote("remote control names one source; the address holds a wildcard".into()));
        }
        crate::control_auth::check_principal(principal).map_err(|e| remote(e.to_string()))?;
        let session = open_addr_session(addr).map_err(|e| remote(e.to_string()))?;
        Ok(RemoteControl {
            session,
            source_key: addr.key.clone(),
            principal: principal.to_owned(),
            key,
            timeout: REPLY_TIMEOUT,
            frame: FrameBuf::default(),
        })
    }

    /// How long to wait for the bridge and for each reply (default [`REPLY_TIMEOUT`]).
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    fn remote(&self, reason: impl Into<String>) -> ControlClientError {
        ControlClientError::Remote { key: self.source_key.clone(), reason: reason.into() }
    }

    /// Waits until the source's bridge is on the network (its liveliness token), so that the
    /// request itself is sent once: a control request is not safe to repeat.
    fn wait_for_bridge(&self, deadline: Instant) -> Result<(), ControlClientError> {
        let alive = keys::under(&self.source_key, keys::ALIVE);
        loop {
            let wait = deadline.saturating_duration_since(Instant::now()).max(Duration::from_millis(100));
            let replies = self
                .session
                .liveliness()
                .get(&alive)
                .timeout(wait)
                .wait()
                .map_err(|e| self.remote(e.to_string()))?;
            if replies.into_iter().any(|r| r.result().is_ok()) {
                return Ok(());
            }
            if Instant::now() >= deadline {
                return Err(self.remote(format!(
                    "no bridge of this source is on the network (waited {:?}); is frond-zenoh running \
                     there, connected to its daemon, and reachable (--connect)?",
                    self.timeout
                )));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Sends `req` and returns the daemon's reply; a refusal (by the bridge: not authenticated,
    /// not allowed; or by the daemon) is [`ControlClientError::Refused`].
    pub fn request(&mut self, req: &ControlRequest) -> Result<ControlReply, ControlClientError> {
        let deadline = Instant::now() + self.timeout;
        self.wait_for_bridge(deadline)?;
        let key_expr = keys::under(&self.source_key, keys::CONTROL);
        let frame = self.frame.encode(req).to_vec();
        let issued_unix_ms = realtime_ns() / 1_000_000;
        let envelope =
            Envelope::sign(&self.key, &self.principal, &key_expr, issued_unix_ms, new_nonce(), &frame)
                .map_err(|e| self.remote(e.to_string()))?;
        let wait = deadline.saturating_duration_since(Instant::now()).max(Duration::from_secs(1));
        let replies = self
            .session
            .get(&key_expr)
            .payload(frame)
            .attachment(envelope.encode())
            .timeout(wait)
            .wait()
            .map_err(|e| self.remote(e.to_string()))?;
        let Ok(reply) = replies.recv() else {
            return Err(self.remote(format!(
                "no answer within {wait:?}: the bridge does not take remote control (start it with \
                 --control FILE), or the request was lost (it may or may not have run)"
            )));
        };
        let sample =
            reply.result().map_err(|e| self.remote(format!("the bridge answered with an error: {e:?}")))?;
        let bytes = sample.payload().to_bytes();
        match decode_frame::<ControlReply>(&bytes) {
            Ok(Some((ControlReply::Error(err), used))) if used == bytes.len() => {
                Err(ControlClientError::Refused { kind: err.kind, message: err.message })
            }
            Ok(Some((reply, used))) if used == bytes.len() => Ok(reply),
            Ok(_) => Err(self.remote("the reply is not one control reply frame")),
            Err(e) => Err(self.remote(format!("bad reply: {e}"))),
        }
    }
}
