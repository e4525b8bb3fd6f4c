//! `frond-gltf live`: collect poses from the running daemon while it records, then bake them.
//!
//! [`LiveCapture`] is the pure part: it takes poses in order and decides when the capture is
//! complete (the `recording` flag went from set to clear). [`capture`] drives it from a
//! `frond_sdk::Subscriber`, polling a stop flag (Ctrl-C) between reads; on a stop it first drains
//! the poses already waiting in the socket, so the last frames before the signal are kept.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use frond_motion::{TakeFrame, TakeHeader};
use frond_protocol::{Hello, Pose, PoseFlags};
use frond_recorder::take_frame;
use frond_sdk::{Event, SdkError, Source, Subscriber};
use thiserror::Error;

use crate::input::TakeInput;

/// Which poses a live capture keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LiveMode {
    /// Poses flagged `recording`; complete when recording stops.
    Recording,
    /// Every pose from the start; complete only on a stop request.
    All,
}

/// Why a live capture ended or failed.
#[derive(Debug, Error)]
pub enum LiveError {
    /// The daemon could not be reached, or the stream failed before anything was captured.
    #[error(transparent)]
    Sdk(#[from] SdkError),
    /// Stopped (Ctrl-C, or the daemon went away) before any pose was captured.
    #[error("nothing was captured: {0}")]
    Nothing(String),
    /// `--field NAME` names none of the running fields.
    #[error("no running field is named `{name}`; running: {running} (pick one with --field NAME)")]
    NoSuchField {
        /// The name asked for.
        name: String,
        /// The running fields' names, comma-separated.
        running: String,
    },
    /// Several fields run and `--field` named none.
    #[error("{count} fields are running ({running}): pick one with --field NAME")]
    WhichField {
        /// How many.
        count: usize,
        /// Their names, comma-separated.
        running: String,
    },
    /// The field cannot be baked as asked (its rig).
    #[error("{0}")]
    Refused(String),
}

/// The poses of one live capture.
#[derive(Debug, Clone)]
pub struct LiveCapture {
    mode: LiveMode,
    frames: Vec<TakeFrame>,
    recording_seen: bool,
    complete: bool,
    /// Frames the daemon dropped for this subscriber during the capture.
    pub missing: u64,
}

impl LiveCapture {
    /// An empty capture.
    pub fn new(mode: LiveMode) -> Self {
        LiveCapture { mode, frames: Vec::new(), recording_seen: false, complete: false, missing: 0 }
    }

    /// Takes one pose; returns true once the capture is complete (recording stopped). Poses
    /// after that are ignored.
    pub fn push(&mut self, pose: &Pose) -> bool {
        if self.complete {
            return true;
        }
        let recording = pose.flags.contains(PoseFlags::RECORDING);
        match self.mode {
            LiveMode::All => self.frames.push(take_frame(pose)),
            LiveMode::Recording if recording => {
                self.recording_seen = true;
                self.frames.push(take_frame(pose));
            }
            LiveMode::Recording if self.recording_seen => self.complete = true,
            LiveMode::Recording => {}
        }
        self.complete
    }

    /// Notes `n` frames dropped by the daemon (counted only while capturing).
    pub fn gap(&mut self, n: u64) {
        if self.mode == LiveMode::All || self.recording_seen {
            self.missing += n;
        }
    }

    /// True once recording has started (or always, in [`LiveMode::All`], after a pose).
    pub fn capturing(&self) -> bool {
        !self.frames.is_empty()
    }

    /// Frames captured so far.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True when nothing was captured.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The capture as a take named `name`, with a header from the daemon's hello.
    pub fn into_take(self, name: &str, hello: &Hello) -> TakeInput {
        let created_unix_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        TakeInput {
            name: name.to_string(),
            header: Some(TakeHeader {
                name: name.to_string(),
                rig_name: hello.rig_name.clone(),
                calibration_id: "unknown (live capture)".to_string(),
                filter: String::new(),
                tick_rate_hz: hello.tick_rate_hz,
                created_unix_s,
                daemon_version: hello.daemon_version.clone(),
                joint_names: hello.joint_names.clone(),
                clock: None,
                stage: None,
                stage_clock: None,
            }),
            element_names: Vec::new(),
            frames: self.frames,
            torn_bytes: 0,
            ended: true,
            damage: None,
        }
    }
}

/// How long to keep reading after a stop request for poses already sent.
pub const DRAIN: Duration = Duration::from_millis(300);

/// Whether a capture that was asked to stop has read for [`DRAIN`] since (the poses and field
/// frames already sent are kept); `until` holds when the reading ends once `stop` is seen.
pub(crate) fn drained(stop: &AtomicBool, until: &mut Option<Instant>) -> bool {
    if until.is_none() && stop.load(Ordering::SeqCst) {
        *until = Some(Instant::now() + DRAIN);
    }
    until.is_some_and(|d| Instant::now() >= d)
}

/// Subscribes to the daemon at `source` (its socket directory, or a `frond-zenoh` bridge on
/// another host) and captures until recording stops (or, in
/// [`LiveMode::All`], until `stop`); on `stop` drains what was already sent, then returns.
/// `status` gets one line per state change. Returns the capture and the last hello.
pub fn capture(
    source: &Source,
    mode: LiveMode,
    stop: &Arc<AtomicBool>,
    status: &mut dyn FnMut(&str),
) -> Result<(LiveCapture, Hello), LiveError> {
    let mut sub = Subscriber::options().read_timeout(Some(Duration::from_millis(100))).subscribe(source)?;
    let mut hello = sub.hello().clone();
    status(&format!(
        "connected to frondd {} (rig `{}`, {} Hz); {}",
        frond_protocol::printable(&hello.daemon_version),
        frond_protocol::printable(&hello.rig_name),
        hello.tick_rate_hz,
        match mode {
            LiveMode::Recording => "waiting for a recording (frond record start NAME)",
            LiveMode::All => "capturing every pose until Ctrl-C",
        }
    ));
    let mut cap = LiveCapture::new(mode);
    let mut drain_until: Option<Instant> = None;
    loop {
        if drained(stop, &mut drain_until) {
            status("stopped");
            break;
        }
        let was_capturing = cap.capturing();
        match sub.next_event() {
            Ok(Event::Pose(p)) => {
                if cap.push(&p) {
                    status(&format!("recording stopped after {} frames", cap.len()));
                    break;
                }
                if !was_capturing && cap.capturing() && mode == LiveMode::Recording {
                    status("recording started");
                }
            }
            Ok(Event::Gap { expected, got }) => cap.gap(got - expected),
            Ok(Event::RigChanged(h)) | Ok(Event::Reconnected(h)) => {
                status(&format!("daemon hello: rig `{}`", frond_protocol::printable(&h.rig_name)));
                hello = h;
            }
            Ok(Event::Disconnected) => status("daemon disconnected; reconnecting"),
            // The capture keeps element ids as they come; the rig names its layers.
            Ok(Event::Elements(_)) => {}
            // Nothing pending: during a drain, everything sent has been read.
            Err(SdkError::Timeout { .. }) if drain_until.is_some() => {
                status("stopped");
                break;
            }
            Err(SdkError::Timeout { .. }) => {}
            Err(e) if !cap.is_empty() => {
                status(&format!("pose stream ended: {e}; keeping the {} frames captured", cap.len()));
                break;
            }
            Err(e) => return Err(e.into()),
        }
    }
    if cap.is_empty() {
        return Err(LiveError::Nothing(match mode {
            LiveMode::Recording => "no recording was seen".to_string(),
            LiveMode::All => "no pose arrived".to_string(),
        }));
    }
    Ok((cap, hello))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(seq: u64, recording: bool) -> Pose {
        let mut flags = PoseFlags::default();
        flags.set(PoseFlags::RECORDING, recording);
        Pose {
            seq,
            flags,
            hand: frond_protocol::HandWire { t: seq as f64 * 0.01, ..Default::default() },
            ..Pose::default()
        }
    }

    #[test]
    fn recording_mode_keeps_the_recorded_run_and_completes_when_it_stops() {
        let mut c = LiveCapture::new(LiveMode::Recording);
        assert!(!c.push(&pose(0, false)));
        c.gap(5); // before recording: not counted
        assert!(!c.push(&pose(1, true)));
        assert!(!c.push(&pose(2, true)));
        c.gap(2);
        assert!(c.push(&pose(5, false)));
        assert!(c.push(&pose(6, true))); // after completion: ignored
        assert_eq!(c.missing, 2);
        let hello = Hello {
            protocol_version: 1,
            daemon_version: "0.1.0".into(),
            rig_name: "grass".into(),
            joint_names: vec![],
            tick_rate_hz: 100,
            elements: Default::default(),
            next_seq: 0,
        };
        let take = c.into_take("live", &hello);
        assert_eq!(take.frames.iter().map(|f| f.seq).collect::<Vec<_>>(), [1, 2]);
        assert_eq!(take.frames[1].pose.t, 0.02);
        assert_eq!(take.header.unwrap().tick_rate_hz, 100);
    }

    #[test]
    fn all_mode_keeps_everything() {
        let mut c = LiveCapture::new(LiveMode::All);
        for s in 0..3 {
            assert!(!c.push(&pose(s, s == 1)));
        }
        assert_eq!(c.len(), 3);
    }
}
