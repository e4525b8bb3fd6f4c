//! `frond-bench-peer`: the remote end of `frond bench`'s `zenoh` section, one process per
//! subscriber, started inside a network namespace (`ip netns exec NS frond-bench-peer ...`) so
//! its sockets live on that "host".
//!
//! Usage:
//! - `frond-bench-peer zenoh-sub ADDRESS`: subscribes to `ADDRESS` (`zenoh:frond/<stage>/<source>?connect=...`)
//!   with `frond_sdk`, exactly as an exporter on another host does;
//! - `frond-bench-peer zenoh-raw ADDRESS`: a bare Zenoh subscriber on the source's `poses` key,
//!   recording in Zenoh's callback (a diagnostic: the pose's cost up to Zenoh's receive thread);
//! - `frond-bench-peer zenoh-sdk-callback ADDRESS`: subscribes with the SDK's callback-driven
//!   subscription (`frond_sdk::zenoh_callback`), recording in the SDK's closure on Zenoh's thread;
//! - `frond-bench-peer udp-sub BIND`: receives poses as plain UDP datagrams on `BIND`, one
//!   socket-protocol frame a datagram (the baseline);
//! - `frond-bench-peer udp-forward SOCKET_DIR ADDR [ADDR ...]`: reads the daemon's pose stream
//!   with `frond_sdk` as `frond-zenoh` does, and sends each pose, re-encoded as `frond-zenoh`
//!   re-encodes it, in one UDP datagram to every `ADDR` (the baseline's bridge);
//! - `frond-bench-peer zenoh-forward SOCKET_DIR ADDRESS`: the same reader, putting each pose on
//!   `ADDRESS`'s `poses` key as `zenoh-pub` does (bare Zenoh, nothing of `frond-zenoh`). Read by
//!   `zenoh-raw`, it is issue 43's latency floor measured whole.
//!
//! - `frond-bench-peer zenoh-pub ADDRESS` / `udp-pub ADDR [ADDR ...]`: the bare transport, no
//!   daemon and no bridge: every millisecond (absolute deadlines) one pose stamped with the time
//!   of sending, put on `ADDRESS`'s `poses` key as `frond-zenoh` puts it (not express, drop when
//!   congested, real-time priority; `ADDRESS`'s `listen` endpoint) or sent in one UDP datagram
//!   to every `ADDR`. Read by `zenoh-raw` and `udp-sub`, they measure the hop between two
//!   namespaces alone, the floor under both paths.
//!
//! - `frond-bench-peer zenoh-router ENDPOINT`: a Zenoh router listening on `ENDPOINT`
//!   (`tcp/ADDR:PORT`, no multicast scouting), the runtime `zenohd` wraps, for the routed
//!   fan-out: bridge and subscribers its clients. It prints `ready` once it listens.
//!
//! Each prints `ready` once poses flow. A subscriber then obeys its standard input: `record`
//! starts recording each pose's latency (receipt time minus the daemon's `host_monotonic_ns`; one
//! `CLOCK_MONOTONIC` serves every namespace of a machine, so the difference is a real latency),
//! `report` prints one JSON line (`{"frames","gaps","missing","latency_us":[...]}`, held frames
//! left out) and stops recording. Every process exits when its standard input closes.

use std::io::{BufRead, Write};
use std::net::{SocketAddr, UdpSocket};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use frond_protocol::{FrameBuf, Pose, PoseFlags, ServerMessage, decode_frame};
use frond_sdk::clock::monotonic_ns;
use frond_sdk::{Event, Source, Subscriber};

/// Most latencies one subscriber keeps (a 60 s window at 1 kHz); later ones are counted only.
const MAX_SAMPLES: usize = 60_000;

/// What a subscriber records between `record` and `report`.
#[derive(Default)]
struct Record {
    frames: u64,
    gaps: u64,
    missing: u64,
    latency_us: Vec<f64>,
}

/// The recording a subscriber shares with its standard-input thread.
struct Recorder {
    on: AtomicBool,
    record: Mutex<Record>,
    /// The sequence number due next where the subscriber sees raw poses (`u64::MAX`: none yet).
    next_seq: AtomicU64,
}

impl Default for Recorder {
    fn default() -> Self {
        Recorder { on: AtomicBool::new(false), record: Mutex::default(), next_seq: AtomicU64::new(u64::MAX) }
    }
}

impl Recorder {
    fn lock(&self) -> std::sync::MutexGuard<'_, Record> {
        self.record.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn pose(&self, pose: &Pose, now_ns: u64) {
        if !self.on.load(Relaxed) || pose.flags.contains(PoseFlags::HELD) {
            return;
        }
        let mut r = self.lock();
        r.frames += 1;
        if r.latency_us.len() < MAX_SAMPLES {
            r.latency_us.push(now_ns.saturating_sub(pose.host_monotonic_ns) as f64 / 1e3);
        }
    }

    /// A pose read off the wire without the SDK: a gap if numbers were skipped, then the pose.
    fn raw_pose(&self, pose: &Pose, now_ns: u64) {
        let expected = self.next_seq.swap(pose.seq + 1, Relaxed);
        if expected != u64::MAX && pose.seq > expected {
            self.gap(pose.seq - expected);
        }
        self.pose(pose, now_ns);
    }

    fn gap(&self, missing: u64) {
        if self.on.load(Relaxed) {
            let mut r = self.lock();
            r.gaps += 1;
            r.missing += missing;
        }
    }

    /// Obeys standard input until it closes, then exits the process.
    fn serve_stdin(self: Arc<Self>) {
        std::thread::spawn(move || {
            for line in std::io::stdin().lock().lines() {
                let Ok(line) = line else { break };
                match line.trim() {
                    "record" => self.on.store(true, Relaxed),
                    "report" => {
                        self.on.store(false, Relaxed);
                        let r = std::mem::take(&mut *self.lock());
                        let json = serde_json::json!({
                            "frames": r.frames, "gaps": r.gaps, "missing": r.missing, "latency_us": r.latency_us,
                        });
                        say(&json.to_string());
                    }
                    other => eprintln!("frond-bench-peer: unknown command {other:?} (record, report)"),
                }
            }
            std::process::exit(0);
        });
    }
}

fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

/// Exits when standard input closes (the forwarder reads no commands).
fn exit_on_stdin_eof() {
    std::thread::spawn(|| {
        let mut sink = String::new();
        while matches!(std::io::stdin().lock().read_line(&mut sink), Ok(n) if n > 0) {
            sink.clear();
        }
        std::process::exit(0);
    });
}

fn zenoh_sub(address: &str) -> Result<(), String> {
    let source: Source = address.parse().map_err(|e| format!("{address}: {e}"))?;
    let opts = Subscriber::options().give_up_after(None).hello_timeout(Duration::from_secs(20));
    let mut sub = opts.subscribe(&source).map_err(|e| format!("{address}: {e}"))?;
    let recorder = Arc::new(Recorder::default());
    let mut ready = false;
    loop {
        match sub.next_event().map_err(|e| e.to_string())? {
            Event::Pose(p) => {
                recorder.pose(&p, monotonic_ns());
                if !ready {
                    ready = true;
                    recorder.clone().serve_stdin();
                    say("ready");
                }
            }
            Event::Gap { expected, got } => recorder.gap(got.saturating_sub(expected)),
            _ => {}
        }
    }
}

/// A `zenoh:` address parsed.
fn zenoh_addr(address: &str) -> Result<frond_sdk::ZenohAddr, String> {
    match address.parse::<Source>().map_err(|e| format!("{address}: {e}"))? {
        Source::Zenoh(addr) => Ok(addr),
        _ => Err(format!("{address}: not a zenoh: address")),
    }
}

/// A `zenoh:` address parsed, and a session opened as it says (endpoints, configuration file).
fn zenoh_session(address: &str) -> Result<(frond_sdk::ZenohAddr, frond_sdk::zenoh::Session), String> {
    let addr = zenoh_addr(address)?;
    let session = frond_sdk::zenoh::open_addr_session(&addr).map_err(|e| e.to_string())?;
    Ok((addr, session))
}

/// The SDK's callback-driven subscription: each pose recorded in the SDK's closure, on Zenoh's
/// receive thread, with no hand-off to a reading thread.
fn zenoh_sdk_callback(address: &str) -> Result<(), String> {
    let addr = zenoh_addr(address)?;
    let recorder = Arc::new(Recorder::default());
    let (ready_tx, ready_rx) = std::sync::mpsc::sync_channel::<()>(1);
    let rec = recorder.clone();
    let _sub = frond_sdk::zenoh_callback::subscribe(&addr, &Subscriber::options(), move |event| {
        let now = monotonic_ns();
        match event {
            Event::Pose(p) => {
                rec.pose(&p, now);
                let _ = ready_tx.try_send(());
            }
            Event::Gap { expected, got } => rec.gap(got.saturating_sub(expected)),
            _ => {}
        }
    })
    .map_err(|e| e.to_string())?;
    serve_once_ready(&ready_rx, recorder)
}

/// A bare Zenoh subscriber on the source's `poses` key that records each sample in Zenoh's own
/// callback: what the pose costs up to Zenoh's receive thread, without the SDK's hand-off to the
/// reading thread (a diagnostic beside [`zenoh_sub`]).
fn zenoh_raw(address: &str) -> Result<(), String> {
    use frond_sdk::zenoh::keys;
    use zenoh::Wait;
    let (addr, session) = zenoh_session(address)?;
    let recorder = Arc::new(Recorder::default());
    let (ready_tx, ready_rx) = std::sync::mpsc::sync_channel::<()>(1);
    let rec = recorder.clone();
    let _sub = session
        .declare_subscriber(keys::under(&addr.key, keys::POSES))
        .callback(move |sample| {
            let now = monotonic_ns();
            let bytes = sample.payload().to_bytes();
            if let Ok(Some((ServerMessage::Pose(p), _))) = decode_frame::<ServerMessage>(&bytes) {
                rec.raw_pose(&p, now);
                let _ = ready_tx.try_send(());
            }
        })
        .wait()
        .map_err(|e| e.to_string())?;
    serve_once_ready(&ready_rx, recorder)
}

/// A subscriber that records in a callback (its subscription held by the caller): waits for the
/// callback's first pose, then obeys standard input and says `ready`, for as long as it runs.
fn serve_once_ready(ready: &std::sync::mpsc::Receiver<()>, recorder: Arc<Recorder>) -> Result<(), String> {
    ready.recv().map_err(|e| e.to_string())?;
    recorder.serve_stdin();
    say("ready");
    loop {
        std::thread::park();
    }
}

fn udp_sub(bind: &str) -> Result<(), String> {
    let socket = UdpSocket::bind(bind).map_err(|e| format!("{bind}: {e}"))?;
    let recorder = Arc::new(Recorder::default());
    let mut buf = vec![0u8; 65_536];
    let mut ready = false;
    loop {
        let n = socket.recv(&mut buf).map_err(|e| e.to_string())?;
        let now = monotonic_ns();
        let Ok(Some((ServerMessage::Pose(p), _))) = decode_frame::<ServerMessage>(&buf[..n]) else {
            continue;
        };
        recorder.raw_pose(&p, now);
        if !ready {
            ready = true;
            recorder.clone().serve_stdin();
            say("ready");
        }
    }
}

/// One UDP socket sending each datagram to every target (the baseline's senders).
struct UdpFanout {
    socket: UdpSocket,
    to: Vec<SocketAddr>,
}

impl UdpFanout {
    fn new(to: &[String]) -> Result<UdpFanout, String> {
        let to = to.iter().map(|a| a.parse().map_err(|e| format!("{a}: {e}"))).collect::<Result<_, _>>()?;
        let socket = UdpSocket::bind("0.0.0.0:0").map_err(|e| e.to_string())?;
        Ok(UdpFanout { socket, to })
    }

    fn send(&self, bytes: &[u8]) {
        for addr in &self.to {
            // A full socket buffer or an unreachable host loses the datagram, as UDP does.
            let _ = self.socket.send_to(bytes, addr);
        }
    }
}

fn udp_forward(socket_dir: &str, to: &[String]) -> Result<(), String> {
    let fanout = UdpFanout::new(to)?;
    forward(socket_dir, |bytes| fanout.send(&bytes))
}

/// The floor's forwarder: reads the daemon's pose stream as [`udp_forward`] does and puts each
/// pose on ADDRESS's `poses` key as [`zenoh_pub`] puts it, with nothing of `frond-zenoh` on the
/// way (no element tables, no replay ring, no per-peer accounting). Read by `zenoh-raw` in
/// Zenoh's callback, it is issue 43's floor measured whole: the leg both paths share (daemon ->
/// a reader on host 0) plus a bare Zenoh put -> callback hop.
fn zenoh_forward(socket_dir: &str, address: &str) -> Result<(), String> {
    use zenoh::Wait;
    let (addr, session) = zenoh_session(address)?;
    let publisher = bare_publisher(&session, &addr)?;
    forward(socket_dir, |bytes| {
        let _ = publisher.put(bytes).wait();
    })
}

/// Reads the daemon's pose stream in `socket_dir` with `frond_sdk` and hands `send` each pose,
/// re-encoded as `frond-zenoh` re-encodes it into a buffer of its own; prints `ready` after the
/// first.
fn forward(socket_dir: &str, mut send: impl FnMut(Vec<u8>)) -> Result<(), String> {
    let mut sub = Subscriber::connect(socket_dir).map_err(|e| format!("{socket_dir}: {e}"))?;
    let mut frame = FrameBuf::default();
    let mut ready = false;
    exit_on_stdin_eof();
    loop {
        if let Event::Pose(p) = sub.next_event().map_err(|e| e.to_string())? {
            // As frond-zenoh: one owned buffer per pose, re-encoded from the decoded pose.
            send(frame.encode(&ServerMessage::Pose(p)).to_vec());
            if !ready {
                ready = true;
                say("ready");
            }
        }
    }
}

/// How often the bare publishers send (the daemons' rate in the bench).
const BARE_PERIOD: Duration = Duration::from_millis(1);

/// Calls `send` with a fresh pose (stamped now, numbered from 0) every [`BARE_PERIOD`], on
/// absolute deadlines so a late wake-up does not shift the ones after it.
fn every_period(mut send: impl FnMut(&[u8])) -> Result<(), String> {
    let mut frame = FrameBuf::default();
    let start = std::time::Instant::now();
    exit_on_stdin_eof();
    say("ready");
    for seq in 0u64.. {
        let due = start + BARE_PERIOD * u32::try_from(seq % (1 << 31)).unwrap_or(0);
        if let Some(wait) = due.checked_duration_since(std::time::Instant::now()) {
            std::thread::sleep(wait);
        }
        let pose = Pose { seq, host_monotonic_ns: monotonic_ns(), ..Pose::default() };
        send(frame.encode(&ServerMessage::Pose(pose)));
    }
    Ok(())
}

fn zenoh_pub(address: &str) -> Result<(), String> {
    use zenoh::Wait;
    let (addr, session) = zenoh_session(address)?;
    let publisher = bare_publisher(&session, &addr)?;
    every_period(|bytes| {
        // As frond-zenoh: an owned buffer per put; a put that fails is a lost pose.
        let _ = publisher.put(bytes.to_vec()).wait();
    })
}

/// A publisher on `addr`'s `poses` key declared as `frond-zenoh` declares its own: not express,
/// drop when congested, real-time priority.
fn bare_publisher<'a>(
    session: &'a frond_sdk::zenoh::Session,
    addr: &frond_sdk::ZenohAddr,
) -> Result<zenoh::pubsub::Publisher<'a>, String> {
    use frond_sdk::zenoh::keys;
    use zenoh::Wait;
    use zenoh::qos::{CongestionControl, Priority};
    session
        .declare_publisher(keys::under(&addr.key, keys::POSES))
        .congestion_control(CongestionControl::Drop)
        .priority(Priority::RealTime)
        .express(false) // as frond-zenoh: frond_zenoh::EXPRESS
        .wait()
        .map_err(|e| e.to_string())
}

/// A Zenoh router on `endpoint` until standard input closes.
fn zenoh_router(endpoint: &str) -> Result<(), String> {
    use frond_sdk::zenoh::{config, open_session};
    let cfg =
        config(None, Some("router"), &[], &[endpoint.to_owned()], &[("scouting/multicast/enabled", "false")])
            .map_err(|e| e.to_string())?;
    let _session = open_session(cfg).map_err(|e| format!("router on {endpoint}: {e}"))?;
    exit_on_stdin_eof();
    say("ready");
    loop {
        std::thread::park();
    }
}

fn udp_pub(to: &[String]) -> Result<(), String> {
    let fanout = UdpFanout::new(to)?;
    every_period(|bytes| fanout.send(bytes))
}

/// The remote end of `frond bench`'s `zenoh` section: one subscriber, bridge or bare sender.
#[derive(clap::Parser)]
#[command(name = "frond-bench-peer")]
enum Peer {
    /// Subscribes to ADDRESS with `frond_sdk`, as an exporter on another host does.
    ZenohSub { address: String },
    /// A bare Zenoh subscriber on ADDRESS's `poses` key.
    ZenohRaw { address: String },
    /// Subscribes to ADDRESS with the SDK's callback-driven subscription.
    ZenohSdkCallback { address: String },
    /// Receives poses as plain UDP datagrams on BIND.
    UdpSub { bind: String },
    /// Reads the daemon's pose stream and sends each pose in one UDP datagram to every ADDR.
    UdpForward {
        socket_dir: String,
        #[arg(required = true, value_name = "ADDR")]
        to: Vec<String>,
    },
    /// Reads the daemon's pose stream and puts each pose on ADDRESS's `poses` key, bare.
    ZenohForward { socket_dir: String, address: String },
    /// Puts a stamped pose on ADDRESS's `poses` key every millisecond.
    ZenohPub { address: String },
    /// A Zenoh router listening on ENDPOINT (tcp/ADDR:PORT).
    ZenohRouter { endpoint: String },
    /// Sends a stamped pose in one UDP datagram to every ADDR every millisecond.
    UdpPub {
        #[arg(required = true, value_name = "ADDR")]
        to: Vec<String>,
    },
}

fn main() -> ExitCode {
    let peer: Peer = match frond_binmain::parse("frond-bench-peer") {
        Ok(peer) => peer,
        Err(code) => return code,
    };
    let result = match &peer {
        Peer::ZenohSub { address } => zenoh_sub(address),
        Peer::ZenohRaw { address } => zenoh_raw(address),
        Peer::ZenohSdkCallback { address } => zenoh_sdk_callback(address),
        Peer::UdpSub { bind } => udp_sub(bind),
        Peer::UdpForward { socket_dir, to } => udp_forward(socket_dir, to),
        Peer::ZenohForward { socket_dir, address } => zenoh_forward(socket_dir, address),
        Peer::ZenohPub { address } => zenoh_pub(address),
        Peer::UdpPub { to } => udp_pub(to),
        Peer::ZenohRouter { endpoint } => zenoh_router(endpoint),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("frond-bench-peer: {e}");
            ExitCode::FAILURE
        }
    }
}
