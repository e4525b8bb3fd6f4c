//! The `frond-triggers` thread: frond following a mocap stage's master (issue 46).
//!
//! It owns the listening UDP socket ([`TriggerSocket`]), waits on it at most [`TRIGGER_POLL`]
//! (or until a delayed start is due), reads at most [`MAX_DATAGRAMS_PER_WAKE`] datagrams a wake
//! (a flood cannot hold it), and hands each to the pure [`Follower`]. On its decisions it starts
//! and stops takes through the control socket's own path (`record_start` / `record_stop`,
//! holding the recording session as `ControlContext::handle` does), so a trigger take is a take
//! like any other. It never touches the realtime loop but through those calls, and ends within
//! [`TRIGGER_POLL`] of `stop`.

use std::net::IpAddr;
use std::os::fd::AsFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::thread;
use std::time::Duration;

use frond_ltc::FrameRate;
use frond_protocol::ControlReply;
use frond_triggers::{Decision, Follower, FollowerConfig, FollowerState, Ignored, StartTake, TriggerSocket};
use tracing::{debug, info, warn};

use crate::clock::monotonic_ns;
use crate::config::TriggersConfig;
use crate::control_state::ControlContext;
use crate::error::DaemonError;
use crate::log_limit::{LogLimit, cut};
use crate::trigger_link::TriggerLink;

/// Longest wait on the socket: how soon the thread sees `stop`.
pub const TRIGGER_POLL: Duration = Duration::from_millis(100);

/// Most datagrams read per wake; the rest wait in the socket's buffer (the kernel drops what
/// does not fit, and a stage master sends a handful a take).
pub const MAX_DATAGRAMS_PER_WAKE: usize = 64;

/// The trigger sockets a configuration asks for, bound at start-up (so a port frond may not
/// bind fails the start, not a take): what status and the control threads share, and the
/// listening socket the thread will own.
pub struct BoundTriggers {
    /// Shared with the control context.
    pub link: Arc<TriggerLink>,
    /// The listening socket, if frond follows.
    socket: Option<TriggerSocket>,
    /// How it follows.
    follower: FollowerConfig,
    /// The rate of a master's `TimeCode` (`triggers.timecode_fps`, else `ltc.fps`).
    timecode_fps: Option<FrameRate>,
}

/// A running trigger thread.
pub struct TriggerThread {
    stop: Arc<AtomicBool>,
    handle: thread::JoinHandle<()>,
}

impl TriggerThread {
    /// Ends the thread (within [`TRIGGER_POLL`]) and waits for it.
    pub fn stop(self) {
        self.stop.store(true, Relaxed);
        if self.handle.join().is_err() {
            tracing::error!(thread = "frond-triggers", "thread panicked");
        }
    }
}

/// Binds `addr` for triggers, naming the address (and, for a privileged port, the fix) on error.
fn bind(addr: std::net::SocketAddr) -> Result<TriggerSocket, DaemonError> {
    TriggerSocket::bind(addr).map_err(|source| {
        let hint = if source.kind() == std::io::ErrorKind::PermissionDenied && addr.port() < 1024 {
            " (a port below 1024 needs root or CAP_NET_BIND_SERVICE: run frondd with \
             AmbientCapabilities=CAP_NET_BIND_SERVICE, or have the stage send to a port above 1023)"
        } else {
            ""
        };
        DaemonError::Triggers { addr, source, hint }
    })
}

/// Binds what `config` asks for: `None` when triggers are off. `ltc_fps` (`ltc.fps`) is the
/// rate of a master's `TimeCode` when `triggers.timecode_fps` does not say.
pub fn bind_triggers(
    config: &TriggersConfig,
    ltc_fps: Option<FrameRate>,
) -> Result<Option<BoundTriggers>, DaemonError> {
    if !config.enabled() {
        return Ok(None);
    }
    let socket = config.listen.map(bind).transpose()?;
    let listening = socket.as_ref().map(|s| s.local_addr()).transpose().map_err(DaemonError::Thread)?;
    let lead = match config.lead {
        None => None,
        Some(to) => {
            // Sent from the listening socket when there is one (the stage sees frond's port).
            let from = match &socket {
                Some(s) => s.socket().try_clone(),
                None => {
                    let any: std::net::SocketAddr = if to.is_ipv4() {
                        ([0, 0, 0, 0], 0).into()
                    } else {
                        (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                    };
                    bind(any)?.socket().try_clone()
                }
            };
            Some((from.map_err(DaemonError::Thread)?, to))
        }
    };
    let allow = config.allow.clone();
    let link = Arc::new(TriggerLink::new(listening, allow.as_deref().unwrap_or_default(), lead));
    if let Some(addr) = listening {
        info!(%addr, allow = ?allow, "following capture triggers");
    }
    if let Some(to) = config.lead {
        info!(%to, "leading capture triggers");
    }
    let follower = FollowerConfig { allow, honour_delay: config.honour_delay };
    Ok(Some(BoundTriggers { link, socket, follower, timecode_fps: config.timecode_fps.or(ltc_fps) }))
}

impl BoundTriggers {
    /// Starts the `frond-triggers` thread, if frond follows.
    pub fn start(self, ctx: &Arc<ControlContext>) -> Result<Option<TriggerThread>, DaemonError> {
        let Some(socket) = self.socket else { return Ok(None) };
        let stop = Arc::new(AtomicBool::new(false));
        let handle =
            spawn_triggers(socket, self.follower, self.timecode_fps, ctx.clone(), self.link, stop.clone())?;
        Ok(Some(TriggerThread { stop, handle }))
    }
}

/// Starts the trigger thread on `socket`, following `config`, until `stop`.
fn spawn_triggers(
    socket: TriggerSocket,
    config: FollowerConfig,
    timecode_fps: Option<FrameRate>,
    ctx: Arc<ControlContext>,
    link: Arc<TriggerLink>,
    stop: Arc<AtomicBool>,
) -> std::io::Result<thread::JoinHandle<()>> {
    thread::Builder::new().name("frond-triggers".into()).spawn(move || {
        let mut follower = TriggerFollower {
            follower: Follower::new(config),
            timecode_fps,
            ctx,
            link,
            counts: Counts::default(),
        };
        let mut socket = socket;
        while !stop.load(Relaxed) {
            follower.wait(&socket);
            follower.read(&mut socket);
            follower.due(monotonic_ns());
            follower.sync_with_daemon();
            follower.publish();
        }
    })
}

/// The follower and what it acts on.
struct TriggerFollower {
    follower: Follower,
    /// The rate a master's `TimeCode` is read at.
    timecode_fps: Option<FrameRate>,
    ctx: Arc<ControlContext>,
    link: Arc<TriggerLink>,
    counts: Counts,
}

/// What the thread counts beyond the follower's own counts: what frond did with its decisions.
#[derive(Debug, Default)]
struct Counts {
    /// Messages acted on: takes started, scheduled, stopped, cancelled.
    accepted: u64,
    /// Takes started.
    started: u64,
    /// Takes stopped.
    stopped: u64,
    /// Starts frond refused.
    start_refused: u64,
    /// Stops for a take frond had stopped already.
    stale_stops: u64,
    /// Starts heard while following was paused.
    paused_starts: u64,
}

impl TriggerFollower {
    /// Waits until a datagram arrives, a delayed start is due, or [`TRIGGER_POLL`] passes.
    fn wait(&self, socket: &TriggerSocket) {
        let now = monotonic_ns();
        let timeout = match self.follower.next_deadline() {
            Some(at) => Duration::from_nanos(at.saturating_sub(now)).min(TRIGGER_POLL),
            None => TRIGGER_POLL,
        };
        if !timeout.is_zero() {
            crate::clock::wait_readable(socket.socket().as_fd(), timeout);
        }
    }

    /// Reads and follows the datagrams waiting, at most [`MAX_DATAGRAMS_PER_WAKE`].
    fn read(&mut self, socket: &mut TriggerSocket) {
        static ERRORS: LogLimit = LogLimit::new();
        for _ in 0..MAX_DATAGRAMS_PER_WAKE {
            let received = match socket.recv() {
                Ok(Some(r)) => r,
                Ok(None) => return,
                Err(e) => {
                    ERRORS.log(
                        "capture-trigger log lines",
                        || warn!(error = %e, "reading the capture-trigger socket"),
                    );
                    return;
                }
            };
            if self.link.is_own(received.bytes) {
                continue;
            }
            let from = received.from.ip().to_canonical();
            let decision = self.follower.on_datagram(from, received.bytes, monotonic_ns());
            self.act(from, decision);
        }
    }

    /// Does what the follower decided about one datagram from `from`.
    fn act(&mut self, from: IpAddr, decision: Decision) {
        static REFUSED: LogLimit = LogLimit::new();
        static IGNORED: LogLimit = LogLimit::new();
        match decision {
            Decision::Start(take) => self.start(take),
            Decision::Scheduled { at_ns } => {
                let ms = at_ns.saturating_sub(monotonic_ns()) / 1_000_000;
                info!(%from, delay_ms = ms, "capture trigger: take starts after its delay");
                self.counts.accepted += 1;
            }
            Decision::Stop { name, result } => self.stop(&name, result),
            Decision::CancelScheduled => {
                info!(%from, "capture trigger: stop before the delayed start; nothing recorded");
                self.counts.accepted += 1;
            }
            Decision::Ignored(Ignored::Foreign) => {
                self.link.update(|s| s.last_refused = Some(format!("{from}: not in triggers.allow")));
                REFUSED.log(
                    "capture-trigger log lines",
                    || warn!(%from, "capture trigger from a host outside triggers.allow ignored"),
                );
            }
            Decision::Ignored(why @ (Ignored::NotRecording | Ignored::OtherTake)) => {
                IGNORED.log(
                    "capture-trigger log lines",
                    || info!(%from, ?why, "capture stop for a take frond is not recording"),
                );
            }
            Decision::Ignored(why) => debug!(%from, ?why, "capture trigger ignored"),
            Decision::Refused(e) => {
                let error = e.to_string();
                let text = cut(&error);
                self.link.update(|s| s.last_refused = Some(format!("{from}: {text}")));
                REFUSED.log(
                    "capture-trigger log lines",
                    || warn!(%from, error = %text, "capture trigger refused"),
                );
            }
        }
    }

    /// Starts `take` as `frond record start NAME` would, unless following is paused (then the
    /// start, immediate or delayed, is counted and dropped: the follower waits for the next).
    fn start(&mut self, take: StartTake) {
        static REFUSED: LogLimit = LogLimit::new();
        static PAUSED: LogLimit = LogLimit::new();
        if self.link.paused() {
            self.follower.take_ended();
            self.counts.paused_starts += 1;
            PAUSED.log(
                "capture-trigger log lines",
                || info!(take = %take.name, from = %take.sender, "capture start not followed: following is paused"),
            );
            return;
        }
        let anchor = self.master_anchor(&take);
        let reply = {
            let _session = self.ctx.recording_session();
            self.ctx.record_start_anchored(take.name.clone(), anchor)
        };
        match reply {
            ControlReply::Recording(_) => {
                info!(take = %take.name, from = %take.sender, "recording started by a capture trigger");
                self.counts.accepted += 1;
                self.counts.started += 1;
            }
            other => {
                // Already recording (frond's own take), a take of that name, the disk: say so.
                self.follower.take_ended();
                self.counts.start_refused += 1;
                REFUSED.log(
                    "capture-trigger log lines",
                    || warn!(take = %take.name, reply = ?other, "capture trigger's take not started"),
                );
            }
        }
    }

    /// The stage clock a start's `TimeCode` gives, taken to label the instant the take starts
    /// (the message's arrival plus its delay): used when no LTC is locked. `None` without a
    /// `TimeCode` (or `00:00:00:00`, "not used"), or when its rate is unknown (a whole-frame
    /// label with neither `triggers.timecode_fps` nor `ltc.fps`) or it is no label at that
    /// rate: said in the log, at most 10 times in 10 s.
    fn master_anchor(&self, take: &StartTake) -> Option<frond_motion::take::StageAnchor> {
        static UNUSED: LogLimit = LogLimit::new();
        let time = take.timecode?;
        let rate = if time.drop_frame { Some(FrameRate::Fps2997Df) } else { self.timecode_fps };
        let anchor = rate.and_then(|rate| crate::ltc_link::master_anchor(time, rate, take.start_at_ns));
        if anchor.is_none() {
            let why = match rate {
                None => "its rate is unknown: set triggers.timecode_fps".to_string(),
                Some(rate) => format!("it is no label at {rate} fps"),
            };
            UNUSED.log(
                "capture-trigger log lines",
                || info!(take = %take.name, timecode = %time, %why, "the capture start's TimeCode is not used"),
            );
        }
        anchor
    }

    /// Stops take `name` as `frond record stop` would, if it is the one recording.
    fn stop(&mut self, name: &str, result: frond_triggers::StopResult) {
        static NOT_OURS: LogLimit = LogLimit::new();
        let _session = self.ctx.recording_session();
        let recording_it = self.ctx.lock().recording.as_ref().is_some_and(|(n, _)| n == name);
        if !recording_it {
            self.counts.stale_stops += 1;
            NOT_OURS.log(
                "capture-trigger log lines",
                || info!(take = %name, "capture stop for a take frond is no longer recording"),
            );
            return;
        }
        match self.ctx.record_stop() {
            ControlReply::Recording(r) => {
                info!(take = %r.name, frames = r.frames, ?result, "recording stopped by a capture trigger");
                self.counts.accepted += 1;
                self.counts.stopped += 1;
            }
            other => warn!(take = %name, reply = ?other, "capture trigger's stop failed"),
        }
    }

    /// Starts a delayed take whose time has come.
    fn due(&mut self, now_ns: u64) {
        if let Some(take) = self.follower.poll(now_ns) {
            self.start(take);
        }
    }

    /// Forgets the follower's take once frond no longer records it (the operator stopped it),
    /// so the next `CaptureStart` is followed.
    fn sync_with_daemon(&mut self) {
        if let FollowerState::Recording { name } = self.follower.state() {
            let still = self.ctx.lock().recording.as_ref().is_some_and(|(n, _)| n == name);
            if !still {
                self.follower.take_ended();
            }
        }
    }

    /// Copies the follower's counts and last message to what status shows.
    fn publish(&self) {
        let c = self.follower.counters();
        if let Some(last) = self.follower.last_message() {
            self.link.set_last(last);
        }
        let scheduled = match self.follower.state() {
            FollowerState::Scheduled(take) => Some(take.name.clone()),
            _ => None,
        };
        let own = &self.counts;
        self.link.update(|s| {
            s.received = c.received;
            s.accepted = own.accepted;
            s.started = own.started;
            s.stopped = own.stopped;
            s.start_refused = own.start_refused;
            s.stops_without_take = c.not_recording + c.other_take + own.stale_stops;
            s.duplicates = c.duplicates;
            s.out_of_order = c.out_of_order;
            s.foreign = c.foreign;
            s.malformed = c.malformed;
            s.oversized = c.oversized;
            s.already_recording = c.already_recording;
            s.scheduled = scheduled;
            s.paused_starts = own.paused_starts;
        });
    }
}
