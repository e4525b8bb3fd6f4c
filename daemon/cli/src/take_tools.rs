//! `frond take import|resample|filter|splice|loop|field|retime|guided|align`: the seed 000 motion
//! toolkit on takes on disk (the math is in `frond_motion`; this is argument checking and I/O).
//!
//! Commands that write a take put `OUT.take` in the takes directory (`-o OUT`, default
//! `NAME-<command>`; an existing take is only replaced with `--force`), or with `--jsonl` print
//! the result's global poses as JSON Lines on stdout instead. Everything works at `--fps`
//! (default 30, the seed's rate): recorded 1 kHz takes are resampled first.

use anyhow::anyhow;
use frond_formats::field_json::{FieldJson, TransitionsJson};
use frond_formats::import::{ImportKind, import_jsonl};
use frond_motion::align::align;
use frond_motion::clip::{Clip, frame_count};
use frond_motion::controls::{Retime, retime};
use frond_motion::edit::{post_filter, splice};
use frond_motion::field::{Field, FieldParams, make_field};
use frond_motion::guided::{GuidedParams, guided};
use frond_motion::layers::{GLOBAL_LAYER, Take, frames_from_clip};
use frond_motion::looping::{LoopParams, PlaybackParams, find_transitions, loop_clip};
use frond_motion::rig::DEFAULT_THUMB_RANGE_DEG;
use frond_motion::{Calibration, FilterSpec, Mapper, TakeFrame, TakeHeader};
use frond_protocol::ElementId;

use crate::calibrate::write_atomically_bytes;
use crate::control::load_rig;
use crate::error::{UsageError, usage};
use crate::global::Global;
use crate::take_file::check_output_frames;
use crate::take_io::{Output, check_fps, emit, global_clip, layer_clip, read_take, resample_layer};

mod args;
pub use args::TakeTool;
use args::{
    AlignArgs, FieldArgs, FilterArgs, GuidedArgs, ImportArgs, LoopArgs, ResampleArgs, RetimeArgs, SpliceArgs,
};

/// Runs one toolkit command.
pub fn run(g: &Global, cmd: TakeTool) -> anyhow::Result<()> {
    match cmd {
        TakeTool::Import(a) => import(g, a),
        TakeTool::Simulate(a) => crate::take_sim::run(g, a),
        TakeTool::Graph(a) => crate::take_graph::graph(g, a),
        TakeTool::Walk(a) => crate::take_graph::walk(g, a),
        TakeTool::Resample(a) => resample(g, a),
        TakeTool::Filter(a) => filter(g, a),
        TakeTool::Splice(a) => splice_takes(g, a),
        TakeTool::Loop(a) => loop_take(g, a),
        TakeTool::Field(a) => field(g, a),
        TakeTool::Retime(a) => retime_take(g, a),
        TakeTool::Guided(a) => guided_take(g, a),
        TakeTool::Align(a) => align_takes(g, a),
    }
}

fn triple(flag: &str, text: &str) -> anyhow::Result<[f64; 3]> {
    let v: Result<Vec<f64>, _> = text.split(',').map(|x| x.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if v.len() == 3 && v.iter().all(|x| x.is_finite()) => Ok([v[0], v[1], v[2]]),
        _ => usage(format!("{flag} takes three comma-separated numbers, got {text:?}")),
    }
}

/// A derived take: `src`'s header and names, the global layer replaced by `clip`.
fn derived(src: &Take, clip: &Clip, keep_other_layers: bool) -> Take {
    let mut t = src.clone();
    t.header.tick_rate_hz = clip.fps.round().max(1.0) as u32;
    t.markers.clear();
    if !keep_other_layers {
        t.frames.clear();
    }
    t.set_layer(GLOBAL_LAYER, None, frames_from_clip(clip, GLOBAL_LAYER, 0, None));
    t
}

fn layer_names(t: &Take) -> Vec<String> {
    t.layer_ids().into_iter().map(|id| t.layer_name(id)).collect()
}

/// `frond take import`: hand samples mapped (or poses taken as they are) into a take.
fn import(g: &Global, a: ImportArgs) -> anyhow::Result<()> {
    let kind = match a.kind.as_str() {
        "auto" => ImportKind::Auto,
        "hand" => ImportKind::Hand,
        "pose" => ImportKind::Pose,
        other => return usage(format!("--kind must be auto, hand or pose, got {other:?}")),
    };
    let (rig, rig_name) = match &a.rig {
        Some(p) => {
            let (r, _) = load_rig(p)?;
            let n = r.name.clone();
            (Some(r), n)
        }
        None => (None, "none".to_string()),
    };
    let mapping = rig.as_ref().map(|r| r.mapping()).unwrap_or_default();
    let cal = import_calibration(a.calibration.as_deref(), rig.as_ref())?;
    let spec = match &a.filter {
        Some(s) => s.parse::<FilterSpec>().map_err(|e| UsageError(format!("--filter: {e}")))?,
        None => rig.as_ref().map_or(FilterSpec::None, |r| r.filter),
    };
    let mut mapper = Mapper::new(mapping, cal.params(), spec);
    let file = &a.file;
    let text = frond_formats::rig_files::read_small_text(file, frond_formats::jsonl::MAX_HAND_FILE_BYTES)
        .map_err(|e| anyhow!("cannot read {}: {}", file.display(), e.reason()))?;
    let frames = import_jsonl(&text, kind, &mut mapper).map_err(|e| anyhow!("{}: {e}", file.display()))?;
    let header = TakeHeader {
        name: a.name.clone(),
        rig_name,
        calibration_id: cal.id.clone(),
        filter: spec.to_string(),
        tick_rate_hz: 0,
        created_unix_s: 0,
        daemon_version: format!("frond {} (import)", env!("CARGO_PKG_VERSION")),
        joint_names: rig
            .as_ref()
            .map_or_else(|| (0..4).map(|i| format!("joint{i}")).collect(), |r| r.joint_names()),
        clock: None,
        stage: None,
        stage_clock: None,
    };
    let mut take = Take::new(header);
    take.set_layer(GLOBAL_LAYER, None, frames);
    let out = Output { output: Some(a.name.clone()), jsonl: a.jsonl, force: a.force, fps: 30.0 };
    emit(g, take, a.name, &out)
}

/// The calibration `frond take import` maps hand samples with: `--calibration`'s, else the
/// rig's neutral one, else none (zero neutral, the default thumb ranges).
fn import_calibration(
    file: Option<&std::path::Path>,
    rig: Option<&frond_motion::Rig>,
) -> anyhow::Result<Calibration> {
    Ok(match (file, rig) {
        (Some(p), _) => crate::control::load_calibration(p)?.0,
        (None, Some(r)) => Calibration::neutral_for(r),
        (None, None) => Calibration {
            id: "none".into(),
            neutral_wrist_deg: [0.0; 3],
            neutral_thumb_deg: [0.0; 3],
            thumb_range_deg: DEFAULT_THUMB_RANGE_DEG,
            wrist_range_deg: None,
        },
    })
}

/// `frond take resample`: every layer at `--fps`.
fn resample(g: &Global, a: ResampleArgs) -> anyhow::Result<()> {
    let (name, out) = (a.name, a.out);
    check_fps(out.fps)?;
    let src = read_take(g, &name)?;
    let mut t = src.clone();
    t.frames.clear();
    t.markers.clear();
    t.header.tick_rate_hz = out.fps.round().max(1.0) as u32;
    for id in src.layer_ids() {
        let what = format!("take {name:?}, layer {id}");
        let f = resample_layer(&src.layer(id, false), out.fps, out.force, &what)?;
        t.set_layer(id, None, f);
    }
    emit(g, t, format!("{name}-resample"), &out)
}

/// `frond take filter`: a zero-phase low-pass of one layer.
fn filter(g: &Global, a: FilterArgs) -> anyhow::Result<()> {
    let FilterArgs { name, filter, layer, out } = a;
    check_fps(out.fps)?;
    let spec = filter.parse::<FilterSpec>().map_err(|e| UsageError(format!("--filter: {e}")))?;
    let src = read_take(g, &name)?;
    let Some(id) = src.layer_id(&layer).filter(|id| src.layer_ids().contains(id)) else {
        return usage(format!("take {name:?} has no layer {layer:?} (layers: {:?})", layer_names(&src)));
    };
    let frames = resample_layer(&src.layer(id, false), out.fps, out.force, &format!("take {name:?}"))?;
    let poses: Vec<_> = frames.iter().map(|f| f.pose).collect();
    let filtered = post_filter(&poses, spec).map_err(|e| UsageError(format!("--filter: {e}")))?;
    let mut t = src.clone();
    t.markers.clear();
    t.header.filter = format!("{} + post {spec}", t.header.filter);
    t.set_layer(
        id,
        None,
        frames.into_iter().zip(filtered).map(|(mut f, p)| {
            f.pose = p;
            f
        }),
    );
    emit(g, t, format!("{name}-filter"), &out)
}

/// `frond take splice`: frames FROM..=TO of BASE re-authored with NEW.
fn splice_takes(g: &Global, a: SpliceArgs) -> anyhow::Result<()> {
    let SpliceArgs { base, from, to, with, blend, out } = a;
    check_fps(out.fps)?;
    let b = read_take(g, &base)?;
    let n = read_take(g, &with)?;
    let frame_of = |flag: &str, v: &str| -> anyhow::Result<usize> {
        if let Ok(k) = v.parse::<usize>() {
            return Ok(k);
        }
        match b.marker_time(v) {
            Some(t) => Ok((t * out.fps).round() as usize),
            None => usage(format!("{flag} {v:?} is neither a frame number nor a marker of {base:?}")),
        }
    };
    let (f0, f1) = (frame_of("--from", &from)?, frame_of("--to", &to)?);
    let bf = resample_layer(&b.layer(GLOBAL_LAYER, false), out.fps, out.force, &format!("take {base:?}"))?;
    let nf = resample_layer(&n.layer(GLOBAL_LAYER, false), out.fps, out.force, &format!("take {with:?}"))?;
    let spliced = splice(&bf, f0, f1, &nf, blend, out.fps).map_err(|e| UsageError(e.to_string()))?;
    let mut t = b.clone();
    t.frames.clear();
    t.markers.clear();
    t.header.tick_rate_hz = out.fps.round().max(1.0) as u32;
    t.set_layer(GLOBAL_LAYER, None, spliced);
    emit(g, t, format!("{base}-splice"), &out)
}

/// `frond take loop`: endless animation by looping (seed 000, Eq. 5).
fn loop_take(g: &Global, a: LoopArgs) -> anyhow::Result<()> {
    let LoopArgs { name, regions, per_region, window, seed, duration, threshold, explain, out } = a;
    check_fps(out.fps)?;
    if !(duration.is_finite() && duration > 0.0 && duration <= 86_400.0) {
        return usage(format!("--duration must be in (0, 86400] seconds, got {duration}"));
    }
    if !(threshold.is_finite() && threshold > 0.0) {
        return usage(format!("--threshold must be > 0 degrees, got {threshold}"));
    }
    let src = read_take(g, &name)?;
    let clip = global_clip(&src, out.fps, &name, Some(out.force))?;
    let t = find_transitions(&clip, &LoopParams { regions, per_region, window })
        .map_err(|e| UsageError(format!("{name}: {e}")))?;
    if explain {
        frond_binmain::outln!("{}", t.explain_json())?;
        return Ok(());
    }
    let frames = frond_motion::clip::frames_needed(duration, out.fps);
    check_output_frames("the loop", frames, duration, out.fps, out.force)?;
    let count = frame_count(duration, out.fps);
    let playback = PlaybackParams { threshold_deg: threshold, max_inserted: 10 };
    let (looped, _) = loop_clip(&clip, &t, seed, playback, 0, count);
    emit(g, derived(&src, &looped, false), format!("{name}-loop"), &out)
}

/// `frond take field`: a field of plants playing the take (Eq. 6-7), written as field.json.
fn field(g: &Global, a: FieldArgs) -> anyhow::Result<()> {
    let FieldArgs { name, rows, cols, cell, speed, direction, density, seed, fps, compact, output } = a;
    check_fps(fps)?;
    let src = read_take(g, &name)?;
    let clip = global_clip(&src, fps, &name, None)?;
    let params =
        FieldParams { rows, cols, cell_m: cell, speed_m_s: speed, direction_deg: direction, density, seed };
    let field = make_field(&params, &name, clip.len(), fps).map_err(|e| UsageError(e.to_string()))?;
    let count = field.plants.len();
    let (field, how) = if compact {
        (Field { plants: Vec::new(), ..field }, ", left out: readers make them from the parameters")
    } else {
        (field, "")
    };
    write_atomically_bytes(&output, field.to_json().as_bytes())?;
    frond_binmain::outln!("wrote {} ({count} plants{how})", output.display())?;
    Ok(())
}

/// `frond take retime`: speed, scale, bend rotation and rigidity delays (seed 000, section 6.3).
fn retime_take(g: &Global, a: RetimeArgs) -> anyhow::Result<()> {
    let RetimeArgs { name, speed, scale, rotate, delay, out } = a;
    check_fps(out.fps)?;
    let delays_s = triple("--delay", &delay)?;
    let src = read_take(g, &name)?;
    let clip = global_clip(&src, out.fps, &name, Some(out.force))?;
    if speed.is_finite() && speed > 0.0 {
        let seconds = clip.duration_s() / speed;
        let frames = frond_motion::clip::frames_needed(seconds, out.fps);
        let what = format!("take {name:?} at --speed {speed}");
        check_output_frames(&what, frames, seconds, out.fps, out.force)?;
    }
    let r = retime(&clip, &Retime { speed, scale, rotate_deg: rotate, delays_s })
        .map_err(|e| UsageError(e.to_string()))?;
    emit(g, derived(&src, &r, false), format!("{name}-retime"), &out)
}

/// `frond take guided`: guided procedural motion (seed 000, Eq. 8).
fn guided_take(g: &Global, a: GuidedArgs) -> anyhow::Result<()> {
    let GuidedArgs { name, sigma, sg, thumb_range, rig, out } = a;
    check_fps(out.fps)?;
    let sigma_s = triple("--sigma", &sigma)?;
    let s_g = triple("--sg", &sg)?;
    let range = match (thumb_range, &rig) {
        (Some(r), _) => r,
        (None, Some(p)) => load_rig(p)?.0.thumb_range_deg[2],
        (None, None) => DEFAULT_THUMB_RANGE_DEG[2],
    };
    let src = read_take(g, &name)?;
    let layer: Vec<TakeFrame> = src.layer(GLOBAL_LAYER, false);
    let frames = resample_layer(&layer, out.fps, out.force, &format!("take {name:?}"))?;
    if frames.is_empty() {
        anyhow::bail!("take {name:?} has no global frames");
    }
    let clip = Clip { fps: out.fps, frames: frames.iter().map(|f| f.pose).collect() };
    let hands: Vec<_> = frames.iter().map(|f| f.hand).collect();
    let gp = GuidedParams { sigma_s, s_g, g3_range_deg: range };
    let result = guided(&clip, &hands, &gp).map_err(|e| UsageError(e.to_string()))?;
    let mut t = derived(&src, &result, false);
    t.set_layer(GLOBAL_LAYER, None, frames_from_clip(&result, GLOBAL_LAYER, 0, Some(&hands)));
    emit(g, t, format!("{name}-guided"), &out)
}

/// `frond take align`: a secondary take aligned with a global one (section 6.5), as a layer.
fn align_takes(g: &Global, a: AlignArgs) -> anyhow::Result<()> {
    let AlignArgs { global, secondary, window, seed, layer, explain, out } = a;
    check_fps(out.fps)?;
    if layer == "global" || layer.parse::<ElementId>().is_ok() {
        return usage(format!("--layer must be an element name such as leaf, got {layer:?}"));
    }
    let gt = read_take(g, &global)?;
    let st = read_take(g, &secondary)?;
    let gc = global_clip(&gt, out.fps, &global, Some(out.force))?;
    // A secondary recorded with `frond record layer` holds only its layer: that is its motion.
    let sc = layer_clip(&st, st.main_layer().unwrap_or(GLOBAL_LAYER), out.fps, &secondary, Some(out.force))?;
    let transitions = find_transitions(&sc, &LoopParams::default()).ok();
    let (aligned, steps) =
        align(&gc, &sc, transitions.as_ref(), window, seed).map_err(|e| UsageError(e.to_string()))?;
    if explain {
        frond_binmain::errln!("{}", serde_json::to_string(&steps)?);
    }
    let mut t = derived(&gt, &gc, false);
    let id = t.layer_id(&layer).unwrap_or(ElementId::new(t.element_names.len() as u16 + 1));
    t.set_layer(id, Some(&layer), frames_from_clip(&aligned, id, 0, None));
    emit(g, t, format!("{global}-aligned"), &out)
}
