//! Command-line syntax of `frond` (clap derive). Parsing only; validation happens in the commands.
//!
//! The doc comments here are `frond --help` text first, printed verbatim by clap: they write
//! `<stage>` and `[p,y,r]` as a user reads them, not as rustdoc markup.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

use std::path::PathBuf;

use clap::{Parser, Subcommand};

pub use crate::bench::BenchArgs;
pub use crate::calibrate::CalibrateArgs;
pub use crate::global::Global;

/// frond: operate the hand-to-plant puppet daemon.
#[derive(Debug, Parser)]
#[command(
    name = "frond",
    version,
    about,
    propagate_version = true,
    after_help = "The papers quoted by their titles (\"Interactive authoring\", ...) are named in docs/methods.md."
)]
pub struct Cli {
    /// Options shared by every command.
    #[command(flatten)]
    pub global: Global,
    /// The command to run.
    #[command(subcommand)]
    pub command: Command,
}

/// `frond` commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Show the daemon's state: source, rig, rates, loop lateness, subscribers, recording.
    Status {
        /// Print the full status report as JSON.
        #[arg(long)]
        json: bool,
        /// Ask a daemon on another host through its frond-zenoh bridge:
        /// `zenoh:frond/<stage>/<source>[?connect=tcp/HOST:PORT]` (default: this host's daemon).
        /// With `*` for the stage or the source, every source it matches, each under its name
        /// (with --json, an object from `<stage>/<source>` to its report).
        #[arg(long, value_name = "ADDRESS")]
        from: Option<frond_sdk::Source>,
    },
    /// Print live poses. Frames that only repeat the previous pose (flag `held`) are skipped
    /// unless --include-held is given, so each line is one new device sample.
    Tap {
        /// One JSON object a line: {"seq":..,"t":..,"joints":[[p,y,r],x4]}, plus "element" (its
        /// id) for any element but the global one and "flags" when set. Default: readable lines.
        #[arg(long)]
        jsonl: bool,
        /// Exit after printing N frames.
        #[arg(long, value_name = "N")]
        count: Option<u64>,
        /// Also print held frames (every tick of the daemon).
        #[arg(long)]
        include_held: bool,
        /// Only this element: its id or its name in the element table (`walker3`, `leaf`, ...).
        /// Default: every element (the global one, hands' layers, field plants, walkers).
        #[arg(long, value_name = "ID|NAME")]
        element: Option<String>,
        /// Read the poses of a daemon on another host through its frond-zenoh bridge:
        /// `zenoh:frond/<stage>/<source>[?connect=tcp/HOST:PORT]` (default: this host's daemon).
        /// With `*` for the stage or the source, every source it matches, now and as they join,
        /// each line tagged with its source ("source":"<stage>/<source>" first in JSON Lines).
        #[arg(long, value_name = "ADDRESS")]
        from: Option<frond_sdk::Source>,
    },
    /// Map a hand recording (JSONL on stdin) to poses (JSONL on stdout), offline, with the
    /// daemon's own mapping code. Bad lines are reported on stderr with their line number and
    /// skipped; the good ones are written; the exit status is 1 if any line was bad.
    Map {
        /// Rig: an embedded name (grass, flower, shrub) or a rig file (TOML).
        #[arg(long, value_name = "NAME|FILE")]
        rig: PathBuf,
        /// Calibration file (TOML) [default: zero neutral, the rig's thumb ranges].
        #[arg(long, value_name = "FILE")]
        calibration: Option<PathBuf>,
        /// Jitter filter: none, lowpass, one-euro, or a full spec such as
        /// lowpass:cutoff_hz=8 [default: the rig's filter].
        #[arg(long, value_name = "SPEC")]
        filter: Option<String>,
        /// Read this file instead of stdin.
        #[arg(long, value_name = "FILE")]
        input: Option<PathBuf>,
    },
    /// Measure a user's neutral pose and comfortable ranges and write a calibration file.
    Calibrate(CalibrateArgs),
    /// Manage calibrations on the running daemon.
    #[command(subcommand)]
    Calibration(CalibrationCommand),
    /// Manage the rig of the running daemon.
    #[command(subcommand)]
    Rig(RigCommand),
    /// Set the daemon's jitter filter (none, lowpass:cutoff_hz=8,
    /// one-euro:min_cutoff=1,beta=0.007,d_cutoff=1).
    Filter {
        /// Filter spec.
        spec: String,
    },
    /// Put a labelled marker into the current recording.
    Mark {
        /// Marker text (at most 256 bytes).
        label: String,
    },
    /// Start or stop recording a take.
    #[command(subcommand)]
    Record(RecordCommand),
    /// Follow the mocap stage's capture triggers, or pause following (frondd must listen for
    /// them: --triggers or [triggers] listen). Paused, a CaptureStart is counted and ignored; a
    /// CaptureStop still ends a take a trigger started.
    Triggers {
        /// follow or pause.
        #[arg(value_enum)]
        mode: TriggerMode,
    },
    /// List, export and repair recorded takes.
    #[command(subcommand)]
    Take(TakeCommand),
    /// Loop a recorded take on the live pose stream (the global element), or --stop.
    Play {
        /// Take name.
        take: Option<String>,
        /// Stop looping.
        #[arg(long, conflicts_with = "take")]
        stop: bool,
        /// Seed of the loop's random jumps.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Field playback in the daemon ("Interactive authoring", section 6.2).
    #[command(subcommand)]
    Field(FieldCommand),
    /// The simulated plant ("Physically-based Driven Tree Animations", section 4) in the
    /// daemon, blown by the hand.
    #[command(subcommand)]
    Sim(crate::graph_live::SimCommand),
    /// Plants walking a motion graph in the daemon ("Physically-based Driven Tree Animations",
    /// section 6), directed live.
    #[command(subcommand)]
    Graph(crate::graph_live::GraphCommand),
    /// Steer the playing field from the keyboard: arrows set the force direction, + and - its
    /// strength, q quits ("Interactive authoring", section 6.3). A wrist swipe steers it too.
    Control,
    /// Guided procedural motion on the live mapping ("Interactive authoring", Eq. 8):
    /// `sigma=S1,S2,S3;sg=G1,G2,G3` (seconds; gains), or `off`.
    Guided {
        /// Spec or `off`.
        spec: String,
    },
    /// Start the daemon on the virtual glove, show live status, record a take, stop everything.
    /// The daemon gets a private socket directory (--socket-dir is not used); the take goes to
    /// --takes-dir. Ctrl-C stops the recording and the daemon before exiting.
    Demo {
        /// Seconds to record.
        #[arg(long, default_value_t = 5.0, value_name = "N")]
        seconds: f64,
        /// Take name [default: demo-<unix time>].
        #[arg(long, value_name = "NAME")]
        name: Option<String>,
        /// After the take: keep the daemon on the virtual glove and the console running (the
        /// plant moving live in the browser) for this many seconds [default: until Ctrl-C];
        /// 0 ends at once (scripts, CI).
        #[arg(long, value_name = "SECONDS")]
        stay: Option<f64>,
    },
    /// Measure frond's speed, each figure against a baseline measured in the same run (loop
    /// lateness, glove-to-subscriber latency, tick cost, highest rate, daemon CPU/RSS, motion
    /// toolkit and exporters) and say whether each target holds.
    Bench(BenchArgs),
    /// Check what a stage set-up needs (daemon, socket directory, glove node and permissions,
    /// udev rule, frond group, FUSE, realtime limits, the service, the exporters) and say how to
    /// fix each problem. Exit status 1 when something needs fixing.
    Doctor {
        /// One JSON object: {"healthy", "checks": [{"name", "verdict", "found", "fix"}]}.
        #[arg(long)]
        json: bool,
    },
    /// Print a shell completion script for frond (bash, zsh, fish, elvish, powershell), e.g.
    /// `frond completions bash > /etc/bash_completion.d/frond`.
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
    /// Write frond's man pages (frond.1 and one per command, frond-take-export.1 ...) into DIR.
    Man {
        /// Directory to write them to (created if missing).
        #[arg(short = 'o', long = "output", value_name = "DIR")]
        dir: std::path::PathBuf,
    },
    /// Run the daemon on the virtual glove under faults (unplugs, corrupt reports, a clock jump,
    /// a SIGSTOP pause, a full disk under the recording, slow and reconnecting subscribers) for
    /// a while, then check it held up and print the figures. Needs /dev/fuse and root (the
    /// glove's hidraw node, the tmpfs the takes fill), and frondd and frond-vhid beside frond or
    /// on PATH. Exit status 1 when a check fails.
    Soak {
        /// How long to run, seconds (at least 20).
        #[arg(long, default_value_t = 60.0, value_name = "SECONDS")]
        duration: f64,
        /// Print the figures as JSON.
        #[arg(long)]
        json: bool,
        /// Seed of the glove's fault injection and the exporter's restart pattern.
        #[arg(long, default_value_t = 0x5EED, value_name = "N")]
        seed: u64,
    },
}

/// `frond calibration ...`
#[derive(Debug, Subcommand)]
pub enum CalibrationCommand {
    /// Send a calibration file to the daemon, which applies it live.
    Apply {
        /// Calibration file (TOML).
        file: PathBuf,
    },
}

/// `frond rig ...`
#[derive(Debug, Subcommand)]
pub enum RigCommand {
    /// Send a rig to the daemon, which switches to it live (subscribers are told).
    Set {
        /// Rig: an embedded name (grass, flower, shrub) or a rig file (TOML).
        file: PathBuf,
    },
}

/// `frond triggers MODE`
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum TriggerMode {
    /// A CaptureStart starts a take, a CaptureStop stops it.
    Follow,
    /// Starts are heard and counted, not followed.
    Pause,
}

/// `frond record ...`
#[derive(Debug, Subcommand)]
pub enum RecordCommand {
    /// Start recording a take NAME into the daemon's takes directory. With --stage: record
    /// every source of a stage over Zenoh, from this host, each to its own take NAME-<source>
    /// in --takes-dir, on one timeline (see `frond take export --align`), until Ctrl-C or --for.
    Start(crate::stage_record::RecordStart),
    /// Stop the current recording and print the take's path and frame count.
    Stop,
    /// Record a secondary layer ("Interactive authoring", section 5.3): the hand animates the rig's element
    /// LAYER (e.g. leaf) while GLOBAL, the whole plant's take, loops on the stream for reference.
    Layer {
        /// New take name.
        name: String,
        /// Secondary element of the rig (e.g. leaf, petal).
        #[arg(long)]
        layer: String,
        /// Global take to loop meanwhile.
        #[arg(long = "over")]
        over: Option<String>,
        /// Seed of the loop's random jumps.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

/// `frond field ...`
#[derive(Debug, Subcommand)]
pub enum FieldCommand {
    /// Play a field (field.json from `frond take field`) of a looped take in the daemon.
    Start {
        /// Take name (in the takes directory).
        #[arg(long)]
        take: String,
        /// field.json file.
        #[arg(long)]
        field: PathBuf,
        /// Plants published on the pose stream (1..=64).
        #[arg(long, default_value_t = 16)]
        plants: u16,
        /// Seed of the loop's random jumps.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// The plants' rig: an embedded rig's name or a rig file [default: the active rig].
        #[arg(long, value_name = "NAME|FILE")]
        rig: Option<PathBuf>,
        /// The field's stage name [default: field]: fields under different names play side by
        /// side (a meadow of grass and flowers is a field of each rig), steered as one.
        #[arg(long, value_name = "NAME")]
        name: Option<String>,
    },
    /// Stop field playback: every field, or the one named.
    Stop {
        /// The field's stage name [default: every field].
        #[arg(long, value_name = "NAME")]
        name: Option<String>,
    },
    /// One control: left, right, up, down, stronger (+), weaker (-), to every field or the one
    /// named.
    Key {
        /// Key name.
        key: String,
        /// The field's stage name [default: every field].
        #[arg(long, value_name = "NAME")]
        name: Option<String>,
    },
}

/// `frond take ...`
#[derive(Debug, Subcommand)]
pub enum TakeCommand {
    /// List the takes in the takes directory.
    List {
        /// JSON array instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Print a take's poses (main skeleton), one JSON object a line: {"t":..,"joints":[..]}.
    /// Held frames (repeats of the previous pose) are skipped unless --include-held is given, so
    /// each line is one device sample with its recorded time. With --fps the poses are
    /// resampled by linear interpolation and `t` counts from 0.
    Export(crate::take_export::ExportArgs),
    /// Cut a torn tail off a take (after a crash) and close it, keeping every complete frame.
    /// Refuses takes modified in the last few seconds, which may still be recording.
    Repair {
        /// Take name (or a path to a .take file).
        name: String,
    },
    /// The motion toolkit ("Interactive authoring"; simulate, graph and walk: "Physically-based
    /// Driven Tree Animations"): import, resample, filter, splice, loop, field, retime, guided,
    /// align, simulate, graph, walk.
    #[command(flatten)]
    Tool(crate::take_tools::TakeTool),
}
