//! Reading the soak's takes back and comparing them with what a healthy subscriber saw.

use std::path::Path;

use serde::Serialize;

use super::clients::push_run;

/// The take as read back after the run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct TakeFigures {
    pub path: String,
    pub frames: u64,
    pub frames_reported: u64,
    pub recorder_dropped: u64,
    pub ended: bool,
    pub torn_bytes: u64,
    /// Places where the take's frame sequence differs from the fresh (not `held`) frames flagged
    /// `recording` that healthy-1 received: frames missing from the take, or extra ones.
    pub seq_breaks: u64,
    /// Fresh recorded frames healthy-1 received that are not in the take.
    pub missing_frames: u64,
    pub error: Option<String>,
}

/// Which of the recorded frames a subscriber saw a take must hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Part {
    /// Every one up to the take's last frame (a take cut by a fault, or the first of several).
    UpToItsEnd,
    /// Every one from the take's first frame on.
    FromItsStart,
}

/// The runs of `seen` inside `lo..=hi`.
fn clip_runs(seen: &[(u64, u64)], lo: u64, hi: u64) -> Vec<(u64, u64)> {
    seen.iter()
        .filter_map(|&(start, len)| {
            let (a, b) = (start.max(lo), (start + len - 1).min(hi));
            (a <= b).then(|| (a, b - a + 1))
        })
        .collect()
}

/// Reads the take back and compares its frames with `part` of `seen`, the fresh recorded frames
/// a healthy subscriber received (as runs).
pub(super) fn read_take(t: &mut TakeFigures, seen: &[(u64, u64)], part: Part) {
    let bytes = match frond_formats::rig_files::read_take_file(Path::new(&t.path)) {
        Ok(b) => b,
        Err(e) => {
            t.error = Some(format!("cannot read: {}", e.reason()));
            return;
        }
    };
    match frond_formats::scan_take(&bytes) {
        Ok(scan) => {
            let mut runs = Vec::new();
            let mut increasing = true;
            let mut last: Option<u64> = None;
            for f in scan.frames.iter().filter(|f| f.element.is_global()) {
                increasing &= last.is_none_or(|l| f.seq > l);
                last = Some(f.seq);
                push_run(&mut runs, f.seq);
            }
            t.frames = runs.iter().map(|r| r.1).sum();
            t.ended = scan.ended;
            t.torn_bytes = scan.torn_bytes;
            if !increasing {
                t.error = Some("frame sequence numbers do not increase".into());
            }
            let (first, last) = (runs.first().map_or(0, |r| r.0), runs.last().map_or(0, |r| r.0 + r.1 - 1));
            let seen = match part {
                Part::UpToItsEnd => clip_runs(seen, 0, last),
                Part::FromItsStart => clip_runs(seen, first, u64::MAX),
            };
            // Differences between the two run lists: runs present in one and not the other.
            let (a, b): (std::collections::HashSet<_>, std::collections::HashSet<_>) =
                (runs.iter().collect(), seen.iter().collect());
            t.seq_breaks = a.symmetric_difference(&b).count() as u64;
            let seen_total: u64 = seen.iter().map(|r| r.1).sum();
            t.missing_frames = seen_total.saturating_sub(t.frames);
        }
        Err(e) => t.error = Some(e.to_string()),
    }
}
