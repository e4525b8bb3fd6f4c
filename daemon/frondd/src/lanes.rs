//! Direct lanes: the subscribers the realtime loop writes to itself.
//!
//! Handing every frame to a publisher thread cost a thread wake-up per frame before any
//! subscriber saw it: on a 2-vCPU VM a tenth of a millisecond at p50 and most of the
//! publisher's CPU (issue 9, measured with `perf` and `frond bench`). So the loop encodes each
//! frame once into a preallocated buffer and `send`s it, `MSG_DONTWAIT`, to every subscriber on
//! a direct lane: one system call each, no allocation, no lock, never a wait.
//!
//! A subscriber whose socket cannot take a whole frame (it fell some 200 frames behind and its
//! socket buffer is full) moves, with the unsent tail of that frame, to the publisher thread's
//! slow lane ([`SlowLane`], bounded per-subscriber backlog, drops counted, disconnected after
//! the write timeout) and stays there: a slow subscriber never costs the loop more than one
//! failed `send`, nor the other subscribers anything. A subscriber that hung up is handed to
//! housekeeping to be closed (closing and freeing are not the loop's business).
//!
//! New subscribers arrive from the acceptor with their `Hello` already encoded
//! ([`PatchableHello`]); the loop writes in the sequence number of its next frame, so the
//! subscriber's stream starts exactly there.

use std::os::fd::AsRawFd;
use std::os::unix::net::UnixStream;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;

use crossbeam_channel::Sender;
use frond_protocol::{PatchableHello, Pose, ServerMessage, encode_frame};

use crate::engine::{Garbage, MAX_SUBSCRIBERS};
use crate::publisher::{PublisherWake, SubscriberCounters};

/// Longest unsent tail handed to the slow lane (a pose frame encodes to ~230 bytes).
pub const TAIL_MAX: usize = 512;
/// Bytes reserved for encoding one frame.
const FRAME_BUF: usize = 4096;

/// A subscriber the acceptor hands to the loop.
pub struct NewLane {
    /// Subscriber id (status, logs).
    pub id: u64,
    /// Its connection; taken by the loop.
    pub stream: Option<UnixStream>,
    /// Its counters; taken by the loop.
    pub counters: Option<Arc<SubscriberCounters>>,
    /// Its `Hello`, encoded.
    pub hello: PatchableHello,
}

/// A subscriber on its way from the loop to the publisher's slow lane.
pub struct SlowLane {
    /// Subscriber id.
    pub id: u64,
    /// Its connection.
    pub stream: UnixStream,
    /// Its counters.
    pub counters: Arc<SubscriberCounters>,
    /// The part of the last frame its socket did not take (sent first).
    pub tail: [u8; TAIL_MAX],
    /// Bytes of `tail` in use.
    pub tail_len: usize,
    /// Sequence number of the first frame the slow lane owes it.
    pub from_seq: u64,
}

/// A subscriber on a direct lane.
pub struct Lane {
    id: u64,
    stream: UnixStream,
    counters: Arc<SubscriberCounters>,
}

/// What became of one `send` to a lane.
enum Sent {
    All,
    Part(usize),
    Gone,
}

fn send_nowait(stream: &UnixStream, bytes: &[u8]) -> Sent {
    loop {
        // SAFETY: `bytes` is a valid buffer of its length; the descriptor belongs to `stream`,
        // which outlives the call. MSG_NOSIGNAL: a hung-up peer is an error, not SIGPIPE.
        let n = unsafe {
            libc::send(
                stream.as_raw_fd(),
                bytes.as_ptr().cast(),
                bytes.len(),
                libc::MSG_DONTWAIT | libc::MSG_NOSIGNAL,
            )
        };
        if n >= 0 {
            let n = n as usize;
            return if n == bytes.len() { Sent::All } else { Sent::Part(n) };
        }
        match std::io::Error::last_os_error().raw_os_error() {
            Some(libc::EINTR) => continue,
            Some(libc::EAGAIN) => return Sent::Part(0),
            _ => return Sent::Gone,
        }
    }
}

/// The loop's direct lanes. Allocates only in [`Lanes::new`].
pub struct Lanes {
    slots: Box<[Option<Lane>]>,
    live: usize,
    buf: Vec<u8>,
    slow: Sender<SlowLane>,
    wake: Arc<PublisherWake>,
    /// Subscribers moved to the slow lane, and ones that left, since start (for tests/status).
    demoted: u64,
}

impl Lanes {
    /// Room for [`MAX_SUBSCRIBERS`]; `slow` feeds the publisher, whose `wake` counts them.
    pub fn new(slow: Sender<SlowLane>, wake: Arc<PublisherWake>) -> Self {
        Lanes {
            slots: (0..MAX_SUBSCRIBERS).map(|_| None).collect(),
            live: 0,
            buf: Vec::with_capacity(FRAME_BUF),
            slow,
            wake,
            demoted: 0,
        }
    }

    /// Subscribers on direct lanes.
    pub fn len(&self) -> usize {
        self.live
    }

    /// Whether no subscriber is on a direct lane.
    pub fn is_empty(&self) -> bool {
        self.live == 0
    }

    /// Subscribers moved to the slow lane so far.
    pub fn demoted(&self) -> u64 {
        self.demoted
    }

    /// Admits `new`: writes its `Hello` with `next_seq` and puts it on a lane (or, if its socket
    /// cannot take the `Hello`, on the slow lane; if every lane is taken, lets it go).
    pub fn admit(&mut self, new: &mut NewLane, next_seq: u64, garbage: &Sender<Garbage>) {
        let (Some(stream), Some(counters)) = (new.stream.take(), new.counters.take()) else { return };
        let lane = Lane { id: new.id, stream, counters };
        let Some(slot) = self.slots.iter().position(Option::is_none) else {
            lane.counters.closed.store(true, Relaxed);
            let _ = garbage.try_send(Garbage::Lane(lane));
            return;
        };
        let hello = new.hello.with_next_seq(next_seq);
        match send_nowait(&lane.stream, hello) {
            Sent::All => {
                self.slots[slot] = Some(lane);
                self.live += 1;
            }
            Sent::Part(n) => self.demote(lane, &hello[n..], next_seq, garbage),
            Sent::Gone => self.close(lane, garbage),
        }
    }

    /// Encodes `pose` once and sends it to every direct lane.
    pub fn send(&mut self, pose: &Pose, garbage: &Sender<Garbage>) {
        if self.live == 0 {
            return;
        }
        self.buf.clear();
        encode_frame(&ServerMessage::Pose(*pose), &mut self.buf);
        for i in 0..self.slots.len() {
            let Some(lane) = &self.slots[i] else { continue };
            match send_nowait(&lane.stream, &self.buf) {
                Sent::All => {
                    lane.counters.sent.fetch_add(1, Relaxed);
                }
                Sent::Part(n) => {
                    let Some(lane) = self.slots[i].take() else { continue };
                    self.live -= 1;
                    if n == 0 {
                        // Nothing of this frame went out: the slow lane owes it this one too.
                        self.hand_to_slow(lane, [0u8; TAIL_MAX], 0, pose.seq, garbage);
                        continue;
                    }
                    // Part of the frame went out; the slow lane sends the rest first.
                    lane.counters.sent.fetch_add(1, Relaxed);
                    let rest = self.buf.len() - n;
                    if rest > TAIL_MAX {
                        self.close(lane, garbage);
                        continue;
                    }
                    let mut tail = [0u8; TAIL_MAX];
                    tail[..rest].copy_from_slice(&self.buf[n..]);
                    self.hand_to_slow(lane, tail, rest, pose.seq + 1, garbage);
                }
                Sent::Gone => {
                    if let Some(lane) = self.slots[i].take() {
                        self.live -= 1;
                        self.close(lane, garbage);
                    }
                }
            }
        }
    }

    fn demote(&mut self, lane: Lane, rest: &[u8], from_seq: u64, garbage: &Sender<Garbage>) {
        if rest.len() > TAIL_MAX {
            // Only a Hello that a fresh socket refused could be this long: let it go.
            self.close(lane, garbage);
            return;
        }
        let mut tail = [0u8; TAIL_MAX];
        tail[..rest.len()].copy_from_slice(rest);
        self.hand_to_slow(lane, tail, rest.len(), from_seq, garbage);
    }

    fn hand_to_slow(
        &mut self,
        lane: Lane,
        tail: [u8; TAIL_MAX],
        tail_len: usize,
        from_seq: u64,
        garbage: &Sender<Garbage>,
    ) {
        self.demoted += 1;
        // Counted before the hand-over, so frames from `from_seq` on wake the publisher.
        self.wake.add_slow();
        let Lane { id, stream, counters } = lane;
        let msg = SlowLane { id, stream, counters, tail, tail_len, from_seq };
        if let Err(e) = self.slow.try_send(msg) {
            // The publisher cannot take it (gone, or a burst of slow subscribers): let it go.
            self.wake.remove_slow();
            let SlowLane { id, stream, counters, .. } = e.into_inner();
            self.close(Lane { id, stream, counters }, garbage);
        }
    }

    fn close(&mut self, lane: Lane, garbage: &Sender<Garbage>) {
        lane.counters.closed.store(true, Relaxed);
        if let Err(e) = garbage.try_send(Garbage::Lane(lane)) {
            // Housekeeping is gone (shutdown): dropping here is all that is left.
            drop(e.into_inner());
        }
    }

    /// Id of the subscriber on each direct lane (for tests).
    pub fn ids(&self) -> impl Iterator<Item = u64> + '_ {
        self.slots.iter().flatten().map(|l| l.id)
    }
}
