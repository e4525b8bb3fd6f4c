//! Plants walking motion graphs on the pose stream (seed 003, section 6): `plants` walkers, plant
//! `i` on source `i mod n` (a take and its graph: section 6.1's instancing), each with its own
//! seed and start, published at [`GRAPH_PUBLISH_HZ`] as
//! announced `field-plant` elements (a group of plants, as a field's), interpolating between the
//! walks' frames. The goal is set live ([`GraphGoal`]): off (random walks), a direction, the
//! hand's bend direction (section 6.1.2: "the animator can direct the animation at each
//! arbitrary moment"), or a pose (a frame of each plant's own take, or 12 angles: the nearest
//! node of each graph), whose shortest-path plans are computed over the following ticks
//! ([`PosePlanner`], a bounded number of nodes per tick, one source after the other).

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, AtomicU32, AtomicU64, Ordering::Relaxed};

use frond_formats::graph_file::GraphFile;
use frond_formats::layers::TakeBytes;
use frond_motion::clip::Joints;
use frond_motion::graph::walk::PosePlanner;
use frond_motion::graph::{Goal, MotionGraph, NearestNodeSearch, Walker};
use frond_motion::layers::{GLOBAL_LAYER, Take};
use frond_motion::sample::JOINTS;
use frond_motion::{HandSample, PoseFrame};
use frond_protocol::control::StageKind;
use frond_protocol::{ControlErrorKind, ElementId, GraphGoal, StageInput};

use super::budget::{self, TickWork};
use super::error::BuildError;
use super::live::{BuildContext, BuiltStage, FrameSink, LiveStage, StageInfo, StageReport, TickContext};
use crate::clock::NS_PER_S;

/// Most plants of one graph stage.
pub const MAX_GRAPH_PLANTS: usize = 64;
/// Frames per second on the stream.
pub const GRAPH_PUBLISH_HZ: u32 = 60;
/// Most nodes the pose planner settles per tick (a 1 kHz tick spends some tens of
/// microseconds); fewer when the walk leaves less of the stage's budget ([`walk_work`]).
pub const PLAN_NODES_PER_TICK: usize = 2_000;
/// Fewest nodes the planner settles per tick, so that a plan always makes progress.
pub const MIN_PLAN_NODES_PER_TICK: usize = 64;
/// Most walk frames per plant one tick catches up by when the stage is built without a budget
/// ([`GraphStage::new`]); [`build`] sets it from the stage's share of the tick.
pub const DEFAULT_CATCH_UP_FRAMES: u64 = 32;
/// Largest graph file read, bytes.
pub const MAX_GRAPH_FILE_BYTES: u64 = frond_formats::graph_file::MAX_GRAPH_FILE_BYTES;
/// Smallest bend of the root, degrees, that sets a goal from the hand (below it the plants walk
/// at random).
pub const HAND_GOAL_MIN_BEND_DEG: f32 = 5.0;

const GOAL_OFF: u8 = 0;
const GOAL_DIR: u8 = 1;
const GOAL_HAND: u8 = 2;
const GOAL_FRAME: u8 = 3;
const GOAL_POSE: u8 = 4;

/// What `frond status` says of a graph walk: goal, the first plant's node, transitions taken.
pub struct GraphReport {
    take: String,
    plants: usize,
    nodes: usize,
    goal: AtomicU8,
    goal_dir_deg: AtomicU64,
    goal_frame: AtomicU32,
    planned: AtomicU8,
    node_frame: AtomicU32,
    transitions: AtomicU64,
    skipped_frames: AtomicU64,
    late_ticks: AtomicU64,
}

impl StageReport for GraphReport {
    fn describe(&self) -> String {
        let goal = match self.goal.load(Relaxed) {
            GOAL_DIR => format!("goal direction {:.0} deg", f64::from_bits(self.goal_dir_deg.load(Relaxed))),
            GOAL_HAND => {
                format!("goal from the hand ({:.0} deg)", f64::from_bits(self.goal_dir_deg.load(Relaxed)))
            }
            GOAL_FRAME => format!(
                "goal pose of frame {}{}",
                self.goal_frame.load(Relaxed),
                if self.planned.load(Relaxed) == 1 { "" } else { " (planning)" }
            ),
            GOAL_POSE => match self.planned.load(Relaxed) {
                1 => {
                    format!("goal pose given by its angles, nearest frame {}", self.goal_frame.load(Relaxed))
                }
                _ => "goal pose given by its angles (planning)".into(),
            },
            _ => "random walks".into(),
        };
        let late = match self.late_ticks.load(Relaxed) {
            0 => String::new(),
            n => format!(
                "; BEHIND: {} walk frames skipped in {n} ticks over the budget (kept real time)",
                self.skipped_frames.load(Relaxed)
            ),
        };
        format!(
            "graph walk of {}: {} plants on {} nodes; {goal}; plant 0 at frame {}; {} transitions taken{late}",
            self.take,
            self.plants,
            self.nodes,
            self.node_frame.load(Relaxed),
            self.transitions.load(Relaxed)
        )
    }

    fn dropped_work(&self) -> u64 {
        self.skipped_frames.load(Relaxed)
    }
}

/// One take a walk draws on: its graph, its frames, and the plan towards a pose goal on it.
pub struct GraphSource {
    /// The take's name (for `frond status`).
    pub take: String,
    /// The graph, built on [`GraphSource::poses`].
    pub graph: MotionGraph,
    /// The take's frames at the graph's rate.
    pub poses: Vec<PoseFrame>,
    planner: PosePlanner,
    /// A pose goal's nearest-node search, [`PLAN_NODES_PER_TICK`] nodes per tick.
    nearest: Option<NearestNodeSearch>,
}

impl GraphSource {
    /// A source (allocates its planner: off the realtime thread).
    pub fn new(take: &str, graph: MotionGraph, poses: Vec<PoseFrame>) -> Self {
        GraphSource { take: take.to_string(), planner: PosePlanner::new(&graph), graph, poses, nearest: None }
    }

    /// Whether the planner has a target but no plan yet.
    fn planning(&self) -> bool {
        self.planner.target().is_some() && self.planner.plan().is_none()
    }

    /// Whether a pose goal still needs work on this source.
    fn busy(&self) -> bool {
        self.nearest.is_some() || self.planning()
    }

    /// One tick's share of the search and the plan; the goal node's frame when the search ends.
    fn work(&mut self, budget: usize) -> Option<u32> {
        if let Some(search) = &mut self.nearest {
            let node = search.work(&self.graph, &self.poses, budget)?;
            self.nearest = None;
            self.planner.start(Some(node));
            return Some(self.graph.node_frames[node as usize]);
        }
        if self.planning() {
            self.planner.work(budget);
        }
        None
    }
}

/// The walkers in the loop.
pub struct GraphStage {
    sources: Vec<GraphSource>,
    /// Per plant: its source and its walker.
    walkers: Vec<(usize, Walker)>,
    /// Per plant: the walk's previous and next frame, interpolated between.
    frames: Vec<(Joints, Joints)>,
    ids: Vec<ElementId>,
    frame_ns: u64,
    t0_ns: u64,
    next_publish_ns: u64,
    frames_done: u64,
    goal: GraphGoal,
    hand_dir_deg: Option<f64>,
    /// Most walk frames per plant one tick steps (catching up after a late tick).
    catch_up_frames: u64,
    /// Nodes of a pose goal's search or plan per tick.
    plan_nodes: usize,
    report: Arc<GraphReport>,
}

impl GraphStage {
    /// Walkers over `sources` (every graph at `fps`) published as `ids` (one plant each, at most
    /// [`MAX_GRAPH_PLANTS`]), plant `i` on source `i mod n` with seed `seed + i`, starting at host
    /// time `t0_ns`; with the report `frond status` reads. Allocates (off the realtime thread).
    pub fn new(
        sources: Vec<GraphSource>,
        ids: &[ElementId],
        seed: u64,
        fps: f64,
        t0_ns: u64,
    ) -> (Self, Arc<GraphReport>) {
        assert!(!sources.is_empty(), "a graph walk needs a source");
        let plants = ids.len().clamp(1, MAX_GRAPH_PLANTS);
        let walkers: Vec<(usize, Walker)> = (0..plants)
            .map(|i| {
                let k = i % sources.len();
                let g = &sources[k].graph;
                (k, Walker::new(g, (i * g.len() / plants) as u32, seed.wrapping_add(i as u64), fps))
            })
            .collect();
        let names: Vec<&str> = sources.iter().map(|s| s.take.as_str()).collect();
        let report = Arc::new(GraphReport {
            take: names.join(", "),
            plants,
            nodes: sources.iter().map(|s| s.graph.len()).sum(),
            goal: AtomicU8::new(GOAL_OFF),
            goal_dir_deg: AtomicU64::new(f64::NAN.to_bits()),
            goal_frame: AtomicU32::new(0),
            planned: AtomicU8::new(0),
            node_frame: AtomicU32::new(sources[0].graph.node_frames[0]),
            transitions: AtomicU64::new(0),
            skipped_frames: AtomicU64::new(0),
            late_ticks: AtomicU64::new(0),
        });
        let rest = [[0.0f32; 3]; JOINTS];
        let stage = GraphStage {
            sources,
            walkers,
            frames: vec![(rest, rest); plants],
            ids: ids[..plants].to_vec(),
            frame_ns: (NS_PER_S as f64 / fps).round().max(1.0) as u64,
            t0_ns,
            next_publish_ns: t0_ns,
            frames_done: 0,
            goal: GraphGoal::Off,
            hand_dir_deg: None,
            catch_up_frames: DEFAULT_CATCH_UP_FRAMES,
            plan_nodes: PLAN_NODES_PER_TICK,
            report: report.clone(),
        };
        (stage, report)
    }

    /// The same stage stepping at most `catch_up_frames` walk frames per plant per tick (at least
    /// 2: the frames published between) and settling `plan_nodes` planner nodes per tick.
    pub fn with_budget(mut self, catch_up_frames: u64, plan_nodes: usize) -> Self {
        self.catch_up_frames = catch_up_frames.max(2);
        self.plan_nodes = plan_nodes.max(1);
        self
    }

    fn walker_goal(&self) -> Goal {
        match self.goal {
            GraphGoal::Dir { deg } => Goal::Direction { dir_deg: deg },
            GraphGoal::Hand => match self.hand_dir_deg {
                Some(dir_deg) => Goal::Direction { dir_deg },
                None => Goal::Random,
            },
            GraphGoal::Off | GraphGoal::Frame { .. } | GraphGoal::Pose { .. } => Goal::Random,
        }
    }

    fn set_goals(&mut self) {
        // Direction and random goals hold no heap data: cloning them never allocates.
        let goal = self.walker_goal();
        for (_, w) in &mut self.walkers {
            w.set_goal(goal.clone());
        }
    }

    /// Advances every walker by one walk frame.
    fn step(&mut self) {
        for ((k, w), f) in self.walkers.iter_mut().zip(self.frames.iter_mut()) {
            let src = &self.sources[*k];
            let s = w.next_frame_with(&src.graph, &src.poses, src.planner.plan());
            *f = (f.1, s.pose.joints_deg);
        }
        self.frames_done += 1;
        if let Some((k, w)) = self.walkers.first() {
            self.report.node_frame.store(self.sources[*k].graph.node_frames[w.node() as usize], Relaxed);
        }
        let taken: u64 = self.walkers.iter().map(|(_, w)| w.transitions_taken()).sum();
        self.report.transitions.store(taken, Relaxed);
    }
}

fn lerp(a: &Joints, b: &Joints, u: f32) -> Joints {
    std::array::from_fn(|j| std::array::from_fn(|c| a[j][c] + (b[j][c] - a[j][c]) * u))
}

/// The ground-plane direction the root bends towards, degrees (0 towards +X, 90 towards +Z), or
/// `None` for a bend under [`HAND_GOAL_MIN_BEND_DEG`]: pitch about +X takes +Y towards +Z, yaw
/// about +Z takes it towards -X (frond's rotation convention).
pub fn bend_direction_deg(root_deg: [f32; 3]) -> Option<f64> {
    let [pitch, yaw, _] = root_deg;
    if pitch.hypot(yaw) < HAND_GOAL_MIN_BEND_DEG {
        return None;
    }
    let (x, z) = (-(yaw.to_radians().sin()) as f64, (pitch.to_radians().sin()) as f64);
    Some(z.atan2(x).to_degrees().rem_euclid(360.0))
}

impl LiveStage for GraphStage {
    fn on_hand(&mut self, _hand: &HandSample, pose: &mut PoseFrame, _element: &mut ElementId) {
        if self.goal == GraphGoal::Hand {
            let dir = bend_direction_deg(pose.joints_deg[0]);
            if dir.is_some() != self.hand_dir_deg.is_some()
                || matches!((dir, self.hand_dir_deg), (Some(a), Some(b)) if (a - b).abs() > 1.0)
            {
                self.hand_dir_deg = dir;
                self.report.goal_dir_deg.store(dir.unwrap_or(f64::NAN).to_bits(), Relaxed);
                self.set_goals();
            }
        }
    }

    fn tick(&mut self, ctx: &TickContext, out: &mut dyn FrameSink) {
        // Pose goals: one source at a time gets the tick's planning budget.
        if let Some(k) = self.sources.iter().position(GraphSource::busy) {
            if let Some(frame) = self.sources[k].work(self.plan_nodes)
                && k == 0
            {
                self.report.goal_frame.store(frame, Relaxed);
            }
            if !self.sources.iter().any(GraphSource::busy) {
                self.report.planned.store(1, Relaxed);
            }
        }
        let elapsed = ctx.now_ns.saturating_sub(self.t0_ns);
        // Catch up with the walk's own frame rate, at most `catch_up_frames` per tick (its
        // budget); behind by more (a late tick, a stall), the walk skips ahead to now, keeping
        // real time, and the frames it skipped are counted.
        // The walk is one frame ahead of now: `frames` holds walk frames `due` and `due + 1`.
        let due = elapsed / self.frame_ns;
        let needed = (due + 2).saturating_sub(self.frames_done);
        if needed > self.catch_up_frames {
            let skipped = needed - self.catch_up_frames;
            self.frames_done += skipped;
            self.report.skipped_frames.fetch_add(skipped, Relaxed);
            self.report.late_ticks.fetch_add(1, Relaxed);
        }
        while self.frames_done <= due + 1 {
            self.step();
        }
        if ctx.now_ns < self.next_publish_ns {
            return;
        }
        let period = NS_PER_S / u64::from(GRAPH_PUBLISH_HZ);
        self.next_publish_ns = (self.next_publish_ns + period).max(ctx.now_ns);
        // `frames.0` is walk frame `due` (at `due * frame_ns <= elapsed`), `frames.1` the next.
        let u = ((elapsed - due * self.frame_ns) as f64 / self.frame_ns as f64).clamp(0.0, 1.0);
        for (id, (a, b)) in self.ids.iter().zip(&self.frames) {
            out.emit(*id, lerp(a, b, u as f32));
        }
    }

    fn every_tick(&self) -> bool {
        true
    }

    fn input(&mut self, input: StageInput) {
        let StageInput::GraphGoal(goal) = input else { return };
        self.goal = goal;
        let (code, dir, frame) = match goal {
            GraphGoal::Off => (GOAL_OFF, f64::NAN, 0),
            GraphGoal::Dir { deg } => (GOAL_DIR, deg, 0),
            GraphGoal::Hand => (GOAL_HAND, f64::NAN, 0),
            GraphGoal::Frame { frame } => (GOAL_FRAME, f64::NAN, frame),
            GraphGoal::Pose { .. } => (GOAL_POSE, f64::NAN, 0),
        };
        self.report.goal.store(code, Relaxed);
        self.report.goal_dir_deg.store(dir.to_bits(), Relaxed);
        self.report.goal_frame.store(frame, Relaxed);
        self.report.planned.store(0, Relaxed);
        for src in &mut self.sources {
            let target = match goal {
                // The node nearest the frame of each plant's own take: the graph keeps frames in
                // order, so the first node at or after it (or the last one).
                GraphGoal::Frame { frame } => {
                    let i = src.graph.node_frames.partition_point(|&f| f < frame);
                    Some(i.min(src.graph.len() - 1) as u32)
                }
                _ => None,
            };
            // A pose by its angles: first the nearest node, over the next ticks, then its plan.
            src.nearest = match goal {
                GraphGoal::Pose { joints_deg } => {
                    Some(NearestNodeSearch::new(PoseFrame { t: 0.0, joints_deg }))
                }
                _ => None,
            };
            src.planner.start(target);
        }
        self.hand_dir_deg = None;
        self.set_goals();
    }
}

fn takes_goals(input: &StageInput) -> bool {
    matches!(input, StageInput::GraphGoal(_))
}

/// Builds `plants` walkers over `sources` (takes and graphs in the takes directory).
pub fn build(
    sources: &[frond_protocol::GraphSource],
    plants: u16,
    seed: u64,
    ctx: &BuildContext,
) -> Result<BuiltStage, BuildError> {
    let plants = usize::from(plants);
    if !(1..=MAX_GRAPH_PLANTS).contains(&plants) {
        return Err(BuildError::invalid(format!(
            "a graph walk has 1..={MAX_GRAPH_PLANTS} plants, not {plants}"
        )));
    }
    let max = frond_protocol::MAX_GRAPH_SOURCES.min(plants);
    if sources.is_empty() || sources.len() > max {
        return Err(BuildError::invalid(format!(
            "a walk of {plants} plants draws on 1..={max} takes, not {}",
            sources.len()
        )));
    }
    let ids = super::live::element_ids(ctx, plants)?;
    let mut loaded = Vec::with_capacity(sources.len());
    let mut fps = None;
    for src in sources {
        let (source, src_fps) = load_source(&src.take, &src.graph, ctx)?;
        match fps {
            Some(f) if f != src_fps => {
                return Err(BuildError::invalid(format!(
                    "the graphs of one walk share one frame rate: {:?} is at {f} fps, graph {:?} at {src_fps}",
                    sources[0].graph, src.graph
                )));
            }
            _ => fps = Some(src_fps),
        }
        loaded.push(source);
    }
    let fps = fps.unwrap_or(30.0);
    let (work, catch_up, plan_nodes) = walk_work(plants, fps, ctx.tick_rate_hz);
    work.check(ctx.tick_rate_hz)?;
    let (stage, report) = GraphStage::new(loaded, ids, seed, fps, ctx.now_ns);
    let stage = stage.with_budget(catch_up, plan_nodes);
    let elements = super::live::plant_elements(ids, "walker", &ctx.rig.name, ctx);
    Ok(BuiltStage {
        stage: Box::new(stage),
        info: StageInfo {
            kind: StageKind::Graph,
            report,
            elements,
            hand_element: None,
            accepts: takes_goals,
            rig: super::live::rig_info(ctx.rig),
            work,
        },
    })
}

/// A walk's work per tick (`plants` walkers on graphs at `fps`, ticks at `tick_rate_hz`): the
/// walk frames a tick steps (at least 2 per plant, the frames published between) and the
/// planner's share of what is left of the stage's budget; with the most frames per plant a
/// late tick may catch up by and the planner's nodes per tick.
pub fn walk_work(plants: usize, fps: f64, tick_rate_hz: u32) -> (TickWork, u64, usize) {
    let per_plant = budget::steps_per_tick(1.0 / fps, tick_rate_hz).max(2);
    let plants = plants.max(1) as u64;
    let walk_ns = plants.saturating_mul(per_plant).saturating_mul(budget::GRAPH_WALK_FRAME_NS);
    let share = budget::stage_share_ns(tick_rate_hz);
    let plan_nodes = (share.saturating_sub(walk_ns) / budget::GRAPH_PLAN_NODE_NS)
        .clamp(MIN_PLAN_NODES_PER_TICK as u64, PLAN_NODES_PER_TICK as u64);
    let plan_ns = plan_nodes * budget::GRAPH_PLAN_NODE_NS;
    let catch_up = (share.saturating_sub(plan_ns) / (plants * budget::GRAPH_WALK_FRAME_NS)).max(per_plant);
    let work = TickWork {
        asked_by: format!("a walk of {plants} plants on graphs at {fps} fps"),
        unit: "walk frames",
        units: plants.saturating_mul(per_plant),
        unit_ns: budget::GRAPH_WALK_FRAME_NS,
        extra_ns: plan_ns,
        fix: "walk fewer plants, or use graphs built at a lower frame rate".into(),
    };
    (work, catch_up, plan_nodes as usize)
}

/// Reads take `take` and its graph `graph` (checked against each other); the graph's rate.
fn load_source(take: &str, graph: &str, ctx: &BuildContext) -> Result<(GraphSource, f64), BuildError> {
    frond_protocol::paths::validate_take_name(graph)
        .map_err(|e| BuildError { kind: ControlErrorKind::BadName, message: format!("graph name: {e}") })?;
    let path = ctx.takes_dir.join(format!("{graph}.graph.json"));
    let text = frond_formats::rig_files::read_small_text(&path, MAX_GRAPH_FILE_BYTES).map_err(|e| {
        BuildError::invalid(format!("cannot read graph {graph:?} at {}: {}", path.display(), e.reason()))
    })?;
    let file =
        GraphFile::from_json(&text).map_err(|e| BuildError::invalid(format!("{}: {e}", path.display())))?;
    let bytes = super::live::read_take(ctx.takes_dir, take)?;
    let (t, damage) = Take::from_bytes_noting_damage(&bytes)
        .map_err(|e| BuildError::invalid(format!("take {take:?}: {e}")))?;
    // The take is resampled to the graph's rate only once it is known to give the frames the
    // graph was built on: counted first, so that a take whose times stretch it (frames a second
    // apart at 1000 fps) costs nothing before it is refused.
    let recorded: Vec<PoseFrame> = t.layer(GLOBAL_LAYER, false).iter().map(|f| f.pose).collect();
    drop(t);
    let plan = frond_motion::take::resample_plan(&recorded, file.fps);
    if plan.frames != u64::from(file.take_frames) {
        return Err(BuildError::invalid(format!(
            "graph {graph:?} was built on {} frames at {} fps, but take {take:?} makes {} frames at that rate{}",
            file.take_frames,
            file.fps,
            plan.frames,
            damage.map(|d| format!(" (damaged: {d})")).unwrap_or_default()
        )));
    }
    let poses = frond_motion::clip::Clip::from_poses(&recorded, file.fps).frames;
    drop(recorded);
    let motion_graph = file.graph_for(&poses).map_err(|e| {
        BuildError::invalid(format!(
            "graph {graph:?} and take {take:?}{}: {e}",
            damage.map(|d| format!(" (damaged: {d})")).unwrap_or_default()
        ))
    })?;
    Ok((GraphSource::new(take, motion_graph, poses), file.fps))
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_formats::rig_toml::RigText;
    use frond_motion::graph::{ControlPoint, GraphParams, build_graph, control_positions_m};
    use frond_motion::skeleton::Skeleton;

    struct Sink(Vec<Joints>);
    impl FrameSink for Sink {
        fn emit(&mut self, _element: ElementId, joints_deg: Joints) {
            self.0.push(joints_deg);
        }
    }

    #[test]
    fn published_frames_interpolate_between_walk_frames() {
        let sway = frond_motion::graph::sample_sway(600);
        let path = control_positions_m(ControlPoint::Top, &Skeleton::even(1.0), 1.0, &sway);
        let graph = build_graph(&sway, &path, &GraphParams::new(ControlPoint::Top)).unwrap();
        // The same walk, frame by frame, as the reference.
        let mut reference = Walker::new(&graph, 0, 4, 30.0);
        let walk: Vec<Joints> =
            (0..40).map(|_| reference.next_frame(&graph, &sway).pose.joints_deg).collect();
        let (mut stage, _) =
            GraphStage::new(vec![GraphSource::new("sway", graph, sway)], &[ElementId::new(40)], 4, 30.0, 0);
        let hand = HandSample::default();
        let mut sink = Sink(Vec::new());
        // Publishing at 60 Hz on 1 ms ticks: a publication at time t shows the walk between
        // frames floor(t / 33.3 ms) and the next, in proportion.
        let mut times = Vec::new();
        for tick in 0..1000u64 {
            let ctx = TickContext { now_ns: tick * 1_000_000, device_time_us: 0, hand };
            let before = sink.0.len();
            stage.tick(&ctx, &mut sink);
            if sink.0.len() > before {
                times.push(ctx.now_ns);
            }
        }
        assert!(sink.0.len() >= 59, "{} publications in 1 s", sink.0.len());
        let frame_ns = (1e9f64 / 30.0).round() as u64;
        for (k, got) in sink.0.iter().enumerate().take(50) {
            let due = (times[k] / frame_ns) as usize;
            let (a, b) = (walk[due], walk[due + 1]);
            let u = (times[k] - due as u64 * frame_ns) as f32 / frame_ns as f32;
            for j in 0..JOINTS {
                for c in 0..3 {
                    let want = a[j][c] + (b[j][c] - a[j][c]) * u;
                    assert!((got[j][c] - want).abs() < 1e-3, "publication {k}: {} vs {want}", got[j][c]);
                }
            }
        }
    }

    #[test]
    fn a_pose_goal_finds_its_nearest_node_over_several_ticks() {
        let sway = frond_motion::graph::sample_sway(600);
        let path = control_positions_m(ControlPoint::Top, &Skeleton::even(1.0), 1.0, &sway);
        let graph = build_graph(&sway, &path, &GraphParams::new(ControlPoint::Top)).unwrap();
        let goal = PoseFrame { t: 0.0, joints_deg: [[9.0, -14.0, 3.0], [4.0, 2.0, 0.0], [0.0; 3], [1.0; 3]] };
        // Brute force, by the squared angle differences.
        let d2 = |p: &PoseFrame| -> f64 {
            (0..JOINTS)
                .flat_map(|j| (0..3).map(move |c| (j, c)))
                .map(|(j, c)| (p.joints_deg[j][c] as f64 - goal.joints_deg[j][c] as f64).powi(2))
                .sum()
        };
        let want = (0..graph.len())
            .min_by(|&a, &b| {
                d2(&sway[graph.node_frames[a] as usize]).total_cmp(&d2(&sway[graph.node_frames[b] as usize]))
            })
            .unwrap() as u32;
        let mut search = NearestNodeSearch::new(goal);
        let mut ticks = 1;
        let found = loop {
            if let Some(n) = search.work(&graph, &sway, 7) {
                break n;
            }
            ticks += 1;
        };
        assert_eq!(found, want);
        assert_eq!(ticks, graph.len().div_ceil(7), "7 nodes a tick");
    }

    #[test]
    fn a_walk_behind_its_budget_skips_ahead_and_says_so() {
        let sway = frond_motion::graph::sample_sway(600);
        let path = control_positions_m(ControlPoint::Top, &Skeleton::even(1.0), 1.0, &sway);
        let graph = build_graph(&sway, &path, &GraphParams::new(ControlPoint::Top)).unwrap();
        let (stage, report) =
            GraphStage::new(vec![GraphSource::new("sway", graph, sway)], &[ElementId::new(40)], 4, 30.0, 0);
        let mut stage = stage.with_budget(4, 100);
        let mut sink = Sink(Vec::new());
        let at = |ns: u64| TickContext { now_ns: ns, device_time_us: 0, hand: HandSample::default() };
        // The first tick steps walk frames 0 and 1; on time, nothing is skipped.
        stage.tick(&at(0), &mut sink);
        assert_eq!(stage.frames_done, 2);
        assert!(!report.describe().contains("BEHIND"), "{}", report.describe());
        // A 1 s stall at 30 fps: frame 30 is due, frames 2..=31 needed (30), 4 fit: 26 are
        // skipped and the walk holds frames 30 and 31, at the present.
        stage.tick(&at(1_000_000_000), &mut sink);
        assert_eq!(stage.frames_done, 32);
        let said = report.describe();
        assert!(said.contains("BEHIND: 26 walk frames skipped in 1 ticks over the budget"), "{said}");
        assert_eq!(report.dropped_work(), 26);
    }

    #[test]
    fn a_walk_that_does_not_fit_in_a_tick_is_refused() {
        // 64 plants at 1000 fps on 30 Hz ticks: 34 frames each a tick, 2176 walk frames of
        // 100 ns, 218 us: fits the 2083 us share. At 1 kHz: 2 each, 128, 13 us: fits, with the
        // planner's 2000 nodes (40 us). At 8 kHz: 128 frames, 13 us, over the 7.8 us share.
        let (w, _, nodes) = walk_work(64, 1000.0, 30);
        assert!(w.check(30).is_ok() && w.units == 2176 && nodes == 2000, "{w:?}");
        let (w, catch_up, nodes) = walk_work(64, 30.0, 1000);
        assert_eq!((w.units, nodes), (128, 2000));
        assert!(w.check(1000).is_ok(), "{w:?}");
        assert_eq!(catch_up, 3, "(62500 - 40000) / (64 * 100) walk frames per plant");
        let (w, _, nodes) = walk_work(64, 30.0, 8000);
        assert_eq!(nodes, MIN_PLAN_NODES_PER_TICK);
        let e = w.check(8000).unwrap_err().message;
        assert!(
            e.starts_with(
                "a walk of 64 plants on graphs at 30 fps asks for 128 walk frames per tick at 8000 Hz"
            ),
            "{e}"
        );
    }

    #[test]
    fn a_take_is_counted_at_the_graphs_rate_before_it_is_resampled() {
        use frond_motion::layers::Take;
        use frond_motion::take::{TakeFrame, TakeHeader};
        let dir = tempfile::tempdir().unwrap();
        // A graph of 600 sway frames at 30 fps, and a take of 2000 frames 0.9 s apart (each gap
        // under the 1 s discontinuity rule, so interpolated): 1999 * 0.9 s = 1799.1 s at 30 fps
        // is frames 0..=53973, 53974 frames, not the 600 the graph was built on.
        let sway = frond_motion::graph::sample_sway(600);
        let path = control_positions_m(ControlPoint::Top, &Skeleton::even(1.0), 1.0, &sway);
        let params = GraphParams::new(ControlPoint::Top);
        let graph = build_graph(&sway, &path, &params).unwrap();
        let file = GraphFile::new(&graph, &params, "stretched", 30.0, &sway);
        std::fs::write(dir.path().join("stretched.graph.json"), file.to_json()).unwrap();
        let frames = (0..2000u64)
            .map(|k| TakeFrame {
                seq: k,
                pose: PoseFrame { t: 0.9 * k as f64, joints_deg: [[k as f32 * 0.01; 3]; 4] },
                ..Default::default()
            })
            .collect();
        let take = Take {
            header: TakeHeader::offline("stretched", "grass", 30),
            element_names: vec![],
            frames,
            markers: vec![],
        };
        std::fs::write(dir.path().join("stretched.take"), take.to_bytes()).unwrap();
        let rig = frond_motion::Rig::from_toml_str(include_str!("../../../../rig-files/plants/grass.toml"))
            .unwrap();
        let ctx = BuildContext {
            takes_dir: dir.path(),
            rig: &rig,
            g3_range_deg: 60.0,
            tick_rate_hz: 1000,
            now_ns: 0,
            free_ids: &[ElementId::FIRST_STAGE],
            name: "walk",
        };
        let e = load_source("stretched", "stretched", &ctx).err().unwrap().message;
        assert_eq!(
            e,
            "graph \"stretched\" was built on 600 frames at 30 fps, but take \"stretched\" makes 53974 \
             frames at that rate"
        );
    }

    #[test]
    fn the_hand_bend_sets_the_goal_direction() {
        // Pitch bends towards +Z (90 deg), negative yaw towards +X (0 deg), positive yaw -X.
        assert!((bend_direction_deg([20.0, 0.0, 0.0]).unwrap() - 90.0).abs() < 1e-6);
        assert!((bend_direction_deg([-20.0, 0.0, 0.0]).unwrap() - 270.0).abs() < 1e-6);
        assert!(bend_direction_deg([0.0, -20.0, 0.0]).unwrap().abs() < 1e-6);
        assert!((bend_direction_deg([0.0, 20.0, 0.0]).unwrap() - 180.0).abs() < 1e-6);
        assert_eq!(bend_direction_deg([2.0, 2.0, 40.0]), None, "roll alone is no bend");
    }
}
