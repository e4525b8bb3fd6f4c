//! `frond take graph` and `frond take walk`: the motion graphs and walks of seed 003 (sections 5
//! and 6) on takes on disk. The math is `frond_motion::graph`; this is argument checking and I/O.

use std::path::{Path, PathBuf};

use anyhow::anyhow;
use frond_formats::graph_file::GraphFile;
use frond_formats::graph_file::MAX_GRAPH_FILE_BYTES;
use frond_motion::clip::Clip;
use frond_motion::graph::walk::PosePlan;
use frond_motion::graph::{
    ControlPoint, EdgeKind, GraphError, GraphParams, MotionGraph, PoseGoalSpec, Walker, build_graph,
    control_positions_m, nearest_node,
};
use frond_motion::layers::{GLOBAL_LAYER, Take, frames_from_clip};
use frond_motion::sample::PoseFrame;
use frond_motion::skeleton::Skeleton;

use crate::calibrate::write_atomically_bytes;
use crate::control::load_rig;
use crate::error::usage;
use crate::global::Global;
use crate::take_io::{Output, check_fps, emit, global_clip, read_take};

/// Longest walk, seconds (an hour).
const MAX_WALK_S: f64 = 3600.0;
/// Most plants of one `frond take walk`.
const MAX_PLANTS: u32 = 256;

/// What `frond take graph` was asked.
#[derive(Debug, clap::Args)]
pub struct Graph {
    /// Take name.
    pub name: String,
    /// Control point: joint1, joint2, joint3 or top.
    #[arg(long, default_value = "top", value_name = "POINT")]
    pub control: String,
    /// Samples a transition is extended by on each side (k of Fig. 4).
    #[arg(long, default_value_t = 2, value_name = "K")]
    pub extend: u32,
    /// Largest 12-joint-angle distance between the two ends of a transition, degrees.
    #[arg(long, default_value_t = 10.0, value_name = "DEG")]
    pub max_pose_deg: f64,
    /// Scale of the search radius (the paper's is one step, 1).
    #[arg(long, default_value_t = 1.0, value_name = "X")]
    pub radius_scale: f64,
    /// Most transitions leaving one sample (the nearest in pose are kept).
    #[arg(long, default_value_t = 3, value_name = "N")]
    pub max_transitions: u32,
    /// Rig of the take [default: the rig it was recorded on, when that is an embedded rig; a rig
    /// loaded from a file must be given here].
    #[arg(long, value_name = "NAME|FILE")]
    pub rig: Option<PathBuf>,
    /// Graph file to write [default: NAME.graph.json in the takes directory, where `frond
    /// graph play` finds it].
    #[arg(short = 'o', long = "output", value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Print what was found and pruned as JSON on stderr.
    #[arg(long)]
    pub explain: bool,
    /// Frame rate the graph is built at.
    #[arg(long, default_value_t = 30.0, value_name = "FPS")]
    pub fps: f64,
    /// Replace an existing graph file.
    #[arg(long)]
    pub force: bool,
}

/// The take's global poses at `fps`.
fn take_clip(g: &Global, name: &str, fps: f64) -> anyhow::Result<(Take, Clip)> {
    let take = read_take(g, name)?;
    let clip = global_clip(&take, fps, name, None)?;
    Ok((take, clip))
}

/// The control point's path over `poses` of `take`, by forward kinematics of the rig it was
/// recorded on (or `--rig`).
fn control_path(
    take: &Take,
    rig: Option<&Path>,
    control: ControlPoint,
    poses: &[PoseFrame],
) -> anyhow::Result<Vec<[f64; 3]>> {
    let rig = match rig {
        Some(spec) => load_rig(spec)?.0,
        None => {
            crate::take_file::recorded_rig(&format!("take {:?}", take.header.name), &take.header.rig_name)?
                .rig
        }
    };
    let top_m = rig.sim_node_heights_m()[4] as f32;
    Ok(control_positions_m(control, &Skeleton::from_rig(&rig), top_m, poses))
}

/// Builds the graph and writes `NAME.graph.json` (or `-o FILE`).
pub(crate) fn graph(g: &Global, a: Graph) -> anyhow::Result<()> {
    check_fps(a.fps)?;
    let control: ControlPoint = match a.control.parse() {
        Ok(c) => c,
        Err(e) => return usage(format!("--control: {e}")),
    };
    let params = GraphParams {
        control,
        extend: a.extend,
        max_pose_deg: a.max_pose_deg,
        radius_scale: a.radius_scale,
        max_transitions: a.max_transitions,
    };
    if let Err(e) = params.check() {
        return usage(format!("--{}", e.to_string().replace('_', "-")));
    }
    let out = match &a.output {
        Some(out) => out.clone(),
        None => {
            // Beside the takes, in frond's own directory, made on first use.
            let out = default_graph_path(g, &a.name);
            if let Some(dir) = out.parent() {
                std::fs::create_dir_all(dir).map_err(|e| anyhow!("cannot create {}: {e}", dir.display()))?;
            }
            out
        }
    };
    if out.exists() && !a.force {
        return usage(format!("{} exists; use --force to replace it", out.display()));
    }
    let (take, clip) = take_clip(g, &a.name, a.fps)?;
    let path = control_path(&take, a.rig.as_deref(), control, &clip.frames)?;
    let graph = match build_graph(&clip.frames, &path, &params) {
        Ok(graph) => graph,
        Err(e @ (GraphError::NoTransition { .. } | GraphError::SampleCount(_))) => {
            anyhow::bail!("take {:?}: {e}", a.name)
        }
        Err(e) => return Err(e.into()),
    };
    let file = GraphFile::new(&graph, &params, &a.name, a.fps, &clip.frames);
    write_atomically_bytes(&out, file.to_json().as_bytes())?;
    frond_binmain::outln!(
        "wrote {} ({} nodes of {} frames, {} transitions; pruned {} dead-end and {} unconnected frames)",
        out.display(),
        graph.len(),
        clip.frames.len(),
        graph.transitions(),
        count(&graph.pruned.dead_end_frames),
        count(&graph.pruned.outside_largest_part_frames),
    )?;
    if a.explain {
        let per_node = graph.transitions() as f64 / graph.len() as f64;
        let explain = serde_json::json!({
            "take": a.name,
            "frames": clip.frames.len(),
            "nodes": graph.len(),
            "transitions": graph.transitions(),
            "transitions_per_node": per_node,
            "pruned": graph.pruned,
        });
        frond_binmain::errln!("{explain}");
    }
    Ok(())
}

fn count(ranges: &[[u32; 2]]) -> u64 {
    ranges.iter().map(|r| (r[1] - r[0] + 1) as u64).sum()
}

/// What `frond take walk` was asked.
#[derive(Debug, clap::Args)]
pub struct Walk {
    /// Take names, each with its graph (instancing as in "Physically-based Driven Tree
    /// Animations", section 6.1: plant `p` walks take `p mod count`'s graph, so several takes,
    /// or one take's graphs for several control points built into files of their own, make one
    /// grove).
    #[arg(required = true, num_args = 1..)]
    pub names: Vec<String>,
    /// Graph file (from frond take graph), one per take in the same order
    /// [default: NAME.graph.json in the takes directory].
    #[arg(long, value_name = "FILE")]
    pub graph: Vec<PathBuf>,
    /// Seconds to walk.
    #[arg(long, value_name = "S")]
    pub duration: f64,
    /// Seed of the random choices.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub seed: u64,
    /// Goal direction in the ground plane, degrees.
    #[arg(long, value_name = "DEG", conflicts_with = "goal_pose", allow_hyphen_values = true)]
    pub goal_dir: Option<f64>,
    /// Goal pose: frame=N or 12 comma-separated angles, degrees.
    #[arg(long, value_name = "P", allow_hyphen_values = true)]
    pub goal_pose: Option<String>,
    /// Plants walking [default: one per take].
    #[arg(long, value_name = "N")]
    pub plants: Option<u32>,
    /// Print the path and the transitions taken as JSON on stderr.
    #[arg(long)]
    pub explain: bool,
    /// Name of the take to write [default: NAME-walk, NAME the first take].
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    pub output: Option<String>,
    /// Print the first plant's poses as JSON Lines on stdout instead of writing a take.
    #[arg(long)]
    pub jsonl: bool,
    /// Replace an existing take of the same name.
    #[arg(long)]
    pub force: bool,
}

/// `NAME.graph.json` in the takes directory.
pub(crate) fn default_graph_path(g: &Global, name: &str) -> PathBuf {
    frond_protocol::paths::takes_dir(g.takes_dir.clone()).join(format!("{name}.graph.json"))
}

/// Reads and checks a graph file (regular, at most [`MAX_GRAPH_FILE_BYTES`]).
pub(crate) fn read_graph_file(path: &Path) -> anyhow::Result<GraphFile> {
    let text = frond_formats::rig_files::read_small_text(path, MAX_GRAPH_FILE_BYTES).map_err(|e| {
        let hint = if path.exists() { String::new() } else { missing_graph_hint(path) };
        anyhow!("cannot read {}: {}{hint}", path.display(), e.reason())
    })?;
    GraphFile::from_json(&text).map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// What to say when a graph file does not exist: how to make one (`frond take graph TAKE` writes
/// `TAKE.graph.json` beside the take).
pub(crate) fn missing_graph_hint(path: &Path) -> String {
    let name = path.file_name().and_then(|n| n.to_str()).and_then(|n| n.strip_suffix(".graph.json"));
    match name {
        Some(take) => format!(
            "; make it with `frond take graph {take} --control top` (from take {take:?}; \
             `frond take simulate` makes a take to build one from)"
        ),
        None => "; make a take's graph with `frond take graph TAKE --control top` and pass its \
                 TAKE.graph.json"
            .to_string(),
    }
}

/// `--goal-pose`: `frame=N` (a frame of the take at the graph's rate) or 12 comma-separated
/// angles in degrees (pitch, yaw, roll of joints 0..3).
fn parse_goal_pose(spec: &str, poses: &[PoseFrame]) -> anyhow::Result<PoseFrame> {
    match spec.parse::<PoseGoalSpec>() {
        Err(e) => usage(format!("--goal-pose {e}")),
        Ok(PoseGoalSpec::Frame(n)) => match poses.get(n as usize) {
            Some(p) => Ok(*p),
            None => usage(format!(
                "--goal-pose {spec:?}: the take has {} frames at the graph's rate",
                poses.len()
            )),
        },
        Ok(PoseGoalSpec::Angles(joints_deg)) => Ok(PoseFrame { t: 0.0, joints_deg }),
    }
}

/// One take a walk draws on: its graph and poses.
struct Source {
    name: String,
    graph_path: PathBuf,
    fps: f64,
    /// The take's header, element names and rig, without its frames (each plant's take is made
    /// from it: the source's frames are not kept twice).
    template: Take,
    poses: Vec<PoseFrame>,
    graph: MotionGraph,
    goal: frond_motion::graph::Goal,
}

/// Reads take `name` with its graph and resolves the goal on it.
fn walk_source(g: &Global, a: &Walk, name: &str, graph_path: PathBuf) -> anyhow::Result<Source> {
    let file = read_graph_file(&graph_path)?;
    let (mut take, clip) = take_clip(g, name, file.fps)?;
    take.frames = Vec::new();
    take.markers = Vec::new();
    let graph = file.graph_for(&clip.frames).map_err(|e| anyhow!("{}: {e}", graph_path.display()))?;
    let poses = clip.frames;
    let goal = match (&a.goal_pose, a.goal_dir) {
        (Some(p), _) => {
            let pose = parse_goal_pose(p, &poses)?;
            let node = nearest_node(&graph, &poses, &pose);
            frond_motion::graph::Goal::Pose(PosePlan::new(&graph, node))
        }
        (None, Some(dir_deg)) => frond_motion::graph::Goal::Direction { dir_deg },
        (None, None) => frond_motion::graph::Goal::Random,
    };
    Ok(Source { name: name.to_string(), graph_path, fps: file.fps, template: take, poses, graph, goal })
}

/// Walks the graphs and writes one take per plant.
pub(crate) fn walk(g: &Global, a: Walk) -> anyhow::Result<()> {
    let (plants, base) = check_walk(g, &a)?;
    let mut sources = Vec::with_capacity(a.names.len());
    for (i, name) in a.names.iter().enumerate() {
        let path = a.graph.get(i).cloned().unwrap_or_else(|| default_graph_path(g, name));
        sources.push(walk_source(g, &a, name, path)?);
    }
    // Count what the walk makes before making it, as every take tool does: at most
    // MAX_EXPORT_FRAMES in all without --force, never more than MAX_RESAMPLED_FRAMES.
    let total: u64 = (0..plants as usize).map(|p| walk_frames(&a, &sources[p % sources.len()])).sum();
    check_walk_frames(total, plants, a.duration, a.force)?;
    // Each plant's take is written as soon as it is walked: one plant's frames in memory at a
    // time, not every plant's.
    let mut explains = Vec::new();
    for plant in 0..plants {
        // Plant p: take p mod count.
        let src = &sources[plant as usize % sources.len()];
        explains.extend(walk_plant(g, &a, src, (plant, plants), &base)?);
    }
    if a.explain {
        let graphs: Vec<_> = sources.iter().map(|s| &s.graph_path).collect();
        frond_binmain::errln!(
            "{}",
            serde_json::json!({ "graphs": graphs, "goal": goal_name(&a), "plants": explains })
        );
    }
    Ok(())
}

/// Checks what `frond take walk` was asked before reading or walking anything, every output
/// name included (no half-written set of takes); returns the number of plants and the output
/// name of the first.
fn check_walk(g: &Global, a: &Walk) -> anyhow::Result<(u32, String)> {
    if !(a.duration.is_finite() && a.duration > 0.0 && a.duration <= MAX_WALK_S) {
        return usage(format!("--duration must be in (0, {MAX_WALK_S}] seconds, got {}", a.duration));
    }
    let plants = a.plants.unwrap_or(a.names.len().min(MAX_PLANTS as usize) as u32);
    if plants == 0 || plants > MAX_PLANTS || a.names.len() > MAX_PLANTS as usize {
        return usage(format!(
            "--plants must be 1 to {MAX_PLANTS} (and at most as many takes), got {plants}"
        ));
    }
    if let Some(d) = a.goal_dir
        && !(d.is_finite() && d.abs() <= 360.0)
    {
        return usage(format!("--goal-dir must be a finite angle within +-360 degrees, got {d}"));
    }
    if !a.graph.is_empty() && a.graph.len() != a.names.len() {
        return usage(format!(
            "give one --graph per take ({} takes, {} graphs), or none for NAME.graph.json",
            a.names.len(),
            a.graph.len()
        ));
    }
    if a.jsonl && plants > 1 {
        return usage("--jsonl prints one plant; use it with one take and without --plants, or write takes");
    }
    let base = a.output.clone().unwrap_or_else(|| format!("{}-walk", a.names[0]));
    for plant in 0..plants {
        let name = plant_take_name(&base, plant);
        if let Err(e) = frond_protocol::paths::validate_take_name(&name) {
            return usage(e.to_string());
        }
        let path = frond_protocol::paths::takes_dir(g.takes_dir.clone()).join(format!("{name}.take"));
        if !a.jsonl && !a.force && path.exists() {
            return usage(format!(
                "{} exists; use --force to replace it or -o to choose another name",
                path.display()
            ));
        }
    }
    Ok((plants, base))
}

/// Frames of one plant's walk of `src`.
fn walk_frames(a: &Walk, src: &Source) -> u64 {
    (a.duration * src.fps).round().max(1.0) as u64
}

/// Walks plant `plant` of `plants` on `src` (seed + plant, starting at a node spread over its
/// graph) and writes its take; with `--explain`, what it did.
fn walk_plant(
    g: &Global,
    a: &Walk,
    src: &Source,
    (plant, plants): (u32, u32),
    base: &str,
) -> anyhow::Result<Option<serde_json::Value>> {
    let (graph, poses) = (&src.graph, &src.poses);
    let start = (plant as u64 * graph.len() as u64 / plants as u64) as u32;
    let seed = a.seed.wrapping_add(plant as u64);
    let mut w = Walker::new(graph, start, seed, src.fps);
    w.set_goal(src.goal.clone());
    let frames = walk_frames(a, src) as usize;
    let mut walked = Vec::with_capacity(frames);
    let mut taken = Vec::new();
    for _ in 0..frames {
        let s = w.next_frame(graph, poses);
        if a.explain
            && let (Some(node), Some(e)) = (s.node, s.chose)
            && e.kind == EdgeKind::Transition
        {
            taken.push(serde_json::json!({
                "t": s.pose.t,
                "from_frame": graph.node_frames[node as usize],
                "to_frame": graph.node_frames[e.to as usize],
                "inbetweens": e.inbetweens,
            }));
        }
        walked.push(s.pose);
    }
    let clip = Clip { fps: src.fps, frames: walked };
    let mut out_take = src.template.clone();
    out_take.header.tick_rate_hz = src.fps.round().max(1.0) as u32;
    out_take.header.filter = format!("walk of {} seed={seed} goal={}", src.name, goal_name(a));
    out_take.set_layer(GLOBAL_LAYER, None, frames_from_clip(&clip, GLOBAL_LAYER, 0, None));
    let name = plant_take_name(base, plant);
    let out = Output { output: Some(name.clone()), jsonl: a.jsonl, force: a.force, fps: src.fps };
    emit(g, out_take, name, &out)?;
    Ok(a.explain.then(|| {
        serde_json::json!({
            "plant": plant,
            "take": src.name,
            "graph": src.graph_path,
            "seed": seed,
            "start_frame": graph.node_frames[start as usize],
            "end_node_frame": graph.node_frames[w.node() as usize],
            "transitions_taken": w.transitions_taken(),
            "transitions": taken,
        })
    }))
}

/// Refuses a walk of `plants` takes lasting `duration_s` that makes `total` frames in all: more
/// than [`crate::take_file::MAX_EXPORT_FRAMES`] without `force`, or than [`MAX_RESAMPLED_FRAMES`].
fn check_walk_frames(total: u64, plants: u32, duration_s: f64, force: bool) -> anyhow::Result<()> {
    use crate::take_file::MAX_EXPORT_FRAMES;
    use frond_motion::take::MAX_RESAMPLED_FRAMES;
    let what = format!("the walk of {plants} plants for {duration_s} s makes {total} frames in all");
    if total > MAX_RESAMPLED_FRAMES as u64 {
        anyhow::bail!("{what}, more than the {MAX_RESAMPLED_FRAMES} any output may have");
    }
    if !force && total > MAX_EXPORT_FRAMES {
        anyhow::bail!("{what}, more than {MAX_EXPORT_FRAMES}; pass --force to go past it");
    }
    Ok(())
}

/// Plant 0 is `base`, plant `p` is `base-plantP`.
fn plant_take_name(base: &str, plant: u32) -> String {
    if plant == 0 { base.to_string() } else { format!("{base}-plant{plant}") }
}

fn goal_name(a: &Walk) -> String {
    match (&a.goal_pose, a.goal_dir) {
        (Some(p), _) => format!("pose:{p}"),
        (None, Some(d)) => format!("dir:{d}"),
        (None, None) => "random".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_graph_says_how_to_make_it() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_graph_file(&dir.path().join("gale.graph.json")).unwrap_err().to_string();
        assert!(e.contains("frond take graph gale"), "{e}");
        let e = read_graph_file(&dir.path().join("odd.json")).unwrap_err().to_string();
        assert!(e.contains("frond take graph TAKE"), "{e}");
    }
}
