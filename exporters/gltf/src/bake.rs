//! Baking: a take (all its layers) on one plant, or on every plant of a field, into a glTF
//! document held in memory. Pure: the inputs come from [`crate::input`] (or a test), the output
//! goes to [`crate::output`].

use gltf_json as json;
use serde_json::json;

use frond_motion::JOINTS;
use frond_motion::clip::Clip;
use frond_motion::mesh::PlantModel;
use frond_protocol::{ElementId, printable};

use crate::anim::{Joints, Layers, check_fps, push_joint_quats};
use crate::doc::{AnimationBuilder, DocBuilder, Placement, PlantAssets, PlantNodes};
use crate::error::BakeError;
use crate::field::Field;
use crate::input::{LoadedRig, TakeInput};
use frond_motion::layers::{assign_layers, layer_kind};

/// Options shared by every bake.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BakeOptions {
    /// Key rate, frames per second (the seed's authoring rate, 30, by default).
    pub fps: f64,
    /// Seed of the random assignment of secondary layers to similar element instances.
    pub seed: u64,
    /// Bake past [`MAX_BAKE_KEYS`] (never past `frond_motion::take::MAX_RESAMPLED_FRAMES`).
    pub force: bool,
}

impl BakeOptions {
    /// The key rate, checked (named `--fps` in the error).
    pub(crate) fn checked_fps(&self) -> Result<f64, BakeError> {
        check_fps(self.fps).map_err(|e| BakeError::Option { option: "--fps", reason: e.to_string() })
    }

    /// Keys a channel may have, and what an error past it says: [`MAX_BAKE_KEYS`], or with
    /// `force` the hard limit.
    pub(crate) fn key_limit(&self) -> (u64, &'static str) {
        if self.force {
            (frond_motion::take::MAX_RESAMPLED_FRAMES as u64, " (the hard limit)")
        } else {
            (MAX_BAKE_KEYS, "; pass --force to go past it")
        }
    }
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions { fps: 30.0, seed: 0, force: false }
    }
}

/// Keys a take bake may have without `--force` (10 hours at 30 FPS, as `frond take export`).
pub const MAX_BAKE_KEYS: u64 = 1_080_000;

/// Counts describing a bake.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BakeStats {
    /// Plants (skins) in the document.
    pub plants: usize,
    /// Keys per channel.
    pub keys: usize,
    /// Rotation channels.
    pub channels: usize,
    /// Vertices of the shared mesh.
    pub vertices: usize,
}

/// A baked document: JSON, binary buffer, and notes worth telling the user.
#[derive(Debug, Clone)]
pub struct Baked {
    /// The glTF JSON. Buffer 0 is [`Baked::bin`] (no `uri` until written as `.gltf`).
    pub root: json::Root,
    /// The binary buffer, 4-byte aligned.
    pub bin: Vec<u8>,
    /// Warnings that did not stop the bake (rig mismatch, torn tail, unknown layers).
    pub notes: Vec<String>,
    /// Counts.
    pub stats: BakeStats,
}

/// Progress callback: `(done, total)` in keys.
pub type Progress<'a> = &'a mut dyn FnMut(u64, u64);

/// Bakes takes into documents, reusing its buffers from one bake to the next (give a finished
/// [`Baked`] back with [`Baker::recycle`]).
#[derive(Debug, Default)]
pub struct Baker {
    pub(crate) bin: Vec<u8>,
    pub(crate) quats: Vec<[f32; 4]>,
    pub(crate) poses: Vec<Joints>,
}

impl Baker {
    /// A baker with empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    /// Returns a document's buffer for reuse.
    pub fn recycle(&mut self, baked: Baked) {
        if baked.bin.capacity() > self.bin.capacity() {
            self.bin = baked.bin;
        }
    }

    /// One plant animated by every layer of a take: element 0 on the rig's joints, layer `k + 1`
    /// on every instance of the rig's secondary element `k`. One animation, named after the take.
    pub fn bake_take(
        &mut self,
        rig: &LoadedRig,
        model: &PlantModel,
        take: &TakeInput,
        opts: &BakeOptions,
        progress: Progress<'_>,
    ) -> Result<Baked, BakeError> {
        let fps = opts.checked_fps()?;
        // The budget is checked before any key is allocated.
        let (keys, discontinuities) = Layers::plan(&take.frames, fps);
        let (limit, hint) = opts.key_limit();
        if keys > limit {
            return Err(BakeError::TooManyKeys { name: take.name.clone(), keys, fps, limit, hint });
        }
        let layers = Layers::from_frames(&take.frames, fps)
            .ok_or_else(|| BakeError::TakeEmpty { name: take.name.clone() })?;
        let mut notes = take_notes(rig, take);
        if discontinuities > 0 {
            notes.push(format!(
                "take `{}` has {discontinuities} step{} in time longer than {} s: each is one key, \
                 not interpolated",
                take.name,
                if discontinuities == 1 { "" } else { "s" },
                frond_motion::take::MAX_INTERPOLATED_GAP_S
            ));
        }
        let mut doc = DocBuilder::new(std::mem::take(&mut self.bin));
        let assets = doc.plant_assets(model, &joint_names(rig), &element_names(rig));
        let assignment = assign(rig, take, &layers, opts.seed, &assets, &mut notes);
        let nodes = doc.plant(&assets, &rig.rig.name, &Placement::default());
        let input = doc.times(&layers.times_s);
        let mut anim = doc.begin_animation(input);
        let keys = layers.times_s.len();
        let total = (keys * layers.layers.len()) as u64;
        let mut channels = 0;
        for (n, layer) in layers.layers.iter().enumerate() {
            let targets = targets(&nodes, &assignment, layer.element);
            channels += joint_channels(&mut doc, &mut anim, &targets, &layer.poses, &mut self.quats);
            progress(((n + 1) * keys) as u64, total);
        }
        let extras = take_extras(rig, take, fps, None);
        doc.end_animation(anim, &take.name, extras.clone());
        let (root, bin) = doc.finish(extras);
        Ok(Baked {
            root,
            bin,
            notes,
            stats: BakeStats { plants: 1, keys, channels, vertices: assets.vertices },
        })
    }

    /// Every plant of a field (seed 000, section 6.2): each plant its own skeleton and skin over
    /// the one shared mesh, animated by the take delayed per plant with its bend turned to the
    /// force (Eq. 6-7, section 6.3 (1)(b), see [`Field::pose_at`]); secondary layers get the same
    /// delayed lookup. `duration_s` long from 0, one animation named after the take.
    #[allow(clippy::too_many_arguments)]
    pub fn bake_field(
        &mut self,
        rig: &LoadedRig,
        model: &PlantModel,
        take: &TakeInput,
        field: &Field,
        duration_s: f64,
        opts: &BakeOptions,
        progress: Progress<'_>,
    ) -> Result<Baked, BakeError> {
        let fps = opts.checked_fps()?;
        if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 24.0 * 3600.0) {
            return Err(BakeError::Option {
                option: "--duration",
                reason: format!("must be a number of seconds above 0 and at most 86400, got {duration_s}"),
            });
        }
        // The budget before any key is allocated, counted uncapped: a capped count would bake a
        // too-long field cut short. Keys per channel, and keys over every plant.
        let keys = frond_motion::clip::frames_needed(duration_s, fps);
        let all_keys = keys.saturating_mul(field.plants().len() as u64);
        let (limit, hint) = opts.key_limit();
        let hard = frond_motion::take::MAX_RESAMPLED_FRAMES as u64;
        if keys > limit || all_keys > hard {
            let (keys, limit) = if keys > limit { (keys, limit) } else { (all_keys, hard) };
            return Err(BakeError::TooManyKeys { name: take.name.clone(), keys, fps, limit, hint });
        }
        // The take's layers at the field's own frame rate: the clips plants look up.
        let layers = Layers::from_frames(&take.frames, field.fps())
            .ok_or_else(|| BakeError::TakeEmpty { name: take.name.clone() })?;
        let clips: Vec<Clip> =
            layers.layers.iter().map(|l| Clip::from_joints(l.poses.iter().copied(), field.fps())).collect();
        let mut notes = take_notes(rig, take);
        let f = &field.field;
        if !f.take.is_empty() && f.take != take.name {
            notes.push(format!(
                "field {} was laid out for take `{}`; baking take `{}`",
                field.origin, f.take, take.name
            ));
        }
        if layers.times_s.len() < f.frames {
            notes.push(format!(
                "field {} expects {} frames of the take, it has {}: plants hold the last frame past its end (bake a looped take: frond take loop)",
                field.origin,
                f.frames,
                layers.times_s.len()
            ));
        }
        let keys = keys as usize;
        let times_s: Vec<f64> = (0..keys).map(|k| k as f64 / fps).collect();

        let mut doc = DocBuilder::new(std::mem::take(&mut self.bin));
        let assets = doc.plant_assets(model, &joint_names(rig), &element_names(rig));
        let assignment = assign(rig, take, &layers, opts.seed, &assets, &mut notes);
        let n_plants = field.plants().len();
        let plants = doc.plants(&assets, &rig.rig.name, n_plants, |i| field.placement(i));
        let input = doc.times(&times_s);
        let mut anim = doc.begin_animation(input);
        let total = (keys * plants.len()) as u64;
        let mut channels = 0;
        for (i, nodes) in plants.iter().enumerate() {
            for (layer, clip) in layers.layers.iter().zip(&clips) {
                let targets = targets(nodes, &assignment, layer.element);
                if targets.is_empty() {
                    continue;
                }
                self.poses.clear();
                self.poses.extend(times_s.iter().map(|&t| field.pose_at(i, clip, t)));
                channels += joint_channels(&mut doc, &mut anim, &targets, &self.poses, &mut self.quats);
            }
            progress(((i + 1) * keys) as u64, total);
        }
        let extras = take_extras(rig, take, fps, Some(field));
        doc.end_animation(anim, &take.name, extras.clone());
        let (root, bin) = doc.finish(extras);
        Ok(Baked {
            root,
            bin,
            notes,
            stats: BakeStats { plants: plants.len(), keys, channels, vertices: assets.vertices },
        })
    }
}

/// Keys a capture of `span_s` seconds of a field of `plants` plants bakes into at `fps`, checked
/// against the limits before anything is allocated: [`MAX_BAKE_KEYS`] keys a channel (with
/// `force`, `frond_motion::take::MAX_RESAMPLED_FRAMES`), and `MAX_RESAMPLED_FRAMES` keys over
/// every plant (as [`Baker::bake_field`]). The error names the numbers and the longest capture,
/// and the highest rate, that fit.
pub fn live_field_keys(
    field: &str,
    plants: usize,
    span_s: f64,
    fps: f64,
    opts: &BakeOptions,
) -> Result<u64, BakeError> {
    let keys = frond_motion::clip::frames_needed(span_s.max(0.0), fps);
    let (limit, hint) = opts.key_limit();
    let hard = frond_motion::take::MAX_RESAMPLED_FRAMES as u64;
    let plants64 = plants.max(1) as u64;
    let max_keys = limit.min(hard / plants64);
    if keys <= max_keys {
        return Ok(keys);
    }
    let usable = max_keys.saturating_sub(1) as f64;
    let why = if limit <= hard / plants64 {
        format!("the limit of a channel{hint}")
    } else {
        format!("{hard} keys over every plant, of {JOINTS} joint rotations each")
    };
    Err(BakeError::LiveFieldTooLong(Box::new(crate::error::LiveFieldTooLong {
        field: printable(field).into_owned(),
        plants,
        keys,
        span_s,
        fps,
        max_keys,
        why,
        max_s: usable / fps,
        max_fps: fitting_fps(span_s, fps, max_keys).unwrap_or(0.0),
    })))
}

/// The highest rate below `fps`, in whole hundredths of a frame a second, at which `span_s`
/// needs at most `max_keys` keys ([`frond_motion::clip::frames_needed`]); `None` when not even
/// 0.01 FPS does.
fn fitting_fps(span_s: f64, fps: f64, max_keys: u64) -> Option<f64> {
    let fits = |hundredths: f64| frond_motion::clip::frames_needed(span_s, hundredths / 100.0) <= max_keys;
    // `frames_needed` is floor(span_s * fps + FRAME_TOLERANCE) + 1, so a rate fits when
    // span_s * fps + FRAME_TOLERANCE < max_keys; a step or two down settles the rounding.
    let bound = (max_keys as f64 - frond_motion::clip::FRAME_TOLERANCE) / span_s.max(1e-9);
    let mut hundredths = (bound * 100.0).min(fps * 100.0).floor();
    for _ in 0..4 {
        if hundredths < 1.0 {
            return None;
        }
        if fits(hundredths) {
            return Some(hundredths / 100.0);
        }
        hundredths -= 1.0;
    }
    None
}

pub(crate) fn joint_names(rig: &LoadedRig) -> [String; JOINTS] {
    std::array::from_fn(|i| rig.rig.joints[i].name.clone())
}

pub(crate) fn element_names(rig: &LoadedRig) -> Vec<String> {
    rig.rig.elements.iter().map(|e| e.name.clone()).collect()
}

/// Writes a rotation channel for each joint of each joint set in `targets`, keyed by `poses`
/// (one per key time); returns how many. `quats` is scratch space.
pub(crate) fn joint_channels(
    doc: &mut DocBuilder,
    anim: &mut AnimationBuilder,
    targets: &[[gltf_json::Index<gltf_json::Node>; JOINTS]],
    poses: &[Joints],
    quats: &mut Vec<[f32; 4]>,
) -> usize {
    let mut channels = 0;
    for joints in targets {
        for (j, node) in joints.iter().enumerate() {
            quats.clear();
            push_joint_quats(poses.iter().map(|p| p[j]), quats);
            doc.rotation_channel(anim, *node, quats);
            channels += 1;
        }
    }
    channels
}

/// The joint sets a layer animates: the main joints for layer 0, the element instances it was
/// assigned to otherwise.
pub(crate) fn targets(
    nodes: &PlantNodes,
    assignment: &[Option<ElementId>],
    layer: ElementId,
) -> Vec<[gltf_json::Index<gltf_json::Node>; JOINTS]> {
    if layer.is_global() {
        return vec![nodes.main];
    }
    nodes.elements.iter().zip(assignment).filter(|(_, a)| **a == Some(layer)).map(|(j, _)| *j).collect()
}

/// Which layer animates each element instance of the plant (in `assets.elements` order), by
/// `frond_motion::layers::assign_layers` (seed 000, section 5.3: by kind name, at random among
/// several layers of one kind).
pub(crate) fn assign(
    rig: &LoadedRig,
    take: &TakeInput,
    layers: &Layers,
    seed: u64,
    assets: &PlantAssets,
    notes: &mut Vec<String>,
) -> Vec<Option<ElementId>> {
    let named: Vec<(ElementId, String)> = layers
        .layers
        .iter()
        .filter(|l| !l.element.is_global())
        .map(|l| (l.element, take.layer_name(l.element, &rig.rig)))
        .collect();
    let chosen = assign_layers(&rig.rig.elements, &named, seed);
    for (id, name) in &named {
        if !rig.rig.elements.iter().any(|e| e.name == layer_kind(name)) {
            notes.push(format!(
                "take layer {id} `{}` matches no secondary element of rig `{}`; ignored",
                printable(name),
                printable(&rig.rig.name)
            ));
        }
    }
    assets
        .elements
        .iter()
        .map(|e| {
            chosen.iter().find(|a| a.element == e.element && a.instance == e.instance).and_then(|a| a.layer)
        })
        .collect()
}

pub(crate) fn take_notes(rig: &LoadedRig, take: &TakeInput) -> Vec<String> {
    let mut notes = Vec::new();
    if let Some(h) = &take.header
        && !h.rig_name.is_empty()
        && h.rig_name != rig.rig.name
    {
        // The header's name is the take file's: escaped, it cannot reach a terminal as an
        // escape sequence or forge a line of output.
        notes.push(format!(
            "take `{}` was recorded with rig `{}`; baking it on rig `{}`",
            printable(&take.name),
            printable(&h.rig_name),
            printable(&rig.rig.name)
        ));
    }
    if let Some(damage) = &take.damage {
        notes.push(format!("take `{}` is damaged: {damage}; baked the readable frames", take.name));
    }
    if let Some(k) = frond_motion::take::main_element(&take.frames).filter(|k| !k.is_global()) {
        notes.push(format!(
            "take `{}` is a layer take (no frames of the plant, element 0): its layers from element {k} move on a plant at rest",
            printable(&take.name)
        ));
    }
    if take.torn_bytes > 0 {
        notes.push(format!(
            "take `{}` ends in a torn tail of {} bytes (still being written, or a crash); baked the frames before it",
            take.name, take.torn_bytes
        ));
    }
    notes
}

/// `extras` written on the asset and the animation, so a file can be traced back to its take.
fn take_extras(
    rig: &LoadedRig,
    take: &TakeInput,
    fps: f64,
    field: Option<&Field>,
) -> Option<Box<json::extras::RawValue>> {
    let mut v = extras_json(rig, take, fps);
    if let Some(f) = field {
        v["field"] = json!({
            "source": f.origin,
            "plants": f.plants().len(),
            "fps": f.fps(),
            "take": f.field.take,
            "direction_deg": f.field.direction_deg,
            "speed_m_s": f.field.speed_m_s,
            "seed": f.field.seed,
        });
    }
    json::extras::RawValue::from_string(v.to_string()).ok()
}

/// The take's provenance as extras: name, rigs, capture rate, calibration, filter, versions.
pub(crate) fn extras_json(rig: &LoadedRig, take: &TakeInput, fps: f64) -> serde_json::Value {
    let h = take.header.as_ref();
    json!({
        "take": take.name,
        "rig": rig.rig.name,
        "take_rig": h.map(|h| h.rig_name.clone()),
        "capture_rate_hz": h.map(|h| h.tick_rate_hz),
        "calibration_id": h.map(|h| h.calibration_id.clone()),
        "filter": h.map(|h| h.filter.clone()),
        "daemon_version": h.map(|h| h.daemon_version.clone()),
        "recorded_unix_s": h.map(|h| h.created_unix_s),
        "bake_fps": fps,
        "timecode_start": h.and_then(|h| h.start_timecode(&take.frames, fps)).map(|t| t.to_string()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_live_field_budget_names_the_numbers_and_what_fits() {
        let opts = BakeOptions::default();
        assert_eq!(live_field_keys("m", 10_000, 10.0, 30.0, &opts).unwrap(), 301);
        // 10,000 plants: at most 1677 keys each (16,777,216 over every plant).
        let e = live_field_keys("m", 10_000, 60.0, 30.0, &opts).unwrap_err().to_string();
        assert!(e.contains("field `m`: 10000 plants x 1801 keys (60.0 s at 30 FPS)"), "{e}");
        assert!(e.contains("at most 1677 keys a plant (16777216 keys over every plant"), "{e}");
        assert!(!e.contains("--force"), "{e}");
        assert!(e.contains("capture at most 55.87 s") && e.contains("--fps 27.94"), "{e}");
        // One plant: the per-channel limit, which --force lifts.
        let e = live_field_keys("m", 1, 40_000.0, 30.0, &opts).unwrap_err().to_string();
        assert!(e.contains("at most 1080000 keys a plant (the limit of a channel; pass --force"), "{e}");
        let forced = BakeOptions { force: true, ..opts };
        assert_eq!(live_field_keys("m", 1, 40_000.0, 30.0, &forced).unwrap(), 1_200_001);
    }

    fn too_long(
        plants: usize,
        span_s: f64,
        fps: f64,
        opts: &BakeOptions,
    ) -> Option<crate::error::LiveFieldTooLong> {
        match live_field_keys("m", plants, span_s, fps, opts) {
            Err(BakeError::LiveFieldTooLong(t)) => Some(*t),
            Err(e) => panic!("{e}"),
            Ok(_) => None,
        }
    }

    #[test]
    fn a_capture_past_the_limit_has_the_highest_rate_that_bakes_it_whole() {
        let opts = BakeOptions::default();
        // By hand: 10,000 plants may have 1677 keys; 60 s at 27.94 FPS is 1676.4 frames, so keys
        // 0..=1676 (1677); at 27.95 FPS 1677.0 frames, 1678 keys.
        let t = too_long(10_000, 60.0, 30.0, &opts).unwrap();
        assert_eq!(t.fitting_fps(), Some(27.94));
        assert_eq!(live_field_keys("m", 10_000, 60.0, 27.94, &opts).unwrap(), 1677);
        assert!(live_field_keys("m", 10_000, 60.0, 27.95, &opts).is_err());
        // Over a grid of fields, spans and rates: every rate given is the highest in hundredths
        // that fits, and below the rate asked.
        let forced = BakeOptions { force: true, ..opts };
        let mut seen = 0;
        for o in [&opts, &forced] {
            for plants in [1, 7, 400, 10_000, 100_000] {
                for span_s in [0.5, 3.3, 60.0, 601.7, 40_000.0, 2.0e6] {
                    for fps in [1.0, 29.97, 30.0, 120.0, 10_000.0] {
                        let Some(t) = too_long(plants, span_s, fps, o) else { continue };
                        seen += 1;
                        let Some(f) = t.fitting_fps() else {
                            assert!(live_field_keys("m", plants, span_s, 0.01, o).is_err(), "{t}");
                            continue;
                        };
                        let hundredths = f * 100.0;
                        assert!(f < fps && (hundredths - hundredths.round()).abs() < 1e-6, "{t}: {f}");
                        assert!(live_field_keys("m", plants, span_s, f, o).is_ok(), "{t}: {f} does not fit");
                        assert!(
                            live_field_keys("m", plants, span_s, f + 0.01, o).is_err(),
                            "{t}: {f} is not the highest"
                        );
                    }
                }
            }
        }
        assert!(seen > 40, "only {seen} captures past the limit");
    }
}
