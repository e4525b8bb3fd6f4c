//! The gate's tests: each refusal's reason, and that no principal's flood, refusals or replays
//! take what another's requests need.

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
    let text: String = (0..n).map(|i| format!("[[principal]]\nname = \"p{i}\"\nkey = \"{KEY}\"\n")).collect();
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
    assert_eq!(gate.check(Some(&env), AT, &frame, at(1_000_700)).unwrap_err().reason, RefusalReason::Replay);
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
    let env =
        Envelope::sign(&ControlKey::from_hex(KEY).unwrap(), "director", AT, now, [10; 16], b"junk").unwrap();
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
        assert!(send(&gate, "viewer", nonce, &ControlRequest::Status, T).is_ok(), "viewer request {nonce}");
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
    assert_eq!(send_at(after(99, 0)).unwrap_err().reason, RefusalReason::RateLimited, "99 ms: 0.99 of one");
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
    let passed = (1..40).filter(|n| send(&gate, "director", *n, &ControlRequest::Status, T).is_ok()).count();
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
    assert!(busy.error.message.contains("\"p0\" already has 4 requests waiting"), "{}", busy.error.message);
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
