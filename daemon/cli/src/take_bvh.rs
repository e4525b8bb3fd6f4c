//! `frond take export NAME --bvh -o FILE.bvh [--field field.json --duration S]`: a take (or every
//! plant of a field) as BVH, the mocap exchange format (`frond_formats::bvh`), at `--fps`
//! (default 30, the seed's rate), on the take's rig (or `--rig`).

use std::path::Path;

use anyhow::anyhow;
use frond_formats::bvh::{self, BvhPlant};
use frond_formats::field_json::FieldJson;
use frond_motion::clip::Clip;
use frond_motion::field::{Field, MAX_FIELD_FILE_BYTES};
use frond_motion::rig::Rig;
use frond_motion::sample::JOINTS;
use frond_motion::sim::node_heights_m;

use crate::error::usage;
use crate::global::Global;
use crate::take_file::{MAX_EXPORT_FRAMES, TakeForFile, take_for_file};

/// Longest field export, seconds.
const MAX_FIELD_DURATION_S: f64 = 24.0 * 3600.0;

/// What `--bvh` was asked.
pub(crate) struct BvhExport<'a> {
    pub name: &'a str,
    pub output: &'a Path,
    pub fps: Option<f64>,
    pub rig: Option<&'a Path>,
    pub field: Option<&'a Path>,
    pub duration_s: Option<f64>,
    pub force: bool,
}

fn plant(rig: &Rig, prefix: String, position_m: [f64; 2], scale: f64) -> BvhPlant {
    BvhPlant {
        prefix,
        joint_names: std::array::from_fn(|j| rig.joints[j].name.clone()),
        heights_m: node_heights_m(std::array::from_fn(|j| rig.joints[j].height_m), &rig.mesh),
        position_m,
        scale,
    }
}

/// Writes the BVH file.
pub(crate) fn export_bvh(g: &Global, a: BvhExport<'_>) -> anyhow::Result<()> {
    let fps = TakeForFile::fps(a.fps, "BVH")?;
    if let Some(d) = a.duration_s
        && !(d.is_finite() && d > 0.0 && d <= MAX_FIELD_DURATION_S)
    {
        return usage(format!("--duration must be in (0, {MAX_FIELD_DURATION_S}] seconds, got {d}"));
    }
    let take = take_for_file(g, a.name, a.rig)?;
    let rig = &take.rig.rig;
    let mut out = String::new();
    match (a.field, a.duration_s) {
        (None, None) => {
            let poses = take.resampled(fps, a.force)?;
            let plants = [plant(rig, String::new(), [0.0, 0.0], 1.0)];
            bvh::begin(&plants, poses.len(), 1.0 / fps, &mut out);
            for p in &poses {
                bvh::push_frame(&plants, std::slice::from_ref(&p.joints_deg), &mut out);
            }
        }
        (Some(field_path), Some(duration_s)) => {
            let text = frond_formats::rig_files::read_small_text(field_path, MAX_FIELD_FILE_BYTES)
                .map_err(|e| anyhow!("cannot read field {}: {}", field_path.display(), e.reason()))?;
            let field = Field::from_json(&text).map_err(|e| anyhow!("{}: {e}", field_path.display()))?;
            if field.plants.is_empty() {
                anyhow::bail!("{}: the field has no plants", field_path.display());
            }
            // Counted uncapped: a capped count would pass a too-long export, cut short.
            let frames = frond_motion::clip::frames_needed(duration_s, fps);
            let values = frames.saturating_mul(field.plants.len() as u64);
            let limit =
                if a.force { frond_motion::take::MAX_RESAMPLED_FRAMES as u64 } else { MAX_EXPORT_FRAMES };
            if values > limit {
                return usage(format!(
                    "{} plants x {frames} frames is {values} plant-frames, more than {limit}{}",
                    field.plants.len(),
                    if a.force { " (the hard limit)" } else { "; pass --force to go past it" }
                ));
            }
            let frames = frames as usize;
            let what = take.path.display().to_string();
            crate::take_file::check_resample(&what, &take.source, field.fps, a.force)?;
            let clip = Clip::from_poses(&frond_motion::resample(&take.source, field.fps), field.fps);
            let digits = field.plants.len().to_string().len();
            let plants: Vec<BvhPlant> = field
                .plants
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let prefix = format!("{}_{i:0digits$}", rig.name);
                    plant(rig, prefix, p.position_m.map(f64::from), f64::from(p.scale))
                })
                .collect();
            bvh::begin(&plants, frames, 1.0 / fps, &mut out);
            let mut row: Vec<[[f32; 3]; JOINTS]> = vec![[[0.0; 3]; JOINTS]; plants.len()];
            for k in 0..frames {
                let t = k as f64 / fps;
                for (i, pose) in row.iter_mut().enumerate() {
                    *pose = field.pose(i, &clip, t);
                }
                bvh::push_frame(&plants, &row, &mut out);
            }
        }
        _ => return usage("--field and --duration go together"),
    }
    crate::calibrate::write_atomically_bytes(a.output, out.as_bytes())?;
    frond_binmain::outln!("{}", a.output.display())?;
    Ok(())
}
