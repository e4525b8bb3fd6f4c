//! Seed 003 in `frond bench` (part of section 6): the simulated plant's step, motion graph builds
//! at 2k, 10k and 100k samples (with their growth against `n log n`), and walkers per plant per
//! tick, 64 plants against the 1 kHz tick. Every time beside a baseline measured in this run.

use std::hint::black_box;

use frond_motion::graph::{ControlPoint, GraphParams, MotionGraph, Walker, build_graph, control_positions_m};
use frond_motion::rig::Rig;
use frond_motion::sample::{JOINTS, PoseFrame};
use frond_motion::sim::{PlantSim, WindSpec};
use frond_motion::skeleton::Skeleton;
use frondd::clock::monotonic_ns;
use serde_json::{Value, json};

use crate::Options;
use crate::report::{Bound, Measurement, Section, Status};
use crate::tick::median;

type Part = Result<Section, (Status, String)>;

/// A long sway whose top path crosses itself often (three incommensurate periods), `n` frames.
fn sway(n: usize) -> Vec<PoseFrame> {
    (0..n)
        .map(|i| {
            let t = i as f64 / 30.0;
            let pitch = 12.0 * (t * 1.31).sin() + 3.0 * (t * 0.23).sin();
            let yaw = 12.0 * (t * 0.97 + 0.4).sin() + 3.0 * (t * 0.31).cos();
            let mut joints_deg = [[0.0f32; 3]; JOINTS];
            for (j, a) in joints_deg.iter_mut().enumerate() {
                let s = 1.0 / (j + 1) as f64;
                *a = [(pitch * s) as f32, (yaw * s) as f32, 0.0];
            }
            PoseFrame { t, joints_deg }
        })
        .collect()
}

fn positions(poses: &[PoseFrame]) -> Vec<[f64; 3]> {
    control_positions_m(ControlPoint::Top, &Skeleton::even(1.0), 1.0, poses)
}

fn ns_of(mut f: impl FnMut()) -> f64 {
    let t = monotonic_ns();
    f();
    (monotonic_ns() - t) as f64
}

/// The simulation step against one 12 x 12 matrix-vector product (the least one conjugate
/// gradient iteration of the step does).
pub fn sim_step(o: &Options) -> Part {
    let rig: Rig = match frond_formats::rig_files::embedded_rig("grass") {
        Some(Ok(loaded)) => loaded.rig,
        Some(Err(e)) => return Err((Status::Error, e.to_string())),
        None => return Err((Status::Error, "no embedded grass rig".into())),
    };
    let wind: WindSpec =
        "speed=3,dir=0,gust=0.8,seed=4".parse().map_err(|e| (Status::Error, format!("{e}")))?;
    let mut plant =
        PlantSim::new(rig.sim_node_heights_m(), rig.sim, wind).map_err(|e| (Status::Error, e.to_string()))?;
    let steps = if o.quick { 2_000 } else { 20_000 };
    for _ in 0..500 {
        plant.step().map_err(|e| (Status::Error, e.to_string()))?;
    }
    let mut step_ns = Vec::with_capacity(steps);
    let mut matvec_ns = Vec::with_capacity(steps);
    let m: [[f64; 12]; 12] = std::array::from_fn(|i| std::array::from_fn(|j| 1.0 / (1 + i + j) as f64));
    let mut v = [1.0f64; 12];
    for _ in 0..steps {
        step_ns.push(ns_of(|| {
            black_box(plant.step()).ok();
        }));
        matvec_ns.push(ns_of(|| {
            let x = black_box(v);
            for (i, row) in m.iter().enumerate() {
                v[i] = row.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>() * 0.5;
            }
            black_box(&v);
        }));
    }
    let step = median(&mut step_ns);
    let per_s = step * 1000.0 / 1e9;
    Ok(Section::ok(
        "sim_step",
        "simulated plant: one implicit Euler step (Physically-based Driven Tree Animations, section 4)",
        vec![
            Measurement::new(
                "sim_step_ns",
                "ns",
                step,
                "one 12 x 12 matrix-vector product",
                median(&mut matvec_ns),
            )
            .with_target(
                "one step well under a 1 kHz tick (< 100 us)",
                Bound::MaxMeasured,
                100_000.0,
            ),
        ],
        json!({"steps": steps, "timestep_s": rig.sim.timestep_s, "fraction_of_core_for_1000_steps_per_s": per_s}),
    ))
}

/// Graph builds at 2k, 10k and 100k samples against sorting the same samples by one coordinate
/// (an `n log n` pass over the same data); the growth exponent says how close to `n log n`.
pub fn graph_build(o: &Options) -> Part {
    let runs = if o.quick { 1 } else { 3 };
    let mut measurements = Vec::new();
    let mut details = serde_json::Map::new();
    let mut times = Vec::new();
    for n in [2_000usize, 10_000, 100_000] {
        let poses = sway(n);
        let path = positions(&poses);
        let params = GraphParams::new(ControlPoint::Top);
        let mut graph: Option<MotionGraph> = None;
        let mut build: Vec<f64> =
            (0..runs).map(|_| ns_of(|| graph = build_graph(&poses, &path, &params).ok())).collect();
        let graph = graph.ok_or((Status::Error, format!("no graph from the {n}-sample sway")))?;
        let mut sort: Vec<f64> = (0..runs)
            .map(|_| {
                let mut xs: Vec<f64> = path.iter().map(|p| p[0]).collect();
                ns_of(|| xs.sort_by(f64::total_cmp))
            })
            .collect();
        let build_ms = median(&mut build) / 1e6;
        let examined = graph.pruned.transitions_found as f64 / n as f64;
        times.push((build_ms, examined));
        let k = n / 1000;
        let mut m = Measurement::new(
            format!("graph_build_{k}k_samples_ms"),
            "ms",
            build_ms,
            "sorting the same samples by x (n log n)",
            median(&mut sort) / 1e6,
        );
        if n == 100_000 {
            m = m.with_target("sub-second at 100,000 samples", Bound::MaxMeasured, 1000.0);
        }
        measurements.push(m);
        details.insert(
            format!("{k}k"),
            json!({"nodes": graph.len(), "transitions": graph.transitions(),
                   "neighbours_in_front_per_sample": examined}),
        );
    }
    // Growth from 2k to 100k: time ~ n^e. n log n gives e = ln(50 ln(1e5) / ln(2e3)) / ln 50.
    // A longer take over the same sway is denser (more neighbours within one step, up to the
    // cap), so the growth is also given per neighbour examined.
    let growth = |a: f64, b: f64| (b / a).ln() / 50f64.ln();
    let e = growth(times[0].0, times[2].0);
    let per_neighbour = growth(times[0].0 / times[0].1.max(1.0), times[2].0 / times[2].1.max(1.0));
    let nlogn = (50.0 * 100_000f64.ln() / 2_000f64.ln()).ln() / 50f64.ln();
    let verdict = if e <= nlogn + 0.15 {
        "close to n log n"
    } else if per_neighbour <= nlogn + 0.15 {
        "close to n log n per neighbour examined; above it overall because the longer take is denser (more neighbours per sample, at most 64)"
    } else {
        "faster than n log n"
    };
    details.insert(
        "growth".into(),
        json!({"exponent_2k_to_100k": e, "exponent_per_neighbour": per_neighbour,
               "n_log_n_exponent": nlogn, "verdict": verdict}),
    );
    Ok(Section::ok(
        "graph_build",
        "motion graph build (Physically-based Driven Tree Animations, section 5) at 2k, 10k and 100k samples",
        measurements,
        Value::Object(details),
    ))
}

/// Walkers: one plant's frame against copying a pose out of the take, and 64 plants' frames in
/// one tick against the 1 kHz tick.
pub fn graph_walk(o: &Options) -> Part {
    let poses = sway(18_000);
    let graph = build_graph(&poses, &positions(&poses), &GraphParams::new(ControlPoint::Top))
        .map_err(|e| (Status::Error, e.to_string()))?;
    let mut walkers: Vec<Walker> =
        (0..64).map(|i| Walker::new(&graph, (i * graph.len() / 64) as u32, i as u64, 30.0)).collect();
    let ticks = if o.quick { 2_000 } else { 20_000 };
    let mut tick_ns = Vec::with_capacity(ticks);
    let mut copy_ns = Vec::with_capacity(ticks);
    let mut out = [poses[0]; 64];
    for k in 0..ticks {
        tick_ns.push(ns_of(|| {
            for (w, o) in walkers.iter_mut().zip(out.iter_mut()) {
                *o = w.next_frame(&graph, &poses).pose;
            }
            black_box(&out);
        }));
        copy_ns.push(ns_of(|| {
            for (i, o) in out.iter_mut().enumerate() {
                *o = black_box(poses[(k * 64 + i) % poses.len()]);
            }
            black_box(&out);
        }));
    }
    let tick = median(&mut tick_ns);
    let copy = median(&mut copy_ns);
    Ok(Section::ok(
        "graph_walk",
        "motion graph walkers (Physically-based Driven Tree Animations, section 6): per plant, and 64 plants in a 1 kHz tick",
        vec![
            Measurement::new(
                "walk_frame_per_plant_ns",
                "ns",
                tick / 64.0,
                "copying one pose out of the take",
                copy / 64.0,
            ),
            Measurement::new(
                "walk_64_plants_per_tick_us",
                "us",
                tick / 1e3,
                "copying 64 poses out of the take",
                copy / 1e3,
            )
            .with_target(
                "a small fraction of the 1 kHz tick (<= 50 us, 5 %)",
                Bound::MaxMeasured,
                50.0,
            ),
        ],
        json!({"nodes": graph.len(), "transitions": graph.transitions(), "ticks": ticks,
               "fraction_of_1khz_tick": tick / 1e6}),
    ))
}
