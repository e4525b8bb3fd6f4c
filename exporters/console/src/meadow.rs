//! A running field for the page (protocol 3; seed 000, Eq. 6-7 and section 6.3): the console
//! passes on what the daemon publishes, each field's definition and every field frame, and the
//! page evaluates every plant itself (`page/field.js`, `frond_motion::field_eval` ported) and
//! draws them instanced (`page/meadow.js`). What goes to the page does not grow with the
//! field, except each field's layout, fetched once per definition as bytes
//! ([`FieldRelay::layout`]).
//!
//! The subscription thread (`crate::relay`) takes the SDK's field frames in order
//! ([`frond_sdk::Subscriber::take_field_frames`], [`collect`]) into a ring of the last
//! [`FIELD_FRAME_RING`]; each page's socket sends those after its own cursor at the display
//! rate. A page that loses frames (it reads slowly, the ring moved on) evaluates again once the
//! daemon's trickle has brought the missing stream frames back, as any subscriber does.

use std::collections::VecDeque;
use std::sync::Arc;

use frond_protocol::ElementId;
use frond_protocol::field::{FieldDefinition, FieldFrame};
use frond_sdk::Subscriber;
pub use frond_sdk::field::{LAYOUT_BYTES_PER_PLANT, layout_bytes};
use frond_web::http::Response;
use serde_json::{Value, json};

/// Field frames the console keeps for its pages (about 4 s at 60 Hz).
pub const FIELD_FRAME_RING: usize = 256;
/// Field frames a page that has just connected gets from the ring (a second at 60 Hz: the
/// newest stream frames at once, the rest of the history from the trickle).
pub const FIELD_FRAMES_ON_CONNECT: u64 = 64;
/// Field frames in one message to a page at most (a page that was busy gets all it missed in
/// one, about 200 KB at most).
pub const FIELD_FRAMES_PER_MESSAGE: usize = 128;

/// One running field as the page gets it.
pub use frond_sdk::field::RelayedField;

/// The running fields and their latest frames, shared with the page connections.
#[derive(Debug, Default)]
pub struct FieldRelay {
    /// Bumped whenever the running fields change.
    pub version: u64,
    /// The running fields.
    pub fields: Vec<RelayedField>,
    /// The latest field frames, each with its number (`next` - 1 the newest).
    frames: VecDeque<(u64, FieldFrame)>,
    next: u64,
    /// Field frames the SDK dropped before the subscription thread took them.
    pub dropped: u64,
}

impl FieldRelay {
    /// The layout of field `id`, if it runs.
    pub fn layout(&self, id: ElementId) -> Option<Arc<Vec<u8>>> {
        self.fields.iter().find(|f| f.definition.id == id).map(|f| Arc::clone(&f.layout))
    }

    /// `{"type": "fields", "version", "fields": [...]}`: what the page needs, besides the
    /// layout, to evaluate each field (field.js's `FieldEval` parameters).
    pub fn table_json(&self) -> Value {
        let fields: Vec<Value> = self
            .fields
            .iter()
            .map(|f| {
                let d = &f.definition;
                json!({
                    "id": d.id,
                    "source": d.source,
                    "rig": d.rig,
                    "plants": d.plants,
                    "rows": d.layout.rows,
                    "cols": d.layout.cols,
                    "cell_m": d.layout.cell_m,
                    "authored_direction_deg": d.layout.authored_direction_deg,
                    "stream_fps": d.stream_fps,
                    "history_frames": d.history_frames,
                    "publish_hz": d.publish_hz,
                    "layout": format!("/api/fields/{}/layout", d.id.get()),
                })
            })
            .collect();
        json!({ "type": "fields", "version": self.version, "fields": fields })
    }

    /// Appends to `out` the frames numbered from `*cursor` on and moves the cursor past them; a
    /// cursor of `u64::MAX` (a page just connected) starts [`FIELD_FRAMES_ON_CONNECT`] before
    /// the newest. A page more than `max` frames behind gets the newest `max` (it draws now,
    /// not what it missed: the daemon's trickle brings the stream frames it skipped again).
    pub fn frames_since(&self, cursor: &mut u64, max: usize, out: &mut Vec<FieldFrame>) {
        if *cursor == u64::MAX {
            *cursor = self.next.saturating_sub(FIELD_FRAMES_ON_CONNECT);
        }
        let from = (*cursor).max(self.next.saturating_sub(max as u64));
        for (n, f) in self.frames.iter().filter(|(n, _)| *n >= from).take(max) {
            out.push(*f);
            *cursor = n + 1;
        }
    }

    fn push(&mut self, frame: FieldFrame) {
        if self.frames.len() == FIELD_FRAME_RING {
            self.frames.pop_front();
        }
        self.frames.push_back((self.next, frame));
        self.next += 1;
    }
}

const MEADOW_JS: &str = include_str!("../page/meadow.js");
const MEADOW_RIG_JS: &str = include_str!("../page/meadow_rig.js");
const FIELD_JS: &str = include_str!("../page/field.js");

/// `GET /meadow.js` (the instanced drawing, a module; `/meadow_rig.js` the rigs it draws) and
/// `/field.js` (the evaluation, a classic script).
pub fn page_file(path: &str) -> Response {
    let body = match path {
        "/meadow.js" => MEADOW_JS,
        "/meadow_rig.js" => MEADOW_RIG_JS,
        _ => FIELD_JS,
    };
    Response::new(200, "text/javascript; charset=utf-8", body)
}

/// `GET /api/fields/ID/layout`: the running field `ID`'s plants ([`layout_bytes`]); 404 when
/// no such field runs (it stopped, or the page's table is older than the console's).
/// `layout_of` looks the field up (under the lock; the bytes are copied after it).
pub fn layout_response(path: &str, layout_of: impl FnOnce(ElementId) -> Option<Arc<Vec<u8>>>) -> Response {
    let id = path
        .strip_prefix("/api/fields/")
        .and_then(|r| r.strip_suffix("/layout"))
        .and_then(|n| n.parse::<u16>().ok())
        .map(ElementId::new);
    let Some(id) = id else {
        return Response::error(404, "no such path here (/api/fields/ID/layout, ID a field's number)");
    };
    match layout_of(id) {
        Some(bytes) => Response::new(200, "application/octet-stream", bytes.as_ref().clone()),
        None => Response::error(404, format!("no field {} runs", id.get())),
    }
}

/// What changed of the running fields since the last [`collect`]: a new table (with each
/// field's layout) and the field frames taken, in order.
#[derive(Debug, Default)]
pub struct FieldUpdate {
    table: Option<Vec<RelayedField>>,
    frames: Vec<FieldFrame>,
    dropped: u64,
}

impl FieldRelay {
    /// Takes `update` (what [`collect`] made, outside the lock).
    pub fn apply(&mut self, update: &mut FieldUpdate) {
        if let Some(fields) = update.table.take() {
            self.fields = fields;
            self.version += 1;
        }
        self.dropped += std::mem::take(&mut update.dropped);
        for f in update.frames.drain(..) {
            self.push(f);
        }
    }
}

/// What the SDK kept of the running fields after an event, into `update`: a new table (each
/// new field's layout made here, outside any lock; `known` is the table last seen) and the
/// field frames, in order. `false` when nothing changed.
pub fn collect(sub: &mut Subscriber, known: &mut Vec<FieldDefinition>, update: &mut FieldUpdate) -> bool {
    update.frames.clear();
    update.dropped = sub.take_field_frames(&mut update.frames);
    update.table = frond_sdk::field::changed_layouts(sub.fields(), known, usize::MAX);
    update.table.is_some() || !update.frames.is_empty() || update.dropped > 0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(seq: u64) -> FieldFrame {
        FieldFrame { seq, ..FieldFrame::default() }
    }

    #[test]
    fn a_page_gets_each_frame_once_in_order_and_a_new_page_the_last_second() {
        let mut r = FieldRelay::default();
        for s in 0..100 {
            r.push(frame(s));
        }
        let (mut cursor, mut out) = (u64::MAX, Vec::new());
        r.frames_since(&mut cursor, 1000, &mut out);
        let seqs: Vec<u64> = out.iter().map(|f| f.seq).collect();
        assert_eq!(seqs, (100 - FIELD_FRAMES_ON_CONNECT..100).collect::<Vec<_>>());
        out.clear();
        r.frames_since(&mut cursor, 1000, &mut out);
        assert!(out.is_empty(), "nothing new, nothing sent");
        for s in 100..110 {
            r.push(frame(s));
        }
        r.frames_since(&mut cursor, 1000, &mut out);
        assert_eq!(out.iter().map(|f| f.seq).collect::<Vec<_>>(), (100..110).collect::<Vec<_>>());
        // A page further behind than a message holds goes on from the newest that fit in one.
        let mut behind = 5;
        for s in 110..110 + FIELD_FRAME_RING as u64 {
            r.push(frame(s));
        }
        out.clear();
        r.frames_since(&mut behind, 4, &mut out);
        let newest = 110 + FIELD_FRAME_RING as u64;
        assert_eq!(out.iter().map(|f| f.seq).collect::<Vec<_>>(), (newest - 4..newest).collect::<Vec<_>>());
        out.clear();
        r.frames_since(&mut behind, 4, &mut out);
        assert!(out.is_empty(), "and then nothing it had");
    }
}
