//! Fuzzes the motion graph file `NAME.graph.json`: `frond_formats::graph_file::GraphFile::from_json`,
//! the reader behind `frond take walk` and the daemon's graph stage. An accepted file reads back
//! from its own `to_json`, and its graph, when it matches the take, walks without a panic: every
//! index the walker uses was checked on reading.

use frond_formats::graph_file::{GraphFile, GraphFileError};
use frond_fuzz::{Target, as_text, assert_message, fuzz};
use frond_motion::graph::{
    ControlPoint, Goal, GraphParams, Walker, build_graph, control_positions_m, sample_sway,
};
use frond_motion::sample::PoseFrame;
use frond_motion::skeleton::Skeleton;

const FPS: f64 = 30.0;

/// The graph file of a sway of `frames` frames, and those frames.
fn seed(frames: usize, control: ControlPoint) -> (String, Vec<PoseFrame>) {
    let poses = sample_sway(frames);
    let positions = control_positions_m(control, &Skeleton::even(1.0), 1.0, &poses);
    let params = GraphParams::new(control);
    let graph = build_graph(&poses, &positions, &params).expect("seed graph");
    (GraphFile::new(&graph, &params, "sway", FPS, &poses).to_json(), poses)
}

#[test]
fn fuzz_graph_files() {
    let (a, poses) = seed(60, ControlPoint::Top);
    let (b, _) = seed(60, ControlPoint::Joint(2));
    let seeds = [a, b];
    for s in &seeds {
        GraphFile::from_json(s).expect("seed graph files read back");
    }
    let dict = [
        "\"version\"",
        "\"take\"",
        "\"fps\"",
        "\"take_frames\"",
        "\"take_digest\"",
        "\"control\"",
        "\"params\"",
        "\"nodes\"",
        "\"edges\"",
        "\"pruned\"",
        "\"from\"",
        "\"to\"",
        "\"kind\"",
        "\"backbone\"",
        "\"transition\"",
        "\"inbetweens\"",
        "\"frame\"",
        "\"position_m\"",
        "{ \"from\": 7, \"to\": 3, \"kind\": \"transition\", \"inbetweens\": 5 }",
    ];
    let report =
        fuzz(Target::new("graph-file").seeds(&seeds).text().dict(dict).max_len(16 * 1024), move |b| {
            match GraphFile::from_json(&as_text(b)) {
                Ok(file) => {
                    let again =
                        GraphFile::from_json(&file.to_json()).expect("a graph file's own JSON reads back");
                    assert_eq!(again, file);
                    match file.graph_for(&poses) {
                        Ok(graph) => {
                            let mut w = Walker::new(&graph, 0, 1, FPS);
                            w.set_goal(Goal::Direction { dir_deg: 30.0 });
                            for _ in 0..200 {
                                w.next_frame(&graph, &poses);
                            }
                            "walked"
                        }
                        Err(e) => {
                            assert_message(&e);
                            "other take"
                        }
                    }
                }
                Err(e @ (GraphFileError::Syntax(_) | GraphFileError::Invalid { .. })) => {
                    assert_message(&e);
                    "refused"
                }
                Err(e @ GraphFileError::OtherTake { .. }) => {
                    panic!("reading alone never compares takes: {e}")
                }
            }
        });
    report.assert_reaches("walked", 5);
    report.assert_reaches("refused", 100);
}

#[test]
fn graph_file_seeds_fit_the_fuzzer() {
    for control in [ControlPoint::Top, ControlPoint::Joint(2)] {
        let (text, _) = seed(60, control);
        assert!(text.len() < 16 * 1024, "seed of {} bytes", text.len());
    }
}
