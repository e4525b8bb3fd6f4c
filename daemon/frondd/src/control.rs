//! The control socket: status, rig/calibration/filter changes, recording, markers.
//!
//! Each connection gets a thread (bounded in number, `control_conn`)
//! that reads one request frame at a time, with a read timeout, and answers with one reply
//! frame; this module answers the requests (the live stages' in `control_stage`). Every refusal
//! is a typed [`ControlError`](frond_protocol::ControlError) reply and a log line (`refuse`).
//! Changes reach the realtime loop as [`LoopCommand`]s.

pub use crate::access::{AccessError, AccessPolicy, PeerCred, peer_cred};
pub use crate::control_conn::{
    CONTROL_READ_TIMEOUT, CONTROL_REQUEST_DEADLINE, ClientSlot, MAX_CONTROL_CLIENTS, MAX_CONTROL_REQUEST,
    spawn_control,
};
pub use crate::control_state::{ControlContext, DEVICE_EVENTS_KEPT, DaemonState, HandState, Setup};

use std::sync::atomic::Ordering::Relaxed;
use std::thread;
use std::time::{Duration, Instant, SystemTime};

use crossbeam_channel::bounded;
use frond_formats::rig_toml::{CalibrationText, RigText};
use frond_motion::take::{StageAnchor, TakeHeader};
use frond_motion::{Calibration, FilterSpec, Rig};
use frond_protocol::{
    ControlErrorKind, ControlReply, ControlRequest, HandStatus, RecordingStatus, SourceStatus, StatusReport,
    paths::validate_take_name,
};
use tracing::{info, warn};

use crate::control_state::refuse;
use crate::handoff::LoopCommand;
use crate::recorder::RecorderMsg;

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

impl ControlContext {
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

    /// Answers one request.
    pub fn handle(&self, req: ControlRequest) -> ControlReply {
        match req {
            ControlRequest::Status => ControlReply::Status(Box::new(self.status())),
            ControlRequest::SetRig { name, toml } => self.set_rig(name, &toml),
            ControlRequest::SetCalibration { id, toml } => self.set_calibration(id, &toml),
            ControlRequest::SetFilter { spec } => self.set_filter(&spec),
            ControlRequest::RecordStart { name } => {
                let _session = self.recording_session();
                let reply = self.record_start(name);
                // frond's own take (not a trigger's: those call `record_start` directly) leads.
                if let (ControlReply::Recording(r), Some(triggers)) = (&reply, &self.triggers) {
                    triggers.lead_start(&r.name);
                }
                reply
            }
            ControlRequest::RecordStop => {
                let _session = self.recording_session();
                let reply = self.record_stop();
                if let (ControlReply::Recording(r), Some(triggers)) = (&reply, &self.triggers) {
                    triggers.lead_stop(&r.name);
                }
                reply
            }
            ControlRequest::Mark { label } => self.mark(label),
            ControlRequest::RecordLayer { name, layer, global_take, seed } => {
                let _session = self.recording_session();
                self.record_layer(name, layer, global_take, seed)
            }
            ControlRequest::StageStart { name, spec } => self.stage_start(name, spec),
            ControlRequest::StageStop { name } => self.stage_stop(&name),
            ControlRequest::StageInput { name, input } => self.stage_input(&name, input),
            ControlRequest::SetTriggers { follow } => self.set_triggers(follow),
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

    /// Follows a mocap stage's capture triggers again, or pauses following (issue 46: on and
    /// off from the CLI and the console, not only at start-up). Refused when frondd listens for
    /// none: there is nothing to follow, and binding a port is a start-up decision.
    fn set_triggers(&self, follow: bool) -> ControlReply {
        match &self.triggers {
            Some(link) if link.listens() => {
                link.set_following(follow);
                ControlReply::Ok
            }
            _ => refuse(
                ControlErrorKind::WrongState,
                "frondd listens for no capture triggers: start it with --triggers ADDR:PORT (or \
                 listen in its [triggers] table) to follow a stage",
            ),
        }
    }

    /// Starts a take (the hand's frames are recorded as the element they are published as).
    pub(crate) fn record_start(&self, name: String) -> ControlReply {
        self.record_start_anchored(name, None)
    }

    /// [`Self::record_start`], with `fallback` as the take's stage clock when no LTC is locked
    /// (a trigger's `TimeCode`, issue 46): a locked LTC input is the stage's clock itself and
    /// wins; the master's label, read once as the message arrived, stands in for it.
    pub(crate) fn record_start_anchored(&self, name: String, fallback: Option<StageAnchor>) -> ControlReply {
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
        // Both clocks read back to back: frames' host times get wall times (timecode); with a
        // locked LTC input, the stage's timecode at the same instant anchors the take.
        let unix_ns = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map(|d| d.as_nanos() as u64)
            .unwrap_or(0);
        let host_ns = crate::clock::monotonic_ns();
        let stage_clock = self.ltc.as_ref().and_then(|l| l.anchor(host_ns)).or(fallback);
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
            clock: Some(frond_motion::take::TakeClock { unix_ns, host_ns }),
            stage: None,
            stage_clock,
        };
        let stage_label = header.stage_clock.as_ref().map(|a| a.label.clone());
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
        info!(take = %name, path = %path.display(), stage_timecode = ?stage_label, "recording started");
        state.recording = Some((name.clone(), path.clone()));
        ControlReply::Recording(RecordingStatus {
            name,
            path: path.display().to_string(),
            frames: 0,
            dropped: 0,
            active: true,
        })
    }

    /// Stops the take recording (and ends the layer it records, if any).
    pub(crate) fn record_stop(&self) -> ControlReply {
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
                        camera: h.counters.camera.status(),
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
            triggers: self.triggers.as_ref().map(|t| t.status(crate::clock::monotonic_ns())),
            ltc: self.ltc.as_ref().map(|l| l.status(crate::clock::monotonic_ns())),
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
