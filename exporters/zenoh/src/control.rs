//! Remote control: the `.../control` queryable (off unless `--control FILE`). Each query is one
//! control request frame signed by a principal of the allow-list file
//! ([`frond_sdk::control_auth`]); the bridge's [`ControlGate`] checks the signature, the issue
//! time, the nonce, what the principal may send and its budget, then the request goes to the
//! daemon's control socket on one worker thread and is answered with the daemon's reply.
//! Refusals are answered, counted ([`crate::BridgeStats::control_refused`]) and logged once per
//! principal and reason. Each principal has its own nonces, rate budget and share of the
//! pending slots, so that one cannot lock out another (see [`gate`]).

use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use frond_protocol::{ControlError, ControlErrorKind, ControlReply, ControlRequest};
use frond_sdk::control_auth::{ControlKey, MAX_ENVELOPE_LEN, check_principal};
use frond_sdk::{ControlClient, ControlClientError};
use serde::Deserialize;
use zenoh::Wait;

use crate::Shared;

pub mod gate;

pub use gate::{
    Admitted, BURST_PER_PRINCIPAL, ControlGate, MAX_NONCES_PER_PRINCIPAL, MAX_PENDING,
    MAX_PENDING_PER_PRINCIPAL, Now, PendingSlot, RATE_PER_PRINCIPAL_HZ, Refusal, RefusalReason,
};

/// Largest allow-list file.
pub const MAX_POLICY_FILE: u64 = 256 * 1024;
/// Most principals in one allow-list.
pub const MAX_PRINCIPALS: usize = 64;
/// Distinct (principal, reason) pairs logged; later new pairs are counted only.
const MAX_LOGGED: usize = 256;

/// Requests a remote peer may never send: testing aids that stall or crash the daemon.
const NEVER_REMOTE: &[&str] = &["freeze-loop", "panic-for-test"];

/// Names an allow-list may use beyond single requests.
const GROUPS: &[(&str, &[&str])] = &[
    ("read", &["status", "raw-sample"]),
    ("record", &["record-start", "record-stop", "mark", "record-layer", "set-triggers"]),
    ("setup", &["set-rig", "set-calibration", "set-filter"]),
    ("stage", &["stage-start", "stage-stop", "stage-input"]),
];

/// Every request a remote peer may send (what `*` means).
fn remote_requests() -> impl Iterator<Item = &'static str> {
    GROUPS.iter().flat_map(|(_, names)| names.iter().copied())
}

// No Debug: a key must not be printable by accident.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPolicy {
    #[serde(default)]
    principal: Vec<RawPrincipal>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPrincipal {
    name: String,
    /// Any TOML value, so that one of the wrong type is refused without serde quoting it.
    key: toml::Value,
    allow: Option<Vec<String>>,
}

/// One principal of the allow-list.
#[derive(Debug, Clone)]
pub struct Principal {
    key: ControlKey,
    /// The request names it may send.
    allowed: HashSet<&'static str>,
}

/// Who may control the daemon remotely, and what each may send: the `--control FILE`.
#[derive(Debug, Clone, Default)]
pub struct ControlPolicy {
    principals: HashMap<String, Principal>,
}

/// Why the allow-list file cannot be used: every problem, each with its place in the file.
#[derive(Debug, thiserror::Error)]
#[error("remote control allow-list {path}:\n  {}", problems.join("\n  "))]
pub struct PolicyError {
    /// The file.
    pub path: String,
    /// What is wrong.
    pub problems: Vec<String>,
}

impl ControlPolicy {
    /// Reads and checks an allow-list file (regular, small, not readable by other users).
    pub fn read(path: &Path) -> Result<ControlPolicy, PolicyError> {
        let fail = |problems| PolicyError { path: path.display().to_string(), problems };
        let text = frond_sdk::control_auth::read_secret_file(
            path,
            MAX_POLICY_FILE,
            "the principals' control keys, secrets",
        )
        .map_err(|e| fail(vec![e.to_string()]))?;
        ControlPolicy::parse(&text).map_err(fail)
    }

    /// Parses an allow-list's text (see the README's "Remote control").
    pub fn parse(text: &str) -> Result<ControlPolicy, Vec<String>> {
        let raw: RawPolicy = toml::from_str(text).map_err(|e| vec![toml_problem(text, &e)])?;
        let mut problems = Vec::new();
        if raw.principal.is_empty() {
            problems.push("no [[principal]]: nobody could use remote control".to_owned());
        }
        if raw.principal.len() > MAX_PRINCIPALS {
            problems.push(format!("{} principals; the limit is {MAX_PRINCIPALS}", raw.principal.len()));
        }
        let mut principals = HashMap::new();
        for (i, p) in raw.principal.iter().enumerate().take(MAX_PRINCIPALS) {
            let at = format!("principal[{i}]");
            if let Err(e) = check_principal(&p.name) {
                problems.push(format!("{at}.name: {e}"));
            }
            let key = match &p.key {
                toml::Value::String(hex) => {
                    ControlKey::from_hex(hex).map_err(|e| problems.push(format!("{at}.key: {e}"))).ok()
                }
                other => {
                    problems.push(format!(
                        "{at}.key: not a string but {}: write the hex key in quotes",
                        other.type_str()
                    ));
                    None
                }
            };
            let mut allowed = HashSet::new();
            for name in p.allow.as_deref().unwrap_or(&["*".to_owned()]) {
                match allow_entry(name) {
                    Ok(names) => allowed.extend(names),
                    Err(e) => problems.push(format!("{at}.allow: {e}")),
                }
            }
            if principals.contains_key(&p.name) {
                problems.push(format!("{at}.name: {:?} is listed twice", p.name));
            }
            if let Some(key) = key {
                principals.insert(p.name.clone(), Principal { key, allowed });
            }
        }
        if problems.is_empty() { Ok(ControlPolicy { principals }) } else { Err(problems) }
    }

    /// How many principals it lists.
    pub fn len(&self) -> usize {
        self.principals.len()
    }

    /// Whether it lists nobody.
    pub fn is_empty(&self) -> bool {
        self.principals.is_empty()
    }
}

/// A TOML error in words and its place, without the line it quotes by default: that line may be
/// a principal's key.
fn toml_problem(text: &str, e: &toml::de::Error) -> String {
    let message = e.message().trim_end();
    match e.span() {
        Some(span) => {
            let before = text.get(..span.start).unwrap_or(text);
            let line = before.matches('\n').count() + 1;
            let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            format!("line {line}, column {column}: {message}")
        }
        None => message.to_owned(),
    }
}

/// An `allow` entry that stands for no request a principal may be given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
enum AllowEntryError {
    /// A request that exists but is never allowed remotely (the name given).
    #[error("{0:?} is a testing aid, never allowed remotely")]
    TestingAid(String),
    /// Neither `*`, a group nor a request (the name given); the text lists what is.
    #[error(
        "unknown request {0:?}; use \"*\", a group ({groups}) or a request ({requests})",
        groups = GROUPS.iter().map(|(g, _)| *g).collect::<Vec<_>>().join(", "),
        requests = remote_requests().collect::<Vec<_>>().join(", ")
    )]
    Unknown(String),
}

/// The request names one `allow` entry stands for.
fn allow_entry(name: &str) -> Result<Vec<&'static str>, AllowEntryError> {
    if name == "*" {
        return Ok(remote_requests().collect());
    }
    if let Some((_, names)) = GROUPS.iter().find(|(group, _)| *group == name) {
        return Ok(names.to_vec());
    }
    if let Some(single) = remote_requests().find(|r| *r == name) {
        return Ok(vec![single]);
    }
    if NEVER_REMOTE.contains(&name) {
        return Err(AllowEntryError::TestingAid(name.to_string()));
    }
    Err(AllowEntryError::Unknown(name.to_string()))
}

/// One accepted request waiting for the daemon.
struct Pending {
    query: zenoh::query::Query,
    /// The request, its principal and the slot it holds until it is answered (dropped).
    admitted: Admitted,
}

/// The queryable and its worker.
pub(crate) struct RemoteControl {
    _queryable: zenoh::query::Queryable<()>,
    worker: Option<std::thread::JoinHandle<()>>,
    /// Dropping it stops the worker.
    tx: Option<crossbeam_channel::Sender<Pending>>,
}

impl Drop for RemoteControl {
    fn drop(&mut self) {
        drop(self.tx.take());
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

/// Logs a refusal the first time its (principal, reason) pair is seen.
struct RefusalLog(Mutex<HashSet<(Option<String>, RefusalReason)>>);

impl RefusalLog {
    fn note(&self, r: &Refusal, key: &str) {
        let mut seen = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        // A name not on the allow-list is the peer's choice: all of them count as one, so that
        // made-up names cannot use up the log's room and silence the principals' refusals.
        let principal = if r.reason == RefusalReason::UnknownPrincipal { None } else { r.principal.clone() };
        let pair = (principal, r.reason);
        if seen.len() < MAX_LOGGED && seen.insert(pair) {
            tracing::warn!(
                %key,
                principal = %r.principal.as_deref().unwrap_or("-"),
                reason = ?r.reason,
                message = %r.error.message,
                "remote control request refused (further refusals like it are counted, not logged)"
            );
        }
    }
}

fn reply_frame(reply: &ControlReply) -> Vec<u8> {
    let mut out = Vec::new();
    frond_protocol::encode_frame(reply, &mut out);
    out
}

fn answer(query: &zenoh::query::Query, reply: &ControlReply) {
    if let Err(e) = query.reply(query.key_expr().clone(), reply_frame(reply)).wait() {
        tracing::debug!(error = %e, "control reply failed");
    }
}

impl RemoteControl {
    /// Declares `<source_key>/control` and starts the worker that talks to the daemon.
    pub(crate) fn start(
        session: &zenoh::Session,
        source_key: &str,
        socket_dir: &Path,
        policy: ControlPolicy,
        shared: Arc<Shared>,
    ) -> Result<RemoteControl, zenoh::Error> {
        let key = frond_sdk::zenoh::keys::under(source_key, frond_sdk::zenoh::keys::CONTROL);
        let (tx, rx) = crossbeam_channel::bounded::<Pending>(MAX_PENDING);
        let gate = ControlGate::new(policy);
        let log = RefusalLog(Mutex::new(HashSet::new()));
        let worker = {
            let socket_dir = socket_dir.to_owned();
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("remote-control".into())
                .spawn(move || work(&rx, &socket_dir, &shared))
                .map_err(|e| zenoh::Error::from(e.to_string()))?
        };
        let tx_cb = tx.clone();
        let key_cb = key.clone();
        let queryable = session
            .declare_queryable(&key)
            .callback(move |query| {
                // Standing by, another bridge owns this name and answers (see `claim`).
                if shared.standing_by() {
                    return;
                }
                let frame = query.payload().map(|p| bounded_copy(p, MAX_FRAME_LEN)).unwrap_or_default();
                let envelope = query.attachment().map(|a| bounded_copy(a, MAX_ENVELOPE_LEN));
                let clock = shared.clock();
                let now =
                    Now { unix_ms: clock.unix_ns / 1_000_000, monotonic_ms: clock.monotonic_ns / 1_000_000 };
                let refused = |r: Refusal| {
                    shared.stats.control_refused.fetch_add(1, Ordering::Relaxed);
                    log.note(&r, &key_cb);
                    answer(&query, &ControlReply::Error(r.error));
                };
                match gate.check(envelope.as_deref(), &key_cb, &frame, now) {
                    Err(r) => refused(r),
                    Ok(admitted) => {
                        let principal = admitted.principal.clone();
                        // The gate holds the pending count to MAX_PENDING, the channel's size, so
                        // this fails only when the worker is gone.
                        if tx_cb.try_send(Pending { query: query.clone(), admitted }).is_err() {
                            refused(Refusal {
                                principal: Some(principal),
                                reason: RefusalReason::Busy,
                                error: ControlError {
                                    kind: ControlErrorKind::Internal,
                                    message: "the bridge's remote control worker has stopped".into(),
                                },
                            });
                        }
                    }
                }
            })
            .wait()?;
        tracing::info!(%key, "remote control on");
        Ok(RemoteControl { _queryable: queryable, worker: Some(worker), tx: Some(tx) })
    }
}

/// The longest request frame.
const MAX_FRAME_LEN: usize = frond_protocol::MAX_CONTROL_REQUEST + frond_protocol::HEADER_LEN;

/// At most `max + 1` bytes of a query's payload or attachment: enough for the gate to refuse a
/// longer one by its length, without a copy of it (Zenoh takes messages of up to 1 GiB by
/// default, and a peer chooses the size).
fn bounded_copy(bytes: &zenoh::bytes::ZBytes, max: usize) -> Vec<u8> {
    use std::io::Read;
    let mut out = Vec::with_capacity(bytes.len().min(max + 1));
    // Reading bytes already in memory cannot fail.
    let _ = bytes.reader().take(max as u64 + 1).read_to_end(&mut out);
    out
}

/// How long the worker waits for the daemon's reply.
const DAEMON_TIMEOUT: Duration = Duration::from_secs(10);

/// Sends one request on the worker's connection, connecting first if there is none. A reused
/// connection that turns out broken (the daemon restarted since) is re-made once; a fresh one
/// never is, so a request is not run twice.
fn ask(
    client: &mut Option<ControlClient>,
    socket_dir: &Path,
    request: &ControlRequest,
) -> Result<ControlReply, ControlClientError> {
    let reused = client.is_some();
    let mut c = match client.take() {
        Some(c) => c,
        None => ControlClient::connect_with_timeout(socket_dir, DAEMON_TIMEOUT)?,
    };
    match c.request(request) {
        Err(ControlClientError::Send { .. } | ControlClientError::Closed { .. }) if reused => {
            ask(client, socket_dir, request)
        }
        // The connection's state is unknown after these: drop it.
        Err(e @ (ControlClientError::Timeout { .. } | ControlClientError::BadReply { .. })) => Err(e),
        other => {
            *client = Some(c);
            other
        }
    }
}

/// The worker: one control-socket connection, one request at a time.
fn work(rx: &crossbeam_channel::Receiver<Pending>, socket_dir: &Path, shared: &Shared) {
    let mut client: Option<ControlClient> = None;
    while let Ok(p) = rx.recv() {
        // `p`, and with it the request's pending slot, is dropped once answered.
        let Admitted { principal, request, .. } = &p.admitted;
        let reply = match ask(&mut client, socket_dir, request) {
            Ok(reply) => reply,
            Err(ControlClientError::Refused { kind, message }) => {
                ControlReply::Error(ControlError { kind, message })
            }
            Err(e) => ControlReply::Error(ControlError {
                kind: ControlErrorKind::Internal,
                message: format!("the bridge could not reach its daemon: {e}"),
            }),
        };
        shared.stats.control_answered.fetch_add(1, Ordering::Relaxed);
        tracing::info!(
            principal = %principal,
            request = request.name(),
            ok = !matches!(reply, ControlReply::Error(_)),
            "remote control request"
        );
        answer(&p.query, &reply);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: &str = "1111111111111111111111111111111111111111111111111111111111111111";

    #[test]
    fn allow_list_problems_are_all_reported_with_their_place() {
        let text = format!(
            "[[principal]]\nname = \"a/b\"\nkey = \"12\"\nallow = [\"record\", \"freeze-loop\", \"fly\"]\n\
             [[principal]]\nname = \"x\"\nkey = \"{KEY}\"\n[[principal]]\nname = \"x\"\nkey = \"{KEY}\"\n"
        );
        let problems = ControlPolicy::parse(&text).unwrap_err();
        let joined = problems.join("\n");
        for needle in [
            "principal[0].name",
            "principal[0].key",
            "principal[0].allow: \"freeze-loop\" is a testing aid",
            "principal[0].allow: unknown request \"fly\"",
            "principal[2].name: \"x\" is listed twice",
        ] {
            assert!(joined.contains(needle), "{needle} missing in:\n{joined}");
        }
        assert!(ControlPolicy::parse("").unwrap_err()[0].contains("no [[principal]]"));
        assert!(ControlPolicy::parse("[[principal]]\nname=\"a\"\nkey=\"00\"\ncolour=1\n").is_err());
    }

    #[test]
    fn allow_list_errors_never_quote_a_key() {
        // Each a mistake on a key's line; TOML's own message would quote the line.
        let secret = "5ec7e75ec7e75ec7e75ec7e75ec7e75ec7e75ec7e75ec7e75ec7e75ec7e75ec7";
        let digits = "2718281828459045235360287471352662497757247093699959574966967627";
        for text in [
            format!("[[principal]]\nname = \"a\"\nkey = \"{secret}\n"),
            format!("[[principal]]\nname = \"a\"\nkey = {secret}\n"),
            format!("[[principal]]\nname = \"a\"\nkey = \"{secret}\" \"{secret}\"\n"),
            format!("[[principal]]\nname = \"a\"\nkey = \"{secret}\"\nkey = \"{secret}\"\n"),
            format!("[[principal]]\nname = \"a\"\nkey = \"{}zz\"\n", &secret[..62]),
            // Keys of the wrong type, which serde would quote: an integer, a float, an array.
            format!("[[principal]]\nname = \"a\"\nkey = {}\n", &digits[..18]),
            format!("[[principal]]\nname = \"a\"\nkey = {digits}\n"),
            format!("[[principal]]\nname = \"a\"\nkey = {}.5\n", &digits[..18]),
            format!("[[principal]]\nname = \"a\"\nkey = [{}]\n", &digits[..18]),
        ] {
            let problems = ControlPolicy::parse(&text).unwrap_err().join("\n");
            assert!(
                !problems.contains(&secret[..6]) && !problems.contains(&digits[..6]),
                "a key in the message:\n{problems}"
            );
            assert!(problems.starts_with("line ") || problems.contains("principal[0].key"), "{problems}");
        }
    }

    #[test]
    fn an_allow_list_its_group_or_others_may_read_or_change_is_refused_with_the_fix() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("control.toml");
        std::fs::write(&path, format!("[[principal]]\nname = \"director\"\nkey = \"{KEY}\"\n")).unwrap();
        let shown = path.display().to_string();
        for (mode, who) in [
            (0o640, "its group may read it"),
            (0o644, "its group and other users may read it"),
            (0o620, "its group may change it"),
            (0o602, "other users may change it"),
        ] {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
            let e = ControlPolicy::read(&path).unwrap_err().to_string();
            assert!(
                e.contains(&format!(
                    "{shown}: mode {mode:03o}: {who}; it holds the principals' control keys, secrets: \
                     chmod 600 {shown}"
                )),
                "{e}"
            );
            assert!(!e.contains(&KEY[..8]), "{e}");
        }
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(ControlPolicy::read(&path).unwrap().len(), 1);
    }

    #[test]
    fn no_debug_output_of_a_policy_prints_a_key() {
        let policy =
            ControlPolicy::parse(&format!("[[principal]]\nname = \"director\"\nkey = \"{KEY}\"\n")).unwrap();
        let shown = format!("{policy:?}");
        assert!(shown.contains("director") && !shown.contains(&KEY[..8]), "{shown}");
    }

    #[test]
    fn a_query_is_copied_no_further_than_the_gate_needs_to_refuse_it() {
        let big = zenoh::bytes::ZBytes::from(vec![7u8; 1 << 20]);
        assert_eq!(bounded_copy(&big, 100), vec![7u8; 101], "one byte past the limit");
        let small = zenoh::bytes::ZBytes::from(vec![1u8, 2, 3]);
        assert_eq!(bounded_copy(&small, 100), vec![1, 2, 3]);
        assert_eq!(bounded_copy(&zenoh::bytes::ZBytes::default(), 100), Vec::<u8>::new());
    }

    #[test]
    fn star_means_every_remote_request_and_nothing_else() {
        let all = allow_entry("*").unwrap();
        // ControlRequest's 15 requests but the two testing aids.
        assert_eq!(all.len(), 13);
        assert!(all.contains(&"set-triggers"), "following a stage's triggers is the record group's");
        for never in NEVER_REMOTE {
            assert!(!all.contains(never));
        }
    }
}
