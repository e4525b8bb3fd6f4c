//! Walks on a motion graph allocate nothing per frame (seed 003, section 6, as a realtime stage
//! of many plants will use them): random, goal-directed and pose-goal walkers, in-betweens
//! included. Everything is built before the walk.

use frond_motion::graph::walk::PosePlan;
use frond_motion::graph::{
    ControlPoint, EdgeKind, Goal, GraphParams, Walker, build_graph, control_positions_m, sample_sway,
};
use frond_motion::skeleton::Skeleton;

use crate::common;

#[test]
fn walkers_do_not_allocate_per_frame() {
    let poses = sample_sway(1200);
    let path = control_positions_m(ControlPoint::Top, &Skeleton::even(1.0), 1.0, &poses);
    let graph = build_graph(&poses, &path, &GraphParams::new(ControlPoint::Top)).unwrap();
    let plan = PosePlan::new(&graph, (graph.len() / 3) as u32);
    let mut walkers: Vec<Walker> = (0..64).map(|i| Walker::new(&graph, i * 7, i as u64, 30.0)).collect();
    for (i, w) in walkers.iter_mut().enumerate() {
        w.set_goal(match i % 3 {
            0 => Goal::Random,
            1 => Goal::Direction { dir_deg: 45.0 * i as f64 },
            _ => Goal::Pose(plan.clone()),
        });
    }
    let ((transitions, inbetweens), allocations) = common::allocations_in(|| {
        let (mut transitions, mut inbetweens) = (0u64, 0u64);
        for _ in 0..2000 {
            for w in &mut walkers {
                let s = w.next_frame(&graph, &poses);
                transitions += u64::from(s.chose.is_some_and(|e| e.kind == EdgeKind::Transition));
                inbetweens += u64::from(s.node.is_none());
            }
        }
        (transitions, inbetweens)
    });
    assert_eq!(allocations, 0, "allocations during 2000 frames of 64 walkers");
    assert!(transitions > 1000 && inbetweens > 1000, "{transitions} transitions, {inbetweens} in-betweens");
}
