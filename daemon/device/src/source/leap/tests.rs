//! The Leap backend against fake services that misbehave: flooding pings, trickling, oversized
//! messages, sending flat out; each is read at a bounded pace, dropped, and never holds a stop.

use std::io::Write as _;
use std::net::TcpStream;
use std::os::fd::AsRawFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use super::source::STOP_WAIT;
use super::{LeapSource, MAX_MESSAGE_BYTES};
use crate::report::DeviceSample;
use crate::source::hand::HandSource;

/// A fake service on a fresh port: after the handshake and the greeting, each connection
/// is handed to `then` (on its own thread). Returns the port and the connections taken.
fn service(
    then: impl Fn(tungstenite::WebSocket<TcpStream>) + Send + Sync + 'static,
) -> (u16, Arc<AtomicU64>) {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let small: libc::c_int = 4096;
    // SAFETY: a listening socket we own and a c_int option of the right size (accepted
    // sockets inherit it): the service's receive buffer fills at once.
    unsafe {
        libc::setsockopt(
            listener.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&small as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        );
    }
    let port = listener.local_addr().unwrap().port();
    let taken = Arc::new(AtomicU64::new(0));
    let (then, count) = (Arc::new(then), Arc::clone(&taken));
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(stream) = stream else { return };
            count.fetch_add(1, Ordering::Relaxed);
            let then = Arc::clone(&then);
            std::thread::spawn(move || {
                let Ok(mut ws) = tungstenite::accept(stream) else { return };
                let _ = ws.send(tungstenite::Message::text(r#"{"version": 6}"#));
                then(ws);
            });
        }
    });
    (port, taken)
}

fn connect(port: u16) -> LeapSource {
    LeapSource::connect(&format!("leap://127.0.0.1:{port}").parse().unwrap()).unwrap()
}

/// Drops `source` on another thread; how long that took, or `None` past `bound`.
fn drop_within(source: LeapSource, bound: Duration) -> Option<Duration> {
    let (tx, rx) = crossbeam_channel::bounded(1);
    std::thread::spawn(move || {
        let t0 = Instant::now();
        drop(source);
        let _ = tx.send(t0.elapsed());
    });
    rx.recv_timeout(bound).ok()
}

fn wait_until(bound: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + bound;
    while !cond() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    cond()
}

/// Raw unmasked pings as fast as the socket takes them; nothing is ever read.
fn flood_pings(mut ws: tungstenite::WebSocket<TcpStream>) {
    let ping: Vec<u8> = [0x89u8, 125].into_iter().chain(std::iter::repeat_n(b'p', 125)).collect();
    let burst = ping.repeat(512);
    let tcp = ws.get_mut();
    tcp.set_write_timeout(Some(Duration::from_millis(50))).unwrap();
    // Where the next write starts: a short write must not cut a ping in two.
    let mut at = 0;
    loop {
        match tcp.write(&burst[at..]) {
            Ok(n) => at = (at + n) % burst.len(),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(_) => return, // dropped by the client
        }
    }
}

/// Issue 42: a service that floods pings and never reads fills the socket with the pongs
/// it owes; the client's writes never wait, so it is dropped (counted) after
/// PEER_WRITE_DEADLINE and connected to again, and stopping the source takes no longer
/// than a read poll. (The old client blocked in the pong write, for ever: stopping the
/// source joined it.)
#[test]
fn a_service_that_floods_pings_and_never_reads_is_dropped_and_cannot_hold_a_stop() {
    let (port, taken) = service(flood_pings);
    let source = connect(port);
    let counters = source.counters();
    assert!(
        wait_until(Duration::from_secs(20), || counters.peers_dropped.load(Ordering::Relaxed) >= 1),
        "never dropped: {:?}",
        counters.snapshot()
    );
    assert!(wait_until(Duration::from_secs(10), || taken.load(Ordering::Relaxed) >= 2), "not reconnected");
    // Flooded again: stop now, in the middle of it.
    std::thread::sleep(Duration::from_millis(500));
    let took = drop_within(source, Duration::from_secs(5)).expect("the source did not stop");
    assert!(took <= STOP_WAIT + Duration::from_millis(500), "stopping took {took:?}");
}

/// Issue 42: a service trickling one message a byte at a time (each byte before the read
/// poll runs out) cannot keep the client reading past a stop.
#[test]
fn a_service_trickling_a_message_cannot_hold_a_stop() {
    let (port, taken) = service(|mut ws| {
        // A text frame of 120 bytes, sent one byte every 50 ms (6 s in all).
        let mut frame = vec![0x81u8, 120];
        frame.extend(std::iter::repeat_n(b' ', 120));
        for b in frame {
            if ws.get_mut().write_all(&[b]).is_err() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    });
    let source = connect(port);
    assert!(wait_until(Duration::from_secs(5), || taken.load(Ordering::Relaxed) >= 1));
    std::thread::sleep(Duration::from_millis(500));
    let took = drop_within(source, Duration::from_secs(4)).expect("the source did not stop");
    assert!(took <= STOP_WAIT + Duration::from_millis(500), "stopping took {took:?}");
}

/// Issue 42: a message longer than MAX_MESSAGE_BYTES is refused from its header (the
/// connection with it), counted as oversized; a frame of 5,000 hands as too_many; and a
/// good frame after them still gives a sample.
#[test]
fn oversized_messages_and_frames_of_too_many_hands_are_counted_by_reason() {
    let hand = r#"{"id":1,"type":"left","direction":[0,0,-1],"palmNormal":[0,-1,0]}"#;
    let many = format!(r#"{{"id":1,"timestamp":0,"hands":[{}]}}"#, vec![hand; 5000].join(","));
    let sent = Arc::new(AtomicU64::new(0));
    let turn = Arc::clone(&sent);
    let (port, _) = service(move |mut ws| {
        let good = r#"{"id":2,"timestamp":5,"hands":[{"id":7,"type":"right","direction":[0,0,-1],"palmNormal":[0,-1,0]}],"pointables":[{"handId":7,"type":0,"bases":[[[1,0,0],[0,1,0],[0,0,1]],[[1,0,0],[0,1,0],[0,0,1]],[[1,0,0],[0,1,0],[0,0,1]],[[1,0,0],[0,1,0],[0,0,1]]]}]}"#;
        if turn.fetch_add(1, Ordering::Relaxed) == 0 {
            let _ = ws.send(tungstenite::Message::text(many.clone()));
            let _ = ws.send(tungstenite::Message::text("x".repeat(MAX_MESSAGE_BYTES + 1)));
            std::thread::sleep(Duration::from_secs(10));
        } else {
            let _ = ws.send(tungstenite::Message::text(good));
            std::thread::sleep(Duration::from_secs(10));
        }
    });
    let mut source = connect(port);
    let counters = source.counters();
    let mut out = [DeviceSample::default(); 4];
    let mut got = 0;
    let deadline = Instant::now() + Duration::from_secs(10);
    while got == 0 && Instant::now() < deadline {
        got += source.read_pending(&mut out).unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    let c = counters.snapshot();
    assert_eq!((got, c.too_many, c.oversized, c.malformed), (1, 1, 1, 0), "{c:?}");
    assert_eq!(c.rejected(), 2);
}

/// Issue 42: a service sending as fast as it can (large messages of nothing frond uses) is
/// read at frond's pace, 10 MiB/s, not at its own: what it sends in 2 s, with every socket
/// buffer full, stays far below what loopback carries (the old client read and parsed all
/// of it, hundreds of MiB a second, as fast as a core could).
#[test]
fn a_service_sending_as_fast_as_it_can_is_read_at_a_bounded_pace() {
    let written = Arc::new(AtomicU64::new(0));
    let total = Arc::clone(&written);
    let (port, _) = service(move |mut ws| {
        let body = format!(r#"{{"pad":"{}"}}"#, "x".repeat(500_000));
        let mut frame = vec![0x81u8, 127];
        frame.extend_from_slice(&(body.len() as u64).to_be_bytes());
        frame.extend_from_slice(body.as_bytes());
        let tcp = ws.get_mut();
        tcp.set_write_timeout(Some(Duration::from_millis(100))).unwrap();
        let t0 = Instant::now();
        let mut at = 0;
        while t0.elapsed() < Duration::from_secs(2) {
            match tcp.write(&frame[at..]) {
                Ok(n) => {
                    total.fetch_add(n as u64, Ordering::Relaxed);
                    at = (at + n) % frame.len();
                }
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
                Err(_) => return,
            }
        }
    });
    let source = connect(port);
    std::thread::sleep(Duration::from_millis(2500));
    let sent = written.load(Ordering::Relaxed);
    let counters = source.counters().snapshot();
    drop(source);
    // 2 s at 10 MiB/s, plus both sockets' buffers (a few MiB each), generously.
    assert!(sent > 0);
    assert!(sent < 60 << 20, "the service got {} MiB read in 2 s", sent >> 20);
    assert_eq!(counters.rejected(), 0, "{counters:?}");
}

/// Writes `head` once, then `body` again and again as fast as the socket takes it, for at
/// most `for_how_long` or until the client drops the connection; `started` is set when the
/// flood begins.
fn flood(
    ws: &mut tungstenite::WebSocket<TcpStream>,
    head: &[u8],
    body: &[u8],
    for_how_long: Duration,
    started: &std::sync::OnceLock<Instant>,
) {
    let tcp = ws.get_mut();
    if tcp.write_all(head).is_err() {
        return;
    }
    let burst = body.repeat(4096);
    tcp.set_write_timeout(Some(Duration::from_millis(50))).unwrap();
    let t0 = *started.get_or_init(Instant::now);
    let mut at = 0;
    while t0.elapsed() < for_how_long {
        match tcp.write(&burst[at..]) {
            Ok(n) => at = (at + n) % burst.len(),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(_) => return,
        }
    }
}

/// Issue 42: a service sending empty text messages (2-byte frames) flat out is read at
/// frond's pace in messages, not only in bytes: each frame costs FRAME_COST (1 KiB) of the
/// 1 MiB budget per 100 ms window, so at most 1,024 frames (+1 started at the edge) a
/// window; a 1 s span overlaps at most 11 windows: 11 * 1,025 = 11,275 messages, however
/// fast the service sends (the old client parsed and refused about 2 million a second).
/// And a service that only sends junk is dropped, counted as peers_dropped.
#[test]
fn a_leap_service_sending_empty_messages_flat_out_is_read_at_a_bounded_pace_and_dropped() {
    let started: Arc<std::sync::OnceLock<Instant>> = Arc::default();
    let t0 = Arc::clone(&started);
    let (port, _) = service(move |mut ws| {
        flood(&mut ws, &[], &[0x81, 0x00], Duration::from_secs(20), &t0);
    });
    let source = connect(port);
    let counters = source.counters();
    assert!(wait_until(Duration::from_secs(5), || started.get().is_some()), "the flood did not start");
    // A second of it, from a first message on.
    assert!(wait_until(Duration::from_secs(5), || counters.malformed.load(Ordering::Relaxed) > 0));
    let before = counters.malformed.load(Ordering::Relaxed);
    std::thread::sleep(Duration::from_secs(1));
    let in_a_second = counters.malformed.load(Ordering::Relaxed) - before;
    assert!(in_a_second > 0);
    assert!(in_a_second <= 11 * 1025, "{in_a_second} empty messages read in 1 s");
    assert!(
        wait_until(Duration::from_secs(10), || counters.peers_dropped.load(Ordering::Relaxed) >= 1),
        "never dropped: {:?}",
        counters.snapshot()
    );
}

/// Issue 42: endless zero-length fragments of a message that never ends are paid for frame
/// by frame; the service never sends a message frond can use, so it is dropped (the old
/// client read them at 10 MiB/s and kept the connection for ever).
#[test]
fn a_leap_service_sending_endless_empty_fragments_is_dropped() {
    let (port, _) = service(move |mut ws| {
        // A text frame that is not the last (FIN clear), then continuations, all empty.
        flood(&mut ws, &[0x01, 0x00], &[0x00, 0x00], Duration::from_secs(20), &Default::default());
    });
    let source = connect(port);
    let counters = source.counters();
    assert!(
        wait_until(Duration::from_secs(10), || counters.peers_dropped.load(Ordering::Relaxed) >= 1),
        "never dropped: {:?}",
        counters.snapshot()
    );
    assert_eq!(counters.snapshot().rejected(), 0);
}
