//! Several sources at once: a [`StageSubscriber`] follows every source a selector matches
//! (`zenoh:frond/stage1/*`: every performer of stage1; `zenoh:frond/*/*` or `zenoh:`: every
//! source on the network), including sources whose bridges join later, and delivers their events
//! in one stream, each tagged with its source.
//!
//! Each source is an ordinary [`Subscriber`] (the same hello, element table, gap detection,
//! disconnect and reconnect), opened in one Zenoh session shared by all of them, on a thread of
//! its own that hands its events to the one stream. Sources are found by their bridges' liveliness
//! tokens (`<selector>/alive`). A source whose subscription ends with an error is reported
//! ([`StageEvent::Lost`]) and followed again when its bridge's token comes back.
//!
//! Fields (issue 48) cross per source as for one [`Subscriber`]: each follower evaluates its
//! source's announced plants into [`Event::Pose`]s, and passes the field messages it took on
//! ([`StageEvent::Field`]), in its source's order, just before the events they give. A program
//! that draws every source's fields keeps a [`StageFields`] and gives it each item:
//!
//! ```no_run
//! use frond_sdk::zenoh_many::{StageFields, StageSubscriber};
//! use frond_sdk::{Source, Subscriber};
//!
//! let Source::Zenoh(addr) = "zenoh:frond/stage1/*".parse::<Source>()? else { unreachable!() };
//! let stage = StageSubscriber::open(&addr, Subscriber::options())?;
//! let mut fields = StageFields::new();
//! while let Some(item) = stage.next_event(None)? {
//!     if let Some((source, live)) = fields.on_event(&item) {
//!         for field in live.iter() {
//!             // Plant 1234 of this source's field, as its daemon evaluates it.
//!             println!("{source}: {:?}", field.plant_pose(1234, field.tau_s()));
//!         }
//!     }
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::{BTreeMap, HashSet};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ::zenoh::Wait;
use ::zenoh::sample::SampleKind;
use crossbeam_channel::{Receiver, RecvTimeoutError, Sender, bounded};
use frond_protocol::Hello;
use frond_protocol::field::FieldMessage;

use crate::error::SdkError;
use crate::field::LiveFields;
use crate::source::ZenohAddr;
pub use crate::zenoh::short;
use crate::zenoh::{FRAME_QUEUE, keys, open_addr_session, source_key_of};
use crate::{Event, Subscriber, SubscriberOptions};

/// Most sources one [`StageSubscriber`] follows; tokens of further sources are counted in
/// [`StageSubscriber::ignored_sources`] and not followed.
pub const MAX_FOLLOWED_SOURCES: usize = 64;

/// How often a follower thread looks up from its source to see whether it is to stop.
const POLL: Duration = Duration::from_millis(200);
/// How long dropping a [`StageSubscriber`] waits for its followers to stop.
const DROP_WAIT: Duration = Duration::from_secs(1);

/// One item of a [`StageSubscriber`]'s stream. `source` is the source's key below `frond/`:
/// `<stage>/<source>` (`stage1/glove-a`).
#[derive(Debug)]
pub enum StageEvent {
    /// A source is followed from now on (it was there at the start, or its bridge joined).
    Joined {
        /// `<stage>/<source>`.
        source: String,
        /// Its daemon's hello.
        hello: Box<Hello>,
    },
    /// An event of a followed source, in that source's order.
    Event {
        /// `<stage>/<source>`.
        source: String,
        /// The event, as [`Subscriber::next_event`] reports it.
        event: Event,
    },
    /// A field message of a followed source, as its subscription took it: a table (the
    /// source's running fields) or a frame, in that source's order before the events it gives
    /// (its announced plants' poses). Keep them per source with [`StageFields`].
    Field {
        /// `<stage>/<source>`.
        source: String,
        /// The table or frame (boxed: a frame is large beside an event).
        message: Box<FieldMessage>,
    },
    /// A source's subscription could not be opened or ended with an error. It is followed
    /// again when its bridge's liveliness token comes back.
    Lost {
        /// `<stage>/<source>`.
        source: String,
        /// Why.
        error: SdkError,
    },
}

/// What the discovery callback, the follower threads and the stream share.
struct Shared {
    stop: AtomicBool,
    /// Keys (`frond/<stage>/<source>`) with a follower thread now.
    followed: Mutex<HashSet<String>>,
    ignored: AtomicU64,
    threads: Mutex<Vec<JoinHandle<()>>>,
}

impl Shared {
    fn followed(&self) -> std::sync::MutexGuard<'_, HashSet<String>> {
        self.followed.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Follows every source a selector matches; see the [module docs](self).
pub struct StageSubscriber {
    selector: String,
    events: Receiver<StageEvent>,
    shared: Arc<Shared>,
    _tokens: ::zenoh::pubsub::Subscriber<()>,
    _session: ::zenoh::Session,
}

impl StageSubscriber {
    /// Opens one session as `addr` says (endpoints, configuration file) and follows every
    /// source its key matches, now and as they join. `opts` applies to each source's
    /// subscription (its read timeout is the follower's own business and is replaced).
    pub fn open(addr: &ZenohAddr, opts: SubscriberOptions) -> Result<StageSubscriber, SdkError> {
        let setup = |e: crate::zenoh::ZenohSetupError| SdkError::Zenoh {
            source_key: addr.to_string(),
            reason: e.to_string(),
        };
        let session = open_addr_session(addr).map_err(setup)?;
        let (tx, events) = bounded(FRAME_QUEUE);
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            followed: Mutex::new(HashSet::new()),
            ignored: AtomicU64::new(0),
            threads: Mutex::new(Vec::new()),
        });
        let opts = opts.read_timeout(Some(POLL));
        let tokens = {
            let (shared, session2, tx) = (shared.clone(), session.clone(), tx.clone());
            session
                .liveliness()
                .declare_subscriber(keys::under(&addr.key, keys::ALIVE))
                .history(true)
                .callback(move |sample| {
                    if sample.kind() != SampleKind::Put {
                        return; // a follower sees its own source go
                    }
                    if let Some(key) = source_key_of(sample.key_expr().as_str()) {
                        follow(&shared, &session2, key, &opts, &tx);
                    }
                })
                .wait()
                .map_err(|e| SdkError::Zenoh { source_key: addr.to_string(), reason: e.to_string() })?
        };
        Ok(StageSubscriber { selector: addr.key.clone(), events, shared, _tokens: tokens, _session: session })
    }

    /// The selector followed (`frond/stage1/*`).
    pub fn selector(&self) -> &str {
        &self.selector
    }

    /// The next item of any source, waiting at most `timeout` (`None`: until one comes).
    /// `Ok(None)` when the wait ran out.
    pub fn next_event(&self, timeout: Option<Duration>) -> Result<Option<StageEvent>, SdkError> {
        let got = match timeout {
            Some(t) => self.events.recv_timeout(t),
            None => self.events.recv().map_err(|_| RecvTimeoutError::Disconnected),
        };
        match got {
            Ok(ev) => Ok(Some(ev)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            // The discovery callback holds a sender for as long as the session lives.
            Err(RecvTimeoutError::Disconnected) => Err(SdkError::Zenoh {
                source_key: self.selector.clone(),
                reason: "the Zenoh session closed".into(),
            }),
        }
    }

    /// The sources followed now (`<stage>/<source>`), sorted.
    pub fn sources(&self) -> Vec<String> {
        let mut v: Vec<String> = self.shared.followed().iter().map(|k| short(k).to_owned()).collect();
        v.sort();
        v
    }

    /// Sources seen but not followed because [`MAX_FOLLOWED_SOURCES`] were followed already.
    pub fn ignored_sources(&self) -> u64 {
        self.shared.ignored.load(Relaxed)
    }
}

impl Drop for StageSubscriber {
    /// Stops every follower. One that is streaming or reconnecting sees the stop within
    /// 200 ms and is joined; one still opening its subscription (waiting for a hello, up to
    /// the options' hello timeout) is left to finish on its own after a second: it delivers
    /// nothing more and ends as soon as its open returns.
    fn drop(&mut self) {
        self.shared.stop.store(true, Relaxed);
        // Followers blocked on a full stream see the stop within POLL once it is drained.
        while self.events.try_recv().is_ok() {}
        let threads =
            std::mem::take(&mut *self.shared.threads.lock().unwrap_or_else(PoisonError::into_inner));
        let deadline = Instant::now() + DROP_WAIT;
        for t in threads {
            while !t.is_finished() && Instant::now() < deadline {
                while self.events.try_recv().is_ok() {}
                std::thread::sleep(Duration::from_millis(10));
            }
            if t.is_finished() {
                let _ = t.join();
            }
        }
    }
}

/// Starts a follower for `key` unless one runs or the limit is reached. Runs on Zenoh's thread:
/// it only spawns.
fn follow(
    shared: &Arc<Shared>,
    session: &::zenoh::Session,
    key: String,
    opts: &SubscriberOptions,
    tx: &Sender<StageEvent>,
) {
    if shared.stop.load(Relaxed) {
        return;
    }
    {
        let mut followed = shared.followed();
        if followed.contains(&key) {
            return;
        }
        if followed.len() >= MAX_FOLLOWED_SOURCES {
            shared.ignored.fetch_add(1, Relaxed);
            return;
        }
        followed.insert(key.clone());
    }
    let (shared2, session, opts, tx) = (shared.clone(), session.clone(), opts.clone(), tx.clone());
    let thread_key = key.clone();
    let spawned = std::thread::Builder::new()
        .name(format!("frond-follow {}", short(&key)))
        .spawn(move || run_follower(&shared2, session, &thread_key, opts, &tx));
    match spawned {
        Ok(handle) => {
            let mut threads = shared.threads.lock().unwrap_or_else(PoisonError::into_inner);
            threads.retain(|t| !t.is_finished());
            threads.push(handle);
        }
        Err(_) => {
            // No thread to be had: forget the source so its next token tries again.
            shared.followed().remove(&key);
        }
    }
}

/// Hands `ev` to the stream, waiting while it is full; false when the subscriber is gone.
fn deliver(shared: &Shared, tx: &Sender<StageEvent>, mut ev: StageEvent) -> bool {
    loop {
        if shared.stop.load(Relaxed) {
            return false;
        }
        match tx.send_timeout(ev, POLL) {
            Ok(()) => return true,
            Err(crossbeam_channel::SendTimeoutError::Timeout(back)) => ev = back,
            Err(crossbeam_channel::SendTimeoutError::Disconnected(_)) => return false,
        }
    }
}

fn run_follower(
    shared: &Shared,
    session: ::zenoh::Session,
    key: &str,
    opts: SubscriberOptions,
    tx: &Sender<StageEvent>,
) {
    let source = short(key).to_owned();
    let addr = ZenohAddr { key: key.to_owned(), connect: Vec::new(), listen: Vec::new(), config: None };
    let lost = |error| StageEvent::Lost { source: source.clone(), error };
    match Subscriber::open_in_session(session, &addr, opts) {
        Ok(mut sub) => {
            sub.pass_field_messages();
            let joined = StageEvent::Joined { source: source.clone(), hello: Box::new(sub.hello().clone()) };
            if deliver(shared, tx, joined) {
                'events: loop {
                    match sub.next_event() {
                        Ok(event) => {
                            let passed: Vec<FieldMessage> = sub.take_passed().collect();
                            for message in passed {
                                let field =
                                    StageEvent::Field { source: source.clone(), message: Box::new(message) };
                                if !deliver(shared, tx, field) {
                                    break 'events;
                                }
                            }
                            if !deliver(shared, tx, StageEvent::Event { source: source.clone(), event }) {
                                break;
                            }
                        }
                        Err(SdkError::Timeout { .. }) if !shared.stop.load(Relaxed) => {}
                        Err(SdkError::Timeout { .. }) => break,
                        Err(e) => {
                            deliver(shared, tx, lost(e));
                            break;
                        }
                    }
                }
            }
        }
        Err(e) => {
            deliver(shared, tx, lost(e));
        }
    }
    shared.followed().remove(key);
}

/// Every followed source's running fields, kept from a [`StageSubscriber`]'s stream: what
/// [`Subscriber::fields`] is for one source (see the [module docs](self)). A source starts
/// afresh when it joins (again); its fields are forgotten when it disconnects, as its own
/// subscription forgets them, and the source with them when it is lost.
#[derive(Debug, Clone, Default)]
pub struct StageFields {
    sources: BTreeMap<String, LiveFields>,
}

impl StageFields {
    /// No source yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one item of the stream. When it changed a source's fields (a table or a frame
    /// taken), returns that source (`<stage>/<source>`) and its fields now.
    pub fn on_event<'a>(&'a mut self, item: &'a StageEvent) -> Option<(&'a str, &'a LiveFields)> {
        match item {
            StageEvent::Joined { source, .. } => {
                self.sources.insert(source.clone(), LiveFields::keeping(0));
                None
            }
            // A lost source's follower has ended: drop its entry, so sources that come and go
            // under ever new names do not pile up.
            StageEvent::Lost { source, .. } => {
                self.sources.remove(source);
                None
            }
            StageEvent::Event { source, event: Event::Disconnected | Event::Reconnected(_) } => {
                if let Some(fields) = self.sources.get_mut(source) {
                    fields.clear();
                }
                None
            }
            StageEvent::Event { .. } => None,
            StageEvent::Field { source, message } => {
                // Only followed sources have an entry: at most MAX_FOLLOWED_SOURCES.
                let fields = self.sources.get_mut(source)?;
                let changed = match &**message {
                    // The follower's subscription already logged any definition it left out.
                    FieldMessage::Table(table) => {
                        fields.on_table(table.clone());
                        true
                    }
                    FieldMessage::Frame(frame) => fields.on_frame(frame).is_some(),
                };
                changed.then_some((source.as_str(), &*fields))
            }
        }
    }

    /// One source's fields (`<stage>/<source>`), while it is followed.
    pub fn source(&self, source: &str) -> Option<&LiveFields> {
        self.sources.get(source)
    }

    /// Every followed source and its fields, by source name.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &LiveFields)> + '_ {
        self.sources.iter().map(|(s, f)| (s.as_str(), f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_fields_keep_followed_sources_only_and_forget_lost_ones() {
        use frond_protocol::field::FieldTable;
        let hello = Hello {
            protocol_version: frond_protocol::PROTOCOL_VERSION,
            daemon_version: "test".into(),
            rig_name: "grass".into(),
            joint_names: ["a", "b", "c", "d"].map(String::from).to_vec(),
            tick_rate_hz: 1000,
            elements: Default::default(),
            next_seq: 0,
        };
        let table = |source: &str| StageEvent::Field {
            source: source.into(),
            message: Box::new(FieldMessage::Table(FieldTable { elements_version: 1, fields: Vec::new() })),
        };
        let mut fields = StageFields::new();
        // A source never joined (a follower's item after its loss) makes no entry.
        assert!(fields.on_event(&table("s/x")).is_none());
        assert!(fields.source("s/x").is_none());
        fields.on_event(&StageEvent::Joined { source: "s/a".into(), hello: Box::new(hello) });
        assert_eq!(fields.on_event(&table("s/a")).map(|(s, f)| (s, f.is_empty())), Some(("s/a", true)));
        assert_eq!(fields.iter().map(|(s, _)| s).collect::<Vec<_>>(), ["s/a"]);
        let lost = StageEvent::Lost { source: "s/a".into(), error: SdkError::Closed };
        assert!(fields.on_event(&lost).is_none());
        assert!(fields.source("s/a").is_none() && fields.iter().next().is_none());
    }

    #[test]
    fn token_keys_name_plain_sources_only() {
        assert_eq!(source_key_of("frond/stage1/glove-a/alive").as_deref(), Some("frond/stage1/glove-a"));
        assert_eq!(source_key_of("frond/stage1/glove-a/poses"), None);
        assert_eq!(source_key_of("frond/stage1/glove-a/alive/x"), None);
        assert_eq!(source_key_of("other/stage1/glove-a/alive"), None);
        assert_eq!(source_key_of("frond/stage1/$*/alive"), None);
        assert_eq!(source_key_of("frond/stage1"), None);
        assert_eq!(short("frond/stage1/glove-a"), "stage1/glove-a");
    }
}
