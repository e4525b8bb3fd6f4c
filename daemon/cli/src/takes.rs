//! `frond take list|export|repair`: takes on disk, read with the motion crate's codec.
//!
//! States: `complete` (closed with an End record), `open` (no End record and no torn bytes:
//! still recording, or the recorder stopped between records), `torn` (a partial record at the
//! end: a crash mid-write, or a write in progress), `corrupt` (damage in the middle; not
//! repairable by cutting the tail).

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use anyhow::{Context, anyhow, bail};
use frond_motion::jsonl::write_pose_line;
use frond_motion::take::{TakeRecord, encode_record};
use frond_motion::{PoseFrame, TakeScan, resample, scan_take};
use frond_protocol::{PoseFlags, paths};
use serde::Serialize;

use crate::args::Global;
use crate::calibrate::write_atomically_bytes;
use crate::usage;

/// A take modified more recently than this may still be recording; `repair` leaves it alone.
const RECENT: Duration = Duration::from_secs(5);

/// Finds a take: a path to an existing file (containing `/` or ending in `.take`), else
/// `NAME.take` in the takes directory.
pub(crate) fn resolve(g: &Global, name: &str) -> anyhow::Result<PathBuf> {
    let as_path = Path::new(name);
    if (name.contains('/') || name.ends_with(".take")) && as_path.is_file() {
        return Ok(as_path.to_owned());
    }
    if let Err(e) = paths::validate_take_name(name) {
        return usage(e.to_string());
    }
    let dir = paths::takes_dir(g.takes_dir.clone());
    let path = dir.join(format!("{name}.take"));
    if !path.is_file() {
        bail!("no take named {name:?} in {} (`frond take list` shows the takes there)", dir.display());
    }
    Ok(path)
}

fn read_scan(path: &Path) -> anyhow::Result<(TakeScan, u64)> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read take {}", path.display()))?;
    let scan = scan_take(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    Ok((scan, bytes.len() as u64))
}

/// One row of `take list`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct TakeInfo {
    pub name: String,
    pub path: String,
    /// Main-skeleton frames (every recorded tick, held ones included).
    pub frames: u64,
    /// Time from the first to the last main-skeleton pose, seconds.
    pub duration_s: f64,
    pub size_bytes: u64,
    /// `complete`, `open`, `torn` or `corrupt`.
    pub state: &'static str,
    pub torn_bytes: u64,
    pub markers: u64,
    pub rig: Option<String>,
    /// Why a corrupt take could not be read.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

pub(crate) fn info(path: &Path) -> TakeInfo {
    let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut info = TakeInfo {
        name,
        path: path.display().to_string(),
        frames: 0,
        duration_s: 0.0,
        size_bytes: 0,
        state: "corrupt",
        torn_bytes: 0,
        markers: 0,
        rig: None,
        error: None,
    };
    match read_scan(path) {
        Ok((scan, size)) => {
            let poses = scan.poses();
            info.frames = poses.len() as u64;
            info.duration_s = match (poses.first(), poses.last()) {
                (Some(a), Some(b)) => b.t - a.t,
                _ => 0.0,
            };
            info.size_bytes = size;
            info.torn_bytes = scan.torn_bytes;
            info.markers = scan.markers.len() as u64;
            info.rig = scan.header.map(|h| h.rig_name);
            info.state = state(scan.ended, scan.torn_bytes);
        }
        Err(e) => {
            info.size_bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
            info.error = Some(format!("{e:#}"));
        }
    }
    info
}

fn state(ended: bool, torn_bytes: u64) -> &'static str {
    match (ended, torn_bytes) {
        (_, 1..) => "torn",
        (true, 0) => "complete",
        (false, 0) => "open",
    }
}

/// `12 B`, `3.4 KiB`, `5.6 MiB`.
pub(crate) fn human_size(bytes: u64) -> String {
    match bytes {
        0..1024 => format!("{bytes} B"),
        1024..1_048_576 => format!("{:.1} KiB", bytes as f64 / 1024.0),
        _ => format!("{:.1} MiB", bytes as f64 / 1_048_576.0),
    }
}

pub(crate) fn list(g: &Global, json: bool) -> anyhow::Result<()> {
    let dir = paths::takes_dir(g.takes_dir.clone());
    let mut paths: Vec<PathBuf> = match std::fs::read_dir(&dir) {
        Ok(rd) => rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "take") && p.is_file())
            .collect(),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(e).with_context(|| format!("cannot list {}", dir.display())),
    };
    paths.sort();
    let infos: Vec<TakeInfo> = paths.iter().map(|p| info(p)).collect();
    let stdout = io::stdout();
    let mut out = stdout.lock();
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&infos)?)?;
        return Ok(());
    }
    if infos.is_empty() {
        writeln!(out, "no takes in {}", dir.display())?;
        return Ok(());
    }
    writeln!(out, "takes in {}", dir.display())?;
    let width = infos.iter().map(|i| i.name.len()).max().unwrap_or(4).max(4);
    writeln!(
        out,
        "{:<width$}  {:>8}  {:>9}  {:>10}  {:<8}  RIG",
        "NAME", "FRAMES", "DURATION", "SIZE", "STATE"
    )?;
    for i in &infos {
        let state = match (i.state, &i.error) {
            ("torn", _) => format!("torn ({} bytes; `frond take repair {}`)", i.torn_bytes, i.name),
            (_, Some(e)) => format!("corrupt: {e}"),
            (s, None) => s.to_string(),
        };
        writeln!(
            out,
            "{:<width$}  {:>8}  {:>8.2}s  {:>10}  {:<8}  {}",
            i.name,
            i.frames,
            i.duration_s,
            human_size(i.size_bytes),
            state,
            i.rig.as_deref().unwrap_or("-"),
        )?;
    }
    Ok(())
}

/// The poses `export` prints: main skeleton, held frames dropped unless asked for, resampled
/// when `fps` is given.
pub(crate) fn export_poses(scan: &TakeScan, fps: Option<f64>, include_held: bool) -> Vec<PoseFrame> {
    let poses: Vec<PoseFrame> = scan
        .frames
        .iter()
        .filter(|f| f.element == 0 && (include_held || !PoseFlags(f.flags).contains(PoseFlags::HELD)))
        .map(|f| f.pose)
        .collect();
    match fps {
        Some(fps) => resample(&poses, fps),
        None => poses,
    }
}

pub(crate) fn export(g: &Global, name: &str, fps: Option<f64>, include_held: bool) -> anyhow::Result<()> {
    if let Some(fps) = fps
        && !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0)
    {
        return usage(format!("--fps must be between 0 and 10000, got {fps}"));
    }
    let path = resolve(g, name)?;
    let (scan, _) = read_scan(&path)?;
    if scan.torn_bytes > 0 {
        eprintln!(
            "frond: warning: {} ends with a torn record ({} bytes); exporting the {} complete frames",
            path.display(),
            scan.torn_bytes,
            scan.frames.len()
        );
    } else if !scan.ended {
        eprintln!(
            "frond: warning: {} is not closed (still recording?); exporting what is there",
            path.display()
        );
    }
    let poses = export_poses(&scan, fps, include_held);
    let stdout = io::stdout();
    let mut out = io::BufWriter::new(stdout.lock());
    let mut line = String::with_capacity(256);
    for p in &poses {
        line.clear();
        write_pose_line(p, None, &mut line);
        line.push('\n');
        out.write_all(line.as_bytes())?;
    }
    out.flush()?;
    Ok(())
}

/// What `repair` did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Repaired {
    pub dropped_bytes: u64,
    pub frames: u64,
    pub closed: bool,
}

/// The repaired bytes: the valid prefix, plus an End record if the take was not closed.
/// `None` when there is nothing to repair.
pub(crate) fn repaired_bytes(bytes: &[u8]) -> anyhow::Result<Option<(Vec<u8>, Repaired)>> {
    let scan = scan_take(bytes).map_err(|e| {
        anyhow!("{e}; only a torn tail can be repaired (the damage here is in the middle of the take)")
    })?;
    if scan.torn_bytes == 0 && scan.ended {
        return Ok(None);
    }
    if scan.valid_len < frond_motion::take::MAGIC.len() as u64 {
        bail!("the take is too short to hold even its 8-byte signature; nothing can be kept");
    }
    let mut out = bytes[..scan.valid_len as usize].to_vec();
    let frames = scan.frames.len() as u64;
    if !scan.ended {
        encode_record(&TakeRecord::End { frames }, &mut out);
    }
    // The result must read back as a complete take with the same frames.
    let check =
        scan_take(&out).map_err(|e| anyhow!("internal error: the repaired take does not read back: {e}"))?;
    if !check.ended || check.torn_bytes != 0 || check.frames != scan.frames {
        bail!("internal error: the repaired take does not read back identically");
    }
    Ok(Some((out, Repaired { dropped_bytes: scan.torn_bytes, frames, closed: !scan.ended })))
}

pub(crate) fn repair(g: &Global, name: &str) -> anyhow::Result<()> {
    let path = resolve(g, name)?;
    let age = std::fs::metadata(&path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|m| SystemTime::now().duration_since(m).ok())
        .unwrap_or(Duration::MAX);
    if age < RECENT {
        bail!(
            "{} was modified {:.1} s ago and may still be recording; stop the recording \
             (`frond record stop`) or wait a few seconds, then repair",
            path.display(),
            age.as_secs_f64()
        );
    }
    let bytes = std::fs::read(&path).with_context(|| format!("cannot read take {}", path.display()))?;
    let Some((fixed, r)) = repaired_bytes(&bytes).map_err(|e| anyhow!("{}: {e:#}", path.display()))? else {
        println!("{} is complete; nothing to repair", path.display());
        return Ok(());
    };
    write_atomically_bytes(&path, &fixed)?;
    println!(
        "repaired {}: dropped {} torn bytes, kept {} frames{}",
        path.display(),
        r.dropped_bytes,
        r.frames,
        if r.closed { ", closed with an End record" } else { "" }
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use frond_motion::take::encode_file_start;
    use frond_motion::{HandSample, TakeFrame};

    use super::*;

    fn frame(seq: u64, t: f64, flags: PoseFlags) -> TakeFrame {
        TakeFrame {
            seq,
            device_time_us: (t * 1e6) as u64,
            host_ns: seq,
            flags: flags.0,
            element: 0,
            pose: PoseFrame { t, joints_deg: [[t as f32; 3]; 4] },
            hand: HandSample { t, ..Default::default() },
        }
    }

    fn take(frames: &[TakeFrame], end: bool) -> Vec<u8> {
        let mut b = Vec::new();
        encode_file_start(&mut b);
        for f in frames {
            encode_record(&TakeRecord::Frame(*f), &mut b);
        }
        if end {
            encode_record(&TakeRecord::End { frames: frames.len() as u64 }, &mut b);
        }
        b
    }

    #[test]
    fn states() {
        assert_eq!(state(true, 0), "complete");
        assert_eq!(state(false, 0), "open");
        assert_eq!(state(false, 3), "torn");
    }

    #[test]
    fn export_skips_held_and_other_elements() {
        let mut leaf = frame(1, 0.0, PoseFlags::default());
        leaf.element = 1;
        let frames = [
            frame(0, 0.0, PoseFlags::default()),
            leaf,
            frame(1, 0.0, PoseFlags::HELD),
            frame(2, 0.5, PoseFlags::FILTERED),
        ];
        let scan = scan_take(&take(&frames, true)).unwrap();
        let ts = |v: Vec<PoseFrame>| v.iter().map(|p| p.t).collect::<Vec<_>>();
        assert_eq!(ts(export_poses(&scan, None, false)), [0.0, 0.5]);
        assert_eq!(ts(export_poses(&scan, None, true)), [0.0, 0.0, 0.5]);
        assert_eq!(ts(export_poses(&scan, Some(4.0), false)), [0.0, 0.25, 0.5]);
    }

    #[test]
    fn repair_cuts_the_tail_and_closes() {
        let frames = [frame(0, 0.0, PoseFlags::default()), frame(1, 0.1, PoseFlags::default())];
        let mut bytes = take(&frames, false);
        bytes.extend_from_slice(&[50, 0, 0, 0, 1, 2]); // half a record
        let (fixed, r) = repaired_bytes(&bytes).unwrap().unwrap();
        assert_eq!(r, Repaired { dropped_bytes: 6, frames: 2, closed: true });
        assert_eq!(fixed, take(&frames, true));
        assert!(repaired_bytes(&fixed).unwrap().is_none());
    }

    #[test]
    fn repair_refuses_damage_in_the_middle() {
        let frames: Vec<TakeFrame> = (0..4).map(|i| frame(i, i as f64, PoseFlags::default())).collect();
        let mut bytes = take(&frames, true);
        bytes[30] ^= 0xff; // inside the first frame record's payload
        let err = repaired_bytes(&bytes).unwrap_err().to_string();
        assert!(err.contains("corrupt record at offset 8"), "{err}");
        assert!(err.contains("only a torn tail can be repaired"), "{err}");
    }

    #[test]
    fn sizes_read_naturally() {
        assert_eq!(human_size(12), "12 B");
        assert_eq!(human_size(3 * 1024 + 512), "3.5 KiB");
        assert_eq!(human_size(5 * 1_048_576), "5.0 MiB");
    }
}
