//! Criterion micro-benchmarks of the realtime loop's per-report work: calibrate + filter + map
//! (seed 000, Eq. 2-4) with each jitter filter, and of the motion toolkit's field playback and
//! loop transition search. `cargo bench -p frond-motion`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use frond_formats::rig_toml::RigText;
use frond_motion::clip::Clip;
use frond_motion::field_player::bench_field_1000;
use frond_motion::looping::{LoopParams, find_transitions};
use frond_motion::{Calibration, FilterSpec, HandSample, Mapper, Rig};

fn hand(k: u64) -> HandSample {
    let t = k as f64 * 0.001;
    HandSample {
        t,
        wrist_deg: [(t * 1.7).sin() as f32 * 20.0, (t * 0.9).cos() as f32 * 10.0, 3.0],
        thumb_deg: [20.0 + (t * 2.3).sin() as f32 * 10.0, 25.0, (t * 3.1).cos() as f32 * 15.0 + 20.0],
    }
}

fn mapping(c: &mut Criterion) {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).expect("grass rig");
    let cal = Calibration::neutral_for(&rig);
    for (name, filter) in [
        ("none", FilterSpec::None),
        ("lowpass", FilterSpec::LowPass { cutoff_hz: 8.0 }),
        ("one-euro", FilterSpec::OneEuro { min_cutoff: 1.0, beta: 0.007, d_cutoff: 1.0 }),
    ] {
        let mut mapper = Mapper::new(rig.mapping(), cal.params(), filter);
        let mut k = 0u64;
        c.bench_function(&format!("calibrate+filter+map ({name})"), |b| {
            b.iter(|| {
                k += 1;
                black_box(mapper.process(black_box(&hand(k))))
            })
        });
    }
}

fn toolkit(c: &mut Criterion) {
    let (mut player, mut out) = bench_field_1000();
    let mut t = 0.0;
    c.bench_function("field frame (1000 plants)", |b| {
        b.iter(|| {
            t += 1.0 / 60.0;
            player.frame(t, &mut out);
            black_box(&out);
        })
    });
    let clip = Clip::from_joints(
        (0..1800).map(|k| {
            let s = (k as f32 * 0.07).sin() * 20.0 + (k as f32 * 0.011).sin() * 5.0;
            [
                [s, -s * 0.5, 0.0],
                [s * 0.5, -s * 0.25, 0.0],
                [s * 0.5, -s * 0.25, 3.0],
                [s * 0.3, -s * 0.1, 3.0],
            ]
        }),
        30.0,
    );
    c.bench_function("loop transitions (60 s take at 30 FPS)", |b| {
        b.iter(|| black_box(find_transitions(black_box(&clip), &LoopParams::default())))
    });
}

/// The live stages' per-tick work units, for their budgets (`frondd::stage::budget`): one
/// simulation step of the grass plant in a gusty wind (seed 003, section 4.2) and one walk frame
/// of a motion-graph walker (section 6).
fn stage_units(c: &mut Criterion) {
    use frond_motion::graph::{ControlPoint, GraphParams, Walker, build_graph, control_positions_m};
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).expect("grass rig");
    let mut plant =
        frond_motion::sim::PlantSim::from_rig(&rig, "speed=4,dir=30,gust=0.8,seed=2".parse().expect("wind"))
            .expect("plant");
    c.bench_function("sim step (grass, gusty wind)", |b| b.iter(|| black_box(plant.step())));
    let sway = frond_motion::graph::sample_sway(600);
    let skeleton = frond_motion::skeleton::Skeleton::even(1.0);
    let path = control_positions_m(ControlPoint::Top, &skeleton, 1.0, &sway);
    let graph = build_graph(&sway, &path, &GraphParams::new(ControlPoint::Top)).expect("graph");
    let mut walker = Walker::new(&graph, 0, 4, 30.0);
    c.bench_function("graph walk frame (one plant)", |b| {
        b.iter(|| black_box(walker.next_frame(&graph, &sway)))
    });
}

criterion_group!(benches, mapping, toolkit, stage_units);
criterion_main!(benches);
