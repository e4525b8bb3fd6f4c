//! Admission: which connections a server keeps when more arrive than it serves, so that slow or
//! idle clients can never lock an operator out.
//!
//! A connection is *reading* from its accept until its request has arrived whole, then
//! *answering* while its answer is made, then *writing* until the answer is written. Reading
//! and writing are the cheap phases for an attacker (open a socket and trickle a byte now and
//! then, or ask for a large answer and never read it), so they are the ones that give way:
//! - every request must arrive whole within [`Limits::request_deadline`] (one deadline for the
//!   request, not one per read);
//! - a peer address holds at most [`Limits::max_reading_per_peer`] reading connections: its
//!   next one evicts its oldest;
//! - when the server holds [`Limits::max_connections`], a new connection evicts the oldest
//!   reading connection of the peer that holds the most (room is always kept for a new
//!   request); when none is reading, the oldest writing connection of the peer that holds the
//!   most writing ones (a client that does not read its answer held its place until
//!   [`Limits::write_deadline`], and a few dozen of them, asking again, kept every request 503);
//!   a new connection is answered 503 only when every connection is making its answer;
//! - the answers being written hold at most [`Limits::max_writing_bytes`] between them (each
//!   holds its whole body until written): the oldest writing ones are cut to make room for a
//!   new one, which is never refused (one answer alone may be larger).
//!
//! An evicted connection is shut down (its blocked read returns) and leaves the count at once.
//! A loopback server sees every local client as one peer, so there the eviction of the oldest is
//! what keeps the operator served: a browser sends its request within a millisecond of
//! connecting, long before it is the oldest.

use std::net::{IpAddr, Shutdown, TcpStream};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// A server's connection limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Most connections at once, reading or answering (each has a thread).
    pub max_connections: usize,
    /// Most connections one peer address may have reading at once.
    pub max_reading_per_peer: usize,
    /// How long a whole request (head and body) may take to arrive.
    pub request_deadline: Duration,
    /// How long a whole answer may take to be written.
    pub write_deadline: Duration,
    /// Largest request body, bytes.
    pub max_body_bytes: usize,
    /// Most bytes of answers being written at once (see the module docs).
    pub max_writing_bytes: usize,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_connections: 64,
            max_reading_per_peer: 32,
            request_deadline: Duration::from_secs(10),
            write_deadline: Duration::from_secs(10),
            max_body_bytes: crate::http::MAX_BODY_BYTES,
            max_writing_bytes: 256 << 20,
        }
    }
}

/// What the gate has done, for a server's status.
#[derive(Debug, Default)]
pub struct GateCounters {
    /// Connections admitted.
    pub admitted: AtomicU64,
    /// Reading or writing connections shut down to make room for newer ones.
    pub evicted: AtomicU64,
    /// Connections answered 503 because every slot was answering.
    pub full: AtomicU64,
    /// Requests that did not arrive whole within the deadline (408).
    pub timed_out: AtomicU64,
}

#[derive(Debug)]
struct Reader {
    id: u64,
    peer: IpAddr,
    since: Instant,
    /// A handle on the connection, to shut it down when evicted.
    stream: TcpStream,
    /// The answer's bytes (writing connections).
    bytes: usize,
}

#[derive(Debug, Default)]
struct Inner {
    next_id: u64,
    reading: Vec<Reader>,
    answering: usize,
    writing: Vec<Reader>,
}

/// The admission state of one server.
#[derive(Debug)]
pub struct Gate {
    limits: Limits,
    inner: Mutex<Inner>,
    /// Its counters.
    pub counters: GateCounters,
}

/// Why a connection was not admitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Full;

impl Gate {
    /// A gate with `limits` (each at least 1).
    pub fn new(limits: Limits) -> Arc<Gate> {
        let limits = Limits {
            max_connections: limits.max_connections.max(1),
            max_reading_per_peer: limits.max_reading_per_peer.max(1),
            ..limits
        };
        Arc::new(Gate { limits, inner: Mutex::default(), counters: GateCounters::default() })
    }

    /// Its limits.
    pub fn limits(&self) -> Limits {
        self.limits
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Admits `stream` from `peer` as reading, making room as the module docs say; [`Full`]
    /// when every connection is answering.
    pub fn admit(self: &Arc<Gate>, stream: &TcpStream, peer: IpAddr) -> Result<Ticket, Full> {
        let handle = stream.try_clone().map_err(|_| Full)?;
        let mut inner = self.lock();
        let own = inner.reading.iter().filter(|r| r.peer == peer).count();
        if own >= self.limits.max_reading_per_peer {
            self.evict_oldest_of(&mut inner, peer);
        }
        if inner.reading.len() + inner.answering + inner.writing.len() >= self.limits.max_connections {
            if let Some(p) = busiest_peer(&inner.reading) {
                self.evict_oldest_of(&mut inner, p);
            } else if let Some(p) = busiest_peer(&inner.writing) {
                evict_oldest(&mut inner.writing, Some(p), &self.counters);
            } else {
                self.counters.full.fetch_add(1, Ordering::Relaxed);
                return Err(Full);
            }
        }
        let id = inner.next_id;
        inner.next_id += 1;
        inner.reading.push(Reader { id, peer, since: Instant::now(), stream: handle, bytes: 0 });
        self.counters.admitted.fetch_add(1, Ordering::Relaxed);
        Ok(Ticket { gate: Arc::clone(self), id, state: State::Reading, handle: None })
    }

    fn evict_oldest_of(&self, inner: &mut Inner, peer: IpAddr) {
        evict_oldest(&mut inner.reading, Some(peer), &self.counters);
    }

    /// Connections reading and answering (making or writing their answer) now.
    pub fn load(&self) -> (usize, usize) {
        let inner = self.lock();
        (inner.reading.len(), inner.answering + inner.writing.len())
    }
}

/// Shuts down and removes the oldest of `conns` (of `peer`, when given); `false` when none.
fn evict_oldest(conns: &mut Vec<Reader>, peer: Option<IpAddr>, counters: &GateCounters) -> bool {
    let oldest = conns
        .iter()
        .enumerate()
        .filter(|(_, r)| peer.is_none_or(|p| r.peer == p))
        .min_by_key(|(_, r)| (r.since, r.id))
        .map(|(i, _)| i);
    let Some(i) = oldest else { return false };
    let r = conns.swap_remove(i);
    let _ = r.stream.shutdown(Shutdown::Both);
    counters.evicted.fetch_add(1, Ordering::Relaxed);
    true
}

/// The peer with the most connections in `reading` (the lowest address among equals, so the choice
/// does not depend on the list's order).
fn busiest_peer(reading: &[Reader]) -> Option<IpAddr> {
    let mut best: Option<(usize, IpAddr)> = None;
    for r in reading {
        let n = reading.iter().filter(|o| o.peer == r.peer).count();
        if best.is_none_or(|(bn, bp)| n > bn || (n == bn && r.peer < bp)) {
            best = Some((n, r.peer));
        }
    }
    best.map(|(_, p)| p)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Reading,
    Answering,
    Writing,
    Released,
}

/// One admitted connection's place; leaving it (drop) frees the place.
#[derive(Debug)]
pub struct Ticket {
    gate: Arc<Gate>,
    id: u64,
    state: State,
    /// The connection's handle while answering, for [`Ticket::writing`].
    handle: Option<(TcpStream, IpAddr)>,
}

impl Ticket {
    /// Its request has arrived: it now answers, and can no longer be evicted. `false` when it
    /// was evicted meanwhile (its connection is shut down: drop it).
    pub fn answering(&mut self) -> bool {
        let mut inner = self.gate.lock();
        let Some(i) = inner.reading.iter().position(|r| r.id == self.id) else {
            self.state = State::Released;
            return false;
        };
        let r = inner.reading.swap_remove(i);
        self.handle = Some((r.stream, r.peer));
        inner.answering += 1;
        self.state = State::Answering;
        true
    }

    /// Its answer (`bytes` long) is made and is being written: from now on it may be evicted
    /// (shut down, so that the write fails at once) to make room, as the module docs say.
    pub fn writing(&mut self, bytes: usize) {
        let Some((stream, peer)) = self.handle.take().filter(|_| self.state == State::Answering) else {
            return;
        };
        let gate = Arc::clone(&self.gate);
        let mut inner = gate.lock();
        let budget = gate.limits.max_writing_bytes;
        while inner.writing.iter().map(|w| w.bytes).sum::<usize>().saturating_add(bytes) > budget
            && evict_oldest(&mut inner.writing, None, &gate.counters)
        {}
        inner.answering -= 1;
        inner.writing.push(Reader { id: self.id, peer, since: Instant::now(), stream, bytes });
        self.state = State::Writing;
    }

    /// Its request did not arrive in time (counted).
    pub fn timed_out(&self) {
        self.gate.counters.timed_out.fetch_add(1, Ordering::Relaxed);
    }

    /// The connection leaves the gate's count (a WebSocket, which its server counts itself).
    pub fn release(mut self) {
        self.leave();
    }

    fn leave(&mut self) {
        let mut inner = self.gate.lock();
        match self.state {
            State::Reading => inner.reading.retain(|r| r.id != self.id),
            State::Answering => inner.answering -= 1,
            State::Writing => inner.writing.retain(|r| r.id != self.id),
            State::Released => {}
        }
        self.state = State::Released;
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        self.leave();
    }
}

#[cfg(test)]
mod tests {
    use std::io::Read;
    use std::net::{Ipv4Addr, TcpListener};

    use super::*;

    /// A connected pair: (the server's end, the client's end).
    fn pair(l: &TcpListener) -> (TcpStream, TcpStream) {
        let c = TcpStream::connect(l.local_addr().unwrap()).unwrap();
        let (s, _) = l.accept().unwrap();
        (s, c)
    }

    fn ip(last: u8) -> IpAddr {
        IpAddr::V4(Ipv4Addr::new(10, 0, 0, last))
    }

    /// Whether the server end `s` was shut down (a read returns at once with nothing).
    fn shut(s: &mut TcpStream) -> bool {
        s.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
        matches!(s.read(&mut [0u8; 1]), Ok(0))
    }

    fn limits(max: usize, per_peer: usize) -> Limits {
        Limits { max_connections: max, max_reading_per_peer: per_peer, ..Limits::default() }
    }

    #[test]
    fn a_full_gate_evicts_the_oldest_reader_of_the_busiest_peer() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let gate = Gate::new(limits(4, 4));
        let mut conns: Vec<_> = (0..4).map(|_| pair(&l)).collect();
        // Peer 1 holds three, peer 2 one.
        let peers = [ip(1), ip(1), ip(2), ip(1)];
        let tickets: Vec<_> = conns.iter().zip(peers).map(|((s, _), p)| gate.admit(s, p).unwrap()).collect();
        assert_eq!(gate.load(), (4, 0));
        let (s5, _c5) = pair(&l);
        let _t5 = gate.admit(&s5, ip(3)).unwrap();
        assert_eq!(gate.load(), (4, 0));
        assert_eq!(gate.counters.evicted.load(Ordering::Relaxed), 1);
        // The first of peer 1 went; peer 2's one stayed.
        assert!(shut(&mut conns[0].0));
        assert!(!shut(&mut conns[2].0));
        drop(tickets);
        assert_eq!(gate.load(), (1, 0));
    }

    #[test]
    fn one_peer_over_its_share_loses_its_own_oldest() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let gate = Gate::new(limits(64, 2));
        let mut a = pair(&l);
        let b = pair(&l);
        let other = pair(&l);
        let _ta = gate.admit(&a.0, ip(1)).unwrap();
        let _tb = gate.admit(&b.0, ip(1)).unwrap();
        let _to = gate.admit(&other.0, ip(2)).unwrap();
        let c = pair(&l);
        let _tc = gate.admit(&c.0, ip(1)).unwrap();
        assert!(shut(&mut a.0));
        assert_eq!(gate.load(), (3, 0));
    }

    #[test]
    fn answering_connections_are_never_evicted_and_a_gate_of_them_is_full() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let gate = Gate::new(limits(2, 2));
        let (a, b) = (pair(&l), pair(&l));
        let mut ta = gate.admit(&a.0, ip(1)).unwrap();
        let mut tb = gate.admit(&b.0, ip(1)).unwrap();
        assert!(ta.answering() && tb.answering());
        let c = pair(&l);
        assert_eq!(gate.admit(&c.0, ip(1)).unwrap_err(), Full);
        assert_eq!(gate.counters.full.load(Ordering::Relaxed), 1);
        drop(ta);
        let mut tc = gate.admit(&c.0, ip(1)).unwrap();
        // Now full again with one reader: a newcomer evicts it, and the evicted one learns it.
        let d = pair(&l);
        let _td = gate.admit(&d.0, ip(1)).unwrap();
        assert!(!tc.answering());
        drop(tc);
        assert_eq!(gate.load(), (1, 1));
        tb.release();
        assert_eq!(gate.load(), (1, 0));
    }

    /// A client that asks for a large answer and never reads it held its place until the
    /// write deadline: a few dozen of them, asking again, kept every request 503.
    #[test]
    fn a_full_gate_of_unread_answers_cuts_the_oldest_writer_of_the_busiest_peer() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let gate = Gate::new(limits(3, 3));
        let mut conns: Vec<_> = (0..3).map(|_| pair(&l)).collect();
        let peers = [ip(1), ip(2), ip(1)];
        let mut tickets: Vec<_> =
            conns.iter().zip(peers).map(|((s, _), p)| gate.admit(s, p).unwrap()).collect();
        for t in &mut tickets {
            assert!(t.answering());
            t.writing(1000);
        }
        assert_eq!(gate.load(), (0, 3));
        let (s4, _c4) = pair(&l);
        let _t4 = gate.admit(&s4, ip(3)).expect("room is made for a newcomer");
        assert_eq!(gate.counters.evicted.load(Ordering::Relaxed), 1);
        assert_eq!(gate.counters.full.load(Ordering::Relaxed), 0);
        assert!(shut(&mut conns[0].0), "peer 1's oldest writer is cut");
        assert!(!shut(&mut conns[1].0) && !shut(&mut conns[2].0));
        assert_eq!(gate.load(), (1, 2));
        drop(tickets);
        assert_eq!(gate.load(), (1, 0));
    }

    #[test]
    fn answers_being_written_share_a_byte_budget() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let gate = Gate::new(Limits { max_writing_bytes: 100, ..limits(64, 64) });
        let mut conns: Vec<_> = (0..3).map(|_| pair(&l)).collect();
        let mut tickets: Vec<_> = conns.iter().map(|(s, _)| gate.admit(s, ip(1)).unwrap()).collect();
        for t in &mut tickets {
            assert!(t.answering());
        }
        tickets[0].writing(60);
        tickets[1].writing(30);
        assert!(!shut(&mut conns[0].0));
        // 60 + 30 + 50 > 100: the oldest is cut; 30 + 50 fit.
        tickets[2].writing(50);
        assert!(shut(&mut conns[0].0));
        assert!(!shut(&mut conns[1].0));
        assert_eq!(gate.counters.evicted.load(Ordering::Relaxed), 1);
        // One answer alone past the budget is still written.
        let (s, _c) = pair(&l);
        let mut big = gate.admit(&s, ip(1)).unwrap();
        assert!(big.answering());
        big.writing(1000);
        assert!(shut(&mut conns[1].0) && shut(&mut conns[2].0));
        assert_eq!(gate.load(), (0, 1));
        drop(tickets);
        assert_eq!(gate.load(), (0, 1));
    }
}
