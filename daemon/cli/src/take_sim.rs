//! `frond take simulate`: the simulated plant of seed 003 (section 4) written as a take, and,
//! with `--states`, the node positions, velocities and forces of every frame as section 4.3
//! stores them (JSON Lines).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, anyhow};
use clap::Args;
use frond_formats::rig_toml::sim_from_toml_str;
use frond_motion::layers::{GLOBAL_LAYER, Take, frames_from_clip};
use frond_motion::sim::{SimError, WindSpec, simulate_each};
use frond_motion::take::TakeHeader;

use crate::control::load_rig;
use crate::error::usage;
use crate::global::Global;
use crate::take_io::{Output, emit};

/// Largest `--sim` file read, bytes.
const MAX_SIM_FILE_BYTES: u64 = 1 << 20;

/// What `frond take simulate` was asked.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Take name to write.
    pub name: String,
    /// Rig: an embedded name or a rig file (TOML).
    #[arg(long, value_name = "NAME|FILE")]
    pub rig: PathBuf,
    /// A TOML file with a `[sim]` table replacing the rig's.
    #[arg(long, value_name = "FILE")]
    pub sim: Option<PathBuf>,
    /// The wind.
    #[arg(long, value_name = "SPEC")]
    pub wind: String,
    /// Seconds to simulate.
    #[arg(long, value_name = "S")]
    pub duration: f64,
    /// Frames per second of the take.
    #[arg(long, default_value_t = 30.0, value_name = "FPS")]
    pub fps: f64,
    /// Also write every frame's node positions, velocities and forces (JSON Lines).
    #[arg(long, value_name = "FILE.jsonl")]
    pub states: Option<PathBuf>,
    /// Print the poses as JSON Lines instead of writing the take.
    #[arg(long)]
    pub jsonl: bool,
    /// Replace an existing take (and states file) of the same name.
    #[arg(long)]
    pub force: bool,
}

/// Runs the simulation and writes the take (or the poses as JSON Lines) and the states.
pub(crate) fn run(g: &Global, a: SimulateArgs) -> anyhow::Result<()> {
    let wind: WindSpec = match a.wind.parse() {
        Ok(w) => w,
        Err(e) => return usage(format!("--wind {:?}: {e}", a.wind)),
    };
    let (rig, _) = load_rig(&a.rig)?;
    let sim = match &a.sim {
        None => rig.sim,
        Some(path) => {
            let text = frond_formats::rig_files::read_small_text(path, MAX_SIM_FILE_BYTES)
                .map_err(|e| anyhow!("cannot read {}: {}", path.display(), e.reason()))?;
            sim_from_toml_str(&text, rig.sim_node_heights_m())
                .map_err(|e| anyhow!("{}: {e}", path.display()))?
        }
    };
    if let Some(states) = &a.states
        && states.exists()
        && !a.force
    {
        return usage(format!("{} exists; use --force to replace it", states.display()));
    }
    let mut states = match &a.states {
        Some(path) => Some((path, std::io::BufWriter::new(create(path)?))),
        None => None,
    };
    let mut poses = Vec::new();
    let mut write_error = None;
    let bar = progress_bar(a.duration, a.fps);
    let result = simulate_each(&rig, &sim, wind, a.duration, a.fps, &mut |plant, pose| {
        if poses.len() % 64 == 0 {
            bar.set_position(poses.len() as u64);
        }
        if let Some((_, w)) = states.as_mut()
            && write_error.is_none()
        {
            let line = serde_json::json!({
                "t": pose.t,
                "positions_m": plant.positions_m().map(|p| p.to_array()),
                "velocities_m_s": plant.velocities_m_s().map(|v| v.to_array()),
                "forces_n": plant.forces_n().map(|f| f.to_array()),
            });
            if let Err(e) = writeln!(w, "{line}") {
                write_error = Some(e);
            }
        }
        poses.push(pose);
    });
    bar.finish_and_clear();
    match result {
        Ok(()) => {}
        Err(
            e @ (SimError::Argument { .. } | SimError::TooManyFrames { .. } | SimError::TooManySteps { .. }),
        ) => {
            return usage(e.to_string());
        }
        Err(e) => return Err(e.into()),
    }
    if let Some((path, mut w)) = states {
        if let Some(e) = write_error {
            return Err(anyhow!("writing {}: {e}", path.display()));
        }
        w.flush().with_context(|| format!("writing {}", path.display()))?;
    }
    let clip = frond_motion::clip::Clip { fps: a.fps, frames: poses };
    let header = TakeHeader {
        name: a.name.clone(),
        rig_name: rig.name.clone(),
        calibration_id: "none".into(),
        filter: format!("sim {wind}"),
        tick_rate_hz: a.fps.round().max(1.0) as u32,
        created_unix_s: 0,
        daemon_version: format!("frond {} (simulate)", env!("CARGO_PKG_VERSION")),
        joint_names: rig.joint_names(),
        clock: None,
        stage: None,
        stage_clock: None,
    };
    let mut take = Take::new(header);
    take.set_layer(GLOBAL_LAYER, None, frames_from_clip(&clip, GLOBAL_LAYER, 0, None));
    let out = Output { output: Some(a.name.clone()), jsonl: a.jsonl, force: a.force, fps: a.fps };
    emit(g, take, a.name, &out)
}

/// Simulated seconds past which `frond take simulate` shows its progress (on a terminal).
const PROGRESS_FROM_S: f64 = 10.0;

/// A progress bar of the simulated frames on stderr, for `duration_s` at `fps`: drawn only when
/// stderr is a terminal and the simulation is longer than [`PROGRESS_FROM_S`] (never in pipes,
/// logs or tests).
fn progress_bar(duration_s: f64, fps: f64) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    let frames = frond_motion::clip::frames_needed(duration_s, fps);
    if !std::io::stderr().is_terminal()
        || duration_s.partial_cmp(&PROGRESS_FROM_S) != Some(std::cmp::Ordering::Greater)
    {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(frames);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("simulating [{bar:40}] {pos}/{len} frames {elapsed}/{eta}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// Creates the `--states` file where [`frond_formats::rig_files::output_destination`] allows
/// (never over a device, FIFO or directory; into a directory that exists).
fn create(path: &Path) -> anyhow::Result<std::fs::File> {
    let to = frond_formats::rig_files::output_destination(path)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
    std::fs::File::create(&to).with_context(|| format!("cannot create {}", path.display()))
}
