//! Remote control: the `.../control` queryable (off unless `--control FILE`). Each query is one
//! control request frame signed by a principal of the allow-list file
//! ([`frond_sdk::control_auth`]); the bridge checks the signature, the issue time, the nonce and
//! what the principal may send, then hands the request to the daemon's control socket on one
//! worker thread and answers with the daemon's reply. Refusals are answered, counted
//! ([`crate::BridgeStats::control_refused`]) and logged once per principal and reason.

use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use frond_protocol::{ControlError, ControlErrorKind, ControlReply, ControlRequest, MAX_CONTROL_REQUEST};
use frond_sdk::control_auth::{ControlKey, Envelope, MAX_ENVELOPE_LEN, MAX_REQUEST_AGE, check_principal};
use frond_sdk::{ControlClient, ControlClientError};
use serde::Deserialize;
use zenoh::Wait;

use crate::Shared;

/// Largest allow-list file.
pub const MAX_POLICY_FILE: u64 = 256 * 1024;
/// Most principals in one allow-list.
pub const MAX_PRINCIPALS: usize = 64;
/// Requests accepted but not yet answered by the daemon; more are refused as busy. The control
/// socket serves at most 16 clients at once; the bridge is one of them.
pub const MAX_PENDING: usize = 16;
/// Nonces remembered (accepted requests within [`MAX_REQUEST_AGE`]); when full, requests are
/// refused as busy until old ones expire: at most this many remote requests a minute.
pub const MAX_NONCES: usize = 4096;
/// Distinct (principal, reason) pairs logged; later new pairs are counted only.
const MAX_LOGGED: usize = 256;

/// Requests a remote peer may never send: testing aids that stall or crash the daemon.
const NEVER_REMOTE: &[&str] = &["freeze-loop", "panic-for-test"];

/// Names an allow-list may use beyond single requests.
const GROUPS: &[(&str, &[&str])] = &[
    ("read", &["status", "raw-sample"]),
    ("record", &["record-start", "record-stop", "mark", "record-layer"]),
    ("setup", &["set-rig", "set-calibration", "set-filter"]),
    ("stage", &["stage-start", "stage-stop", "stage-input"]),
];

/// Every request a remote peer may send (what `*` means).
fn remote_requests() -> impl Iterator<Item = &'static str> {
    GROUPS.iter().flat_map(|(_, names)| names.iter().copied())
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPolicy {
    #[serde(default)]
    principal: Vec<RawPrincipal>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPrincipal {
    name: String,
    key: String,
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
        let text = frond_sdk::control_auth::read_secret_file(path, MAX_POLICY_FILE)
            .map_err(|e| fail(vec![e.to_string()]))?;
        ControlPolicy::parse(&text).map_err(fail)
    }

    /// Parses an allow-list's text (see the README's "Remote control").
    pub fn parse(text: &str) -> Result<ControlPolicy, Vec<String>> {
        let raw: RawPolicy = toml::from_str(text).map_err(|e| vec![e.to_string()])?;
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
            let key = ControlKey::from_hex(&p.key).map_err(|e| problems.push(format!("{at}.key: {e}"))).ok();
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

/// The request names one `allow` entry stands for.
fn allow_entry(name: &str) -> Result<Vec<&'static str>, String> {
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
        return Err(format!("{name:?} is a testing aid, never allowed remotely"));
    }
    let groups: Vec<&str> = GROUPS.iter().map(|(g, _)| *g).collect();
    Err(format!(
        "unknown request {name:?}; use \"*\", a group ({}) or a request ({})",
        groups.join(", "),
        remote_requests().collect::<Vec<_>>().join(", ")
    ))
}

/// Why a request was refused, as it is counted and logged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RefusalReason {
    /// No envelope, or one that does not parse.
    Unsigned,
    /// The principal is not on the allow-list.
    UnknownPrincipal,
    /// The signature is wrong (wrong key, or the request was altered).
    BadSignature,
    /// Issued too long ago or too far ahead of the bridge's clock.
    Stale,
    /// A nonce already accepted.
    Replay,
    /// The principal may not send this request.
    NotAllowed,
    /// The request frame does not decode or is too large.
    BadRequest,
    /// Too many requests at once.
    Busy,
}

/// A refusal: the reply and what to count.
#[derive(Debug, Clone)]
pub struct Refusal {
    /// Who claimed to send it (unverified unless the reason is `NotAllowed`, `Replay` or `Busy`).
    pub principal: Option<String>,
    /// Why.
    pub reason: RefusalReason,
    /// The error answered.
    pub error: ControlError,
}

fn refusal(
    principal: Option<&str>,
    reason: RefusalReason,
    kind: ControlErrorKind,
    message: String,
) -> Refusal {
    Refusal { principal: principal.map(str::to_owned), reason, error: ControlError { kind, message } }
}

/// Checks signed requests against a [`ControlPolicy`], remembering accepted nonces.
pub struct ControlGate {
    policy: ControlPolicy,
    /// Accepted nonces and their issue times (ms).
    nonces: Mutex<HashMap<[u8; 16], u64>>,
}

impl ControlGate {
    /// A gate for `policy`.
    pub fn new(policy: ControlPolicy) -> ControlGate {
        ControlGate { policy, nonces: Mutex::new(HashMap::new()) }
    }

    /// Checks one query: `envelope` is its attachment, `frame` its payload, `key_expr` the key
    /// it was addressed to, `now_unix_ms` the bridge's clock. On success, who sent which request.
    pub fn check(
        &self,
        envelope: Option<&[u8]>,
        key_expr: &str,
        frame: &[u8],
        now_unix_ms: u64,
    ) -> Result<(String, ControlRequest), Refusal> {
        use ControlErrorKind::{BadRequest, Internal, PermissionDenied};
        let unauthenticated = "not authenticated: ";
        let bytes = envelope.ok_or_else(|| {
            refusal(
                None,
                RefusalReason::Unsigned,
                PermissionDenied,
                format!("{unauthenticated}unsigned request"),
            )
        })?;
        if bytes.len() > MAX_ENVELOPE_LEN {
            return Err(refusal(
                None,
                RefusalReason::Unsigned,
                PermissionDenied,
                format!("{unauthenticated}oversized envelope"),
            ));
        }
        let env = Envelope::decode(bytes).map_err(|e| {
            refusal(None, RefusalReason::Unsigned, PermissionDenied, format!("{unauthenticated}{e}"))
        })?;
        let name = env.principal.as_str();
        // The same answer for an unknown name and a wrong key: a peer learns nothing from it.
        let bad = || {
            format!(
                "{unauthenticated}unknown principal or wrong key for {name:?} (see the bridge's --control file)"
            )
        };
        let Some(principal) = self.policy.principals.get(name) else {
            return Err(refusal(Some(name), RefusalReason::UnknownPrincipal, PermissionDenied, bad()));
        };
        if frame.len() > MAX_CONTROL_REQUEST + frond_protocol::HEADER_LEN {
            return Err(refusal(
                Some(name),
                RefusalReason::BadRequest,
                BadRequest,
                "request too large".into(),
            ));
        }
        if !env.verify(&principal.key, key_expr, frame) {
            return Err(refusal(Some(name), RefusalReason::BadSignature, PermissionDenied, bad()));
        }
        let window = MAX_REQUEST_AGE.as_millis() as u64;
        if env.issued_unix_ms.abs_diff(now_unix_ms) > window {
            return Err(refusal(
                Some(name),
                RefusalReason::Stale,
                PermissionDenied,
                format!(
                    "{unauthenticated}issued {} ms from this host's clock; at most {window} ms is accepted \
                     (are the hosts' clocks set, e.g. by NTP?)",
                    env.issued_unix_ms as i128 - now_unix_ms as i128
                ),
            ));
        }
        {
            let mut nonces = self.nonces.lock().unwrap_or_else(PoisonError::into_inner);
            if nonces.contains_key(&env.nonce) {
                return Err(refusal(
                    Some(name),
                    RefusalReason::Replay,
                    PermissionDenied,
                    "replayed request".into(),
                ));
            }
            if nonces.len() >= MAX_NONCES {
                nonces.retain(|_, issued| issued.abs_diff(now_unix_ms) <= window);
            }
            if nonces.len() >= MAX_NONCES {
                return Err(refusal(
                    Some(name),
                    RefusalReason::Busy,
                    Internal,
                    format!("more than {MAX_NONCES} remote requests within {window} ms; try again later"),
                ));
            }
            nonces.insert(env.nonce, env.issued_unix_ms);
        }
        let request = match frond_protocol::decode_frame::<ControlRequest>(frame) {
            Ok(Some((req, used))) if used == frame.len() => req,
            Ok(_) => {
                return Err(refusal(
                    Some(name),
                    RefusalReason::BadRequest,
                    BadRequest,
                    "not one request frame".into(),
                ));
            }
            Err(e) => return Err(refusal(Some(name), RefusalReason::BadRequest, BadRequest, e.to_string())),
        };
        if !principal.allowed.contains(request.name()) {
            return Err(refusal(
                Some(name),
                RefusalReason::NotAllowed,
                PermissionDenied,
                format!("{name:?} may not send {} remotely (the bridge's --control file)", request.name()),
            ));
        }
        Ok((name.to_owned(), request))
    }
}

/// One accepted request waiting for the daemon.
struct Pending {
    query: zenoh::query::Query,
    principal: String,
    request: ControlRequest,
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
        let pair = (r.principal.clone(), r.reason);
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
                let frame = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
                let envelope = query.attachment().map(|a| a.to_bytes().into_owned());
                let now_ms = shared.clock().unix_ns / 1_000_000;
                let refused = |r: Refusal| {
                    shared.stats.control_refused.fetch_add(1, Ordering::Relaxed);
                    log.note(&r, &key_cb);
                    answer(&query, &ControlReply::Error(r.error));
                };
                match gate.check(envelope.as_deref(), &key_cb, &frame, now_ms) {
                    Err(r) => refused(r),
                    Ok((principal, request)) => {
                        let pending = Pending { query: query.clone(), principal: principal.clone(), request };
                        if tx_cb.try_send(pending).is_err() {
                            refused(refusal(
                                Some(&principal),
                                RefusalReason::Busy,
                                ControlErrorKind::Internal,
                                format!("{MAX_PENDING} remote requests are already waiting; try again"),
                            ));
                        }
                    }
                }
            })
            .wait()?;
        tracing::info!(%key, "remote control on");
        Ok(RemoteControl { _queryable: queryable, worker: Some(worker), tx: Some(tx) })
    }
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
        let reply = match ask(&mut client, socket_dir, &p.request) {
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
            principal = %p.principal,
            request = p.request.name(),
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
    const WRONG: &str = "2222222222222222222222222222222222222222222222222222222222222222";
    const AT: &str = "frond/s/g/control";

    fn policy() -> ControlPolicy {
        ControlPolicy::parse(&format!(
            "[[principal]]\nname = \"director\"\nkey = \"{KEY}\"\n\n\
             [[principal]]\nname = \"viewer\"\nkey = \"{KEY}\"\nallow = [\"read\"]\n"
        ))
        .unwrap()
    }

    fn signed(
        name: &str,
        key: &str,
        at: &str,
        issued: u64,
        nonce: u8,
        req: &ControlRequest,
    ) -> (Vec<u8>, Vec<u8>) {
        let mut frame = Vec::new();
        frond_protocol::encode_frame(req, &mut frame);
        let env = Envelope::sign(&ControlKey::from_hex(key).unwrap(), name, at, issued, [nonce; 16], &frame)
            .unwrap();
        (env.encode(), frame)
    }

    #[test]
    fn a_signed_allowed_request_passes_once() {
        let gate = ControlGate::new(policy());
        let req = ControlRequest::Mark { label: "take 2".into() };
        let (env, frame) = signed("director", KEY, AT, 1_000_000, 1, &req);
        let (who, got) = gate.check(Some(&env), AT, &frame, 1_000_500).unwrap();
        assert_eq!((who.as_str(), got), ("director", req));
        let again = gate.check(Some(&env), AT, &frame, 1_000_600).unwrap_err();
        assert_eq!(again.reason, RefusalReason::Replay);
    }

    #[test]
    fn every_kind_of_bad_request_is_refused_with_its_reason() {
        let gate = ControlGate::new(policy());
        let status = ControlRequest::Status;
        let now = 5_000_000;
        let reason =
            |env: Option<&[u8]>, at: &str, frame: &[u8]| gate.check(env, at, frame, now).unwrap_err().reason;
        let (_, frame) = signed("director", KEY, AT, now, 1, &status);
        assert_eq!(reason(None, AT, &frame), RefusalReason::Unsigned);
        assert_eq!(reason(Some(&[1, 2, 3]), AT, &frame), RefusalReason::Unsigned);
        let (env, frame) = signed("director", WRONG, AT, now, 2, &status);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::BadSignature);
        let (env, frame) = signed("stranger", KEY, AT, now, 3, &status);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::UnknownPrincipal);
        let (env, frame) = signed("director", KEY, "frond/s/other/control", now, 4, &status);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::BadSignature, "signed for another source");
        let (env, frame) = signed("director", KEY, AT, now - 30_001, 5, &status);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::Stale);
        let (env, frame) = signed("director", KEY, AT, now + 30_001, 6, &status);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::Stale);
        let (env, frame) = signed("viewer", KEY, AT, now, 7, &ControlRequest::RecordStop);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::NotAllowed);
        let (env, frame) = signed("viewer", KEY, AT, now, 8, &status);
        assert!(gate.check(Some(&env), AT, &frame, now).is_ok(), "viewer may read");
        let (env, frame) = signed("director", KEY, AT, now, 9, &ControlRequest::PanicForTest);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::NotAllowed, "testing aids never pass");
        // A valid signature over bytes that are not a request.
        let env = Envelope::sign(&ControlKey::from_hex(KEY).unwrap(), "director", AT, now, [10; 16], b"junk")
            .unwrap();
        assert_eq!(reason(Some(&env.encode()), AT, b"junk"), RefusalReason::BadRequest);
    }

    #[test]
    fn the_unknown_name_and_the_wrong_key_get_the_same_words() {
        let gate = ControlGate::new(policy());
        let (env, frame) = signed("stranger", KEY, AT, 0, 1, &ControlRequest::Status);
        let a = gate.check(Some(&env), AT, &frame, 0).unwrap_err().error.message;
        let (env, frame) = signed("director", WRONG, AT, 0, 2, &ControlRequest::Status);
        let b = gate.check(Some(&env), AT, &frame, 0).unwrap_err().error.message;
        assert_eq!(a.replace("stranger", "X"), b.replace("director", "X"));
    }

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
    fn star_means_every_remote_request_and_nothing_else() {
        let all = allow_entry("*").unwrap();
        assert_eq!(all.len(), 12);
        for never in NEVER_REMOTE {
            assert!(!all.contains(never));
        }
    }
}
