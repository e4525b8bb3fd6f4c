//! A running field on the page's socket ([`crate::meadow`]): the fields' table when it
//! changes, then every field frame once, in order, all those since the last message in one;
//! and the page's flow control ([`PageFlow`]).

use std::net::TcpStream;

use serde_json::json;
use tungstenite::WebSocket;

use super::Sent;
use crate::meadow::FIELD_FRAMES_PER_MESSAGE;
use crate::server::Console;

/// Where a page is in the fields' table and frames.
#[derive(Debug)]
pub(super) struct FieldCursor {
    version: u64,
    frame: u64,
    frames: Vec<frond_protocol::field::FieldFrame>,
}

impl Default for FieldCursor {
    fn default() -> Self {
        // Nothing sent yet: the table goes first, then the ring's last second.
        FieldCursor { version: u64::MAX, frame: u64::MAX, frames: Vec::new() }
    }
}

impl Console {
    /// Sends the page what it has not had of the running fields; `false` when it is gone.
    pub(super) fn send_fields(
        &self,
        ws: &mut WebSocket<TcpStream>,
        at: &mut FieldCursor,
        flow: &mut PageFlow,
    ) -> bool {
        let (table, more) = {
            let s = self.live.lock();
            let table = (s.fields.version != at.version).then(|| (s.fields.version, s.fields.table_json()));
            at.frames.clear();
            s.fields.frames_since(&mut at.frame, FIELD_FRAMES_PER_MESSAGE, &mut at.frames);
            (table, !at.frames.is_empty())
        };
        if let Some((version, msg)) = table {
            match flow.count(self.send(ws, msg.to_string())) {
                Sent::Queued => at.version = version,
                Sent::Dropped => {}
                Sent::Gone => return false,
            }
        }
        if more {
            // Frames a slow page cannot take are lost to it (counted): the daemon's trickle
            // brings their stream frames again.
            let msg = json!({ "type": "field-frames", "frames": at.frames });
            if flow.count(self.send(ws, msg.to_string())) == Sent::Gone {
                return false;
            }
        }
        true
    }
}

/// Messages a page that acknowledges may be behind (queued to it and not yet taken): about
/// four display periods of poses and field frames (two messages a period), so that while the
/// page draws one frame in that time the stream goes on, and its next frame draws the newest.
pub(super) const MAX_UNACKED: u64 = 8;

/// What a page has taken of the messages queued to it. The page (console.js) sends
/// `{"ack": N}` as it handles each message, N the messages it has taken on this socket; once it
/// does, it is sent nothing more while it is [`MAX_UNACKED`] behind, so a page slower than the
/// stream (a large meadow drawn in software) draws the latest poses and field frames when it is
/// ready instead of working through seconds of queued ones. A page that never acknowledges is
/// sent everything, as before.
#[derive(Debug, Default)]
pub(super) struct PageFlow {
    queued: u64,
    acked: Option<u64>,
}

impl PageFlow {
    /// Counts a message queued to the page; returns `sent` as it was.
    pub(super) fn count(&mut self, sent: Sent) -> Sent {
        if sent == Sent::Queued {
            self.queued += 1;
        }
        sent
    }

    /// Takes what the page said: `{"ack": N}` (anything else, or a count beyond what was
    /// queued, is ignored).
    pub(super) fn on_text(&mut self, text: &str) {
        let n = serde_json::from_str::<serde_json::Value>(text).ok().and_then(|v| v["ack"].as_u64());
        if let Some(n) = n.filter(|&n| n <= self.queued) {
            self.acked = Some(self.acked.map_or(n, |a| a.max(n)));
        }
    }

    /// Whether the page is too far behind to be sent more now.
    pub(super) fn behind(&self) -> bool {
        self.acked.is_some_and(|a| self.queued - a >= MAX_UNACKED)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_page_that_acknowledges_is_never_more_than_a_few_messages_behind() {
        let mut f = PageFlow::default();
        for _ in 0..15 {
            f.count(Sent::Queued);
        }
        f.count(Sent::Dropped);
        assert!(!f.behind(), "a page that never acknowledges is sent everything");
        f.on_text(r#"{"ack": 8}"#);
        assert!(!f.behind(), "7 behind");
        f.count(Sent::Queued);
        assert!(f.behind(), "8 behind");
        f.on_text(r#"{"ack": 99}"#);
        f.on_text("not json");
        f.on_text(r#"{"ack": 5}"#);
        assert!(f.behind(), "counts beyond what was queued, or older, change nothing");
        f.on_text(r#"{"ack": 9}"#);
        assert!(!f.behind());
    }
}
