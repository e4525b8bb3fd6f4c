//! `frond take export --align TAKE TAKE...`: several takes on one stage timeline (the takes of
//! one `frond record start NAME --stage STAGE`, or takes recorded on one host), as JSON Lines:
//! every main-skeleton frame of every take in timeline order,
//! `{"seq":..,"t":..,"joints":[..],"take":"NAME","stage_ns":..,"host_ns":..}`, where `t` is
//! seconds from the first frame of all the takes, `stage_ns` the frame's instant on the timeline
//! (nanoseconds since 1970, on the recorder's clock) and `host_ns` its own host's monotonic stamp.

use std::io::Write;

use anyhow::anyhow;
use frond_formats::jsonl::write_pose_line;
use frond_motion::PoseFrame;
use frond_motion::timeline::{AlignError, align};

use crate::error::usage;
use crate::global::Global;
use crate::takes::{read_scan, resolve, warn_damage};

/// Most takes one alignment reads.
pub(crate) const MAX_ALIGNED_TAKES: usize = 64;

/// Prints the takes `names` on one timeline (see the module doc).
pub(crate) fn export_aligned(g: &Global, names: &[String], include_held: bool) -> anyhow::Result<()> {
    if names.len() < 2 {
        return usage("--align puts two or more takes on one timeline: name them all");
    }
    if names.len() > MAX_ALIGNED_TAKES {
        return usage(format!("--align takes at most {MAX_ALIGNED_TAKES} takes, got {}", names.len()));
    }
    let mut scans = Vec::with_capacity(names.len());
    for name in names {
        let path = resolve(g, name)?;
        let (scan, _) = read_scan(&path)?;
        warn_damage(&path, &scan);
        scans.push(scan);
    }
    let refs: Vec<&_> = scans.iter().collect();
    let frames = align(&refs, include_held).map_err(|e| match e {
        AlignError::NoClock { take } => anyhow!(
            "take {:?} has no recording clock (made offline, or by an old frond), so it cannot be aligned",
            names[take]
        ),
    })?;
    let Some(origin) = frames.first().map(|f| f.stage_ns) else { return Ok(()) };
    let quoted: Vec<String> =
        names.iter().map(|n| serde_json::Value::String(n.clone()).to_string()).collect();
    let mut out = frond_binmain::StdoutWriter::lock();
    let mut line = String::with_capacity(256);
    for f in &frames {
        line.clear();
        let t = (f.stage_ns - origin) as f64 / 1e9;
        write_pose_line(&PoseFrame { t, joints_deg: f.frame.pose.joints_deg }, Some(f.frame.seq), &mut line);
        if line.ends_with('}') {
            line.pop();
            use std::fmt::Write as _;
            let _ = write!(
                line,
                ",\"take\":{},\"stage_ns\":{},\"host_ns\":{}}}",
                quoted[f.take], f.stage_ns, f.frame.host_ns
            );
        }
        line.push('\n');
        out.write_all(line.as_bytes())?;
    }
    out.flush()?;
    Ok(())
}
