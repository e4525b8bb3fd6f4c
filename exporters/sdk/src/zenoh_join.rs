//! Joining a source over Zenoh: the questions a subscription asks its bridge before it reads
//! (which source a key names, its hello, its running fields), and how one sample is read as one
//! frame. The subscription itself is [`crate::zenoh`]'s.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use ::zenoh::Wait;
use frond_protocol::field::{FieldMessage, FieldTable};
use frond_protocol::{HEADER_LEN, Hello, MAX_FRAME_LEN, ServerMessage, decode_frame};

use crate::check_hello;
use crate::error::{ProtocolError, SdkError};
use crate::source::ZenohAddr;
use crate::zenoh_keys::{keys, no_bridge};

/// One payload is exactly one frame.
pub(crate) fn decode_payload(bytes: &[u8]) -> Result<ServerMessage, ProtocolError> {
    match decode_frame::<ServerMessage>(bytes)? {
        Some((msg, used)) if used == bytes.len() => Ok(msg),
        Some((_, used)) => {
            Err(ProtocolError::Frame(frond_protocol::DecodeError::TrailingBytes(bytes.len() - used)))
        }
        None => Err(ProtocolError::Frame(frond_protocol::DecodeError::Malformed(format!(
            "a Zenoh sample of {} bytes holds a partial frame",
            bytes.len()
        )))),
    }
}

/// Asks `<key>/hello`; returns the answering source's key and its hello, or `None` when no
/// bridge answered. Several sources answering a wildcard key is an error naming them.
pub(crate) fn query_hello(
    session: &::zenoh::Session,
    key: &str,
    deadline: Instant,
) -> Result<Option<(String, Hello)>, SdkError> {
    let zerr = |e: ::zenoh::Error| SdkError::Zenoh { source_key: key.to_owned(), reason: e.to_string() };
    let timeout = deadline
        .saturating_duration_since(Instant::now())
        .clamp(Duration::from_millis(100), Duration::from_secs(2));
    let replies = session.get(keys::under(key, keys::HELLO)).timeout(timeout).wait().map_err(zerr)?;
    let mut found: Vec<(String, Hello)> = Vec::new();
    while let Ok(reply) = replies.recv() {
        let Ok(sample) = reply.result() else { continue };
        let source_key = sample
            .key_expr()
            .as_str()
            .strip_suffix("/hello")
            .unwrap_or(sample.key_expr().as_str())
            .to_owned();
        let bytes = sample.payload().to_bytes();
        let protocol = |error| SdkError::Protocol { path: source_key.clone().into(), error };
        match decode_payload(&bytes).map_err(protocol)? {
            ServerMessage::Hello(hello) => {
                check_hello(&hello).map_err(protocol)?;
                if !found.iter().any(|(k, _)| *k == source_key) {
                    found.push((source_key, hello));
                }
            }
            ServerMessage::Refused(reason) => {
                return Err(SdkError::Refused { path: source_key.into(), reason });
            }
            _ => return Err(protocol(ProtocolError::ExpectedHello)),
        }
    }
    match found.len() {
        0 => Ok(None),
        1 => Ok(found.pop()),
        _ => {
            let mut names: Vec<String> = found.into_iter().map(|(k, _)| k).collect();
            names.sort();
            Err(SdkError::AmbiguousSource { selector: key.to_owned(), matches: names })
        }
    }
}

/// The newer of two field tables (by their element table's version; `b` when equal).
pub(crate) fn newer(a: Option<FieldTable>, b: FieldTable) -> Option<FieldTable> {
    match a {
        Some(a) if a.elements_version > b.elements_version => Some(a),
        _ => Some(b),
    }
}

/// Asks `<key>/fields` (one concrete source key): the newest field table answered, or `None`
/// when no bridge answered in time (an older bridge, a lost reply: the next table put brings
/// it) or an answer is not one (counted in `oversized` when larger than any frame). Waits at
/// most 2 s, and not past `deadline`.
pub(crate) fn query_fields(
    session: &::zenoh::Session,
    key: &str,
    deadline: Instant,
    oversized: &AtomicU64,
) -> Option<FieldTable> {
    let timeout = deadline
        .saturating_duration_since(Instant::now())
        .clamp(Duration::from_millis(100), Duration::from_secs(2));
    let replies = session.get(keys::under(key, keys::FIELDS)).timeout(timeout).wait().ok()?;
    let mut found = None;
    while let Ok(reply) = replies.recv() {
        let Ok(sample) = reply.result() else { continue };
        if sample.payload().len() > MAX_FRAME_LEN + HEADER_LEN {
            oversized.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        match decode_payload(&sample.payload().to_bytes()) {
            Ok(ServerMessage::Field(FieldMessage::Table(table))) => found = newer(found, table),
            _ => tracing::debug!(key, "an answer on fields that is not a field table; skipped"),
        }
    }
    found
}

/// Finds the one source `addr` names (its key may hold wildcards), waiting up to `timeout` for
/// a bridge to answer: its key and the hello it answered with.
pub(crate) fn resolve(
    session: &::zenoh::Session,
    addr: &ZenohAddr,
    timeout: Duration,
) -> Result<(String, Hello), SdkError> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(found) = query_hello(session, &addr.key, deadline)? {
            return Ok(found);
        }
        if Instant::now() >= deadline {
            return Err(no_bridge(session, addr.to_string(), timeout));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_protocol::Pose;

    #[test]
    fn a_payload_is_exactly_one_frame() {
        let mut bytes = Vec::new();
        frond_protocol::encode_frame(&ServerMessage::Pose(Pose { seq: 7, ..Pose::default() }), &mut bytes);
        assert!(matches!(decode_payload(&bytes), Ok(ServerMessage::Pose(p)) if p.seq == 7));
        assert!(decode_payload(&bytes[..bytes.len() - 1]).is_err());
        let mut two = bytes.clone();
        two.extend_from_slice(&bytes);
        assert!(matches!(decode_payload(&two), Err(ProtocolError::Frame(_))));
        assert!(decode_payload(&[]).is_err());
    }
}
