//! Fields of plants (protocol 3; seed 000, Eq. 6-7 and section 6.3): the daemon publishes what
//! defines a running field (its definition, with the element table) and frames of its driving
//! stream; this module keeps each field and evaluates any of its plants with
//! `frond_motion::field_eval`, the same code the daemon's own field runs.
//!
//! ```no_run
//! use frond_sdk::{Event, Subscriber};
//!
//! let mut sub = Subscriber::connect(frond_protocol::paths::socket_dir(None))?;
//! loop {
//!     if let Event::Pose(_) = sub.next_event()? {
//!         for field in sub.fields().iter() {
//!             // Plant 1234 now, as the daemon's own field evaluates it.
//!             if let Some(joints) = field.plant_pose(1234, field.tau_s()) {
//!                 println!("{joints:?}");
//!             }
//!         }
//!     }
//! }
//! # Ok::<(), frond_sdk::SdkError>(())
//! ```
//!
//! The same holds for a `zenoh:` source: a `frond-zenoh` bridge passes each field on as the
//! daemon publishes it (the definitions on `fields`, the frames among the poses; see
//! [`crate::zenoh`]), so a program reads a field the same way from either, and what crosses
//! the network does not grow with the field either.
//!
//! Subscribers that want poses need nothing of this: the plants the daemon announces as
//! `field-plant` elements (its `--plants`, at most 64) arrive as [`Event::Pose`]s, evaluated here
//! at each field frame, as protocol 2 delivered them: numbered with the frame's numbers (the
//! daemon keeps one for each, [`FieldFrame::poses`]), with its times, flagged `playback` (and
//! `recording` when the frame was). A plant not evaluable yet leaves its number out, a gap for
//! whoever passes the poses on.
//! A subscriber that joins a running field evaluates a plant once the stream frames it reads
//! have arrived: each field frame brings the newest ones and a few older ones, so the whole
//! history is there within `history_frames / 8` field frames; until then
//! [`LiveField::plant_pose`] says `None` for plants that read further back.

use std::collections::VecDeque;
use std::sync::Arc;

use frond_motion::clip::Joints;
use frond_motion::field::{Field, FieldError};
use frond_motion::field_eval::FieldState;
use frond_motion::field_wire::{apply_frame, field_from_definition};
use frond_protocol::field::{FieldDefinition, FieldFrame, FieldMessage, FieldTable, MAX_WIRE_FIELDS};
use frond_protocol::{ElementId, HandWire, Pose};

use crate::{Event, SdkError, Subscriber};

/// One running field as a subscriber keeps it.
#[derive(Debug, Clone)]
pub struct LiveField {
    definition: FieldDefinition,
    elements_version: u64,
    state: FieldState,
    /// The last field frame applied (its host time and stream time).
    last: Option<FieldFrame>,
}

impl LiveField {
    /// A field from its definition (the plants made from its layout; limits checked first).
    pub fn new(definition: FieldDefinition, elements_version: u64) -> Result<Self, FieldError> {
        let state = field_from_definition(&definition)?;
        Ok(LiveField { definition, elements_version, state, last: None })
    }

    /// Its definition as the daemon sent it.
    pub fn definition(&self) -> &FieldDefinition {
        &self.definition
    }

    /// The field's plants: positions on the ground, rows, start frames, sizes.
    pub fn layout(&self) -> &Field {
        self.state.field()
    }

    /// Number of plants.
    pub fn plants(&self) -> usize {
        self.state.field().plants.len()
    }

    /// The evaluation state (history, controls, delays), for callers that evaluate many plants.
    pub fn state(&self) -> &FieldState {
        &self.state
    }

    /// The last field frame applied, if any.
    pub fn last_frame(&self) -> Option<&FieldFrame> {
        self.last.as_ref()
    }

    /// The stream time of the last field frame, seconds.
    pub fn tau_s(&self) -> f64 {
        self.state.tau_s()
    }

    /// The stream time at host `CLOCK_MONOTONIC` time `host_ns` (see [`crate::clock`]): the last
    /// frame's, advanced by the motion speed for the time since it was published (for drawing
    /// between frames).
    pub fn tau_at(&self, host_ns: u64) -> f64 {
        let Some(f) = &self.last else { return self.state.tau_s() };
        let dt_s = (host_ns as f64 - f.host_monotonic_ns as f64) / 1e9;
        self.state.tau_s() + self.state.controls().time_step * dt_s
    }

    /// Plant `plant`'s pose at stream time `tau_s` (seed 000, Eq. 6-7 with the rigidity delays,
    /// scale and bend direction of the controls in force): `[pitch, yaw, roll]` per joint,
    /// degrees, root first. `None` for an unknown plant or while the stream frames it reads
    /// have not all arrived.
    pub fn plant_pose(&self, plant: usize, tau_s: f64) -> Option<Joints> {
        self.state.plant_at(plant, tau_s)
    }

    /// Whether every stream frame of the history window has arrived.
    pub fn history_complete(&self) -> bool {
        self.state.history().is_complete()
    }

    /// The element table version this definition came with.
    pub fn elements_version(&self) -> u64 {
        self.elements_version
    }
}

/// Bytes per plant of [`layout_bytes`]: `[x, z]` f32, row u32, start frame u32, scale f32.
pub const LAYOUT_BYTES_PER_PLANT: usize = 20;

/// Field `id`'s plants as bytes, little-endian, in plant order: every plant's `[x, z]` (f32,
/// metres), then every row (u32), every start frame (u32), every scale (f32);
/// [`LAYOUT_BYTES_PER_PLANT`] bytes a plant in all (empty when no such field runs). What a
/// subscriber that evaluates the plants itself, not on this SDK (the console's page, the
/// Blender add-on through frond-osc), needs besides the definition: the layout it was made from
/// says the same, but only `frond_motion::field::make_field` turns it into plants.
pub fn layout_bytes(fields: &LiveFields, id: ElementId) -> Vec<u8> {
    let Some(f) = fields.get(id) else { return Vec::new() };
    let plants = &f.layout().plants;
    let mut out = Vec::with_capacity(plants.len() * LAYOUT_BYTES_PER_PLANT);
    for p in plants {
        out.extend(p.position_m.iter().flat_map(|v| v.to_le_bytes()));
    }
    // Rows and start frames are below the plant count (at most a million): u32 holds them.
    for p in plants {
        out.extend((p.row as u32).to_le_bytes());
    }
    for p in plants {
        out.extend((p.start_frame as u32).to_le_bytes());
    }
    for p in plants {
        out.extend(p.scale.to_le_bytes());
    }
    out
}

/// A running field as a program that passes fields on keeps it (the console for its page,
/// frond-osc for the Blender add-on): its definition and its plants' layout ([`layout_bytes`]).
#[derive(Debug, Clone)]
pub struct RelayedField {
    /// Its definition as the daemon sent it.
    pub definition: FieldDefinition,
    /// Its plants' layout ([`layout_bytes`]; empty for a field over the caller's plant bound).
    pub layout: Arc<Vec<u8>>,
}

/// The running fields with their layouts, when they changed since `known` (which is updated):
/// what a program that passes fields on sends again. A field of more than `max_plants` plants
/// gets an empty layout, its bytes never made.
pub fn changed_layouts(
    fields: &LiveFields,
    known: &mut Vec<FieldDefinition>,
    max_plants: usize,
) -> Option<Vec<RelayedField>> {
    if fields.iter().map(|f| f.definition()).eq(known.iter()) {
        return None;
    }
    known.clear();
    known.extend(fields.iter().map(|f| f.definition().clone()));
    let relayed = known
        .iter()
        .map(|d| RelayedField {
            definition: d.clone(),
            layout: Arc::new(if d.plants as usize > max_plants {
                Vec::new()
            } else {
                layout_bytes(fields, d.id)
            }),
        })
        .collect();
    Some(relayed)
}

/// Most field frames a subscriber keeps for [`Subscriber::take_field_frames`] (4 s at 60 Hz).
pub const MAX_KEPT_FIELD_FRAMES: usize = 256;

/// The running fields of a subscription.
#[derive(Debug, Clone, Default)]
pub struct LiveFields {
    fields: Vec<LiveField>,
    /// The frames taken since [`Subscriber::take_field_frames`] last emptied it, oldest first,
    /// at most `keep` (the oldest dropped first, counted in `kept_dropped`).
    kept: VecDeque<FieldFrame>,
    keep: usize,
    kept_dropped: u64,
    /// Field definitions left out (this SDK cannot evaluate them), and when that was last
    /// logged: a peer that sends one table after another must not flood the log.
    refused: u64,
    refused_logged: Option<std::time::Instant>,
}

/// Least time between two warnings about field definitions left out.
const REFUSED_LOG_EVERY: std::time::Duration = std::time::Duration::from_secs(10);

impl LiveFields {
    /// No fields yet; the last `keep` frames taken are kept (at most
    /// [`MAX_KEPT_FIELD_FRAMES`]).
    pub fn keeping(keep: usize) -> Self {
        LiveFields { keep: keep.min(MAX_KEPT_FIELD_FRAMES), ..Self::default() }
    }

    /// The field with this id.
    pub fn get(&self, id: ElementId) -> Option<&LiveField> {
        self.fields.iter().find(|f| f.definition.id == id)
    }

    /// The field a stage plays, by the stage's name.
    pub fn by_source(&self, source: &str) -> Option<&LiveField> {
        self.fields.iter().find(|f| f.definition.source == source)
    }

    /// Every running field.
    pub fn iter(&self) -> impl Iterator<Item = &LiveField> + '_ {
        self.fields.iter()
    }

    /// Whether no field runs.
    pub fn is_empty(&self) -> bool {
        self.fields.is_empty()
    }

    /// Forgets every field (the connection ended).
    pub fn clear(&mut self) {
        self.fields.clear();
    }

    /// Takes a new table: fields whose definition did not change keep their history, new ones
    /// are made, the others dropped. A definition out of its limits (or whose layout makes
    /// another plant count) is left out; the ids left out and why are returned. At most
    /// [`MAX_WIRE_FIELDS`] fields are taken.
    pub fn on_table(&mut self, table: FieldTable) -> Vec<(ElementId, FieldError)> {
        let mut refused = Vec::new();
        let mut next = Vec::with_capacity(table.fields.len().min(MAX_WIRE_FIELDS));
        for d in table.fields.into_iter().take(MAX_WIRE_FIELDS) {
            match self.fields.iter().position(|f| f.definition == d) {
                Some(i) => {
                    let mut f = self.fields.swap_remove(i);
                    f.elements_version = table.elements_version;
                    next.push(f);
                }
                None => {
                    let id = d.id;
                    match LiveField::new(d, table.elements_version) {
                        Ok(f) => next.push(f),
                        Err(e) => refused.push((id, e)),
                    }
                }
            }
        }
        self.fields = next;
        refused
    }

    /// Applies a field frame to its field; the field, if known and the frame was taken.
    pub fn on_frame(&mut self, frame: &FieldFrame) -> Option<&LiveField> {
        let f = self.fields.iter_mut().find(|f| f.definition.id == frame.field)?;
        if !apply_frame(&mut f.state, frame) {
            return None;
        }
        f.last = Some(*frame);
        if self.keep > 0 {
            if self.kept.len() == self.keep {
                self.kept.pop_front();
                self.kept_dropped += 1;
            }
            self.kept.push_back(*frame);
        }
        self.fields.iter().find(|f| f.definition.id == frame.field)
    }
}

impl Subscriber {
    /// The running fields (protocol 3): evaluate any plant with [`LiveField::plant_pose`].
    pub fn fields(&self) -> &LiveFields {
        &self.fields
    }

    /// Moves the field frames taken since the last call into `out` (appended, oldest first)
    /// and returns how many were dropped unread since (beyond
    /// [`crate::SubscriberOptions::keep_field_frames`]). Nothing is kept without that option.
    pub fn take_field_frames(&mut self, out: &mut Vec<FieldFrame>) -> u64 {
        out.extend(self.fields.kept.drain(..));
        std::mem::take(&mut self.fields.kept_dropped)
    }

    /// From now on, keeps each field message taken (a table, a frame in the sequence) for
    /// [`Subscriber::take_passed`]: a [`crate::zenoh_many::StageSubscriber`]'s follower passes
    /// them on with its source's events, to be kept per source by
    /// [`crate::zenoh_many::StageFields`].
    #[cfg_attr(not(feature = "zenoh"), allow(dead_code))]
    pub(crate) fn pass_field_messages(&mut self) {
        self.passed.get_or_insert_with(VecDeque::new);
    }

    /// The field messages kept since the last call, oldest first.
    #[cfg_attr(not(feature = "zenoh"), allow(dead_code))]
    pub(crate) fn take_passed(&mut self) -> impl Iterator<Item = FieldMessage> + '_ {
        self.passed.iter_mut().flat_map(|q| q.drain(..))
    }

    /// Keeps a field message for whoever passes them on. The follower takes them after every
    /// event, and an event comes within a few messages (each pose is one); should it not, the
    /// oldest frames give way beyond [`MAX_KEPT_FIELD_FRAMES`], never a table.
    fn pass_on(&mut self, msg: impl FnOnce() -> FieldMessage) {
        let Some(q) = &mut self.passed else { return };
        if q.len() >= MAX_KEPT_FIELD_FRAMES
            && let Some(i) = q.iter().position(|m| matches!(m, FieldMessage::Frame(_)))
        {
            q.remove(i);
        }
        q.push_back(msg());
    }

    /// A field message: a table is taken (no event), a frame is numbered like a pose (a gap
    /// is reported) and gives the announced plants' poses. `Ok(None)` when there is nothing to
    /// report.
    pub(crate) fn on_field(&mut self, msg: FieldMessage) -> Result<Option<Event>, SdkError> {
        let frame = match msg {
            FieldMessage::Table(table) if self.relay => {
                self.relayed = Some(FieldMessage::Table(table));
                return Ok(None);
            }
            FieldMessage::Table(table) => {
                self.pass_on(|| FieldMessage::Table(table.clone()));
                for (field, error) in self.fields.on_table(table) {
                    let f = &mut self.fields;
                    f.refused += 1;
                    if f.refused_logged.is_none_or(|t| t.elapsed() >= REFUSED_LOG_EVERY) {
                        f.refused_logged = Some(std::time::Instant::now());
                        tracing::warn!(
                            path = %self.path.display(), %field, %error, refused = f.refused,
                            "leaving out a field whose definition this SDK cannot evaluate \
                             (logged at most every 10 s)"
                        );
                    }
                }
                return Ok(None);
            }
            FieldMessage::Frame(frame) => frame,
        };
        let expected = self.expected_seq;
        if frame.seq < expected {
            return self.seq_went_back(expected, frame.seq).map(Some);
        }
        self.expected_seq = frame.seq.saturating_add(u64::from(frame.poses).max(1));
        let gap = frame.seq > expected;
        if gap {
            self.count_gap(frame.seq - expected);
        }
        if self.relay {
            self.relayed = Some(FieldMessage::Frame(frame));
            return Ok(gap.then_some(Event::Gap { expected, got: frame.seq }));
        }
        self.pass_on(|| FieldMessage::Frame(frame));
        if let Some(field) = self.fields.on_frame(&frame) {
            let tau = field.tau_s();
            let announced = field.definition.plant_elements.iter().take(usize::from(frame.poses));
            for (plant, &element) in announced.enumerate() {
                let Some(joints_deg) = field.plant_pose(plant, tau) else { continue };
                self.stats.frames += 1;
                self.pending.push_back(Event::Pose(Pose {
                    seq: frame.seq + plant as u64,
                    device_time_us: frame.device_time_us,
                    host_monotonic_ns: frame.host_monotonic_ns,
                    flags: frame.flags,
                    element,
                    joints_deg,
                    hand: HandWire { t: frame.hand_t, ..HandWire::default() },
                }));
            }
        }
        if gap {
            return Ok(Some(Event::Gap { expected, got: frame.seq }));
        }
        Ok(self.pending.pop_front())
    }
}
