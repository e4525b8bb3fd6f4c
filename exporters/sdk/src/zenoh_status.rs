//! A bridge's status queries: the latest status report of one source or of every source a
//! selector matches. Re-exported from [`crate::zenoh`].

use std::time::{Duration, Instant};

use ::zenoh::Wait;
use frond_protocol::decode_frame;

use crate::error::{ProtocolError, SdkError};
use crate::source::ZenohAddr;
use crate::zenoh_config::{ZenohSetupError, open_addr_session};
use crate::zenoh_keys::{keys, no_bridge};

/// Asks the bridge of `addr` (one source) for its daemon's latest status report.
pub fn query_status(addr: &ZenohAddr, timeout: Duration) -> Result<frond_protocol::StatusReport, SdkError> {
    let mut found = query_statuses(addr, timeout)?;
    if found.len() > 1 {
        let matches = found.into_iter().map(|(k, _)| k).collect();
        return Err(SdkError::AmbiguousSource { selector: addr.key.clone(), matches });
    }
    Ok(found.pop().expect("query_statuses returns at least one").1)
}

/// Asks every bridge `addr`'s key matches (`frond/stage1/*`: every source of stage1) for its
/// daemon's latest status report; waits up to `timeout` for the first answer. The reports
/// with their sources' keys (`frond/<stage>/<source>`), sorted by key, at least one.
pub fn query_statuses(
    addr: &ZenohAddr,
    timeout: Duration,
) -> Result<Vec<(String, frond_protocol::StatusReport)>, SdkError> {
    let setup = |e: ZenohSetupError| SdkError::Zenoh { source_key: addr.to_string(), reason: e.to_string() };
    let session = open_addr_session(addr).map_err(setup)?;
    query_statuses_in(&session, addr, timeout)
}

/// [`query_statuses`] in a session that is already open (`addr`'s endpoints and configuration
/// file are not used).
pub fn query_statuses_in(
    session: &::zenoh::Session,
    addr: &ZenohAddr,
    timeout: Duration,
) -> Result<Vec<(String, frond_protocol::StatusReport)>, SdkError> {
    let deadline = Instant::now() + timeout;
    let zerr = |e: ::zenoh::Error| SdkError::Zenoh { source_key: addr.to_string(), reason: e.to_string() };
    loop {
        let wait = deadline.saturating_duration_since(Instant::now()).max(Duration::from_millis(100));
        let replies = session.get(keys::under(&addr.key, keys::STATUS)).timeout(wait).wait().map_err(zerr)?;
        let mut found: Vec<(String, frond_protocol::StatusReport)> = Vec::new();
        while let Ok(reply) = replies.recv() {
            let Ok(sample) = reply.result() else { continue };
            let key = sample.key_expr().as_str().to_owned();
            let bytes = sample.payload().to_bytes();
            let bad = |error: ProtocolError| SdkError::Protocol { path: key.clone().into(), error };
            match decode_frame::<frond_protocol::ControlReply>(&bytes).map_err(|e| bad(e.into()))? {
                Some((frond_protocol::ControlReply::Status(report), used)) if used == bytes.len() => {
                    let source = key.trim_end_matches("/status").to_owned();
                    if !found.iter().any(|(k, _)| *k == source) && found.len() < MAX_STAGE_SOURCES {
                        found.push((source, *report));
                    }
                }
                _ => {
                    return Err(bad(ProtocolError::Frame(frond_protocol::DecodeError::Malformed(
                        "a status sample that is not one status frame".into(),
                    ))));
                }
            }
        }
        if !found.is_empty() {
            found.sort_by(|a, b| a.0.cmp(&b.0));
            return Ok(found);
        }
        if Instant::now() >= deadline {
            return Err(no_bridge(session, addr.to_string(), timeout));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Most sources one stage listing returns; more tokens than this are not looked at.
pub const MAX_STAGE_SOURCES: usize = 64;
