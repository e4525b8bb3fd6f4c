//! Admission of remote control requests: who signed it (the allow-list), when (the issue time),
//! whether it was seen before (the nonces), and whether its principal has budget left and a
//! share of the pending slots.
//!
//! One principal cannot lock out another: every principal has its own nonce store, its own
//! rate budget (a token bucket) and at most [`MAX_PENDING_PER_PRINCIPAL`] of the
//! [`MAX_PENDING`] slots. A request is checked in full before anything is taken for it, so a
//! refused one (unsigned, unknown principal, wrong key, stale, malformed, not allowed, replayed,
//! over budget) takes nothing: no nonce is remembered, no token spent, no slot held. Memory is
//! bounded whatever peers send: state exists only for the allow-list's principals, and each
//! remembers at most [`MAX_NONCES_PER_PRINCIPAL`] nonces.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use frond_protocol::{ControlError, ControlErrorKind, ControlRequest, MAX_CONTROL_REQUEST};
use frond_sdk::control_auth::{
    Envelope, MAX_CLOCK_SKEW, MAX_ENVELOPE_LEN, MAX_REQUEST_AGE, NONCE_LEN, check_issue_time,
};

use super::ControlPolicy;

/// Requests accepted but not yet answered by the daemon, all principals together; more are
/// refused as busy. The control socket serves at most 16 clients at once; the bridge is one of
/// them, and sends one request at a time.
pub const MAX_PENDING: usize = 16;
/// How many of the [`MAX_PENDING`] slots one principal may hold: the others always find room.
pub const MAX_PENDING_PER_PRINCIPAL: usize = 4;
/// Requests a second one principal may send, sustained (its token bucket's refill rate).
pub const RATE_PER_PRINCIPAL_HZ: u64 = 10;
/// Requests one principal may send at once after a quiet spell (its token bucket's size).
pub const BURST_PER_PRINCIPAL: u64 = 20;
/// Nonces one principal's store remembers: each accepted request's, until its issue time is
/// older than [`MAX_REQUEST_AGE`] (then it would be refused as stale anyway). The rate budget
/// lets fewer through in that time than the store holds, so it fills only if the bridge's
/// clock steps back; then that principal's requests are refused as busy, nobody else's.
pub const MAX_NONCES_PER_PRINCIPAL: usize = 512;

// A principal's budget never fills its nonce store: a request is remembered from when it is
// accepted (issued up to MAX_CLOCK_SKEW ahead) until it is MAX_REQUEST_AGE old.
const _: () = assert!(
    BURST_PER_PRINCIPAL + RATE_PER_PRINCIPAL_HZ * (MAX_REQUEST_AGE.as_secs() + MAX_CLOCK_SKEW.as_secs() + 1)
        <= MAX_NONCES_PER_PRINCIPAL as u64
);
const _: () = assert!(MAX_PENDING_PER_PRINCIPAL < MAX_PENDING);

/// Why a request was refused, as it is counted and logged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RefusalReason {
    /// No envelope, or one that does not parse.
    Unsigned,
    /// The principal is not on the allow-list.
    UnknownPrincipal,
    /// The signature is wrong (wrong key, or the request was altered).
    BadSignature,
    /// Issued more than [`MAX_REQUEST_AGE`] before the bridge's clock or more than
    /// [`MAX_CLOCK_SKEW`] after it.
    Stale,
    /// A nonce already accepted.
    Replay,
    /// The principal may not send this request.
    NotAllowed,
    /// The request frame does not decode or is too large.
    BadRequest,
    /// The principal sent more than its rate budget allows.
    RateLimited,
    /// Too many requests waiting: the principal's share, or all slots.
    Busy,
}

/// A refusal: the reply and what to count.
#[derive(Debug, Clone)]
pub struct Refusal {
    /// Who claimed to send it (verified for every reason but `Unsigned`, `UnknownPrincipal`,
    /// `BadSignature` and a `BadRequest` that is too large to check).
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

/// The bridge's clocks when a request arrives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Now {
    /// Realtime, milliseconds since 1970: what issue times are compared with.
    pub unix_ms: u64,
    /// Monotonic, milliseconds: what rate budgets refill by (a realtime step cannot fill or
    /// drain them).
    pub monotonic_ms: u64,
}

/// A token bucket in thousandths of a request: it holds at most [`BURST_PER_PRINCIPAL`]
/// requests and gains [`RATE_PER_PRINCIPAL_HZ`] a second.
#[derive(Debug)]
struct TokenBucket {
    milli: u64,
    at_ms: u64,
}

impl TokenBucket {
    const FULL_MILLI: u64 = BURST_PER_PRINCIPAL * 1000;

    fn full() -> TokenBucket {
        TokenBucket { milli: Self::FULL_MILLI, at_ms: 0 }
    }

    fn refill(&mut self, now_ms: u64) {
        let elapsed_ms = now_ms.saturating_sub(self.at_ms);
        // RATE requests a second is RATE thousandths a millisecond.
        self.milli =
            self.milli.saturating_add(elapsed_ms.saturating_mul(RATE_PER_PRINCIPAL_HZ)).min(Self::FULL_MILLI);
        self.at_ms = self.at_ms.max(now_ms);
    }

    /// Milliseconds until one request's worth is there (0: now).
    fn wait_ms(&self) -> u64 {
        1000u64.saturating_sub(self.milli).div_ceil(RATE_PER_PRINCIPAL_HZ)
    }
}

/// What the gate keeps for one principal.
#[derive(Debug)]
struct PrincipalState {
    /// Accepted nonces and their issue times (realtime ms).
    nonces: HashMap<[u8; NONCE_LEN], u64>,
    bucket: TokenBucket,
    /// Slots held: accepted, not yet answered.
    pending: usize,
}

#[derive(Debug)]
struct GateState {
    principals: HashMap<String, PrincipalState>,
    /// Slots held by all principals.
    pending: usize,
}

fn lock(state: &Mutex<GateState>) -> MutexGuard<'_, GateState> {
    state.lock().unwrap_or_else(PoisonError::into_inner)
}

/// One of the [`MAX_PENDING`] slots, held by an accepted request until it is answered; dropping
/// it gives the slot back.
#[derive(Debug)]
pub struct PendingSlot {
    state: Arc<Mutex<GateState>>,
    principal: String,
}

impl Drop for PendingSlot {
    fn drop(&mut self) {
        let mut state = lock(&self.state);
        state.pending = state.pending.saturating_sub(1);
        if let Some(p) = state.principals.get_mut(&self.principal) {
            p.pending = p.pending.saturating_sub(1);
        }
    }
}

/// An accepted request: who sent it, what, and the slot it holds until answered.
#[derive(Debug)]
pub struct Admitted {
    /// The principal (verified).
    pub principal: String,
    /// The request.
    pub request: ControlRequest,
    /// Held until the request is answered.
    pub slot: PendingSlot,
}

/// Checks signed requests against a [`ControlPolicy`], remembering accepted nonces, rate
/// budgets and pending slots per principal.
pub struct ControlGate {
    policy: ControlPolicy,
    state: Arc<Mutex<GateState>>,
}

impl ControlGate {
    /// A gate for `policy`; every principal starts with a full budget.
    pub fn new(policy: ControlPolicy) -> ControlGate {
        let principals = policy
            .principals
            .keys()
            .map(|name| {
                (
                    name.clone(),
                    PrincipalState { nonces: HashMap::new(), bucket: TokenBucket::full(), pending: 0 },
                )
            })
            .collect();
        ControlGate { policy, state: Arc::new(Mutex::new(GateState { principals, pending: 0 })) }
    }

    /// Checks one query: `envelope` is its attachment, `frame` its payload, `key_expr` the key
    /// it was addressed to, `now` the bridge's clocks. On success, who sent which request, and
    /// the pending slot it holds; the nonce is remembered and one request of the principal's
    /// budget spent. On refusal nothing is taken.
    pub fn check(
        &self,
        envelope: Option<&[u8]>,
        key_expr: &str,
        frame: &[u8],
        now: Now,
    ) -> Result<Admitted, Refusal> {
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
        if let Err(e) = check_issue_time(env.issued_unix_ms, now.unix_ms) {
            return Err(refusal(
                Some(name),
                RefusalReason::Stale,
                PermissionDenied,
                format!("{unauthenticated}{e} (are the hosts' clocks set, e.g. by NTP?)"),
            ));
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

        // Signed, fresh, well formed and allowed: now this principal's own state, checked in
        // full before any of it is taken.
        let mut state = lock(&self.state);
        let pending_total = state.pending;
        let Some(mine) = state.principals.get_mut(name) else {
            // Unreachable: the state lists every principal of the policy.
            return Err(refusal(Some(name), RefusalReason::UnknownPrincipal, PermissionDenied, bad()));
        };
        if mine.nonces.contains_key(&env.nonce) {
            return Err(refusal(
                Some(name),
                RefusalReason::Replay,
                PermissionDenied,
                "replayed request".into(),
            ));
        }
        mine.bucket.refill(now.monotonic_ms);
        let wait_ms = mine.bucket.wait_ms();
        if wait_ms > 0 {
            return Err(refusal(
                Some(name),
                RefusalReason::RateLimited,
                Internal,
                format!(
                    "{name:?} sent more than {BURST_PER_PRINCIPAL} requests at once or \
                     {RATE_PER_PRINCIPAL_HZ} a second; try again in {wait_ms} ms"
                ),
            ));
        }
        if mine.pending >= MAX_PENDING_PER_PRINCIPAL {
            return Err(refusal(
                Some(name),
                RefusalReason::Busy,
                Internal,
                format!(
                    "{name:?} already has {MAX_PENDING_PER_PRINCIPAL} requests waiting for the daemon, \
                     its share; try again when one is answered"
                ),
            ));
        }
        if pending_total >= MAX_PENDING {
            return Err(refusal(
                Some(name),
                RefusalReason::Busy,
                Internal,
                format!("{MAX_PENDING} remote requests are already waiting; try again"),
            ));
        }
        if mine.nonces.len() >= MAX_NONCES_PER_PRINCIPAL {
            mine.nonces.retain(|_, issued| {
                now.unix_ms.saturating_sub(*issued) <= MAX_REQUEST_AGE.as_millis() as u64
            });
        }
        if mine.nonces.len() >= MAX_NONCES_PER_PRINCIPAL {
            return Err(refusal(
                Some(name),
                RefusalReason::Busy,
                Internal,
                format!(
                    "{name:?} has {MAX_NONCES_PER_PRINCIPAL} requests within {} ms (has this host's clock \
                     stepped back?); try again later",
                    MAX_REQUEST_AGE.as_millis()
                ),
            ));
        }
        mine.nonces.insert(env.nonce, env.issued_unix_ms);
        mine.bucket.milli -= 1000;
        mine.pending += 1;
        state.pending += 1;
        drop(state);
        Ok(Admitted {
            principal: name.to_owned(),
            request,
            slot: PendingSlot { state: self.state.clone(), principal: name.to_owned() },
        })
    }
}

#[cfg(test)]
mod tests {
    use frond_sdk::control_auth::ControlKey;

    use super::*;

    const KEY: &str = "1111111111111111111111111111111111111111111111111111111111111111";
    const WRONG: &str = "2222222222222222222222222222222222222222222222222222222222222222";
    const AT: &str = "frond/s/g/control";
    /// An instant on both clocks.
    const T: Now = Now { unix_ms: 5_000_000, monotonic_ms: 7_000_000 };

    fn policy() -> ControlPolicy {
        ControlPolicy::parse(&format!(
            "[[principal]]\nname = \"director\"\nkey = \"{KEY}\"\n\n\
             [[principal]]\nname = \"viewer\"\nkey = \"{KEY}\"\nallow = [\"read\"]\n"
        ))
        .unwrap()
    }

    /// A policy of `n` principals `p0`, `p1`, ... that may send anything.
    fn crowd(n: usize) -> ControlPolicy {
        let text: String =
            (0..n).map(|i| format!("[[principal]]\nname = \"p{i}\"\nkey = \"{KEY}\"\n")).collect();
        ControlPolicy::parse(&text).unwrap()
    }

    fn signed(
        name: &str,
        key: &str,
        at: &str,
        issued: u64,
        nonce: u64,
        req: &ControlRequest,
    ) -> (Vec<u8>, Vec<u8>) {
        let mut frame = Vec::new();
        frond_protocol::encode_frame(req, &mut frame);
        let env =
            Envelope::sign(&ControlKey::from_hex(key).unwrap(), name, at, issued, self::nonce(nonce), &frame)
                .unwrap();
        (env.encode(), frame)
    }

    fn nonce(n: u64) -> [u8; NONCE_LEN] {
        let mut bytes = [0xa5; NONCE_LEN];
        bytes[..8].copy_from_slice(&n.to_le_bytes());
        bytes
    }

    /// `name`'s `req` with `nonce`, issued at `now`, through `gate`.
    fn send(
        gate: &ControlGate,
        name: &str,
        nonce: u64,
        req: &ControlRequest,
        now: Now,
    ) -> Result<Admitted, Refusal> {
        let (env, frame) = signed(name, KEY, AT, now.unix_ms, nonce, req);
        gate.check(Some(&env), AT, &frame, now)
    }

    fn reason(r: Result<Admitted, Refusal>) -> Option<RefusalReason> {
        r.err().map(|r| r.reason)
    }

    #[test]
    fn a_signed_allowed_request_passes_once() {
        let gate = ControlGate::new(policy());
        let req = ControlRequest::Mark { label: "take 2".into() };
        let (env, frame) = signed("director", KEY, AT, 1_000_000, 1, &req);
        let at = |unix_ms| Now { unix_ms, monotonic_ms: 0 };
        let ok = gate.check(Some(&env), AT, &frame, at(1_000_500)).unwrap();
        assert_eq!((ok.principal.as_str(), &ok.request), ("director", &req));
        let again = gate.check(Some(&env), AT, &frame, at(1_000_600)).unwrap_err();
        assert_eq!(again.reason, RefusalReason::Replay);
        // Once answered, still a replay: the nonce outlives the slot.
        drop(ok);
        assert_eq!(
            gate.check(Some(&env), AT, &frame, at(1_000_700)).unwrap_err().reason,
            RefusalReason::Replay
        );
    }

    #[test]
    fn every_kind_of_bad_request_is_refused_with_its_reason() {
        let gate = ControlGate::new(policy());
        let status = ControlRequest::Status;
        let now = T.unix_ms;
        let reason =
            |env: Option<&[u8]>, at: &str, frame: &[u8]| gate.check(env, at, frame, T).unwrap_err().reason;
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
        // From the future: beyond the 5 s of clock skew allowed, however young.
        let (env, frame) = signed("director", KEY, AT, now + 5_001, 6, &status);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::Stale, "5001 ms ahead");
        let (env, frame) = signed("director", KEY, AT, now + 30_000, 6, &status);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::Stale, "30 s ahead");
        let (env, frame) = signed("viewer", KEY, AT, now, 7, &ControlRequest::RecordStop);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::NotAllowed);
        let (env, frame) = signed("viewer", KEY, AT, now, 8, &status);
        assert!(gate.check(Some(&env), AT, &frame, T).is_ok(), "viewer may read");
        let (env, frame) = signed("director", KEY, AT, now, 9, &ControlRequest::PanicForTest);
        assert_eq!(reason(Some(&env), AT, &frame), RefusalReason::NotAllowed, "testing aids never pass");
        // A valid signature over bytes that are not a request.
        let env = Envelope::sign(&ControlKey::from_hex(KEY).unwrap(), "director", AT, now, [10; 16], b"junk")
            .unwrap();
        assert_eq!(reason(Some(&env.encode()), AT, b"junk"), RefusalReason::BadRequest);
        // The edges of the window pass: 30 s old, 5 s ahead.
        let (env, frame) = signed("director", KEY, AT, now - 30_000, 11, &status);
        assert!(gate.check(Some(&env), AT, &frame, T).is_ok(), "30 s old");
        let (env, frame) = signed("director", KEY, AT, now + 5_000, 12, &status);
        assert!(gate.check(Some(&env), AT, &frame, T).is_ok(), "5 s ahead");
    }

    #[test]
    fn the_unknown_name_and_the_wrong_key_get_the_same_words() {
        let gate = ControlGate::new(policy());
        let (env, frame) = signed("stranger", KEY, AT, 0, 1, &ControlRequest::Status);
        let zero = Now { unix_ms: 0, monotonic_ms: 0 };
        let a = gate.check(Some(&env), AT, &frame, zero).unwrap_err().error.message;
        let (env, frame) = signed("director", WRONG, AT, 0, 2, &ControlRequest::Status);
        let b = gate.check(Some(&env), AT, &frame, zero).unwrap_err().error.message;
        assert_eq!(a.replace("stranger", "X"), b.replace("director", "X"));
    }

    #[test]
    fn one_principal_flooding_valid_requests_never_makes_another_busy() {
        let gate = ControlGate::new(policy());
        // 5000 signed, fresh, allowed requests at one instant, each answered at once: more
        // than the old global store of 4096 nonces held.
        let mut accepted = 0;
        for nonce in 0..5000 {
            match send(&gate, "director", nonce, &ControlRequest::Status, T) {
                Ok(_) => accepted += 1,
                Err(r) => assert_eq!(r.reason, RefusalReason::RateLimited, "{:?}", r.error),
            }
        }
        assert_eq!(accepted, 20, "a burst of 20, then the budget is spent");
        // The viewer's own budget is whole.
        for nonce in 0..20 {
            assert!(
                send(&gate, "viewer", nonce, &ControlRequest::Status, T).is_ok(),
                "viewer request {nonce}"
            );
        }
        assert_eq!(
            reason(send(&gate, "viewer", 20, &ControlRequest::Status, T)),
            Some(RefusalReason::RateLimited)
        );
    }

    #[test]
    fn the_budget_refills_at_10_a_second_on_the_monotonic_clock() {
        let gate = ControlGate::new(policy());
        let mut nonce = 0;
        let mut send_at = |now: Now| {
            nonce += 1;
            send(&gate, "director", nonce, &ControlRequest::Status, now).map(drop)
        };
        for _ in 0..20 {
            send_at(T).unwrap();
        }
        let after = |ms: u64, unix_step_ms: u64| Now {
            unix_ms: T.unix_ms + ms + unix_step_ms,
            monotonic_ms: T.monotonic_ms + ms,
        };
        assert_eq!(
            send_at(after(99, 0)).unwrap_err().reason,
            RefusalReason::RateLimited,
            "99 ms: 0.99 of one"
        );
        assert!(send_at(after(100, 0)).is_ok(), "100 ms: one");
        assert_eq!(send_at(after(100, 0)).unwrap_err().reason, RefusalReason::RateLimited);
        // The realtime clock stepping an hour ahead gives nothing.
        assert_eq!(send_at(after(150, 3_600_000)).unwrap_err().reason, RefusalReason::RateLimited);
        // Three seconds of quiet fill it to the burst, not beyond.
        let later = after(3_200, 0);
        let passed = (0..40).filter(|_| send_at(later).is_ok()).count();
        assert_eq!(passed, 20);
    }

    #[test]
    fn a_refused_request_takes_no_nonce_and_no_budget() {
        let gate = ControlGate::new(policy());
        let status = ControlRequest::Status;
        // The viewer asks, thousands of times, for what it may not send; the director's name
        // comes with wrong keys as often.
        for nonce in 0..5000 {
            assert_eq!(
                reason(send(&gate, "viewer", nonce, &ControlRequest::RecordStop, T)),
                Some(RefusalReason::NotAllowed)
            );
            let (env, _) = signed("director", WRONG, AT, T.unix_ms, nonce, &status);
            let (_, frame) = signed("director", KEY, AT, T.unix_ms, nonce, &status);
            assert_eq!(reason(gate.check(Some(&env), AT, &frame, T)), Some(RefusalReason::BadSignature));
        }
        // Junk under a valid signature, and a request from too far ahead, with nonces 0 and 1.
        let env =
            Envelope::sign(&ControlKey::from_hex(KEY).unwrap(), "director", AT, T.unix_ms, nonce(0), b"junk")
                .unwrap();
        assert_eq!(reason(gate.check(Some(&env.encode()), AT, b"junk", T)), Some(RefusalReason::BadRequest));
        let (env, frame) = signed("director", KEY, AT, T.unix_ms + 60_000, 1, &status);
        assert_eq!(reason(gate.check(Some(&env), AT, &frame, T)), Some(RefusalReason::Stale));
        // None of those nonces was remembered, and both budgets are whole: 20 each.
        for nonce in 0..20 {
            assert!(send(&gate, "viewer", nonce, &status, T).is_ok(), "viewer nonce {nonce}");
            assert!(send(&gate, "director", nonce, &status, T).is_ok(), "director nonce {nonce}");
        }
    }

    #[test]
    fn a_replayed_request_spends_nothing_of_its_principals_budget() {
        let gate = ControlGate::new(policy());
        let (env, frame) = signed("director", KEY, AT, T.unix_ms, 0, &ControlRequest::Status);
        assert!(gate.check(Some(&env), AT, &frame, T).is_ok());
        // Anyone who saw it on the wire sends it again, often.
        for _ in 0..1000 {
            assert_eq!(reason(gate.check(Some(&env), AT, &frame, T)), Some(RefusalReason::Replay));
        }
        let passed =
            (1..40).filter(|n| send(&gate, "director", *n, &ControlRequest::Status, T).is_ok()).count();
        assert_eq!(passed, 19, "the rest of the burst of 20");
    }

    #[test]
    fn one_principal_holds_at_most_4_of_the_16_pending_slots() {
        let gate = ControlGate::new(crowd(5));
        let status = ControlRequest::Status;
        let mut held = Vec::new();
        for nonce in 0..4 {
            held.push(send(&gate, "p0", nonce, &status, T).unwrap());
        }
        // p0's fifth waits for one of its own to be answered; the slot costs nothing meanwhile.
        let busy = send(&gate, "p0", 4, &status, T).unwrap_err();
        assert_eq!(busy.reason, RefusalReason::Busy);
        assert!(
            busy.error.message.contains("\"p0\" already has 4 requests waiting"),
            "{}",
            busy.error.message
        );
        for p in ["p1", "p2", "p3"] {
            for nonce in 0..4 {
                held.push(send(&gate, p, nonce, &status, T).unwrap());
            }
        }
        // All 16 held: even p4, who holds none, waits.
        assert_eq!(held.len(), 16);
        assert_eq!(reason(send(&gate, "p4", 0, &status, T)), Some(RefusalReason::Busy));
        // p0's first is answered: its slot is free, and p0's refused nonce 4 was not spent.
        drop(held.remove(0));
        assert!(send(&gate, "p0", 4, &status, T).is_ok());
        drop(held.pop());
        assert!(send(&gate, "p4", 0, &status, T).is_ok(), "p4's refused nonce 0 was not spent");
    }

    #[test]
    fn a_principals_nonce_store_is_bounded_and_forgets_what_has_expired() {
        let gate = ControlGate::new(policy());
        let status = ControlRequest::Status;
        // The monotonic clock runs (the budget refills) while the realtime one stands still, as
        // after a step back: nonces cannot expire, so the store fills.
        let at = |i: u64| Now { unix_ms: T.unix_ms, monotonic_ms: T.monotonic_ms + 100 * i };
        for i in 0..512 {
            assert!(send(&gate, "director", i, &status, at(i)).is_ok(), "request {i}");
        }
        let full = send(&gate, "director", 512, &status, at(512)).unwrap_err();
        assert_eq!(full.reason, RefusalReason::Busy, "{}", full.error.message);
        assert!(send(&gate, "viewer", 0, &status, at(512)).is_ok(), "the viewer's store is its own");
        // 30001 ms later every one of them is too old to pass, so forgotten: room again.
        let later = Now { unix_ms: T.unix_ms + 30_001, monotonic_ms: T.monotonic_ms + 100 * 513 };
        assert!(send(&gate, "director", 512, &status, later).is_ok());
        assert_eq!(gate.state.lock().unwrap().principals["director"].nonces.len(), 1);
    }
}
