//! frond leading the stage: the messages its own `record start` / `record stop` broadcast.

use frond_ltc::SmpteTime;

use crate::encode::{EncodeError, encode};
use crate::message::{StopResult, TriggerFields, TriggerMessage};

/// Numbers frond's messages and encodes them into one reused buffer.
#[derive(Debug, Clone)]
pub struct Leader {
    next_packet_id: u64,
    process_id: String,
    buf: Vec<u8>,
}

impl Leader {
    /// A leader whose packets carry `process_id` (frond's pid) and count from `first_packet_id`
    /// (a value from the clock, so a restarted frond does not repeat ids a follower remembers).
    pub fn new(process_id: u32, first_packet_id: u64) -> Leader {
        Leader {
            next_packet_id: first_packet_id,
            process_id: process_id.to_string(),
            buf: Vec::with_capacity(512),
        }
    }

    /// The `CaptureStart` for take `name`, starting `delay_ms` after it is sent.
    pub fn start(
        &mut self,
        name: &str,
        timecode: Option<SmpteTime>,
        delay_ms: u32,
    ) -> Result<&[u8], EncodeError> {
        let fields = TriggerFields { delay_ms: Some(delay_ms), ..self.fields(name, timecode) };
        self.encode(&TriggerMessage::Start(fields))
    }

    /// The `CaptureStop` for take `name`.
    pub fn stop(&mut self, name: &str, timecode: Option<SmpteTime>) -> Result<&[u8], EncodeError> {
        let fields = self.fields(name, timecode);
        self.encode(&TriggerMessage::Stop { fields, result: StopResult::Success })
    }

    fn fields(&mut self, name: &str, timecode: Option<SmpteTime>) -> TriggerFields {
        let packet_id = self.next_packet_id;
        self.next_packet_id = self.next_packet_id.wrapping_add(1);
        TriggerFields {
            name: Some(name.to_string()),
            timecode,
            packet_id: Some(packet_id),
            process_id: Some(self.process_id.clone()),
            ..TriggerFields::default()
        }
    }

    fn encode(&mut self, message: &TriggerMessage) -> Result<&[u8], EncodeError> {
        encode(message, &mut self.buf)?;
        Ok(&self.buf)
    }
}
