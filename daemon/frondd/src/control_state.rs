//! What the control side shares: the daemon's state as control and status see it
//! ([`DaemonState`], its hands and the setup in force), the context every control thread holds
//! ([`ControlContext`]) and the one way a request is refused ([`refuse`]). The requests
//! themselves are answered in `control` and `control_stage`, the connections served in
//! `control_conn`; all of them use this module, which uses none of them.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crossbeam_channel::Sender;
use frond_device::SourceCounters;
use frond_motion::{Calibration, FilterSpec, Rig};
use frond_protocol::{ControlError, ControlErrorKind, ControlReply, ElementId, ElementTable};
use tracing::warn;

use crate::access::AccessPolicy;
use crate::handoff::{ElementsCell, LoopCommand};
use crate::publisher::SubscriberRegistry;
use crate::recorder::{RecorderCounters, RecorderMsg};
use crate::stage::registry::StageRegistry;
use crate::stats::LoopStats;

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
    pub element: ElementId,
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
    /// A mocap stage's capture triggers, when configured: status reads them, and frond's own
    /// `record start` / `record stop` lead through them.
    pub triggers: Option<Arc<crate::trigger_link::TriggerLink>>,
    /// The stage's timecode from LTC, when an input is configured: status reads it, and a
    /// take's start anchors the take to it.
    pub ltc: Option<Arc<crate::ltc_link::LtcLink>>,
}

/// A refusal of a request: a typed [`ControlError`] reply, and a log line (rate-limited, cut).
pub(crate) fn refuse(kind: ControlErrorKind, message: impl Into<String>) -> ControlReply {
    static REFUSALS: crate::log_limit::LogLimit = crate::log_limit::LogLimit::new();
    let message = message.into();
    // A client decides how often and with what text this runs: rate-limited and cut.
    REFUSALS.log(
        "control refusals",
        || warn!(?kind, message = %crate::log_limit::cut(&message), "control request refused"),
    );
    ControlReply::Error(ControlError { kind, message })
}

impl ControlContext {
    /// The daemon's state, locked; a lock poisoned by a panicking request is taken as it is.
    pub(crate) fn lock(&self) -> std::sync::MutexGuard<'_, DaemonState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Sends `cmd` to the realtime loop, refusing the request if the loop does not take it
    /// within 500 ms.
    pub(crate) fn send_loop(&self, cmd: LoopCommand) -> Result<(), Box<ControlReply>> {
        self.commands.send_timeout(cmd, Duration::from_millis(500)).map_err(|_| {
            Box::new(refuse(ControlErrorKind::Internal, "the realtime loop is not accepting commands"))
        })
    }

    /// The recording session's lock (the field `recording_session`), poisoned or not.
    pub(crate) fn recording_session(&self) -> std::sync::MutexGuard<'_, ()> {
        self.recording_session.lock().unwrap_or_else(|e| e.into_inner())
    }
}
