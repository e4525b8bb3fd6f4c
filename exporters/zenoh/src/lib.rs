//! `frond-zenoh`: carries one daemon's streams onto Zenoh, so exporters, recorders and tools on
//! other hosts subscribe to them with the same SDK (`--from zenoh:frond/<stage>/<source>`).
//!
//! The bridge is an exporter like the others: it reads `poses.sock` through [`frond_sdk`] and
//! polls `control.sock` for status; the daemon's realtime loop never touches the network. What it
//! publishes, under `frond/<stage>/<source>` ([`frond_sdk::zenoh::keys`]):
//!
//! - `poses`: every pose, one socket-protocol frame a sample, congestion control *drop*, so a slow
//!   or far peer loses samples instead of backing the bridge up; not express ([`EXPRESS`]): while
//!   Zenoh's transmit task is behind, poses wait together in one batch instead of one batch each;
//! - `poses` also carries every field frame (protocol 3: a running field's driving stream, a
//!   few hundred bytes at any plant count), numbered among the poses, as `poses.sock` does;
//! - `elements`, `fields` (the running fields' definitions, protocol 3) and `hello`: put when
//!   they change, and answered to late joiners by queryables with the latest value (the
//!   hello's `next_seq` is the next pose the bridge will publish). A remote subscriber
//!   evaluates every plant of a field itself, as a local one does: the bridge passes the
//!   field on as the daemon publishes it, never one pose stream per plant;
//! - `status`: the daemon's status report (a `ControlReply::Status` frame) every
//!   [`BridgeConfig::status_interval`], and answered by a queryable;
//! - `alive`: a liveliness token, held while the bridge is connected to its daemon. Subscribers
//!   see it go when the daemon stops, the bridge stops, or its host becomes unreachable.
//!
//! - `control`: remote control, a queryable declared only when the bridge is given an allow-list
//!   (`--control FILE`, [`control`]): signed control requests, answered with the daemon's reply.
//! - `bridge/<id>`: the bridge's claim on its name, a liveliness token (module `claim`): of two
//!   bridges started under one name, the elder publishes and the younger stands by, saying so.
//! - `clock`: a queryable answering this host's realtime and monotonic clocks read together
//!   (JSON `{"unix_ns":..,"monotonic_ns":..}`), so a stage recorder measures how far this host's
//!   clock is from its own.
//!
//! - `replay`: a queryable answering lost poses from the last [`BridgeConfig::replay_frames`]
//!   published (module `replay`, the wire in [`frond_sdk::zenoh_replay`]): a reliable subscriber
//!   (a stage recorder) fills its gaps from it; every SDK subscriber also reports its counts
//!   there about once a second, which `peers` answers (JSON) and `--stats` prints.
//!
//! Every pose sample carries its **stage time** as its attachment (8 bytes, `u64` little-endian):
//! the pose's `host_monotonic_ns` on this host's realtime clock, nanoseconds since 1970
//! ([`frond_sdk::stage_time`]). Samples also carry Zenoh timestamps (the session's hybrid logical
//! clock, the time of the put).

#![warn(missing_docs)]

mod claim;
pub mod control;
mod queryables;
mod replay;
mod status;

pub use replay::{DEFAULT_REPLAY_FRAMES, MAX_REPLAY_FRAMES};

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use frond_protocol::field::{FieldMessage, FieldTable};
use frond_protocol::{ElementTable, FrameBuf, Hello, ServerMessage};
use frond_sdk::stage_time::{ClockReading, encode_attachment, realtime_ns};
use frond_sdk::zenoh::{ZenohSetupError, keys};
use frond_sdk::zenoh_replay::PeerReport;
use frond_sdk::{Event, Relayed, SdkError, Subscriber, ZenohAddr};
use queryables::Latest;
use zenoh::Wait;
use zenoh::bytes::ZBytes;
use zenoh::qos::{CongestionControl, Priority};

/// How often the daemon's status is published by default.
pub const DEFAULT_STATUS_INTERVAL: Duration = Duration::from_millis(250);
/// Accepted status intervals.
pub const STATUS_INTERVAL_RANGE: std::ops::RangeInclusive<Duration> =
    Duration::from_millis(50)..=Duration::from_secs(10);

/// Whether the bridge's samples are express. They are not: Zenoh gives each express sample a
/// batch of its own, and a link's real-time queue holds 2 batches (`transport.link.tx.queue.size`);
/// a put that finds none free waits `wait_before_drop` (1 ms) and is dropped, and the ones after
/// it too until a batch comes back. So a transmit task held off the CPU for 3 ms (a busy 2-core
/// host) dropped poses on a healthy link: 4-233 of 80,000 with 16 subscribers, every drop traced
/// by Zenoh as "over the deadline". Not express, a pose joins the batch that is waiting, so the
/// same 2 batches hold about 500 poses (half a second at 1 kHz) while the task catches up; an
/// idle task still sends each pose at once (batching only under back-pressure).
pub const EXPRESS: bool = false;

/// What the bridge needs; built and validated by the binary.
#[derive(Debug, Clone)]
pub struct BridgeConfig {
    /// The daemon's socket directory.
    pub socket_dir: PathBuf,
    /// Where to publish: `frond/<stage>/<source>` (no wildcard).
    pub addr: ZenohAddr,
    /// How often the daemon's status is published.
    pub status_interval: Duration,
    /// Added to every realtime clock reading the bridge reports (pose stage times, `.../clock`
    /// answers): 0, except under the test hook `FROND_TEST_CLOCK_OFFSET_NS`, which makes this
    /// host's clock look that far off, as a host without NTP would.
    pub clock_offset_ns: i64,
    /// Remote control's allow-list; `None` (the default) declares no control queryable.
    pub control: Option<control::ControlPolicy>,
    /// Poses the replay ring keeps for reliable subscribers (0: none).
    pub replay_frames: usize,
}

/// What can stop the bridge.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    /// The Zenoh session could not be opened or an entity not declared.
    #[error(transparent)]
    Setup(#[from] ZenohSetupError),
    /// Declaring a publisher, queryable or token failed.
    #[error("Zenoh: declaring {what}: {reason}")]
    Declare {
        /// What was being declared.
        what: String,
        /// Zenoh's error.
        reason: String,
    },
    /// The pose stream failed in a way no reconnection cures (a protocol version mismatch).
    #[error(transparent)]
    Stream(#[from] SdkError),
}

/// Counters since the bridge started.
#[derive(Debug, Default)]
pub struct BridgeStats {
    /// Poses received from the daemon.
    pub poses: AtomicU64,
    /// Field frames received from the daemon (protocol 3), published among the poses.
    pub field_frames: AtomicU64,
    /// Poses Zenoh refused to take (the session is closing).
    pub put_errors: AtomicU64,
    /// Gaps in the daemon's stream (the bridge itself read too slowly).
    pub gaps: AtomicU64,
    /// Element tables, field tables and hellos published.
    pub announcements: AtomicU64,
    /// Status reports published.
    pub statuses: AtomicU64,
    /// Queries answered (hello, elements, fields, status, clock).
    pub queries: AtomicU64,
    /// Times the daemon connection was re-established.
    pub reconnects: AtomicU64,
    /// Poses not published because an elder bridge under the same name publishes (the README's
    /// "One bridge per name").
    pub withheld: AtomicU64,
    /// Remote control requests handed to the daemon and answered with its reply.
    pub control_answered: AtomicU64,
    /// Remote control requests refused by the bridge (not signed, unknown principal, wrong key,
    /// stale, replayed, not allowed, malformed, busy).
    pub control_refused: AtomicU64,
    /// Poses sent again from the replay ring to subscribers that lost them.
    pub replayed: AtomicU64,
    /// Each peer's own counts, as it reported them.
    peers: replay::Peers,
}

impl BridgeStats {
    /// Each subscriber's counts as it last reported them (frames, missing, recovered) and the
    /// poses the ring sent it: the bridge's view of who loses what.
    pub fn peers(&self) -> Vec<PeerReport> {
        self.peers.reports()
    }
}

impl std::fmt::Display for BridgeStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        write!(
            f,
            "poses={} field_frames={} put_errors={} gaps={} announcements={} statuses={} queries={} reconnects={} \
             withheld={} control_answered={} control_refused={} replayed={} peers={}",
            g(&self.poses),
            g(&self.field_frames),
            g(&self.put_errors),
            g(&self.gaps),
            g(&self.announcements),
            g(&self.statuses),
            g(&self.queries),
            g(&self.reconnects),
            g(&self.withheld),
            g(&self.control_answered),
            g(&self.control_refused),
            g(&self.replayed),
            replay::summary(&self.peers.reports())
        )
    }
}

struct Shared {
    latest: Mutex<Latest>,
    /// Sequence number of the next pose (written per pose, so not behind the mutex).
    next_seq: AtomicU64,
    stats: Arc<BridgeStats>,
    /// [`BridgeConfig::clock_offset_ns`].
    clock_offset_ns: i64,
    /// An elder bridge publishes under this name: publish and answer nothing ([`claim`]).
    standby: AtomicBool,
    /// The last poses published, for the `replay` queryable.
    ring: Mutex<replay::Ring>,
}

impl Shared {
    /// This host's clocks read back to back, the test hook's offset added to the realtime one.
    fn clock(&self) -> ClockReading {
        let monotonic_ns = frond_sdk::clock::monotonic_ns();
        let unix_ns = realtime_ns().saturating_add_signed(self.clock_offset_ns);
        ClockReading { unix_ns, monotonic_ns }
    }
}

impl Shared {
    /// Whether an elder bridge under the same name publishes, so this one must keep quiet.
    fn standing_by(&self) -> bool {
        self.standby.load(Ordering::Relaxed)
    }

    fn latest(&self) -> std::sync::MutexGuard<'_, Latest> {
        self.latest.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn ring(&self) -> std::sync::MutexGuard<'_, replay::Ring> {
        self.ring.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A running bridge: a Zenoh session with its publishers, queryables and token.
pub struct Bridge {
    config: BridgeConfig,
    session: zenoh::Session,
    poses: zenoh::pubsub::Publisher<'static>,
    elements: zenoh::pubsub::Publisher<'static>,
    fields: zenoh::pubsub::Publisher<'static>,
    hello: zenoh::pubsub::Publisher<'static>,
    _queryables: Vec<zenoh::query::Queryable<()>>,
    _control: Option<control::RemoteControl>,
    token: Option<zenoh::liveliness::LivelinessToken>,
    _claim: claim::Claim,
    /// Whether [`Bridge::follow_claim`] last saw the bridge standing by.
    standing_by: bool,
    shared: Arc<Shared>,
    frame: FrameBuf,
    /// This host's clocks, re-read every [`CLOCK_REFRESH`]: stage time of a pose.
    clock: ClockReading,
    clock_read_at: Instant,
}

/// How often the bridge re-reads its host's clocks (the realtime clock may be slewed by NTP).
const CLOCK_REFRESH: Duration = Duration::from_secs(1);

fn declare_err(what: &str) -> impl Fn(zenoh::Error) -> BridgeError + '_ {
    move |e| BridgeError::Declare { what: what.to_owned(), reason: e.to_string() }
}

impl Bridge {
    /// Opens the Zenoh session (peer mode unless the configuration file says otherwise, with
    /// timestamping on) and declares the publishers and queryables.
    pub fn open(config: BridgeConfig) -> Result<Bridge, BridgeError> {
        let zconfig = frond_sdk::zenoh::config(
            config.addr.config.as_deref(),
            None,
            &config.addr.connect,
            &config.addr.listen,
            &[("timestamping/enabled", "true")],
        )?;
        let session = frond_sdk::zenoh::open_session(zconfig)?;
        let key = config.addr.key.clone();
        let publisher = |leaf: &str, priority: Priority| {
            let k = keys::under(&key, leaf);
            session
                .declare_publisher(k.clone())
                .congestion_control(CongestionControl::Drop)
                .priority(priority)
                .express(EXPRESS)
                .wait()
                .map_err(declare_err(&k))
        };
        // One priority for everything a subscriber reads in order (poses and field frames,
        // tables, hellos).
        let poses = publisher(keys::POSES, Priority::RealTime)?;
        let elements = publisher(keys::ELEMENTS, Priority::RealTime)?;
        let fields = publisher(keys::FIELDS, Priority::RealTime)?;
        let hello = publisher(keys::HELLO, Priority::RealTime)?;
        let shared = Arc::new(Shared {
            latest: Mutex::new(Latest::default()),
            next_seq: AtomicU64::new(0),
            stats: Arc::default(),
            clock_offset_ns: config.clock_offset_ns,
            standby: AtomicBool::new(false),
            ring: Mutex::new(replay::Ring::new(config.replay_frames)),
        });
        // The claim first, and the claims already on the network asked for before anything is
        // published, so that a bridge started under a taken name stands by from the start.
        let connects = !config.addr.connect.is_empty() || config.addr.config.is_some();
        let claim = claim::Claim::declare(&session, &key, shared.clone(), connects)
            .map_err(declare_err(&keys::under(&key, keys::BRIDGE)))?;
        let queryables = queryables::declare(&session, &key, &shared)?;
        let remote_control = match config.control.clone() {
            None => None,
            Some(policy) => Some(
                control::RemoteControl::start(&session, &key, &config.socket_dir, policy, shared.clone())
                    .map_err(declare_err(&keys::under(&key, keys::CONTROL)))?,
            ),
        };
        Ok(Bridge {
            config,
            session,
            poses,
            elements,
            fields,
            hello,
            _queryables: queryables,
            _control: remote_control,
            token: None,
            _claim: claim,
            standing_by: false,
            clock: shared.clock(),
            clock_read_at: Instant::now(),
            shared,
            frame: FrameBuf::with_capacity(1024),
        })
    }

    /// The bridge's counters.
    pub fn stats(&self) -> &BridgeStats {
        &self.shared.stats
    }

    /// The counters, to read from another thread while [`Bridge::run`] goes on.
    pub fn stats_handle(&self) -> Arc<BridgeStats> {
        self.shared.stats.clone()
    }

    /// The Zenoh id of the bridge's session.
    pub fn zid(&self) -> String {
        self.session.zid().to_string()
    }

    /// Streams until `stop` is set: connects to the daemon (waiting for it when it is not
    /// running, and again whenever it stops), publishes its streams and polls its status.
    pub fn run(&mut self, stop: &AtomicBool) -> Result<(), BridgeError> {
        let status = status::spawn(
            self.config.socket_dir.clone(),
            self.session.clone(),
            keys::under(&self.config.addr.key, keys::STATUS),
            self.config.status_interval,
            self.shared.clone(),
        )?;
        let result = self.stream(stop);
        status.stop();
        self.set_alive(false);
        result
    }

    fn stream(&mut self, stop: &AtomicBool) -> Result<(), BridgeError> {
        let mut waiting_since: Option<Instant> = None;
        while !stop.load(Ordering::Relaxed) {
            let opts = Subscriber::options()
                .give_up_after(None)
                .max_retry_interval(Duration::from_millis(500))
                .read_timeout(Some(Duration::from_millis(200)));
            let mut sub = match opts.connect(&self.config.socket_dir) {
                Ok(sub) => sub,
                Err(e) if e.is_fatal() => return Err(e.into()),
                Err(e) => {
                    if waiting_since.is_none() {
                        tracing::warn!(error = %e, "waiting for the daemon");
                        waiting_since = Some(Instant::now());
                    }
                    std::thread::sleep(Duration::from_millis(200));
                    continue;
                }
            };
            if waiting_since.take().is_some() {
                self.shared.stats.reconnects.fetch_add(1, Ordering::Relaxed);
            }
            self.follow_claim();
            let doing = if self.standing_by { "connected; standing by" } else { "publishing" };
            tracing::info!(key = %self.config.addr.key, rig = %sub.hello().rig_name, "{doing}");
            self.on_hello(sub.hello().clone());
            self.pump(&mut sub, stop)?;
        }
        Ok(())
    }

    /// Forwards one subscription's events until `stop`, or until it fails for good.
    fn pump(&mut self, sub: &mut Subscriber, stop: &AtomicBool) -> Result<(), BridgeError> {
        while !stop.load(Ordering::Relaxed) {
            self.follow_claim();
            match sub.next_relayed() {
                Ok(Relayed::Event(Event::Pose(pose))) => {
                    self.shared.stats.poses.fetch_add(1, Ordering::Relaxed);
                    let (seq, host_ns) = (pose.seq, pose.host_monotonic_ns);
                    self.publish_numbered(seq, 1, host_ns, &ServerMessage::Pose(pose));
                }
                Ok(Relayed::Field(FieldMessage::Frame(frame))) => {
                    self.shared.stats.field_frames.fetch_add(1, Ordering::Relaxed);
                    let (seq, span) = (frame.seq, u64::from(frame.poses).max(1));
                    let msg = ServerMessage::Field(FieldMessage::Frame(frame));
                    self.publish_numbered(seq, span, frame.host_monotonic_ns, &msg);
                }
                Ok(Relayed::Field(FieldMessage::Table(table))) => self.on_fields(table),
                Ok(Relayed::Event(Event::Gap { .. })) => {
                    self.shared.stats.gaps.fetch_add(1, Ordering::Relaxed);
                }
                Ok(Relayed::Event(Event::Elements(table))) => self.on_elements(table),
                Ok(Relayed::Event(Event::RigChanged(hello))) => self.announce_hello(hello),
                Ok(Relayed::Event(Event::Reconnected(hello))) => {
                    self.shared.stats.reconnects.fetch_add(1, Ordering::Relaxed);
                    tracing::info!(rig = %hello.rig_name, "the daemon is back");
                    self.on_hello(hello);
                }
                Ok(Relayed::Event(Event::Disconnected)) => {
                    tracing::warn!("the daemon went away; subscribers see this source as disconnected");
                    let mut latest = self.shared.latest();
                    (latest.hello, latest.fields) = (None, None);
                    drop(latest);
                    self.set_alive(false);
                }
                Err(SdkError::Timeout { .. }) => {}
                Err(e) if e.is_fatal() => return Err(e.into()),
                Err(e) => tracing::warn!(error = %e, "pose stream"),
            }
        }
        Ok(())
    }

    /// Publishes a pose or a field frame (`span` sequence numbers from `seq`: a field frame's
    /// own and its announced plants', which subscribers evaluate) on `poses`, stamped with its
    /// stage time, and keeps it in the replay ring.
    fn publish_numbered(&mut self, seq: u64, span: u64, host_monotonic_ns: u64, msg: &ServerMessage) {
        self.shared.next_seq.store(seq.saturating_add(span), Ordering::Relaxed);
        if self.standing_by {
            self.shared.stats.withheld.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if self.clock_read_at.elapsed() >= CLOCK_REFRESH {
            self.clock = self.shared.clock();
            self.clock_read_at = Instant::now();
        }
        let stage_ns = self.clock.stage_ns_of(host_monotonic_ns);
        let bytes = ZBytes::from(self.frame.encode(msg).to_vec());
        let attachment = encode_attachment(stage_ns).to_vec();
        if self.poses.put(bytes.clone()).attachment(attachment).wait().is_err() {
            self.shared.stats.put_errors.fetch_add(1, Ordering::Relaxed);
        }
        self.shared.ring().push_pose(seq, bytes, stage_ns);
    }

    /// Acts on a turn of the claims (see [`claim`]): standing by, the `alive` token goes, so
    /// subscribers see the source as disconnected until it publishes again; taking over, the
    /// hello and the token come back, so they rejoin on this bridge's daemon.
    fn follow_claim(&mut self) {
        let now = self.shared.standing_by();
        if now == self.standing_by {
            return;
        }
        self.standing_by = now;
        if now {
            self.set_alive(false);
        } else {
            let hello = self.shared.latest().hello.clone();
            if let Some(hello) = hello {
                // The daemon's hello, brought up to the pose that comes next.
                self.on_hello(Hello { next_seq: self.shared.next_seq.load(Ordering::Relaxed), ..hello });
            }
        }
    }

    /// A (new) daemon connection: its hello is the latest, and the token says the source is up.
    fn on_hello(&mut self, hello: Hello) {
        self.shared.next_seq.store(hello.next_seq, Ordering::Relaxed);
        // A new connection: the daemon sends its field table after the hello if a field runs.
        let mut latest = self.shared.latest();
        (latest.hello, latest.fields) = (Some(hello.clone()), None);
        drop(latest);
        self.publish(Which::Hello, &ServerMessage::Hello(hello));
        self.set_alive(true);
    }

    fn announce_hello(&mut self, hello: Hello) {
        self.shared.latest().hello = Some(hello.clone());
        self.publish(Which::Hello, &ServerMessage::Hello(hello));
    }

    fn on_elements(&mut self, table: ElementTable) {
        if let Some(hello) = self.shared.latest().hello.as_mut() {
            hello.elements = table.clone();
        }
        self.publish(Which::Elements, &ServerMessage::Elements(table));
    }

    /// The daemon's running fields (after each element table): the latest, put on `fields` and
    /// kept in the replay ring between the poses it precedes.
    fn on_fields(&mut self, table: FieldTable) {
        self.shared.latest().fields = Some(table.clone());
        self.publish(Which::Fields, &ServerMessage::Field(FieldMessage::Table(table)));
    }

    fn publish(&mut self, which: Which, msg: &ServerMessage) {
        if self.standing_by {
            return;
        }
        let bytes = ZBytes::from(self.frame.encode(msg).to_vec());
        let publisher = match which {
            Which::Hello => &self.hello,
            Which::Elements | Which::Fields => {
                let next_seq = self.shared.next_seq.load(Ordering::Relaxed);
                self.shared.ring().push_table(next_seq, bytes.clone());
                if matches!(which, Which::Fields) { &self.fields } else { &self.elements }
            }
        };
        self.shared.stats.announcements.fetch_add(1, Ordering::Relaxed);
        if let Err(e) = publisher.put(bytes).wait() {
            tracing::warn!(error = %e, "publishing an announcement");
        }
    }

    fn set_alive(&mut self, alive: bool) {
        let alive = alive && !self.standing_by;
        if alive == self.token.is_some() {
            return;
        }
        if !alive {
            if let Some(token) = self.token.take()
                && let Err(e) = token.undeclare().wait()
            {
                tracing::warn!(error = %e, "withdrawing the liveliness token");
            }
            return;
        }
        let key = keys::under(&self.config.addr.key, keys::ALIVE);
        match self.session.liveliness().declare_token(key).wait() {
            Ok(token) => self.token = Some(token),
            Err(e) => tracing::warn!(error = %e, "declaring the liveliness token"),
        }
    }
}

#[derive(Clone, Copy)]
enum Which {
    Hello,
    Elements,
    Fields,
}
