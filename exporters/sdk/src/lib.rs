//! Client side of frond's pose stream, for exporters.
//!
//! ```no_run
//! use frond_sdk::Subscriber;
//!
//! let mut sub = Subscriber::connect("/run/user/1000/frond")?;
//! println!("rig {}", sub.hello().rig_name);
//! for pose in sub.by_ref().take(100) {
//!     let pose = pose?;
//!     println!("{} {:?}", pose.seq, pose.joints_deg);
//! }
//! println!("{:?}", sub.stats());
//! # Ok::<(), frond_sdk::SdkError>(())
//! ```
//!
//! A [`Subscriber`] connects to `poses.sock` in the daemon's socket directory, reads the daemon's
//! [`Hello`] with its [`ElementTable`] (what each element id is: the hand, a layer, a looped take,
//! a field plant; kept up to date by [`Event::Elements`]), then delivers [`Pose`]s. It watches sequence numbers: a pose whose `seq` is past the
//! expected one is reported as [`Event::Gap`] (the daemon dropped frames for this subscriber, e.g.
//! because it read too slowly). When the connection ends it reports [`Event::Disconnected`] and, if
//! reconnection is enabled (the default), reconnects with exponential backoff; a restarted daemon
//! numbers its frames from its new `Hello.next_seq`, which is a [`Event::Reconnected`], not a gap.
//!
//! Nothing the socket delivers can make it panic: undecodable bytes surface as
//! [`SdkError::Protocol`] and the connection is dropped (and re-established when reconnection is
//! on); a daemon speaking a newer protocol version is refused with
//! [`ProtocolError::UnsupportedVersion`], which ends the subscription.

#![warn(missing_docs)]

pub mod clock;
mod conn;
pub mod control;
#[cfg(feature = "zenoh")]
pub mod control_auth;
mod error;
pub mod field;
pub mod health;
mod reconnect;
pub mod source;
#[cfg(feature = "zenoh")]
pub mod stage_time;
#[cfg(feature = "zenoh")]
pub mod zenoh;
#[cfg(feature = "zenoh")]
pub mod zenoh_callback;
#[cfg(feature = "zenoh")]
mod zenoh_config;
#[cfg(feature = "zenoh")]
pub mod zenoh_control;
#[cfg(feature = "zenoh")]
mod zenoh_join;
#[cfg(feature = "zenoh")]
mod zenoh_keys;
#[cfg(feature = "zenoh")]
pub mod zenoh_many;
#[cfg(feature = "zenoh")]
pub mod zenoh_replay;
#[cfg(feature = "zenoh")]
pub mod zenoh_runtime_env;
#[cfg(feature = "zenoh")]
pub mod zenoh_stage;
#[cfg(feature = "zenoh")]
mod zenoh_status;

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::time::Duration;

pub use control::{ControlClient, ControlClientError};
pub use error::{ProtocolError, SdkError};
pub use frond_protocol::{
    ElementId, ElementInfo, ElementKind, ElementTable, HandWire, Hello, PROTOCOL_VERSION, Pose, PoseFlags,
    RigInfo,
};
pub use source::{Source, SourceError, ZenohAddr};

use conn::{Conn, ReadOutcome};
use frond_protocol::ServerMessage;

/// What [`Subscriber::next_event`] reports.
///
/// ```no_run
/// use frond_sdk::{Event, Subscriber};
///
/// let mut sub = Subscriber::connect(frond_protocol::paths::socket_dir(None))?;
/// loop {
///     match sub.next_event()? {
///         Event::Pose(p) => println!("element {} seq {}: {:?}", p.element, p.seq, p.joints_deg),
///         Event::Gap { expected, got } => eprintln!("{} frames lost", got - expected),
///         Event::Elements(table) => eprintln!("{} elements now", table.elements.len()),
///         Event::RigChanged(hello) | Event::Reconnected(hello) => eprintln!("rig {}", hello.rig_name),
///         Event::Disconnected => eprintln!("the daemon went away; reconnecting"),
///     }
/// }
/// # Ok::<(), frond_sdk::SdkError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// One pose, in order.
    Pose(Pose),
    /// Poses `expected..got` never arrived (the daemon dropped them for this subscriber).
    /// `got - expected` frames are missing; the pose numbered `got` is the next event.
    Gap {
        /// The sequence number that was due.
        expected: u64,
        /// The sequence number that arrived.
        got: u64,
    },
    /// The daemon's rig changed: it sent a new hello on the same connection, or an element table
    /// whose first rig (the daemon's) differs from the hello's. Carries the hello brought up to
    /// date (rig name, joint names, elements); an [`Event::Elements`] with the table follows.
    RigChanged(Hello),
    /// The daemon announced a new element table (its live stages or rig changed); it applies to
    /// the poses that follow. [`Subscriber::elements`] has it too.
    Elements(ElementTable),
    /// A new connection was made after a disconnect; carries the new daemon's hello.
    Reconnected(Hello),
    /// The connection ended (daemon stopped or restarted). With reconnection on, the next call
    /// reconnects; with it off, the subscription is finished.
    Disconnected,
}

/// What [`Subscriber::next_relayed`] returns: an event, or a field message as the daemon sent
/// it, for a program that passes the stream on rather than reads it (the Zenoh bridge).
#[derive(Debug, Clone, PartialEq)]
// A field frame is large beside an event, but it is read once and passed on at once.
#[allow(clippy::large_enum_variant)]
pub enum Relayed {
    /// One event, as [`Subscriber::next_event`] reports it (never an announced plant's pose:
    /// whoever reads the relayed field frames evaluates those).
    Event(Event),
    /// A field's table or one of its frames, numbered in the stream (a frame after lost ones
    /// comes after its [`Event::Gap`]).
    Field(frond_protocol::field::FieldMessage),
}

/// Counters since the subscriber was created.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Poses delivered.
    pub frames: u64,
    /// Gap events.
    pub gaps: u64,
    /// Frames missing in all gaps together.
    pub missing: u64,
    /// Successful reconnections.
    pub reconnects: u64,
    /// Connections that ended (cleanly or not).
    pub disconnects: u64,
    /// Zenoh samples on the source's keys that were not one frame of this protocol (anyone who
    /// may put on the key can send one): skipped, counted here and logged. Always 0 over the
    /// daemon's socket, where a bad frame ends the connection instead.
    pub rejected: u64,
    /// Poses a reliable Zenoh subscription lost on the way and got back from the bridge's replay
    /// ring ([`SubscriberOptions::reliable`]); they are in `frames`, not in `missing`.
    pub recovered: u64,
}

/// How a [`Subscriber`] behaves. Build with [`SubscriberOptions::new`] and the setters.
#[derive(Debug, Clone)]
pub struct SubscriberOptions {
    reconnect: bool,
    retry_interval: Duration,
    max_retry_interval: Duration,
    give_up_after: Option<Duration>,
    read_timeout: Option<Duration>,
    hello_timeout: Duration,
    reliable: bool,
    keep_field_frames: usize,
}

impl Default for SubscriberOptions {
    fn default() -> Self {
        SubscriberOptions {
            reconnect: true,
            retry_interval: Duration::from_millis(100),
            max_retry_interval: Duration::from_secs(2),
            give_up_after: Some(Duration::from_secs(30)),
            read_timeout: None,
            hello_timeout: Duration::from_secs(5),
            reliable: false,
            keep_field_frames: 0,
        }
    }
}

impl SubscriberOptions {
    /// Defaults: reconnect on, first retry after 100 ms doubling up to 2 s, give up after 30 s,
    /// block without read timeout, 5 s for the hello.
    pub fn new() -> Self {
        Self::default()
    }
    /// Reconnect after the connection ends (default on).
    pub fn reconnect(mut self, on: bool) -> Self {
        self.reconnect = on;
        self
    }
    /// Delay before the first reconnection attempt; doubles after each failure (default 100 ms).
    pub fn retry_interval(mut self, interval: Duration) -> Self {
        self.retry_interval = interval.max(Duration::from_millis(1));
        self
    }
    /// Upper bound of the backoff delay (default 2 s).
    pub fn max_retry_interval(mut self, interval: Duration) -> Self {
        self.max_retry_interval = interval.max(Duration::from_millis(1));
        self
    }
    /// Stop reconnecting after this long without success (`None`: never give up; default 30 s).
    pub fn give_up_after(mut self, limit: Option<Duration>) -> Self {
        self.give_up_after = limit;
        self
    }
    /// Return [`SdkError::Timeout`] when no message arrives for this long (default: block).
    /// The connection survives a timeout. It applies while reconnecting too: a reconnection
    /// still under way when the timeout runs out returns [`SdkError::Timeout`] and carries on at
    /// the next call, its backoff and [`SubscriberOptions::give_up_after`] counted from the
    /// disconnection, so a caller that checks a stop flag between calls is never held longer.
    pub fn read_timeout(mut self, timeout: Option<Duration>) -> Self {
        self.read_timeout = timeout.filter(|t| !t.is_zero());
        self
    }
    /// How long to wait for the daemon's hello after connecting (default 5 s).
    pub fn hello_timeout(mut self, timeout: Duration) -> Self {
        self.hello_timeout = timeout.max(Duration::from_millis(1));
        self
    }
    /// Over Zenoh, fill every gap from the bridge's replay ring before passing the pose after it
    /// on (default off): a recorder or an archive gets every frame while its link is up and it
    /// keeps within the ring (10 s at 1 kHz by default), at the price of a late burst after a
    /// loss; nobody else waits for it ([`zenoh_replay`]). No effect on the socket, where the
    /// daemon's slow lane already keeps a subscriber's backlog.
    pub fn reliable(mut self, on: bool) -> Self {
        self.reliable = on;
        self
    }
    /// Keep the last `frames` field frames taken (default 0, none; at most
    /// [`field::MAX_KEPT_FIELD_FRAMES`]) for [`Subscriber::take_field_frames`]: a program that
    /// passes a field on as the daemon publishes it (the console hands its frames to the page,
    /// which evaluates the plants itself) gets every frame, in order.
    pub fn keep_field_frames(mut self, frames: usize) -> Self {
        self.keep_field_frames = frames.min(field::MAX_KEPT_FIELD_FRAMES);
        self
    }
    /// Connects to `poses.sock` in socket directory `dir` with these options.
    pub fn connect(self, dir: impl AsRef<Path>) -> Result<Subscriber, SdkError> {
        Subscriber::with_options(dir, self)
    }
    /// Subscribes to `source` (a socket directory or a Zenoh address) with these options.
    pub fn subscribe(self, source: &Source) -> Result<Subscriber, SdkError> {
        Subscriber::open(source, self)
    }
}

/// One open connection.
enum Wire {
    Unix(Box<Conn>),
    #[cfg(feature = "zenoh")]
    Zenoh(Box<zenoh::ZenohConn>),
}

enum State {
    Connected(Wire),
    /// The connection ended; a Zenoh subscription keeps its session to rejoin on.
    Disconnected(Option<Wire>),
    Finished,
}

/// Opens `source`, reusing a Zenoh session kept from before a disconnect.
fn open_wire(
    source: &Source,
    opts: &SubscriberOptions,
    kept: &mut Option<Wire>,
) -> Result<(Wire, Hello), SdkError> {
    match source {
        Source::Socket(dir) => {
            let (conn, hello) = Conn::open(&dir.join(frond_protocol::POSES_SOCKET), opts)?;
            Ok((Wire::Unix(Box::new(conn)), hello))
        }
        #[cfg(feature = "zenoh")]
        Source::Zenoh(addr) => match kept {
            // A failed rejoin keeps the session for the next attempt.
            Some(Wire::Zenoh(conn)) => {
                let hello = conn.rejoin(opts)?;
                let wire = kept.take().expect("matched Some above");
                Ok((wire, hello))
            }
            _ => {
                let (conn, hello) = zenoh::ZenohConn::open(addr, opts)?;
                Ok((Wire::Zenoh(Box::new(conn)), hello))
            }
        },
        #[cfg(not(feature = "zenoh"))]
        Source::Zenoh(addr) => {
            let _ = kept;
            Err(SdkError::Zenoh {
                source_key: addr.to_string(),
                reason: "this program was built without Zenoh (frond-sdk's `zenoh` feature)".into(),
            })
        }
    }
}

/// A subscription to the daemon's pose stream. Also an iterator of poses (see the
/// [`Iterator`] impl).
pub struct Subscriber {
    source: Source,
    /// The pose socket, or the Zenoh source key: what errors and logs name.
    path: PathBuf,
    opts: SubscriberOptions,
    state: State,
    hello: Hello,
    elements: ElementTable,
    /// Sequence number due next on the current connection.
    expected_seq: u64,
    pending: VecDeque<Event>,
    stats: Stats,
    iter_done: bool,
    /// A reconnection under way across calls (a read timeout came first).
    retry: Option<reconnect::Retry>,
    /// The running fields (protocol 3).
    fields: field::LiveFields,
    /// Field messages are passed on by [`Subscriber::next_relayed`], not evaluated.
    relay: bool,
    /// The field message [`Subscriber::next_relayed`] returns next.
    relayed: Option<frond_protocol::field::FieldMessage>,
    /// The field messages taken since a [`zenoh_many::StageSubscriber`]'s follower last passed
    /// them on (`None`: nobody passes them on).
    passed: Option<VecDeque<frond_protocol::field::FieldMessage>>,
}

impl std::fmt::Debug for Subscriber {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscriber")
            .field("path", &self.path)
            .field("hello", &self.hello)
            .field("expected_seq", &self.expected_seq)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

impl Subscriber {
    /// Connects with default options to `poses.sock` in the socket directory `dir`
    /// (see `frond_protocol::paths::socket_dir` for the usual one) and reads the daemon's hello.
    ///
    /// Fails at once with [`SdkError::NotRunning`] when no daemon listens; reconnection applies
    /// only to connections that were established once.
    pub fn connect(dir: impl AsRef<Path>) -> Result<Subscriber, SdkError> {
        Self::with_options(dir, SubscriberOptions::default())
    }

    /// Options builder; finish with [`SubscriberOptions::connect`].
    pub fn options() -> SubscriberOptions {
        SubscriberOptions::default()
    }

    /// Connects with `opts`.
    pub fn with_options(dir: impl AsRef<Path>, opts: SubscriberOptions) -> Result<Subscriber, SdkError> {
        Self::open(&Source::Socket(dir.as_ref().to_owned()), opts)
    }

    /// Subscribes to `source`: the socket directory of a daemon on this host, or a
    /// `frond-zenoh` bridge's source over Zenoh (see [`Source`]). The same events either way:
    /// over Zenoh, [`Event::Disconnected`] is the bridge's liveliness token going away (the
    /// bridge lost its daemon, stopped, or its host is unreachable past Zenoh's lease), or
    /// sequence numbers that start again (another bridge took over the name), and
    /// [`Event::Reconnected`] its return; a subscription starts at the first pose that reaches it.
    pub fn open(source: &Source, opts: SubscriberOptions) -> Result<Subscriber, SdkError> {
        let (wire, hello) = open_wire(source, &opts, &mut None)?;
        Ok(Self::from_wire(source, wire, hello, opts))
    }

    /// [`Subscriber::open`] for a Zenoh source in a session that is already open, so that many
    /// subscriptions of one process share one session (as [`zenoh_many::StageSubscriber`]'s do):
    /// `addr`'s endpoints and configuration file are not used, the session's are.
    #[cfg(feature = "zenoh")]
    pub fn open_in_session(
        session: ::zenoh::Session,
        addr: &ZenohAddr,
        opts: SubscriberOptions,
    ) -> Result<Subscriber, SdkError> {
        let (conn, hello) = zenoh::ZenohConn::open_in(session, addr, &opts)?;
        Ok(Self::from_wire(&Source::Zenoh(addr.clone()), Wire::Zenoh(Box::new(conn)), hello, opts))
    }

    fn from_wire(source: &Source, wire: Wire, hello: Hello, opts: SubscriberOptions) -> Subscriber {
        let fields = field::LiveFields::keeping(opts.keep_field_frames);
        let path = match (&wire, source) {
            #[cfg(feature = "zenoh")]
            (Wire::Zenoh(conn), _) => PathBuf::from(format!("{}{}", source::ZENOH_SCHEME, conn.key())),
            (_, Source::Socket(dir)) => dir.join(frond_protocol::POSES_SOCKET),
            (_, other) => PathBuf::from(other.to_string()),
        };
        Subscriber {
            source: source.clone(),
            path,
            expected_seq: hello.next_seq,
            elements: hello.elements.clone(),
            hello,
            opts,
            state: State::Connected(wire),
            pending: VecDeque::new(),
            stats: Stats::default(),
            iter_done: false,
            retry: None,
            fields,
            relay: false,
            relayed: None,
            passed: None,
        }
    }

    /// The stage time of the pose most recently read from the wire (the one an [`Event::Pose`]
    /// just returned, or the one an [`Event::Gap`] announces): its instant on the source host's
    /// realtime clock, nanoseconds since 1970, as the `frond-zenoh` bridge stamps it (see
    /// [`stage_time`]). `None` for socket sources and bridges that do not stamp it.
    pub fn stage_time_ns(&self) -> Option<u64> {
        match &self.state {
            #[cfg(feature = "zenoh")]
            State::Connected(Wire::Zenoh(conn)) => conn.stage_time_ns(),
            _ => None,
        }
    }

    /// The latest hello from the daemon (updated on reconnect and rig change).
    pub fn hello(&self) -> &Hello {
        &self.hello
    }

    /// The element table in force: what each [`Pose::element`] id is (kind, name, rig, joint
    /// names). Updated by [`Event::Elements`] and on reconnect.
    pub fn elements(&self) -> &ElementTable {
        &self.elements
    }

    /// Counters since creation.
    pub fn stats(&self) -> Stats {
        let (rejected, recovered) = match &self.state {
            #[cfg(feature = "zenoh")]
            State::Connected(Wire::Zenoh(conn)) | State::Disconnected(Some(Wire::Zenoh(conn))) => {
                (conn.rejected(), conn.recovered())
            }
            _ => (0, 0),
        };
        Stats { rejected, recovered, ..self.stats }
    }

    /// Path of the pose socket (for a Zenoh source, `zenoh:<source key>`).
    pub fn socket_path(&self) -> &Path {
        &self.path
    }

    /// Where this subscription reads from.
    pub fn source(&self) -> &Source {
        &self.source
    }

    /// Poses the transport delivered that this subscriber's queue had no room for (a Zenoh
    /// subscription that reads too slowly; they also show as gaps). Always 0 on the socket,
    /// where the daemon counts them.
    pub fn overflow(&self) -> u64 {
        match &self.state {
            #[cfg(feature = "zenoh")]
            State::Connected(Wire::Zenoh(conn)) | State::Disconnected(Some(Wire::Zenoh(conn))) => {
                conn.overflow()
            }
            _ => 0,
        }
    }

    /// True while a connection is open.
    pub fn is_connected(&self) -> bool {
        matches!(self.state, State::Connected(_))
    }

    /// Waits for the next event.
    ///
    /// After [`Event::Disconnected`] the next call reconnects (when enabled), blocking with
    /// backoff until it succeeds ([`Event::Reconnected`]) or the bound of
    /// [`SubscriberOptions::give_up_after`] passes ([`SdkError::ReconnectFailed`]), or, with a
    /// [`SubscriberOptions::read_timeout`], until that runs out ([`SdkError::Timeout`]; the next
    /// call goes on reconnecting). After a protocol error the connection is dropped and the
    /// same applies. Once finished, returns
    /// [`SdkError::Closed`].
    pub fn next_event(&mut self) -> Result<Event, SdkError> {
        // A field message with nothing to report (a field's table, a frame before its plants
        // can be evaluated) is taken and the next message read.
        loop {
            if let Some(ev) = self.read_event()? {
                return Ok(ev);
            }
        }
    }

    /// For a program that passes the stream on (the Zenoh bridge): the next event, or the next
    /// field message as the daemon sent it, in the stream's order. Field frames are numbered as
    /// [`Subscriber::next_event`] numbers them (gaps and sequence checks alike), but neither
    /// applied to [`Subscriber::fields`] nor evaluated into the announced plants' poses: the
    /// reader of the relayed stream does both. Once called, a subscription relays for good; do
    /// not mix it with [`Subscriber::next_event`].
    pub fn next_relayed(&mut self) -> Result<Relayed, SdkError> {
        self.relay = true;
        loop {
            if let Some(msg) = self.relayed.take() {
                return Ok(Relayed::Field(msg));
            }
            if let Some(ev) = self.read_event()? {
                return Ok(Relayed::Event(ev));
            }
        }
    }

    fn read_event(&mut self) -> Result<Option<Event>, SdkError> {
        if let Some(ev) = self.pending.pop_front() {
            return Ok(Some(ev));
        }
        match self.state {
            State::Finished => return Err(SdkError::Closed),
            State::Disconnected(_) if !self.opts.reconnect => {
                self.state = State::Finished;
                return Err(SdkError::Closed);
            }
            State::Disconnected(_) => return self.reconnect().map(Some),
            State::Connected(_) => {}
        }
        let State::Connected(wire) = &mut self.state else { unreachable!("checked above") };
        let outcome = match wire {
            Wire::Unix(conn) => conn.read_message(&self.path, self.opts.read_timeout),
            #[cfg(feature = "zenoh")]
            Wire::Zenoh(conn) => conn.read_message(self.opts.read_timeout),
        };
        let event = match outcome {
            ReadOutcome::Message(ServerMessage::Field(msg)) => return self.on_field(msg),
            ReadOutcome::Message(ServerMessage::Pose(pose)) => self.on_pose(pose),
            ReadOutcome::Message(ServerMessage::Elements(table)) => {
                self.elements = table.clone();
                // The table names the daemon's rig first: a different one is a rig change
                // (`frond rig set`, SIGHUP), reported as one with the hello brought up to date.
                match table.rigs.first() {
                    Some(rig)
                        if rig.name != self.hello.rig_name || rig.joint_names != self.hello.joint_names =>
                    {
                        self.hello.rig_name = rig.name.clone();
                        self.hello.joint_names = rig.joint_names.clone();
                        self.hello.elements = table.clone();
                        self.pending.push_back(Event::Elements(table));
                        Ok(Event::RigChanged(self.hello.clone()))
                    }
                    _ => Ok(Event::Elements(table)),
                }
            }
            ReadOutcome::Message(ServerMessage::Hello(hello)) => match check_hello(&hello) {
                Ok(()) => {
                    self.hello = hello.clone();
                    self.elements = hello.elements.clone();
                    Ok(Event::RigChanged(hello))
                }
                Err(error) => Err(self.fail(error)),
            },
            // Only sent in place of a hello; mid-stream it can only mean the daemon is closing.
            ReadOutcome::Message(ServerMessage::Refused(reason)) => {
                tracing::warn!(path = %self.path.display(), %reason, "the daemon dropped the subscription");
                self.drop_connection();
                Ok(Event::Disconnected)
            }
            ReadOutcome::Closed => {
                tracing::info!(path = %self.path.display(), "pose stream closed");
                self.drop_connection();
                Ok(Event::Disconnected)
            }
            ReadOutcome::Err(SdkError::Io { source, path }) => {
                tracing::warn!(path = %path.display(), error = %source, "pose stream i/o error");
                self.drop_connection();
                Ok(Event::Disconnected)
            }
            ReadOutcome::Err(SdkError::Protocol { error, .. }) => Err(self.fail(error)),
            ReadOutcome::Err(other) => Err(other),
        };
        event.map(Some)
    }

    fn on_pose(&mut self, pose: Pose) -> Result<Event, SdkError> {
        let expected = self.expected_seq;
        if pose.seq < expected {
            return self.seq_went_back(expected, pose.seq);
        }
        self.expected_seq = pose.seq + 1;
        self.stats.frames += 1;
        if pose.seq > expected {
            self.count_gap(pose.seq - expected);
            self.pending.push_back(Event::Pose(pose));
            return Ok(Event::Gap { expected, got: pose.seq });
        }
        Ok(Event::Pose(pose))
    }

    /// A frame numbered `got`, below the `expected` one.
    fn seq_went_back(&mut self, expected: u64, got: u64) -> Result<Event, SdkError> {
        // Over Zenoh, numbers that start again are another daemon's stream under the key (one
        // bridge gave way to another under the same name, and the new one's frames arrived
        // before the old one's token was seen to go), not a broken daemon: the subscription
        // rejoins, as when a bridge goes away and comes back.
        #[cfg(feature = "zenoh")]
        if matches!(self.state, State::Connected(Wire::Zenoh(_))) && self.opts.reconnect {
            tracing::info!(
                path = %self.path.display(), expected, got,
                "the source's sequence numbers started again: another stream; rejoining"
            );
            self.drop_connection();
            return Ok(Event::Disconnected);
        }
        Err(self.fail(ProtocolError::SeqWentBackwards { expected, got }))
    }

    /// Counts `missing` frames lost before the one just read.
    fn count_gap(&mut self, missing: u64) {
        self.stats.gaps += 1;
        self.stats.missing += missing;
        // Over Zenoh, an element or field table published during the loss may be lost with it.
        #[cfg(feature = "zenoh")]
        if let State::Connected(Wire::Zenoh(conn)) = &mut self.state {
            conn.refresh_elements();
        }
    }

    fn drop_connection(&mut self) {
        let kept = match std::mem::replace(&mut self.state, State::Finished) {
            #[cfg(feature = "zenoh")]
            State::Connected(wire @ Wire::Zenoh(_)) => Some(wire),
            _ => None,
        };
        self.state = State::Disconnected(kept);
        self.stats.disconnects += 1;
        self.fields.clear();
    }

    /// Drops the connection after a protocol error; a fatal one (or any, without reconnection)
    /// finishes the subscription.
    fn fail(&mut self, error: ProtocolError) -> SdkError {
        tracing::warn!(path = %self.path.display(), %error, "protocol error; dropping the connection");
        self.drop_connection();
        if error.is_fatal() || !self.opts.reconnect {
            self.state = State::Finished;
        }
        SdkError::Protocol { path: self.path.clone(), error }
    }

    /// Iterator over poses only; see the [`Iterator`] impl.
    pub fn poses(&mut self) -> &mut Self {
        self
    }
}

/// Yields every pose in order. Gaps are counted in [`Subscriber::stats`] and reconnections happen
/// inside; the iterator ends when the connection closes with reconnection off, and after a fatal
/// error (which it yields first). Non-fatal errors (a timeout, a protocol error that a reconnect
/// may cure) are yielded and iteration can continue.
impl Iterator for Subscriber {
    type Item = Result<Pose, SdkError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.iter_done {
            return None;
        }
        loop {
            match self.next_event() {
                Ok(Event::Pose(pose)) => return Some(Ok(pose)),
                Ok(Event::Gap { .. } | Event::RigChanged(_) | Event::Elements(_) | Event::Reconnected(_)) => {
                    continue;
                }
                Ok(Event::Disconnected) if self.opts.reconnect => continue,
                Ok(Event::Disconnected) | Err(SdkError::Closed) => {
                    self.iter_done = true;
                    return None;
                }
                Err(e) => {
                    if matches!(self.state, State::Finished) {
                        self.iter_done = true;
                    }
                    return Some(Err(e));
                }
            }
        }
    }
}

fn check_hello(hello: &Hello) -> Result<(), ProtocolError> {
    if hello.protocol_version != PROTOCOL_VERSION {
        return Err(ProtocolError::UnsupportedVersion {
            got: hello.protocol_version,
            supported: PROTOCOL_VERSION,
        });
    }
    Ok(())
}
