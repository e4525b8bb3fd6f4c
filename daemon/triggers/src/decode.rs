//! One datagram to one [`TriggerMessage`], bounded, with an error naming what was wrong.
//!
//! The size is checked before anything is read; the XML is read by `quick-xml`, a pull
//! parser that expands no entities but the five predefined ones and numeric references, so
//! there is no entity expansion to bound; a document type declaration is refused outright.
//! Elements are counted and nesting is limited to the published shape (a root with flat
//! field elements), so no input makes the decoder work harder than its length.

use frond_ltc::{SmpteTime, TimecodeError};
use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

use crate::message::{
    MAX_DATAGRAM_BYTES, MAX_DELAY_MS, MAX_ELEMENTS, MAX_NAME_BYTES, MAX_PROCESS_ID_BYTES, MAX_TEXT_BYTES,
    StopResult, TriggerFields, TriggerMessage,
};

/// Why a datagram is no trigger message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// Larger than [`MAX_DATAGRAM_BYTES`]; refused unread.
    #[error("datagram of {0} bytes is over the {MAX_DATAGRAM_BYTES}-byte limit")]
    Oversized(usize),
    /// Nothing but NULs and white space.
    #[error("datagram is empty")]
    Empty,
    /// Not UTF-8 (the published messages declare `encoding="UTF-8"`).
    #[error("datagram is not UTF-8 text (at byte {0})")]
    NotUtf8(usize),
    /// Not well-formed XML.
    #[error("malformed XML at byte {position}: {message}")]
    Xml {
        /// Where the parser stopped.
        position: u64,
        /// What it found.
        message: String,
    },
    /// A `<!DOCTYPE>`: refused, so no entity can be declared.
    #[error("a document type declaration is refused in a trigger message")]
    DocType,
    /// A root element other than `CaptureStart` or `CaptureStop`.
    #[error("<{0}> is not a capture trigger (expected CaptureStart or CaptureStop)")]
    UnknownMessage(String),
    /// No root element at all.
    #[error("no CaptureStart or CaptureStop element")]
    NoRoot,
    /// More than [`MAX_ELEMENTS`] elements.
    #[error("more than {MAX_ELEMENTS} elements")]
    TooManyElements,
    /// An element inside a field element.
    #[error("<{0}> is nested inside a field; trigger fields are flat")]
    TooDeep(String),
    /// The datagram ends inside the message (cut short).
    #[error("the message ends before its root element closes")]
    Truncated,
    /// Another element after the root closed.
    #[error("content after the end of the message")]
    TrailingContent,
    /// A field given twice.
    #[error("<{0}> appears twice")]
    Duplicate(&'static str),
    /// A field without its `VALUE` attribute.
    #[error("<{0}> has no VALUE attribute")]
    MissingValue(&'static str),
    /// A field longer than its bound.
    #[error("<{field}> VALUE is {len} bytes, more than {max}")]
    TooLong {
        /// The field.
        field: &'static str,
        /// Its length.
        len: usize,
        /// Its bound.
        max: usize,
    },
    /// A number field that is not a whole number in range.
    #[error("<{field}> VALUE {value:?} is not a whole number from 0 to {max}")]
    BadNumber {
        /// The field.
        field: &'static str,
        /// What it held (cut to 32 characters).
        value: String,
        /// Its largest value.
        max: u64,
    },
    /// A `TimeCode` that is no timecode.
    #[error("<TimeCode>: {0}")]
    Timecode(#[from] TimecodeError),
    /// A `CaptureStop RESULT` other than `SUCCESS` or `CANCEL`.
    #[error("CaptureStop RESULT {0:?} is neither SUCCESS nor CANCEL")]
    BadResult(String),
}

/// Decodes one datagram. Trailing NULs are allowed (Vicon's packets are NUL-terminated),
/// unknown field elements are skipped (`SessionName`, `Assets`, `SetActiveClip`, `HostName`
/// ...), known ones are checked against their bounds. Never panics.
pub fn decode(datagram: &[u8]) -> Result<TriggerMessage, DecodeError> {
    if datagram.len() > MAX_DATAGRAM_BYTES {
        return Err(DecodeError::Oversized(datagram.len()));
    }
    let end = datagram.iter().rposition(|&b| b != 0 && !b.is_ascii_whitespace()).map_or(0, |i| i + 1);
    if end == 0 {
        return Err(DecodeError::Empty);
    }
    let text = std::str::from_utf8(&datagram[..end]).map_err(|e| DecodeError::NotUtf8(e.valid_up_to()))?;
    let mut reader = Reader::from_str(text);
    reader.config_mut().trim_text(true);
    let mut parser = Parser::default();
    loop {
        let event = reader.read_event().map_err(|e| xml_error(&reader, e))?;
        match event {
            Event::Eof if parser.depth > 0 => return Err(DecodeError::Truncated),
            Event::Eof => break,
            Event::DocType(_) => return Err(DecodeError::DocType),
            Event::Start(e) => parser.open(&e, false)?,
            Event::Empty(e) => parser.open(&e, true)?,
            Event::End(_) => parser.depth = parser.depth.saturating_sub(1),
            Event::Text(_) | Event::CData(_) | Event::GeneralRef(_)
                if parser.root.is_some() && parser.depth == 0 =>
            {
                return Err(DecodeError::TrailingContent);
            }
            Event::Decl(_)
            | Event::Comment(_)
            | Event::PI(_)
            | Event::Text(_)
            | Event::CData(_)
            | Event::GeneralRef(_) => {}
        }
    }
    let fields = parser.fields;
    match parser.root {
        None => Err(DecodeError::NoRoot),
        Some(Root::Start) => Ok(TriggerMessage::Start(fields)),
        Some(Root::Stop(result)) => Ok(TriggerMessage::Stop { fields, result }),
    }
}

fn xml_error(reader: &Reader<&[u8]>, e: quick_xml::Error) -> DecodeError {
    DecodeError::Xml { position: reader.error_position(), message: e.to_string().chars().take(200).collect() }
}

#[derive(Debug, Clone, Copy)]
enum Root {
    Start,
    Stop(StopResult),
}

#[derive(Debug, Default)]
struct Parser {
    root: Option<Root>,
    /// 0 before the root and after it closed, 1 inside it, 2 inside a field element.
    depth: u32,
    elements: usize,
    fields: TriggerFields,
}

impl Parser {
    fn open(&mut self, e: &BytesStart<'_>, empty: bool) -> Result<(), DecodeError> {
        self.elements += 1;
        if self.elements > MAX_ELEMENTS {
            return Err(DecodeError::TooManyElements);
        }
        let name = e.name();
        let name = String::from_utf8_lossy(name.as_ref());
        match (self.depth, self.root) {
            (0, Some(_)) => return Err(DecodeError::TrailingContent),
            (0, None) => self.root = Some(root(&name, e)?),
            (1, _) => read_field(&name, e, &mut self.fields)?,
            _ => return Err(DecodeError::TooDeep(name.chars().take(64).collect())),
        }
        if !empty {
            self.depth += 1;
        }
        Ok(())
    }
}

fn root(name: &str, e: &BytesStart<'_>) -> Result<Root, DecodeError> {
    match name {
        "CaptureStart" => Ok(Root::Start),
        "CaptureStop" => {
            let result = match attribute(e, b"RESULT")?.as_deref() {
                None => StopResult::Unspecified,
                Some("SUCCESS") => StopResult::Success,
                Some("CANCEL") => StopResult::Cancel,
                Some(other) => return Err(DecodeError::BadResult(other.chars().take(32).collect())),
            };
            Ok(Root::Stop(result))
        }
        other => Err(DecodeError::UnknownMessage(other.chars().take(64).collect())),
    }
}

/// The unescaped value of attribute `key`, if present.
fn attribute(e: &BytesStart<'_>, key: &[u8]) -> Result<Option<String>, DecodeError> {
    for attr in e.attributes() {
        let attr = attr.map_err(|err| DecodeError::Xml { position: 0, message: err.to_string() })?;
        if attr.key.as_ref() == key {
            let value = attr
                .unescape_value()
                .map_err(|err| DecodeError::Xml { position: 0, message: err.to_string() })?;
            return Ok(Some(value.into_owned()));
        }
    }
    Ok(None)
}

fn read_field(name: &str, e: &BytesStart<'_>, fields: &mut TriggerFields) -> Result<(), DecodeError> {
    let (field, max): (&'static str, usize) = match name {
        "Name" => ("Name", MAX_NAME_BYTES),
        "Notes" => ("Notes", MAX_TEXT_BYTES),
        "Description" => ("Description", MAX_TEXT_BYTES),
        "DatabasePath" => ("DatabasePath", MAX_TEXT_BYTES),
        "ProcessID" => ("ProcessID", MAX_PROCESS_ID_BYTES),
        "TimeCode" | "Delay" | "PacketID" => (static_name(name), 32),
        _ => return Ok(()), // a field this crate does not use
    };
    let value = attribute(e, b"VALUE")?.ok_or(DecodeError::MissingValue(field))?;
    if value.len() > max {
        return Err(DecodeError::TooLong { field, len: value.len(), max });
    }
    match field {
        "Name" => set(&mut fields.name, field, value),
        "Notes" => set(&mut fields.notes, field, value),
        "Description" => set(&mut fields.description, field, value),
        "DatabasePath" => set(&mut fields.database_path, field, value),
        "ProcessID" => set(&mut fields.process_id, field, value),
        "Delay" => set(&mut fields.delay_ms, field, number(field, &value, u64::from(MAX_DELAY_MS))? as u32),
        "PacketID" => set(&mut fields.packet_id, field, number(field, &value, u64::MAX)?),
        _ => {
            let time = SmpteTime::parse(&value)?;
            let unused = time
                == SmpteTime { hours: 0, minutes: 0, seconds: 0, frames: 0, drop_frame: time.drop_frame };
            if fields.timecode.is_some() {
                return Err(DecodeError::Duplicate(field));
            }
            fields.timecode = (!unused).then_some(time);
            Ok(())
        }
    }
}

fn static_name(name: &str) -> &'static str {
    match name {
        "TimeCode" => "TimeCode",
        "Delay" => "Delay",
        _ => "PacketID",
    }
}

fn set<T>(slot: &mut Option<T>, field: &'static str, value: T) -> Result<(), DecodeError> {
    if slot.is_some() {
        return Err(DecodeError::Duplicate(field));
    }
    *slot = Some(value);
    Ok(())
}

fn number(field: &'static str, value: &str, max: u64) -> Result<u64, DecodeError> {
    let bad = || DecodeError::BadNumber { field, value: value.chars().take(32).collect(), max };
    let digits = value.trim();
    if digits.is_empty() || digits.len() > 20 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    digits.parse::<u64>().ok().filter(|&n| n <= max).ok_or_else(bad)
}
