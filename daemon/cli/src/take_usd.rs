//! `frond take export NAME --usd -o FILE.usda`: a take as a USD (UsdSkel) layer
//! (`frond_motion::usd`): the rig's skinned mesh, skeleton and the take's animation at `--fps`
//! (default 30), on the take's rig (or `--rig`).

use std::path::{Path, PathBuf};

use anyhow::anyhow;
use frond_motion::usd::{UsdTake, write_usda};

use crate::args::Global;
use crate::takes::{check_resample, export_poses, resolve, warn_damage};
use crate::usage;

/// What `--usd` was asked.
pub(crate) struct UsdExport<'a> {
    pub name: &'a str,
    pub output: &'a Path,
    pub fps: Option<f64>,
    pub rig: Option<&'a Path>,
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
    let fps = a.fps.unwrap_or(crate::take_bvh::DEFAULT_BVH_FPS);
    if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
        return usage(format!("--fps must be above 0 and at most 1000 for USD, got {fps}"));
    }
    let path = resolve(g, a.name)?;
    let bytes = frond_motion::rig_files::read_take_file(&path)
        .map_err(|e| anyhow!("cannot read take {}: {}", path.display(), e.reason()))?;
    let scan = frond_motion::take::scan_take(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    warn_damage(&path, &scan);
    let rig_spec: PathBuf = match (a.rig, &scan.header) {
        (Some(r), _) => r.to_path_buf(),
        (None, Some(h)) if !h.rig_name.is_empty() => PathBuf::from(&h.rig_name),
        _ => return usage(format!("{} names no rig; give one with --rig NAME|FILE", path.display())),
    };
    let loaded = frond_motion::rig_files::load_rig(&rig_spec.to_string_lossy())?;
    let model = frond_motion::rig_files::plant_model(&loaded).map_err(|e| anyhow!("{e}"))?;
    let source = export_poses(&scan, None, false);
    if source.is_empty() {
        anyhow::bail!("{} has no frames of the main skeleton to export", path.display());
    }
    check_resample(&path.display().to_string(), &source, fps, a.force)?;
    let poses: Vec<_> = export_poses(&scan, Some(fps), false).iter().map(|p| p.joints_deg).collect();
    let joint_names: [String; 4] = std::array::from_fn(|j| loaded.rig.joints[j].name.clone());
    let h = scan.header.as_ref();
    let info = [
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
