//! The motion graph file (`NAME.graph.json`) round-trips, refuses damage with the path of the
//! problem, and a damaged file that still passes its checks walks without a panic.

use frond_formats::graph_file::{GraphFile, GraphFileError};
use frond_motion::graph::walk::PosePlan;
use frond_motion::graph::{
    ControlPoint, Goal, GraphParams, Walker, build_graph, control_positions_m, sample_sway,
};
use frond_motion::sample::PoseFrame;
use frond_motion::skeleton::Skeleton;

const FPS: f64 = 30.0;

fn positions(poses: &[PoseFrame]) -> Vec<[f64; 3]> {
    control_positions_m(ControlPoint::Top, &Skeleton::even(1.0), 1.0, poses)
}

#[test]
fn the_graph_file_round_trips_and_refuses_damage() {
    let poses = sample_sway(1200);
    let params = GraphParams::new(ControlPoint::Top);
    let g = build_graph(&poses, &positions(&poses), &params).unwrap();
    let file = GraphFile::new(&g, &params, "sway", FPS, &poses);
    let text = file.to_json();
    let back = GraphFile::from_json(&text).unwrap();
    assert_eq!(back.graph_for(&poses).unwrap(), g);
    let mut other = poses.clone();
    other[3].joints_deg[1][1] += 0.5;
    assert!(matches!(back.graph_for(&other), Err(GraphFileError::OtherTake { .. })));
    let damaged = text.replacen("\"to\": 1,", "\"to\": 999999,", 1);
    let err = GraphFile::from_json(&damaged).unwrap_err();
    assert!(err.to_string().contains("edges[0]"), "{err}");
    assert!(GraphFile::from_json("{}").is_err());
    assert!(GraphFile::from_json(&text.replacen("\"version\": 1", "\"version\": 9", 1)).is_err());
}

mod damaged_files {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        /// A graph file with bytes changed is refused or, if it still passes the checks, walks
        /// without a panic: every index the walker uses was validated.
        #[test]
        fn damaged_graph_files_never_panic(edits in proptest::collection::vec((any::<usize>(), 0u8..128), 1..8)) {
            let poses = sample_sway(300);
            let params = GraphParams::new(ControlPoint::Top);
            let g = build_graph(&poses, &positions(&poses), &params).unwrap();
            let mut bytes = GraphFile::new(&g, &params, "sway", FPS, &poses).to_json().into_bytes();
            for (at, b) in edits {
                let i = at % bytes.len();
                bytes[i] = b;
            }
            let Ok(text) = String::from_utf8(bytes) else { return Ok(()) };
            if let Ok(file) = GraphFile::from_json(&text)
                && let Ok(graph) = file.graph_for(&poses)
            {
                let mut w = Walker::new(&graph, 0, 1, FPS);
                w.set_goal(Goal::Direction { dir_deg: 30.0 });
                for _ in 0..500 {
                    w.next_frame(&graph, &poses);
                }
                let plan = PosePlan::new(&graph, (graph.len() - 1) as u32);
                w.set_goal(Goal::Pose(plan));
                for _ in 0..500 {
                    w.next_frame(&graph, &poses);
                }
            }
        }
    }
}
