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
        let (env, request) = self.authenticate(envelope, key_expr, frame, now)?;
        self.take_budget(&env, now)?;
        let name = env.principal;
        Ok(Admitted {
            principal: name.clone(),
            request,
            slot: PendingSlot { state: self.state.clone(), principal: name },
        })
    }

    /// The envelope and the request, when the envelope is signed by a principal of the policy
    /// over this key and frame, fresh, and the frame is one request that principal may send.
    /// Stateless: nothing is taken.
    fn authenticate(
        &self,
        envelope: Option<&[u8]>,
        key_expr: &str,
        frame: &[u8],
        now: Now,
    ) -> Result<(Envelope, ControlRequest), Refusal> {
        use ControlErrorKind::{BadRequest, PermissionDenied};
        let bytes = envelope.ok_or_else(|| {
            refusal(
                None,
                RefusalReason::Unsigned,
                PermissionDenied,
                format!("{UNAUTHENTICATED}unsigned request"),
            )
        })?;
        if bytes.len() > MAX_ENVELOPE_LEN {
            return Err(refusal(
                None,
                RefusalReason::Unsigned,
                PermissionDenied,
                format!("{UNAUTHENTICATED}oversized envelope"),
            ));
        }
        let env = Envelope::decode(bytes).map_err(|e| {
            refusal(None, RefusalReason::Unsigned, PermissionDenied, format!("{UNAUTHENTICATED}{e}"))
        })?;
        let name = env.principal.as_str();
        let Some(principal) = self.policy.principals.get(name) else {
            return Err(refusal(
                Some(name),
                RefusalReason::UnknownPrincipal,
                PermissionDenied,
                bad_key(name),
            ));
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
            return Err(refusal(Some(name), RefusalReason::BadSignature, PermissionDenied, bad_key(name)));
        }
        if let Err(e) = check_issue_time(env.issued_unix_ms, now.unix_ms) {
            return Err(refusal(
                Some(name),
                RefusalReason::Stale,
                PermissionDenied,
                format!("{UNAUTHENTICATED}{e} (are the hosts' clocks set, e.g. by NTP?)"),
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
        Ok((env, request))
    }

    /// For a signed, fresh, well formed and allowed request: the principal's own state (a
    /// replayed nonce, its rate, its pending requests and everyone's, its remembered nonces),
    /// checked in full before any of it is taken; then the nonce is remembered, one request of
    /// its budget spent and a pending slot held (released by the [`PendingSlot`]).
    fn take_budget(&self, env: &Envelope, now: Now) -> Result<(), Refusal> {
        use ControlErrorKind::{Internal, PermissionDenied};
        let name = env.principal.as_str();
        let mut state = lock(&self.state);
        let pending_total = state.pending;
        let Some(mine) = state.principals.get_mut(name) else {
            // Unreachable: the state lists every principal of the policy.
            return Err(refusal(
                Some(name),
                RefusalReason::UnknownPrincipal,
                PermissionDenied,
                bad_key(name),
            ));
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
        Ok(())
    }
}

/// What every refusal of an unsigned or unverified request starts with.
const UNAUTHENTICATED: &str = "not authenticated: ";

/// The same answer for an unknown name and a wrong key: a peer learns nothing from it.
fn bad_key(name: &str) -> String {
    format!("{UNAUTHENTICATED}unknown principal or wrong key for {name:?} (see the bridge's --control file)")
}

#[cfg(test)]
mod tests;
