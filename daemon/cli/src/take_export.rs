//! `frond take export`: a take's poses as JSON Lines (the default), or as a BVH or USD file, or
//! several takes on one stage timeline (`--align`). Which one is the options' choice; the
//! formats are in `take_bvh`, `take_usd` and `take_align`.

use std::io::Write;
use std::path::PathBuf;

use clap::Args;
use frond_formats::jsonl::write_pose_line;
use frond_motion::resample;

use crate::error::usage;
use crate::global::Global;
use crate::take_file::{check_resample, start_timecode};
use crate::takes::{read_scan, resolve, warn_damage};
use crate::{take_align, take_bvh, take_usd};

/// What `frond take export` was asked.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Take name (or a path to a .take file).
    pub name: String,
    /// With --align: the other takes to put on the same timeline.
    #[arg(value_name = "TAKE", requires = "align")]
    pub more: Vec<String>,
    /// Put NAME and the TAKEs on one stage timeline (the takes of one `record start
    /// --stage`, or takes of one host): every main-skeleton frame of all of them in time
    /// order, {"seq","t","joints","take","stage_ns","host_ns"} a line, `t` in seconds from
    /// the first frame of any.
    #[arg(long, conflicts_with_all = ["bvh", "usd", "fps", "timecode", "timecode_start"])]
    pub align: bool,
    /// JSON Lines output on stdout (the default).
    #[arg(long, conflicts_with_all = ["bvh", "usd"])]
    pub jsonl: bool,
    /// BVH (Biovision Hierarchy) into -o FILE: the mocap exchange format MotionBuilder, Maya
    /// and Blender import; metres, Y up, channels Zrotation Xrotation Yrotation (frond's
    /// R = R_yaw R_pitch R_roll), at --fps (default 30).
    #[arg(long, requires = "output", group = "file_format")]
    pub bvh: bool,
    /// USD (UsdSkel) layer into -o FILE.usda (text) or FILE.usdc (binary): the rig's skinned
    /// mesh, skeleton and the take's animation, Y up, metres, time codes at --fps (default 30).
    #[arg(long, requires = "output", group = "file_format", conflicts_with = "field")]
    pub usd: bool,
    /// Output file (with --bvh or --usd).
    #[arg(short = 'o', long = "output", value_name = "FILE", requires = "file_format")]
    pub output: Option<PathBuf>,
    /// Rig whose joint names, heights (and, for USD, mesh) the file takes [default: the
    /// take's rig when it is an embedded one; a rig loaded from a file must be given here].
    #[arg(long, value_name = "NAME|FILE", requires = "file_format")]
    pub rig: Option<PathBuf>,
    /// Field file (field.json from `frond take field`): every plant of the field, one BVH
    /// root each (with --bvh and --duration).
    #[arg(long, value_name = "FILE", requires_all = ["bvh", "duration"])]
    pub field: Option<PathBuf>,
    /// Length of a field export, seconds.
    #[arg(long, value_name = "S", requires = "field")]
    pub duration: Option<f64>,
    /// Resample to this many frames per second (e.g. 30, the rate the hand-gesture paper authors at).
    #[arg(long, value_name = "FPS")]
    pub fps: Option<f64>,
    /// Also print held frames (every recorded tick); ignored with --fps.
    #[arg(long)]
    pub include_held: bool,
    /// SMPTE timecode of the first frame, HH:MM:SS:FF at --fps (with --usd or --timecode;
    /// BVH has no timecode field) [default: the time of day, UTC, the take's first frame was
    /// recorded at, when the take knows it].
    #[arg(long, value_name = "HH:MM:SS:FF", conflicts_with = "bvh")]
    pub timecode_start: Option<String>,
    /// JSON Lines: add each frame's SMPTE timecode ("tc": "HH:MM:SS:FF", at --fps) from the
    /// take's recording clock or --timecode-start.
    #[arg(long, requires = "fps", conflicts_with_all = ["bvh", "usd"])]
    pub timecode: bool,
    /// Resample past the export limit (1,080,000 frames); never past 16,777,216.
    #[arg(long)]
    pub force: bool,
}

/// Runs `frond take export` in the format its options choose.
pub(crate) fn run(g: &Global, a: ExportArgs) -> anyhow::Result<()> {
    if a.align {
        let names: Vec<String> = std::iter::once(a.name).chain(a.more).collect();
        return take_align::export_aligned(g, &names, a.include_held);
    }
    match (a.bvh, &a.output) {
        (false, Some(output)) if a.usd => take_usd::export_usd(
            g,
            take_usd::UsdExport {
                name: &a.name,
                output,
                fps: a.fps,
                rig: a.rig.as_deref(),
                timecode_start: a.timecode_start.as_deref(),
                force: a.force,
            },
        ),
        (true, Some(output)) => take_bvh::export_bvh(
            g,
            take_bvh::BvhExport {
                name: &a.name,
                output,
                fps: a.fps,
                rig: a.rig.as_deref(),
                field: a.field.as_deref(),
                duration_s: a.duration,
                force: a.force,
            },
        ),
        _ if a.timecode_start.is_some() && !a.timecode => {
            usage("--timecode-start goes with --usd or --timecode")
        }
        _ => export_jsonl(
            g,
            &a.name,
            a.fps,
            a.include_held,
            a.timecode.then_some(a.timecode_start.as_deref()),
            a.force,
        ),
    }
}

/// The take's poses as JSON Lines on stdout (`--jsonl`, the default), at `fps` when given,
/// each with its SMPTE timecode with `timecode` (`Some(start)`: `--timecode-start`, else the
/// take's recording clock).
fn export_jsonl(
    g: &Global,
    name: &str,
    fps: Option<f64>,
    include_held: bool,
    timecode: Option<Option<&str>>,
    force: bool,
) -> anyhow::Result<()> {
    if let Some(fps) = fps
        && !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0)
    {
        return usage(format!("--fps must be greater than 0 and at most 10000, got {fps}"));
    }
    let path = resolve(g, name)?;
    let (scan, _) = read_scan(&path)?;
    warn_damage(&path, &scan);
    if scan.torn_bytes > 0 {
        frond_binmain::errln!(
            "frond: warning: {} ends with a torn record ({} bytes); exporting the {} complete frames",
            path.display(),
            scan.torn_bytes,
            scan.frames.len()
        );
    } else if !scan.ended {
        frond_binmain::errln!(
            "frond: warning: {} is not closed (still recording?); exporting what is there",
            path.display()
        );
    }
    if let Some(k) = scan.main_element().filter(|k| !k.is_global()) {
        frond_binmain::errln!(
            "frond: note: {} is a layer take (its frames are element {k}, a secondary layer): exporting that layer",
            path.display()
        );
    }
    let mut poses = scan.main_poses(include_held);
    if let Some(fps) = fps {
        check_resample(&path.display().to_string(), &poses, fps, force)?;
        poses = resample(&poses, fps);
    }
    // `--timecode`: frame k of the export is the start plus k frames (on the --fps grid).
    let start = match (timecode, fps) {
        (Some(given), Some(fps)) => match start_timecode(&scan, fps, given)? {
            Some(tc) => Some(tc),
            None => {
                return usage(format!(
                    "{} has no recording clock (made offline?): give --timecode-start HH:MM:SS:FF",
                    path.display()
                ));
            }
        },
        _ => None,
    };
    let mut out = frond_binmain::StdoutWriter::lock();
    let mut line = String::with_capacity(256);
    for (k, p) in poses.iter().enumerate() {
        line.clear();
        write_pose_line(p, None, &mut line);
        if let Some(tc) = start
            && line.ends_with('}')
        {
            line.pop();
            use std::fmt::Write as _;
            let _ = write!(line, ",\"tc\":\"{}\"}}", tc.plus_frames(k as u64));
        }
        line.push('\n');
        out.write_all(line.as_bytes())?;
    }
    out.flush()?;
    Ok(())
}
