//! The exporter loop. Forwarding every frame, one thread reads the daemon's pose stream, encodes
//! each frame once and sends it to every target (non-blocking sockets: a stalled network path
//! never holds it up), so a pose crosses no queue between threads. Resampling (`--rate`), a
//! subscriber thread reads the stream and hands poses to the sending loop over a bounded queue
//! (dropping, and counting, what does not fit), and the sending loop wakes on the resampler's
//! ticks, which a read of the daemon's socket could not time finely.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::time::{Duration, Instant};

use frond_protocol::field::{FieldDefinition, FieldFrame};
use frond_protocol::{ElementTable, Hello, Pose};
use frond_sdk::field::MAX_KEPT_FIELD_FRAMES;
use frond_sdk::{Event, SdkError, Source, Subscriber};
use thiserror::Error;

use crate::encode::{
    ClockOffset, Datagrams, EncodeError, FrondEncoder, Timetags, VmcEncoder, VmcRig, monotonic_ns,
};
use crate::fields::{FieldSender, FieldTable, collect_table};
use crate::resample::{ResampleCounters, Resampler};
use crate::sender::{Sender, SenderError, TargetCounters};

/// Which OSC dialect to send.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// frond's own namespace (`/frond/pose`, ...).
    Frond,
    /// The VMC protocol.
    Vmc,
}

/// Everything the bridge needs.
#[derive(Debug, Clone)]
pub struct BridgeConfig {
    /// Where the poses come from: the daemon's socket directory on this host, or a
    /// `frond-zenoh` bridge on another (`--from zenoh:frond/<stage>/<source>`).
    pub source: Source,
    /// Dialect.
    pub protocol: Protocol,
    /// Destinations.
    pub targets: Vec<SocketAddr>,
    /// Local address to send from (default: any, port 0).
    pub bind: Option<SocketAddr>,
    /// Output rate; `None` forwards every frame as it arrives.
    pub rate_hz: Option<f64>,
    /// VMC rig (heights, bone names).
    pub vmc_rig: VmcRig,
    /// When true the VMC bone names are fixed (humanoid, `--vmc-bones` or a rig file's `[vmc]`
    /// table); otherwise (`--vmc-bones joints`) they follow the daemon's hello (its joint names).
    pub vmc_names_fixed: bool,
    /// Timetag clock offset (measure it with [`ClockOffset::measure`]).
    pub clock_offset: ClockOffset,
    /// What the frames' timetags say.
    pub timetags: Timetags,
    /// Capacity of the queue between the subscriber thread and the sending loop (with
    /// `rate_hz` only: forwarding every frame, one thread reads and sends).
    pub queue_capacity: usize,
}

impl BridgeConfig {
    /// A configuration with defaults for everything but the source, dialect and targets.
    pub fn new(source: Source, protocol: Protocol, targets: Vec<SocketAddr>) -> BridgeConfig {
        BridgeConfig {
            source,
            protocol,
            targets,
            bind: None,
            rate_hz: None,
            vmc_rig: VmcRig::default(),
            vmc_names_fixed: false,
            clock_offset: ClockOffset::measure(),
            timetags: Timetags::Publish,
            queue_capacity: 4096,
        }
    }
}

/// Why the bridge stopped or could not start.
#[derive(Debug, Error)]
pub enum BridgeError {
    /// The targets could not be set up.
    #[error(transparent)]
    Sender(#[from] SenderError),
    /// The subscription failed (daemon not running, gave up reconnecting, version mismatch).
    #[error(transparent)]
    Subscribe(#[from] SdkError),
    /// A frame could not be encoded.
    #[error(transparent)]
    Encode(#[from] EncodeError),
}

/// Counters of a running bridge.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BridgeStats {
    /// Poses the subscriber received.
    pub received: u64,
    /// Gaps in the daemon's sequence numbers (frames the daemon dropped for us).
    pub gaps: u64,
    /// Frames missing in those gaps.
    pub missing: u64,
    /// Poses dropped because the sending loop was behind (queue full; resampling only).
    pub queue_dropped: u64,
    /// Reconnections to the daemon.
    pub reconnects: u64,
    /// Frames encoded and handed to the sender.
    pub frames_out: u64,
    /// Resampler counters (zero without `--rate`).
    pub resample: ResampleCounters,
    /// Field frames sent (a running field sent whole, `frond` namespace).
    pub field_frames: u64,
    /// Field frames the subscriber could not keep between two takes (beyond
    /// `frond_sdk::field::MAX_KEPT_FIELD_FRAMES`): a receiver's field history misses them.
    pub field_frames_dropped: u64,
    /// Per-target counters.
    pub targets: Vec<(SocketAddr, TargetCounters)>,
}

impl std::fmt::Display for BridgeStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "received={} gaps={} missing={} queue_dropped={} reconnects={} frames_out={}",
            self.received, self.gaps, self.missing, self.queue_dropped, self.reconnects, self.frames_out
        )?;
        if self.field_frames > 0 || self.field_frames_dropped > 0 {
            write!(
                f,
                " field_frames={} field_frames_dropped={}",
                self.field_frames, self.field_frames_dropped
            )?;
        }
        let r = &self.resample;
        if r.received > 0 {
            write!(
                f,
                " superseded={} idle_ticks={} missed_ticks={}",
                r.superseded, r.idle_ticks, r.missed_ticks
            )?;
        }
        for (addr, c) in &self.targets {
            write!(
                f,
                " | {addr}: frames={} datagrams={} bytes={} refused={} would_block={} errors={}",
                c.frames_sent, c.datagrams_sent, c.bytes_sent, c.refused, c.would_block, c.errors
            )?;
        }
        Ok(())
    }
}

#[derive(Default)]
struct SubCounters {
    received: AtomicU64,
    gaps: AtomicU64,
    missing: AtomicU64,
    queue_dropped: AtomicU64,
    reconnects: AtomicU64,
    field_frames_dropped: AtomicU64,
}

enum Msg {
    Pose(Pose),
    Hello(Hello),
    Elements(ElementTable),
    /// The running fields changed (frond namespace only).
    Fields(FieldTable),
    /// A field frame (frond namespace only), boxed: it is large beside a pose.
    FieldFrame(Box<FieldFrame>),
    End(SdkError),
}

/// How often the `frond` namespace repeats its names bundle (a receiver started late learns
/// them within this).
pub const NAMES_EVERY: Duration = Duration::from_secs(1);

enum Encoder {
    Frond(FrondEncoder),
    Vmc(VmcEncoder),
}

impl Encoder {
    fn encode(&mut self, pose: &Pose, out: &mut Datagrams) -> Result<(), EncodeError> {
        match self {
            Encoder::Frond(e) => e.encode(pose, out),
            Encoder::Vmc(e) => e.encode(pose, out),
        }
    }
}

/// Where the sending loop gets the daemon's messages.
enum Feed {
    /// It reads the subscription itself (forwarding every frame), and takes the field frames
    /// and tables from it (`frames` reused for them).
    Direct { sub: Box<Subscriber>, frames: Vec<FieldFrame>, known: Vec<FieldDefinition> },
    /// A subscriber thread reads it and queues what it reads (resampling).
    Queue(Receiver<Msg>),
}

/// How long a read of the daemon waits at most, so that `stop` and the names bundle are seen to.
const READ_TIMEOUT: Duration = Duration::from_millis(100);

/// A connected bridge, ready to [`run`](Bridge::run).
pub struct Bridge {
    feed: Feed,
    counters: Arc<SubCounters>,
    encoder: Encoder,
    sender: Sender,
    resampler: Option<Resampler>,
    datagrams: Datagrams,
    vmc_names_fixed: bool,
    frames_out: u64,
    /// The daemon's hello (rig, joint names) with its latest element table: the names bundle.
    names: Hello,
    names_due: Instant,
    /// Running fields sent whole (`frond` namespace only).
    fields: Option<FieldSender>,
}

impl Bridge {
    /// Sets up the targets, connects to the daemon (failing at once if it is not running) and,
    /// when resampling, starts the subscriber thread. After that the subscriber reconnects for
    /// ever.
    pub fn connect(config: &BridgeConfig) -> Result<Bridge, BridgeError> {
        let sender = Sender::new(&config.targets, config.bind)?;
        let frond = config.protocol == Protocol::Frond;
        let sub = Subscriber::options()
            .give_up_after(None)
            .read_timeout(Some(READ_TIMEOUT))
            .keep_field_frames(if frond { MAX_KEPT_FIELD_FRAMES } else { 0 })
            .subscribe(&config.source)?;
        let mut vmc_rig = config.vmc_rig.clone();
        if !config.vmc_names_fixed {
            apply_hello_names(&mut vmc_rig, sub.hello());
        }
        let mut names = sub.hello().clone();
        names.elements = sub.elements().clone();
        let encoder = match config.protocol {
            Protocol::Frond => {
                let mut e = FrondEncoder::new(config.clock_offset);
                e.set_timetags(config.timetags);
                Encoder::Frond(e)
            }
            Protocol::Vmc => {
                let mut e = VmcEncoder::new(config.clock_offset, vmc_rig);
                e.set_timetags(config.timetags);
                Encoder::Vmc(e)
            }
        };
        let counters = Arc::new(SubCounters::default());
        let feed = if config.rate_hz.is_some() {
            let (tx, rx) = sync_channel(config.queue_capacity.max(1));
            let thread_counters = Arc::clone(&counters);
            std::thread::Builder::new()
                .name("frond-osc-sub".into())
                .spawn(move || subscribe(sub, &tx, &thread_counters, frond))
                .expect("spawn the subscriber thread");
            Feed::Queue(rx)
        } else {
            let frames = Vec::with_capacity(MAX_KEPT_FIELD_FRAMES);
            Feed::Direct { sub: Box::new(sub), frames, known: Vec::new() }
        };
        Ok(Bridge {
            feed,
            counters,
            encoder,
            sender,
            resampler: config.rate_hz.map(Resampler::new),
            datagrams: Datagrams::new(),
            vmc_names_fixed: config.vmc_names_fixed,
            frames_out: 0,
            names,
            names_due: Instant::now(),
            fields: frond.then(|| FieldSender::new(config.clock_offset, config.timetags)),
        })
    }

    /// The sender (targets and their local addresses).
    pub fn sender(&self) -> &Sender {
        &self.sender
    }

    /// Counters so far.
    pub fn stats(&self) -> BridgeStats {
        let c = &self.counters;
        BridgeStats {
            received: c.received.load(Ordering::Relaxed),
            gaps: c.gaps.load(Ordering::Relaxed),
            missing: c.missing.load(Ordering::Relaxed),
            queue_dropped: c.queue_dropped.load(Ordering::Relaxed),
            reconnects: c.reconnects.load(Ordering::Relaxed),
            frames_out: self.frames_out,
            field_frames: self.fields.as_ref().map_or(0, |f| f.frames_sent),
            field_frames_dropped: c.field_frames_dropped.load(Ordering::Relaxed),
            resample: self.resampler.as_ref().map(Resampler::counters).unwrap_or_default(),
            targets: self.sender.targets().iter().map(|t| (t.addr(), t.counters())).collect(),
        }
    }

    /// Runs until `stop` is set (checked at least every 100 ms) or the subscription ends for good.
    /// Calls `on_stats` every `stats_every` (if given).
    pub fn run(
        &mut self,
        stop: &AtomicBool,
        stats_every: Option<Duration>,
        mut on_stats: impl FnMut(&BridgeStats),
    ) -> Result<(), BridgeError> {
        let mut last_stats = Instant::now();
        // The names first, so that a receiver knows the joints before the first frame.
        self.send_names_if_due()?;
        while !stop.load(Ordering::Relaxed) {
            let mut wait = Duration::from_millis(100);
            if let Some(due) = self.resampler.as_ref().and_then(Resampler::next_tick_ns) {
                wait = wait.min(Duration::from_nanos(due.saturating_sub(monotonic_ns())));
            }
            let msg = match &mut self.feed {
                Feed::Direct { sub, frames, known } => {
                    let msg = triage(sub.next_event(), &self.counters);
                    if let Some(fields) = &mut self.fields {
                        if let Some(table) = collect_table(sub, known) {
                            fields.set_table(table);
                        }
                        let dropped = sub.take_field_frames(frames);
                        self.counters.field_frames_dropped.fetch_add(dropped, Ordering::Relaxed);
                        for f in frames.drain(..) {
                            fields.send_frame(&f, &mut self.datagrams, &mut self.sender)?;
                        }
                    }
                    msg
                }
                Feed::Queue(rx) => match rx.recv_timeout(wait) {
                    Ok(msg) => Some(msg),
                    Err(RecvTimeoutError::Timeout) => None,
                    Err(RecvTimeoutError::Disconnected) => return Err(SdkError::Closed.into()),
                },
            };
            match msg {
                Some(Msg::Pose(pose)) => match &mut self.resampler {
                    Some(r) => r.push(pose, monotonic_ns()),
                    None => self.send(&pose)?,
                },
                Some(Msg::Hello(hello)) => self.on_hello(&hello),
                Some(Msg::Elements(table)) => {
                    self.names.elements = table;
                    self.names_due = Instant::now();
                }
                Some(Msg::Fields(table)) => {
                    if let Some(fields) = &mut self.fields {
                        fields.set_table(table);
                    }
                }
                Some(Msg::FieldFrame(f)) => {
                    if let Some(fields) = &mut self.fields {
                        fields.send_frame(&f, &mut self.datagrams, &mut self.sender)?;
                    }
                }
                Some(Msg::End(e)) => return Err(e.into()),
                None => {}
            }
            if let Some(mut r) = self.resampler.take() {
                let mut result = Ok(());
                r.poll(monotonic_ns(), |pose| {
                    if result.is_ok() {
                        result = self.send(pose);
                    }
                });
                self.resampler = Some(r);
                result?;
            }
            self.send_names_if_due()?;
            if let Some(fields) = &mut self.fields {
                fields.poll(&self.names.elements, &mut self.datagrams, &mut self.sender)?;
            }
            if let Some(every) = stats_every
                && last_stats.elapsed() >= every
            {
                last_stats = Instant::now();
                on_stats(&self.stats());
            }
        }
        Ok(())
    }

    /// Sends the `frond` namespace's names bundle when it is due (see [`NAMES_EVERY`]).
    fn send_names_if_due(&mut self) -> Result<(), EncodeError> {
        if let Encoder::Frond(e) = &self.encoder
            && Instant::now() >= self.names_due
        {
            let h = &self.names;
            e.encode_names(&h.rig_name, &h.joint_names, &h.elements, &mut self.datagrams)?;
            self.sender.send(&self.datagrams);
            self.names_due = Instant::now() + NAMES_EVERY;
        }
        Ok(())
    }

    fn send(&mut self, pose: &Pose) -> Result<(), EncodeError> {
        self.encoder.encode(pose, &mut self.datagrams)?;
        self.sender.send(&self.datagrams);
        self.frames_out += 1;
        Ok(())
    }

    fn on_hello(&mut self, hello: &Hello) {
        tracing::info!(rig = %hello.rig_name, joints = ?hello.joint_names, "daemon hello");
        self.names = hello.clone();
        self.names_due = Instant::now();
        if let Encoder::Vmc(e) = &mut self.encoder
            && !self.vmc_names_fixed
        {
            let mut rig = e.rig().clone();
            apply_hello_names(&mut rig, hello);
            e.set_rig(rig);
        }
    }
}

/// Takes the bone names from the daemon's joint names when it announces four valid ones.
fn apply_hello_names(rig: &mut VmcRig, hello: &Hello) {
    if hello.joint_names.len() == 4 && hello.joint_names.iter().all(|n| !n.is_empty() && n.len() <= 255) {
        rig.bone_names = std::array::from_fn(|i| hello.joint_names[i].clone());
    }
}

/// The subscriber thread (resampling): reads the daemon and queues what the sending loop needs
/// (with `fields`, the running fields' tables and every field frame, never dropped: the
/// receiver's history needs each).
fn subscribe(mut sub: Subscriber, tx: &SyncSender<Msg>, counters: &SubCounters, fields: bool) {
    let (mut frames, mut known) = (Vec::with_capacity(MAX_KEPT_FIELD_FRAMES), Vec::new());
    loop {
        let msg = triage(sub.next_event(), counters);
        if fields {
            if let Some(table) = collect_table(&sub, &mut known)
                && tx.send(Msg::Fields(table)).is_err()
            {
                return;
            }
            let dropped = sub.take_field_frames(&mut frames);
            counters.field_frames_dropped.fetch_add(dropped, Ordering::Relaxed);
            for f in frames.drain(..) {
                if tx.send(Msg::FieldFrame(Box::new(f))).is_err() {
                    return;
                }
            }
        }
        let Some(msg) = msg else { continue };
        let sent = match msg {
            // A pose that does not fit is dropped and counted: the sending loop is behind.
            Msg::Pose(_) => match tx.try_send(msg) {
                Ok(()) => true,
                Err(TrySendError::Full(_)) => {
                    counters.queue_dropped.fetch_add(1, Ordering::Relaxed);
                    true
                }
                Err(TrySendError::Disconnected(_)) => false,
            },
            Msg::End(_) => {
                let _ = tx.send(msg);
                false
            }
            other => tx.send(other).is_ok(),
        };
        if !sent {
            return;
        }
    }
}

/// What the sending loop must hear of one result of `next_event`, counting poses, gaps and
/// reconnections on the way; `None` when nothing (a gap, a read that timed out, a disconnection
/// the subscriber recovers from).
fn triage(result: Result<Event, SdkError>, counters: &SubCounters) -> Option<Msg> {
    match result {
        Ok(Event::Pose(pose)) => {
            counters.received.fetch_add(1, Ordering::Relaxed);
            Some(Msg::Pose(pose))
        }
        Ok(Event::Gap { expected, got }) => {
            counters.gaps.fetch_add(1, Ordering::Relaxed);
            counters.missing.fetch_add(got - expected, Ordering::Relaxed);
            None
        }
        // Element addresses are by id (`/frond/element/N/pose`); the names bundle names them.
        Ok(Event::Elements(table)) => Some(Msg::Elements(table)),
        Ok(Event::RigChanged(hello)) => Some(Msg::Hello(hello)),
        Ok(Event::Reconnected(hello)) => {
            counters.reconnects.fetch_add(1, Ordering::Relaxed);
            Some(Msg::Hello(hello))
        }
        Ok(Event::Disconnected) => {
            tracing::warn!("daemon disconnected; reconnecting");
            None
        }
        Err(SdkError::Timeout { .. }) => None,
        Err(e) if e.is_fatal() => Some(Msg::End(e)),
        Err(e) => {
            tracing::warn!(error = %e, "pose stream error");
            None
        }
    }
}
