//! Command-line arguments of `frond-warp`, parsed raw (numbers as written, negative ones too) and
//! validated (`cli::validate`) into [`SceneParams`](crate::params::SceneParams) so that every bad
//! parameter is reported at once, by name, with its allowed range.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

use crate::params::Checker;

mod validate;

const ABOUT: &str = "Animate vegetation in a picture with the wind, driven by the hand.

The method is \"A Simple Method to Animate Vegetation in Images Using Simulation-guided
Grid-based Warping\" (docs/methods.md names the four papers frond follows).

A picture's vegetation layers (masks cut out of the picture, or RGBA images with alpha) sway over
the background (given, or inpainted where masks fully cover the picture). Per frame:
  1. wind: stable fluids on a coarse grid (--fluid-grid, default 64), open boundaries; forces of a
     direction (--direction), strength in [0, 1] (--strength) and interval between injections
     (--interval) at a source (--source border|X,Y, --radius);
  2. vegetation: a damped wave simulation of each layer's velocity (Eq. 3-4), pulled towards the
     wind (--stiffness), damping --gamma in [0.01, 1], wave speed --c in [1, 10];
  3. warp: a grid of --cell pixels over each layer, corners moved against the velocity by
     lambda * R * V_p * dt cells (Eq. 5-7; --lambda-x/--lambda-y, R = (l/h)^r with --rigidity r
     in [0, 10] and --horizon bottom|top|none), each pixel mapped bilinearly inside its cell
     (Eq. 8) and filtered bilinearly; an optional --scale-map (grey) scales lambda per pixel.
Pixels outside every layer never change (unless --sway-margin lets layers grow).

Live: `serve` subscribes to frondd (--socket-dir, env FROND_SOCKET_DIR): the root joint's bend
sets the wind direction and strength (full at 15.075 degrees, the simulated plant's bend in a
10 m/s wind), the sway rate the interval. Without a daemon it falls back to a procedural wind
with the page's settings and says so, or with --wind-sim to the simulation wind of
\"Physically-based Driven Tree Animations\" (speed=S,dir=DEG,gust=G,seed=N[,until=S], as frond
take simulate --wind; strength = speed / 10 m/s); render takes --wind-sim too.
`serve --mode cage` (\"Sketch-based shape-preserving tree animations\") shows the layer's cage
tree: draw a sketch on the page with the pointer and the plant morphs towards it (Escape resets);
with no sketch the live hand bends the plant through its skinned crown cage.

Examples:
  frond-warp make-samples rig-files/images
  frond-warp render --image rig-files/images/grass.png --layer rig-files/images/grass-mask.png \\
      --scale-map rig-files/images/grass-scale.png --frames 90 --fps 30 -o grass.gif
  frond-warp render --image rig-files/images/shrub-background.png --layer rig-files/images/shrub.png \\
      --horizon bottom --rigidity 1 --sway-margin 6 --frames 60 -o frames/
  frond-warp serve --image rig-files/images/grass.png --layer rig-files/images/grass-mask.png \\
      --listen 127.0.0.1:8080
  frond-warp serve --mode cage --image rig-files/images/shrub-background.png \\
      --layer rig-files/images/shrub.png
  frond-warp bench --json";

/// `frond-warp`.
#[derive(Debug, Parser)]
#[command(
    name = "frond-warp",
    version,
    about = "Hand-driven vegetation-in-the-wind preview (grid-based warping)",
    long_about = ABOUT,
    // `--log-level` before or after the subcommand.
    mut_arg("log_level", |a| a.global(true))
)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
    /// `--log-level LEVEL` (what `frond-warp serve` logs of its daemon connection).
    #[command(flatten)]
    pub log: frond_binmain::LogArgs,
    /// `--man DIR`, `--completions SHELL`: handled by `DocsArgs::early` before parsing.
    #[command(flatten)]
    pub docs: frond_binmain::DocsArgs,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render an animation offline to a GIF, an animated WebP or a directory of PNGs.
    Render(RenderArgs),
    /// Serve the live preview on a web page.
    Serve(ServeArgs),
    /// Write the procedurally drawn sample pictures into DIR.
    MakeSamples {
        /// Output directory (created if needed).
        dir: PathBuf,
    },
    /// Time the warp of one frame (single thread) and the full pipeline.
    Bench(BenchArgs),
    /// Morph a layer towards a sketch, keeping its shape (the sketch-based paper, section 5).
    #[command(long_about = MORPH_ABOUT)]
    Morph(MorphArgs),
    /// Multiscale cages of a vegetation layer (the sketch-based paper): build them, inspect their
    /// coordinates.
    #[command(subcommand)]
    Cage(CageCommand),
}

/// `frond-warp cage ...`.
#[derive(Debug, Subcommand)]
pub enum CageCommand {
    /// Build the multiscale cage tree of a layer (crowns, lobes inside them) into cage.json.
    #[command(long_about = CAGE_BUILD_ABOUT)]
    Build(CageBuildArgs),
    /// Print the mean value coordinates of points for one cage, as JSON.
    Coords(CageCoordsArgs),
}

const CAGE_BUILD_ABOUT: &str = "Build the multiscale cage tree of a vegetation layer.

The cages are those of \"Sketch-based shape-preserving tree animations\", section 5.2.

Each 4-connected part of the layer's matte (a greyscale mask, or an RGBA image's alpha) holding at
least --min-part of the foliage is a crown (a root cage); a cage's foliage is split into --lobes
compact clusters, each outlined and clipped inside it, down to --levels levels. Outlines are traced
along pixel edges, simplified and resampled to --vertices vertices. The file (cage.json, documented
in exporters/warp/README.md) lists every cage with its parent, kind and vertices in image pixels.

Example:
  frond-warp cage build --layer rig-files/images/shrub.png -o shrub-cage.json";

const MORPH_ABOUT: &str = "Morph a vegetation layer towards a sketch, keeping its shape.

The method is \"Sketch-based shape-preserving tree animations\", section 5.

The layer's multiscale cage tree (--cage, or built from the layer as `cage build` does) carries the
picture: the sketched crown moves to the sketch's outline (closed sketch) or has the oversketched
stretch replaced (open sketch), finer cages follow by mean value coordinates and Eq. 1, lobes
stretch over parts of their parent they leave uncovered (off: --no-adapt) and lobes mostly outside
a closed sketch fade out (off: --no-prune). The pixels move with the grid-based warp's remap. --report
writes the discrete Frechet distance of each frame's outline to the reference in-between.

sketch.json: {\"version\":1,\"closed\":true|false,\"points\":[[x,y],...]} in image pixels.

Example:
  frond-warp morph --image rig-files/images/shrub-background.png --layer rig-files/images/shrub.png \\
      --sketch heart.json --frames 30 -o morph.webp --report quality.json";

/// `frond-warp morph`.
#[derive(Debug, Clone, Args)]
pub struct MorphArgs {
    /// The picture (PNG, JPEG, GIF or WebP).
    #[arg(long, value_name = "IMG")]
    pub image: PathBuf,
    /// The vegetation layer that morphs: a mask (cut out of the picture) or an RGBA image.
    #[arg(long, value_name = "MASK_OR_RGBA")]
    pub layer: PathBuf,
    /// Background under the layer (default: the picture, inpainted under the mask).
    #[arg(long, value_name = "BG")]
    pub background: Option<PathBuf>,
    /// The layer's cage tree (cage.json; default: built from the layer).
    #[arg(long, value_name = "FILE")]
    pub cage: Option<PathBuf>,
    /// The sketch (sketch.json).
    #[arg(long, value_name = "FILE")]
    pub sketch: PathBuf,
    /// Frames, the first the picture and the last the target.
    #[arg(long, default_value_t = 30, allow_negative_numbers = true)]
    pub frames: i64,
    /// Frame rate of the animation.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub fps: f32,
    /// Output: FILE.gif, FILE.webp, or DIR/ for PNG frames.
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    pub output: PathBuf,
    /// Write the quality report (JSON: t, frechet_px per frame, crown, pruned) here.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// No self-adaptive cages (section 5.4.1).
    #[arg(long)]
    pub no_adapt: bool,
    /// No pruning (section 5.4.2).
    #[arg(long)]
    pub no_prune: bool,
    /// No progress bar or summary.
    #[arg(long)]
    pub quiet: bool,
}

/// `frond-warp cage build`.
#[derive(Debug, Clone, Args)]
pub struct CageBuildArgs {
    /// The vegetation layer: a greyscale mask, or an RGBA image (its alpha is the matte).
    #[arg(long, value_name = "MASK_OR_RGBA")]
    pub layer: PathBuf,
    /// Levels of cages: 1 = crowns only; 3 = crown, outer lobes, inner lobes.
    #[arg(long, default_value_t = 3, value_name = "N")]
    pub levels: usize,
    /// Vertices per cage.
    #[arg(long, default_value_t = 64, value_name = "V")]
    pub vertices: usize,
    /// Lobes each internal cage is split into.
    #[arg(long, default_value_t = 3, value_name = "K")]
    pub lobes: usize,
    /// Matte level (0-255) counted as vegetation.
    #[arg(long, default_value_t = 128, value_name = "LEVEL")]
    pub threshold: u8,
    /// Smallest part that is a crown, as a fraction of all the foliage.
    #[arg(long = "min-part", default_value_t = 0.02, value_name = "FRACTION")]
    pub min_part: f64,
    /// Output file (cage.json); `-` for standard output.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
}

/// `frond-warp cage coords`.
#[derive(Debug, Clone, Args)]
pub struct CageCoordsArgs {
    /// The cage file.
    #[arg(long, value_name = "FILE")]
    pub cage: PathBuf,
    /// The cage's id in the file.
    #[arg(long, value_name = "N")]
    pub id: u32,
    /// A point `X,Y` in image pixels; repeat for several.
    #[arg(long = "at", value_name = "X,Y", required = true, allow_hyphen_values = true)]
    pub at: Vec<String>,
}

/// The picture and its layers.
#[derive(Debug, Clone, Args)]
pub struct SceneArgs {
    /// The picture (PNG, JPEG, GIF or WebP).
    #[arg(long, value_name = "IMG")]
    pub image: PathBuf,
    /// A vegetation layer: a mask (greyscale / no alpha: cut out of the picture) or an RGBA image
    /// with alpha. Repeat for several layers, back to front.
    #[arg(long = "layer", value_name = "MASK_OR_RGBA")]
    pub layers: Vec<PathBuf>,
    /// Background under the layers (default: the picture, inpainted under fully masked areas).
    #[arg(long, value_name = "BG")]
    pub background: Option<PathBuf>,
    /// Greyscale map of |lambda| per pixel (white = full motion).
    #[arg(long, value_name = "MAP")]
    pub scale_map: Option<PathBuf>,
}

/// Simulation and warp parameters (raw; see [`SimArgs::to_params`]).
#[derive(Debug, Clone, Args)]
#[command(next_help_heading = "Wind and vegetation")]
pub struct SimArgs {
    /// Wind direction in degrees: 0 blows to the right, 90 down [-360, 360].
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub direction: f32,
    /// Wind strength [0, 1].
    #[arg(long, default_value_t = 0.6, allow_negative_numbers = true)]
    pub strength: f32,
    /// Seconds between wind injections (0 = continuous) [0, 10].
    #[arg(long, default_value_t = 0.8, allow_negative_numbers = true)]
    pub interval: f32,
    /// Wind source: `border` (the upwind border) or a point `X,Y` in fractions of the picture.
    #[arg(long, default_value = "border", allow_negative_numbers = true)]
    pub source: String,
    /// Radius of a point source / depth of the border source, fraction of the picture [0.01, 0.5].
    #[arg(long, default_value_t = 0.08, allow_negative_numbers = true)]
    pub radius: f32,
    /// Wind grid cells per side [8, 256].
    #[arg(long, default_value_t = 64, allow_negative_numbers = true)]
    pub fluid_grid: i64,
    /// Wind viscosity [0, 0.01].
    #[arg(long, default_value_t = 0.0001, allow_negative_numbers = true)]
    pub viscosity: f32,
    /// Damping gamma of the vegetation [0.01, 1] (larger: more rigid).
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
    pub gamma: f32,
    /// Wave speed c [1, 10] (wave-grid cells per second).
    #[arg(long, default_value_t = 4.0, allow_negative_numbers = true)]
    pub c: f32,
    /// How fast the vegetation follows the wind, Hz [0.1, 10].
    #[arg(long, default_value_t = 1.2, allow_negative_numbers = true)]
    pub stiffness: f32,
    /// Rigidity r [0, 10] of R = (l/h)^r (Eq. 6).
    #[arg(long, default_value_t = 1.5, allow_negative_numbers = true)]
    pub rigidity: f32,
    /// Where the vegetation is fixed: bottom (roots visible), top (field seen from above), none.
    #[arg(long, default_value = "bottom")]
    pub horizon: String,
    /// Grid cell size s_x = s_y in pixels [2, 256].
    #[arg(long, default_value_t = 16, allow_negative_numbers = true)]
    pub cell: i64,
    /// Scale factor lambda_x [0, 1000] (Eq. 5).
    #[arg(long, default_value_t = 12.0, allow_negative_numbers = true)]
    pub lambda_x: f32,
    /// Scale factor lambda_y [0, 1000] (Eq. 5).
    #[arg(long, default_value_t = 4.0, allow_negative_numbers = true)]
    pub lambda_y: f32,
    /// Wave grid cells along the picture's longer side [4, 256].
    #[arg(long, default_value_t = 48, allow_negative_numbers = true)]
    pub wave_grid: i64,
    /// Pixels a layer may sway beyond its mask [0, 64].
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub sway_margin: i64,
    /// Per-layer override `N:key=value[,key=value]` (keys: gamma, c, stiffness, rigidity, horizon,
    /// cell, lambda_x, lambda_y, wave_grid, sway_margin); N counts layers from 0. Repeatable.
    #[arg(long = "layer-set", value_name = "N:K=V,...")]
    pub layer_set: Vec<String>,
    /// Seed of the procedural wind.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// `frond-warp render`.
#[derive(Debug, Clone, Args)]
pub struct RenderArgs {
    /// Picture and layers.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Parameters.
    #[command(flatten)]
    pub sim: SimArgs,
    /// A recorded take: its root joint drives the wind instead of the procedural wind. A name is
    /// looked up in the takes directory (`NAME.take`); a path (with a `/` or ending `.take`) is
    /// read as given, as every frond tool takes a take.
    #[arg(long, value_name = "NAME|FILE")]
    pub take: Option<String>,
    /// Directory of recorded takes [default: $FROND_TAKES_DIR, else
    /// $XDG_DATA_HOME/frond/takes, else ~/.local/share/frond/takes, else /var/lib/frond/takes].
    #[arg(long, value_name = "DIR")]
    pub takes_dir: Option<PathBuf>,
    /// The tree-animation paper's simulation wind `speed=S,dir=DEG[,gust=G,seed=N,until=S]` (as `frond take
    /// simulate --wind`): the wind that blows the simulated plant blows the picture.
    #[arg(long, value_name = "SPEC", conflicts_with = "take")]
    pub wind_sim: Option<String>,
    /// How the picture moves: `wave` (wind, waves, grid warp) or `cage` (the
    /// first layer's crown cage skinned to the plant skeleton, bent by --take's poses).
    #[arg(long, value_enum, default_value_t = RenderMode::Wave)]
    pub mode: RenderMode,
    /// Cage mode: the cage tree and the skeleton.
    #[command(flatten)]
    pub cage: CageArgs,
    /// Frames to render [1, 100000].
    #[arg(long, allow_negative_numbers = true)]
    pub frames: i64,
    /// Frames per second [1, 240].
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub fps: f32,
    /// Output: out.gif, out.webp or a directory (DIR/) of PNG frames.
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    pub output: PathBuf,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// The cage mode's tree and skeleton (`render --mode cage`, `serve --mode cage`).
#[derive(Debug, Clone, Default, Args)]
pub struct CageArgs {
    /// Cage mode: the layer's cage tree (default: built from the layer as `cage build` does).
    #[arg(long, value_name = "FILE")]
    pub cage: Option<PathBuf>,
    /// Cage mode: where the skeleton stands, `X,Y` pixels (default: the crown's bottom centre).
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true)]
    pub anchor: Option<String>,
    /// Cage mode: the skeleton's rig, an embedded rig's name or a rig file (default: the rig
    /// the take was recorded on for `render`, the daemon's for `serve`, when that is an
    /// embedded rig; a name from a take or a daemon is never opened as a file, so a rig loaded
    /// from a file is given here).
    #[arg(long, value_name = "RIG")]
    pub rig: Option<String>,
}

/// How `render` moves the picture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RenderMode {
    /// Wind, waves and the grid warp ("Simulation-guided Grid-based Warping").
    Wave,
    /// The crown cage ("Sketch-based shape-preserving tree animations") skinned to the skeleton
    /// of --take.
    Cage,
}

/// `frond-warp serve`.
#[derive(Debug, Clone, Args)]
pub struct ServeArgs {
    /// Picture and layers.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Parameters (initial values; the page changes them).
    #[command(flatten)]
    pub sim: SimArgs,
    /// Address to listen on (port 0 picks a free port; the URL is printed). Anything but a
    /// loopback address needs a token for every request (printed in the URL).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub listen: String,
    /// File holding the token (16-256 printable ASCII bytes, only its owner may read it) instead
    /// of a fresh one, for a page served beyond loopback.
    #[arg(long, value_name = "FILE")]
    pub token_file: Option<PathBuf>,
    /// Socket directory of frondd [default: $FROND_SOCKET_DIR, else
    /// $XDG_RUNTIME_DIR/frond, else /run/frond for root, else /tmp/frond-UID].
    /// The variable is read only when --from is not given, so an operator's environment does
    /// not conflict with --from.
    #[arg(long)]
    pub socket_dir: Option<PathBuf>,
    /// Follow a daemon on another host through its frond-zenoh bridge:
    /// `zenoh:frond/<stage>/<source>[?connect=tcp/HOST:PORT]` (default: this host's daemon).
    #[arg(long, value_name = "ADDRESS", conflicts_with_all = ["socket_dir", "no_daemon"])]
    pub from: Option<frond_sdk::Source>,
    /// Do not connect to the daemon (procedural wind only).
    #[arg(long)]
    pub no_daemon: bool,
    /// The tree-animation paper's simulation wind `speed=S,dir=DEG[,gust=G,seed=N,until=S]` instead of the
    /// procedural one while no hand drives the wind (time from the start of the page).
    #[arg(long, value_name = "SPEC")]
    pub wind_sim: Option<String>,
    /// What the page shows: `wave` (wind, waves, grid warp) or `cage` (the
    /// layer's cage tree; sketch on the page with the pointer, or bend it with the live hand).
    #[arg(long, value_enum, default_value_t = RenderMode::Wave)]
    pub mode: RenderMode,
    /// Cage mode: the cage tree and the skeleton.
    #[command(flatten)]
    pub cage: CageArgs,
    /// Cage mode: how long a morph towards a sketch plays, seconds (0, 60].
    #[arg(long, default_value_t = 1.5, allow_negative_numbers = true)]
    pub morph_s: f64,
    /// Cage mode: no self-adaptive cages (section 5.4.1).
    #[arg(long)]
    pub no_adapt: bool,
    /// Cage mode: no pruning of lobes outside a closed sketch (section 5.4.2).
    #[arg(long)]
    pub no_prune: bool,
}

impl ServeArgs {
    /// Where the preview reads poses: `--from`, else the daemon's socket directory.
    pub fn pose_source(&self) -> frond_sdk::Source {
        match &self.from {
            Some(source) => source.clone(),
            None => frond_sdk::Source::Socket(frond_protocol::paths::socket_dir(self.socket_dir.clone())),
        }
    }
}

/// `--wind-sim SPEC` parsed (a bad spec is reported through `ck` with the others).
pub fn sim_wind(spec: Option<&str>, ck: &mut Checker) -> Option<crate::wind::SimWind> {
    match spec?.parse::<frond_motion::sim::WindSpec>() {
        Ok(w) => Some(crate::wind::SimWind::new(w)),
        Err(e) => {
            ck.push("--wind-sim", format!("{:?}", spec.unwrap_or_default()), e);
            None
        }
    }
}

/// `frond-warp bench`.
#[derive(Debug, Clone, Args)]
pub struct BenchArgs {
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Frame width for the warp timing.
    #[arg(long, default_value_t = 1920)]
    pub width: usize,
    /// Frame height for the warp timing.
    #[arg(long, default_value_t = 1080)]
    pub height: usize,
    /// Timed warps.
    #[arg(long, default_value_t = 20)]
    pub iterations: usize,
    /// Frames per pipeline measurement (at 1280x720 and 1920x1080); 0 skips it.
    #[arg(long, default_value_t = 30)]
    pub pipeline_frames: usize,
    /// Also write the frame and displacement field for exporters/warp/bench/remap.py into DIR.
    #[arg(long, value_name = "DIR")]
    pub write_field: Option<PathBuf>,
    /// Also time every warp kernel this CPU runs (scalar, SSE2, AVX2).
    #[arg(long)]
    pub all_kernels: bool,
    /// Morph frames timed for the cage mode at the warp's size; 0 skips it.
    #[arg(long, default_value_t = 10)]
    pub cage_frames: usize,
}
