//! Building the optimised motion graph: seed 003, sections 5.1 to 5.3.
//!
//! 1. Backbone: an edge from every sample to the next (5.1).
//! 2. Transitions (5.2.1, Fig. 4): for each sample `p_t` with a successor, the samples `s` within
//!    `d = radius_scale * |p(t+1) - p(t)|` that lie in front, `(s - p_t) . v_t > 0` with
//!    `v_t = p(t+1) - p(t)`. The neighbour search is an R-tree (`rstar`) that examines at most
//!    [`MAX_NEIGHBOURS`] samples within `d` (the tree's first, in its spatial order), so
//!    building stays near `O(n log n)` even for a long take whose path covers a small region
//!    ever more densely (where only a handful of transitions per sample are kept anyway).
//!    - Beyond the paper, a pose gate (applied after the thinning of step 3): the 12 joint
//!      angles of `s` and `p_t` must lie within
//!      `max_pose_deg` (Euclidean, degrees) of each other, since one point's distance can join
//!      poses that look different (the paper's own section 7 says so).
//!    - Samples within `2k + 1` frames of `t` are the backbone itself, not a transition.
//!    - Each transition is extended by `k` samples on each side: from `p(t-k)` to `s(j+k)`.
//!    - In-between frames: `max(2k, 1) - 1` (the frames the original path takes between the two
//!      ends, less one) plus one per median backbone pose step of the pose distance bridged, so
//!      their count grows with the distance (section 7, "adapting the length of each transition to
//!      the similarity of the states it bridges").
//! 3. Optimisations (5.3): of the neighbours on one contiguous segment only the latest is kept,
//!    and of those at most `max_transitions` per sample, the nearest in pose;
//!    dead ends are removed (nodes without an outgoing edge, repeated until nothing changes); then
//!    only the largest strongly connected part is kept, so a walk never stalls and never gets
//!    stuck in a corner.

use rstar::RTree;
use rstar::primitives::GeomWithData;

use super::{
    ControlPoint, Edge, EdgeKind, GraphError, MAX_EXTEND, MAX_GRAPH_SAMPLES, MAX_INBETWEENS, MotionGraph,
    Pruned, Rows,
};
use crate::sample::PoseFrame;

/// Fewest samples a graph is built from.
pub const MIN_GRAPH_SAMPLES: usize = 8;

/// Build parameters (`frond take graph` flags).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraphParams {
    /// The control point.
    pub control: ControlPoint,
    /// `k` of Fig. 4: how many samples a transition is extended by on each side (default 2).
    pub extend: u32,
    /// Largest distance of the 12 joint angles between the two ends of a crossing, degrees
    /// (Euclidean norm; default 10).
    pub max_pose_deg: f64,
    /// Scale of the search radius `d` (the paper's is 1).
    pub radius_scale: f64,
    /// Most transitions leaving one sample, the nearest in pose kept (default 3; section 5.3
    /// suggests "restricting the amount of transitions": with many, a random walk jumps at
    /// nearly every sample and shows mostly in-betweens).
    pub max_transitions: u32,
}

impl GraphParams {
    /// The defaults for a control point: `k = 2`, a 10 degree pose gate, the paper's radius.
    pub fn new(control: ControlPoint) -> Self {
        GraphParams { control, extend: 2, max_pose_deg: 10.0, radius_scale: 1.0, max_transitions: 3 }
    }

    /// Checks every value.
    pub fn check(&self) -> Result<(), GraphError> {
        if self.extend > MAX_EXTEND {
            return Err(GraphError::Parameter {
                what: "extend",
                value: self.extend as f64,
                requirement: "at most 64",
            });
        }
        if !(self.max_pose_deg.is_finite() && self.max_pose_deg > 0.0 && self.max_pose_deg <= 720.0) {
            return Err(GraphError::Parameter {
                what: "max_pose_deg",
                value: self.max_pose_deg,
                requirement: "above 0 and at most 720",
            });
        }
        if !(self.radius_scale.is_finite() && self.radius_scale > 0.0 && self.radius_scale <= 100.0) {
            return Err(GraphError::Parameter {
                what: "radius_scale",
                value: self.radius_scale,
                requirement: "above 0 and at most 100",
            });
        }
        if !(1..=MAX_TRANSITIONS_PER_NODE).contains(&self.max_transitions) {
            return Err(GraphError::Parameter {
                what: "max_transitions",
                value: self.max_transitions as f64,
                requirement: "1 to 32",
            });
        }
        Ok(())
    }
}

/// Most samples within the radius examined per sample.
pub const MAX_NEIGHBOURS: usize = 64;

/// Largest `max_transitions`.
pub const MAX_TRANSITIONS_PER_NODE: u32 = 32;

/// Euclidean distance of two poses' 12 joint angles, degrees.
pub fn pose_distance_deg(a: &PoseFrame, b: &PoseFrame) -> f64 {
    let (fa, fb) = (a.flat(), b.flat());
    fa.iter().zip(fb.iter()).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum::<f64>().sqrt()
}

/// Builds the optimised motion graph of a take's `poses` (at one frame rate) whose control point
/// is at `positions_m` in each frame (see the module doc).
pub fn build_graph(
    poses: &[PoseFrame],
    positions_m: &[[f64; 3]],
    params: &GraphParams,
) -> Result<MotionGraph, GraphError> {
    check_samples(poses, positions_m, params)?;
    let n = poses.len();
    let mut pruned = Pruned::default();
    let transitions = find_transitions(poses, positions_m, params, &mut pruned);
    // Adjacency over frames (the backbone implicit): transitions by source and by target.
    let succ = Rows::new(n, transitions.iter().map(|&(a, b, _)| (a as usize, b)));
    let preds = Rows::new(n, transitions.iter().map(|&(a, b, _)| (b as usize, a)));
    let alive = remove_dead_ends(n, &succ, &preds, &mut pruned);
    let keep = keep_largest_part(n, &alive, &succ, &mut pruned);
    connect(positions_m, &transitions, &keep, params, pruned)
}

/// The parameters are valid, the sample count is within bounds and matches the positions, and
/// every position and angle is finite.
fn check_samples(
    poses: &[PoseFrame],
    positions_m: &[[f64; 3]],
    params: &GraphParams,
) -> Result<(), GraphError> {
    params.check()?;
    let n = poses.len();
    if !(MIN_GRAPH_SAMPLES..=MAX_GRAPH_SAMPLES).contains(&n) || positions_m.len() != n {
        return Err(GraphError::SampleCount(n));
    }
    for (i, (p, f)) in positions_m.iter().zip(poses).enumerate() {
        if !p.iter().all(|x| x.is_finite()) || !f.flat().iter().all(|x| x.is_finite()) {
            return Err(GraphError::NotFinite(i));
        }
    }
    Ok(())
}

/// Section 5.3: the transitions `(from frame, to frame, in-betweens)` of every sample to its
/// neighbours ahead within the radius, one per contiguous run, through the pose gate, the
/// closest `max_transitions` of them; sorted, one per pair. Counts what it drops in `pruned`.
fn find_transitions(
    poses: &[PoseFrame],
    positions_m: &[[f64; 3]],
    params: &GraphParams,
    pruned: &mut Pruned,
) -> Vec<(u32, u32, u32)> {
    let n = poses.len();
    let k = params.extend as usize;
    let mut steps_deg: Vec<f64> = poses.windows(2).map(|w| pose_distance_deg(&w[0], &w[1])).collect();
    steps_deg.sort_by(f64::total_cmp);
    let median_step_deg = steps_deg[steps_deg.len() / 2];

    let tree = RTree::bulk_load(
        positions_m.iter().enumerate().map(|(i, p)| GeomWithData::new(*p, i as u32)).collect(),
    );
    // Transitions as (from frame, to frame, in-betweens).
    let mut transitions: Vec<(u32, u32, u32)> = Vec::new();
    let mut candidates: Vec<usize> = Vec::new();
    let mut kept: Vec<(f64, usize)> = Vec::new();
    // Queries in the tree's own (spatial) order, not the take's: neighbouring queries then walk
    // the same part of the tree, which keeps a large take's search in cache. Each sample's
    // transitions depend on that sample alone, and they are sorted afterwards.
    let order: Vec<usize> = tree.iter().map(|s| s.data as usize).collect();
    for &t in &order {
        if t + 1 == n {
            continue;
        }
        let p = positions_m[t];
        let v = sub(positions_m[t + 1], p);
        let d = params.radius_scale * dot(v, v).sqrt();
        if d == 0.0 {
            continue;
        }
        candidates.clear();
        // At most MAX_NEIGHBOURS of the samples within `d` (the R-tree's first, in its spatial
        // order): a long take over a small region has ever more samples within `d`, and
        // examining them all would make building quadratic.
        for s in tree.locate_within_distance(p, d * d).take(MAX_NEIGHBOURS) {
            let j = s.data as usize;
            if j.abs_diff(t) > 2 * k + 1 && dot(sub(*s.geom(), p), v) > 0.0 {
                candidates.push(j);
            }
        }
        pruned.transitions_found += candidates.len() as u64;
        candidates.sort_unstable();
        // 5.3: of each contiguous run of neighbours keep the latest; then the pose gate.
        kept.clear();
        for (idx, &j) in candidates.iter().enumerate() {
            if candidates.get(idx + 1) == Some(&(j + 1)) {
                pruned.transitions_same_segment += 1;
                continue;
            }
            let dist_deg = pose_distance_deg(&poses[t], &poses[j]);
            if dist_deg > params.max_pose_deg {
                pruned.transitions_pose_gate += 1;
            } else if t >= k && j + k < n {
                kept.push((dist_deg, j));
            }
        }
        kept.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let cap = params.max_transitions as usize;
        pruned.transitions_over_cap += kept.len().saturating_sub(cap) as u64;
        for &(dist_deg, j) in kept.iter().take(cap) {
            let extra = if median_step_deg > 0.0 { (dist_deg / median_step_deg).round() } else { 0.0 };
            let m = ((2 * k).max(1) as f64 - 1.0 + extra).min(MAX_INBETWEENS as f64) as u32;
            transitions.push(((t - k) as u32, (j + k) as u32, m));
        }
    }
    transitions.sort_unstable();
    transitions.dedup_by_key(|e| (e.0, e.1));
    transitions
}

/// Removes nodes with no way on, repeatedly (a frame whose only ways on lead to removed frames
/// is removed too): which frames are alive, the dead ones recorded in `pruned`.
fn remove_dead_ends(n: usize, succ: &Rows<u32>, preds: &Rows<u32>, pruned: &mut Pruned) -> Vec<bool> {
    let mut alive = vec![true; n];
    let mut out_degree: Vec<u32> = (0..n).map(|i| u32::from(i + 1 < n) + succ.row(i).len() as u32).collect();
    // Dead ends: remove nodes with no way on, repeatedly.
    let mut queue: Vec<usize> = (0..n).filter(|&i| out_degree[i] == 0).collect();
    let mut dead = Vec::new();
    while let Some(i) = queue.pop() {
        if !alive[i] {
            continue;
        }
        alive[i] = false;
        dead.push(i as u32);
        let mut drop_pred = |q: usize| {
            if alive[q] {
                out_degree[q] -= 1;
                if out_degree[q] == 0 {
                    queue.push(q);
                }
            }
        };
        if i > 0 {
            drop_pred(i - 1);
        }
        for &q in preds.row(i) {
            drop_pred(q as usize);
        }
    }
    dead.sort_unstable();
    pruned.dead_end_frames = ranges(&dead);
    alive
}

/// Which frames to keep: the alive ones in the largest strongly connected part (the rest
/// recorded in `pruned`).
fn keep_largest_part(n: usize, alive: &[bool], succ: &Rows<u32>, pruned: &mut Pruned) -> Vec<bool> {
    // The strongly connected parts of the survivors (Tarjan skips the dead): edge 0 is the
    // backbone where there is one, then the transitions.
    let component = largest_scc(n, alive, |i, e| {
        let transition = match (i + 1 < n, e) {
            (true, 0) => return Some(i + 1),
            (true, e) => e - 1,
            (false, e) => e,
        };
        succ.row(i).get(transition).map(|&s| s as usize)
    });
    let keep: Vec<bool> = (0..n).map(|i| alive[i] && component[i]).collect();
    let outside: Vec<u32> = (0..n).filter(|&i| alive[i] && !component[i]).map(|i| i as u32).collect();
    pruned.outside_largest_part_frames = ranges(&outside);
    keep
}

/// The graph of the kept frames: their backbone edges, then the transitions between them.
/// `Err` when fewer than two frames or no transition survived the pruning.
fn connect(
    positions_m: &[[f64; 3]],
    transitions: &[(u32, u32, u32)],
    keep: &[bool],
    params: &GraphParams,
    mut pruned: Pruned,
) -> Result<MotionGraph, GraphError> {
    let n = keep.len();
    let node_frames: Vec<u32> = (0..n).filter(|&i| keep[i]).map(|i| i as u32).collect();
    let kept_transitions =
        transitions.iter().filter(|&&(a, b, _)| keep[a as usize] && keep[b as usize]).count();
    pruned.transitions_removed = (transitions.len() - kept_transitions) as u64;
    if node_frames.len() < 2 || kept_transitions == 0 {
        return Err(GraphError::NoTransition {
            control: params.control.name(),
            found: pruned.transitions_found,
        });
    }
    let mut index = vec![u32::MAX; n];
    for (id, &f) in node_frames.iter().enumerate() {
        index[f as usize] = id as u32;
    }
    let mut edges = Vec::with_capacity(node_frames.len() + kept_transitions);
    for &f in &node_frames {
        let f = f as usize;
        if f + 1 < n && keep[f + 1] {
            edges.push(Edge { from: index[f], to: index[f + 1], kind: EdgeKind::Backbone, inbetweens: 0 });
        }
    }
    for &(a, b, m) in transitions {
        if keep[a as usize] && keep[b as usize] {
            edges.push(Edge {
                from: index[a as usize],
                to: index[b as usize],
                kind: EdgeKind::Transition,
                inbetweens: m,
            });
        }
    }
    let positions = node_frames.iter().map(|&f| positions_m[f as usize]).collect();
    Ok(MotionGraph::from_parts(node_frames, positions, edges, pruned))
}

/// Marks the nodes of the largest strongly connected part among the `alive` nodes; `edge(i, e)`
/// is node `i`'s `e`-th successor (`None` past the last). Iterative Tarjan, `O(V + E)`.
fn largest_scc(n: usize, alive: &[bool], edge: impl Fn(usize, usize) -> Option<usize>) -> Vec<bool> {
    const UNSEEN: u32 = u32::MAX;
    let mut order = vec![UNSEEN; n];
    let mut low = vec![0u32; n];
    let mut on_stack = vec![false; n];
    let mut stack: Vec<u32> = Vec::new();
    let mut call: Vec<(u32, u32)> = Vec::new();
    let mut counter = 0u32;
    let mut best: Vec<u32> = Vec::new();
    for root in 0..n {
        if !alive[root] || order[root] != UNSEEN {
            continue;
        }
        call.push((root as u32, 0));
        order[root] = counter;
        low[root] = counter;
        counter += 1;
        stack.push(root as u32);
        on_stack[root] = true;
        while let Some(&mut (v, ref mut e)) = call.last_mut() {
            let v = v as usize;
            if let Some(w) = edge(v, *e as usize) {
                *e += 1;
                if !alive[w] {
                    continue;
                }
                if order[w] == UNSEEN {
                    order[w] = counter;
                    low[w] = counter;
                    counter += 1;
                    stack.push(w as u32);
                    on_stack[w] = true;
                    call.push((w as u32, 0));
                } else if on_stack[w] {
                    low[v] = low[v].min(order[w]);
                }
                continue;
            }
            call.pop();
            if let Some(&(parent, _)) = call.last() {
                let p = parent as usize;
                low[p] = low[p].min(low[v]);
            }
            if low[v] == order[v] {
                let mut part = Vec::new();
                while let Some(w) = stack.pop() {
                    on_stack[w as usize] = false;
                    part.push(w);
                    if w as usize == v {
                        break;
                    }
                }
                if part.len() > best.len() {
                    best = part;
                }
            }
        }
    }
    let mut mark = vec![false; n];
    for w in best {
        mark[w as usize] = true;
    }
    mark
}

/// Sorted indices as inclusive `[first, last]` ranges.
fn ranges(sorted: &[u32]) -> Vec<[u32; 2]> {
    let mut out: Vec<[u32; 2]> = Vec::new();
    for &i in sorted {
        match out.last_mut() {
            Some(r) if r[1] + 1 == i => r[1] = i,
            _ => out.push([i, i]),
        }
    }
    out
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
