//! A Zenoh subscription that hands each pose to a closure on Zenoh's own receive thread (issue
//! 43: "the SDK may offer a callback-driven subscription for exporters that can work inside
//! Zenoh's thread").
//!
//! [`crate::Subscriber`] over `zenoh:` queues each sample for the thread that reads it: one
//! thread wake-up per pose, 20-40 us on a virtual machine, which is most of what the SDK adds to
//! Zenoh's own hop (`daemon/bench/PERFORMANCE.md`). [`subscribe`] decodes, numbers and passes
//! each pose inside Zenoh's callback instead, so an exporter that forwards a pose at once (an
//! OSC or UDP sender) has it as early as Zenoh does.
//!
//! What it gives up, for that: it never blocks, so it asks nothing while running. Poses lost on
//! the way are an [`Event::Gap`] (no refill from the bridge's ring: use
//! [`crate::SubscriberOptions::reliable`] with a `Subscriber` for a recorder); the element table
//! comes as [`Event::Elements`] when the bridge puts a new one (the hello's is in
//! [`CallbackSubscription::hello`]); fields are not evaluated (their frames are counted in the
//! sequence and skipped: a program that draws fields reads them with a `Subscriber`); a bridge
//! that goes away is silence, not [`Event::Disconnected`]. Its counts reach the bridge once a
//! second, as every SDK subscriber's do, from a thread of its own that wakes once a second.
//!
//! The closure must not block: while it runs, Zenoh delivers nothing else on that session.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use ::zenoh::Wait;
use crossbeam_channel::{Sender, bounded};
use frond_protocol::{HEADER_LEN, Hello, MAX_FRAME_LEN, ServerMessage};

use crate::error::SdkError;
use crate::source::ZenohAddr;
use crate::zenoh_config::open_addr_session;
use crate::zenoh_join::{decode_payload, resolve};
use crate::zenoh_keys::keys;
use crate::zenoh_replay::{self, REPORT_EVERY, ReplayRequest, numbered};
use crate::{Event, Stats, SubscriberOptions};

/// The counts a callback subscription keeps (its closure's thread writes, anyone reads).
#[derive(Default)]
struct Counts {
    frames: AtomicU64,
    gaps: AtomicU64,
    missing: AtomicU64,
    rejected: AtomicU64,
}

impl Counts {
    fn stats(&self) -> Stats {
        Stats {
            frames: self.frames.load(Ordering::Relaxed),
            gaps: self.gaps.load(Ordering::Relaxed),
            missing: self.missing.load(Ordering::Relaxed),
            rejected: self.rejected.load(Ordering::Relaxed),
            ..Stats::default()
        }
    }
}

/// The sequence a callback subscription follows, and its closure.
struct Follow<F> {
    /// The first number that belongs to this subscription (the hello's `next_seq`).
    floor: u64,
    /// The number due next.
    next: Option<u64>,
    on_event: F,
}

/// A running callback subscription ([`subscribe`]); dropping it ends the subscription and its
/// reporting thread.
pub struct CallbackSubscription {
    hello: Hello,
    key: String,
    counts: Arc<Counts>,
    /// Closing it stops the reporting thread.
    stop: Option<Sender<()>>,
    reporter: Option<JoinHandle<()>>,
    subscriber: Option<::zenoh::pubsub::Subscriber<()>>,
}

impl CallbackSubscription {
    /// The bridge's hello when the subscription started (rig, joints, element table).
    pub fn hello(&self) -> &Hello {
        &self.hello
    }

    /// The source key it follows (`frond/<stage>/<source>`).
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Its counts so far (poses passed on, gaps, poses missing in them, samples refused).
    pub fn stats(&self) -> Stats {
        self.counts.stats()
    }
}

impl Drop for CallbackSubscription {
    fn drop(&mut self) {
        if let Some(s) = self.subscriber.take() {
            let _ = s.undeclare().wait();
        }
        self.stop.take();
        if let Some(r) = self.reporter.take() {
            let _ = r.join();
        }
    }
}

/// Subscribes to `addr` and calls `on_event` on Zenoh's receive thread with each pose
/// ([`Event::Pose`], in order), each loss before one ([`Event::Gap`]) and each new element
/// table ([`Event::Elements`]). Waits up to `opts`' hello timeout for the bridge to answer, as
/// [`crate::Subscriber`] does; the first pose passed on is the first after the hello.
pub fn subscribe<F>(
    addr: &ZenohAddr,
    opts: &SubscriberOptions,
    on_event: F,
) -> Result<CallbackSubscription, SdkError>
where
    F: FnMut(Event) + Send + 'static,
{
    let session = open_addr_session(addr)
        .map_err(|e| SdkError::Zenoh { source_key: addr.to_string(), reason: e.to_string() })?;
    // Poses published before the subscription is declared are not seen; the first one seen
    // starts the numbering, so they are no gap.
    let (key, hello) = resolve(&session, addr, opts.hello_timeout)?;
    let counts = Arc::new(Counts::default());
    let follow = Mutex::new(Follow { floor: hello.next_seq, next: None, on_event });
    let zerr = |e: ::zenoh::Error| SdkError::Zenoh { source_key: key.clone(), reason: e.to_string() };
    let subscriber = {
        let counts = counts.clone();
        session
            .declare_subscriber(keys::under(&key, "*"))
            .callback(move |sample| {
                let leaf = sample.key_expr().as_str().rsplit('/').next().unwrap_or("");
                if !matches!(leaf, keys::POSES | keys::ELEMENTS) {
                    return;
                }
                // Anyone who may put on the key can send anything: what no frame can be is
                // refused before it is copied.
                if sample.payload().len() > MAX_FRAME_LEN + HEADER_LEN {
                    counts.rejected.fetch_add(1, Ordering::Relaxed);
                    return;
                }
                let Ok(msg) = decode_payload(&sample.payload().to_bytes()) else {
                    counts.rejected.fetch_add(1, Ordering::Relaxed);
                    return;
                };
                // Only Zenoh's thread for this subscriber takes the lock: it is never contended
                // (a poisoned one is a closure that panicked, whose state is still whole).
                let mut f = follow.lock().unwrap_or_else(PoisonError::into_inner);
                f.take(msg, &counts);
            })
            .wait()
            .map_err(zerr)?
    };
    let (stop, stopped) = bounded::<()>(0);
    let reporter = {
        let (session, counts) = (session.clone(), counts.clone());
        let replay = keys::under(&key, zenoh_replay::REPLAY);
        std::thread::Builder::new()
            .name("frond-sdk-report".into())
            .spawn(move || {
                let peer = session.zid().to_string();
                // Wakes once a second until the subscription is dropped (the sender goes).
                while let Err(crossbeam_channel::RecvTimeoutError::Timeout) =
                    stopped.recv_timeout(REPORT_EVERY)
                {
                    let s = counts.stats();
                    let request = ReplayRequest {
                        from: 0,
                        to: 0,
                        frames: s.frames,
                        missing: s.missing,
                        recovered: 0,
                        peer: peer.clone(),
                    };
                    zenoh_replay::report(&session, &replay, &request);
                }
            })
            .map_err(|e| SdkError::Zenoh {
                source_key: key.clone(),
                reason: format!("reporting thread: {e}"),
            })?
    };
    Ok(CallbackSubscription {
        hello,
        key,
        counts,
        stop: Some(stop),
        reporter: Some(reporter),
        subscriber: Some(subscriber),
    })
}

impl<F: FnMut(Event)> Follow<F> {
    /// One decoded sample: a pose is numbered (a gap before it when numbers were skipped) and
    /// passed on; a field frame only advances the numbering; an element table is passed on.
    fn take(&mut self, msg: ServerMessage, counts: &Counts) {
        if let Some((seq, span)) = numbered(&msg) {
            // Before the hello, or a number already passed (a duplicate or one out of order).
            if seq < self.floor || self.next.is_some_and(|n| seq < n) {
                return;
            }
            if let Some(expected) = self.next.filter(|&n| seq > n) {
                counts.gaps.fetch_add(1, Ordering::Relaxed);
                counts.missing.fetch_add(seq - expected, Ordering::Relaxed);
                (self.on_event)(Event::Gap { expected, got: seq });
            }
            self.next = Some(seq.saturating_add(span));
            if let ServerMessage::Pose(pose) = msg {
                counts.frames.fetch_add(1, Ordering::Relaxed);
                (self.on_event)(Event::Pose(pose));
            }
            return;
        }
        if let ServerMessage::Elements(table) = msg {
            (self.on_event)(Event::Elements(table));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_protocol::Pose;
    use frond_protocol::field::{FieldFrame, FieldMessage};

    fn pose(seq: u64) -> ServerMessage {
        ServerMessage::Pose(Pose { seq, ..Pose::default() })
    }

    /// Numbering worked out by hand: the hello says 10; 9 is before it; 10, 11 pass; 14 after a
    /// gap of 12-13; a field frame at 15 spanning 3 numbers (its announced plants) is counted
    /// but not passed; 18 follows it with no gap; 17 (late) and 18 (again) are dropped.
    #[test]
    fn poses_are_numbered_from_the_hello_with_gaps_and_field_frames_spans() {
        let counts = Counts::default();
        let mut seen = Vec::new();
        let mut f = Follow { floor: 10, next: None, on_event: |e: Event| seen.push(e) };
        let field = FieldFrame { seq: 15, poses: 3, ..FieldFrame::default() };
        for msg in [
            pose(9),
            pose(10),
            pose(11),
            pose(14),
            ServerMessage::Field(FieldMessage::Frame(field)),
            pose(18),
            pose(17),
            pose(18),
        ] {
            f.take(msg, &counts);
        }
        let got: Vec<String> = seen
            .iter()
            .map(|e| match e {
                Event::Pose(p) => format!("pose {}", p.seq),
                Event::Gap { expected, got } => format!("gap {expected}..{got}"),
                other => format!("{other:?}"),
            })
            .collect();
        assert_eq!(got, ["pose 10", "pose 11", "gap 12..14", "pose 14", "pose 18"]);
        let s = counts.stats();
        assert_eq!((s.frames, s.gaps, s.missing), (4, 1, 2));
    }
}
