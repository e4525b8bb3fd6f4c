//! Capture triggers: the UDP messages a motion-capture stage's master sends when its
//! operator starts and stops a take, so every other system records the same take.
//!
//! # The format, and where it is published
//! One XML document per UDP datagram, root `CaptureStart` or `CaptureStop`, each field an
//! empty element with a `VALUE` attribute:
//!
//! ```text
//! <?xml version="1.0" encoding="UTF-8" standalone="no"?><CaptureStart><Name VALUE="dance"/>
//! <Notes VALUE="..."/><Description VALUE="..."/><DatabasePath VALUE="D:/.../Take"/>
//! <Delay VALUE="33"/><PacketID VALUE="33360"/></CaptureStart>
//! ```
//!
//! - **Vicon** (Shogun, Tracker, Nexus, Blade), "UDP capture broadcast/trigger":
//!   <https://docs.vicon.com/pages/viewpage.action?pageId=133824766> (Shogun 1.7),
//!   <https://vicon-help.atlassian.net/wiki/spaces/Tracker310/pages/13930337/UDP+capture+broadcast+trigger>.
//!   Port configurable, **default 30**; the packet is NUL-terminated and must fit one UDP
//!   packet; white space between tokens removed; `Delay` is the milliseconds between the
//!   broadcast and the capture's start; `PacketID` "is incremented for each packet generated.
//!   Use it to discard duplicate packets". `CaptureStop` carries `RESULT="SUCCESS"` (or
//!   `CANCEL`) with `Name`, `DatabasePath`, `Delay`, `PacketID` (as public senders built on
//!   that page write it).
//! - **OptiTrack Motive**: the same messages ("remote triggering", on in the streaming
//!   settings), broadcast on **port 1512**, the NatNet command port (1510) + 2, per
//!   StretchSense's integration notes:
//!   <https://stretchsense.atlassian.net/wiki/spaces/SS/pages/25821627>, which also lists
//!   Qualisys 8989 and Vicon 30. Motive adds `TimeCode`, `ProcessID` and others
//!   (`SessionName`, `Assets`, `HostName`), skipped here unless used. Motive's own page on the
//!   XML was not in the searchable record when this was written; its exact field set is
//!   unverified beyond what these sources show.
//! - **Rokoko Studio**, "UDP Trigger Messages":
//!   <https://support.rokoko.com/hc/en-us/articles/14905272191505-Rokoko-Studio-UDP-Trigger-Messages>.
//!   Receives on a configured port and sends on that port + 1; `CaptureStart` with `Name`,
//!   `TimeCode` (SMPTE `00:00:00:00`, which means "not used"), `PacketID`, `ProcessID`
//!   ("optional process id", free text); `CaptureStop` with `Name`, `TimeCode`,
//!   `SetActiveClip`, `ProcessID`, and no `PacketID`.
//! - NOKOV XINGYING uses the same start/stop messages on default port 7061:
//!   <https://docs.nokov.com/xingying3.1.0/udp-capture-broadcast-trigger/remote-trigger>.
//!
//! # What is here
//! [`decode`] (bounded, never panics, a [`DecodeError`] naming the problem), [`encode`] into
//! a reused buffer, byte-identical to Vicon's example, [`Follower`] (a pure state machine:
//! allow-list, per-sender packet ids, delay, safe take names, counters), [`Leader`] (frond's
//! own numbered messages), and [`TriggerSocket`], the only I/O, kept apart.
//!
//! [`decode`] is fuzzed in `fuzz/tests/it/triggers.rs` (never a panic, the documented bounds,
//! and `decode(encode(m)) == m` for what it accepts); `tests/it/wire.rs` property-tests it too.

#![warn(missing_docs)]

mod decode;
mod encode;
mod follower;
mod leader;
mod message;
mod socket;
mod take_name;

pub use decode::{DecodeError, decode};
pub use encode::{EncodeError, encode};
pub use follower::{
    Decision, Follower, FollowerConfig, FollowerCounters, FollowerState, Ignored, LastMessage, MAX_SENDERS,
    REORDER_WINDOW, StartTake,
};
pub use leader::Leader;
pub use message::{
    MAX_DATAGRAM_BYTES, MAX_DELAY_MS, MAX_ELEMENTS, MAX_NAME_BYTES, MAX_PROCESS_ID_BYTES, MAX_TEXT_BYTES,
    StopResult, TriggerFields, TriggerMessage,
};
pub use socket::{Received, TriggerSocket};
pub use take_name::safe_take_name;

/// Vicon's default trigger port (Shogun, Tracker, Nexus, Blade).
pub const VICON_PORT: u16 = 30;
/// OptiTrack Motive's trigger broadcast port (NatNet command port 1510 + 2).
pub const MOTIVE_PORT: u16 = 1512;
/// Qualisys QTM's capture broadcast port.
pub const QUALISYS_PORT: u16 = 8989;
