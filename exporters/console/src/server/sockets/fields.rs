//! A running field on the page's socket ([`crate::meadow`]): the fields' table when it
//! changes, then every field frame once, in order, a few dozen to a message.

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
    pub(super) fn send_fields(&self, ws: &mut WebSocket<TcpStream>, at: &mut FieldCursor) -> bool {
        let (table, more) = {
            let s = self.live.lock();
            let table = (s.fields.version != at.version).then(|| (s.fields.version, s.fields.table_json()));
            at.frames.clear();
            s.fields.frames_since(&mut at.frame, FIELD_FRAMES_PER_MESSAGE, &mut at.frames);
            (table, !at.frames.is_empty())
        };
        if let Some((version, msg)) = table {
            match self.send(ws, msg.to_string()) {
                Sent::Queued => at.version = version,
                Sent::Dropped => {}
                Sent::Gone => return false,
            }
        }
        if more {
            // Frames a slow page cannot take are lost to it (counted): the daemon's trickle
            // brings their stream frames again.
            let msg = json!({ "type": "field-frames", "frames": at.frames });
            if self.send(ws, msg.to_string()) == Sent::Gone {
                return false;
            }
        }
        true
    }
}
