//! Running fields sent whole in the `frond` namespace (issue 48: a subscriber that draws a field
//! evaluates each plant itself): what the SDK keeps of each field's definition, its layout
//! ([`frond_sdk::field::layout_bytes`], as the console sends its page) and every field frame,
//! encoded by [`crate::encode::FieldEncoder`].
//!
//! The definitions go out when the fields change and every [`FIELD_DEFS_EVERY`] (UDP may drop
//! them; a receiver started later must get them). Each time they go out a pass over every
//! field's layout starts, [`LAYOUT_CHUNKS_PER_FRAME`] chunks riding with each of that field's
//! frames (a 10,000-plant layout takes 200 chunks: a third of a second at 60 field frames a
//! second), so the layout is repeated too but never sent as a burst that would overflow a
//! receiver's socket buffer.

use std::sync::Arc;
use std::time::{Duration, Instant};

use frond_protocol::ElementTable;
use frond_protocol::field::{FieldDefinition, FieldFrame};
use frond_sdk::Subscriber;
use frond_sdk::field::{LAYOUT_BYTES_PER_PLANT, RelayedField, changed_layouts};

use crate::encode::{
    ClockOffset, Datagrams, EncodeError, FieldEncoder, MAX_OSC_FIELD_PLANTS, Timetags, encode_definitions,
    layout_chunks, layout_key,
};
use crate::sender::Sender;

/// How often the definitions are sent again, and a pass over each layout started.
pub const FIELD_DEFS_EVERY: Duration = Duration::from_secs(2);
/// Layout chunks sent with each field frame while a pass is under way.
pub const LAYOUT_CHUNKS_PER_FRAME: usize = 8;
/// Least time between two warnings about fields left out.
const LEFT_OUT_LOG_EVERY: Duration = Duration::from_secs(10);

/// The running fields' definitions and layouts, as the SDK relays them.
pub type FieldTable = Vec<RelayedField>;

/// The table of fields the subscriber now runs, if it changed since `known` (updated): each
/// field's definition and layout, made here (on the subscriber's thread). A field larger than
/// [`MAX_OSC_FIELD_PLANTS`] gets an empty layout, its bytes never made (the sender leaves it
/// out).
pub fn collect_table(sub: &Subscriber, known: &mut Vec<FieldDefinition>) -> Option<FieldTable> {
    changed_layouts(sub.fields(), known, MAX_OSC_FIELD_PLANTS)
}

#[derive(Debug)]
struct Sent {
    definition: FieldDefinition,
    layout: Arc<Vec<u8>>,
    key: u32,
    /// The next chunk of the pass under way; the chunk count when none is.
    cursor: usize,
}

/// The fields being sent whole, and when their definitions are due.
#[derive(Debug)]
pub struct FieldSender {
    encoder: FieldEncoder,
    fields: Vec<Sent>,
    defs_due: Instant,
    /// Times the (empty) field list is still to go out after the last field stopped.
    empty_sends: u8,
    left_out: u64,
    left_out_logged: Option<Instant>,
    /// Field frames sent, and those of fields not sent whole (left out, or before the table).
    pub frames_sent: u64,
    /// Field frames of fields not sent whole.
    pub frames_skipped: u64,
}

impl FieldSender {
    /// No fields yet; frames timetagged as `timetags` says.
    pub fn new(offset: ClockOffset, timetags: Timetags) -> FieldSender {
        let mut encoder = FieldEncoder::new(offset);
        encoder.set_timetags(timetags);
        FieldSender {
            encoder,
            fields: Vec::new(),
            defs_due: Instant::now(),
            empty_sends: 0,
            left_out: 0,
            left_out_logged: None,
            frames_sent: 0,
            frames_skipped: 0,
        }
    }

    /// Takes a new table of running fields: one larger than [`MAX_OSC_FIELD_PLANTS`], or whose
    /// layout is not its plant count's, is left out (logged at most every 10 s). The
    /// definitions go out at the next [`FieldSender::poll`].
    pub fn set_table(&mut self, table: FieldTable) {
        let had = !self.fields.is_empty();
        self.fields.clear();
        for RelayedField { definition, layout } in table {
            let plants = definition.plants as usize;
            if plants > MAX_OSC_FIELD_PLANTS || layout.len() != plants * LAYOUT_BYTES_PER_PLANT {
                self.left_out += 1;
                if self.left_out_logged.is_none_or(|t| t.elapsed() >= LEFT_OUT_LOG_EVERY) {
                    self.left_out_logged = Some(Instant::now());
                    tracing::warn!(
                        field = %definition.id, source = %definition.source, plants,
                        limit = MAX_OSC_FIELD_PLANTS, left_out = self.left_out,
                        "not sending this field whole: more plants than frond-osc sends (its announced \
                         plants still go out; logged at most every 10 s)"
                    );
                }
                continue;
            }
            let key = layout_key(&layout);
            let cursor = layout_chunks(layout.len());
            self.fields.push(Sent { definition, layout, key, cursor });
        }
        self.encoder.set_fields(self.fields.iter().map(|f| f.definition.id));
        if had && self.fields.is_empty() {
            self.empty_sends = 2;
        }
        self.defs_due = Instant::now();
    }

    /// Sends the definitions when due (see the [module docs](self)) and starts a layout pass
    /// for every field not in one.
    pub fn poll(
        &mut self,
        table: &ElementTable,
        out: &mut Datagrams,
        sender: &mut Sender,
    ) -> Result<(), EncodeError> {
        if Instant::now() < self.defs_due || (self.fields.is_empty() && self.empty_sends == 0) {
            return Ok(());
        }
        self.empty_sends = self.empty_sends.saturating_sub(1);
        let defs: Vec<(&FieldDefinition, &[u8])> =
            self.fields.iter().map(|f| (&f.definition, f.layout.as_slice())).collect();
        encode_definitions(&defs, table, out)?;
        sender.send(out);
        for f in &mut self.fields {
            if f.cursor >= layout_chunks(f.layout.len()) {
                f.cursor = 0;
            }
        }
        self.defs_due = Instant::now() + FIELD_DEFS_EVERY;
        Ok(())
    }

    /// Sends field frame `frame` with the next chunks of its field's layout pass, if one is
    /// under way. No allocation.
    pub fn send_frame(
        &mut self,
        frame: &FieldFrame,
        out: &mut Datagrams,
        sender: &mut Sender,
    ) -> Result<(), EncodeError> {
        let Some(f) = self.fields.iter_mut().find(|f| f.definition.id == frame.field) else {
            self.frames_skipped += 1;
            return Ok(());
        };
        let count = layout_chunks(f.layout.len());
        let range = f.cursor..(f.cursor + LAYOUT_CHUNKS_PER_FRAME).min(count);
        f.cursor = range.end;
        let chunks = (!range.is_empty()).then_some((f.layout.as_slice(), f.key, range));
        if self.encoder.encode_frame(frame, chunks, out)? {
            sender.send(out);
            self.frames_sent += 1;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_protocol::ElementId;
    use frond_protocol::field::FieldLayout;

    fn definition(id: u16, plants: u32) -> FieldDefinition {
        FieldDefinition {
            id: ElementId::new(id),
            source: "field".into(),
            rig: "grass".into(),
            layout: FieldLayout {
                version: 1,
                take: "sway".into(),
                fps: 30.0,
                frames: 60,
                rows: 1,
                cols: plants,
                cell_m: 0.2,
                speed_m_s: 1.0,
                direction_deg: 0.0,
                authored_direction_deg: 0.0,
                density: 1.0,
                seed: 1,
            },
            plants,
            stream_fps: 30.0,
            history_frames: 64,
            publish_hz: 60,
            plant_elements: vec![],
        }
    }

    #[test]
    fn a_layout_pass_rides_with_frames_and_too_large_fields_are_left_out() {
        let sink = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut sender = Sender::new(&[sink.local_addr().unwrap()], None).unwrap();
        let mut fields = FieldSender::new(ClockOffset::fixed(0), Timetags::Publish);
        // 1250 plants: 25,000 bytes, 25 chunks. Beside it one over the limit, and one whose
        // layout is not its plant count's: both left out.
        let too_large = MAX_OSC_FIELD_PLANTS as u32 + 1;
        fields.set_table(vec![
            RelayedField { definition: definition(40, 1250), layout: Arc::new(vec![1; 25_000]) },
            RelayedField { definition: definition(41, too_large), layout: Arc::new(Vec::new()) },
            RelayedField { definition: definition(42, 10), layout: Arc::new(vec![1; 199]) },
        ]);
        assert_eq!((fields.fields.len(), fields.left_out), (1, 2));
        let mut out = Datagrams::new();
        let frame = |field: u16| FieldFrame { field: ElementId::new(field), ..FieldFrame::default() };
        // No pass before the definitions went out.
        fields.send_frame(&frame(40), &mut out, &mut sender).unwrap();
        assert_eq!((out.len(), fields.fields[0].cursor), (1, 25));
        fields.poll(&ElementTable::default(), &mut out, &mut sender).unwrap();
        assert_eq!(fields.fields[0].cursor, 0, "a pass starts with the definitions");
        let mut cursors = Vec::new();
        for _ in 0..5 {
            fields.send_frame(&frame(40), &mut out, &mut sender).unwrap();
            cursors.push(fields.fields[0].cursor);
        }
        assert_eq!(cursors, [8, 16, 24, 25, 25]);
        // The definitions again only when due; frames of fields left out are skipped.
        fields.poll(&ElementTable::default(), &mut out, &mut sender).unwrap();
        assert_eq!(fields.fields[0].cursor, 25);
        fields.send_frame(&frame(41), &mut out, &mut sender).unwrap();
        assert_eq!((fields.frames_sent, fields.frames_skipped), (6, 1));
    }
}
