//! The control socket: status, rig/calibration/filter changes, recording, markers.
//!
//! Each connection gets a thread (bounded in number) that reads one request frame at a time,
//! with a read timeout, and answers with one reply frame. Every refusal is a typed
//! [`ControlError`] reply and a log line. Changes reach the realtime loop as [`LoopCommand`]s.

pub use crate::access::{AccessError, AccessPolicy, PeerCred, peer_cred};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::sync::atomic::Ordering::{AcqRel, Acquire, Relaxed};
use std::sync::atomic::{AtomicBool, AtomicUsize};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant, SystemTime};

use crossbeam_channel::{Sender, bounded};
use frond_device::SourceCounters;
use frond_motion::take::TakeHeader;
use frond_motion::{Calibration, FilterSpec, Rig};
use frond_protocol::{
    ControlError, ControlErrorKind, ControlReply, ControlRequest, DecodeError, ElementTable, FrameBuf,
    HandStatus, ReadError, RecordingStatus, SourceStatus, StatusReport, encode_frame_as,
    paths::validate_take_name, read_frame_limited, write_frame,
};
use tracing::{info, warn};

use crate::handoff::{ElementsCell, LoopCommand};
use crate::publisher::SubscriberRegistry;
use crate::recorder::{RecorderCounters, RecorderMsg};
use crate::stage::registry::StageRegistry;
use crate::stats::LoopStats;

/// Most control connections at once.
pub const MAX_CONTROL_CLIENTS: usize = 16;
/// Idle time between two requests after which a control connection is closed.
pub const CONTROL_READ_TIMEOUT: Duration = Duration::from_secs(30);
/// Time a whole request may take to arrive, from its first byte to its last: a client that
/// trickles a request (slow-loris) is answered `BadRequest` and cut off at this deadline, so it
/// holds a connection slot for at most this long past its first byte. A full 256 KiB request
/// over a local socket takes well under a millisecond.
pub const CONTROL_REQUEST_DEADLINE: Duration = Duration::from_secs(5);
/// Largest control request accepted, bytes.
pub use frond_protocol::MAX_CONTROL_REQUEST;
/// Device events kept for status.
pub const DEVICE_EVENTS_KEPT: usize = 32;

/// What the daemon is doing, as seen by control and status (not touched by the loop).
pub struct DaemonState {
    /// Active rig.
    pub rig: Rig,
    /// Active calibration.
    pub calibration: Calibration,
    /// Active filter.
    pub filter: FilterSpec,
    /// The hand sources, in configuration order (at least one).
    pub hands: Vec<HandState>,
    /// Device history of every hand, oldest first (prefixed by the hand's name when there are
    /// several).
    pub device_events: std::collections::VecDeque<String>,
    /// What is wrong now and needs the operator (a removed socket, ...), one line each.
    pub problems: Vec<String>,
    /// Current take: name and path.
    pub recording: Option<(String, PathBuf)>,
    /// Ticks per second over the last second.
    pub achieved_rate_hz: f64,
    /// Realtime tuning in force.
    pub realtime: String,
    /// The live stages the loop runs.
    pub stages: StageRegistry,
    /// Whether the layer being recorded started the playback it records over.
    pub layer_playback: bool,
    /// The element table last announced.
    pub elements: ElementTable,
}

/// A rig, calibration and filter to put in force together.
pub struct Setup {
    /// The rig.
    pub rig: Rig,
    /// The calibration.
    pub calibration: Calibration,
    /// The jitter filter.
    pub filter: FilterSpec,
}

/// One hand source, as control and status see it.
pub struct HandState {
    /// Its name.
    pub name: String,
    /// Source kind (`hidraw`, `fuse-hidraw`, `in-process`, `replay`, `osc`).
    pub kind: String,
    /// Source path or description.
    pub path: String,
    /// The source's counters.
    pub counters: Arc<SourceCounters>,
    /// Its device history, oldest first.
    pub events: std::collections::VecDeque<String>,
    /// The secondary element of its rig it drives (`None`: the global element).
    pub layer: Option<String>,
    /// The element id it is published as.
    pub element: u16,
    /// Its own rig, calibration and filter; `None` when it follows the daemon's.
    pub own: Option<Setup>,
}

impl HandState {
    /// The rig this hand is mapped by: its own, or the daemon's.
    pub fn rig<'a>(&'a self, state_rig: &'a Rig) -> &'a Rig {
        self.own.as_ref().map_or(state_rig, |s| &s.rig)
    }
}

impl DaemonState {
    /// Adds a device event of hand `hand` (timestamped) to its history and the daemon's.
    pub fn push_event(&mut self, started: Instant, hand: usize, text: String) {
        let line = format!("+{:.3}s {text}", started.elapsed().as_secs_f64());
        let several = self.hands.len() > 1;
        if let Some(h) = self.hands.get_mut(hand) {
            push_bounded(&mut h.events, line.clone());
            let line = if several { format!("{}: {line}", h.name) } else { line };
            push_bounded(&mut self.device_events, line);
        }
    }

    /// The hand stages act on ([`crate::engine::primary_hand`], the loop's rule).
    pub fn primary_hand(&self) -> usize {
        crate::engine::primary_hand(self.hands.iter().map(|h| h.element))
    }
}

fn push_bounded(events: &mut std::collections::VecDeque<String>, line: String) {
    if events.len() == DEVICE_EVENTS_KEPT {
        events.pop_front();
    }
    events.push_back(line);
}

/// Everything the control threads share.
pub struct ControlContext {
    /// Mutable daemon state.
    pub state: Mutex<DaemonState>,
    /// Loop counters.
    pub stats: Arc<LoopStats>,
    /// Subscribers.
    pub registry: Arc<SubscriberRegistry>,
    /// Recorder counters.
    pub recorder_counters: Arc<RecorderCounters>,
    /// Commands to the loop.
    pub commands: Sender<LoopCommand>,
    /// Messages to the recorder.
    pub recorder: Sender<RecorderMsg>,
    /// Daemon start.
    pub started: Instant,
    /// Where takes go.
    pub takes_dir: PathBuf,
    /// Nominal loop rate.
    pub tick_rate_hz: u32,
    /// Who may use the control socket.
    pub access: AccessPolicy,
    /// Whether testing aids (`FreezeLoop`) are enabled (`--test-hooks`).
    pub test_hooks: bool,
    /// The element table for the publisher's slow lane.
    pub elements_cell: Arc<ElementsCell>,
    /// Held across a whole `record start` / `record layer` / `record stop`, which take and drop
    /// the state lock several times: two clients' sessions cannot interleave (one's failed start
    /// undoing the other's layer, say).
    pub recording_session: Mutex<()>,
}

/// Longest marker label, bytes (`frond mark` and the console say the same).
const MAX_MARKER_LABEL_BYTES: usize = 256;

/// A marker label is stored in the take and printed by `frond take` tools and the console:
/// checked where it enters with the rule for every other name (calibration ids, rig names):
/// not blank, at most [`MAX_MARKER_LABEL_BYTES`], no control characters (issue 42: a line break
/// or an escape sequence would draw a fake line wherever the label is shown).
fn check_marker_label(label: &str) -> Result<(), BadMarkerLabel> {
    let mut problems = frond_motion::Problems::default();
    if problems.name("label", label, MAX_MARKER_LABEL_BYTES) { Ok(()) } else { Err(BadMarkerLabel(problems)) }
}

/// Why a marker label was refused: every problem [`check_marker_label`] found, each said as
/// `marker label: ...`, joined by `; `.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}", .0.0.iter().map(|p| format!("marker {p}")).collect::<Vec<_>>().join("; "))]
struct BadMarkerLabel(frond_motion::Problems);

pub(crate) fn refuse(kind: ControlErrorKind, message: impl Into<String>) -> ControlReply {
    static REFUSALS: crate::log_limit::LogLimit = crate::log_limit::LogLimit::new();
    let message = message.into();
    // A client decides how often and with what text this runs: rate-limited and cut.
    let verdict = REFUSALS.check(Instant::now());
    if verdict.held_back_before > 0 {
        warn!(count = verdict.held_back_before, "control refusals not logged (more than 10 in 10 s)");
    }
    if verdict.log {
        warn!(?kind, message = %crate::log_limit::cut(&message), "control request refused");
    }
    ControlReply::Error(ControlError { kind, message })
}

impl ControlContext {
    pub(crate) fn lock(&self) -> std::sync::MutexGuard<'_, DaemonState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub(crate) fn send_loop(&self, cmd: LoopCommand) -> Result<(), Box<ControlReply>> {
        self.commands.send_timeout(cmd, Duration::from_millis(500)).map_err(|_| {
            Box::new(refuse(ControlErrorKind::Internal, "the realtime loop is not accepting commands"))
        })
    }

    /// Answers one request; a panic while handling it (a bug) is caught, logged and answered
    /// `Internal`, so no panic reaches a client or ends its connection thread unanswered.
    pub fn handle_catching(&self, req: ControlRequest) -> ControlReply {
        // The state lock recovers from poisoning (`lock`), and nothing else a request touches
        // is left half-changed in a way a later request could trip over: unwind safety holds.
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| self.handle(req))) {
            Ok(reply) => reply,
            Err(payload) => {
                let what = payload
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "a panic".to_string());
                tracing::error!(panic = %what, "a control request panicked (a bug); answered Internal");
                refuse(
                    ControlErrorKind::Internal,
                    format!("internal error while handling the request (a bug; frondd logged it): {what}"),
                )
            }
        }
    }

    fn recording_session(&self) -> std::sync::MutexGuard<'_, ()> {
        self.recording_session.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Answers one request.
    pub fn handle(&self, req: ControlRequest) -> ControlReply {
        match req {
            ControlRequest::Status => ControlReply::Status(Box::new(self.status())),
            ControlRequest::SetRig { name, toml } => self.set_rig(name, &toml),
            ControlRequest::SetCalibration { id, toml } => self.set_calibration(id, &toml),
            ControlRequest::SetFilter { spec } => self.set_filter(&spec),
            ControlRequest::RecordStart { name } => {
                let _session = self.recording_session();
                self.record_start(name)
            }
            ControlRequest::RecordStop => {
                let _session = self.recording_session();
                self.record_stop()
            }
            ControlRequest::Mark { label } => self.mark(label),
            ControlRequest::RecordLayer { name, layer, global_take, seed } => {
                let _session = self.recording_session();
                self.record_layer(name, layer, global_take, seed)
            }
            ControlRequest::StageStart { name, spec } => self.stage_start(name, spec),
            ControlRequest::StageStop { name } => self.stage_stop(&name),
            ControlRequest::StageInput { name, input } => self.stage_input(&name, input),
            ControlRequest::FreezeLoop { ms } => {
                if !self.test_hooks {
                    return refuse(
                        ControlErrorKind::PermissionDenied,
                        "FreezeLoop needs frondd --test-hooks",
                    );
                }
                warn!(ms, "freezing the realtime loop on request (test hook)");
                match self.send_loop(LoopCommand::Freeze(ms.min(60_000))) {
                    Ok(()) => ControlReply::Ok,
                    Err(reply) => *reply,
                }
            }
            ControlRequest::PanicForTest => {
                if !self.test_hooks {
                    return refuse(
                        ControlErrorKind::PermissionDenied,
                        "PanicForTest needs frondd --test-hooks",
                    );
                }
                warn!("panicking a control thread on request (test hook)");
                panic!("PanicForTest: a control thread panics on request (test hook)");
            }
            // `frond calibrate` calibrates the primary hand (the one on the global element).
            ControlRequest::RawSample => match self.stats.hands[self.lock().primary_hand()].raw.load() {
                Some((t, wrist_deg, thumb_deg, fresh)) => {
                    ControlReply::RawSample { t, wrist_deg, thumb_deg, fresh }
                }
                None => {
                    ControlReply::RawSample { t: 0.0, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3], fresh: false }
                }
            },
        }
    }

    fn set_rig(&self, name: String, text: &str) -> ControlReply {
        let mut rig = match Rig::from_toml_str(text) {
            Ok(rig) => rig,
            Err(e) => return refuse(ControlErrorKind::Invalid, format!("rig {name:?}: {e}")),
        };
        if rig.name.is_empty() {
            rig.name = name;
        }
        let mut state = self.lock();
        // Without a user calibration the thumb ranges come from the rig.
        let calibration = if state.calibration.id == "none" {
            Calibration::neutral_for(&rig)
        } else {
            state.calibration.clone()
        };
        let rig_name = rig.name.clone();
        let filter = state.filter;
        match self.apply_setup(&mut state, Setup { rig, calibration, filter }, true) {
            Ok(()) => {
                info!(rig = %rig_name, "rig applied");
                ControlReply::Ok
            }
            Err(reply) => reply,
        }
    }

    fn set_calibration(&self, id: String, text: &str) -> ControlReply {
        let mut cal = match Calibration::from_toml_str(text) {
            Ok(c) => c,
            Err(e) => return refuse(ControlErrorKind::Invalid, format!("calibration {id:?}: {e}")),
        };
        if cal.id.is_empty() {
            cal.id = id;
        }
        let mut state = self.lock();
        let (rig, filter, cal_id) = (state.rig.clone(), state.filter, cal.id.clone());
        match self.apply_setup(&mut state, Setup { rig, calibration: cal, filter }, false) {
            Ok(()) => {
                info!(calibration = %cal_id, "calibration applied");
                ControlReply::Ok
            }
            Err(reply) => reply,
        }
    }

    fn set_filter(&self, spec: &str) -> ControlReply {
        let filter: FilterSpec = match spec.parse() {
            Ok(f) => f,
            Err(e) => return refuse(ControlErrorKind::Invalid, format!("filter {spec:?}: {e}")),
        };
        let mut state = self.lock();
        let (rig, calibration) = (state.rig.clone(), state.calibration.clone());
        match self.apply_setup(&mut state, Setup { rig, calibration, filter }, false) {
            Ok(()) => {
                info!(%filter, "filter applied");
                ControlReply::Ok
            }
            Err(reply) => reply,
        }
    }

    /// Starts a take (the hand's frames are recorded as the element they are published as).
    pub(crate) fn record_start(&self, name: String) -> ControlReply {
        if let Err(e) = validate_take_name(&name) {
            return refuse(ControlErrorKind::BadName, e.to_string());
        }
        let mut state = self.lock();
        if let Some((current, _)) = &state.recording {
            return refuse(ControlErrorKind::WrongState, format!("already recording take {current:?}"));
        }
        if let Err(e) = std::fs::create_dir_all(&self.takes_dir) {
            return refuse(
                ControlErrorKind::Internal,
                format!("cannot create the takes directory {}: {e}", self.takes_dir.display()),
            );
        }
        let path = self.takes_dir.join(format!("{name}.take"));
        if path.exists() {
            return refuse(
                ControlErrorKind::WrongState,
                format!("take {name:?} already exists at {}; choose another name", path.display()),
            );
        }
        let header = TakeHeader {
            name: name.clone(),
            rig_name: state.rig.name.clone(),
            calibration_id: state.calibration.id.clone(),
            filter: state.filter.to_string(),
            tick_rate_hz: self.tick_rate_hz,
            created_unix_s: SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0),
            daemon_version: env!("CARGO_PKG_VERSION").to_string(),
            joint_names: state.rig.joints.iter().map(|j| j.name.clone()).collect(),
            // Both clocks read back to back: frames' host times get wall times (timecode).
            clock: Some(frond_motion::take::TakeClock {
                unix_ns: SystemTime::now()
                    .duration_since(SystemTime::UNIX_EPOCH)
                    .map(|d| d.as_nanos() as u64)
                    .unwrap_or(0),
                host_ns: crate::clock::monotonic_ns(),
            }),
            stage: None,
        };
        let elements: Vec<String> = state.rig.elements.iter().map(|e| e.name.clone()).collect();
        let (tx, rx) = bounded(1);
        let start = RecorderMsg::Start { path: path.clone(), header: Box::new(header), elements, reply: tx };
        if self.recorder.send_timeout(start, Duration::from_secs(1)).is_err() {
            return refuse(ControlErrorKind::Internal, "the recorder is not accepting requests");
        }
        match rx.recv_timeout(Duration::from_secs(5)) {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return refuse(ControlErrorKind::Internal, e.to_string()),
            Err(_) => return refuse(ControlErrorKind::Internal, "the recorder did not answer"),
        }
        if let Err(reply) = self.send_loop(LoopCommand::SetRecording(true)) {
            return *reply;
        }
        info!(take = %name, path = %path.display(), "recording started");
        state.recording = Some((name.clone(), path.clone()));
        ControlReply::Recording(RecordingStatus {
            name,
            path: path.display().to_string(),
            frames: 0,
            dropped: 0,
            active: true,
        })
    }

    fn record_stop(&self) -> ControlReply {
        let reply = self.record_stop_take();
        self.end_layer();
        reply
    }

    fn record_stop_take(&self) -> ControlReply {
        let mut state = self.lock();
        let Some((name, path)) = state.recording.clone() else {
            return refuse(ControlErrorKind::WrongState, "no take is being recorded");
        };
        if let Err(reply) = self.send_loop(LoopCommand::SetRecording(false)) {
            return *reply;
        }
        // Wait until the loop has stopped forwarding frames, so that every frame it sent is
        // queued before the Stop message and lands in the take.
        let deadline = Instant::now() + Duration::from_secs(2);
        while self.stats.recording.load(std::sync::atomic::Ordering::Acquire) && Instant::now() < deadline {
            thread::sleep(Duration::from_millis(1));
        }
        let (tx, rx) = bounded(1);
        if self.recorder.send_timeout(RecorderMsg::Stop { reply: tx }, Duration::from_secs(1)).is_err() {
            return refuse(ControlErrorKind::Internal, "the recorder is not accepting requests");
        }
        let frames = match rx.recv_timeout(Duration::from_secs(10)) {
            Ok(Ok(frames)) => frames,
            Ok(Err(e)) => {
                // The recorder has let the take go (closed, or left for `take repair`): so must we.
                state.recording = None;
                return refuse(ControlErrorKind::Internal, e.to_string());
            }
            Err(_) => return refuse(ControlErrorKind::Internal, "the recorder did not finish the take"),
        };
        state.recording = None;
        let dropped = self.stats.record_drops.load(Relaxed);
        info!(take = %name, frames, dropped, "recording stopped");
        ControlReply::Recording(RecordingStatus {
            name,
            path: path.display().to_string(),
            frames,
            dropped,
            active: false,
        })
    }

    fn mark(&self, label: String) -> ControlReply {
        if let Err(why) = check_marker_label(&label) {
            return refuse(ControlErrorKind::BadRequest, why.to_string());
        }
        if self.lock().recording.is_none() {
            return refuse(ControlErrorKind::WrongState, "no take is being recorded");
        }
        let seq = self.stats.next_seq.load(Relaxed);
        match self.recorder.send_timeout(RecorderMsg::Mark { seq, label }, Duration::from_secs(1)) {
            Ok(()) => ControlReply::Ok,
            Err(_) => refuse(ControlErrorKind::Internal, "the recorder is not accepting requests"),
        }
    }

    /// Builds a status report.
    pub fn status(&self) -> StatusReport {
        let state = self.lock();
        let s = &self.stats;
        let hands: Vec<HandStatus> = state
            .hands
            .iter()
            .enumerate()
            .map(|(i, h)| {
                let counters = h.counters.snapshot();
                let hs = &s.hands[i];
                let rig = h.rig(&state.rig);
                let calibration = h.own.as_ref().map_or(&state.calibration, |o| &o.calibration);
                HandStatus {
                    name: h.name.clone(),
                    source: SourceStatus {
                        kind: h.kind.clone(),
                        path: h.path.clone(),
                        connected: hs.connected.load(Relaxed),
                        reports: counters.reports,
                        rejected: counters.rejected(),
                        device_seq_gaps: counters.seq_gaps,
                        rejected_by_reason: counters
                            .by_reason()
                            .into_iter()
                            .filter(|&(_, n)| n > 0)
                            .map(|(reason, n)| (reason.to_string(), n))
                            .collect(),
                        peers_dropped: counters.peers_dropped,
                    },
                    element: h.element,
                    element_name: h.layer.clone().unwrap_or_else(|| rig.name.clone()),
                    rig_name: rig.name.clone(),
                    calibration_id: calibration.id.clone(),
                    frames: hs.frames.load(Relaxed),
                    held_frames: hs.held_frames.load(Relaxed),
                    stalls: hs.stall_events.load(Relaxed),
                    lost_events: hs.lost_events.load(Relaxed),
                    discontinuities: hs.discontinuities.load(Relaxed),
                    stale_skipped: hs.stale_skipped.load(Relaxed),
                    events: h.events.iter().cloned().collect(),
                }
            })
            .collect();
        StatusReport {
            daemon_version: env!("CARGO_PKG_VERSION").to_string(),
            uptime_s: self.started.elapsed().as_secs_f64(),
            source: hands[0].source.clone(),
            rig_name: state.rig.name.clone(),
            calibration_id: state.calibration.id.clone(),
            filter: state.filter.to_string(),
            tick_rate_hz: self.tick_rate_hz,
            achieved_rate_hz: state.achieved_rate_hz,
            ticks: s.ticks.load(Relaxed),
            held_ticks: s.held_ticks.load(Relaxed),
            device_wakes: s.device_wakes.load(Relaxed),
            publish_drops: s.publish_drops.load(Relaxed),
            lateness: s.lateness.summary(),
            subscribers: self.registry.snapshot(),
            recording: state.recording.as_ref().map(|(name, path)| RecordingStatus {
                name: name.clone(),
                path: path.display().to_string(),
                frames: self.recorder_counters.frames.load(Relaxed),
                dropped: s.record_drops.load(Relaxed),
                active: true,
            }),
            device_events: state.device_events.iter().cloned().collect(),
            realtime: state.realtime.clone(),
            modes: self.modes(&state),
            stages: state.stages.status(),
            elements: state.elements.elements.clone(),
            hands,
            problems: state.problems.clone(),
            recorder_error: self.recorder_counters.fault(),
            lateness_histogram: s.lateness.log2_buckets_us(),
        }
    }
}

/// Accepts control connections until `stop` is set.
pub fn spawn_control(
    listener: UnixListener,
    ctx: Arc<ControlContext>,
    stop: Arc<AtomicBool>,
) -> std::io::Result<thread::JoinHandle<()>> {
    listener.set_nonblocking(true)?;
    thread::Builder::new().name("frond-control".into()).spawn(move || {
        let clients = Arc::new(AtomicUsize::new(0));
        while !stop.load(Relaxed) {
            let stream = match listener.accept() {
                Ok((s, _)) => s,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    // Woken by a connection (at shutdown the daemon makes one), or every
                    // `STOP_POLL` to look at `stop`.
                    crate::clock::wait_readable(
                        std::os::fd::AsFd::as_fd(&listener),
                        crate::publisher::STOP_POLL,
                    );
                    continue;
                }
                Err(e) => {
                    warn!(error = %e, "accepting a control connection failed");
                    thread::sleep(Duration::from_millis(100));
                    continue;
                }
            };
            let Some(slot) = ClientSlot::take(&clients) else {
                let mut stream = stream;
                let _ = write_frame(
                    &mut stream,
                    &mut FrameBuf::default(),
                    &refuse(ControlErrorKind::Internal, "too many control connections; try again"),
                );
                drain_queued(&mut stream);
                continue;
            };
            let ctx = ctx.clone();
            // The slot moves into the thread and is given back when it is dropped: when the
            // connection ends, when the thread unwinds, or here if the thread never starts.
            let spawned = thread::Builder::new().name("frond-control-conn".into()).spawn(move || {
                let _slot = slot;
                serve_connection(stream, &ctx);
            });
            if let Err(e) = spawned {
                warn!(error = %e, "could not start a control connection thread");
            }
        }
    })
}

/// One of the [`MAX_CONTROL_CLIENTS`] connection slots, held by a connection's thread and given
/// back when dropped, however the thread ends (return, panic, or never started).
#[derive(Debug)]
pub struct ClientSlot(Arc<AtomicUsize>);

impl ClientSlot {
    /// A slot of `clients` (the count of slots held), or `None` when all are taken.
    pub fn take(clients: &Arc<AtomicUsize>) -> Option<ClientSlot> {
        clients
            .fetch_update(AcqRel, Acquire, |n| (n < MAX_CONTROL_CLIENTS).then_some(n + 1))
            .ok()
            .map(|_| ClientSlot(clients.clone()))
    }
}

impl Drop for ClientSlot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, AcqRel);
    }
}

/// Reads one request at a time from a control connection with two limits: at most
/// [`CONTROL_READ_TIMEOUT`] idle before a request's first byte, and the whole request within
/// [`CONTROL_REQUEST_DEADLINE`] of that byte (the socket's read timeout is set to what is left
/// before each read, so a client that sends a byte now and then cannot stretch it).
struct RequestReader<'a> {
    stream: &'a UnixStream,
    /// Deadline of the request being read; `None` until its first byte.
    deadline: Option<Instant>,
    /// Set when a read failed because the deadline passed.
    expired: bool,
}

impl RequestReader<'_> {
    /// Ready for the next request (idle timeout again).
    fn next_request(&mut self) {
        self.deadline = None;
        self.expired = false;
    }
}

impl std::io::Read for RequestReader<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let timeout = match self.deadline {
            None => CONTROL_READ_TIMEOUT,
            Some(deadline) => {
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    self.expired = true;
                    return Err(std::io::ErrorKind::TimedOut.into());
                }
                left
            }
        };
        self.stream.set_read_timeout(Some(timeout))?;
        let result = (&mut &*self.stream).read(buf);
        match &result {
            Ok(n) if *n > 0 && self.deadline.is_none() => {
                self.deadline = Some(Instant::now() + CONTROL_REQUEST_DEADLINE);
            }
            Err(e)
                if self.deadline.is_some()
                    && matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
            {
                self.expired = true;
            }
            _ => {}
        }
        result
    }
}

/// Reads and drops what a client already sent, without waiting (the stream is non-blocking,
/// as accepted): closing a Unix socket with unread bytes resets it, and the client would lose
/// the reply just written. What arrives later may still reset it; the acceptor must not wait.
fn drain_queued(stream: &mut UnixStream) {
    use std::io::Read;
    let _ = stream.set_nonblocking(true);
    let mut buf = [0u8; 4096];
    let mut drained = 0;
    while drained <= MAX_CONTROL_REQUEST {
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => drained += n,
        }
    }
}

/// Closes a connection whose request was refused unread: the reply is written, then what the
/// client still sends is read and dropped (at most a request's worth, for at most a second), so
/// that closing with unread bytes does not reset the connection and lose the reply.
fn close_after_refusal(mut stream: UnixStream) {
    use std::io::Read;
    let _ = stream.shutdown(std::net::Shutdown::Write);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
    let deadline = Instant::now() + Duration::from_secs(1);
    let mut buf = [0u8; 4096];
    let mut drained = 0;
    while drained <= MAX_CONTROL_REQUEST && Instant::now() < deadline {
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => drained += n,
        }
    }
}

fn serve_connection(mut stream: UnixStream, ctx: &ControlContext) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_write_timeout(Some(Duration::from_secs(5)));
    let mut scratch = Vec::new();
    let mut out = FrameBuf::default();
    let allowed = peer_cred(&stream).map_err(AccessError::Credentials);
    if let Err(why) = allowed.and_then(|peer| ctx.access.check(&peer)) {
        let _ =
            write_frame(&mut stream, &mut out, &refuse(ControlErrorKind::PermissionDenied, why.to_string()));
        return;
    }
    let reader_stream = stream.try_clone();
    let Ok(reader_stream) = reader_stream else { return };
    let mut reader = RequestReader { stream: &reader_stream, deadline: None, expired: false };
    loop {
        reader.next_request();
        let reply = match read_frame_limited::<ControlRequest, _>(
            &mut reader,
            &mut scratch,
            MAX_CONTROL_REQUEST,
        ) {
            Ok(req) => ctx.handle_catching(req),
            Err(ReadError::Closed) => return,
            Err(ReadError::Io(_)) if reader.expired => {
                let reply = refuse(
                    ControlErrorKind::BadRequest,
                    format!(
                        "the request did not arrive within {} s of its first byte; closing the connection",
                        CONTROL_REQUEST_DEADLINE.as_secs()
                    ),
                );
                let _ = write_frame(&mut stream, &mut out, &reply);
                return;
            }
            Err(ReadError::Io(e))
                if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
            {
                return;
            }
            Err(ReadError::Decode(DecodeError::UnsupportedVersion { got, supported })) => {
                // An older (or newer) client: answer in its own version, which every frond
                // version can read for an `Error` reply, so it says what is wrong.
                let reply = refuse(
                    ControlErrorKind::BadRequest,
                    format!(
                        "this daemon speaks frond protocol version {supported}, the client version {got}; \
                             use a frond, frondd and exporters of the same release"
                    ),
                );
                let mut bytes = Vec::new();
                encode_frame_as(got, &reply, &mut bytes);
                let _ = std::io::Write::write_all(&mut stream, &bytes);
                close_after_refusal(stream);
                return;
            }
            Err(e) => {
                let reply = refuse(ControlErrorKind::BadRequest, format!("bad control request: {e}"));
                let _ = write_frame(&mut stream, &mut out, &reply);
                close_after_refusal(stream);
                return;
            }
        };
        if write_frame(&mut stream, &mut out, &reply).is_err() {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 42: `frond mark "$(printf 'x\n\033[31mFAKE')"` was stored as is; a marker label
    /// now follows the calibration id's rule (printable, not blank, bounded).
    #[test]
    fn a_marker_label_is_printable_and_bounded() {
        let e = check_marker_label("x\n\u{1b}[31mFAKE").unwrap_err().to_string();
        assert_eq!(e, "marker label: contains the control character '\\n'; a name must be printable");
        let e = check_marker_label("a\u{1b}[2Kb").unwrap_err().to_string();
        assert_eq!(e, "marker label: contains the control character '\\u{1b}'; a name must be printable");
        let e = check_marker_label(&"x".repeat(257)).unwrap_err().to_string();
        assert_eq!(e, "marker label: is 257 bytes; the limit is 256");
        assert_eq!(check_marker_label("  ").unwrap_err().to_string(), "marker label: must not be empty");
        assert_eq!(
            check_marker_label("").map_err(|e| e.to_string()),
            Err("marker label: must not be empty".into())
        );
        assert_eq!(check_marker_label(&"x".repeat(256)), Ok(()));
        assert_eq!(check_marker_label("pétale 2 — take 3"), Ok(()));
    }
}
