//! Fields on the pose socket (protocol version 3; seed 000, sections 6.2-6.3).
//!
//! A field of plants plays one driving motion (a looped take) with a delay per plant (Eq. 6-7,
//! `F_B(t) = F_A(t - gamma_B)`, `gamma_B = ||B - A|| / V_M`), a rigidity delay per joint and the
//! live controls of section 6.3. Version 2 published one [`crate::Pose`] per plant per frame, so
//! what the daemon sent grew with the field. Version 3 publishes what *defines* the field, and
//! every subscriber evaluates the plants it wants with the same equations (`frond_motion`'s
//! `field_eval`, `frond_sdk::field`, the console page's port):
//!
//! - [`FieldTable`], once per change of the live stages (right after the
//!   [`crate::ServerMessage::Elements`] table of the same version, and right after a
//!   [`crate::Hello`] while any field runs): each running field's [`FieldDefinition`], i.e. its
//!   layout as the parameters that make it ([`FieldLayout`], the header of a `field.json`: the
//!   plants follow from them by `frond_motion::field::make_field`, so the definition has the
//!   same size for 1 plant or 100,000), the rate and length of its driving stream and the plants
//!   announced as `field-plant` elements.
//! - [`FieldFrame`], at the field's publish rate (60 Hz), numbered in the same sequence as poses:
//!   the stream time `tau`, the controls in force, the newest frames of the driving stream and
//!   a few older ones (a "trickle" that walks the history the delays need, so a subscriber that
//!   joins a running field or missed frames has the whole history again after
//!   `history_frames / FIELD_FRAME_TRICKLE` field frames). Its size does not depend on the
//!   number of plants.
//!
//! Everything a peer sends that sizes memory is bounded here ([`FieldDefinition::check`],
//! [`FieldEntries`] refuses more than [`FIELD_FRAME_ENTRIES`] while decoding).

use std::fmt;

use serde::de::{SeqAccess, Visitor};
use serde::ser::SerializeSeq;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::{ElementId, PoseFlags};

/// Newest stream frames a [`FieldFrame`] carries (a motion speed of up to 4x at 30 FPS and a
/// 60 Hz publish rate makes 2 new frames per field frame).
pub const FIELD_FRAME_NEW: usize = 4;
/// Older stream frames a [`FieldFrame`] carries, walking the history from oldest to newest.
pub const FIELD_FRAME_TRICKLE: usize = 8;
/// Stream frames a [`FieldFrame`] carries at most.
pub const FIELD_FRAME_ENTRIES: usize = FIELD_FRAME_NEW + FIELD_FRAME_TRICKLE;
/// Most plants a field on the wire may define (one per cell of at most a million cells:
/// `frond_motion::field::MAX_FIELD_CELLS`).
pub const MAX_WIRE_FIELD_PLANTS: u32 = 1_000_000;
/// Most cells (`rows x cols`) of a field's layout on the wire.
pub const MAX_WIRE_FIELD_CELLS: u64 = 1_000_000;
/// Most frames of driving-stream history a field may ask a subscriber to keep (about 12 MB of
/// poses): a take of an hour at 30 FPS plus a minute of delays at 1000 FPS fits.
pub const MAX_FIELD_HISTORY_FRAMES: u32 = 1 << 18;
/// Most plants of one field announced as `field-plant` elements (whose poses the SDK delivers
/// as [`crate::Pose`] events, as version 2 published them).
pub const MAX_ANNOUNCED_PLANTS: usize = 64;
/// Most fields in one [`FieldTable`] (a daemon runs at most 8 live stages).
pub const MAX_WIRE_FIELDS: usize = 8;
/// Longest take name in a [`FieldLayout`], bytes.
pub const MAX_FIELD_TAKE_NAME: usize = 255;
/// Highest driving-stream rate, frames per second.
pub const MAX_FIELD_STREAM_FPS: f64 = 1000.0;

/// The fields running with one element table.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldTable {
    /// The [`crate::ElementTable::version`] this table belongs to.
    pub elements_version: u64,
    /// The running fields (at most [`MAX_WIRE_FIELDS`]).
    pub fields: Vec<FieldDefinition>,
}

/// One running field: everything a subscriber needs, besides the [`FieldFrame`]s, to evaluate
/// any of its plants.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FieldDefinition {
    /// The id its [`FieldFrame::field`] carries (from the element id space, but not an element:
    /// no pose carries it).
    pub id: ElementId,
    /// The live stage that plays it.
    pub source: String,
    /// The rig of its plants (one of [`crate::ElementTable::rigs`]).
    pub rig: String,
    /// The parameters its plants follow from.
    pub layout: FieldLayout,
    /// Its plant count (what the layout makes; a subscriber checks it).
    pub plants: u32,
    /// Frames per second of the driving stream (stream frame `k` is at stream time `k / fps`).
    pub stream_fps: f64,
    /// Stream frames a subscriber keeps: the window the delays and the rows' start frames reach.
    pub history_frames: u32,
    /// Field frames per second.
    pub publish_hz: u32,
    /// The plants announced as `field-plant` elements, in plant order: plant `i` is element
    /// `plant_elements[i]` (at most [`MAX_ANNOUNCED_PLANTS`]).
    pub plant_elements: Vec<ElementId>,
}

/// A field's layout as the parameters that make it: the header of its `field.json` (version 1;
/// see `frond_motion::field`), without the plants, which `make_field` derives from it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FieldLayout {
    /// `field.json` version (1).
    pub version: u32,
    /// Name of the take the layout was made for.
    pub take: String,
    /// Frame rate the take was sampled at for the layout.
    pub fps: f64,
    /// Frames of the take at `fps`.
    pub frames: u64,
    /// Grid rows.
    pub rows: u32,
    /// Grid columns.
    pub cols: u32,
    /// Cell size, metres.
    pub cell_m: f64,
    /// Propagation speed `V_M` of the layout, m/s.
    pub speed_m_s: f64,
    /// Force heading of the layout, degrees.
    pub direction_deg: f64,
    /// Heading the take was authored towards.
    pub authored_direction_deg: f64,
    /// Fraction of cells holding a plant.
    pub density: f64,
    /// Seed of the layout.
    pub seed: u64,
}

/// The live controls of a field (seed 000, section 6.3).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldControlsWire {
    /// Force heading, degrees (propagation direction and bend direction).
    pub direction_deg: f64,
    /// Propagation speed `V_M`, m/s.
    pub speed_m_s: f64,
    /// Motion speed `K`: stream seconds per second.
    pub time_step: f64,
    /// Motion scale.
    pub scale: f32,
    /// Rigidity delays `delta_1..delta_3`, seconds.
    pub delays_s: [f64; 3],
}

/// One frame of a field's driving stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StreamFrame {
    /// Its index in the stream (at stream time `index / stream_fps`).
    pub index: u64,
    /// The driving pose, `[pitch, yaw, roll]` per joint, degrees, root first.
    pub joints_deg: [[f32; 3]; 4],
}

/// Up to [`FIELD_FRAME_ENTRIES`] stream frames, kept inline (no heap: the realtime loop builds
/// them). On the wire, a MessagePack array of [`StreamFrame`]s; decoding refuses a longer one.
#[derive(Clone, Copy, Default)]
pub struct FieldEntries {
    len: u8,
    items: [StreamFrame; FIELD_FRAME_ENTRIES],
}

impl FieldEntries {
    /// Appends `f`; `false` (and nothing changes) when full.
    pub fn push(&mut self, f: StreamFrame) -> bool {
        let n = usize::from(self.len);
        if n == FIELD_FRAME_ENTRIES {
            return false;
        }
        self.items[n] = f;
        self.len += 1;
        true
    }

    /// Empties it.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// The frames held.
    pub fn as_slice(&self) -> &[StreamFrame] {
        &self.items[..usize::from(self.len)]
    }
}

impl PartialEq for FieldEntries {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl fmt::Debug for FieldEntries {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.as_slice()).finish()
    }
}

impl Serialize for FieldEntries {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut seq = s.serialize_seq(Some(usize::from(self.len)))?;
        for f in self.as_slice() {
            seq.serialize_element(f)?;
        }
        seq.end()
    }
}

impl<'de> Deserialize<'de> for FieldEntries {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Entries;
        impl<'de> Visitor<'de> for Entries {
            type Value = FieldEntries;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of at most {FIELD_FRAME_ENTRIES} stream frames")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<FieldEntries, A::Error> {
                let mut out = FieldEntries::default();
                while let Some(f) = seq.next_element::<StreamFrame>()? {
                    if !out.push(f) {
                        return Err(serde::de::Error::custom(format_args!(
                            "a field frame carries at most {FIELD_FRAME_ENTRIES} stream frames"
                        )));
                    }
                }
                Ok(out)
            }
        }
        d.deserialize_seq(Entries)
    }
}

/// One field frame: the field's stream time, controls and a few frames of its driving stream.
/// Numbered in the same sequence as [`crate::Pose`]s: its numbers are its announced plants'
/// poses' ([`FieldFrame::poses`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldFrame {
    /// Sequence number (shared with poses: +1 per frame of any kind).
    pub seq: u64,
    /// Device time of the primary hand's latest report, microseconds.
    pub device_time_us: u64,
    /// Host `CLOCK_MONOTONIC` nanoseconds when the tick published it.
    pub host_monotonic_ns: u64,
    /// Pose flags its plants' poses carry (`playback`, and `recording` while a take records).
    pub flags: PoseFlags,
    /// The primary hand's device time at that tick, seconds (what a stage's poses carry as
    /// their `hand.t`).
    pub hand_t: f64,
    /// How many sequence numbers from its own on belong to the field's announced plants' poses,
    /// which subscribers evaluate: the SDK delivers them numbered `seq ..= seq + poses - 1`, as
    /// protocol 2 sent them, so that the poses have every number; the next frame on the wire is
    /// numbered `seq + max(poses, 1)`.
    pub poses: u8,
    /// The field ([`FieldDefinition::id`]).
    pub field: ElementId,
    /// Stream time at `host_monotonic_ns`, seconds: it advances by `controls.time_step` per second.
    pub tau_s: f64,
    /// The controls in force.
    pub controls: FieldControlsWire,
    /// Stream frames produced so far (the newest is `produced - 1`).
    pub produced: u64,
    /// The newest frames (up to [`FIELD_FRAME_NEW`]) and older ones walking the history.
    pub entries: FieldEntries,
}

/// What [`crate::ServerMessage::Field`] carries.
// A frame is large beside a table, but the realtime loop encodes it by value: boxing it would
// allocate on every field frame.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum FieldMessage {
    /// The running fields' definitions.
    Table(FieldTable),
    /// One field frame.
    Frame(FieldFrame),
}

/// A field definition a peer sent that breaks a limit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("field {id}: {what} is {value}, outside {limit}")]
pub struct FieldDefinitionError {
    /// The field's id.
    pub id: ElementId,
    /// What is out of range.
    pub what: &'static str,
    /// The value found.
    pub value: String,
    /// The limit.
    pub limit: String,
}

impl FieldDefinition {
    /// Checks every quantity that sizes memory or a loop on a subscriber against its limit
    /// (before anything is allocated for it). The plants themselves are checked by whoever makes
    /// them from the layout (`frond_motion::field_wire`).
    pub fn check(&self) -> Result<(), FieldDefinitionError> {
        let err = |what, value: String, limit: String| {
            Err(FieldDefinitionError { id: self.id, what, value, limit })
        };
        let l = &self.layout;
        if l.rows == 0 || l.cols == 0 || u64::from(l.rows) * u64::from(l.cols) > MAX_WIRE_FIELD_CELLS {
            return err(
                "rows x cols",
                format!("{} x {}", l.rows, l.cols),
                format!("1..={MAX_WIRE_FIELD_CELLS} cells"),
            );
        }
        if self.plants > MAX_WIRE_FIELD_PLANTS
            || u64::from(self.plants) > u64::from(l.rows) * u64::from(l.cols)
        {
            return err("plants", self.plants.to_string(), "one per cell".into());
        }
        if !(2..=MAX_FIELD_HISTORY_FRAMES).contains(&self.history_frames) {
            return err(
                "history_frames",
                self.history_frames.to_string(),
                format!("2..={MAX_FIELD_HISTORY_FRAMES}"),
            );
        }
        if !(self.stream_fps.is_finite() && self.stream_fps > 0.0 && self.stream_fps <= MAX_FIELD_STREAM_FPS)
        {
            return err("stream_fps", self.stream_fps.to_string(), format!("(0, {MAX_FIELD_STREAM_FPS}]"));
        }
        if self.plant_elements.len() > MAX_ANNOUNCED_PLANTS.min(self.plants as usize) {
            return err(
                "plant_elements",
                format!("{} ids", self.plant_elements.len()),
                format!("at most {MAX_ANNOUNCED_PLANTS} and the plant count"),
            );
        }
        if l.take.len() > MAX_FIELD_TAKE_NAME {
            return err(
                "layout.take",
                format!("{} bytes", l.take.len()),
                format!("{MAX_FIELD_TAKE_NAME} bytes"),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ServerMessage, decode_frame, encode_frame};

    fn frame(n: usize) -> FieldFrame {
        let mut f =
            FieldFrame { seq: 9, field: ElementId::new(40), tau_s: 1.5, produced: 77, ..Default::default() };
        for k in 0..n {
            assert!(
                f.entries.push(StreamFrame { index: 70 + k as u64, joints_deg: [[k as f32, 1.0, 2.0]; 4] })
            );
        }
        f
    }

    #[test]
    fn field_frames_round_trip_and_hold_at_most_their_entries() {
        for n in [0, 1, FIELD_FRAME_ENTRIES] {
            let msg = ServerMessage::Field(FieldMessage::Frame(frame(n)));
            let mut bytes = Vec::new();
            encode_frame(&msg, &mut bytes);
            let (back, used) = decode_frame::<ServerMessage>(&bytes).unwrap().unwrap();
            assert_eq!((back, used), (msg, bytes.len()));
        }
        let mut full = frame(FIELD_FRAME_ENTRIES);
        assert!(!full.entries.push(StreamFrame::default()), "a full frame refuses more");
        // A peer's array one longer than the limit is refused while decoding, not allocated.
        #[derive(Serialize)]
        struct Long {
            entries: Vec<StreamFrame>,
        }
        let mut bytes = Vec::new();
        encode_frame(&Long { entries: vec![StreamFrame::default(); FIELD_FRAME_ENTRIES + 1] }, &mut bytes);
        #[derive(Deserialize, Debug)]
        #[allow(dead_code)]
        struct Short {
            entries: FieldEntries,
        }
        let err = decode_frame::<Short>(&bytes).unwrap_err().to_string();
        assert!(err.contains("at most 12 stream frames"), "{err}");
        full.entries.clear();
        assert!(full.entries.as_slice().is_empty());
    }

    #[test]
    fn a_field_frame_is_small_whatever_the_field() {
        let mut bytes = Vec::new();
        encode_frame(&ServerMessage::Field(FieldMessage::Frame(frame(FIELD_FRAME_ENTRIES))), &mut bytes);
        assert!(bytes.len() < 2048, "{} bytes", bytes.len());
    }

    fn definition() -> FieldDefinition {
        FieldDefinition {
            id: ElementId::new(40),
            source: "field".into(),
            rig: "grass".into(),
            layout: FieldLayout {
                version: 1,
                take: "sway".into(),
                fps: 30.0,
                frames: 300,
                rows: 100,
                cols: 1000,
                cell_m: 0.2,
                speed_m_s: 1.5,
                direction_deg: 0.0,
                authored_direction_deg: 0.0,
                density: 1.0,
                seed: 1,
            },
            plants: 100_000,
            stream_fps: 30.0,
            history_frames: 2400,
            publish_hz: 60,
            plant_elements: vec![ElementId::new(41)],
        }
    }

    #[test]
    fn definitions_are_checked_against_their_limits() {
        assert_eq!(definition().check(), Ok(()));
        let bad = [
            FieldDefinition { plants: 100_001, ..definition() },
            FieldDefinition { history_frames: MAX_FIELD_HISTORY_FRAMES + 1, ..definition() },
            FieldDefinition { history_frames: 1, ..definition() },
            FieldDefinition { stream_fps: f64::NAN, ..definition() },
            FieldDefinition { plant_elements: vec![ElementId::new(1); 65], ..definition() },
            FieldDefinition { layout: FieldLayout { rows: 0, ..definition().layout }, ..definition() },
            FieldDefinition {
                layout: FieldLayout { cols: 1_000_001, ..definition().layout },
                ..definition()
            },
        ];
        for d in bad {
            assert!(d.check().is_err(), "{d:?}");
        }
        let msg = ServerMessage::Field(FieldMessage::Table(FieldTable {
            elements_version: 3,
            fields: vec![definition()],
        }));
        let mut bytes = Vec::new();
        encode_frame(&msg, &mut bytes);
        assert!(bytes.len() < 1024, "a definition of 100,000 plants is {} bytes", bytes.len());
        assert_eq!(decode_frame::<ServerMessage>(&bytes).unwrap().unwrap().0, msg);
    }
}
