//! Baking a live field whole: every plant of a [`FieldCapture`] (`frond-gltf live --field`), one
//! armature per plant as [`Baker::bake_field`] writes them, each plant's pose at each key
//! evaluated by `frond_motion::field_eval` (the code the daemon's field, the SDK's
//! `LiveField::plant_pose` and the console page run; seed 000, Eq. 6-7 and section 6.3).
//!
//! Key `k` is at host time `t_k = t_0 + k / fps`, `t_0` the first field frame kept. The field
//! frame in force at `t_k` (the last one published at or before it) gives the controls and the
//! stream window a subscriber held then (between two frames, the stream as far as the next one
//! brought it, which the plants furthest ahead read); the stream time is interpolated between
//! that frame's and
//! the next one's (the daemon advances it by the motion speed for the time between them, so this
//! is exact even when the speed changed in between; with a steady speed it is the SDK's
//! `LiveField::tau_at`). At a field frame's own time a key is therefore what every subscriber
//! evaluated there, the announced plants' published poses included.

use std::ops::Range;

use serde_json::json;

use frond_motion::JOINTS;
use frond_motion::clip::Joints;
use frond_motion::field_eval::FieldState;
use frond_motion::field_wire::field_from_definition;
use frond_motion::mesh::PlantModel;
use frond_protocol::printable;

use crate::bake::{
    BakeOptions, BakeStats, Baked, Baker, Progress, element_names, joint_channels, joint_names,
    live_field_keys,
};
use crate::doc::{DocBuilder, Placement};
use crate::error::BakeError;
use crate::input::LoadedRig;
use crate::live_field::{FieldCapture, FieldMark};

/// Poses held at once while baking (48 bytes each: 64 MiB): plants are evaluated this many keys
/// at a time, whatever the field's size.
const POSES_AT_ONCE: usize = (64 << 20) / std::mem::size_of::<Joints>();

impl Baker {
    /// Every plant of a captured live field, keyed at `opts.fps` over the captured span (see
    /// the module): one animation named `name`, each plant its own skeleton and skin over the
    /// one shared mesh, at its place in the field and scaled by its size. The field drives the
    /// plants' main joints; a rig's secondary elements stay at rest.
    pub fn bake_live_field(
        &mut self,
        rig: &LoadedRig,
        model: &PlantModel,
        cap: &FieldCapture,
        name: &str,
        opts: &BakeOptions,
        progress: Progress<'_>,
    ) -> Result<Baked, BakeError> {
        let fps = opts.checked_fps()?;
        let def = cap.definition();
        let origin = format!("live field `{}`", printable(&def.source));
        let base = field_from_definition(def)
            .map_err(|e| BakeError::Field { origin: origin.clone(), reason: e.to_string() })?;
        let n_plants = base.field().plants.len();
        if cap.is_empty() || n_plants == 0 {
            return Err(BakeError::Field { origin, reason: "nothing was captured".to_string() });
        }
        // The budget before any key or node is allocated.
        let keys = live_field_keys(&def.source, n_plants, cap.span_s(), fps, opts)? as usize;
        let times_s: Vec<f64> = (0..keys).map(|k| k as f64 / fps).collect();

        let mut doc = DocBuilder::new(std::mem::take(&mut self.bin));
        let assets = doc.plant_assets(model, &joint_names(rig), &element_names(rig));
        let field_plants = &base.field().plants;
        let plants =
            doc.plants(&assets, &rig.rig.name, n_plants, |i| Placement::of_field_plant(&field_plants[i]));
        let input = doc.times(&times_s);
        let mut anim = doc.begin_animation(input);
        let chunk = (POSES_AT_ONCE / keys.max(1)).clamp(1, n_plants);
        let total = (keys * n_plants) as u64;
        let (mut channels, mut unevaluated) = (0, 0u64);
        let mut state = base.clone();
        for start in (0..n_plants).step_by(chunk) {
            let range = start..(start + chunk).min(n_plants);
            state.clone_from(&base);
            self.poses.clear();
            self.poses.resize(range.len() * keys, [[0.0; 3]; JOINTS]);
            unevaluated += evaluate_keys(&mut state, cap, fps, keys, range.clone(), &mut self.poses);
            for (i, poses) in range.clone().zip(self.poses.chunks(keys)) {
                channels += joint_channels(&mut doc, &mut anim, &[plants[i].main], poses, &mut self.quats);
            }
            progress((range.end * keys) as u64, total);
        }
        let notes = live_notes(rig, cap, unevaluated, total);
        let extras = live_extras(rig, cap, name, fps);
        doc.end_animation(anim, name, extras.clone());
        let (root, bin) = doc.finish(extras);
        Ok(Baked {
            root,
            bin,
            notes,
            stats: BakeStats { plants: n_plants, keys, channels, vertices: assets.vertices },
        })
    }
}

/// Plants `plants`' poses at keys `0..keys` (at `fps` from the first mark) into `out` (plant
/// major: `out[(p - plants.start) * keys + k]`), replaying the capture's marks on `state` (a
/// fresh copy of the field made from its definition): the controls of the mark in force, and
/// the stream frames its window holds (between two marks, those the next one holds). A pose the history cannot give (a stream frame that never
/// arrived) holds the plant's previous key (rest before the first); returns how many.
pub fn evaluate_keys(
    state: &mut FieldState,
    cap: &FieldCapture,
    fps: f64,
    keys: usize,
    plants: Range<usize>,
    out: &mut [Joints],
) -> u64 {
    let marks = cap.marks();
    let Some(first) = marks.first() else { return 0 };
    let window = state.history().capacity() as u64;
    let mut next_index = first.produced.saturating_sub(window);
    let mut applied: Option<usize> = None;
    let mut unevaluated = 0;
    let since_first = |m: &FieldMark| (m.host_ns - first.host_ns) as f64;
    for k in 0..keys {
        let t_ns = k as f64 * 1e9 / fps;
        let mut m = applied.unwrap_or(0);
        while marks.get(m + 1).is_some_and(|n| since_first(n) <= t_ns) {
            m += 1;
        }
        if applied != Some(m) {
            if marks[m].controls != state.controls() {
                state.set_controls(marks[m].controls);
            }
            applied = Some(m);
        }
        // The stream as far as the frame in force had produced it; between two frames, as far
        // as the next one had (the plants furthest ahead may read past the first by then).
        let after_ns = t_ns - since_first(&marks[m]);
        let upto = match marks.get(m + 1) {
            Some(next) if after_ns > 0.0 => next.produced,
            _ => marks[m].produced,
        };
        for index in next_index.max(upto.saturating_sub(window))..upto {
            if let Some(j) = cap.stream_frame(index) {
                state.history_mut().insert(index, *j);
            }
        }
        next_index = next_index.max(upto);
        let tau = tau_at(&marks[m], marks.get(m + 1), after_ns);
        for (n, p) in plants.clone().enumerate() {
            let at = n * keys + k;
            out[at] = match state.plant_at(p, tau) {
                Some(j) => j,
                None => {
                    unevaluated += 1;
                    if k > 0 { out[at - 1] } else { [[0.0; 3]; JOINTS] }
                }
            };
        }
    }
    unevaluated
}

/// The stream time `after_ns` after mark `a`: interpolated towards the next mark `b`, or (after
/// the last) advanced by `a`'s motion speed.
fn tau_at(a: &FieldMark, b: Option<&FieldMark>, after_ns: f64) -> f64 {
    match b {
        Some(b) if b.host_ns > a.host_ns => {
            a.tau_s + (b.tau_s - a.tau_s) * after_ns / (b.host_ns - a.host_ns) as f64
        }
        _ => a.tau_s + a.controls.time_step * after_ns / 1e9,
    }
}

fn live_notes(rig: &LoadedRig, cap: &FieldCapture, unevaluated: u64, total: u64) -> Vec<String> {
    let mut notes = Vec::new();
    let field = printable(&cap.definition().source);
    if cap.missing > 0 {
        notes.push(format!(
            "the daemon dropped {} frames for this subscriber during the capture; the stream time was \
             interpolated across them",
            cap.missing
        ));
    }
    if cap.ignored > 0 {
        notes.push(format!(
            "{} field frames of field `{field}` were left out (a stream time or control not finite, or a host \
             time not after the previous frame's)",
            cap.ignored
        ));
    }
    if let Some(why) = &cap.cut_short {
        notes.push(why.clone());
    }
    if unevaluated > 0 {
        notes.push(format!(
            "{unevaluated} of {total} plant keys read stream frames that never arrived and hold the plant's \
             previous key: start frond-gltf live a few seconds before recording, so that the field's history \
             has arrived"
        ));
    }
    if !rig.rig.elements.is_empty() {
        notes.push(format!(
            "a field drives the plants' main joints: rig `{}`'s secondary elements are baked at rest",
            printable(&rig.rig.name)
        ));
    }
    notes
}

/// `extras` on the asset and the animation: the field, the span captured on the daemon's host
/// clock (`start_host_ns` is key 0's `CLOCK_MONOTONIC` time), and what was lost.
fn live_extras(
    rig: &LoadedRig,
    cap: &FieldCapture,
    name: &str,
    fps: f64,
) -> Option<Box<gltf_json::extras::RawValue>> {
    let d = cap.definition();
    let marks = cap.marks();
    let v = json!({
        "take": name,
        "rig": rig.rig.name,
        "bake_fps": fps,
        "field": {
            "source": d.source,
            "rig": d.rig,
            "plants": d.plants,
            "announced": d.plant_elements.len(),
            "take": d.layout.take,
            "seed": d.layout.seed,
            "stream_fps": d.stream_fps,
            "publish_hz": d.publish_hz,
            "field_frames": marks.len(),
            "start_host_ns": marks.first().map(|m| m.host_ns),
            "end_host_ns": marks.last().map(|m| m.host_ns),
            "tau_start_s": marks.first().map(|m| m.tau_s),
            "missing_frames": cap.missing,
        },
    });
    gltf_json::extras::RawValue::from_string(v.to_string()).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::live::LiveMode;
    use frond_motion::controls::FieldControls;
    use frond_motion::field::{FieldParams, make_field};
    use frond_motion::field_player::{FieldPlayer, bench_sway};
    use frond_motion::field_wire::{FrameFiller, layout_of};
    use frond_protocol::ElementId;
    use frond_protocol::field::{FieldDefinition, FieldFrame};

    /// The daemon's own field (a `FieldPlayer`) publishing 100 field frames at 50 Hz, the
    /// controls changed at frame 50 (motion speed x2, force turned 90 degrees); what it evaluates
    /// at each frame, and halfway to the next (its state advanced there), is the truth.
    #[test]
    fn keys_are_what_the_daemons_field_evaluates_at_frames_and_between() {
        let (clip, transitions) = bench_sway();
        let params = FieldParams {
            rows: 3,
            cols: 4,
            cell_m: 0.3,
            speed_m_s: 1.5,
            direction_deg: 20.0,
            density: 1.0,
            seed: 2,
        };
        let field = make_field(&params, "t", clip.len(), clip.fps).unwrap();
        let controls = FieldControls { direction_deg: 20.0, speed_m_s: 1.5, ..FieldControls::default() };
        let mut player = FieldPlayer::new(field.clone(), clip, &transitions, 1, controls);
        let id = ElementId::new(40);
        let def = FieldDefinition {
            id,
            source: "field".into(),
            rig: "grass".into(),
            layout: layout_of(&field),
            plants: 12,
            stream_fps: 30.0,
            history_frames: player.history_capacity() as u32,
            publish_hz: 50,
            plant_elements: vec![],
        };
        let mut cap = FieldCapture::new(LiveMode::All, def.clone());
        let mut filler = FrameFiller::default();
        let (mut at_frames, mut halfway) = (Vec::new(), Vec::new());
        let truth = |p: &FieldPlayer| {
            let mut s = p.state().clone();
            s.refresh_delays();
            (0..12).map(|i| s.plant(i).unwrap()).collect::<Vec<_>>()
        };
        for n in 0..100u64 {
            if n == 50 {
                player.set_controls(FieldControls { time_step: 2.0, direction_deg: 110.0, ..controls });
            }
            player.advance(n as f64 * 0.02);
            let mut frame = FieldFrame {
                seq: n,
                host_monotonic_ns: 7_000_000_000 + n * 20_000_000,
                field: id,
                ..Default::default()
            };
            filler.fill(player.state(), &mut frame);
            cap.push(&frame, Some(player.state().history()));
            at_frames.push(truth(&player));
            let mut ahead = player.clone();
            ahead.advance(n as f64 * 0.02 + 0.01);
            halfway.push(truth(&ahead));
        }
        let base = field_from_definition(&def).unwrap();
        let close = |a: &Joints, b: &Joints| {
            a.iter().flatten().zip(b.iter().flatten()).all(|(x, y)| (x - y).abs() < 1e-4)
        };
        // At 50 FPS every key is a frame's time.
        let keys =
            live_field_keys("field", 12, cap.span_s(), 50.0, &BakeOptions::default()).unwrap() as usize;
        assert_eq!(keys, 100);
        let mut out = vec![[[0.0; 3]; JOINTS]; 12 * keys];
        assert_eq!(evaluate_keys(&mut base.clone(), &cap, 50.0, keys, 0..12, &mut out), 0);
        for k in 0..keys {
            for p in 0..12 {
                assert!(close(&out[p * keys + k], &at_frames[k][p]), "key {k} plant {p}");
            }
        }
        // At 100 FPS the odd keys fall halfway between frames (but the one where the controls
        // changed, whose subscribers show the old controls until the new frame).
        let keys =
            live_field_keys("field", 12, cap.span_s(), 100.0, &BakeOptions::default()).unwrap() as usize;
        let mut out = vec![[[0.0; 3]; JOINTS]; 4 * keys];
        assert_eq!(evaluate_keys(&mut base.clone(), &cap, 100.0, keys, 8..12, &mut out), 0);
        for k in (1..keys).step_by(2).filter(|k| k / 2 != 49) {
            for p in 8..12 {
                assert!(close(&out[(p - 8) * keys + k], &halfway[k / 2][p]), "key {k} plant {p}");
            }
        }
        assert!(out.iter().flatten().flatten().any(|x| x.abs() > 1.0), "the plants move");
    }
}
