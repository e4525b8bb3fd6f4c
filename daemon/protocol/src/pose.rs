//! Messages on the pose socket.

use serde::{Deserialize, Serialize};

use crate::ElementId;

/// Everything the daemon sends on `poses.sock`.
// A field frame is the largest variant; the realtime loop encodes messages by value, so none is
// boxed (that would allocate per frame).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ServerMessage {
    /// First message on every connection.
    Hello(Hello),
    /// One per realtime tick.
    Pose(Pose),
    /// A new element table: sent whenever the live stages (or the rig) change, before the first
    /// frame of any element it adds; and right after a [`Hello`] whose table is already out of
    /// date. Replaces the table of the [`Hello`] or of the last `Elements`.
    Elements(ElementTable),
    /// Sent instead of a [`Hello`] when the daemon cannot take the connection (its subscriber
    /// limit is reached), saying why; the daemon closes the connection after it.
    Refused(String),
    /// A field's definition or one of its frames (protocol 3, [`crate::field`]): what the
    /// plants of a running field follow from, instead of one pose per plant.
    Field(crate::field::FieldMessage),
}

/// Every element the daemon publishes, with what it is. Element ids are assigned by the daemon
/// and mean nothing by themselves: subscribers look them up here.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ElementTable {
    /// Increases with every change (a daemon's first table is 1); a newer table replaces an
    /// older one whole.
    pub version: u64,
    /// The skeletons the elements use, by name.
    pub rigs: Vec<RigInfo>,
    /// The elements, by id (ids are unique).
    pub elements: Vec<ElementInfo>,
}

/// A skeleton elements refer to by name.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RigInfo {
    /// Rig name (`grass`, `flower`, ...).
    pub name: String,
    /// Its joint names, root first (4 of them).
    pub joint_names: Vec<String>,
}

impl ElementTable {
    /// The element with this id, if announced.
    pub fn get(&self, id: ElementId) -> Option<&ElementInfo> {
        self.elements.iter().find(|e| e.id == id)
    }

    /// Joint names of element `id`'s skeleton, if announced.
    pub fn joint_names(&self, id: ElementId) -> Option<&[String]> {
        let e = self.get(id)?;
        self.rigs.iter().find(|r| r.name == e.rig).map(|r| r.joint_names.as_slice())
    }

    /// Elements of one kind, in table order.
    pub fn of_kind(&self, kind: ElementKind) -> impl Iterator<Item = &ElementInfo> + '_ {
        self.elements.iter().filter(move |e| e.kind == kind)
    }
}

/// What produces an element's frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ElementKind {
    /// A hand source mapped onto the plant's global element.
    Hand,
    /// A hand source recording a secondary layer of the rig (`leaf`, `petal`, ...).
    Layer,
    /// A take looping as the plant's global element (seed 000, section 5.3).
    Playback,
    /// One plant of a playing field (seed 000, section 6.2).
    FieldPlant,
}

impl ElementKind {
    /// The kind's name on the wire and in status (`hand`, `layer`, `playback`, `field-plant`).
    pub fn as_str(self) -> &'static str {
        match self {
            ElementKind::Hand => "hand",
            ElementKind::Layer => "layer",
            ElementKind::Playback => "playback",
            ElementKind::FieldPlant => "field-plant",
        }
    }
}

/// One announced element.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ElementInfo {
    /// The id its [`Pose`] frames carry in [`Pose::element`].
    pub id: ElementId,
    /// A readable name: the rig for the global element, the layer's name, `field/plant3`, ...
    pub name: String,
    /// What produces it.
    pub kind: ElementKind,
    /// The live stage that publishes it (`playback`, `field`, ...), or the hand source's name.
    pub source: String,
    /// Rig whose skeleton the joints belong to (one of [`ElementTable::rigs`]).
    pub rig: String,
}

/// Sent once when a subscriber connects (and again if the rig changes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// Version of this protocol the daemon speaks ([`crate::PROTOCOL_VERSION`]).
    pub protocol_version: u8,
    /// `CARGO_PKG_VERSION` of the daemon.
    pub daemon_version: String,
    /// Name of the active rig (e.g. `grass`).
    pub rig_name: String,
    /// Joint names, root first (4 of them).
    pub joint_names: Vec<String>,
    /// Nominal tick rate of the realtime loop.
    pub tick_rate_hz: u32,
    /// The elements a subscriber can receive (what each [`Pose::element`] id is).
    #[serde(default)]
    pub elements: ElementTable,
    /// Sequence number of the next pose this subscriber will receive. Keep it the last field:
    /// [`PatchableHello`] writes it into the encoded frame's last bytes.
    pub next_seq: u64,
}

/// Bit flags carried by every [`Pose`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct PoseFlags(pub u32);

impl PoseFlags {
    /// No new device report arrived this tick: the last pose is repeated.
    pub const HELD: PoseFlags = PoseFlags(1);
    /// The hand device is gone (unplugged, stalled, never appeared).
    pub const DEVICE_LOST: PoseFlags = PoseFlags(1 << 1);
    /// A jitter filter (low-pass or One Euro) was applied before mapping.
    pub const FILTERED: PoseFlags = PoseFlags(1 << 2);
    /// A recording is in progress.
    pub const RECORDING: PoseFlags = PoseFlags(1 << 3);
    /// The pose comes from looped playback of a take, not from the hand.
    pub const PLAYBACK: PoseFlags = PoseFlags(1 << 4);
    /// The hand's time is discontinuous here: its timestamp jumped forward by more than a
    /// second, went backwards or repeated (a tracker restarted, a host paused), or the daemon
    /// resumed after a pause and skipped stale reports. The filter was reset at this pose.
    pub const DISCONTINUITY: PoseFlags = PoseFlags(1 << 5);

    /// True when every bit of `other` is set in `self`.
    pub const fn contains(self, other: PoseFlags) -> bool {
        self.0 & other.0 == other.0
    }
    /// Sets the bits of `other`.
    pub fn insert(&mut self, other: PoseFlags) {
        self.0 |= other.0;
    }
    /// Clears the bits of `other`.
    pub fn remove(&mut self, other: PoseFlags) {
        self.0 &= !other.0;
    }
    /// Sets or clears the bits of `other`.
    pub fn set(&mut self, other: PoseFlags, on: bool) {
        if on { self.insert(other) } else { self.remove(other) }
    }
    /// Names of the set flags, for logs and JSON output.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        const NAMES: [(PoseFlags, &str); 5] = [
            (PoseFlags::HELD, "held"),
            (PoseFlags::DEVICE_LOST, "device_lost"),
            (PoseFlags::FILTERED, "filtered"),
            (PoseFlags::RECORDING, "recording"),
            (PoseFlags::PLAYBACK, "playback"),
        ];
        NAMES.into_iter().filter(move |(f, _)| self.contains(*f)).map(|(_, n)| n)
    }
}

impl std::ops::BitOr for PoseFlags {
    type Output = PoseFlags;
    fn bitor(self, rhs: PoseFlags) -> PoseFlags {
        PoseFlags(self.0 | rhs.0)
    }
}

/// The calibrated hand sample a pose was mapped from (degrees; `t` in seconds of device time).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct HandWire {
    /// Device time of the sample in seconds. A frame a stage publishes (flagged `PLAYBACK`:
    /// a loop, a field plant, a walker) carries the primary hand's device time at that tick, so
    /// all elements share one timeline; its wrist and thumb angles are zero.
    pub t: f64,
    /// Calibrated wrist `[pitch, yaw, roll]` (`W` of seed 000, Eq. 2), degrees.
    pub wrist_deg: [f32; 3],
    /// Calibrated thumb bends `[G1, G2, G3]` (seed 000, Eq. 3), degrees.
    pub thumb_deg: [f32; 3],
}

/// One realtime tick's output.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Tick sequence number, +1 per tick from daemon start; gaps mean dropped frames.
    pub seq: u64,
    /// Device timestamp of the report the pose was mapped from, microseconds (device clock,
    /// unwrapped to 64 bits).
    pub device_time_us: u64,
    /// Host `CLOCK_MONOTONIC` nanoseconds when the tick published the pose.
    pub host_monotonic_ns: u64,
    /// Pose flags (held, device lost, filtered, ...).
    pub flags: PoseFlags,
    /// Element id, announced in the [`ElementTable`]: 0 is the plant's global element, 1..
    /// secondary layers (rig elements in order); stages publish theirs under ids the daemon
    /// assigns (look them up in the table, never guess from the number).
    pub element: ElementId,
    /// Joint rotations `[pitch, yaw, roll]` in degrees, joint 0 = root, 3 = top.
    pub joints_deg: [[f32; 3]; 4],
    /// The calibrated (and filtered) hand sample behind this pose.
    pub hand: HandWire,
}

/// A `Hello` frame encoded ahead of time whose `next_seq` is filled in at the last moment: the
/// daemon's realtime loop admits a subscriber between two frames and must not allocate or
/// serialise, so the acceptor thread encodes the frame and the loop only patches eight bytes.
///
/// `next_seq` is the last field of [`Hello`]; encoded as `u64::MAX` it is MessagePack `uint 64`
/// (`0xcf` and 8 big-endian bytes) at the very end of the frame. Any value written there in that
/// form is valid MessagePack (decoders accept a wider-than-needed integer).
#[derive(Debug, Clone, PartialEq)]
pub struct PatchableHello {
    bytes: Vec<u8>,
    elements_version: u64,
}

impl PatchableHello {
    /// Encodes `hello` (its `next_seq` is ignored).
    pub fn new(hello: &Hello) -> Self {
        let mut h = hello.clone();
        h.next_seq = u64::MAX;
        let mut bytes = Vec::new();
        crate::encode_frame(&ServerMessage::Hello(h), &mut bytes);
        debug_assert!(bytes.len() >= 9 && bytes[bytes.len() - 9] == 0xcf);
        PatchableHello { bytes, elements_version: hello.elements.version }
    }

    /// Version of the element table the hello carries.
    pub fn elements_version(&self) -> u64 {
        self.elements_version
    }

    /// The frame with `next_seq` set to `seq`.
    pub fn with_next_seq(&mut self, seq: u64) -> &[u8] {
        let n = self.bytes.len();
        self.bytes[n - 8..].copy_from_slice(&seq.to_be_bytes());
        &self.bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patched_hello_decodes_with_the_patched_next_seq() {
        let hello = Hello {
            protocol_version: crate::PROTOCOL_VERSION,
            daemon_version: "1.2.3".into(),
            rig_name: "grass".into(),
            joint_names: vec!["root".into(), "a".into(), "b".into(), "tip".into()],
            tick_rate_hz: 1000,
            elements: ElementTable {
                version: 3,
                rigs: vec![RigInfo { name: "grass".into(), joint_names: vec!["root".into()] }],
                elements: vec![ElementInfo {
                    id: ElementId::GLOBAL,
                    name: "grass".into(),
                    kind: ElementKind::Hand,
                    source: "hand".into(),
                    rig: "grass".into(),
                }],
            },
            next_seq: 7,
        };
        let mut p = PatchableHello::new(&hello);
        for seq in [0u64, 1, 127, 128, 65_536, 1 << 40, u64::MAX - 1] {
            let bytes = p.with_next_seq(seq).to_vec();
            let (msg, used) = crate::decode_frame::<ServerMessage>(&bytes).unwrap().unwrap();
            assert_eq!(used, bytes.len());
            assert_eq!(msg, ServerMessage::Hello(Hello { next_seq: seq, ..hello.clone() }), "seq {seq}");
        }
    }
}
