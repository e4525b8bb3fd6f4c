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
//! ([`PatchableHello`](frond_protocol::PatchableHello)); the loop writes in the sequence number
//! of its next frame, so the subscriber's stream starts exactly there, and sends the element
//! table in force right after it. A new element table (the live stages changed) goes to every lane between two frames.

use std::os::fd::AsRawFd;
use std::os::unix::net::UnixStream;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;

use crossbeam_channel::Sender;
use frond_protocol::field::{FieldFrame, FieldMessage};
use frond_protocol::{Pose, ServerMessage, encode_frame};

/// Re-exported where `frond bench` has always named it.
pub use crate::handoff::NewLane;
use crate::handoff::{Garbage, Lane, MAX_SUBSCRIBERS, PublisherWake, SlowLane};

/// Bytes reserved for encoding one frame.
const FRAME_BUF: usize = 4096;
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

/// `parts` copied one after the other into `tail`; their length, or `None` if they do not fit.
fn fill_tail(tail: &mut [u8], parts: &[&[u8]]) -> Option<usize> {
    let mut len = 0;
    for part in parts {
        tail.get_mut(len..len + part.len())?.copy_from_slice(part);
        len += part.len();
    }
    Some(len)
}

/// What a frame sent to every lane is.
#[derive(Clone, Copy)]
enum Broadcast {
    /// Frame number `seq` (a pose or a field frame).
    Pose { seq: u64 },
    /// An element table, before pose `next_seq`.
    Table { next_seq: u64 },
}

/// The loop's direct lanes. Allocates only in [`Lanes::new`].
pub struct Lanes {
    slots: Box<[Option<Lane>]>,
    live: usize,
    buf: Vec<u8>,
    slow: Sender<SlowLane>,
    wake: Arc<PublisherWake>,
    /// Subscribers moved to the slow lane since start.
    demoted: u64,
    /// Version of the last element table sent to every lane.
    elements_version: u64,
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
            elements_version: 0,
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

    /// Admits `new`: writes its `Hello` with `next_seq` and the element table `elements` (an
    /// encoded frame) and puts it on a lane (or, if its socket cannot take them, on the slow lane
    /// with the rest; if every lane is taken, lets it go).
    pub fn admit(&mut self, new: &mut NewLane, next_seq: u64, elements: &[u8], garbage: &Sender<Garbage>) {
        let (Some(stream), Some(counters), Some(tail)) =
            (new.stream.take(), new.counters.take(), new.tail.take())
        else {
            return;
        };
        let mut lane = Lane { id: new.id, stream, counters, tail };
        let Some(slot) = self.slots.iter().position(Option::is_none) else {
            lane.counters.closed.store(true, Relaxed);
            let _ = garbage.try_send(Garbage::Lane(lane));
            return;
        };
        let hello = new.hello.with_next_seq(next_seq);
        let rest = match send_nowait(&lane.stream, hello) {
            Sent::All => match send_nowait(&lane.stream, elements) {
                Sent::All => {
                    self.slots[slot] = Some(lane);
                    self.live += 1;
                    return;
                }
                Sent::Part(n) => fill_tail(&mut lane.tail, &[&elements[n..]]),
                Sent::Gone => None,
            },
            Sent::Part(n) => fill_tail(&mut lane.tail, &[&hello[n..], elements]),
            Sent::Gone => None,
        };
        match rest {
            Some(len) => self.hand_to_slow(lane, len, next_seq, garbage),
            // Gone, or a Hello and table longer than the tail that a fresh socket refused.
            None => self.close(lane, garbage),
        }
    }

    /// Sends the encoded element table `frame` to every direct lane, before pose `next_seq`.
    pub fn send_table(&mut self, frame: &[u8], version: u64, next_seq: u64, garbage: &Sender<Garbage>) {
        self.elements_version = version;
        self.broadcast(frame, Broadcast::Table { next_seq }, garbage);
    }

    /// Encodes `pose` once and sends it to every direct lane.
    pub fn send(&mut self, pose: &Pose, garbage: &Sender<Garbage>) {
        if self.live == 0 {
            return;
        }
        self.buf.clear();
        encode_frame(&ServerMessage::Pose(*pose), &mut self.buf);
        let buf = std::mem::take(&mut self.buf);
        self.broadcast(&buf, Broadcast::Pose { seq: pose.seq }, garbage);
        self.buf = buf;
    }

    /// Encodes a field frame once and sends it to every direct lane (a numbered frame, like a
    /// pose: a lane that cannot take it moves to the slow lane, which is owed it).
    pub fn send_field(&mut self, frame: &FieldFrame, garbage: &Sender<Garbage>) {
        if self.live == 0 {
            return;
        }
        self.buf.clear();
        encode_frame(&ServerMessage::Field(FieldMessage::Frame(*frame)), &mut self.buf);
        let buf = std::mem::take(&mut self.buf);
        self.broadcast(&buf, Broadcast::Pose { seq: frame.seq }, garbage);
        self.buf = buf;
    }

    fn broadcast(&mut self, bytes: &[u8], what: Broadcast, garbage: &Sender<Garbage>) {
        for i in 0..self.slots.len() {
            let Some(lane) = &self.slots[i] else { continue };
            match send_nowait(&lane.stream, bytes) {
                Sent::All => {
                    if matches!(what, Broadcast::Pose { .. }) {
                        lane.counters.sent.fetch_add(1, Relaxed);
                    }
                }
                Sent::Part(n) => {
                    let Some(mut lane) = self.slots[i].take() else { continue };
                    self.live -= 1;
                    // The slow lane sends the unsent rest first, then the frames owed after it.
                    // A pose nothing of which went out is owed whole (it is in the publisher's
                    // queue); a table always goes in the tail, whole or its rest.
                    let (rest, from_seq): (&[u8], u64) = match what {
                        Broadcast::Pose { seq } if n == 0 => (&[], seq),
                        Broadcast::Pose { seq } => {
                            lane.counters.sent.fetch_add(1, Relaxed);
                            (&bytes[n..], seq + 1)
                        }
                        Broadcast::Table { next_seq } => (&bytes[n..], next_seq),
                    };
                    match fill_tail(&mut lane.tail, &[rest]) {
                        Some(len) => self.hand_to_slow(lane, len, from_seq, garbage),
                        None => self.close(lane, garbage),
                    }
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

    fn hand_to_slow(&mut self, lane: Lane, tail_len: usize, from_seq: u64, garbage: &Sender<Garbage>) {
        self.demoted += 1;
        // Counted before the hand-over, so frames from `from_seq` on wake the publisher.
        self.wake.add_slow();
        let Lane { id, stream, counters, tail } = lane;
        let elements_version = self.elements_version;
        let msg = SlowLane { id, stream, counters, tail, tail_len, from_seq, elements_version };
        if let Err(e) = self.slow.try_send(msg) {
            // The publisher cannot take it (gone, or a burst of slow subscribers): let it go.
            self.wake.remove_slow();
            let SlowLane { id, stream, counters, tail, .. } = e.into_inner();
            self.close(Lane { id, stream, counters, tail }, garbage);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::handoff::{SubscriberCounters, TAIL_MAX};
    use frond_protocol::PatchableHello;

    #[test]
    fn tails_up_to_tail_max_are_kept_longer_ones_refused() {
        let bytes: Vec<u8> = (0..=TAIL_MAX as u32).map(|i| i as u8).collect();
        let mut tail = vec![0u8; TAIL_MAX];
        let len = fill_tail(&mut tail, &[&bytes[..10], &bytes[10..TAIL_MAX]]).unwrap();
        assert_eq!((len, &tail[..]), (TAIL_MAX, &bytes[..TAIL_MAX]));
        assert_eq!(fill_tail(&mut tail, &[]), Some(0));
        assert!(fill_tail(&mut tail, &[&bytes]).is_none());
        assert!(fill_tail(&mut tail, &[&bytes[..TAIL_MAX], &[1]]).is_none());
    }

    #[test]
    fn a_subscriber_that_hung_up_is_closed_and_handed_to_housekeeping() {
        let (slow_tx, slow_rx) = crossbeam_channel::bounded(4);
        let (garbage_tx, garbage_rx) = crossbeam_channel::bounded(4);
        let mut lanes = Lanes::new(slow_tx, Arc::default());
        let (daemon_end, sub_end) = UnixStream::pair().unwrap();
        let counters = Arc::new(SubscriberCounters::default());
        let hello = frond_protocol::Hello {
            protocol_version: frond_protocol::PROTOCOL_VERSION,
            daemon_version: "t".into(),
            rig_name: "grass".into(),
            joint_names: vec![],
            tick_rate_hz: 1000,
            elements: Default::default(),
            next_seq: 0,
        };
        let mut new = NewLane::new(9, daemon_end, counters.clone(), PatchableHello::new(&hello));
        lanes.admit(&mut new, 5, &[], &garbage_tx);
        assert_eq!(lanes.ids().collect::<Vec<_>>(), vec![9]);
        lanes.send(&Pose { seq: 5, ..Pose::default() }, &garbage_tx);
        assert_eq!(counters.sent.load(Relaxed), 1);
        drop(sub_end);
        lanes.send(&Pose { seq: 6, ..Pose::default() }, &garbage_tx);
        assert!(lanes.is_empty());
        assert!(counters.closed.load(Relaxed));
        assert!(matches!(garbage_rx.try_recv(), Ok(Garbage::Lane(_))));
        assert!(slow_rx.is_empty(), "a hung-up subscriber is not moved to the slow lane");
        assert_eq!(lanes.demoted(), 0);
    }
}
