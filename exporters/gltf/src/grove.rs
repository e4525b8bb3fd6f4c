//! Groves: several plants in one document, each animated by its own take (seed 003, section 6.1,
//! "instancing": the walks `frond take walk --plants N` writes, or any takes at all), standing on
//! a square grid. Pure, like [`crate::bake`].

use frond_motion::mesh::PlantModel;

use crate::anim::Layers;
use crate::bake::{BakeOptions, BakeStats, Baked, Baker, Progress};
use crate::doc::{DocBuilder, Placement};
use crate::error::BakeError;
use crate::input::{LoadedRig, TakeInput};

/// Most plants of one grove (as many as a field may hold).
pub const MAX_GROVE_PLANTS: usize = 4096;
/// Largest grid spacing, metres.
pub const MAX_SPACING_M: f32 = 1000.0;

/// Where plant `i` of `n` stands: row-major on a grid of `ceil(sqrt(n))` columns, `spacing_m`
/// apart, centred on the origin (x across the columns, z across the rows).
pub fn grove_placement(i: usize, n: usize, spacing_m: f32) -> Placement {
    let cols = (n as f64).sqrt().ceil().max(1.0) as usize;
    let rows = n.div_ceil(cols).max(1);
    let (row, col) = (i / cols, i % cols);
    let x = (col as f32 - (cols - 1) as f32 / 2.0) * spacing_m;
    let z = (row as f32 - (rows - 1) as f32 / 2.0) * spacing_m;
    Placement::on_ground(x, z, 0.0, 1.0)
}

/// The default spacing of a rig's grove: its top joint's height, so plants bending by less than
/// about 45 degrees towards each other never touch.
pub fn default_spacing_m(rig: &LoadedRig) -> f32 {
    rig.rig.joints.last().map_or(0.3, |j| j.height_m).max(0.05)
}

impl Baker {
    /// One plant per take, plant `i` animated by every layer of `takes[i]` (secondary layers on
    /// its own element instances, assigned with seed `seed + i`), on one shared time base from
    /// 0 to the longest take's end; a shorter take holds its last pose. One animation, `name`.
    #[allow(clippy::too_many_arguments)]
    pub fn bake_grove(
        &mut self,
        rig: &LoadedRig,
        model: &PlantModel,
        takes: &[TakeInput],
        spacing_m: f32,
        name: &str,
        opts: &BakeOptions,
        progress: Progress<'_>,
    ) -> Result<Baked, BakeError> {
        let fps = opts.checked_fps()?;
        check_grove(takes, spacing_m, fps, opts)?;
        let (layers, mut notes) = grove_layers(rig, takes, fps)?;
        let keys = layers.iter().map(|l| l.times_s.len()).max().unwrap_or(1);
        let times_s: Vec<f64> = (0..keys).map(|k| k as f64 / fps).collect();

        let mut doc = DocBuilder::new(std::mem::take(&mut self.bin));
        let assets =
            doc.plant_assets(model, &crate::bake::joint_names(rig), &crate::bake::element_names(rig));
        let n = takes.len();
        let plants = doc.plants(&assets, &rig.rig.name, n, |i| grove_placement(i, n, spacing_m));
        let input = doc.times(&times_s);
        let mut anim = doc.begin_animation(input);
        let total = (keys * n) as u64;
        let mut channels = 0;
        for (i, ((take, l), nodes)) in takes.iter().zip(&layers).zip(&plants).enumerate() {
            let seed = opts.seed.wrapping_add(i as u64);
            let assignment = crate::bake::assign(rig, take, l, seed, &assets, &mut notes);
            for layer in &l.layers {
                let targets = crate::bake::targets(nodes, &assignment, layer.element);
                if targets.is_empty() {
                    continue;
                }
                self.poses.clear();
                let last = layer.poses.len() - 1;
                self.poses.extend((0..keys).map(|k| layer.poses[k.min(last)]));
                channels +=
                    crate::bake::joint_channels(&mut doc, &mut anim, &targets, &self.poses, &mut self.quats);
            }
            progress(((i + 1) * keys) as u64, total);
        }
        notes.sort();
        notes.dedup();
        let mut extras = crate::bake::extras_json(rig, &takes[0], fps);
        extras["grove"] = serde_json::json!({
            "takes": takes.iter().map(|t| t.name.as_str()).collect::<Vec<_>>(),
            "spacing_m": spacing_m,
            "seed": opts.seed,
        });
        let extras = gltf_json::extras::RawValue::from_string(extras.to_string()).ok();
        doc.end_animation(anim, name, extras.clone());
        let (root, bin) = doc.finish(extras);
        Ok(Baked {
            root,
            bin,
            notes,
            stats: BakeStats { plants: n, keys, channels, vertices: assets.vertices },
        })
    }
}

/// The grove's options and budgets, checked before anything is built: 1 to
/// [`MAX_GROVE_PLANTS`] takes, a spacing within (0, [`MAX_SPACING_M`]], and the keys of every
/// take within the per-channel limit and of all of them within the resampling limit.
fn check_grove(takes: &[TakeInput], spacing_m: f32, fps: f64, opts: &BakeOptions) -> Result<(), BakeError> {
    if takes.is_empty() || takes.len() > MAX_GROVE_PLANTS {
        return Err(BakeError::Option {
            option: "--take",
            reason: format!("a grove has 1 to {MAX_GROVE_PLANTS} takes, got {}", takes.len()),
        });
    }
    if !(spacing_m.is_finite() && spacing_m > 0.0 && spacing_m <= MAX_SPACING_M) {
        return Err(BakeError::Option {
            option: "--spacing",
            reason: format!("must be metres above 0 and at most {MAX_SPACING_M}, got {spacing_m}"),
        });
    }
    // Budgets first: keys per channel, and keys over every plant.
    let hard = frond_motion::take::MAX_RESAMPLED_FRAMES as u64;
    let (limit, hint) = opts.key_limit();
    let mut all_keys = 0u64;
    for take in takes {
        let (keys, _) = Layers::plan(&take.frames, fps);
        all_keys = all_keys.saturating_add(keys);
        if keys > limit || all_keys > hard {
            let (keys, limit) = if keys > limit { (keys, limit) } else { (all_keys, hard) };
            return Err(BakeError::TooManyKeys { name: take.name.clone(), keys, fps, limit, hint });
        }
    }
    Ok(())
}

/// Every take's layers resampled at `fps`, and the notes about them: the take's own (rig
/// mismatch, damage) and, for a take whose keys are not uniform in time (a step longer than
/// frond interpolates over), that its keys follow its frames.
fn grove_layers(
    rig: &LoadedRig,
    takes: &[TakeInput],
    fps: f64,
) -> Result<(Vec<Layers>, Vec<String>), BakeError> {
    let mut notes = Vec::new();
    let mut layers = Vec::with_capacity(takes.len());
    for take in takes {
        let l = Layers::from_frames(&take.frames, fps)
            .ok_or_else(|| BakeError::TakeEmpty { name: take.name.clone() })?;
        notes.extend(crate::bake::take_notes(rig, take));
        layers.push(l);
    }
    for (take, l) in takes.iter().zip(&layers) {
        let uniform = l.times_s.iter().enumerate().all(|(k, &t)| (t - k as f64 / fps).abs() < 1e-6);
        if !uniform {
            notes.push(format!(
                "take `{}` has steps in time longer than {} s: its keys follow its frames, not its clock",
                take.name,
                frond_motion::take::MAX_INTERPOLATED_GAP_S
            ));
        }
    }
    Ok((layers, notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plants_stand_on_a_centred_square_grid() {
        // 5 plants: 3 columns, 2 rows, 0.5 m apart, centred.
        let at: Vec<[f32; 3]> = (0..5).map(|i| grove_placement(i, 5, 0.5).translation_m).collect();
        assert_eq!(
            at,
            vec![
                [-0.5, 0.0, -0.25],
                [0.0, 0.0, -0.25],
                [0.5, 0.0, -0.25],
                [-0.5, 0.0, 0.25],
                [0.0, 0.0, 0.25]
            ]
        );
        assert_eq!(grove_placement(0, 1, 2.0).translation_m, [0.0; 3]);
    }
}
