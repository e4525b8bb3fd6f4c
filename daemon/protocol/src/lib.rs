//! frond's wire protocol, shared by the daemon, the operator CLI and every exporter.
//!
//! Two Unix stream sockets speak it:
//! - `poses.sock`: the daemon sends one [`ServerMessage::Hello`] on connect (with the element
//!   table: what each element id is), then [`ServerMessage::Pose`]s, at least one per realtime
//!   tick, and a [`ServerMessage::Elements`] table whenever the live stages or the rig change.
//!   Nothing a subscriber sends is read as a command.
//! - `control.sock`: a client sends [`ControlRequest`]s, the daemon answers each with one
//!   [`ControlReply`].
//!
//! Framing (see [`frame`]): `u32` little-endian length `N`, then `N` bytes: one protocol version byte
//! followed by a MessagePack body (rmp-serde, structs as maps with field names so that third-party
//! decoders can read it without our schema). A peer refuses frames of a newer version with
//! [`DecodeError::UnsupportedVersion`] rather than guessing.

#![warn(missing_docs)]

pub mod control;
pub mod convention;
pub mod element_id;
pub mod errors;
pub mod field;
pub mod frame;
pub mod paths;
pub mod pose;
pub mod source_kind;

pub use control::{
    CameraStatus, ControlError, ControlErrorKind, ControlReply, ControlRequest, GraphGoal, GraphSource,
    HandStatus, HistogramBucket, LatencySummary, LtcStatus, MAX_GRAPH_SOURCES, MAX_STAGE_RIG_BYTES,
    RecordingStatus, SourceStatus, StageInput, StageKey, StageSpec, StageStatus, StatusReport,
    SubscriberStatus, TriggerLast, TriggerStatus,
};
pub use element_id::ElementId;
pub use errors::printable;
pub use frame::{
    DecodeError, FrameBuf, HEADER_LEN, MAX_CONTROL_REQUEST, MAX_FRAME_LEN, PROTOCOL_VERSION, ReadError,
    decode_frame, encode_frame, encode_frame_as, read_frame, read_frame_limited, write_frame,
};
pub use pose::{
    ElementInfo, ElementKind, ElementTable, HandWire, Hello, PatchableHello, Pose, PoseFlags, RigInfo,
    ServerMessage,
};
pub use source_kind::SourceKind;

/// Default socket file names inside the socket directory.
pub const POSES_SOCKET: &str = "poses.sock";
/// Control socket file name inside the socket directory.
pub const CONTROL_SOCKET: &str = "control.sock";
