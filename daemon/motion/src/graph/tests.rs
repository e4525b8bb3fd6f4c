//! Motion graph and walk invariants (seed 003, sections 5 and 6), on motions whose geometry is
//! known: the Lissajous [`sample_sway`] that crosses itself often, a straight sweep that never does.

use super::build::{GraphParams, build_graph, pose_distance_deg};
use super::walk::{Goal, PosePlan, Walker};
use super::*;
use crate::sample::{JOINTS, PoseFrame};
use crate::skeleton::Skeleton;

const FPS: f64 = 30.0;

fn skeleton() -> Skeleton {
    Skeleton::even(1.0)
}

fn positions(poses: &[PoseFrame]) -> Vec<[f64; 3]> {
    control_positions_m(ControlPoint::Top, &skeleton(), 1.0, poses)
}

fn graph_of(poses: &[PoseFrame]) -> MotionGraph {
    build_graph(poses, &positions(poses), &GraphParams::new(ControlPoint::Top)).expect("graph")
}

fn reach(graph: &MotionGraph, from: u32, reverse: bool) -> Vec<bool> {
    let mut seen = vec![false; graph.len()];
    let mut stack = vec![from];
    seen[from as usize] = true;
    while let Some(v) = stack.pop() {
        for e in &graph.edges {
            let (a, b) = if reverse { (e.to, e.from) } else { (e.from, e.to) };
            if a == v && !seen[b as usize] {
                seen[b as usize] = true;
                stack.push(b);
            }
        }
    }
    seen
}

#[test]
fn the_graph_is_closed_and_strongly_connected() {
    let poses = sample_sway(1200);
    let g = graph_of(&poses);
    assert!(g.transitions() >= 10, "only {} transitions", g.transitions());
    for i in 0..g.len() as u32 {
        assert!(!g.out_edges(i).is_empty(), "node {i} dead-ends");
        let t = g.out_edges(i).iter().filter(|e| e.kind == EdgeKind::Transition).count();
        assert!(t <= 3, "node {i} has {t} transitions, the default cap is 3");
    }
    assert!(g.pruned.transitions_over_cap > 0, "the sample sway crosses itself more than 3 times");
    assert!(reach(&g, 0, false).iter().all(|&r| r), "not every node is reachable from node 0");
    assert!(reach(&g, 0, true).iter().all(|&r| r), "node 0 is not reachable from every node");
}

#[test]
fn transitions_lie_within_the_radius_and_in_front() {
    let poses = sample_sway(1200);
    let p = positions(&poses);
    let g = graph_of(&poses);
    let k = 2;
    for e in g.edges.iter().filter(|e| e.kind == EdgeKind::Transition) {
        // Fig. 4: the crossing is at p(t) -> s(j) with t = from + k, j = to - k.
        let t = g.node_frames[e.from as usize] as usize + k;
        let j = g.node_frames[e.to as usize] as usize - k;
        let v: Vec<f64> = (0..3).map(|c| p[t + 1][c] - p[t][c]).collect();
        let s: Vec<f64> = (0..3).map(|c| p[j][c] - p[t][c]).collect();
        let d = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let dist = s.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(dist <= d + 1e-12, "transition {e:?}: {dist} m away, radius {d} m");
        assert!(s.iter().zip(&v).map(|(a, b)| a * b).sum::<f64>() > 0.0, "transition {e:?} is not in front");
        assert!(pose_distance_deg(&poses[t], &poses[j]) <= 10.0);
        assert!(t.abs_diff(j) > 2 * k + 1, "transition {e:?} is the backbone itself");
    }
}

#[test]
fn one_transition_per_contiguous_segment_the_latest() {
    let poses = sample_sway(1200);
    let g = graph_of(&poses);
    for i in 0..g.len() as u32 {
        let targets: Vec<u32> = g
            .out_edges(i)
            .iter()
            .filter(|e| e.kind == EdgeKind::Transition)
            .map(|e| g.node_frames[e.to as usize])
            .collect();
        for w in targets.windows(2) {
            assert!(w[1] > w[0] + 1, "node {i} has transitions to consecutive frames {w:?}");
        }
    }
    assert!(g.pruned.transitions_same_segment > 0, "the sample sway has runs of neighbours");
}

#[test]
fn a_straight_sweep_is_refused() {
    let poses: Vec<PoseFrame> = (0..300)
        .map(|i| {
            let mut joints_deg = [[0.0f32; 3]; JOINTS];
            joints_deg[0][0] = -30.0 + 0.2 * i as f32;
            PoseFrame { t: i as f64 / FPS, joints_deg }
        })
        .collect();
    let err = build_graph(&poses, &positions(&poses), &GraphParams::new(ControlPoint::Top)).unwrap_err();
    assert!(matches!(err, GraphError::NoTransition { .. }), "{err}");
    assert!(err.to_string().contains("no usable transition"));
}

#[test]
fn a_tail_that_leaves_for_good_is_pruned_as_a_dead_end() {
    // The sway, then a slow straight drift away from everything before.
    let mut poses = sample_sway(900);
    let last = *poses.last().unwrap();
    for i in 0..60 {
        let mut p = last;
        p.t += (i + 1) as f64 / FPS;
        p.joints_deg[0][0] += 1.0 * (i + 1) as f32;
        poses.push(p);
    }
    let g = graph_of(&poses);
    let last_node = *g.node_frames.last().unwrap();
    // Past 30 frames of drift joint 0 is pitched beyond anything the sway reached (15 degrees).
    assert!(last_node < 930, "the drift (frames 900..960) must be pruned, last node {last_node}");
    let dead = &g.pruned.dead_end_frames;
    assert!(dead.last().is_some_and(|r| r[0] <= 930 && r[1] == 959), "{dead:?}");
}

#[test]
fn bad_parameters_and_sizes_are_refused() {
    let poses = sample_sway(100);
    let p = positions(&poses);
    let mut params = GraphParams::new(ControlPoint::Top);
    params.extend = 65;
    assert!(matches!(build_graph(&poses, &p, &params), Err(GraphError::Parameter { what: "extend", .. })));
    params = GraphParams::new(ControlPoint::Top);
    params.max_pose_deg = f64::NAN;
    assert!(build_graph(&poses, &p, &params).is_err());
    params = GraphParams::new(ControlPoint::Top);
    assert!(matches!(build_graph(&poses[..5], &p[..5], &params), Err(GraphError::SampleCount(5))));
    let mut bad = poses.clone();
    bad[7].joints_deg[2][1] = f32::INFINITY;
    assert!(matches!(build_graph(&bad, &p, &params), Err(GraphError::NotFinite(7))));
    assert!("hand".parse::<ControlPoint>().is_err());
}

#[test]
fn the_control_point_follows_forward_kinematics() {
    // Joint 0 pitched 90 degrees about +X: the straight plant lies along +Z (R_x(90) takes +Y to
    // +Z), so the top of a 1 m plant is at (0, 0, 1) and joint 2 at (0, 0, 0.5).
    let mut pose = PoseFrame { t: 0.0, joints_deg: [[0.0; 3]; JOINTS] };
    pose.joints_deg[0][0] = 90.0;
    let s = skeleton();
    let top = ControlPoint::Top.position_m(&s, 1.0, &pose);
    assert!((top - glam::Vec3::new(0.0, 0.0, 1.0)).length() < 1e-6, "{top}");
    let j2 = ControlPoint::Joint(2).position_m(&s, 1.0, &pose);
    assert!((j2 - glam::Vec3::new(0.0, 0.0, 0.5)).length() < 1e-6, "{j2}");
}

#[test]
fn random_walks_never_stall_and_are_deterministic() {
    let poses = sample_sway(1200);
    let g = graph_of(&poses);
    let run = |seed| {
        let mut w = Walker::new(&g, 0, seed, FPS);
        (0..20_000).map(|_| w.next_frame(&g, &poses)).collect::<Vec<_>>()
    };
    let a = run(7);
    assert_eq!(a, run(7), "same seed, same walk");
    assert_ne!(a, run(8), "another seed, another walk");
    assert!(a.iter().filter(|s| s.chose.is_some_and(|e| e.kind == EdgeKind::Transition)).count() > 50);
    for (i, s) in a.iter().enumerate() {
        assert!((s.pose.t - i as f64 / FPS).abs() < 1e-9);
    }
}

/// Largest second difference of any angle over a run of poses, degrees per frame squared.
fn max_accel(poses: &[PoseFrame]) -> f64 {
    poses
        .windows(3)
        .map(|w| {
            let (a, b, c) = (w[0].flat(), w[1].flat(), w[2].flat());
            (0..3 * JOINTS).map(|i| (a[i] as f64 - 2.0 * b[i] as f64 + c[i] as f64).abs()).fold(0.0, f64::max)
        })
        .fold(0.0, f64::max)
}

#[test]
fn inbetweens_have_no_kink_at_either_end() {
    let poses = sample_sway(1200);
    let g = graph_of(&poses);
    let mut w = Walker::new(&g, 0, 3, FPS);
    let walk: Vec<PoseFrame> = (0..20_000).map(|_| w.next_frame(&g, &poses).pose).collect();
    // A Hermite bridge of a gap of D degrees over m + 1 frames accelerates by at most about
    // 6 D / (m + 1)^2 on top of the take's own acceleration; a kink (a velocity jump of the
    // take's speed, 15 * 2 pi / 29.7 ~ 3.2 degrees per frame) would be far above that.
    let own = max_accel(&poses);
    let bridge = g
        .edges
        .iter()
        .filter(|e| e.kind == EdgeKind::Transition)
        .map(|e| {
            let d = pose_distance_deg(
                &poses[g.node_frames[e.from as usize] as usize],
                &poses[g.node_frames[e.to as usize] as usize],
            );
            6.0 * d / ((e.inbetweens + 1) as f64).powi(2)
        })
        .fold(0.0, f64::max);
    let walk_accel = max_accel(&walk);
    assert!(walk_accel <= 2.0 * own + bridge + 1e-3, "walk {walk_accel}, take {own}, bridge {bridge}");
    // And the bound is not trivially loose: a plain cut (no in-betweens) jumps much more.
    let cut_edge = g.edges.iter().find(|e| e.kind == EdgeKind::Transition).unwrap();
    let a = g.node_frames[cut_edge.from as usize] as usize;
    let b = g.node_frames[cut_edge.to as usize] as usize;
    let cut = [poses[a - 1], poses[a], poses[b], poses[b + 1]];
    assert!(max_accel(&cut) > walk_accel, "a cut {} vs the walk {walk_accel}", max_accel(&cut));
}

#[test]
fn the_number_of_inbetweens_grows_with_the_distance_bridged() {
    let poses = sample_sway(2400);
    let g = graph_of(&poses);
    let mut pairs: Vec<(f64, u32)> = g
        .edges
        .iter()
        .filter(|e| e.kind == EdgeKind::Transition)
        .map(|e| {
            let t = g.node_frames[e.from as usize] as usize + 2;
            let j = g.node_frames[e.to as usize] as usize - 2;
            (pose_distance_deg(&poses[t], &poses[j]), e.inbetweens)
        })
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    for w in pairs.windows(2) {
        assert!(w[1].1 >= w[0].1, "more distance, fewer in-betweens: {w:?}");
    }
    assert!(pairs[0].1 >= 3, "k = 2 gives at least 2k - 1 in-betweens");
    assert!(pairs.last().unwrap().1 > pairs[0].1);
}

fn fraction_towards(walk: &[PoseFrame], dir_deg: f64) -> f64 {
    let (gx, gz) = (dir_deg.to_radians().cos(), dir_deg.to_radians().sin());
    let p = positions(walk);
    p.iter().filter(|q| q[0] * gx + q[2] * gz > 0.0).count() as f64 / p.len() as f64
}

#[test]
fn goal_directed_walks_spend_clearly_more_time_towards_the_goal() {
    let poses = sample_sway(2400);
    let g = graph_of(&poses);
    for dir_deg in [0.0, 90.0, 225.0] {
        let mut random = Walker::new(&g, 0, 11, FPS);
        let mut goal = Walker::new(&g, 0, 11, FPS);
        goal.set_goal(Goal::Direction { dir_deg });
        let r: Vec<PoseFrame> = (0..30_000).map(|_| random.next_frame(&g, &poses).pose).collect();
        let d: Vec<PoseFrame> = (0..30_000).map(|_| goal.next_frame(&g, &poses).pose).collect();
        let (fr, fd) = (fraction_towards(&r, dir_deg), fraction_towards(&d, dir_deg));
        assert!(fd > fr + 0.15, "towards {dir_deg} deg: goal-directed {fd:.2}, random {fr:.2}");
    }
}

#[test]
fn a_pose_goal_is_reached_by_the_shortest_path_and_revisited() {
    let poses = sample_sway(1200);
    let g = graph_of(&poses);
    let target = (g.len() / 2) as u32;
    let plan = PosePlan::new(&g, target);
    assert!(plan.frames_to_target.iter().all(|&d| d != u32::MAX));
    let mut w = Walker::new(&g, 0, 1, FPS);
    w.set_goal(Goal::Pose(plan.clone()));
    let expected = plan.frames_to_target[0] as usize;
    let steps: Vec<_> = (0..expected + 1).map(|_| w.next_frame(&g, &poses)).collect();
    assert_eq!(steps[expected].node, Some(target), "the goal is reached after exactly the planned frames");
    assert!(steps[..expected].iter().all(|s| s.node != Some(target)));
    // It keeps coming back.
    let later: Vec<_> = (0..5000).map(|_| w.next_frame(&g, &poses)).collect();
    assert!(later.iter().filter(|s| s.node == Some(target)).count() >= 2);
}
