//! Takes as the source of an export: the output limits every resampling is checked against
//! (`take export`, the toolkit, the graph and walk commands, BVH and USD), and a take read with
//! its rig for a file of another format (`--bvh`, `--usd`).

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail};
use frond_motion::take::{MAX_INTERPOLATED_GAP_S, MAX_RESAMPLED_FRAMES};
use frond_motion::{PoseFrame, TakeScan, resample, resample_plan};

use crate::error::usage;
use crate::global::Global;
use crate::takes::{read_scan, resolve, warn_damage};

/// `take export --fps` and the baker refuse to resample to more frames than this unless
/// `--force` (10 hours at 30 FPS); [`MAX_RESAMPLED_FRAMES`] is the limit even with `--force`.
pub(crate) const MAX_EXPORT_FRAMES: u64 = 1_080_000;

/// The poses `export` prints: main skeleton, held frames dropped unless asked for, resampled
/// when `fps` is given.
pub(crate) fn export_poses(scan: &TakeScan, fps: Option<f64>, include_held: bool) -> Vec<PoseFrame> {
    let poses = scan.main_poses(include_held);
    match fps {
        Some(fps) => resample(&poses, fps),
        None => poses,
    }
}

/// Checks a resampling before it is done: refuses past [`MAX_EXPORT_FRAMES`] unless `force`
/// (never past [`MAX_RESAMPLED_FRAMES`]) and warns about time discontinuities.
pub(crate) fn check_resample(what: &str, poses: &[PoseFrame], fps: f64, force: bool) -> anyhow::Result<()> {
    check_resample_with(what, poses, fps, Some(force))
}

/// Checks an output of `frames` frames at `fps` (`seconds` long) before it is made: past
/// [`MAX_EXPORT_FRAMES`] only with `force`, never past [`MAX_RESAMPLED_FRAMES`]: refused, never
/// cut short. `what` names the output in the message.
pub(crate) fn check_output_frames(
    what: &str,
    frames: u64,
    seconds: f64,
    fps: f64,
    force: bool,
) -> anyhow::Result<()> {
    if frames > MAX_RESAMPLED_FRAMES as u64 {
        bail!(
            "{what} lasts {seconds:.1} s: {frames} frames at {fps} FPS, more than the {MAX_RESAMPLED_FRAMES} any output may have"
        );
    }
    if !force && frames > MAX_EXPORT_FRAMES {
        bail!(
            "{what} lasts {seconds:.1} s: {frames} frames at {fps} FPS, more than {MAX_EXPORT_FRAMES}; pass --force to go past it"
        );
    }
    Ok(())
}

/// [`check_resample`] for a command with (`Some(force)`) or without (`None`: the limit holds and
/// no `--force` is offered) a way past the limit.
pub(crate) fn check_resample_with(
    what: &str,
    poses: &[PoseFrame],
    fps: f64,
    force: Option<bool>,
) -> anyhow::Result<()> {
    let plan = resample_plan(poses, fps);
    if let Some(i) = plan.first_discontinuity {
        frond_binmain::errln!(
            "frond: warning: {what}: {} step{} in time longer than {MAX_INTERPOLATED_GAP_S} s or backwards \
             (the first before pose {i}, the largest forward {:.3} s): each is a discontinuity, \
             not interpolated",
            plan.discontinuities,
            if plan.discontinuities == 1 { "" } else { "s" },
            plan.largest_gap_s
        );
    }
    plan.check(fps, MAX_RESAMPLED_FRAMES as u64).map_err(|e| anyhow!("{what}: {e} (the hard limit)"))?;
    match force {
        Some(true) => {}
        Some(false) => plan.check(fps, MAX_EXPORT_FRAMES).map_err(|e| {
            anyhow!("{what}: {e} ({:.1} s of output); pass --force to go past it", plan.duration_s)
        })?,
        None => plan
            .check(fps, MAX_EXPORT_FRAMES)
            .map_err(|e| anyhow!("{what}: {e} ({:.1} s of output)", plan.duration_s))?,
    }
    Ok(())
}

/// A take to write as a file of another format (`--bvh`, `--usd`): its path, its scan (damage
/// warned about), the rig it is written on (`--rig`, else the take's own) and its main-skeleton
/// poses (at least one).
pub(crate) struct TakeForFile {
    pub path: PathBuf,
    pub scan: TakeScan,
    pub rig: frond_formats::rig_files::LoadedRig,
    pub source: Vec<PoseFrame>,
}

/// Frame rate of a file export (BVH, USD): `--fps`, or the seed's authoring rate.
pub(crate) const DEFAULT_FILE_FPS: f64 = 30.0;

impl TakeForFile {
    /// `--fps` of a `format` export checked (default [`DEFAULT_FILE_FPS`]).
    pub fn fps(fps: Option<f64>, format: &str) -> anyhow::Result<f64> {
        let fps = fps.unwrap_or(DEFAULT_FILE_FPS);
        if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
            return usage(format!("--fps must be above 0 and at most 1000 for {format}, got {fps}"));
        }
        Ok(fps)
    }

    /// The main-skeleton poses resampled to `fps`, refused past the export limits first.
    pub fn resampled(&self, fps: f64, force: bool) -> anyhow::Result<Vec<PoseFrame>> {
        check_resample(&self.path.display().to_string(), &self.source, fps, force)?;
        Ok(resample(&self.source, fps))
    }
}

/// Timecode of the first exported frame at `fps`: `start` (`HH:MM:SS:FF`) if given, else the
/// wall-clock time of day (UTC) the take's first kept frame was recorded at, when the take
/// knows it (recorded by a daemon that writes its clock).
pub(crate) fn start_timecode(
    scan: &TakeScan,
    fps: f64,
    start: Option<&str>,
) -> anyhow::Result<Option<frond_motion::timecode::Timecode>> {
    let rate =
        frond_motion::timecode::nominal_rate(fps).map_err(|e| crate::error::UsageError(e.to_string()))?;
    if let Some(text) = start {
        let tc = frond_motion::timecode::Timecode::parse(text, rate)
            .map_err(|e| crate::error::UsageError(format!("--timecode-start {e}")))?;
        return Ok(Some(tc));
    }
    Ok(scan.header.as_ref().and_then(|h| h.start_timecode(&scan.frames, fps)))
}

/// The rig a take was recorded on ([`frond_formats::rig_files::recorded_rig`]: an embedded rig,
/// never a path), as a usage error naming the take.
pub(crate) fn recorded_rig(
    take: &str,
    rig_name: &str,
) -> anyhow::Result<frond_formats::rig_files::LoadedRig> {
    if rig_name.is_empty() {
        return usage(format!("{take} names no rig; give one with --rig NAME|FILE"));
    }
    frond_formats::rig_files::recorded_rig(rig_name).or_else(|e| usage(format!("{take}: {e}")))
}

/// Reads take `name` and its rig for a file export.
pub(crate) fn take_for_file(g: &Global, name: &str, rig: Option<&Path>) -> anyhow::Result<TakeForFile> {
    let path = resolve(g, name)?;
    let (scan, _) = read_scan(&path)?;
    warn_damage(&path, &scan);
    let rig = match (rig, &scan.header) {
        (Some(r), _) => frond_formats::rig_files::load_rig(&r.to_string_lossy())?,
        (None, header) => {
            recorded_rig(&path.display().to_string(), header.as_ref().map_or("", |h| h.rig_name.as_str()))?
        }
    };
    let source = export_poses(&scan, None, false);
    if source.is_empty() {
        bail!("{} has no frames of the main skeleton to export", path.display());
    }
    Ok(TakeForFile { path, scan, rig, source })
}
