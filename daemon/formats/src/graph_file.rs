//! The motion graph file, `NAME.graph.json` (written by `frond take graph`, read by
//! `frond take walk` and `frond graph play`).
//!
//! ```json
//! {
//!   "version": 1,
//!   "take": "breeze",            // the take the graph was built on
//!   "fps": 30.0,                 // the rate its frames were taken at
//!   "take_frames": 900,          // frames of the take at that rate
//!   "take_digest": "9f3c...",    // FNV-1a 64 of the joint angles: a walk refuses another take
//!   "control": "top",            // joint1 | joint2 | joint3 | top
//!   "params": { "extend": 2, "max_pose_deg": 10.0, "radius_scale": 1.0, "max_transitions": 3 },
//!   "nodes": [ { "id": 0, "frame": 14, "position_m": [0.01, 0.79, 0.0] } ],
//!   "edges": [ { "from": 0, "to": 1, "kind": "backbone", "inbetweens": 0 },
//!              { "from": 7, "to": 310, "kind": "transition", "inbetweens": 5 } ],
//!   "pruned": { "transitions_found": 812, "transitions_same_segment": 240,
//!               "transitions_pose_gate": 35, "transitions_over_cap": 120,
//!               "dead_end_frames": [[880, 899]], "outside_largest_part_frames": [[0, 13]],
//!               "transitions_removed": 31 }
//! }
//! ```
//!
//! Node ids are `0..nodes.len()` in order, frames strictly increasing below `take_frames`; a
//! backbone edge joins consecutive frames; every node has an outgoing edge. Everything is checked
//! on reading, with the path of the first problem.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use frond_motion::graph::GraphParams;
use frond_motion::graph::{
    ControlPoint, Edge, EdgeKind, MAX_EXTEND, MAX_GRAPH_SAMPLES, MAX_INBETWEENS, MotionGraph, Pruned,
};
use frond_motion::sample::PoseFrame;

/// The format version this build writes and reads.
pub const GRAPH_FILE_VERSION: u32 = 1;
/// Largest graph file read, bytes.
pub const MAX_GRAPH_FILE_BYTES: u64 = 512 << 20;

/// Build parameters as stored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoredParams {
    /// `k` of Fig. 4.
    pub extend: u32,
    /// The pose gate, degrees.
    pub max_pose_deg: f64,
    /// The search radius' scale.
    pub radius_scale: f64,
    /// Most transitions per sample.
    pub max_transitions: u32,
}

/// One node as stored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoredNode {
    /// Its index.
    pub id: u32,
    /// Its take frame.
    pub frame: u32,
    /// The control point's position, metres.
    pub position_m: [f64; 3],
}

/// One edge as stored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoredEdge {
    /// Source node id.
    pub from: u32,
    /// Target node id.
    pub to: u32,
    /// `backbone` or `transition`.
    pub kind: EdgeKind,
    /// In-between frames.
    pub inbetweens: u32,
}

/// The whole file (see the module doc).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphFile {
    /// [`GRAPH_FILE_VERSION`].
    pub version: u32,
    /// The take's name.
    pub take: String,
    /// Frame rate of the take's frames.
    pub fps: f64,
    /// Frames of the take at `fps`.
    pub take_frames: u32,
    /// [`take_digest`] of those frames.
    pub take_digest: String,
    /// The control point.
    pub control: String,
    /// How it was built.
    pub params: StoredParams,
    /// Nodes.
    pub nodes: Vec<StoredNode>,
    /// Edges.
    pub edges: Vec<StoredEdge>,
    /// What pruning removed.
    pub pruned: Pruned,
}

/// Why a graph file was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GraphFileError {
    /// Not JSON of this shape.
    #[error("not a motion graph file: {0}")]
    Syntax(String),
    /// A value is out of range or inconsistent.
    #[error("{path}: {problem}")]
    Invalid {
        /// Where.
        path: String,
        /// What.
        problem: String,
    },
    /// The graph was built on other frames than the take given.
    #[error(
        "the graph was built on take {take:?} ({frames} frames at {fps} fps, digest {digest}); the \
         take given has {given_frames} frames at that rate, digest {given_digest}: rebuild it with \
         frond take graph"
    )]
    OtherTake {
        /// The take it names.
        take: String,
        /// Its frames.
        frames: u32,
        /// Its rate.
        fps: f64,
        /// Its digest.
        digest: String,
        /// Frames of the take given.
        given_frames: usize,
        /// Digest of the take given.
        given_digest: String,
    },
}

/// FNV-1a 64 of the joint angles of `poses` (little-endian f32 bits), as 16 hex digits.
pub fn take_digest(poses: &[PoseFrame]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in poses {
        for x in p.flat() {
            for b in x.to_bits().to_le_bytes() {
                h ^= b as u64;
                h = h.wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    format!("{h:016x}")
}

impl GraphFile {
    /// The file for `graph`, built with `params` on `poses` of take `take` at `fps`.
    pub fn new(graph: &MotionGraph, params: &GraphParams, take: &str, fps: f64, poses: &[PoseFrame]) -> Self {
        GraphFile {
            version: GRAPH_FILE_VERSION,
            take: take.to_string(),
            fps,
            take_frames: poses.len() as u32,
            take_digest: take_digest(poses),
            control: params.control.name(),
            params: StoredParams {
                extend: params.extend,
                max_pose_deg: params.max_pose_deg,
                radius_scale: params.radius_scale,
                max_transitions: params.max_transitions,
            },
            nodes: graph
                .node_frames
                .iter()
                .zip(&graph.node_positions_m)
                .enumerate()
                .map(|(id, (&frame, &position_m))| StoredNode { id: id as u32, frame, position_m })
                .collect(),
            edges: graph
                .edges
                .iter()
                .map(|e| StoredEdge { from: e.from, to: e.to, kind: e.kind, inbetweens: e.inbetweens })
                .collect(),
            pruned: graph.pruned.clone(),
        }
    }

    /// Parses and checks a file's text.
    pub fn from_json(text: &str) -> Result<Self, GraphFileError> {
        let f: GraphFile = serde_json::from_str(text).map_err(|e| GraphFileError::Syntax(e.to_string()))?;
        f.check()?;
        Ok(f)
    }

    /// The file as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a graph file serialises")
    }

    /// The control point.
    pub fn control_point(&self) -> Result<ControlPoint, GraphFileError> {
        self.control.parse().map_err(|e: frond_motion::graph::GraphError| invalid("control", e.to_string()))
    }

    fn check(&self) -> Result<(), GraphFileError> {
        if self.version != GRAPH_FILE_VERSION {
            return Err(invalid(
                "version",
                format!("version {} is not supported (this frond reads {GRAPH_FILE_VERSION})", self.version),
            ));
        }
        if !(self.fps.is_finite() && self.fps > 0.0 && self.fps <= 1000.0) {
            return Err(invalid("fps", format!("must be in (0, 1000], found {}", self.fps)));
        }
        if self.take_frames as usize > MAX_GRAPH_SAMPLES {
            return Err(invalid(
                "take_frames",
                format!("at most {MAX_GRAPH_SAMPLES}, found {}", self.take_frames),
            ));
        }
        self.control_point()?;
        if self.params.extend > MAX_EXTEND {
            return Err(invalid(
                "params.extend",
                format!("at most {MAX_EXTEND}, found {}", self.params.extend),
            ));
        }
        let n = self.nodes.len();
        if n < 2 || n > self.take_frames as usize {
            return Err(invalid(
                "nodes",
                format!("2 to take_frames ({}) nodes, found {n}", self.take_frames),
            ));
        }
        for (i, node) in self.nodes.iter().enumerate() {
            let path = || format!("nodes[{i}]");
            if node.id as usize != i {
                return Err(invalid(&path(), format!("id must be {i}, found {}", node.id)));
            }
            if node.frame >= self.take_frames {
                return Err(invalid(
                    &path(),
                    format!("frame {} is past the take's {} frames", node.frame, self.take_frames),
                ));
            }
            if i > 0 && node.frame <= self.nodes[i - 1].frame {
                return Err(invalid(&path(), "frames must be strictly increasing".into()));
            }
            if !node.position_m.iter().all(|x| x.is_finite()) {
                return Err(invalid(&path(), "position_m is not finite".into()));
            }
        }
        if self.edges.len() > 64 * n {
            return Err(invalid("edges", format!("at most 64 per node, found {}", self.edges.len())));
        }
        let mut has_out = vec![false; n];
        for (i, e) in self.edges.iter().enumerate() {
            let path = || format!("edges[{i}]");
            if e.from as usize >= n || e.to as usize >= n {
                return Err(invalid(
                    &path(),
                    format!("node {} or {} does not exist ({n} nodes)", e.from, e.to),
                ));
            }
            let (fa, fb) = (self.nodes[e.from as usize].frame, self.nodes[e.to as usize].frame);
            match e.kind {
                EdgeKind::Backbone if fb != fa + 1 || e.inbetweens != 0 => {
                    return Err(invalid(
                        &path(),
                        "a backbone edge joins consecutive frames with no in-betweens".into(),
                    ));
                }
                EdgeKind::Transition if e.inbetweens > MAX_INBETWEENS => {
                    return Err(invalid(
                        &path(),
                        format!("at most {MAX_INBETWEENS} in-betweens, found {}", e.inbetweens),
                    ));
                }
                _ => {}
            }
            has_out[e.from as usize] = true;
        }
        if let Some(i) = has_out.iter().position(|h| !h) {
            return Err(invalid(&format!("nodes[{i}]"), "has no outgoing edge (a walk would stall)".into()));
        }
        Ok(())
    }

    /// The graph, after checking that `poses` are the frames it was built on.
    pub fn graph_for(&self, poses: &[PoseFrame]) -> Result<MotionGraph, GraphFileError> {
        let digest = take_digest(poses);
        if poses.len() != self.take_frames as usize || digest != self.take_digest {
            return Err(GraphFileError::OtherTake {
                take: self.take.clone(),
                frames: self.take_frames,
                fps: self.fps,
                digest: self.take_digest.clone(),
                given_frames: poses.len(),
                given_digest: digest,
            });
        }
        Ok(MotionGraph::from_parts(
            self.nodes.iter().map(|n| n.frame).collect(),
            self.nodes.iter().map(|n| n.position_m).collect(),
            self.edges
                .iter()
                .map(|e| Edge { from: e.from, to: e.to, kind: e.kind, inbetweens: e.inbetweens })
                .collect(),
            self.pruned.clone(),
        ))
    }
}

fn invalid(path: &str, problem: String) -> GraphFileError {
    GraphFileError::Invalid { path: path.to_string(), problem }
}
