//! The bridge's queryables: what a late joiner asks for (`hello`, `elements`, `fields`,
//! `status`, `clock`), the `replay` ring and the `peers` reports, answered from what the bridge
//! last saw ([`Latest`]) and nothing while it stands by.

use std::sync::Arc;
use std::sync::atomic::Ordering;

use frond_protocol::field::{FieldMessage, FieldTable};
use frond_protocol::{Hello, ServerMessage};
use frond_sdk::zenoh::keys;
use frond_sdk::zenoh_replay::{self, ReplayRequest};
use zenoh::Wait;

use crate::{BridgeError, Shared, declare_err};

/// The latest values the queryables answer with.
#[derive(Default)]
pub(crate) struct Latest {
    /// The daemon's hello while connected (its `next_seq` is overwritten when answering).
    pub(crate) hello: Option<Hello>,
    /// The last status frame.
    pub(crate) status: Option<Vec<u8>>,
    /// The daemon's last field table since its hello (`None`: none yet, so no field runs).
    pub(crate) fields: Option<FieldTable>,
}

/// Declares every queryable of the bridge under `key`.
pub(crate) fn declare(
    session: &zenoh::Session,
    key: &str,
    shared: &Arc<Shared>,
) -> Result<Vec<zenoh::query::Queryable<()>>, BridgeError> {
    let mut queryables = Vec::new();
    for leaf in [keys::HELLO, keys::ELEMENTS, keys::FIELDS, keys::STATUS, keys::CLOCK] {
        let k = keys::under(key, leaf);
        let shared = shared.clone();
        let reply_key = k.clone();
        let q = session
            .declare_queryable(k.clone())
            .callback(move |query| {
                if shared.standing_by() {
                    return;
                }
                let bytes = if leaf == keys::CLOCK {
                    Some(shared.clock().to_json().into_bytes())
                } else {
                    answer(&shared.latest(), shared.next_seq.load(Ordering::Relaxed), leaf)
                };
                if let Some(bytes) = bytes {
                    shared.stats.queries.fetch_add(1, Ordering::Relaxed);
                    if let Err(e) = query.reply(reply_key.clone(), bytes).wait() {
                        tracing::debug!(error = %e, "reply failed");
                    }
                }
            })
            .wait()
            .map_err(declare_err(&k))?;
        queryables.push(q);
    }
    let replay_key = keys::under(key, zenoh_replay::REPLAY);
    let replay = {
        let (shared, reply_key) = (shared.clone(), replay_key.clone());
        session
            .declare_queryable(replay_key.clone())
            .callback(move |query| shared.on_replay(&query, &reply_key))
            .wait()
            .map_err(declare_err(&replay_key))?
    };
    queryables.push(replay);
    let peers_key = keys::under(key, zenoh_replay::PEERS);
    let peers = {
        let (shared, reply_key) = (shared.clone(), peers_key.clone());
        session
            .declare_queryable(peers_key.clone())
            .callback(move |query| {
                if shared.standing_by() {
                    return;
                }
                let json = serde_json::to_vec(&shared.stats.peers.reports()).unwrap_or_default();
                if let Err(e) = query.reply(reply_key.clone(), json).wait() {
                    tracing::debug!(error = %e, "reply failed");
                }
            })
            .wait()
            .map_err(declare_err(&peers_key))?
    };
    queryables.push(peers);
    Ok(queryables)
}

impl Shared {
    /// A `replay` query: its poses answered from the ring (with the query's own congestion
    /// control, so a full link drops them instead of blocking), its counts kept.
    fn on_replay(&self, query: &zenoh::query::Query, reply_key: &str) {
        if self.standing_by() {
            return;
        }
        let Some(request) = query.payload().and_then(|p| ReplayRequest::decode(&p.to_bytes())) else {
            return;
        };
        let mut replayed = 0;
        if !request.report_only() {
            let (replies, poses) = self.ring().answer(request.from, request.to);
            replayed = poses;
            for (payload, attachment) in replies {
                if let Err(e) = query.reply(reply_key, payload).attachment(attachment).wait() {
                    tracing::debug!(error = %e, "replay reply failed");
                }
            }
            self.stats.replayed.fetch_add(poses, Ordering::Relaxed);
        }
        let more = self.stats.peers.heard(&request, replayed);
        if more > 0 && self.stats.peers.log_due() {
            tracing::warn!(
                peer = %request.peer, missing = request.missing, recovered = request.recovered,
                frames = request.frames,
                "a subscriber lost poses on the way (its link or its reading could not keep up)"
            );
        }
    }
}

/// The frame a queryable answers with, if it has one.
fn answer(latest: &Latest, next_seq: u64, leaf: &str) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    match leaf {
        keys::HELLO => {
            let hello = Hello { next_seq, ..latest.hello.clone()? };
            frond_protocol::encode_frame(&ServerMessage::Hello(hello), &mut out);
        }
        keys::ELEMENTS => {
            let table = latest.hello.as_ref()?.elements.clone();
            frond_protocol::encode_frame(&ServerMessage::Elements(table), &mut out);
        }
        // No table since the hello: no field runs (the daemon follows its hello with one if
        // any does), which an empty table of the hello's element table says.
        keys::FIELDS => {
            let hello = latest.hello.as_ref()?;
            let table = latest.fields.clone().unwrap_or_else(|| FieldTable {
                elements_version: hello.elements.version,
                fields: Vec::new(),
            });
            frond_protocol::encode_frame(&ServerMessage::Field(FieldMessage::Table(table)), &mut out);
        }
        keys::STATUS => return latest.status.clone(),
        _ => return None,
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_protocol::ElementTable;

    #[test]
    fn queryables_answer_only_what_they_have() {
        let mut latest = Latest::default();
        assert!(answer(&latest, 0, keys::HELLO).is_none());
        assert!(answer(&latest, 0, keys::ELEMENTS).is_none());
        assert!(answer(&latest, 0, keys::FIELDS).is_none());
        assert!(answer(&latest, 0, keys::STATUS).is_none());
        latest.hello = Some(Hello {
            protocol_version: frond_protocol::PROTOCOL_VERSION,
            daemon_version: "test".into(),
            rig_name: "grass".into(),
            joint_names: vec!["root".into()],
            tick_rate_hz: 1000,
            elements: ElementTable::default(),
            next_seq: 3,
        });
        let bytes = answer(&latest, 42, keys::HELLO).unwrap();
        let (msg, used) = frond_protocol::decode_frame::<ServerMessage>(&bytes).unwrap().unwrap();
        assert_eq!(used, bytes.len());
        match msg {
            ServerMessage::Hello(h) => assert_eq!((h.rig_name.as_str(), h.next_seq), ("grass", 42)),
            other => panic!("{other:?}"),
        }
        assert!(answer(&latest, 42, "poses").is_none());
        // Fields: an empty table of the hello's elements until the daemon sends one, then it.
        let fields = |latest: &Latest| {
            let bytes = answer(latest, 42, keys::FIELDS).unwrap();
            match frond_protocol::decode_frame::<ServerMessage>(&bytes).unwrap().unwrap().0 {
                ServerMessage::Field(FieldMessage::Table(t)) => t,
                other => panic!("{other:?}"),
            }
        };
        latest.hello.as_mut().unwrap().elements.version = 7;
        assert_eq!(fields(&latest), FieldTable { elements_version: 7, fields: vec![] });
        let table = FieldTable { elements_version: 8, fields: vec![] };
        latest.fields = Some(table.clone());
        assert_eq!(fields(&latest), table);
    }
}
