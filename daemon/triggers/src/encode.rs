//! A [`TriggerMessage`] to the bytes of one datagram, for frond leading the stage.
//!
//! The layout is Vicon's published one, byte for byte: the XML declaration, the root, one
//! empty element per field with its `VALUE` attribute in the order `Name`, `Notes`,
//! `Description`, `DatabasePath`, `Delay`, `PacketID` (then `TimeCode` and `ProcessID`, which
//! Motive and Rokoko add), no white space between elements, and a terminating NUL ("the
//! packet contents are null terminated").

use crate::message::{MAX_DATAGRAM_BYTES, StopResult, TriggerFields, TriggerMessage};

/// The declaration every published example starts with.
const DECLARATION: &str = r#"<?xml version="1.0" encoding="UTF-8" standalone="no"?>"#;

/// Why a message cannot be sent.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// Longer than one datagram may be (Vicon does not send such a broadcast either).
    #[error("the message is {0} bytes, over the {MAX_DATAGRAM_BYTES}-byte datagram limit")]
    TooLarge(usize),
    /// A control character XML 1.0 cannot carry.
    #[error("<{field}> holds control character U+{code:04X}, which XML cannot carry")]
    Character {
        /// The field.
        field: &'static str,
        /// The character's code point.
        code: u32,
    },
}

/// Writes `message` into `out` (cleared first; its capacity is reused), NUL-terminated.
pub fn encode(message: &TriggerMessage, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    out.clear();
    out.extend_from_slice(DECLARATION.as_bytes());
    let root = message.kind();
    out.push(b'<');
    out.extend_from_slice(root.as_bytes());
    if let TriggerMessage::Stop { result, .. } = message {
        match result {
            StopResult::Unspecified => {}
            StopResult::Success => out.extend_from_slice(br#" RESULT="SUCCESS""#),
            StopResult::Cancel => out.extend_from_slice(br#" RESULT="CANCEL""#),
        }
    }
    out.push(b'>');
    write_fields(message.fields(), out)?;
    out.extend_from_slice(b"</");
    out.extend_from_slice(root.as_bytes());
    out.extend_from_slice(b">\0");
    if out.len() > MAX_DATAGRAM_BYTES {
        return Err(EncodeError::TooLarge(out.len()));
    }
    Ok(())
}

fn write_fields(fields: &TriggerFields, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    let texts = [
        ("Name", fields.name.as_deref()),
        ("Notes", fields.notes.as_deref()),
        ("Description", fields.description.as_deref()),
        ("DatabasePath", fields.database_path.as_deref()),
    ];
    for (field, value) in texts {
        if let Some(value) = value {
            element(field, value, out)?;
        }
    }
    if let Some(delay) = fields.delay_ms {
        element("Delay", &delay.to_string(), out)?;
    }
    if let Some(id) = fields.packet_id {
        element("PacketID", &id.to_string(), out)?;
    }
    if let Some(tc) = fields.timecode {
        element("TimeCode", &tc.to_string(), out)?;
    }
    if let Some(pid) = fields.process_id.as_deref() {
        element("ProcessID", pid, out)?;
    }
    Ok(())
}

/// `<field VALUE="value"/>`, the value escaped.
fn element(field: &'static str, value: &str, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    out.push(b'<');
    out.extend_from_slice(field.as_bytes());
    out.extend_from_slice(b" VALUE=\"");
    for c in value.chars() {
        match c {
            '&' => out.extend_from_slice(b"&amp;"),
            '<' => out.extend_from_slice(b"&lt;"),
            '>' => out.extend_from_slice(b"&gt;"),
            '"' => out.extend_from_slice(b"&quot;"),
            // Written as references: a parser normalises literal tabs and line ends in an
            // attribute to spaces.
            '\t' | '\n' | '\r' => out.extend_from_slice(format!("&#{};", u32::from(c)).as_bytes()),
            c if c.is_control() && (c as u32) < 0x20 => {
                return Err(EncodeError::Character { field, code: c as u32 });
            }
            c => {
                let mut utf8 = [0; 4];
                out.extend_from_slice(c.encode_utf8(&mut utf8).as_bytes());
            }
        }
    }
    out.extend_from_slice(b"\"/>");
    Ok(())
}
