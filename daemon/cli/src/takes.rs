//! `frond take list|export|repair`: takes on disk, read with the motion crate's codec.
//!
//! States: `complete` (closed with an End record), `open` (no End record and no torn bytes:
//! still recording, or the recorder stopped between records), `torn` (a partial record at the
//! end: a crash mid-write, or a write in progress), `damaged` (damaged records in the middle,
//! skipped by the reader: everything else reads, and `repair` rewrites the take without them),
//! `empty` (0 bytes: nothing was ever written), `corrupt` (unreadable: not a take, or a
//! checksummed record this version cannot read, or a non-finite value; the error says which).
//!
//! Readers resynchronise after damage (`frond_motion::take`): `export` and the toolkit work on
//! what is readable and say, on stderr, what they skipped.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use anyhow::{Context, anyhow, bail};
use frond_formats::scan_take;
use frond_formats::take_repair::Repaired;
use frond_motion::TakeScan;
use frond_protocol::paths;
use serde::Serialize;

use crate::calibrate::write_atomically_bytes;
use crate::error::usage;
use crate::global::Global;

/// A take without an End record modified more recently than this may still be recording;
/// `repair` leaves it alone.
const RECENT: Duration = frond_formats::take_repair::MAY_BE_RECORDING;
/// Finds a take: a path to an existing file (containing `/` or ending in `.take`), else
/// `NAME.take` in the takes directory.
pub(crate) fn resolve(g: &Global, name: &str) -> anyhow::Result<PathBuf> {
    let as_path = Path::new(name);
    let looks_like_path = name.contains('/') || name.ends_with(".take");
    // Something is there but it is not a take file: say what it is rather than that the name is
    // bad or that no take has it.
    let not_a_file = |path: &Path| {
        std::fs::metadata(path)
            .ok()
            .and_then(|m| frond_formats::rig_files::not_regular(m.file_type()))
            .map(|what| anyhow!("{} is {what}, not a take file", path.display()))
    };
    if looks_like_path {
        if as_path.is_file() {
            return Ok(as_path.to_owned());
        }
        if let Some(e) = not_a_file(as_path) {
            return Err(e);
        }
        if name.contains('/') {
            return usage(format!(
                "no take file {}: it does not exist (a name without '/' is looked up in the takes directory)",
                as_path.display()
            ));
        }
    }
    if let Err(e) = paths::validate_take_name(name) {
        return usage(e.to_string());
    }
    let dir = paths::takes_dir(g.takes_dir.clone());
    let path = dir.join(format!("{name}.take"));
    if !path.is_file() {
        if let Some(e) = not_a_file(&path) {
            return Err(e);
        }
        bail!("no take named {name:?} in {} (`frond take list` shows the takes there)", dir.display());
    }
    Ok(path)
}

/// A take file's bytes: a regular file within `rig_files::MAX_TAKE_FILE_BYTES`.
pub(crate) fn read_take_bytes(path: &Path) -> anyhow::Result<Vec<u8>> {
    frond_formats::rig_files::read_take_file(path)
        .map_err(|e| anyhow!("cannot read take {}: {}", path.display(), e.reason()))
}

pub(crate) fn read_scan(path: &Path) -> anyhow::Result<(TakeScan, u64)> {
    let bytes = read_take_bytes(path)?;
    let scan = scan_take(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    Ok((scan, bytes.len() as u64))
}

/// Warns on stderr that `path` is damaged and only its readable part is used.
pub(crate) fn warn_damage(path: &Path, scan: &TakeScan) {
    warn_damaged(path, scan.damage().as_deref(), scan.frames.len());
}

/// The same warning, from what the reader said (`TakeScan::damage`) and the frames it kept.
pub(crate) fn warn_damaged(path: &Path, damage: Option<&str>, readable_frames: usize) {
    if let Some(d) = damage {
        frond_binmain::errln!(
            "frond: warning: {}: {d}; using the {readable_frames} readable frames (`frond take repair` rewrites the take without the damage)",
            path.display(),
        );
    }
}

/// One row of `take list`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct TakeInfo {
    pub name: String,
    pub path: String,
    /// Main-skeleton frames (every recorded tick, held ones included); a layer take's layer
    /// (`frond_motion::take::main_element`).
    pub frames: u64,
    /// Time from the first to the last main-skeleton pose, seconds.
    pub duration_s: f64,
    pub size_bytes: u64,
    /// `complete`, `open`, `torn`, `damaged`, `empty` or `corrupt`.
    pub state: &'static str,
    pub torn_bytes: u64,
    /// Bytes of damaged records the reader skipped.
    pub skipped_bytes: u64,
    /// What was skipped, in words (for `damaged`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub damage: Option<String>,
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
        skipped_bytes: 0,
        damage: None,
        markers: 0,
        rig: None,
        error: None,
    };
    match read_scan(path) {
        Ok((scan, size)) => {
            info.frames = scan.main_frame_count();
            info.duration_s = scan.duration_s();
            info.size_bytes = size;
            info.torn_bytes = scan.torn_bytes;
            info.skipped_bytes = scan.skipped_bytes();
            info.damage = scan.damage();
            info.markers = scan.markers.len() as u64;
            info.state = scan.state(size);
            info.rig = scan.header.map(|h| h.rig_name);
        }
        Err(e) => {
            info.size_bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
            info.error = Some(format!("{e:#}"));
        }
    }
    info
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
    let mut out = frond_binmain::StdoutWriter::lock();
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
        // A file name may hold any byte but '/' and NUL: escaped like the header's rig name.
        let name = frond_protocol::printable(&i.name);
        let state = match (i.state, &i.error) {
            ("torn", _) => format!("torn ({} bytes; `frond take repair {name}`)", i.torn_bytes),
            ("damaged", _) => format!(
                "damaged: {}; `frond take repair {name}`",
                i.damage.as_deref().unwrap_or("records skipped"),
            ),
            (_, Some(e)) => format!("corrupt: {e}"),
            (s, None) => s.to_string(),
        };
        writeln!(
            out,
            "{:<width$}  {:>8}  {:>9}  {:>10}  {:<8}  {}",
            name,
            i.frames,
            duration_text(i.duration_s),
            human_size(i.size_bytes),
            state,
            i.rig.as_deref().map_or("-".into(), frond_protocol::printable),
        )?;
    }
    Ok(())
}

/// A take's duration for `take list`: `12.34s`, or in scientific notation past a thousand
/// days, since a take's times are untrusted (one frame at t = 1e300 made a 300-digit column).
fn duration_text(seconds: f64) -> String {
    if seconds.abs() < 1e8 { format!("{seconds:.2}s") } else { format!("{seconds:.2e}s") }
}

/// The repaired bytes of a take (`frond_formats::take_repair`), errors as `anyhow`.
pub(crate) fn repaired_bytes(bytes: &[u8]) -> anyhow::Result<Option<(Vec<u8>, Repaired)>> {
    Ok(frond_formats::take_repair::repaired_bytes(bytes)?)
}

/// `repair`'s report: exactly what was dropped.
pub(crate) fn repair_report(path: &Path, r: &Repaired) -> String {
    r.report(&path.display().to_string())
}

pub(crate) fn repair(g: &Global, name: &str) -> anyhow::Result<()> {
    let path = resolve(g, name)?;
    let bytes = read_take_bytes(&path)?;
    let Some((fixed, r)) = repaired_bytes(&bytes).map_err(|e| anyhow!("{}: {e:#}", path.display()))? else {
        frond_binmain::outln!("{} is complete; nothing to repair", path.display())?;
        return Ok(());
    };
    // A take closed with an End record is not being recorded, however recent; one without may be.
    let age = std::fs::metadata(&path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|m| SystemTime::now().duration_since(m).ok())
        .unwrap_or(Duration::MAX);
    if !r.closed_before() && age < RECENT {
        bail!(
            "{} was modified {:.1} s ago and may still be recording; stop the recording \
             (`frond record stop`) or wait a few seconds, then repair",
            path.display(),
            age.as_secs_f64()
        );
    }
    write_atomically_bytes(&path, &fixed)?;
    frond_binmain::outln!("{}", repair_report(&path, &r))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use frond_formats::take::{TakeRecord, encode_file_start, encode_record};
    use frond_motion::{HandSample, PoseFrame, TakeFrame};
    use frond_protocol::ElementId;
    use frond_protocol::PoseFlags;

    use super::*;
    use crate::take_file::export_poses;

    fn frame(seq: u64, t: f64, flags: PoseFlags) -> TakeFrame {
        TakeFrame {
            seq,
            device_time_us: (t * 1e6) as u64,
            host_ns: seq,
            flags: flags.0,
            element: ElementId::GLOBAL,
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
        let frames = [frame(0, 0.0, PoseFlags::default()), frame(1, 0.1, PoseFlags::default())];
        let st = |b: &[u8]| scan_take(b).unwrap().state(b.len() as u64);
        assert_eq!(st(&take(&frames, true)), "complete");
        assert_eq!(st(&take(&frames, false)), "open");
        let mut torn = take(&frames, false);
        torn.extend_from_slice(&[9, 0, 0]);
        assert_eq!(st(&torn), "torn");
        let mut damaged = take(&frames, true);
        damaged[30] ^= 0x10;
        assert_eq!(st(&damaged), "damaged");
        // Nothing was ever written: not a take still recording.
        assert_eq!(st(b""), "empty");
    }

    #[test]
    fn export_skips_held_and_other_elements() {
        let mut leaf = frame(1, 0.0, PoseFlags::default());
        leaf.element = ElementId::FIRST_LAYER;
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
    fn durations_stay_a_column_wide() {
        assert_eq!(duration_text(12.345), "12.35s");
        assert_eq!(duration_text(99_999_999.0), "99999999.00s");
        assert_eq!(duration_text(1e300), "1.00e300s");
    }

    #[test]
    fn repair_cuts_the_tail_and_closes() {
        let frames = [frame(0, 0.0, PoseFlags::default()), frame(1, 0.1, PoseFlags::default())];
        let mut bytes = take(&frames, false);
        bytes.extend_from_slice(&[50, 0, 0, 0, 1, 2]); // half a record
        let (fixed, r) = repaired_bytes(&bytes).unwrap().unwrap();
        assert_eq!(
            r,
            Repaired { dropped_bytes: 6, skipped: vec![], lost_frames: 0, frames: 2, closed: true }
        );
        assert_eq!(fixed, take(&frames, true));
        assert!(repaired_bytes(&fixed).unwrap().is_none());
        let report = repair_report(Path::new("t.take"), &r);
        assert_eq!(
            report,
            "repaired t.take: dropped 6 torn bytes at the end; kept 2 frames, closed with an End record"
        );
        assert_eq!(
            Repaired { dropped_bytes: 0, skipped: vec![], lost_frames: 0, frames: 2005, closed: true }
                .report("k1.take"),
            "repaired k1.take: nothing dropped; kept 2005 frames, closed with an End record"
        );
    }

    #[test]
    fn repair_drops_damage_in_the_middle_and_says_what() {
        let frames: Vec<TakeFrame> = (0..4).map(|i| frame(i, i as f64, PoseFlags::default())).collect();
        let mut bytes = take(&frames, true);
        // Frame records are 127 bytes from offset 8: damage the second one's payload.
        bytes[8 + 127 + 40] ^= 0xff;
        let (fixed, r) = repaired_bytes(&bytes).unwrap().unwrap();
        let kept = [frames[0], frames[2], frames[3]];
        assert_eq!(fixed, take(&kept, true));
        assert_eq!(r.lost_frames, 1);
        assert_eq!(r.skipped.len(), 1);
        assert_eq!(
            repair_report(Path::new("t.take"), &r),
            "repaired t.take: dropped 127 bytes at offset 135 (checksum mismatch); 1 frame lost; kept 3 frames"
        );
        assert!(repaired_bytes(&fixed).unwrap().is_none());

        // A non-finite frame with a good checksum is dropped too, named.
        let mut bad = frames.clone();
        bad[1].pose.joints_deg[3][2] = f32::NAN;
        let (fixed, r) = repaired_bytes(&take(&bad, true)).unwrap().unwrap();
        assert_eq!(fixed, take(&kept, true));
        let report = repair_report(Path::new("t.take"), &r);
        assert!(report.contains("frame 1 (seq 1) holds NaN in pose joint 3"), "{report}");
        assert!(report.contains("1 frame lost"), "{report}");
    }

    #[test]
    fn an_empty_take_is_not_repaired_into_anything() {
        let err = repaired_bytes(b"").unwrap_err().to_string();
        assert!(err.contains("empty (0 bytes)"), "{err}");
    }

    #[test]
    fn sizes_read_naturally() {
        assert_eq!(human_size(12), "12 B");
        assert_eq!(human_size(3 * 1024 + 512), "3.5 KiB");
        assert_eq!(human_size(5 * 1_048_576), "5.0 MiB");
    }
}
