//! The key expressions under a source's key, and how sources are named and listed: the base
//! every other Zenoh module of the SDK uses (re-exported from [`crate::zenoh`]).

use std::time::Duration;

use ::zenoh::Wait;

use crate::error::SdkError;
use crate::source::{KEY_ROOT, check_name};

/// Key expressions below a source's key.
pub mod keys {
    /// Every pose.
    pub const POSES: &str = "poses";
    /// The element table.
    pub const ELEMENTS: &str = "elements";
    /// The running fields' definitions (protocol 3; their frames travel with the poses).
    pub const FIELDS: &str = "fields";
    /// The daemon's hello.
    pub const HELLO: &str = "hello";
    /// The daemon's status report.
    pub const STATUS: &str = "status";
    /// The bridge's liveliness token.
    pub const ALIVE: &str = "alive";
    /// Bridges' claims on the source's name: liveliness tokens `bridge/<id>`, one per bridge
    /// (the elder publishes, a younger one stands by; see `frond-zenoh`).
    pub const BRIDGE: &str = "bridge";
    /// The bridge host's clocks (a queryable, see `crate::stage_time`).
    pub const CLOCK: &str = "clock";
    /// Remote control (a queryable, only on bridges started with `--control FILE`; requests
    /// are signed, see `crate::control_auth`).
    pub const CONTROL: &str = "control";

    /// `<source_key>/<leaf>`.
    pub fn under(source_key: &str, leaf: &str) -> String {
        format!("{source_key}/{leaf}")
    }
}

/// How long a failed lookup waits for the list of the sources that are on the network.
const PRESENT_TIMEOUT: Duration = Duration::from_millis(500);
/// Most sources a failed lookup names.
const MAX_PRESENT: usize = 16;

/// The error for `source_key`, which no bridge answered within `waited`, naming the sources
/// (`<stage>/<source>`) whose bridges are on the network instead (their `alive` tokens).
pub(crate) fn no_bridge(session: &::zenoh::Session, source_key: String, waited: Duration) -> SdkError {
    let selector = format!("{}/*/*/{}", KEY_ROOT, keys::ALIVE);
    let present = session.liveliness().get(selector).timeout(PRESENT_TIMEOUT).wait().ok().map(|replies| {
        let mut names = std::collections::BTreeSet::new();
        while let Ok(reply) = replies.recv() {
            if let Some(key) = reply.result().ok().and_then(|s| source_key_of(s.key_expr().as_str())) {
                names.insert(short(&key).to_owned());
            }
        }
        let mut names: Vec<String> = names.into_iter().collect();
        if names.len() > MAX_PRESENT {
            let more = names.len() - MAX_PRESENT;
            names.truncate(MAX_PRESENT);
            names.push(format!("and {more} more"));
        }
        names
    });
    SdkError::NoBridge { source_key, waited, present }
}

/// `frond/<stage>/<source>` of a token key `frond/<stage>/<source>/alive`, if the names are
/// plain key chunks.
pub(crate) fn source_key_of(token: &str) -> Option<String> {
    let mut parts = token.split('/');
    let (root, stage, source, leaf) = (parts.next()?, parts.next()?, parts.next()?, parts.next()?);
    if root != KEY_ROOT || leaf != keys::ALIVE || parts.next().is_some() {
        return None;
    }
    check_name("stage", stage).ok()?;
    check_name("source", source).ok()?;
    Some(format!("{KEY_ROOT}/{stage}/{source}"))
}

/// `<stage>/<source>` of a source key `frond/<stage>/<source>`: how a source is named to people.
pub fn short(key: &str) -> &str {
    key.strip_prefix(KEY_ROOT).and_then(|k| k.strip_prefix('/')).unwrap_or(key)
}
