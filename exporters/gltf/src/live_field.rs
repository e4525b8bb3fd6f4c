//! `frond-gltf live --field`: keep what defines a running field while the daemon records (its
//! definition, every field frame's host time, stream time and controls, and the frames of its
//! driving stream), then bake every plant of it ([`crate::bake_live`]).
//!
//! The daemon publishes no pose per plant (protocol 3; seed 000, section 6.2): a field frame
//! carries the stream time `tau`, the controls and a few frames of the driving stream, and every
//! subscriber evaluates the plants it draws. [`FieldCapture`] is the pure part: it takes the
//! field frames in order, keeps one [`FieldMark`] per frame and each stream frame once, and
//! decides when the capture is complete (the `recording` flag went from set to clear).
//! [`capture_field`] drives it from a `frond_sdk::Subscriber` that keeps every field frame
//! (`SubscriberOptions::keep_field_frames`), as [`crate::live::capture`] drives poses.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use frond_motion::clip::Joints;
use frond_motion::controls::FieldControls;
use frond_motion::field_eval::StreamHistory;
use frond_motion::field_wire::controls_from_wire;
use frond_protocol::field::{FieldDefinition, FieldFrame};
use frond_protocol::{PoseFlags, printable};
use frond_sdk::field::{LiveFields, MAX_KEPT_FIELD_FRAMES};
use frond_sdk::{Event, SdkError, Source, Subscriber};

use crate::bake::{BakeOptions, live_field_keys};
use crate::live::{LiveError, LiveMode, drained};

/// Most stream frames one capture keeps (about 19 hours of a 30 FPS stream at motion speed 1;
/// 2^21 frames of 48 bytes): a peer whose stream runs further ends the capture there.
pub const MAX_CAPTURED_STREAM_FRAMES: u64 = 1 << 21;

/// One field frame as the bake uses it: when it was published, the stream time then, the
/// controls in force and how far the driving stream had been produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldMark {
    /// Host `CLOCK_MONOTONIC` nanoseconds of the frame.
    pub host_ns: u64,
    /// Stream time, seconds.
    pub tau_s: f64,
    /// The controls in force.
    pub controls: FieldControls,
    /// Stream frames produced (the newest is `produced - 1`).
    pub produced: u64,
}

/// The field frames of one live capture of one field.
#[derive(Debug, Clone)]
pub struct FieldCapture {
    mode: LiveMode,
    definition: FieldDefinition,
    marks: Vec<FieldMark>,
    /// Stream frame `stream_base + k` is `stream[k]` (`None` until it arrived).
    stream_base: u64,
    stream: Vec<Option<Joints>>,
    recording_seen: bool,
    complete: bool,
    /// Why the capture ended early (the stream ran past [`MAX_CAPTURED_STREAM_FRAMES`], or
    /// started again).
    pub cut_short: Option<String>,
    /// Frames (of any kind) the daemon dropped for this subscriber during the capture, and
    /// field frames the SDK could not keep for it.
    pub missing: u64,
    /// Field frames of this field left out: controls or stream time not finite, or a host time
    /// not after the previous frame's.
    pub ignored: u64,
}

impl FieldCapture {
    /// An empty capture of the field `definition` describes.
    pub fn new(mode: LiveMode, definition: FieldDefinition) -> Self {
        FieldCapture {
            mode,
            definition,
            marks: Vec::new(),
            stream_base: 0,
            stream: Vec::new(),
            recording_seen: false,
            complete: false,
            cut_short: None,
            missing: 0,
            ignored: 0,
        }
    }

    /// The field's definition as the daemon sent it.
    pub fn definition(&self) -> &FieldDefinition {
        &self.definition
    }

    /// One mark per field frame kept, in order of host time.
    pub fn marks(&self) -> &[FieldMark] {
        &self.marks
    }

    /// Stream frame `index`, if it arrived during the capture (or was held when it began).
    pub fn stream_frame(&self, index: u64) -> Option<&Joints> {
        let k = usize::try_from(index.checked_sub(self.stream_base)?).ok()?;
        self.stream.get(k)?.as_ref()
    }

    /// The captured span, seconds of host time from the first frame kept to the last.
    pub fn span_s(&self) -> f64 {
        match (self.marks.first(), self.marks.last()) {
            (Some(a), Some(b)) => (b.host_ns - a.host_ns) as f64 / 1e9,
            _ => 0.0,
        }
    }

    /// Field frames kept.
    pub fn len(&self) -> usize {
        self.marks.len()
    }

    /// True when no field frame was kept.
    pub fn is_empty(&self) -> bool {
        self.marks.is_empty()
    }

    /// True once the first frame was kept.
    pub fn capturing(&self) -> bool {
        !self.marks.is_empty()
    }

    /// Takes one field frame (frames of other fields are not this capture's); `history` is the
    /// field's stream history the subscriber holds now, copied when the capture begins (the
    /// plants read back up to the delays the definition's `history_frames` cover). Returns true
    /// once the capture is complete (recording stopped); frames after that are ignored.
    pub fn push(&mut self, frame: &FieldFrame, history: Option<&StreamHistory>) -> bool {
        if self.complete || frame.field != self.definition.id {
            return self.complete;
        }
        let recording = frame.flags.contains(PoseFlags::RECORDING);
        match self.mode {
            LiveMode::All => {}
            LiveMode::Recording if recording => self.recording_seen = true,
            LiveMode::Recording if self.recording_seen => {
                self.complete = true;
                return true;
            }
            LiveMode::Recording => return false,
        }
        let Some(controls) = controls_from_wire(&frame.controls) else {
            self.ignored += 1;
            return false;
        };
        if !frame.tau_s.is_finite() || self.marks.last().is_some_and(|m| frame.host_monotonic_ns <= m.host_ns)
        {
            self.ignored += 1;
            return false;
        }
        if self.marks.is_empty() {
            self.stream_base = frame.produced.saturating_sub(u64::from(self.definition.history_frames));
            if let Some(h) = history {
                for k in h.oldest().max(self.stream_base)..h.produced() {
                    if let Some(j) = h.get(k) {
                        self.store(k, *j);
                    }
                }
            }
        }
        if self.marks.last().is_some_and(|m| frame.produced < m.produced) {
            // Stream frames are numbered from 0 again: another stream (the daemon or the field
            // restarted under the same id), whose frames must not mix with these.
            self.cut_short = Some(format!(
                "the field's driving stream started again (the daemon or the field restarted); kept the {} \
                 field frames before",
                self.marks.len()
            ));
            self.complete = true;
            return true;
        }
        if frame.produced.saturating_sub(self.stream_base) > MAX_CAPTURED_STREAM_FRAMES {
            self.cut_short = Some(format!(
                "the field's driving stream ran past {MAX_CAPTURED_STREAM_FRAMES} frames during the capture; \
                 kept the {} field frames before",
                self.marks.len()
            ));
            self.complete = true;
            return true;
        }
        // As `frond_motion::field_wire::apply_frame`: only frames the stream has produced.
        for e in frame.entries.as_slice().iter().filter(|e| e.index < frame.produced) {
            self.store(e.index, e.joints_deg);
        }
        self.marks.push(FieldMark {
            host_ns: frame.host_monotonic_ns,
            tau_s: frame.tau_s,
            controls,
            produced: frame.produced,
        });
        false
    }

    /// A pose of the stream: one not flagged `recording` after recording was seen ends a
    /// [`LiveMode::Recording`] capture (the field stopped while recording, or recording
    /// stopped between two field frames).
    pub fn pose_flags(&mut self, flags: PoseFlags) -> bool {
        if self.mode == LiveMode::Recording && self.recording_seen && !flags.contains(PoseFlags::RECORDING) {
            self.complete = true;
        }
        self.complete
    }

    /// Notes `n` frames dropped (counted only while capturing).
    pub fn gap(&mut self, n: u64) {
        if self.capturing() {
            self.missing = self.missing.saturating_add(n);
        }
    }

    fn store(&mut self, index: u64, joints: Joints) {
        let Some(k) = index.checked_sub(self.stream_base) else { return };
        if k >= MAX_CAPTURED_STREAM_FRAMES {
            return;
        }
        let k = k as usize;
        if k >= self.stream.len() {
            self.stream.resize(k + 1, None);
        }
        self.stream[k] = Some(joints);
    }
}

/// Which running field to capture: the one named (its stage's name), or the only one. `Ok(None)`
/// while no field runs; an error when the name matches none of those running, or when several
/// run and none was named.
pub fn pick_field(fields: &LiveFields, name: Option<&str>) -> Result<Option<FieldDefinition>, LiveError> {
    let running: Vec<String> =
        fields.iter().map(|f| printable(&f.definition().source).into_owned()).collect();
    match name {
        Some(n) => match fields.by_source(n) {
            Some(f) => Ok(Some(f.definition().clone())),
            None if running.is_empty() => Ok(None),
            None => {
                Err(LiveError::NoSuchField { name: printable(n).into_owned(), running: running.join(", ") })
            }
        },
        None => match running.len() {
            0 => Ok(None),
            1 => Ok(fields.iter().next().map(|f| f.definition().clone())),
            count => Err(LiveError::WhichField { count, running: running.join(", ") }),
        },
    }
}

/// Subscribes to the daemon at `source` and captures the field frames of the running field
/// `name` picks ([`pick_field`]) until recording stops (or, in [`LiveMode::All`], until `stop`);
/// on `stop` drains what was already sent, then returns. `accept` is asked about the field once
/// picked (its rig), so that a field that cannot be baked is refused before the performance;
/// `status` says once when the capture grows past what `opts` can bake
/// ([`crate::bake::live_field_keys`]).
pub fn capture_field(
    source: &Source,
    mode: LiveMode,
    name: Option<&str>,
    stop: &Arc<AtomicBool>,
    opts: &BakeOptions,
    accept: &mut dyn FnMut(&FieldDefinition) -> Result<(), String>,
    status: &mut dyn FnMut(&str),
) -> Result<FieldCapture, LiveError> {
    let mut sub = Subscriber::options()
        .read_timeout(Some(Duration::from_millis(100)))
        .keep_field_frames(MAX_KEPT_FIELD_FRAMES)
        .subscribe(source)?;
    let hello = sub.hello();
    status(&format!(
        "connected to frondd {}; {} {}",
        printable(&hello.daemon_version),
        match mode {
            LiveMode::Recording => "waiting for a recording (frond record start NAME) of",
            LiveMode::All => "capturing every field frame until Ctrl-C of",
        },
        match name {
            Some(n) => format!("field `{}`", printable(n)),
            None => "the running field".to_string(),
        }
    ));
    let mut cap: Option<FieldCapture> = None;
    let mut frames = Vec::with_capacity(MAX_KEPT_FIELD_FRAMES);
    let mut drain_until: Option<Instant> = None;
    let mut warned = false;
    loop {
        if drained(stop, &mut drain_until) {
            status("stopped");
            break;
        }
        let event = sub.next_event();
        // The field frames read with this event first: they came before it.
        let dropped = sub.take_field_frames(&mut frames);
        if let Some(c) = cap.as_mut() {
            c.gap(dropped);
        }
        let mut done = false;
        for f in frames.drain(..) {
            if cap.as_ref().is_none_or(|c| !c.capturing() && sub.fields().get(c.definition.id).is_none()) {
                cap = pick(sub.fields(), name, mode, accept, status)?;
            }
            let Some(c) = cap.as_mut() else { continue };
            let was_capturing = c.capturing();
            let history = sub.fields().get(f.field).map(|lf| lf.state().history());
            if c.push(&f, history) {
                done = true;
                break;
            }
            if !was_capturing && c.capturing() && mode == LiveMode::Recording {
                status("recording started");
            }
        }
        if let Some(c) = cap.as_ref().filter(|c| !warned && c.capturing()) {
            let d = c.definition();
            if let Err(e) = live_field_keys(&d.source, d.plants as usize, c.span_s(), opts.fps, opts) {
                warned = true;
                status(&format!(
                    "warning: {e}; stop soon: when the capture ends it is baked whole at the highest rate that fits"
                ));
            }
        }
        let c = cap.as_mut();
        match event {
            Ok(Event::Pose(p)) if !done => done = c.is_some_and(|c| c.pose_flags(p.flags)),
            Ok(Event::Gap { expected, got }) => {
                if let Some(c) = c {
                    c.gap(got - expected);
                }
            }
            Ok(Event::Disconnected) => status("daemon disconnected; reconnecting"),
            Ok(_) => {}
            Err(SdkError::Timeout { .. }) if drain_until.is_some() => {
                status("stopped");
                break;
            }
            Err(SdkError::Timeout { .. }) => {}
            Err(e) if c.as_ref().is_some_and(|c| c.capturing()) => {
                status(&format!("stream ended: {e}; keeping the field frames captured"));
                break;
            }
            Err(e) => return Err(e.into()),
        }
        if done {
            let c = cap.as_ref().map_or(0, |c| c.len());
            status(&format!("recording stopped after {c} field frames"));
            break;
        }
    }
    match cap {
        Some(c) if c.capturing() => Ok(c),
        Some(_) => Err(LiveError::Nothing(match mode {
            LiveMode::Recording => "no recording was seen".to_string(),
            LiveMode::All => "no field frame arrived".to_string(),
        })),
        None => Err(LiveError::Nothing(match name {
            Some(n) => format!("no field named `{}` ran", printable(n)),
            None => "no field ran (frond field start)".to_string(),
        })),
    }
}

/// [`pick_field`] with `accept`'s verdict and a status line.
fn pick(
    fields: &LiveFields,
    name: Option<&str>,
    mode: LiveMode,
    accept: &mut dyn FnMut(&FieldDefinition) -> Result<(), String>,
    status: &mut dyn FnMut(&str),
) -> Result<Option<FieldCapture>, LiveError> {
    let Some(d) = pick_field(fields, name)? else { return Ok(None) };
    accept(&d).map_err(LiveError::Refused)?;
    status(&format!("field `{}`: {} plants of rig `{}`", printable(&d.source), d.plants, printable(&d.rig)));
    Ok(Some(FieldCapture::new(mode, d)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_motion::field_wire::controls_to_wire;
    use frond_protocol::ElementId;
    use frond_protocol::field::{FieldLayout, StreamFrame};

    fn definition() -> FieldDefinition {
        FieldDefinition {
            id: ElementId::new(40),
            source: "field".into(),
            rig: "grass".into(),
            layout: FieldLayout {
                version: 1,
                take: "t".into(),
                fps: 30.0,
                frames: 60,
                rows: 2,
                cols: 2,
                cell_m: 0.2,
                speed_m_s: 1.0,
                direction_deg: 0.0,
                authored_direction_deg: 0.0,
                density: 1.0,
                seed: 1,
            },
            plants: 4,
            stream_fps: 30.0,
            history_frames: 10,
            publish_hz: 60,
            plant_elements: vec![],
        }
    }

    fn frame(n: u64, recording: bool) -> FieldFrame {
        let mut f = FieldFrame {
            seq: n,
            host_monotonic_ns: 1_000_000_000 + n * 16_666_667,
            field: ElementId::new(40),
            tau_s: n as f64 / 60.0,
            controls: controls_to_wire(&FieldControls::default()),
            produced: 20 + n,
            ..FieldFrame::default()
        };
        f.flags.set(PoseFlags::RECORDING, recording);
        f.entries.push(StreamFrame { index: 19 + n, joints_deg: [[n as f32; 3]; 4] });
        f
    }

    #[test]
    fn keeps_the_recorded_frames_and_the_history_then_completes() {
        let mut c = FieldCapture::new(LiveMode::Recording, definition());
        let mut h = StreamHistory::new(10);
        for k in 0..20 {
            h.push([[100.0 + k as f32; 3]; 4]);
        }
        assert!(!c.push(&frame(0, false), Some(&h)));
        c.gap(3); // before recording: not counted
        assert!(!c.push(&frame(1, true), Some(&h)));
        assert!(!c.push(&FieldFrame { field: ElementId::new(41), ..frame(2, true) }, None));
        let mut bad = frame(2, true);
        bad.tau_s = f64::NAN;
        assert!(!c.push(&bad, None));
        assert!(!c.push(&FieldFrame { host_monotonic_ns: 5, ..frame(2, true) }, None));
        assert!(!c.push(&frame(3, true), None));
        c.gap(2);
        assert!(c.push(&frame(4, false), None));
        assert!(c.push(&frame(5, true), None));
        assert_eq!((c.len(), c.missing, c.ignored), (2, 2, 2));
        assert_eq!(c.marks()[1].produced, 23);
        assert!((c.span_s() - 2.0 * 0.016_666_667).abs() < 1e-9);
        // The window at the first frame kept (21 produced, 10 held: 11..=20), then the entries.
        assert_eq!(c.stream_frame(10), None);
        assert_eq!(c.stream_frame(11).unwrap()[0][0], 111.0);
        assert_eq!(c.stream_frame(20).unwrap()[0][0], 1.0, "frame 1's entry replaced the history's");
        assert_eq!(c.stream_frame(22).unwrap()[0][0], 3.0);
        assert_eq!(c.stream_frame(u64::MAX), None);
    }

    #[test]
    fn a_pose_after_recording_ends_it_and_a_runaway_or_restarted_stream_cuts_it_short() {
        let mut c = FieldCapture::new(LiveMode::Recording, definition());
        assert!(!c.pose_flags(PoseFlags::default()));
        assert!(!c.push(&frame(1, true), None));
        assert!(c.pose_flags(PoseFlags::default()));
        let mut c = FieldCapture::new(LiveMode::All, definition());
        assert!(!c.push(&frame(1, false), None));
        assert!(c.push(&FieldFrame { produced: u64::MAX, ..frame(2, false) }, None));
        assert!(c.cut_short.as_deref().unwrap().contains("kept the 1 field frames"));
        assert_eq!(c.len(), 1);
        // A stream numbered from 0 again (a restarted daemon or field under the same id).
        let mut c = FieldCapture::new(LiveMode::All, definition());
        assert!(!c.push(&frame(5, false), None));
        assert!(c.push(&FieldFrame { produced: 3, ..frame(6, false) }, None));
        assert!(c.cut_short.as_deref().unwrap().contains("started again"));
        assert_eq!((c.len(), c.stream_frame(24).unwrap()[0][0]), (1, 5.0));
    }

    #[test]
    fn picks_the_named_or_only_field_and_says_which_run() {
        use frond_protocol::field::FieldTable;
        let mut fields = LiveFields::default();
        assert!(pick_field(&fields, None).unwrap().is_none());
        assert!(pick_field(&fields, Some("x")).unwrap().is_none());
        let flowers = FieldDefinition { id: ElementId::new(41), source: "flowers".into(), ..definition() };
        fields.on_table(FieldTable { elements_version: 1, fields: vec![definition()] });
        assert_eq!(pick_field(&fields, None).unwrap().unwrap().source, "field");
        fields.on_table(FieldTable { elements_version: 2, fields: vec![definition(), flowers] });
        assert_eq!(pick_field(&fields, Some("flowers")).unwrap().unwrap().id, ElementId::new(41));
        let e = pick_field(&fields, None).unwrap_err().to_string();
        assert!(e.contains("2 fields are running (field, flowers)") && e.contains("--field NAME"), "{e}");
        let e = pick_field(&fields, Some("tulips")).unwrap_err().to_string();
        assert!(e.contains("no running field is named `tulips`; running: field, flowers"), "{e}");
    }
}
