//! The typed form of one trigger message, and the bounds every field is held to.

use frond_ltc::SmpteTime;

/// The largest datagram read: refused unread above this. A trigger must fit one UDP packet
/// (Vicon: "the broadcast must fit into one UDP packet ... if it does not, the broadcast is
/// not sent"); 16 KiB is a generous notes field and far below the 64 KiB UDP limit.
pub const MAX_DATAGRAM_BYTES: usize = 16 * 1024;
/// The longest take name accepted from a message, in bytes (made safe and cut to the take
/// name rules' 128 afterwards).
pub const MAX_NAME_BYTES: usize = 1024;
/// The longest notes, description or database path, in bytes.
pub const MAX_TEXT_BYTES: usize = 8 * 1024;
/// The longest process id, in bytes (Rokoko documents it as free text).
pub const MAX_PROCESS_ID_BYTES: usize = 64;
/// The longest delay honoured: a minute. Vicon's example is 33 ms; anything near this is a
/// mistake, and a start that far off would surprise an operator.
pub const MAX_DELAY_MS: u32 = 60_000;
/// The most elements in one message (the published ones have at most ten).
pub const MAX_ELEMENTS: usize = 64;

/// How a capture ended, from `CaptureStop`'s `RESULT` attribute (Vicon: `SUCCESS`, or
/// `CANCEL` when the operator cancelled the capture).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopResult {
    /// No `RESULT` attribute (Motive, Rokoko).
    Unspecified,
    /// `RESULT="SUCCESS"`.
    Success,
    /// `RESULT="CANCEL"`.
    Cancel,
}

/// The fields both messages may carry.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct TriggerFields {
    /// The take name as sent (`Name`), not yet made safe.
    pub name: Option<String>,
    /// `Notes`.
    pub notes: Option<String>,
    /// `Description`.
    pub description: Option<String>,
    /// `DatabasePath`: where the master writes its files; reported, never used as a path.
    pub database_path: Option<String>,
    /// `TimeCode`: the master's timecode at the start or stop (`00:00:00:00` means none, per
    /// Rokoko's documentation).
    pub timecode: Option<SmpteTime>,
    /// `Delay`: milliseconds between the message and the capture's start.
    pub delay_ms: Option<u32>,
    /// `PacketID`: incremented for each packet, to discard duplicates.
    pub packet_id: Option<u64>,
    /// `ProcessID`: the sending program's process.
    pub process_id: Option<String>,
}

/// One decoded trigger message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TriggerMessage {
    /// `CaptureStart`: start recording a take.
    Start(TriggerFields),
    /// `CaptureStop`: stop recording.
    Stop {
        /// The fields.
        fields: TriggerFields,
        /// Its `RESULT`.
        result: StopResult,
    },
}

impl TriggerMessage {
    /// The fields, whichever the kind.
    pub fn fields(&self) -> &TriggerFields {
        match self {
            TriggerMessage::Start(fields) | TriggerMessage::Stop { fields, .. } => fields,
        }
    }

    /// The root element's name.
    pub fn kind(&self) -> &'static str {
        match self {
            TriggerMessage::Start(_) => "CaptureStart",
            TriggerMessage::Stop { .. } => "CaptureStop",
        }
    }
}
