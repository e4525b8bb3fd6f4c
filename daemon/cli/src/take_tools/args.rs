//! `frond take` toolkit's command-line syntax (clap derive): what each subcommand takes.
//! Parsing only; [`super::run`] checks the values and does the work.

use std::path::PathBuf;

use clap::{Args, Subcommand};

/// Where a command's result goes.
#[derive(Debug, Clone, Args)]
pub struct Output {
    /// Name of the take to write [default: NAME-<command>].
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    pub output: Option<String>,
    /// Print the result's poses as JSON Lines on stdout instead of writing a take.
    #[arg(long)]
    pub jsonl: bool,
    /// Replace an existing take of the same name, and go past the output limit of 1,080,000
    /// frames (10 hours at 30 FPS; 16,777,216 even with --force).
    #[arg(long)]
    pub force: bool,
    /// Frame rate to work at.
    #[arg(long, default_value_t = 30.0, value_name = "FPS")]
    pub fps: f64,
}

/// The toolkit's `frond take` subcommands.
#[derive(Debug, Subcommand)]
pub enum TakeTool {
    /// Make a take from a JSONL file: hand samples (mapped with --rig, as `frond map`) or poses
    /// (as written by `frond take export --jsonl`).
    Import {
        /// JSONL file.
        file: PathBuf,
        /// Take name to write.
        name: String,
        /// Rig for hand samples: an embedded name or a rig file (TOML) [default: a blade with
        /// unit scales].
        #[arg(long, value_name = "NAME|FILE")]
        rig: Option<PathBuf>,
        /// Calibration file for hand samples.
        #[arg(long, value_name = "FILE")]
        calibration: Option<PathBuf>,
        /// Jitter filter for hand samples [default: the rig's].
        #[arg(long, value_name = "SPEC")]
        filter: Option<String>,
        /// What the file holds: auto, hand or pose.
        #[arg(long, default_value = "auto", value_name = "KIND")]
        kind: String,
        /// Print the poses as JSON Lines instead of writing the take.
        #[arg(long)]
        jsonl: bool,
        /// Replace an existing take of the same name.
        #[arg(long)]
        force: bool,
    },
    /// The simulated plant of seed 003 (section 4): RIG's mass-spring plant (its `[sim]` table,
    /// or --sim FILE's) blown by --wind from rest for --duration seconds, sampled at --fps, as
    /// take NAME. --wind: `speed=S,dir=DEG,gust=G,seed=N[,until=S]` (m/s; 0 deg towards +X, 90
    /// towards +Z; gust 0..1).
    Simulate {
        /// Take name to write.
        name: String,
        /// Rig: an embedded name or a rig file (TOML).
        #[arg(long, value_name = "NAME|FILE")]
        rig: PathBuf,
        /// A TOML file with a `[sim]` table replacing the rig's.
        #[arg(long, value_name = "FILE")]
        sim: Option<PathBuf>,
        /// The wind.
        #[arg(long, value_name = "SPEC")]
        wind: String,
        /// Seconds to simulate.
        #[arg(long, value_name = "S")]
        duration: f64,
        /// Frames per second of the take.
        #[arg(long, default_value_t = 30.0, value_name = "FPS")]
        fps: f64,
        /// Also write every frame's node positions, velocities and forces (JSON Lines).
        #[arg(long, value_name = "FILE.jsonl")]
        states: Option<PathBuf>,
        /// Print the poses as JSON Lines instead of writing the take.
        #[arg(long)]
        jsonl: bool,
        /// Replace an existing take (and states file) of the same name.
        #[arg(long)]
        force: bool,
    },
    /// A motion graph of seed 003 (section 5) for one control point of take NAME: the backbone,
    /// transitions where the point passes within one step of itself going forwards (extended
    /// by --extend samples each side), pruned to one closed, strongly connected graph. Writes
    /// NAME.graph.json (or -o FILE).
    Graph(crate::take_graph::Graph),
    /// A walk on a motion graph of take NAME (seed 003, section 6): random, towards a ground-
    /// plane direction (--goal-dir DEG: 0 towards +X, 90 towards +Z), or to a pose (--goal-pose
    /// frame=N or 12 comma-separated angles). --plants N walks N plants, each with seed + i,
    /// into takes OUT, OUT-plant1, OUT-plant2, ...
    Walk(crate::take_graph::Walk),
    /// Resample every layer to --fps (poses and hand samples, linear interpolation).
    Resample {
        /// Take name.
        name: String,
        #[command(flatten)]
        out: Output,
    },
    /// Post-processing low-pass of a layer (zero phase: forwards then backwards).
    Filter {
        /// Take name.
        name: String,
        /// lowpass, one-euro, or a full spec such as lowpass:cutoff_hz=4.
        #[arg(long, value_name = "SPEC")]
        filter: String,
        /// Layer to filter (global, a layer name or number).
        #[arg(long, default_value = "global", value_name = "LAYER")]
        layer: String,
        #[command(flatten)]
        out: Output,
    },
    /// Re-author frames FROM..=TO of BASE with the take NEW, blending N frames at each boundary.
    /// FROM and TO are frame numbers at --fps or marker labels.
    Splice {
        /// Base take.
        base: String,
        /// First replaced frame (number or marker label).
        #[arg(long, value_name = "F0")]
        from: String,
        /// Last replaced frame (number or marker label).
        #[arg(long, value_name = "F1")]
        to: String,
        /// The re-authored take.
        #[arg(long = "with", value_name = "NEW")]
        with: String,
        /// Frames blended at each boundary.
        #[arg(long, default_value_t = 5, value_name = "N")]
        blend: usize,
        #[command(flatten)]
        out: Output,
    },
    /// Endless animation by looping (seed 000, Eq. 5): transition frames, then seeded playback.
    Loop {
        /// Take name.
        name: String,
        /// Regions L.
        #[arg(long, default_value_t = 3, value_name = "L")]
        regions: usize,
        /// Transition frames per region P.
        #[arg(long, default_value_t = 2, value_name = "P")]
        per_region: usize,
        /// Comparison window half-width D, frames.
        #[arg(long, default_value_t = 2, value_name = "D")]
        window: usize,
        /// Random seed.
        #[arg(long, default_value_t = 0, value_name = "S")]
        seed: u64,
        /// Length of the output, seconds.
        #[arg(long, default_value_t = 60.0, value_name = "SECONDS")]
        duration: f64,
        /// Jumps between frames further apart than this (degrees) get interpolated frames.
        #[arg(long, default_value_t = 8.0, value_name = "DEG")]
        threshold: f64,
        /// Print {"pivot":N,"transitions":[...]} on stdout and write nothing.
        #[arg(long)]
        explain: bool,
        #[command(flatten)]
        out: Output,
    },
    /// Lay out a field of plants playing the take with propagation delays (Eq. 6-7) and write
    /// field.json.
    Field {
        /// Take name (a looped take, `frond take loop`, long enough for the playback).
        name: String,
        /// Grid rows (across the force).
        #[arg(long, value_name = "R")]
        rows: usize,
        /// Grid columns (along the force).
        #[arg(long, value_name = "C")]
        cols: usize,
        /// Cell size, metres.
        #[arg(long, value_name = "METRES")]
        cell: f64,
        /// Propagation speed V_M, m/s.
        #[arg(long, value_name = "V_M")]
        speed: f64,
        /// Force heading, degrees (0 = +X, 90 = -Z).
        #[arg(long, default_value_t = 0.0, value_name = "DEG", allow_negative_numbers = true)]
        direction: f64,
        /// Fraction of cells that get a plant.
        #[arg(long, default_value_t = 1.0, value_name = "F")]
        density: f64,
        /// Random seed.
        #[arg(long, default_value_t = 0, value_name = "S")]
        seed: u64,
        /// Frame rate the take is sampled at.
        #[arg(long, default_value_t = 30.0, value_name = "FPS")]
        fps: f64,
        /// Output file.
        #[arg(short = 'o', long = "output", value_name = "FILE")]
        output: PathBuf,
    },
    /// Motion speed, scale, bend rotation and rigidity delays (seed 000, section 6.3).
    Retime {
        /// Take name.
        name: String,
        /// Motion speed K.
        #[arg(long, default_value_t = 1.0, value_name = "K")]
        speed: f64,
        /// Motion scale.
        #[arg(long, default_value_t = 1.0, value_name = "K", allow_negative_numbers = true)]
        scale: f32,
        /// Bend direction rotation, degrees.
        #[arg(long, default_value_t = 0.0, value_name = "DEG", allow_negative_numbers = true)]
        rotate: f64,
        /// Rigidity delays of joints 1..3, seconds.
        #[arg(long, default_value = "0,0,0", value_name = "D1,D2,D3")]
        delay: String,
        #[command(flatten)]
        out: Output,
    },
    /// Guided procedural motion (Eq. 8): upper joints follow the root with thumb-controlled delays.
    Guided {
        /// Take name.
        name: String,
        /// sigma_1..3, seconds.
        #[arg(long, value_name = "S1,S2,S3")]
        sigma: String,
        /// s_g(1..3).
        #[arg(long, default_value = "1,1,1", value_name = "G1,G2,G3")]
        sg: String,
        /// Range of the top thumb joint, degrees [default: the rig's, else 60].
        #[arg(long, value_name = "DEG")]
        thumb_range: Option<f32>,
        /// Rig giving the thumb range: an embedded name or a rig file (TOML).
        #[arg(long, value_name = "NAME|FILE")]
        rig: Option<PathBuf>,
        #[command(flatten)]
        out: Output,
    },
    /// Align a secondary take with a global one (section 6.5); writes a layered take: the
    /// global layer plus the aligned secondary as layer --layer.
    Align {
        /// Global take.
        global: String,
        /// Secondary take (its global layer is used).
        secondary: String,
        /// Subsequence length, seconds.
        #[arg(long, default_value_t = 2.0, value_name = "SECONDS")]
        window: f64,
        /// Random seed.
        #[arg(long, default_value_t = 0, value_name = "S")]
        seed: u64,
        /// Name of the secondary layer in the output.
        #[arg(long, default_value = "leaf", value_name = "NAME")]
        layer: String,
        /// Print the per-subsequence ratios as JSON on stderr.
        #[arg(long)]
        explain: bool,
        #[command(flatten)]
        out: Output,
    },
}
