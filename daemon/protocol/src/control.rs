//! Requests and replies on the control socket.
//!
//! Rigs, calibrations and filters travel as text (TOML or a filter spec string) and are parsed and
//! validated by the daemon, so that a daemon running under a hardened service can apply files it
//! could not read itself, and so that every client gets the daemon's exact validation errors.

use serde::{Deserialize, Serialize};

use crate::ElementId;

/// A request from `frond` (or any client) to the daemon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ControlRequest {
    /// Ask for a [`StatusReport`].
    Status,
    /// Replace the active rig. `toml` is a rig file's contents; `name` labels it.
    SetRig {
        /// Rig name (usually the file stem).
        name: String,
        /// Rig file contents.
        toml: String,
    },
    /// Replace the active calibration. `toml` is a calibration file's contents.
    SetCalibration {
        /// Calibration id (usually the user name).
        id: String,
        /// Calibration file contents.
        toml: String,
    },
    /// Replace the jitter filter: `none`, `lowpass:cutoff_hz=8`,
    /// `one-euro:min_cutoff=1,beta=0.007,d_cutoff=1`.
    SetFilter {
        /// Filter spec text.
        spec: String,
    },
    /// Start recording a take named `name` into the takes directory.
    RecordStart {
        /// Take name: letters, digits, `-`, `_` and `.`, not starting with `.`.
        name: String,
    },
    /// Stop the current recording.
    RecordStop,
    /// Put a marker with `label` into the current take.
    Mark {
        /// Free text, at most 256 bytes.
        label: String,
    },
    /// Ask for the most recent raw (uncalibrated) hand samples, for `frond calibrate`.
    RawSample,
    /// Record a secondary layer (`leaf`, `petal`, ...): hand frames are published and recorded as
    /// that element, optionally while `global_take` loops on the stream as element 0.
    RecordLayer {
        /// New take name.
        name: String,
        /// Layer (a secondary element of the rig).
        layer: String,
        /// Global take to loop meanwhile.
        global_take: Option<String>,
        /// Seed of the loop's random jumps.
        seed: u64,
    },
    /// Starts a live stage (seed 000, sections 5.3, 6.2-6.4): something that publishes poses of
    /// its own or transforms the hand's in the realtime loop. A stage of the same name already
    /// running is replaced. Answered with [`ControlReply::Ok`] once the loop runs it.
    StageStart {
        /// The stage's name, by which it is stopped and steered; `None` names it after its kind
        /// (`playback`, `field`, `guided`).
        name: Option<String>,
        /// What to run.
        spec: StageSpec,
    },
    /// Stops the stage `name` (nothing happens if none runs under that name).
    StageStop {
        /// Stage name.
        name: String,
    },
    /// A typed input to the running stage `name` (a field control key, ...).
    StageInput {
        /// Stage name.
        name: String,
        /// The input.
        input: StageInput,
    },
    /// Testing aid: block the realtime loop for `ms` milliseconds (watchdog tests). Refused
    /// unless the daemon was started with `--test-hooks`.
    FreezeLoop {
        /// How long to block the loop.
        ms: u32,
    },
    /// Testing aid: panic in the control thread that handles it, to prove that a panicking
    /// request is answered `Internal` and gives its connection slot back. Refused unless the
    /// daemon was started with `--test-hooks`.
    PanicForTest,
    /// Follow a mocap stage's capture triggers (`follow`: a `CaptureStart` starts a take), or
    /// pause (starts are heard, counted and ignored; a `CaptureStop` still ends a take a trigger
    /// started). Refused when frondd listens for no triggers. Answered with [`ControlReply::Ok`].
    SetTriggers {
        /// Follow (true) or pause (false).
        follow: bool,
    },
}

impl ControlRequest {
    /// The request's name in messages, logs and the remote-control allow-list (`status`,
    /// `set-rig`, `record-start`, ...).
    pub fn name(&self) -> &'static str {
        match self {
            ControlRequest::Status => "status",
            ControlRequest::SetRig { .. } => "set-rig",
            ControlRequest::SetCalibration { .. } => "set-calibration",
            ControlRequest::SetFilter { .. } => "set-filter",
            ControlRequest::RecordStart { .. } => "record-start",
            ControlRequest::RecordStop => "record-stop",
            ControlRequest::Mark { .. } => "mark",
            ControlRequest::RawSample => "raw-sample",
            ControlRequest::RecordLayer { .. } => "record-layer",
            ControlRequest::StageStart { .. } => "stage-start",
            ControlRequest::StageStop { .. } => "stage-stop",
            ControlRequest::StageInput { .. } => "stage-input",
            ControlRequest::FreezeLoop { .. } => "freeze-loop",
            ControlRequest::PanicForTest => "panic-for-test",
            ControlRequest::SetTriggers { .. } => "set-triggers",
        }
    }
}

/// What a live stage runs, with its parameters. Every kind of stage is one variant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum StageSpec {
    /// Loop a recorded take on the pose stream as the global element, flagged `playback`, as
    /// seed 000 section 5.3 shows the global animation while secondary layers are authored.
    Playback {
        /// Take name in the takes directory.
        take: String,
        /// Seed of the loop's random jumps.
        seed: u64,
    },
    /// Play a field (seed 000, section 6.2): `field_json` as written by `frond take field`, of the
    /// looped `take`; the first `plants` plants are published (60 Hz), each an announced
    /// `field-plant` element. Steered by [`StageInput::Key`] and by wrist swipes (6.3).
    Field {
        /// Take name in the takes directory.
        take: String,
        /// field.json contents.
        field_json: String,
        /// How many plants to publish (1..=64).
        plants: u16,
        /// Seed of the loop's random jumps.
        seed: u64,
    },
    /// A [`StageSpec::Field`] whose plants are the rig of `rig_toml` (a rig file's text), not the
    /// active rig: a meadow of several rigs is one such field per rig, each under its own stage
    /// name. The field definition and its `field-plant` elements name that rig, and the element
    /// table lists it. A variant of its own rather than an optional key of `Field`, so that a
    /// daemon from before it refuses the request (an unknown variant) instead of playing the
    /// active rig without a word.
    FieldOfRig {
        /// Take name in the takes directory.
        take: String,
        /// field.json contents.
        field_json: String,
        /// How many plants to publish (1..=64).
        plants: u16,
        /// Seed of the loop's random jumps.
        seed: u64,
        /// The plants' rig: a rig file's text (at most [`MAX_STAGE_RIG_BYTES`]).
        rig_toml: String,
    },
    /// Walk motion graphs (seed 003, section 6): `plants` plants (1..=64), plant `i` walking
    /// `sources[i mod len]` (instancing, section 6.1: each take with its own graph and control
    /// point), each an announced `field-plant` element published at 60 Hz, each with seed
    /// `seed + i`. Directed by [`StageInput::GraphGoal`].
    Graph {
        /// The takes and their graphs (1..=[`MAX_GRAPH_SOURCES`]).
        sources: Vec<GraphSource>,
        /// How many plants walk (1..=64).
        plants: u16,
        /// Seed of the first plant's walk.
        seed: u64,
    },
    /// The simulated plant of seed 003 (section 4) in the loop, published as the global element
    /// (flagged `playback`): `rig_toml` (a rig file's text; `None`: the active rig) blown by
    /// `wind` (`speed=S,dir=DEG,gust=G,seed=N`); the hand's bend steers the wind live.
    Sim {
        /// Rig file text, or the active rig.
        rig_toml: Option<String>,
        /// Wind spec text.
        wind: String,
    },
    /// Guided procedural motion on the live mapping (seed 000, Eq. 8):
    /// `sigma=S1,S2,S3;sg=G1,G2,G3` (seconds; gains).
    Guided {
        /// Spec text.
        spec: String,
    },
}

impl StageSpec {
    /// The kind of stage it runs (its name is also the stage's default name).
    pub fn kind(&self) -> StageKind {
        match self {
            StageSpec::Playback { .. } => StageKind::Playback,
            StageSpec::Field { .. } | StageSpec::FieldOfRig { .. } => StageKind::Field,
            StageSpec::Guided { .. } => StageKind::Guided,
            StageSpec::Graph { .. } => StageKind::Graph,
            StageSpec::Sim { .. } => StageKind::Sim,
        }
    }
}

/// Every kind of live stage, defined once: a new kind added here makes the compiler list each
/// place that must handle it (its [`StageSpec`] variant, the daemon's builders).
///
/// It travels only as its name ([`StageKind::as_str`]), in [`StageStatus::kind`], which stays
/// text so that a client still reads the status of a daemon that runs a kind it does not know.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StageKind {
    /// A looped take ([`StageSpec::Playback`]).
    Playback,
    /// Layer recording: the hand published as a rig's secondary element (`frond record layer`).
    Layer,
    /// A field of plants ([`StageSpec::Field`], [`StageSpec::FieldOfRig`]).
    Field,
    /// Guided motion on the live mapping ([`StageSpec::Guided`], or a rig's `[guided]` table).
    Guided,
    /// Motion-graph walkers ([`StageSpec::Graph`]).
    Graph,
    /// The simulated plant ([`StageSpec::Sim`]).
    Sim,
}

impl StageKind {
    /// Its name: the default name of a stage of this kind, and its kind in `frond status`.
    pub const fn as_str(self) -> &'static str {
        match self {
            StageKind::Playback => "playback",
            StageKind::Layer => "layer",
            StageKind::Field => "field",
            StageKind::Guided => "guided",
            StageKind::Graph => "graph",
            StageKind::Sim => "sim",
        }
    }
}

impl std::fmt::Display for StageKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A typed input to a running stage.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum StageInput {
    /// A field control key (seed 000, section 6.3).
    Key(StageKey),
    /// The goal of a graph walk (seed 003, section 6.1.2).
    GraphGoal(GraphGoal),
}

impl StageInput {
    /// Checks what a client may have sent, before it reaches the loop (a key is always valid).
    pub fn check(&self) -> Result<(), BadGraphGoal> {
        match self {
            StageInput::Key(_) => Ok(()),
            StageInput::GraphGoal(goal) => goal.check(),
        }
    }
}

/// Largest rig file text a stage start may carry, bytes (a rig file's own limit, 1 MiB, is more
/// than a control request holds; rig files are a few KiB).
pub const MAX_STAGE_RIG_BYTES: usize = 64 << 10;

/// Most takes one live graph walk draws on (each graph is held in memory).
pub const MAX_GRAPH_SOURCES: usize = 8;

/// One take of a live graph walk and its graph.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct GraphSource {
    /// Take name in the takes directory.
    pub take: String,
    /// Graph name in the takes directory (`<takes dir>/<graph>.graph.json`, from `frond take
    /// graph`).
    pub graph: String,
}

/// What the plants of a graph walk aim for.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GraphGoal {
    /// Random walks.
    Off,
    /// A ground-plane direction, degrees (0 towards +X, 90 towards +Z).
    Dir {
        /// The direction.
        deg: f64,
    },
    /// The hand's bend direction, live: the root joint's bend from the mapped pose.
    Hand,
    /// The pose of a take frame (at the graph's rate): the nearest node, by the shortest path.
    Frame {
        /// The frame.
        frame: u32,
    },
    /// A pose given by its 12 angles: the node nearest it (Euclidean over the angles), by the
    /// shortest path.
    Pose {
        /// Pitch, yaw, roll of joints 0..3, degrees (finite, within +-360).
        joints_deg: [[f32; 3]; 4],
    },
}

impl GraphGoal {
    /// Checks what a client may have sent: angles finite and within +-360 degrees.
    pub fn check(&self) -> Result<(), BadGraphGoal> {
        let ok = |a: f64| a.is_finite() && a.abs() <= 360.0;
        match self {
            GraphGoal::Dir { deg } if !ok(*deg) => Err(BadGraphGoal::Direction(*deg)),
            GraphGoal::Pose { joints_deg } if !joints_deg.iter().flatten().all(|&a| ok(a as f64)) => {
                Err(BadGraphGoal::Pose(*joints_deg))
            }
            _ => Ok(()),
        }
    }
}

/// A [`GraphGoal`] a client sent that the daemon refuses (its text is the refusal's message).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BadGraphGoal {
    /// A direction that is not finite or beyond +-360 degrees (the direction sent).
    #[error("goal direction {0} is not a finite angle within +-360 degrees")]
    Direction(f64),
    /// A pose with an angle that is not finite or beyond +-360 degrees (the angles sent).
    #[error("goal pose {0:?} has an angle that is not finite or beyond +-360 degrees")]
    Pose([[f32; 3]; 4]),
}

/// The keys of the field controls (seed 000, section 6.3): arrows turn the propagation direction
/// (left/right) and change its speed (up/down); `+`/`-` make the motion stronger or weaker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StageKey {
    /// Turn the propagation direction left.
    Left,
    /// Turn the propagation direction right.
    Right,
    /// Faster propagation.
    Up,
    /// Slower propagation.
    Down,
    /// Stronger motion (`+`).
    Stronger,
    /// Weaker motion (`-`).
    Weaker,
}

/// A field key name that is none of [`StageKey`]'s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown field key {0:?}: use left, right, up, down, stronger (+), weaker (-)")]
pub struct UnknownStageKey(pub String);

impl std::str::FromStr for StageKey {
    type Err = UnknownStageKey;
    fn from_str(key: &str) -> Result<Self, UnknownStageKey> {
        Ok(match key {
            "left" => StageKey::Left,
            "right" => StageKey::Right,
            "up" => StageKey::Up,
            "down" => StageKey::Down,
            "stronger" | "+" => StageKey::Stronger,
            "weaker" | "-" => StageKey::Weaker,
            other => return Err(UnknownStageKey(other.into())),
        })
    }
}

/// The daemon's answer to one [`ControlRequest`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ControlReply {
    /// The request was applied.
    Ok,
    /// Answer to [`ControlRequest::Status`] (boxed: it is by far the largest reply).
    Status(Box<StatusReport>),
    /// Answer to `RecordStart`/`RecordStop`.
    Recording(RecordingStatus),
    /// Answer to [`ControlRequest::RawSample`]: the latest uncalibrated sample, or none yet.
    RawSample {
        /// Device time in seconds.
        t: f64,
        /// Raw wrist `[pitch, yaw, roll]`, degrees.
        wrist_deg: [f32; 3],
        /// Raw thumb `[g1, g2, g3]`, degrees.
        thumb_deg: [f32; 3],
        /// True when the device is connected and the sample is fresh.
        fresh: bool,
    },
    /// The request was refused.
    Error(ControlError),
}

/// Why a control request was refused.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ControlError {
    /// Machine-readable kind.
    pub kind: ControlErrorKind,
    /// Human-readable explanation naming the problem.
    pub message: String,
}

/// Kinds of control refusals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ControlErrorKind {
    /// The request did not decode or is too large.
    BadRequest,
    /// A rig, calibration or filter failed validation.
    Invalid,
    /// Recording is already running / not running.
    WrongState,
    /// The caller's uid/gid is not allowed.
    PermissionDenied,
    /// The take name is not acceptable (path escape, bad characters).
    BadName,
    /// The daemon could not do it (disk full, queue full, ...).
    Internal,
}

/// Snapshot of the daemon's state for `frond status`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatusReport {
    /// Daemon version.
    pub daemon_version: String,
    /// Seconds since the daemon started.
    pub uptime_s: f64,
    /// The hand source.
    pub source: SourceStatus,
    /// Active rig name.
    pub rig_name: String,
    /// Active calibration id (`none` when neutral is zero).
    pub calibration_id: String,
    /// Active filter spec.
    pub filter: String,
    /// Nominal tick rate.
    pub tick_rate_hz: u32,
    /// Ticks per second measured over the last second.
    pub achieved_rate_hz: f64,
    /// Total ticks since start.
    pub ticks: u64,
    /// Ticks that republished a held pose (no new report).
    pub held_ticks: u64,
    /// Times a report woke the loop between ticks (the device's descriptor is polled; 0 for
    /// sources without one, which are read at the ticks).
    #[serde(default)]
    pub device_wakes: u64,
    /// Frames the loop could not hand to the publisher (queue full).
    pub publish_drops: u64,
    /// Wake-up lateness of the loop (actual wake time minus deadline).
    pub lateness: LatencySummary,
    /// Connected subscribers.
    pub subscribers: Vec<SubscriberStatus>,
    /// Recording in progress, if any.
    pub recording: Option<RecordingStatus>,
    /// Device events (connect, lost, reopened), oldest first, at most the last 32.
    pub device_events: Vec<String>,
    /// Realtime tuning in force (scheduling policy, memory lock), or why not.
    #[serde(default)]
    pub realtime: String,
    /// Live stages in force, one line each: looped playback, layer being recorded, field
    /// playback with its controls, guided motion.
    #[serde(default)]
    pub modes: Vec<String>,
    /// The live stages running, by name.
    #[serde(default)]
    pub stages: Vec<StageStatus>,
    /// The element table subscribers were last sent.
    #[serde(default)]
    pub elements: Vec<crate::ElementInfo>,
    /// Every hand source, in configuration order (`source` is the first's).
    #[serde(default)]
    pub hands: Vec<HandStatus>,
    /// What is wrong now and needs the operator, one line each (empty when all is well).
    #[serde(default)]
    pub problems: Vec<String>,
    /// The current take's write fault (path, error, frames kept and lost), until `record stop`.
    #[serde(default)]
    pub recorder_error: Option<String>,
    /// The loop's wake-up lateness since start as a histogram: buckets with upper bounds 1, 2, 4,
    /// ... microseconds (doubling up to about 1 s), then one for everything later.
    #[serde(default)]
    pub lateness_histogram: Vec<HistogramBucket>,
    /// The capture triggers of a mocap stage (issue 46): where frond listens and leads, the last
    /// message and the counts; `None` when triggers are off (and from older daemons).
    #[serde(default)]
    pub triggers: Option<TriggerStatus>,
    /// The stage's timecode from LTC (issue 46): the input, lock state and counts; `None` when
    /// no LTC input is configured (and from older daemons).
    #[serde(default)]
    pub ltc: Option<LtcStatus>,
}

/// The LTC (SMPTE 12M linear timecode) input frondd reads the stage's clock from. Every field
/// defaults, so a report from a daemon that counts less still reads.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LtcStatus {
    /// The input: a file or FIFO of raw samples, or a WAV file.
    pub input: String,
    /// `searching` (no lock yet), `locked`, `lost` (was locked; no frames now) or `ended` (a
    /// file read to its end).
    pub state: String,
    /// The locked (or last locked) rate: `24`, `25`, `29.97df`, `29.97` (non-drop-frame, as
    /// `ltc.fps` declares it) or `30`.
    pub fps: Option<String>,
    /// The last frame's label (`10:00:00:00`).
    pub last_timecode: Option<String>,
    /// Seconds since the last frame was read, when the report was made.
    pub last_age_s: Option<f64>,
    /// The input's sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Frames decoded.
    pub frames: u64,
    /// Locks gained.
    pub locks: u64,
    /// Locks lost.
    pub losses: u64,
    /// Labels that did not follow the one before while locked.
    pub jumps: u64,
    /// The last read error, in words (the input vanished, a FIFO's writer went away).
    pub last_error: Option<String>,
    /// Overruns of an ALSA capture device (the reading thread fell behind and samples were
    /// lost), recovered; 0 for a file or FIFO.
    pub overruns: u64,
}

/// The capture triggers (`CaptureStart` / `CaptureStop` over UDP): where frond listens for a
/// stage master's messages and where it sends its own, the last message heard, and the counts.
/// Every field defaults, so a report from a daemon that counts less still reads.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TriggerStatus {
    /// The address frond listens on (`0.0.0.0:30`), `None` when it does not follow.
    pub listen: Option<String>,
    /// The hosts followed (empty: any host).
    pub allow: Vec<String>,
    /// Where frond's own `record start` / `record stop` are sent (`255.255.255.255:30`), `None`
    /// when it does not lead.
    pub lead: Option<String>,
    /// The last message followed or ignored by packet id or state (not refused, not foreign).
    pub last: Option<TriggerLast>,
    /// A take waiting for its `Delay`, by name.
    pub scheduled: Option<String>,
    /// The last packet refused or ignored for its sender, in words (`10.0.0.9: not in the
    /// allow-list`).
    pub last_refused: Option<String>,
    /// Datagrams received.
    pub received: u64,
    /// Messages acted on: takes started, scheduled, stopped or cancelled.
    pub accepted: u64,
    /// Takes started by a trigger.
    pub started: u64,
    /// Takes stopped by a trigger.
    pub stopped: u64,
    /// Repeated packet ids, ignored.
    pub duplicates: u64,
    /// Packet ids older than the last one, ignored.
    pub out_of_order: u64,
    /// Datagrams from hosts outside the allow-list, ignored.
    pub foreign: u64,
    /// Datagrams that are not a trigger message, refused.
    pub malformed: u64,
    /// Datagrams longer than a trigger message may be, refused.
    pub oversized: u64,
    /// Stops for a take frond is not recording (nothing, or another take), answered with a count.
    pub stops_without_take: u64,
    /// Starts while a take was recording or waiting, ignored.
    pub already_recording: u64,
    /// Starts frond could not follow (a take of that name exists, the disk failed).
    pub start_refused: u64,
    /// frond's own messages heard back (a broadcast it sent), ignored.
    pub own_echoes: u64,
    /// Messages frond sent as the leader.
    pub lead_sent: u64,
    /// Messages frond could not send as the leader.
    pub lead_failed: u64,
    /// Following is paused (`frond triggers pause`, the console): starts are counted in
    /// `paused_starts` and not followed.
    pub paused: bool,
    /// Starts heard while paused, not followed.
    pub paused_starts: u64,
}

/// The last trigger message heard.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TriggerLast {
    /// `CaptureStart` or `CaptureStop`.
    pub kind: String,
    /// The take name it carried, as sent.
    pub name: Option<String>,
    /// Its sender's address.
    pub from: String,
    /// Its packet id.
    pub packet_id: Option<u64>,
    /// Seconds since it arrived, when the report was made.
    pub age_s: f64,
}

/// One bucket of a latency histogram.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HistogramBucket {
    /// Upper bound of the bucket, microseconds (values at most this and above the previous
    /// bucket's); `None` for the last, unbounded bucket.
    pub le_us: Option<f64>,
    /// Values in the bucket.
    pub count: u64,
}

/// One hand source: where it reads, what it drives, and its own counters and history.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandStatus {
    /// Its name (`hand` when only one is configured).
    pub name: String,
    /// Its device.
    pub source: SourceStatus,
    /// The element id it is published as.
    pub element: ElementId,
    /// That element's name (the rig's name for the global element, else the layer's).
    pub element_name: String,
    /// The rig it is mapped by.
    pub rig_name: String,
    /// Its calibration's id.
    pub calibration_id: String,
    /// Frames published from its reports.
    pub frames: u64,
    /// Held frames published for it (periods without a report).
    pub held_frames: u64,
    /// Times it stalled (open, but no reports).
    pub stalls: u64,
    /// Times it was declared lost.
    pub lost_events: u64,
    /// Reports whose time jumped forward, went back or repeated (each starts a new timeline,
    /// flagged `discontinuity`, the filter reset).
    #[serde(default)]
    pub discontinuities: u64,
    /// Stale reports skipped when the daemon resumed after a pause (SIGSTOP, overload).
    #[serde(default)]
    pub stale_skipped: u64,
    /// Its device events (connect, lost, reopened), oldest first, at most the last 32.
    pub events: Vec<String>,
}

/// One running live stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageStatus {
    /// Its name.
    pub name: String,
    /// Its kind ([`StageKind::as_str`]: `playback`, `layer`, `field`, `guided`, `graph`, `sim`).
    pub kind: String,
    /// What it is doing, in words (read from its own lock-free cell).
    pub state: String,
    /// Ids of the elements it publishes.
    pub elements: Vec<ElementId>,
    /// Work it dropped to keep within its share of the tick since it started (simulation steps,
    /// graph walk frames): it kept real time and the loop its rate, but showed less than asked.
    /// 0 while it keeps up (and from daemons that do not count it); `state` says so in words.
    #[serde(default)]
    pub dropped_work: u64,
}

/// The hand source's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceStatus {
    /// `hidraw` (real device), `fuse-hidraw` (virtual glove node), `in-process` (virtual glove
    /// without a device node), `replay`, `osc`.
    pub kind: String,
    /// Device path or description.
    pub path: String,
    /// True while reports arrive.
    pub connected: bool,
    /// Valid reports read.
    pub reports: u64,
    /// Reports rejected (bad id, short, corrupt, out of range).
    pub rejected: u64,
    /// Reports lost before frond read them: gaps in the device's own report sequence numbers,
    /// and datagrams the kernel dropped from a full OSC receive buffer.
    pub device_seq_gaps: u64,
    /// The rejected reports by reason, the reasons that occurred only: `wrong_id`, `short`,
    /// `oversized` (longer than a report, datagram or message may be), `checksum`,
    /// `out_of_range`, `malformed`, `too_many` (a Leap frame listing more hands than it may).
    #[serde(default)]
    pub rejected_by_reason: std::collections::BTreeMap<String, u64>,
    /// Connections to a hand service (Leap) dropped because it did not read what frond wrote.
    #[serde(default)]
    pub peers_dropped: u64,
    /// A camera source's frames (`webcam`): rate, latency, the model's time; `None` for other
    /// kinds (and from daemons that do not report it).
    #[serde(default)]
    pub camera: Option<CameraStatus>,
}

/// What a camera hand source does (`webcam`): its landmark helper's frames.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraStatus {
    /// Frames the helper reported since the daemon started.
    pub frames: u64,
    /// Frames in which no hand was found.
    pub empty_frames: u64,
    /// Frames a second over the last second.
    pub fps: f64,
    /// The last frame's capture to its sample, milliseconds (the model's time included).
    pub latency_ms: f64,
    /// The hand model's time on the last frame, milliseconds.
    pub model_ms: f64,
    /// Times the helper was started (more than 1: it stopped and was started again).
    pub helper_starts: u64,
    /// The camera's preview picture (the frame with the hand drawn, a few times a second): a
    /// file name in the daemon's socket directory ([`crate::paths::is_camera_preview_name`]),
    /// `None` when the daemon keeps none (and from daemons that do not).
    #[serde(default)]
    pub preview: Option<String>,
}

/// Percentiles of a latency, microseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct LatencySummary {
    /// Median.
    pub p50_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// 99.9th percentile.
    pub p999_us: f64,
    /// Maximum.
    pub max_us: f64,
    /// Number of samples behind the figures.
    pub samples: u64,
}

/// One connected pose subscriber.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubscriberStatus {
    /// Connection id, increasing.
    pub id: u64,
    /// Seconds since it connected.
    pub connected_s: f64,
    /// Frames written to it.
    pub sent: u64,
    /// Frames dropped because its queue was full.
    pub dropped: u64,
    /// The subscriber's process id as the socket reported it when it connected (`SO_PEERCRED`;
    /// 0 when unknown, or from a daemon that did not send it), so `frond doctor` can name the
    /// exporters that are connected.
    #[serde(default)]
    pub pid: u32,
}

/// A recording's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordingStatus {
    /// Take name.
    pub name: String,
    /// Path of the take file.
    pub path: String,
    /// Frames written so far.
    pub frames: u64,
    /// Frames the recorder could not accept (its queue was full); should stay 0.
    pub dropped: u64,
    /// True while recording continues.
    pub active: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graph_goals_from_a_client_are_checked() {
        assert!(GraphGoal::Dir { deg: -90.0 }.check().is_ok());
        assert!(
            GraphGoal::Dir { deg: f64::NAN }.check().unwrap_err().to_string().contains("not a finite angle")
        );
        assert!(GraphGoal::Dir { deg: 400.0 }.check().is_err());
        let mut joints_deg = [[10.0f32; 3]; 4];
        assert!(GraphGoal::Pose { joints_deg }.check().is_ok());
        joints_deg[2][1] = f32::INFINITY;
        assert!(GraphGoal::Pose { joints_deg }.check().unwrap_err().to_string().contains("not finite"));
        assert!(GraphGoal::Frame { frame: u32::MAX }.check().is_ok());
    }

    #[test]
    fn a_subscriber_status_from_a_daemon_without_pids_reads_as_pid_0() {
        #[derive(Serialize)]
        struct Before {
            id: u64,
            connected_s: f64,
            sent: u64,
            dropped: u64,
        }
        let mut bytes = Vec::new();
        let mut ser = rmp_serde::Serializer::new(&mut bytes).with_struct_map();
        Before { id: 3, connected_s: 1.5, sent: 10, dropped: 2 }.serialize(&mut ser).unwrap();
        let s: SubscriberStatus = rmp_serde::from_slice(&bytes).unwrap();
        assert_eq!(s, SubscriberStatus { id: 3, connected_s: 1.5, sent: 10, dropped: 2, pid: 0 });
    }
}
