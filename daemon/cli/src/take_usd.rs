//! `frond take export NAME --usd -o FILE.usda`: a take as a USD (UsdSkel) layer
//! (`frond_motion::usd`): the rig's skinned mesh, skeleton and the take's animation at `--fps`
//! (default 30), on the take's rig (or `--rig`).

use std::path::Path;

use anyhow::anyhow;
use frond_motion::usd::{UsdTake, write_usda};

use crate::args::Global;
use crate::takes::{TakeForFile, take_for_file};
use crate::usage;

/// What `--usd` was asked.
pub(crate) struct UsdExport<'a> {
    pub name: &'a str,
    pub output: &'a Path,
    pub fps: Option<f64>,
    pub rig: Option<&'a Path>,
    pub timecode_start: Option<&'a str>,
    pub force: bool,
}

/// Writes the USD layer.
pub(crate) fn export_usd(g: &Global, a: UsdExport<'_>) -> anyhow::Result<()> {
    match a.output.extension().and_then(|e| e.to_str()) {
        Some("usda") => {}
        Some("usdc" | "usd" | "usdz") => {
            return usage(format!(
                "{}: frond writes USD's text form; name it .usda (and convert with `usdcat IN.usda -o OUT.usdc` if a binary layer is wanted)",
                a.output.display()
            ));
        }
        _ => return usage(format!("{}: a USD layer is named .usda", a.output.display())),
    }
    let fps = TakeForFile::fps(a.fps, "USD")?;
    let take = take_for_file(g, a.name, a.rig)?;
    let (scan, loaded) = (&take.scan, &take.rig);
    let model = frond_motion::rig_files::plant_model(loaded).map_err(|e| anyhow!("{e}"))?;
    let poses: Vec<_> = take.resampled(fps, a.force)?.iter().map(|p| p.joints_deg).collect();
    let joint_names: [String; 4] = std::array::from_fn(|j| loaded.rig.joints[j].name.clone());
    let timecode = crate::takes::start_timecode(scan, fps, a.timecode_start)?;
    let h = scan.header.as_ref();
    let info = [
        ("timecode_start", timecode.map(|t| t.to_string()).unwrap_or_default()),
        ("timecode_rate", timecode.map(|t| t.rate.to_string()).unwrap_or_default()),
        ("take", a.name.to_string()),
        ("rig", loaded.rig.name.clone()),
        ("take_rig", h.map(|h| h.rig_name.clone()).unwrap_or_default()),
        ("calibration_id", h.map(|h| h.calibration_id.clone()).unwrap_or_default()),
        ("capture_rate_hz", h.map(|h| h.tick_rate_hz.to_string()).unwrap_or_default()),
        ("recorded_unix_s", h.map(|h| h.created_unix_s.to_string()).unwrap_or_default()),
    ];
    let take = UsdTake { name: &loaded.rig.name, joint_names: &joint_names, fps, info: &info };
    let mut out = String::new();
    write_usda(&take, &model, &poses, &mut out);
    crate::calibrate::write_atomically_bytes(a.output, out.as_bytes())?;
    println!("{}", a.output.display());
    Ok(())
}
