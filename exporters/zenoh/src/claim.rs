//! One bridge per source name. Two bridges started under the same `frond/<stage>/<source>` (two
//! daemons on one host both defaulting to the host's name, or a copied configuration) would
//! interleave two daemons' poses under one key, and every subscriber would see the sequence
//! numbers go backwards. So each bridge holds a claim on its name, a liveliness token
//! `frond/<stage>/<source>/bridge/<id>` whose id is its start time (Unix milliseconds, 13
//! digits) and its Zenoh id, and watches the claims of others on the same name. The elder
//! claim (the smaller id) publishes; a younger one stands by, publishing and answering nothing
//! and withdrawing its `alive` token, and takes over when the elder's claim goes (that bridge
//! stopped, or its host left the network). Both sides rank the same two ids the same way, so
//! they agree without talking; a stale claim (a host whose link went down) only delays a
//! younger bridge until Zenoh drops it.

use std::collections::BTreeSet;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use frond_sdk::zenoh::keys;
use zenoh::Wait;
use zenoh::sample::SampleKind;

use crate::Shared;

/// Most other claims tracked (a flood of tokens from a hostile peer cannot grow the set).
const MAX_OTHERS: usize = 64;

/// A bridge's claim id: its start time and Zenoh id, ordered so that the elder sorts first.
pub(crate) fn claim_id(started_unix_ms: u64, zid: &str) -> String {
    format!("{started_unix_ms:013}-{zid}")
}

/// The claim id in a token key `<source_key>/bridge/<id>`, if it is one: 13 digits, `-`, and a
/// Zenoh id in lower-case hex.
pub(crate) fn id_of(token_key: &str, source_key: &str) -> Option<String> {
    let id = token_key
        .strip_prefix(source_key)?
        .strip_prefix('/')?
        .strip_prefix(keys::BRIDGE)?
        .strip_prefix('/')?;
    let (ms, zid) = id.split_once('-')?;
    let hex = |c: char| c.is_ascii_digit() || ('a'..='f').contains(&c);
    let ok = ms.len() == 13
        && ms.chars().all(|c| c.is_ascii_digit())
        && (1..=32).contains(&zid.len())
        && zid.chars().all(hex);
    ok.then(|| id.to_owned())
}

/// The claims of the other bridges on this name, and what they make of this one.
#[derive(Debug)]
pub(crate) struct Claims {
    own: String,
    others: BTreeSet<String>,
}

/// What a change in the claims means for this bridge.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Turn {
    /// An elder claim appeared: stand by. Names the elder.
    StandBy(String),
    /// No elder claim is left: publish again.
    Resume,
    /// A younger bridge appeared under this name (it stands by). Names it.
    Younger(String),
    /// Nothing this bridge must act on.
    Same,
}

impl Claims {
    pub(crate) fn new(own: String) -> Claims {
        Claims { own, others: BTreeSet::new() }
    }

    /// The elder claim this bridge yields to, if any.
    pub(crate) fn elder(&self) -> Option<&String> {
        self.others.first().filter(|first| **first < self.own)
    }

    /// Applies a claim that appeared (`put`) or went away.
    pub(crate) fn apply(&mut self, id: String, put: bool) -> Turn {
        if id == self.own {
            return Turn::Same;
        }
        let before = self.elder().cloned();
        let younger = put && id > self.own;
        let changed = if put {
            // Full: an elder claim still gets in, in the place of the youngest.
            if self.others.len() >= MAX_OTHERS && !self.others.contains(&id) {
                if self.others.last().is_some_and(|last| id < *last) {
                    self.others.pop_last();
                } else {
                    return Turn::Same;
                }
            }
            self.others.insert(id.clone())
        } else {
            self.others.remove(&id)
        };
        match (before, self.elder().cloned()) {
            (None, Some(elder)) => Turn::StandBy(elder),
            (Some(_), None) => Turn::Resume,
            (None, None) if younger && changed => Turn::Younger(id),
            _ => Turn::Same,
        }
    }
}

/// The Zenoh id and age of a claim id, for people (the age by this host's clock).
pub(crate) fn describe(id: &str, now_unix_ms: u64) -> String {
    let (ms, zid) = id.split_once('-').unwrap_or((id, "?"));
    let ms: u64 = ms.parse().unwrap_or(0);
    let age_s = now_unix_ms.saturating_sub(ms) as f64 / 1000.0;
    format!("Zenoh id {zid}, started {age_s:.1} s ago")
}

fn now_ms() -> u64 {
    frond_sdk::stage_time::realtime_ns() / 1_000_000
}

/// How long a starting bridge told to `--connect` waits for a link before asking for claims.
const LINK_WAIT: Duration = Duration::from_secs(2);
/// How long a starting bridge waits for the claims already on the network.
const ASK_TIMEOUT: Duration = Duration::from_secs(1);

/// A bridge's claim on its name: its token, and the subscriber that watches the others.
pub(crate) struct Claim {
    _token: zenoh::liveliness::LivelinessToken,
    _watch: zenoh::pubsub::Subscriber<()>,
}

/// The claims seen so far, and what to do on a turn.
struct Watch {
    claims: Mutex<Claims>,
    source_key: String,
    shared: Arc<Shared>,
}

impl Watch {
    /// A claim token appeared (`put`) or went: sets `standby` and logs the turn, once.
    fn on(&self, token_key: &str, put: bool) {
        let Some(id) = id_of(token_key, &self.source_key) else { return };
        let turn = self.claims.lock().unwrap_or_else(PoisonError::into_inner).apply(id, put);
        let key = &self.source_key;
        match turn {
            Turn::StandBy(elder) => {
                self.shared.standby.store(true, Ordering::Relaxed);
                tracing::error!(
                    %key,
                    other = %describe(&elder, now_ms()),
                    "another frond-zenoh already publishes under this name: this one stands by, \
                     publishing nothing, until that one stops. Give each bridge its own --source"
                );
            }
            Turn::Resume => {
                self.shared.standby.store(false, Ordering::Relaxed);
                tracing::info!(%key, "the other frond-zenoh under this name is gone: publishing");
            }
            Turn::Younger(id) => tracing::warn!(
                %key,
                other = %describe(&id, now_ms()),
                "a second frond-zenoh started under this name; it stands by while this one runs"
            ),
            Turn::Same => {}
        }
    }
}

impl Claim {
    /// Declares this bridge's claim on `source_key` (started now) and watches the others' (their
    /// history included), setting `shared.standby` while an elder claim is on the network.
    /// Returns once the claims already on the network have answered (at most [`ASK_TIMEOUT`]),
    /// so that a bridge started under a taken name stands by before it publishes anything.
    /// `connects`: the session was told to connect somewhere (`--connect`), which Zenoh does in
    /// the background; the claims are asked for once a link is up (or after [`LINK_WAIT`]).
    pub(crate) fn declare(
        session: &zenoh::Session,
        source_key: &str,
        shared: Arc<Shared>,
        connects: bool,
    ) -> Result<Claim, zenoh::Error> {
        let own = claim_id(now_ms(), &session.zid().to_string());
        if connects {
            let deadline = std::time::Instant::now() + LINK_WAIT;
            let linked = || {
                let info = session.info();
                info.peers_zid().wait().next().is_some() || info.routers_zid().wait().next().is_some()
            };
            while !linked() && std::time::Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        let claims_key = keys::under(source_key, keys::BRIDGE);
        let watch = Arc::new(Watch {
            claims: Mutex::new(Claims::new(own.clone())),
            source_key: source_key.to_owned(),
            shared,
        });
        let on_sample = Arc::clone(&watch);
        let subscriber = session
            .liveliness()
            .declare_subscriber(format!("{claims_key}/*"))
            .history(true)
            .callback(move |sample| {
                on_sample.on(sample.key_expr().as_str(), sample.kind() == SampleKind::Put)
            })
            .wait()?;
        let replies = session.liveliness().get(format!("{claims_key}/*")).timeout(ASK_TIMEOUT).wait()?;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                watch.on(sample.key_expr().as_str(), true);
            }
        }
        let token = session.liveliness().declare_token(format!("{claims_key}/{own}")).wait()?;
        Ok(Claim { _token: token, _watch: subscriber })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: &str = "frond/s1/glove-a";

    #[test]
    fn claim_ids_sort_elder_first_and_parse_back() {
        let a = claim_id(1_764_000_000_000, "9f");
        let b = claim_id(1_764_000_000_001, "1a");
        assert!(a < b, "{a} {b}");
        // Same millisecond: the Zenoh id decides, the same way on both sides.
        assert!(claim_id(5, "1a") < claim_id(5, "9f"));
        assert_eq!(id_of(&format!("{KEY}/bridge/{a}"), KEY), Some(a.clone()));
        for bad in [
            format!("{KEY}/alive"),
            format!("{KEY}/bridge/{a}/x"),
            format!("frond/s1/glove-b/bridge/{a}"),
            format!("{KEY}/bridge/123-9f"),
            format!("{KEY}/bridge/1764000000000-XYZ"),
            format!("{KEY}/bridge/1764000000000-"),
            format!("{KEY}/bridge/1764000000000-{}", "a".repeat(33)),
        ] {
            assert_eq!(id_of(&bad, KEY), None, "{bad}");
        }
    }

    #[test]
    fn a_claim_is_described_by_its_zenoh_id_and_age() {
        assert_eq!(describe(&claim_id(10_000, "9f"), 12_500), "Zenoh id 9f, started 2.5 s ago");
        assert_eq!(
            describe(&claim_id(10_000, "9f"), 9_000),
            "Zenoh id 9f, started 0.0 s ago",
            "clocks apart"
        );
    }

    #[test]
    fn a_younger_bridge_stands_by_until_the_elder_goes() {
        let (elder, me, younger) = (claim_id(1, "aa"), claim_id(2, "bb"), claim_id(3, "cc"));
        let mut claims = Claims::new(me.clone());
        assert_eq!(claims.apply(me.clone(), true), Turn::Same, "its own claim");
        assert_eq!(claims.apply(younger.clone(), true), Turn::Younger(younger.clone()));
        assert_eq!(claims.apply(younger.clone(), true), Turn::Same, "told once");
        assert_eq!(claims.apply(elder.clone(), true), Turn::StandBy(elder.clone()));
        assert_eq!(claims.apply(younger.clone(), false), Turn::Same);
        assert_eq!(claims.apply(elder.clone(), false), Turn::Resume);
        assert_eq!(claims.elder(), None);
        // A claim that goes before it came (Zenoh's history and a delete crossing) changes nothing.
        assert_eq!(claims.apply(claim_id(0, "ff"), false), Turn::Same);
    }

    #[test]
    fn two_elders_release_only_when_both_are_gone() {
        let me = claim_id(10, "bb");
        let mut claims = Claims::new(me);
        assert_eq!(claims.apply(claim_id(1, "aa"), true), Turn::StandBy(claim_id(1, "aa")));
        assert_eq!(claims.apply(claim_id(2, "aa"), true), Turn::Same);
        assert_eq!(claims.apply(claim_id(1, "aa"), false), Turn::Same, "one elder is left");
        assert_eq!(claims.apply(claim_id(2, "aa"), false), Turn::Resume);
    }

    #[test]
    fn a_flood_of_claims_is_bounded() {
        let mut claims = Claims::new(claim_id(0, "00"));
        for i in 0..10_000u64 {
            claims.apply(claim_id(i + 1, "ab"), true);
        }
        assert_eq!(claims.others.len(), MAX_OTHERS);
        assert_eq!(claims.elder(), None, "all younger");
        // An elder still gets in, and its going is still seen.
        let mut claims = Claims::new(claim_id(5_000, "00"));
        for i in 0..10_000u64 {
            claims.apply(claim_id(10_000 + i, "ab"), true);
        }
        assert_eq!(claims.apply(claim_id(1, "ab"), true), Turn::StandBy(claim_id(1, "ab")));
        assert_eq!(claims.others.len(), MAX_OTHERS);
        assert_eq!(claims.apply(claim_id(1, "ab"), false), Turn::Resume);
    }
}
