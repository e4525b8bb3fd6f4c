//! `frond take` toolkit's command-line syntax (clap derive): what each subcommand takes.
//! Parsing only; the toolkit's commands check the values and do the work.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use crate::take_io::Output;

/// The toolkit's `frond take` subcommands.
#[derive(Debug, Subcommand)]
pub enum TakeTool {
    /// Make a take from a JSONL file: hand samples (mapped with --rig, as `frond map`) or poses
    /// (as written by `frond take export --jsonl`).
    Import(ImportArgs),
    /// The simulated plant of "Physically-based Driven Tree Animations" (section 4): RIG's
    /// mass-spring plant (its `[sim]` table, or --sim FILE's) blown by --wind from rest for
    /// --duration seconds, sampled at --fps, as take NAME. --wind:
    /// `speed=S,dir=DEG,gust=G,seed=N[,until=S]` (m/s; 0 deg towards +X, 90 towards +Z; gust
    /// 0..1).
    Simulate(crate::take_sim::SimulateArgs),
    /// A motion graph ("Physically-based Driven Tree Animations", section 5) for one control
    /// point of take NAME: the backbone, transitions where the point passes within one step of
    /// itself going forwards (extended by --extend samples each side), pruned to one closed,
    /// strongly connected graph. Writes NAME.graph.json (or -o FILE).
    Graph(crate::take_graph::Graph),
    /// A walk on a motion graph of take NAME ("Physically-based Driven Tree Animations", section
    /// 6): random, towards a ground-plane direction (--goal-dir DEG: 0 towards +X, 90 towards
    /// +Z), or to a pose (--goal-pose frame=N or 12 comma-separated angles). --plants N walks N
    /// plants, each with seed + i, into takes OUT, OUT-plant1, OUT-plant2, ...
    Walk(crate::take_graph::Walk),
    /// Resample every layer to --fps (poses and hand samples, linear interpolation).
    Resample(ResampleArgs),
    /// Post-processing low-pass of a layer (zero phase: forwards then backwards).
    Filter(FilterArgs),
    /// Re-author frames FROM..=TO of BASE with the take NEW, blending N frames at each boundary.
    /// FROM and TO are frame numbers at --fps or marker labels.
    Splice(SpliceArgs),
    /// Endless animation by looping ("Interactive authoring", Eq. 5): transition frames, then
    /// seeded playback.
    Loop(LoopArgs),
    /// Lay out a field of plants playing the take with propagation delays (Eq. 6-7) and write
    /// field.json.
    Field(FieldArgs),
    /// Motion speed, scale, bend rotation and rigidity delays ("Interactive authoring", section
    /// 6.3).
    Retime(RetimeArgs),
    /// Guided procedural motion (Eq. 8): upper joints follow the root with thumb-controlled delays.
    Guided(GuidedArgs),
    /// Align a secondary take with a global one (section 6.5); writes a layered take: the
    /// global layer plus the aligned secondary as layer --layer.
    Align(AlignArgs),
}

/// What `frond take import` was asked.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// JSONL file.
    pub file: PathBuf,
    /// Take name to write.
    pub name: String,
    /// Rig for hand samples: an embedded name or a rig file (TOML) [default: a blade with
    /// unit scales].
    #[arg(long, value_name = "NAME|FILE")]
    pub rig: Option<PathBuf>,
    /// Calibration file for hand samples.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Jitter filter for hand samples [default: the rig's].
    #[arg(long, value_name = "SPEC")]
    pub filter: Option<String>,
    /// What the file holds: auto, hand or pose.
    #[arg(long, default_value = "auto", value_name = "KIND")]
    pub kind: String,
    /// Print the poses as JSON Lines instead of writing the take.
    #[arg(long)]
    pub jsonl: bool,
    /// Replace an existing take of the same name.
    #[arg(long)]
    pub force: bool,
}

/// What `frond take resample` was asked.
#[derive(Debug, Args)]
pub struct ResampleArgs {
    /// Take name.
    pub name: String,
    #[command(flatten)]
    pub out: Output,
}

/// What `frond take filter` was asked.
#[derive(Debug, Args)]
pub struct FilterArgs {
    /// Take name.
    pub name: String,
    /// lowpass, one-euro, or a full spec such as lowpass:cutoff_hz=4.
    #[arg(long, value_name = "SPEC")]
    pub filter: String,
    /// Layer to filter (global, a layer name or number).
    #[arg(long, default_value = "global", value_name = "LAYER")]
    pub layer: String,
    #[command(flatten)]
    pub out: Output,
}

/// What `frond take splice` was asked.
#[derive(Debug, Args)]
pub struct SpliceArgs {
    /// Base take.
    pub base: String,
    /// First replaced frame (number or marker label).
    #[arg(long, value_name = "F0")]
    pub from: String,
    /// Last replaced frame (number or marker label).
    #[arg(long, value_name = "F1")]
    pub to: String,
    /// The re-authored take.
    #[arg(long = "with", value_name = "NEW")]
    pub with: String,
    /// Frames blended at each boundary.
    #[arg(long, default_value_t = 5, value_name = "N")]
    pub blend: usize,
    #[command(flatten)]
    pub out: Output,
}

/// What `frond take loop` was asked.
#[derive(Debug, Args)]
pub struct LoopArgs {
    /// Take name.
    pub name: String,
    /// Regions L.
    #[arg(long, default_value_t = 3, value_name = "L")]
    pub regions: usize,
    /// Transition frames per region P.
    #[arg(long, default_value_t = 2, value_name = "P")]
    pub per_region: usize,
    /// Comparison window half-width D, frames.
    #[arg(long, default_value_t = 2, value_name = "D")]
    pub window: usize,
    /// Random seed.
    #[arg(long, default_value_t = 0, value_name = "S")]
    pub seed: u64,
    /// Length of the output, seconds.
    #[arg(long, default_value_t = 60.0, value_name = "SECONDS")]
    pub duration: f64,
    /// Jumps between frames further apart than this (degrees) get interpolated frames.
    #[arg(long, default_value_t = 8.0, value_name = "DEG")]
    pub threshold: f64,
    /// Print {"pivot":N,"transitions":[...]} on stdout and write nothing.
    #[arg(long)]
    pub explain: bool,
    #[command(flatten)]
    pub out: Output,
}

/// What `frond take field` was asked.
#[derive(Debug, Args)]
pub struct FieldArgs {
    /// Take name (a looped take, `frond take loop`, long enough for the playback).
    pub name: String,
    /// Grid rows (across the force).
    #[arg(long, value_name = "R")]
    pub rows: usize,
    /// Grid columns (along the force).
    #[arg(long, value_name = "C")]
    pub cols: usize,
    /// Cell size, metres.
    #[arg(long, value_name = "METRES")]
    pub cell: f64,
    /// Propagation speed V_M, m/s.
    #[arg(long, value_name = "V_M")]
    pub speed: f64,
    /// Force heading, degrees (0 = +X, 90 = -Z).
    #[arg(long, default_value_t = 0.0, value_name = "DEG", allow_negative_numbers = true)]
    pub direction: f64,
    /// Fraction of cells that get a plant.
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    pub density: f64,
    /// Random seed.
    #[arg(long, default_value_t = 0, value_name = "S")]
    pub seed: u64,
    /// Frame rate the take is sampled at.
    #[arg(long, default_value_t = 30.0, value_name = "FPS")]
    pub fps: f64,
    /// Leave the plants out of the file: every reader makes them again from the parameters
    /// (as a live field's subscribers do), so a field of thousands of plants stays small enough
    /// for `frond field start`, whose request may be at most 256 KiB.
    #[arg(long)]
    pub compact: bool,
    /// Output file.
    #[arg(short = 'o', long = "output", value_name = "FILE")]
    pub output: PathBuf,
}

/// What `frond take retime` was asked.
#[derive(Debug, Args)]
pub struct RetimeArgs {
    /// Take name.
    pub name: String,
    /// Motion speed K.
    #[arg(long, default_value_t = 1.0, value_name = "K")]
    pub speed: f64,
    /// Motion scale.
    #[arg(long, default_value_t = 1.0, value_name = "K", allow_negative_numbers = true)]
    pub scale: f32,
    /// Bend direction rotation, degrees.
    #[arg(long, default_value_t = 0.0, value_name = "DEG", allow_negative_numbers = true)]
    pub rotate: f64,
    /// Rigidity delays of joints 1..3, seconds.
    #[arg(long, default_value = "0,0,0", value_name = "D1,D2,D3")]
    pub delay: String,
    #[command(flatten)]
    pub out: Output,
}

/// What `frond take guided` was asked.
#[derive(Debug, Args)]
pub struct GuidedArgs {
    /// Take name.
    pub name: String,
    /// sigma_1..3, seconds.
    #[arg(long, value_name = "S1,S2,S3")]
    pub sigma: String,
    /// s_g(1..3).
    #[arg(long, default_value = "1,1,1", value_name = "G1,G2,G3")]
    pub sg: String,
    /// Range of the top thumb joint, degrees [default: the rig's, else 60].
    #[arg(long, value_name = "DEG")]
    pub thumb_range: Option<f32>,
    /// Rig giving the thumb range: an embedded name or a rig file (TOML).
    #[arg(long, value_name = "NAME|FILE")]
    pub rig: Option<PathBuf>,
    #[command(flatten)]
    pub out: Output,
}

/// What `frond take align` was asked.
#[derive(Debug, Args)]
pub struct AlignArgs {
    /// Global take.
    pub global: String,
    /// Secondary take (its global layer is used).
    pub secondary: String,
    /// Subsequence length, seconds.
    #[arg(long, default_value_t = 2.0, value_name = "SECONDS")]
    pub window: f64,
    /// Random seed.
    #[arg(long, default_value_t = 0, value_name = "S")]
    pub seed: u64,
    /// Name of the secondary layer in the output.
    #[arg(long, default_value = "leaf", value_name = "NAME")]
    pub layer: String,
    /// Print the per-subsequence ratios as JSON on stderr.
    #[arg(long)]
    pub explain: bool,
    #[command(flatten)]
    pub out: Output,
}
