//! OSC hand input: any tracker that can send wrist and thumb angles drives frond (seed 000,
//! section 5.4: the method is device independent).
//!
//! Message: `/frond/hand` with seven numbers (`f` or `d`, `i` accepted too): `t` (seconds), wrist
//! pitch, yaw, roll, thumb g1, g2, g3 (degrees). Bundles are unpacked. Anything else is counted
//! and dropped: undecodable datagrams and wrong argument lists as `malformed`, other addresses as
//! `wrong_id`, non-finite or beyond +-360 degree values as `out_of_range`.
//!
//! The realtime loop polls the UDP socket itself (its ready descriptor) and decodes each datagram
//! in place with the allocation-free [`super::osc_wire`] decoder: one hop from the tracker to the
//! subscribers, no receiver thread. [`decode_hand_packet`] (rosc, allocating) is the reference
//! the in-place decoder is tested against, and what the fuzzer drives.

use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::Ordering;

use frond_motion::HandSample;
use rosc::{OscPacket, OscType};

pub use super::osc_wire::OSC_HAND_ADDRESS;
use super::osc_wire::{MAX_BUNDLE_DEPTH, Reject, for_each_hand};
use frond_protocol::SourceKind;

use super::hand::{HandSource, SourceError};
use super::spec::{Backend, SourceSpec, SpecError, SpecInput};
use crate::report::{DeviceSample, SourceCounters};

/// `osc://IP:PORT`: `/frond/hand` messages received on that UDP address.
pub(crate) const BACKEND: Backend = Backend { syntax: "osc://IP:PORT", parse };

fn parse(kind: &str, input: &SpecInput<'_>) -> Option<Result<SourceSpec, SpecError>> {
    let addr = kind.strip_prefix("osc://")?;
    Some(match addr.parse::<SocketAddr>() {
        Ok(_) => Ok(SourceSpec::Osc(addr.to_string())),
        Err(_) => Err(SpecError::BadOsc { key: input.key.to_string(), kind: kind.to_string() }),
    })
}

/// Largest UDP datagram.
const DATAGRAM_MAX: usize = 65_536;
/// Samples one datagram can hold at most (a `/frond/hand` message takes 52 bytes in a bundle):
/// what does not fit the caller's buffer waits here for the next `read_pending`.
const PENDING_MAX: usize = DATAGRAM_MAX / 48 + 1;
/// Samples a second one OSC source may bring, sustained: twice the fastest hand tracker's rate
/// (1 kHz) and four times the daemon's default tick. Past it, samples are refused and counted
/// as `too_many`, so a flood costs the loop a bounded amount of work a second, whatever it sends.
pub const MAX_SAMPLE_RATE_HZ: f64 = 2000.0;
/// Samples an OSC source may bring at once above its rate: a tracker that sends a second of
/// samples in one bundle (issue 14) loses none.
pub const MAX_SAMPLE_BURST: f64 = PENDING_MAX as f64;
/// Datagrams one `read_pending` reads at most while they hold no sample (a flood of refused
/// datagrams is left for the next call, not read to the end on the loop's thread).
const MAX_EMPTY_DATAGRAMS_PER_READ: usize = 64;

/// The samples a source may still take now: [`MAX_SAMPLE_BURST`] at most, refilled at
/// [`MAX_SAMPLE_RATE_HZ`] (a token bucket on the monotonic clock; never allocates).
#[derive(Debug, Clone, Copy)]
struct SampleBudget {
    tokens: f64,
    at: std::time::Instant,
}

impl SampleBudget {
    fn full() -> SampleBudget {
        SampleBudget { tokens: MAX_SAMPLE_BURST, at: std::time::Instant::now() }
    }

    /// Refills for the time since the last call.
    fn refill(&mut self, now: std::time::Instant) {
        let dt = now.saturating_duration_since(self.at).as_secs_f64();
        self.tokens = (self.tokens + dt * MAX_SAMPLE_RATE_HZ).min(MAX_SAMPLE_BURST);
        self.at = now;
    }

    /// Takes one sample's token, or `false` when none is left.
    fn take(&mut self) -> bool {
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

/// Why one OSC message was dropped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OscHandError {
    /// Not an OSC packet, or wrong arguments.
    Malformed(String),
    /// Another address.
    OtherAddress(String),
    /// A value out of range.
    OutOfRange(String),
}

fn number(arg: &OscType) -> Option<f64> {
    match *arg {
        OscType::Float(v) => Some(f64::from(v)),
        OscType::Double(v) => Some(v),
        OscType::Int(v) => Some(f64::from(v)),
        _ => None,
    }
}

fn decode_message(msg: &rosc::OscMessage) -> Result<HandSample, OscHandError> {
    if msg.addr != OSC_HAND_ADDRESS {
        return Err(OscHandError::OtherAddress(msg.addr.clone()));
    }
    if msg.args.len() != 7 {
        return Err(OscHandError::Malformed(format!(
            "{OSC_HAND_ADDRESS} takes 7 numbers (t, wrist pitch yaw roll, thumb g1 g2 g3), got {} arguments",
            msg.args.len()
        )));
    }
    let mut v = [0.0f64; 7];
    for (i, arg) in msg.args.iter().enumerate() {
        v[i] = number(arg)
            .ok_or_else(|| OscHandError::Malformed(format!("argument {i} is {arg:?}, not a number")))?;
    }
    let hand = HandSample {
        t: v[0],
        wrist_deg: [v[1] as f32, v[2] as f32, v[3] as f32],
        thumb_deg: [v[4] as f32, v[5] as f32, v[6] as f32],
    };
    hand.check_plausible().map_err(|e| OscHandError::OutOfRange(e.to_string()))?;
    Ok(hand)
}

fn collect(packet: &OscPacket, out: &mut Vec<Result<HandSample, OscHandError>>) {
    match packet {
        OscPacket::Message(m) => out.push(decode_message(m)),
        OscPacket::Bundle(b) => b.content.iter().for_each(|p| collect(p, out)),
    }
}

// MAX_BUNDLE_DEPTH: rosc decodes nested bundles recursively, so one datagram of a few thousand
// nested bundles (64 KiB holds over 3000) would overflow the stack and abort the daemon.

/// How deep bundles nest in `datagram` (0 for a message), walking the element size fields
/// without recursion; stops counting once past `limit`.
fn bundle_depth(datagram: &[u8], limit: usize) -> usize {
    const BUNDLE_HEAD: usize = 16; // "#bundle\0" and the 8-byte time tag
    let mut deepest = 0;
    let mut pending: Vec<(&[u8], usize)> = vec![(datagram, 1)];
    while let Some((element, depth)) = pending.pop() {
        if !element.starts_with(b"#bundle\0") {
            continue;
        }
        deepest = deepest.max(depth);
        if deepest > limit {
            break;
        }
        let mut rest = element.get(BUNDLE_HEAD..).unwrap_or(&[]);
        while let Some(size) = rest.first_chunk::<4>().map(|b| u32::from_be_bytes(*b) as usize) {
            let Some(inner) = rest.get(4..4 + size) else { break };
            pending.push((inner, depth + 1));
            rest = &rest[4 + size..];
        }
    }
    deepest
}

/// Decodes one UDP datagram into hand samples (or the reason each message was dropped).
pub fn decode_hand_packet(datagram: &[u8]) -> Vec<Result<HandSample, OscHandError>> {
    if bundle_depth(datagram, MAX_BUNDLE_DEPTH) > MAX_BUNDLE_DEPTH {
        return vec![Err(OscHandError::Malformed(format!("bundles nested deeper than {MAX_BUNDLE_DEPTH}")))];
    }
    match rosc::decoder::decode_udp(datagram) {
        Ok((_, packet)) => {
            let mut out = Vec::new();
            collect(&packet, &mut out);
            out
        }
        Err(e) => vec![Err(OscHandError::Malformed(format!("not an OSC packet: {e:?}")))],
    }
}

/// Hand samples received as OSC over UDP, read and decoded by the loop itself.
pub struct OscHandSource {
    socket: UdpSocket,
    buf: Box<[u8]>,
    /// Samples of the last datagram that did not fit the caller's buffer, in order.
    pending: Box<[DeviceSample]>,
    pending_at: usize,
    pending_len: usize,
    seq: u32,
    /// The kernel's count of datagrams it dropped for this socket, as last read (`SO_RXQ_OVFL`).
    kernel_drops: u32,
    counters: Arc<SourceCounters>,
    describe: String,
    local: SocketAddr,
    budget: SampleBudget,
}

/// `SO_RXQ_OVFL` (the generic Linux value; not exported by every libc version): each received
/// datagram carries the socket's count of datagrams dropped because its receive buffer was full.
const SO_RXQ_OVFL: libc::c_int = 40;

/// Asks the kernel to report dropped datagrams with every datagram received. `false` when it
/// refuses (then drops stay uncounted, as they would be anyway).
fn count_kernel_drops(socket: &UdpSocket) -> bool {
    use std::os::fd::AsRawFd;
    let on: libc::c_int = 1;
    // SAFETY: a valid socket descriptor we own and a c_int option value of the right size.
    unsafe {
        libc::setsockopt(
            socket.as_raw_fd(),
            libc::SOL_SOCKET,
            SO_RXQ_OVFL,
            (&on as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        ) == 0
    }
}

impl OscHandSource {
    /// Binds `addr` (e.g. `127.0.0.1:9001`), non-blocking.
    pub fn bind(addr: &str) -> Result<Self, SourceError> {
        let what = format!("osc://{addr}");
        let open_err = |e: std::io::Error| SourceError::Open { what: what.clone(), reason: e.to_string() };
        let socket = UdpSocket::bind(addr).map_err(open_err)?;
        socket.set_nonblocking(true).map_err(open_err)?;
        let local = socket.local_addr().map_err(open_err)?;
        count_kernel_drops(&socket);
        Ok(Self {
            socket,
            buf: vec![0u8; DATAGRAM_MAX].into_boxed_slice(),
            pending: vec![DeviceSample::default(); PENDING_MAX].into_boxed_slice(),
            pending_at: 0,
            pending_len: 0,
            seq: 0,
            kernel_drops: 0,
            counters: Arc::new(SourceCounters::default()),
            describe: format!("osc://{local}"),
            local,
            budget: SampleBudget::full(),
        })
    }

    /// The bound address (useful with port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// Receives one datagram into `buf` without blocking, and counts the datagrams the kernel
    /// dropped since the last one (its receive buffer was full: the tracker sent faster than the
    /// loop read) as `seq_gaps`, lost reports like a glove's sequence gaps. One `recvmsg`, no
    /// allocation.
    fn recv(&mut self) -> std::io::Result<usize> {
        use std::os::fd::AsRawFd;
        let mut iov = libc::iovec { iov_base: self.buf.as_mut_ptr().cast(), iov_len: self.buf.len() };
        // Room for one cmsghdr and a u32, 8-byte aligned.
        let mut control = [0u64; 4];
        // SAFETY: msghdr is plain data; every pointer set below outlives the call.
        let mut msg: libc::msghdr = unsafe { std::mem::zeroed() };
        msg.msg_iov = &mut iov;
        msg.msg_iovlen = 1;
        msg.msg_control = control.as_mut_ptr().cast();
        msg.msg_controllen = std::mem::size_of_val(&control) as _;
        // SAFETY: a socket we own; `msg` points at `iov` (into our own buffer of `iov_len`
        // bytes) and at `control`, both live and exclusively borrowed for the call.
        let n = unsafe { libc::recvmsg(self.socket.as_raw_fd(), &mut msg, libc::MSG_DONTWAIT) };
        if n < 0 {
            return Err(std::io::Error::last_os_error());
        }
        // SAFETY: `msg` was filled by recvmsg; CMSG_FIRSTHDR/CMSG_NXTHDR stay inside
        // `msg_control[..msg_controllen]`, and a SO_RXQ_OVFL header carries a u32.
        unsafe {
            let mut c = libc::CMSG_FIRSTHDR(&msg);
            while !c.is_null() {
                if (*c).cmsg_level == libc::SOL_SOCKET && (*c).cmsg_type == SO_RXQ_OVFL {
                    let drops = std::ptr::read_unaligned(libc::CMSG_DATA(c).cast::<u32>());
                    let new = drops.wrapping_sub(self.kernel_drops);
                    self.kernel_drops = drops;
                    if new > 0 {
                        SourceCounters::bump(&self.counters.seq_gaps, u64::from(new));
                    }
                }
                c = libc::CMSG_NXTHDR(&msg, c);
            }
        }
        Ok(n as usize)
    }

    /// Decodes the datagram in `buf[..len]`: samples into `out[n..]`, the rest into `pending`.
    /// Samples past the source's [`SampleBudget`] are refused as `too_many`.
    fn decode(&mut self, len: usize, out: &mut [DeviceSample], n: &mut usize) {
        let Self { buf, pending, pending_len, seq, counters, budget, .. } = self;
        let bump = |c: &std::sync::atomic::AtomicU64| c.fetch_add(1, Ordering::Relaxed);
        budget.refill(std::time::Instant::now());
        for_each_hand(&buf[..len], &mut |item| match item {
            Ok(_) if !budget.take() => {
                bump(&counters.too_many);
            }
            Ok(hand) => {
                *seq = seq.wrapping_add(1);
                let sample = DeviceSample {
                    device_seq: *seq,
                    device_time_us: (hand.t * 1e6).round() as u64,
                    raw: hand,
                    flex_deg: [0.0; 4],
                    status: 1,
                };
                bump(&counters.reports);
                if *n < out.len() {
                    out[*n] = sample;
                    *n += 1;
                } else if *pending_len < pending.len() {
                    pending[*pending_len] = sample;
                    *pending_len += 1;
                } else {
                    // Cannot happen: a datagram holds at most PENDING_MAX messages.
                    bump(&counters.seq_gaps);
                }
            }
            Err(Reject::Malformed) => {
                bump(&counters.malformed);
            }
            Err(Reject::OtherAddress) => {
                bump(&counters.wrong_id);
            }
            Err(Reject::OutOfRange) => {
                bump(&counters.out_of_range);
            }
        });
    }
}

impl HandSource for OscHandSource {
    fn kind(&self) -> SourceKind {
        SourceKind::Osc
    }

    fn describe(&self) -> &str {
        &self.describe
    }

    fn ready_fd(&self) -> Option<std::os::fd::RawFd> {
        Some(std::os::fd::AsRawFd::as_raw_fd(&self.socket))
    }

    /// Takes what the last datagram left, or else the next datagram waiting on the socket: one
    /// `recv` per call that finds one. Not draining until `EAGAIN` saves a system call per sample
    /// at the tracker's rate (the loop's `ppoll` is level-triggered: a socket with more
    /// datagrams wakes it again at once). Never blocks, never allocates.
    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        let mut n = 0;
        while n < out.len() && self.pending_at < self.pending_len {
            out[n] = self.pending[self.pending_at];
            self.pending_at += 1;
            n += 1;
        }
        if self.pending_at == self.pending_len {
            (self.pending_at, self.pending_len) = (0, 0);
        } else {
            return Ok(n);
        }
        for _ in 0..MAX_EMPTY_DATAGRAMS_PER_READ {
            if n > 0 {
                break;
            }
            match self.recv() {
                // A datagram of only rejected messages gives nothing: try the next one.
                Ok(len) => self.decode(len, out, &mut n),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                // WouldBlock: nothing more; anything else (an ICMP error on a UDP socket) is
                // not a lost source either.
                Err(_) => break,
            }
        }
        Ok(n)
    }

    fn counters(&self) -> Arc<SourceCounters> {
        Arc::clone(&self.counters)
    }

    fn reopen(&mut self) -> Result<(), SourceError> {
        // A UDP listener has nothing to reopen; it never reports Disconnected.
        Ok(())
    }
}

#[cfg(test)]
pub(super) mod tests {
    use std::time::Duration;

    use super::*;

    /// One hand message inside `depth` nested bundles, each level's size field covering the rest.
    pub(crate) fn nested_bundles(depth: usize) -> Vec<u8> {
        let mut out = hand_bytes();
        for _ in 0..depth {
            let mut b = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
            b.extend_from_slice(&(out.len() as u32).to_be_bytes());
            b.extend_from_slice(&out);
            out = b;
        }
        out
    }

    #[test]
    fn deeply_nested_bundles_are_refused_not_a_stack_overflow() {
        // Found by frond-fuzz (fuzz/corpus/osc-hand/crash-nested-bundles): ~3000 levels in one
        // 64 KiB datagram overflowed the 2 MiB stack inside rosc's recursive decoder.
        let deep = nested_bundles(3200);
        assert!(deep.len() <= 65_507, "fits one UDP datagram");
        let out = decode_hand_packet(&deep);
        assert!(
            matches!(&out[..], [Err(OscHandError::Malformed(m))] if m.contains("nested deeper")),
            "{out:?}"
        );
        let ok = decode_hand_packet(&nested_bundles(MAX_BUNDLE_DEPTH));
        assert!(matches!(&ok[..], [Ok(_)]), "{ok:?}");
        assert_eq!(bundle_depth(&hand_bytes(), MAX_BUNDLE_DEPTH), 0);
        assert_eq!(bundle_depth(&nested_bundles(3), MAX_BUNDLE_DEPTH), 3);
        // The loop's own decoder refuses it too (without recursing into 3200 levels).
        let mut src = OscHandSource::bind("127.0.0.1:0").unwrap();
        src.buf[..deep.len()].copy_from_slice(&deep);
        let (mut out, mut n) = ([DeviceSample::default(); 4], 0);
        src.decode(deep.len(), &mut out, &mut n);
        assert_eq!((n, src.counters().snapshot().malformed), (0, 1));
    }

    /// `/frond/hand ,fffffff` with t = 0.5, wrist 10 -20 30, thumb 1 2 3, encoded by hand.
    pub(crate) fn hand_bytes() -> Vec<u8> {
        let mut b = b"/frond/hand\0".to_vec(); // 11 chars + NUL = 12, aligned
        b.extend_from_slice(b",fffffff\0\0\0\0"); // 8 chars + NUL padded to 12
        for v in [0.5f32, 10.0, -20.0, 30.0, 1.0, 2.0, 3.0] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b
    }

    #[test]
    fn decodes_a_hand_written_message() {
        let got = decode_hand_packet(&hand_bytes());
        assert_eq!(
            got,
            vec![Ok(HandSample { t: 0.5, wrist_deg: [10.0, -20.0, 30.0], thumb_deg: [1.0, 2.0, 3.0] })]
        );
    }

    #[test]
    fn counts_and_drops_bad_messages() {
        assert!(matches!(decode_hand_packet(b"garbage")[0], Err(OscHandError::Malformed(_))));
        let mut other = hand_bytes();
        other[1..6].copy_from_slice(b"xxxxx");
        assert!(matches!(decode_hand_packet(&other)[0], Err(OscHandError::OtherAddress(_))));
        let mut wild = hand_bytes();
        let at = wild.len() - 4 * 6; // wrist pitch
        wild[at..at + 4].copy_from_slice(&1000.0f32.to_be_bytes());
        assert!(matches!(decode_hand_packet(&wild)[0], Err(OscHandError::OutOfRange(_))));
        let mut nan = hand_bytes();
        let at = nan.len() - 4;
        nan[at..].copy_from_slice(&f32::NAN.to_be_bytes());
        assert!(matches!(decode_hand_packet(&nan)[0], Err(OscHandError::OutOfRange(_))));
        let short = rosc::encoder::encode(&OscPacket::Message(rosc::OscMessage {
            addr: OSC_HAND_ADDRESS.into(),
            args: vec![OscType::Float(1.0)],
        }))
        .unwrap();
        assert!(matches!(decode_hand_packet(&short)[0], Err(OscHandError::Malformed(_))));
    }

    #[test]
    fn source_delivers_in_order_and_counts_rejects() {
        let mut src = OscHandSource::bind("127.0.0.1:0").unwrap();
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        for k in 0..20 {
            let msg = OscPacket::Message(rosc::OscMessage {
                addr: OSC_HAND_ADDRESS.into(),
                args: [k as f32 * 0.01, k as f32, 0.0, 0.0, 5.0, 5.0, 5.0]
                    .into_iter()
                    .map(OscType::Float)
                    .collect(),
            });
            tx.send_to(&rosc::encoder::encode(&msg).unwrap(), src.local_addr()).unwrap();
        }
        tx.send_to(b"not osc", src.local_addr()).unwrap();
        let mut out = [DeviceSample::default(); 64];
        let mut got = Vec::new();
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while got.len() < 20 && std::time::Instant::now() < deadline {
            let n = src.read_pending(&mut out).unwrap();
            got.extend_from_slice(&out[..n]);
            std::thread::sleep(Duration::from_millis(5));
        }
        assert_eq!(got.len(), 20);
        for (k, s) in got.iter().enumerate() {
            assert_eq!(s.raw.wrist_deg[0], k as f32);
            assert_eq!(s.device_time_us, (k as f64 * f64::from(0.01f32) * 1e6).round() as u64);
        }
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while src.counters().snapshot().malformed == 0 && std::time::Instant::now() < deadline {
            assert_eq!(src.read_pending(&mut out).unwrap(), 0);
            std::thread::sleep(Duration::from_millis(5));
        }
        let c = src.counters().snapshot();
        assert_eq!((c.reports, c.malformed), (20, 1));
    }

    /// Issue 14, point 13: datagrams the kernel drops because the loop did not read fast enough
    /// are counted (as `seq_gaps`), exactly: every datagram sent is either read or counted.
    #[test]
    fn datagrams_the_kernel_drops_are_counted() {
        let mut src = OscHandSource::bind("127.0.0.1:0").unwrap();
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let sent = 5000u64;
        for k in 0..sent {
            let msg = OscPacket::Message(rosc::OscMessage {
                addr: OSC_HAND_ADDRESS.into(),
                args: [k as f32 * 1e-3, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
                    .into_iter()
                    .map(OscType::Float)
                    .collect(),
            });
            tx.send_to(&rosc::encoder::encode(&msg).unwrap(), src.local_addr()).unwrap();
        }
        // Nothing read while they were sent: the receive buffer overflowed.
        let mut out = [DeviceSample::default(); 64];
        let mut read = 0u64;
        while let Ok(n) = src.read_pending(&mut out) {
            if n == 0 {
                break;
            }
            read += n as u64;
        }
        // The kernel stamps its drop count on the datagrams it queues after the drops: the next
        // one the tracker sends tells.
        assert!(read < sent, "the receive buffer never overflowed");
        let msg = OscPacket::Message(rosc::OscMessage {
            addr: OSC_HAND_ADDRESS.into(),
            args: [9.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0].into_iter().map(OscType::Float).collect(),
        });
        tx.send_to(&rosc::encoder::encode(&msg).unwrap(), src.local_addr()).unwrap();
        let (before, deadline) = (read, std::time::Instant::now() + Duration::from_secs(5));
        while read == before && std::time::Instant::now() < deadline {
            read += src.read_pending(&mut out).unwrap() as u64;
        }
        let c = src.counters().snapshot();
        assert_eq!(read + c.seq_gaps, sent + 1, "read {read}, counted {}", c.seq_gaps);
        assert_eq!(c.reports, read);
    }

    /// One datagram: a bundle of 1000 hand messages, message `k` at `t = k ms` with wrist pitch
    /// `pitch(k)`.
    fn thousand_hands(pitch: impl Fn(usize) -> f32) -> Vec<u8> {
        let content = (0..1000)
            .map(|k| {
                OscPacket::Message(rosc::OscMessage {
                    addr: OSC_HAND_ADDRESS.into(),
                    args: [k as f32 * 1e-3, pitch(k), 0.0, 0.0, 0.0, 0.0, 0.0]
                        .into_iter()
                        .map(OscType::Float)
                        .collect(),
                })
            })
            .collect();
        let bundle = OscPacket::Bundle(rosc::OscBundle { timetag: rosc::OscTime::from((0, 1)), content });
        rosc::encoder::encode(&bundle).unwrap()
    }

    /// Issue 14, point 13: a bundle holding far more samples than one read takes loses none.
    /// The rest of the datagram waits in the source and comes out, in order, on the next reads.
    #[test]
    fn a_bundle_larger_than_a_read_loses_nothing() {
        let mut src = OscHandSource::bind("127.0.0.1:0").unwrap();
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let bytes = thousand_hands(|k| (k % 300) as f32);
        assert!(bytes.len() <= DATAGRAM_MAX, "{} bytes", bytes.len());
        tx.send_to(&bytes, src.local_addr()).unwrap();
        let mut out = [DeviceSample::default(); 8];
        let mut got = Vec::new();
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while got.len() < 1000 && std::time::Instant::now() < deadline {
            let n = src.read_pending(&mut out).unwrap();
            got.extend(out[..n].iter().map(|s| s.raw.wrist_deg[0]));
        }
        let want: Vec<f32> = (0..1000).map(|k| (k % 300) as f32).collect();
        assert_eq!(got, want);
        let c = src.counters().snapshot();
        assert_eq!((c.reports, c.seq_gaps, c.malformed), (1000, 0, 0));
    }

    /// A flood of valid samples is taken at the source's rate, the rest refused and counted as
    /// `too_many`: bundles of 1000 hands sent flat out for 0.5 s bring at most the burst plus
    /// 0.5 s at [`MAX_SAMPLE_RATE_HZ`] (worked out: 1366 + 1000 = 2366), not the ~1M sent.
    #[test]
    fn a_flood_of_valid_samples_is_taken_at_the_sources_rate() {
        let mut src = OscHandSource::bind("127.0.0.1:0").unwrap();
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let bytes = thousand_hands(|_| 1.0);
        let mut out = [DeviceSample::default(); 64];
        let (mut got, mut sent) = (0u64, 0u64);
        let start = std::time::Instant::now();
        let span = Duration::from_millis(500);
        while start.elapsed() < span {
            for _ in 0..4 {
                if tx.send_to(&bytes, src.local_addr()).is_ok() {
                    sent += 1000;
                }
            }
            for _ in 0..64 {
                match src.read_pending(&mut out).unwrap() {
                    0 => break,
                    n => got += n as u64,
                }
            }
        }
        let elapsed = start.elapsed().as_secs_f64();
        let c = src.counters().snapshot();
        let most = MAX_SAMPLE_BURST + elapsed * MAX_SAMPLE_RATE_HZ + 1.0;
        assert!(sent > 20_000, "the flood was a flood: {sent}");
        assert!((got as f64) <= most, "took {got} samples in {elapsed:.3} s; at most {most:.0}");
        assert!(c.too_many > 0, "{c:?}");
        assert_eq!(c.reports, got);
    }

    /// The loop waits on the OSC source's ready descriptor: quiet with nothing queued, readable
    /// as soon as a sample is, quiet again once `read_pending` took it.
    #[test]
    fn ready_descriptor_wakes_a_poll_per_sample() {
        let poll = |fd: i32, ms: i32| {
            let mut pfd = libc::pollfd { fd, events: libc::POLLIN, revents: 0 };
            // SAFETY: one valid pollfd.
            unsafe { libc::poll(&mut pfd, 1, ms) == 1 }
        };
        let mut src = OscHandSource::bind("127.0.0.1:0").unwrap();
        let fd = src.ready_fd().expect("a ready descriptor");
        assert!(!poll(fd, 50));
        let msg = OscPacket::Message(rosc::OscMessage {
            addr: OSC_HAND_ADDRESS.into(),
            args: [0.5f32, 1.0, 2.0, 3.0, 5.0, 5.0, 5.0].into_iter().map(OscType::Float).collect(),
        });
        UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .send_to(&rosc::encoder::encode(&msg).unwrap(), src.local_addr())
            .unwrap();
        assert!(poll(fd, 10_000), "the sample did not wake the poll");
        let mut out = [DeviceSample::default(); 4];
        assert_eq!(src.read_pending(&mut out).unwrap(), 1);
        assert_eq!(out[0].raw.wrist_deg, [1.0, 2.0, 3.0]);
        assert!(!poll(fd, 50), "still readable after the sample was taken");
    }
}
