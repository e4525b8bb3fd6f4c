//! Motion graphs of seed 003, section 5 ("Motion Processing and Optimisation"), as pure math.
//!
//! A graph is built from any take (simulated or performed by hand) for one control point of the
//! plant ([`ControlPoint`]): the backbone of successive samples (5.1), transitions where the
//! control point's path passes near itself going forwards (5.2.1, Fig. 4), thinned and pruned
//! (5.3) into one strongly connected graph that a walk ([`walk`]) can traverse forever.
//!
//! - [`build`]: [`build_graph`] and its [`GraphParams`];
//! - [`walk`]: random, goal-directed (6.1.2) and pose-goal walks and their in-between frames.
//!
//! The graph file (`NAME.graph.json`) is `frond_formats::graph_file`.

use glam::{Mat4, Vec3};
use thiserror::Error;

use crate::sample::{JOINTS, PoseFrame};
use crate::skeleton::Skeleton;

pub mod build;
#[cfg(test)]
mod tests;
pub mod walk;

pub use build::{GraphParams, build_graph};
pub use walk::{Goal, WalkStep, Walker};

/// Most samples a graph is built from (an hour at 300 frames per second).
pub const MAX_GRAPH_SAMPLES: usize = 1_080_000;
/// Largest `extend` (k of Fig. 4).
pub const MAX_EXTEND: u32 = 64;
/// Most in-between frames of one transition.
pub const MAX_INBETWEENS: u32 = 1024;

/// The point of the plant a graph is built for (section 5: "only one specific control point").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlPoint {
    /// Joint 1, 2 or 3 (joint 0 is anchored and never moves).
    Joint(u8),
    /// The top of the plant (the rig's `mesh.height_m`).
    Top,
}

impl ControlPoint {
    /// The name used on the command line and in the graph file.
    pub fn name(self) -> String {
        match self {
            ControlPoint::Joint(i) => format!("joint{i}"),
            ControlPoint::Top => "top".into(),
        }
    }

    /// The control point's world position in a pose, by forward kinematics of the skeleton
    /// ([`Skeleton::joint_matrices`]); `top_m` is the plant's top height.
    pub fn position_m(self, skeleton: &Skeleton, top_m: f32, pose: &PoseFrame) -> Vec3 {
        let world: [Mat4; JOINTS] = skeleton.joint_matrices(&pose.joints_deg);
        match self {
            ControlPoint::Joint(i) => world[i as usize].w_axis.truncate(),
            ControlPoint::Top => {
                let above = (top_m - skeleton.heights_m[JOINTS - 1]).max(0.0);
                world[JOINTS - 1].transform_point3(Vec3::new(0.0, above, 0.0))
            }
        }
    }
}

impl std::str::FromStr for ControlPoint {
    type Err = GraphError;
    fn from_str(s: &str) -> Result<Self, GraphError> {
        match s {
            "joint1" => Ok(ControlPoint::Joint(1)),
            "joint2" => Ok(ControlPoint::Joint(2)),
            "joint3" => Ok(ControlPoint::Joint(3)),
            "top" => Ok(ControlPoint::Top),
            other => Err(GraphError::BadControl(other.to_string())),
        }
    }
}

/// The control point's positions over a take's frames, f64 for the neighbour search.
pub fn control_positions_m(
    control: ControlPoint,
    skeleton: &Skeleton,
    top_m: f32,
    poses: &[PoseFrame],
) -> Vec<[f64; 3]> {
    poses.iter().map(|p| control.position_m(skeleton, top_m, p).as_dvec3().to_array()).collect()
}

/// A sway whose top path crosses itself often, `frames` frames at 30 per second: joint 0 swings
/// 15 degrees in pitch and in yaw with incommensurate periods (41.3 and 29.7 frames), the other
/// joints at half its angles. The motion the graph, allocation and stage tests build graphs of.
pub fn sample_sway(frames: usize) -> Vec<PoseFrame> {
    (0..frames)
        .map(|i| {
            let t = i as f64;
            let pitch = 15.0 * (std::f64::consts::TAU * t / 41.3).sin();
            let yaw = 15.0 * (std::f64::consts::TAU * t / 29.7 + 0.5).sin();
            let mut joints_deg = [[(pitch * 0.5) as f32, (yaw * 0.5) as f32, 0.0]; JOINTS];
            joints_deg[0] = [pitch as f32, yaw as f32, 0.0];
            PoseFrame { t: t / 30.0, joints_deg }
        })
        .collect()
}

/// How an edge moves between two nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EdgeKind {
    /// From a sample to the next one of the take (section 5.1).
    Backbone,
    /// A transition to another part of the take, bridged by in-between frames (5.2.1, 6.1.1).
    Transition,
}

/// One edge: node indices, its kind and its in-between frame count (0 for the backbone).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    /// Source node index.
    pub from: u32,
    /// Target node index.
    pub to: u32,
    /// Backbone or transition.
    pub kind: EdgeKind,
    /// Frames shown between `from` and `to`.
    pub inbetweens: u32,
}

impl Edge {
    /// Frames the walk spends on this edge (from `from` up to, not including, `to`).
    pub fn frames(&self) -> u32 {
        self.inbetweens + 1
    }
}

/// Ranges of take frames (inclusive) that pruning removed, and why.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Pruned {
    /// Transitions found before the optimisations of section 5.3.
    pub transitions_found: u64,
    /// Transitions dropped because a later sample of the same contiguous segment was kept.
    pub transitions_same_segment: u64,
    /// Transitions dropped by the pose gate (`max_pose_deg`).
    pub transitions_pose_gate: u64,
    /// Transitions dropped because a sample had more than `max_transitions`.
    pub transitions_over_cap: u64,
    /// Frames removed as dead ends (repeated until nothing changed), as `[first, last]` ranges.
    pub dead_end_frames: Vec<[u32; 2]>,
    /// Frames outside the largest strongly connected part, as `[first, last]` ranges.
    pub outside_largest_part_frames: Vec<[u32; 2]>,
    /// Transitions removed with the frames above.
    pub transitions_removed: u64,
}

/// An optimised, closed motion graph over a take's frames (Fig. 5): every node has an outgoing
/// edge and every node reaches every other.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionGraph {
    /// The take frame of each node, strictly increasing.
    pub node_frames: Vec<u32>,
    /// The control point's position at each node, metres.
    pub node_positions_m: Vec<[f64; 3]>,
    /// Edges sorted by `from`, then backbone first, then by `to`.
    pub edges: Vec<Edge>,
    /// `edges[first_edge[i]..first_edge[i + 1]]` leave node `i`.
    pub first_edge: Vec<u32>,
    /// What the optimisations removed.
    pub pruned: Pruned,
}

impl MotionGraph {
    /// Assembles a graph from nodes and edges in any order (edges by node index), building the
    /// outgoing-edge index.
    pub fn from_parts(
        node_frames: Vec<u32>,
        node_positions_m: Vec<[f64; 3]>,
        mut edges: Vec<Edge>,
        pruned: Pruned,
    ) -> Self {
        edges.sort_by_key(|e| (e.from, e.kind == EdgeKind::Transition, e.to));
        let first_edge = row_starts(node_frames.len(), edges.iter().map(|e| e.from as usize));
        MotionGraph { node_frames, node_positions_m, edges, first_edge, pruned }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.node_frames.len()
    }

    /// True for a graph without nodes (never from [`build_graph`]).
    pub fn is_empty(&self) -> bool {
        self.node_frames.is_empty()
    }

    /// Edges leaving node `node`.
    pub fn out_edges(&self, node: u32) -> &[Edge] {
        let n = node as usize;
        &self.edges[self.first_edge[n] as usize..self.first_edge[n + 1] as usize]
    }

    /// Number of transition edges.
    pub fn transitions(&self) -> usize {
        self.edges.iter().filter(|e| e.kind == EdgeKind::Transition).count()
    }

    /// The node at take frame `frame`, if the graph kept it.
    pub fn node_at_frame(&self, frame: u32) -> Option<u32> {
        self.node_frames.binary_search(&frame).ok().map(|i| i as u32)
    }
}

/// Where each key's row starts in values grouped by key (compressed sparse rows): row `k` is
/// `start[k]..start[k + 1]`, for `keys` keys (each `< keys`).
pub(crate) fn row_starts(keys: usize, of: impl Iterator<Item = usize>) -> Vec<u32> {
    let mut start = vec![0u32; keys + 1];
    for k in of {
        start[k + 1] += 1;
    }
    for k in 0..keys {
        start[k + 1] += start[k];
    }
    start
}

/// Values grouped by a key, each row in the order given (compressed sparse rows): the
/// adjacency lists of the graph build and of the pose planner.
#[derive(Debug, Clone)]
pub(crate) struct Rows<T> {
    start: Vec<u32>,
    values: Vec<T>,
}

impl<T: Copy + Default> Rows<T> {
    /// Groups `items` (`(key, value)`, keys `< keys`) by key.
    pub(crate) fn new(keys: usize, items: impl Iterator<Item = (usize, T)> + Clone) -> Self {
        let start = row_starts(keys, items.clone().map(|(k, _)| k));
        let mut values = vec![T::default(); start[keys] as usize];
        let mut fill = start.clone();
        for (k, v) in items {
            values[fill[k] as usize] = v;
            fill[k] += 1;
        }
        Rows { start, values }
    }

    /// The values of key `k`.
    pub(crate) fn row(&self, k: usize) -> &[T] {
        &self.values[self.start[k] as usize..self.start[k + 1] as usize]
    }
}

/// A pose goal as written (`--goal-pose P`, `frond graph goal pose P`): a take frame or the 12
/// joint angles themselves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoseGoalSpec {
    /// `frame=N`: the pose of frame `N` of the take at the graph's rate.
    Frame(u32),
    /// 12 comma-separated angles, degrees: pitch, yaw, roll of joints 0..3.
    Angles([[f32; 3]; JOINTS]),
}

/// Largest absolute angle of a pose goal, degrees.
pub const MAX_GOAL_ANGLE_DEG: f32 = 360.0;

impl std::str::FromStr for PoseGoalSpec {
    type Err = PoseGoalError;

    fn from_str(spec: &str) -> Result<Self, PoseGoalError> {
        if let Some(n) = spec.strip_prefix("frame=") {
            return n
                .trim()
                .parse()
                .map(PoseGoalSpec::Frame)
                .map_err(|_| PoseGoalError::BadFrame(spec.to_string()));
        }
        let values: Vec<f32> = spec
            .split(',')
            .take(3 * JOINTS + 1)
            .map(|v| v.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|_| PoseGoalError::NotNumbers(spec.to_string()))?;
        if values.len() != 3 * JOINTS
            || !values.iter().all(|v| v.is_finite() && v.abs() <= MAX_GOAL_ANGLE_DEG)
        {
            return Err(PoseGoalError::BadAngles { spec: spec.to_string(), found: values.len() });
        }
        Ok(PoseGoalSpec::Angles(std::array::from_fn(|j| std::array::from_fn(|c| values[3 * j + c]))))
    }
}

/// A pose goal ([`PoseGoalSpec`]) that does not parse; each names what was typed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PoseGoalError {
    /// `frame=N` whose `N` is not a frame number.
    #[error("{0:?}: frame=N needs a frame number from 0 to {max}", max = u32::MAX)]
    BadFrame(String),
    /// Neither `frame=N` nor comma-separated numbers.
    #[error("{0:?}: expected frame=N or 12 comma-separated angles in degrees")]
    NotNumbers(String),
    /// Numbers, but not 12 of them, or one not finite or beyond [`MAX_GOAL_ANGLE_DEG`].
    #[error(
        "{spec:?}: expected 12 finite angles within +-{max} degrees (pitch, yaw, roll of joints 0..3), found {found}{more} values",
        max = MAX_GOAL_ANGLE_DEG,
        more = if *found > 3 * JOINTS { " or more" } else { "" }
    )]
    BadAngles {
        /// What was typed.
        spec: String,
        /// How many numbers were read (reading stops after 13).
        found: usize,
    },
}

/// The node whose take pose is nearest `goal` (Euclidean over the 12 angles,
/// [`build::pose_distance_deg`]); the first of equals. `poses` are the take's frames the graph
/// was built on.
pub fn nearest_node(graph: &MotionGraph, poses: &[PoseFrame], goal: &PoseFrame) -> u32 {
    NearestNodeSearch::new(*goal).work(graph, poses, usize::MAX).unwrap_or(0)
}

/// [`nearest_node`] a bounded number of nodes at a time, for the realtime loop (a
/// 100,000-node graph would take a millisecond in one go). Holds no heap data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearestNodeSearch {
    goal: PoseFrame,
    next: usize,
    best: (f64, u32),
}

impl NearestNodeSearch {
    /// A search for the node nearest `goal`, nothing scanned yet.
    pub fn new(goal: PoseFrame) -> Self {
        NearestNodeSearch { goal, next: 0, best: (f64::INFINITY, 0) }
    }

    /// Scans up to `budget` more nodes; the nearest node once every node is seen.
    pub fn work(&mut self, graph: &MotionGraph, poses: &[PoseFrame], budget: usize) -> Option<u32> {
        let end = self.next.saturating_add(budget).min(graph.len());
        for (i, &f) in graph.node_frames[self.next..end].iter().enumerate() {
            let d = build::pose_distance_deg(&poses[f as usize], &self.goal);
            if d < self.best.0 {
                self.best = (d, (self.next + i) as u32);
            }
        }
        self.next = end;
        (end == graph.len()).then_some(self.best.1)
    }
}

/// Why a graph could not be built or walked.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GraphError {
    /// `--control` names no control point.
    #[error("unknown control point {0:?} (expected joint1, joint2, joint3 or top)")]
    BadControl(String),
    /// A parameter is out of range.
    #[error("{what} must be {requirement}, found {value}")]
    Parameter {
        /// The parameter.
        what: &'static str,
        /// The value given.
        value: f64,
        /// The rule it breaks.
        requirement: &'static str,
    },
    /// Too few or too many samples.
    #[error("a motion graph needs between 8 and {MAX_GRAPH_SAMPLES} samples, the take has {0}")]
    SampleCount(usize),
    /// A position or an angle is not finite.
    #[error("sample {0} has a position or an angle that is not finite")]
    NotFinite(usize),
    /// No transition survived: the control point's path never passes near itself going forwards
    /// (a straight sweep, say), so every walk would dead-end.
    #[error(
        "no usable transition: the {control} never passes within one step of an earlier or later \
         sample going forwards with a similar pose ({found} candidate transitions, none left after \
         pruning); record a longer take that sways back and forth, or raise --max-pose-deg or \
         --radius-scale"
    )]
    NoTransition {
        /// The control point.
        control: String,
        /// Transitions found before pruning.
        found: u64,
    },
}
