//! Takes in and out of the motion toolkit (`frond take import|resample|...|graph|walk|simulate`):
//! reading a take by name, resampling it at `--fps` within the output limit, and writing the
//! result as `OUT.take` or JSON Lines ([`Output`]). A module of its own so that the toolkit's
//! commands share it without importing the toolkit's dispatcher.

use std::io::Write;
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::{Context, anyhow};
use clap::Args;
use frond_formats::jsonl::write_pose_line;
use frond_formats::layers::TakeBytes;
use frond_motion::TakeFrame;
use frond_motion::clip::Clip;
use frond_motion::edit::resample_frames;
use frond_motion::layers::{GLOBAL_LAYER, Take};
use frond_protocol::{ElementId, paths};

use crate::calibrate::write_atomically_bytes;
use crate::error::{UsageError, usage};
use crate::global::Global;
use crate::{take_file, takes};

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

/// The take `name` (a name in the takes directory or a path), what it skipped as damaged
/// said on stderr.
pub(crate) fn read_take(g: &Global, name: &str) -> anyhow::Result<Take> {
    let path = takes::resolve(g, name)?;
    let bytes = takes::read_take_bytes(&path)?;
    // One read of the bytes: the take and what it skipped.
    let (take, damage) =
        Take::from_bytes_noting_damage(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    takes::warn_damaged(&path, damage.as_deref(), take.frames.len());
    Ok(take)
}

/// Refuses an `--fps` outside (0, 1000].
pub(crate) fn check_fps(fps: f64) -> anyhow::Result<()> {
    if fps.is_finite() && fps > 0.0 && fps <= 1000.0 {
        Ok(())
    } else {
        usage(format!("--fps must be in (0, 1000], got {fps}"))
    }
}

fn now_unix_s() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs())
}

/// The take's global layer resampled at `fps`, refused past the output limit unless `force`
/// (`None`: the command has no way past it) rather than cut short
/// ([`take_file::check_resample_with`]).
pub(crate) fn global_clip(take: &Take, fps: f64, what: &str, force: Option<bool>) -> anyhow::Result<Clip> {
    layer_clip(take, GLOBAL_LAYER, fps, what, force)
}

/// One layer of a take resampled at `fps`, checked like [`global_clip`].
pub(crate) fn layer_clip(
    take: &Take,
    id: ElementId,
    fps: f64,
    what: &str,
    force: Option<bool>,
) -> anyhow::Result<Clip> {
    let poses: Vec<_> = take.layer(id, false).iter().map(|f| f.pose).collect();
    take_file::check_resample_with(&format!("take {what:?}"), &poses, fps, force)?;
    let c = take.clip(id, fps);
    if c.is_empty() {
        anyhow::bail!("take {what:?} has no {} frames", take.layer_name(id));
    }
    Ok(c)
}

/// One layer's frames resampled at `fps` ([`resample_frames`]), refused past the output limit
/// unless `force` ([`take_file::check_resample`]) rather than cut short.
pub(crate) fn resample_layer(
    frames: &[TakeFrame],
    fps: f64,
    force: bool,
    what: &str,
) -> anyhow::Result<Vec<TakeFrame>> {
    let poses: Vec<_> = frames.iter().map(|f| f.pose).collect();
    take_file::check_resample(what, &poses, fps, force)?;
    Ok(resample_frames(frames, fps).map_err(|e| UsageError(e.to_string()))?)
}

/// Writes the result: JSONL of its global layer on stdout, or `OUT.take` in the takes dir.
pub(crate) fn emit(g: &Global, mut take: Take, default_name: String, out: &Output) -> anyhow::Result<()> {
    if out.jsonl {
        let mut w = frond_binmain::StdoutWriter::lock();
        let mut line = String::with_capacity(256);
        for f in take.layer(GLOBAL_LAYER, true) {
            line.clear();
            write_pose_line(&f.pose, None, &mut line);
            line.push('\n');
            w.write_all(line.as_bytes())?;
        }
        w.flush()?;
        return Ok(());
    }
    let name = out.output.clone().unwrap_or(default_name);
    write_take(g, &mut take, &name, out.force)
}

fn write_take(g: &Global, take: &mut Take, name: &str, force: bool) -> anyhow::Result<()> {
    if let Err(e) = paths::validate_take_name(name) {
        return usage(e.to_string());
    }
    let dir = paths::takes_dir(g.takes_dir.clone());
    let path = dir.join(format!("{name}.take"));
    if path.exists() && !force {
        return usage(format!(
            "{} exists; use --force to replace it or -o to choose another name",
            path.display()
        ));
    }
    take.header.name = name.to_string();
    take.header.created_unix_s = now_unix_s();
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    write_atomically_bytes(&path, &take.to_bytes())?;
    let frames = take.layer(GLOBAL_LAYER, true).len();
    frond_binmain::outln!("wrote {} ({} frames, {} layers)", path.display(), frames, take.layer_ids().len())?;
    Ok(())
}
