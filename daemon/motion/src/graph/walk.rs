//! Walks on a motion graph: seed 003, section 6.1.
//!
//! A [`Walker`] emits one frame per call: the take's frame at a node, or an in-between frame on a
//! transition. At each node it picks an outgoing edge by its [`Goal`]:
//!
//! - [`Goal::Random`] (6.1.1): any outgoing edge, uniformly, from a seeded generator (same seed,
//!   same walk). Every node of an optimised graph has an outgoing edge, so a walk never stalls.
//! - [`Goal::Direction`] (6.1.2): the edge whose original path afterwards leads the control point
//!   most towards a ground-plane direction (0 deg towards +X, 90 deg towards +Z, as the wind):
//!   the score is the control point's displacement along the direction from the current node to
//!   `lookahead_frames` backbone samples past the edge's target ("based on the velocities of a
//!   few successive samples located on the corresponding path").
//! - [`Goal::Pose`] (beyond the paper): the shortest path in frames to a target node, planned by
//!   [`PosePlan::new`] (Dijkstra on the reversed graph) and replanned whenever the goal changes;
//!   at the target the walk takes the shortest loop back to it.
//!
//! In-between frames (6.1.1) are cubic Hermite curves in each joint angle from the transition's
//! first frame to its last, with the take's velocity at both ends (one frame's change, scaled to
//! the curve), so neither angle nor angular velocity jumps where a transition starts or ends.
//! [`Walker::next_frame`] does not allocate.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::{Edge, EdgeKind, MotionGraph, Rows};
use crate::rng::SeededRng;
use crate::sample::{JOINTS, PoseFrame};

/// Default lookahead of goal-directed choices, frames.
pub const DEFAULT_LOOKAHEAD_FRAMES: u32 = 10;

/// Shortest distances in frames from every node to one target node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PosePlan {
    /// The target node.
    pub target: u32,
    /// Frames from each node to the target (`u32::MAX`: unreachable, never in an optimised graph).
    pub frames_to_target: Vec<u32>,
}

impl PosePlan {
    /// Plans every node's shortest way to `target` (Dijkstra on the reversed edges, weights the
    /// frames each edge takes).
    pub fn new(graph: &MotionGraph, target: u32) -> Self {
        let mut planner = PosePlanner::new(graph);
        planner.start(Some(target));
        while !planner.work(usize::MAX) {}
        PosePlan { target: planner.target.unwrap_or(target), frames_to_target: planner.dist }
    }
}

/// [`PosePlan`] for a live stage: the buffers allocated once, and the search spread over ticks
/// (`work` pops at most a budget of nodes per call), so a goal change never stalls a tick and
/// never allocates.
#[derive(Debug, Clone)]
pub struct PosePlanner {
    /// Each node's incoming edges as (source, frames).
    rev: Rows<(u32, u32)>,
    dist: Vec<u32>,
    heap: BinaryHeap<Reverse<(u32, u32)>>,
    target: Option<u32>,
    done: bool,
}

impl PosePlanner {
    /// Buffers for `graph` (allocates; off the realtime thread).
    pub fn new(graph: &MotionGraph) -> Self {
        let rev = Rows::new(graph.len(), graph.edges.iter().map(|e| (e.to as usize, (e.from, e.frames()))));
        PosePlanner {
            rev,
            dist: vec![u32::MAX; graph.len()],
            heap: BinaryHeap::with_capacity(graph.edges.len() + 1),
            target: None,
            done: false,
        }
    }

    /// Starts planning towards `target` (clamped to the graph); `None` stops.
    pub fn start(&mut self, target: Option<u32>) {
        self.dist.fill(u32::MAX);
        self.heap.clear();
        self.target = target.map(|t| t.min(self.dist.len().saturating_sub(1) as u32));
        self.done = false;
        if let Some(t) = self.target {
            self.dist[t as usize] = 0;
            self.heap.push(Reverse((0, t)));
        }
    }

    /// Runs at most `budget` steps of the search; true once the plan is complete. The lazy
    /// Dijkstra pushes at most one entry per edge plus one, the heap's capacity: no allocation.
    pub fn work(&mut self, budget: usize) -> bool {
        for _ in 0..budget {
            let Some(Reverse((d, v))) = self.heap.pop() else {
                self.done = self.target.is_some();
                return self.done;
            };
            if d > self.dist[v as usize] {
                continue;
            }
            for &(u, w) in self.rev.row(v as usize) {
                let nd = d.saturating_add(w);
                if nd < self.dist[u as usize] {
                    self.dist[u as usize] = nd;
                    self.heap.push(Reverse((nd, u)));
                }
            }
        }
        false
    }

    /// The target, if planning towards one.
    pub fn target(&self) -> Option<u32> {
        self.target
    }

    /// The complete plan (frames to the target from each node), once [`Self::work`] finished.
    pub fn plan(&self) -> Option<&[u32]> {
        self.done.then_some(&self.dist[..])
    }
}

/// What a walk aims for.
#[derive(Debug, Clone, PartialEq)]
pub enum Goal {
    /// Any outgoing edge at random.
    Random,
    /// A ground-plane direction, degrees (0 towards +X, 90 towards +Z).
    Direction {
        /// The direction, degrees.
        dir_deg: f64,
    },
    /// The shortest way to a node.
    Pose(PosePlan),
}

/// One frame of a walk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkStep {
    /// The pose (its `t` is the walk's frame time).
    pub pose: PoseFrame,
    /// The node shown, or `None` for an in-between frame.
    pub node: Option<u32>,
    /// The edge being followed from this frame on, if this frame is a node.
    pub chose: Option<Edge>,
}

/// A walk on a graph over a take's poses (see the module doc).
#[derive(Debug, Clone)]
pub struct Walker {
    node: u32,
    edge: Option<Edge>,
    step: u32,
    rng: SeededRng,
    goal: Goal,
    lookahead_frames: u32,
    frame: u64,
    fps: f64,
    transitions_taken: u64,
}

impl Walker {
    /// A walk starting at `start` (clamped to the graph) with a seeded generator, at `fps`.
    pub fn new(graph: &MotionGraph, start: u32, seed: u64, fps: f64) -> Self {
        Walker {
            node: start.min(graph.len().saturating_sub(1) as u32),
            edge: None,
            step: 0,
            rng: SeededRng::new(seed),
            goal: Goal::Random,
            lookahead_frames: DEFAULT_LOOKAHEAD_FRAMES,
            frame: 0,
            fps,
            transitions_taken: 0,
        }
    }

    /// Sets the goal from the next choice on.
    pub fn set_goal(&mut self, goal: Goal) {
        self.goal = goal;
    }

    /// The current goal.
    pub fn goal(&self) -> &Goal {
        &self.goal
    }

    /// Sets the lookahead of direction goals (at least 1 frame).
    pub fn set_lookahead_frames(&mut self, frames: u32) {
        self.lookahead_frames = frames.max(1);
    }

    /// The node last shown or being left.
    pub fn node(&self) -> u32 {
        self.node
    }

    /// Transitions taken so far.
    pub fn transitions_taken(&self) -> u64 {
        self.transitions_taken
    }

    /// Frames emitted so far.
    pub fn frames(&self) -> u64 {
        self.frame
    }

    /// The next frame of the walk over `poses` (the take `graph` was built on, at its rate).
    pub fn next_frame(&mut self, graph: &MotionGraph, poses: &[PoseFrame]) -> WalkStep {
        self.next_frame_with(graph, poses, None)
    }

    /// [`Self::next_frame`], with a shared pose plan (frames to the target from each node, as
    /// [`PosePlanner::plan`] gives) taking the place of the goal while it is `Some`.
    pub fn next_frame_with(
        &mut self,
        graph: &MotionGraph,
        poses: &[PoseFrame],
        plan: Option<&[u32]>,
    ) -> WalkStep {
        let t = self.frame as f64 / self.fps;
        self.frame += 1;
        if let Some(e) = self.edge
            && self.step <= e.inbetweens
        {
            let pose = inbetween(graph, poses, &e, self.step);
            self.step += 1;
            return WalkStep { pose: PoseFrame { t, ..pose }, node: None, chose: None };
        }
        if let Some(e) = self.edge {
            self.node = e.to;
        }
        let e = match plan {
            Some(p) => choose_by_plan(graph.out_edges(self.node), p),
            None => self.choose(graph),
        };
        if e.kind == EdgeKind::Transition {
            self.transitions_taken += 1;
        }
        self.edge = Some(e);
        self.step = 1;
        let pose = poses[graph.node_frames[self.node as usize] as usize];
        WalkStep { pose: PoseFrame { t, ..pose }, node: Some(self.node), chose: Some(e) }
    }

    fn choose(&mut self, graph: &MotionGraph) -> Edge {
        let out = graph.out_edges(self.node);
        match &self.goal {
            Goal::Random => out[self.rng.below(out.len())],
            Goal::Direction { dir_deg } => {
                let r = dir_deg.to_radians();
                let (gx, gz) = (r.cos(), r.sin());
                let here = graph.node_positions_m[self.node as usize];
                let mut best = out[0];
                let mut best_score = f64::NEG_INFINITY;
                for e in out {
                    let there = graph.node_positions_m[ahead(graph, e.to, self.lookahead_frames) as usize];
                    let score = (there[0] - here[0]) * gx + (there[2] - here[2]) * gz;
                    if score > best_score {
                        best_score = score;
                        best = *e;
                    }
                }
                best
            }
            Goal::Pose(plan) => choose_by_plan(out, &plan.frames_to_target),
        }
    }
}

/// The edge of `out` on a shortest way to the plan's target.
fn choose_by_plan(out: &[Edge], frames_to_target: &[u32]) -> Edge {
    let mut best = out[0];
    let mut best_cost = u64::MAX;
    for e in out {
        let rest = frames_to_target.get(e.to as usize).copied().unwrap_or(u32::MAX);
        let cost = e.frames() as u64 + rest as u64;
        if cost < best_cost {
            best_cost = cost;
            best = *e;
        }
    }
    best
}

/// The node `frames` backbone steps after `node` (or the last one reachable on the backbone).
fn ahead(graph: &MotionGraph, mut node: u32, frames: u32) -> u32 {
    for _ in 0..frames {
        match graph.out_edges(node).first() {
            Some(e) if e.kind == EdgeKind::Backbone => node = e.to,
            _ => break,
        }
    }
    node
}

/// In-between frame `i` (1-based) of a transition: cubic Hermite from the first node's pose to
/// the last's with the take's one-frame velocity at both ends (see the module doc).
pub fn inbetween(graph: &MotionGraph, poses: &[PoseFrame], e: &Edge, i: u32) -> PoseFrame {
    let fa = graph.node_frames[e.from as usize] as usize;
    let fb = graph.node_frames[e.to as usize] as usize;
    let intervals = (e.inbetweens + 1) as f32;
    let u = i as f32 / intervals;
    let (a, b) = (&poses[fa], &poses[fb]);
    let va = velocity(poses, fa, true);
    let vb = velocity(poses, fb, false);
    let (h00, h10, h01, h11) = hermite(u);
    let mut joints_deg = [[0.0f32; 3]; JOINTS];
    for j in 0..JOINTS {
        for c in 0..3 {
            joints_deg[j][c] = h00 * a.joints_deg[j][c]
                + h10 * intervals * va[j][c]
                + h01 * b.joints_deg[j][c]
                + h11 * intervals * vb[j][c];
        }
    }
    PoseFrame { t: 0.0, joints_deg }
}

/// The take's velocity at frame `f` in degrees per frame: forwards at a transition's start,
/// backwards at its end (falling back to the other side at the take's ends).
fn velocity(poses: &[PoseFrame], f: usize, start: bool) -> [[f32; 3]; JOINTS] {
    let (p, q) = if (start && f + 1 < poses.len()) || f == 0 { (f, f + 1) } else { (f - 1, f) };
    let q = q.min(poses.len() - 1);
    std::array::from_fn(|j| std::array::from_fn(|c| poses[q].joints_deg[j][c] - poses[p].joints_deg[j][c]))
}

fn hermite(u: f32) -> (f32, f32, f32, f32) {
    let (u2, u3) = (u * u, u * u * u);
    (2.0 * u3 - 3.0 * u2 + 1.0, u3 - 2.0 * u2 + u, -2.0 * u3 + 3.0 * u2, u3 - u2)
}
