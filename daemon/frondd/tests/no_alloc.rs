//! The realtime rule, proven: a steady-state loop tick allocates nothing.
//!
//! The counting global allocator (`frond-alloc-count`) counts allocations made on the thread
//! that runs the ticks (other threads, such as the subscriber drain below, are not counted). The engine is driven through
//! every steady-state path: fresh reports (one and several per tick), held ticks, device loss,
//! subscribers (draining and full), recording, and live filter/calibration changes.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use frond_alloc_count::{CountingAlloc, count_allocations};
use frond_device::{DeviceSample, HandSource, SourceCounters, SourceError, SourceKind};
use frond_formats::field_json::FieldJson;
use frond_formats::layers::TakeBytes;
use frond_formats::rig_toml::RigText;
use frond_motion::{CalibrationParams, FilterSpec, HandSample, Mapper, Rig};
use frond_protocol::ElementId;
use frondd::engine::{Engine, LoopCommand};

mod common;
use common::{new_lane, subscriber_pair};

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

/// A scripted device: `pattern[tick % len]` reports per read, then a disconnect every so often.
struct Scripted {
    tick: u64,
    seq: u32,
    counters: Arc<SourceCounters>,
    pattern: [usize; 8],
    fail_every: u64,
}

impl HandSource for Scripted {
    fn kind(&self) -> SourceKind {
        SourceKind::InProcess
    }
    fn describe(&self) -> &str {
        "scripted"
    }
    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        self.tick += 1;
        if self.fail_every > 0 && self.tick.is_multiple_of(self.fail_every) {
            return Err(SourceError::Disconnected { what: String::new(), reason: String::new() });
        }
        let n = self.pattern[(self.tick % 8) as usize].min(out.len());
        for slot in out.iter_mut().take(n) {
            self.seq += 1;
            let t = f64::from(self.seq) * 0.001;
            *slot = DeviceSample {
                device_seq: self.seq,
                device_time_us: u64::from(self.seq) * 1000,
                raw: HandSample {
                    t,
                    wrist_deg: [(t.sin() * 30.0) as f32, 5.0, -3.0],
                    thumb_deg: [10.0, 20.0, (t * 7.0) as f32],
                },
                ..DeviceSample::default()
            };
        }
        Ok(n)
    }
    fn counters(&self) -> Arc<SourceCounters> {
        self.counters.clone()
    }
    fn reopen(&mut self) -> Result<(), SourceError> {
        Ok(())
    }
}

fn scripted(pattern: [usize; 8], fail_every: u64) -> Box<dyn HandSource> {
    Box::new(Scripted { tick: 0, seq: 0, counters: Arc::new(SourceCounters::default()), pattern, fail_every })
}

#[test]
fn steady_state_ticks_allocate_nothing() {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(
        rig.mapping(),
        cal.params(),
        FilterSpec::OneEuro { min_cutoff: 1.0, beta: 0.01, d_cutoff: 1.0 },
    );
    // A small publisher queue drained by another thread, which starts draining only after the
    // first 5000 counted ticks: both the dropped path (queue full) and the delivered path run,
    // whatever the scheduling.
    let (mut engine, ends) =
        Engine::with_channels(mapper, Some(scripted([1, 1, 0, 3, 1, 0, 1, 2], 0)), 250_000_000, 256, 100_000);
    let (cmd_tx, publish_rx, rec_rx, reopen_rx, stats) =
        (ends.commands, ends.frames, ends.recorder, ends.reopen, ends.stats);
    let drained = Arc::new(AtomicU64::new(0));
    let drain_count = drained.clone();
    let start_draining = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let go = start_draining.clone();
    let drain = std::thread::spawn(move || {
        while !go.load(Relaxed) {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        while let Ok(_pose) = publish_rx.recv() {
            drain_count.fetch_add(1, Relaxed);
        }
    });
    cmd_tx.send(LoopCommand::SetRecording(true)).unwrap();

    // Warm-up: first ticks may touch lazily initialised state.
    let mut now = 1_000_000_000u64;
    for _ in 0..1000 {
        now += 1_000_000;
        engine.tick(now);
    }
    // Steady state, with live changes arriving as commands (built before counting starts).
    let changes: Vec<LoopCommand> = vec![
        LoopCommand::SetFilter(FilterSpec::LowPass { cutoff_hz: 8.0 }),
        LoopCommand::SetCalibration(CalibrationParams { ..cal.params() }),
        LoopCommand::SetFilter(FilterSpec::None),
    ];
    for c in changes {
        cmd_tx.send(c).unwrap();
    }
    let before_seq = engine.next_seq();
    let ((), allocations) = count_allocations(|| {
        for i in 0..20_000 {
            now += 1_000_000;
            engine.tick(now);
            if i == 5_000 {
                start_draining.store(true, Relaxed);
            }
        }
    });
    let published = engine.next_seq() - before_seq;
    let total_published = engine.next_seq();

    assert_eq!(allocations, 0, "{allocations} allocations in 20000 ticks");
    // The ticks did real work: at least one frame per tick, more when several reports arrived.
    assert!(published > 20_000, "published {published}");
    assert!(stats.held_ticks.load(Relaxed) > 0);
    assert!(stats.publish_drops.load(Relaxed) > 0, "drops at a full publisher queue are counted");
    assert!(!rec_rx.is_empty(), "frames reached the recorder queue");
    assert!(reopen_rx.is_empty());
    drop(engine);
    drop(cmd_tx);
    drain.join().unwrap();
    // Every frame was either delivered to the publisher or counted as dropped.
    assert_eq!(drained.load(Relaxed) + stats.publish_drops.load(Relaxed), total_published);
}

#[test]
fn device_loss_and_reopen_allocate_nothing_in_the_loop() {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    let (mut engine, ends) = Engine::with_channels(mapper, Some(scripted([1; 8], 500)), 250_000_000, 16, 16);
    let (cmd_tx, reopen_rx, stats) = (ends.commands, ends.reopen, ends.stats);
    let mut now = 1_000_000_000u64;
    let ((), allocations) = count_allocations(|| {
        for _ in 0..5_000 {
            now += 1_000_000;
            engine.tick(now);
            // The "reopen thread": hand the source straight back (moving a Box allocates nothing).
            if let Ok(lost) = reopen_rx.try_recv() {
                cmd_tx.send(LoopCommand::ReplaceSource(lost.hand, lost.source)).unwrap();
            }
        }
    });
    assert_eq!(allocations, 0);
    assert!(stats.hands[0].lost_events.load(Relaxed) >= 9, "{}", stats.hands[0].lost_events.load(Relaxed));
}

/// A 3 s take (1 kHz frames) as bytes, for the live modes.
fn take_bytes() -> Vec<u8> {
    use frond_motion::PoseFrame;
    use frond_motion::layers::Take;
    use frond_motion::take::{TakeFrame, TakeHeader};
    let header = TakeHeader::offline("g", "flower", 1000);
    let mut take = Take::new(header);
    let frames = (0..3000u64).map(|k| {
        let t = k as f64 / 1000.0;
        let a = (t * 2.0).sin() as f32 * 20.0;
        TakeFrame {
            seq: k,
            device_time_us: k * 1000,
            pose: PoseFrame {
                t,
                joints_deg: [[a, a / 2.0, 0.0], [a / 3.0, 0.0, 0.0], [a, 1.0, 2.0], [a, -a, 3.0]],
            },
            ..TakeFrame::default()
        }
    });
    take.set_layer(ElementId::GLOBAL, None, frames);
    take.to_bytes()
}

/// A stage command for `slot`, built before counting (boxing allocates).
fn stage_command(slot: usize, action: frondd::stage::StageAction, table: Option<Vec<u8>>) -> LoopCommand {
    LoopCommand::Stage(Box::new(frondd::stage::StageCommand {
        slot,
        action,
        elements_frame: table,
        elements_version: 2,
        applied: Arc::default(),
    }))
}

#[test]
fn every_live_stage_allocates_nothing_per_tick() {
    use frond_motion::field::{Field, FieldParams, make_field};
    use frond_protocol::{StageInput, StageKey};
    use frondd::stage::StageAction::{Input, Install};
    use frondd::stage::field::{FieldReport, FieldStage};
    use frondd::stage::guided::{GuidedStage, parse_guided};
    use frondd::stage::layer::LayerStage;
    use frondd::stage::playback::PlaybackStage;
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/flower.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    let (mut engine, ends) = Engine::with_channels(
        mapper,
        Some(scripted([1, 0, 1, 2, 1, 1, 0, 1], 0)),
        250_000_000,
        1 << 20,
        100_000,
    );
    let (cmd_tx, sub_rx, garbage_rx) = (ends.commands, ends.frames, ends.garbage);
    let bytes = take_bytes();
    let field = make_field(
        &FieldParams {
            rows: 10,
            cols: 10,
            cell_m: 0.5,
            speed_m_s: 1.0,
            direction_deg: 30.0,
            density: 1.0,
            seed: 3,
        },
        "g",
        90,
        30.0,
    )
    .unwrap();
    let t0 = 1_000_000_000u64;
    let ids: Vec<ElementId> = (40..56).map(ElementId::new).collect();
    let report = Arc::new(FieldReport::new("g", 100));
    let field = Field::from_json(&field.to_json()).unwrap();
    let looped = frondd::stage::playback::looped_clip(&bytes).unwrap();
    let live_field = FieldStage::new(looped, field, ids[0], ids.len(), 5, t0, report.clone()).unwrap();
    let field_frames = ends.publish_wake.clone();
    // Four plants walking a motion graph of a Lissajous sway (seed 003, section 6).
    let sway = frond_motion::graph::sample_sway(1200);
    let control = frond_motion::graph::ControlPoint::Top;
    let path = frond_motion::graph::control_positions_m(
        control,
        &frond_motion::skeleton::Skeleton::from_rig(&rig),
        0.5,
        &sway,
    );
    let graph =
        frond_motion::graph::build_graph(&sway, &path, &frond_motion::graph::GraphParams::new(control))
            .unwrap();
    let (walk, graph_report) = frondd::stage::graph::GraphStage::new(
        vec![
            frondd::stage::graph::GraphSource::new("sway", graph.clone(), sway.clone()),
            frondd::stage::graph::GraphSource::new("sway2", graph, sway),
        ],
        &[60, 61, 62, 63].map(ElementId::new),
        9,
        30.0,
        t0,
    );
    // The simulated plant (seed 003, section 4) in a gusty wind the hand turns.
    let plant =
        frond_motion::sim::PlantSim::from_rig(&rig, "speed=4,dir=30,gust=0.8,seed=2".parse().unwrap())
            .unwrap();
    let (sim, sim_report) = frondd::stage::sim::SimStage::new(
        plant,
        "speed=4,dir=30,gust=0.8,seed=2".parse().unwrap(),
        t0,
        "flower",
    );
    let stages: [Box<dyn frondd::stage::LiveStage>; 6] = [
        Box::new(PlaybackStage::new(
            frondd::stage::playback::looped_clip(&bytes).unwrap(),
            5,
            t0,
            ElementId::GLOBAL,
        )),
        Box::new(live_field),
        Box::new(GuidedStage::new(parse_guided("sigma=0.1,0.2,0.3", 60.0).unwrap(), 1000)),
        Box::new(LayerStage::new(ElementId::FIRST_LAYER)),
        Box::new(walk),
        Box::new(sim),
    ];
    for (slot, stage) in stages.into_iter().enumerate() {
        cmd_tx.send(stage_command(slot, Install(Some(stage)), None)).unwrap();
    }
    cmd_tx.send(LoopCommand::SetRecording(true)).unwrap();
    let mut now = t0;
    for _ in 0..500 {
        now += 1_000_000;
        engine.tick(now);
    }
    // Inputs and a new element table arrive while counting (built here).
    let mut changes: Vec<LoopCommand> = [StageKey::Left, StageKey::Stronger]
        .into_iter()
        .map(|k| stage_command(1, Input(StageInput::Key(k)), None))
        .collect();
    changes.push(stage_command(0, frondd::stage::StageAction::Announce, Some(vec![0u8; 300])));
    // Graph goals (popped last to first: the pose goal, planned over the following ticks, last).
    use frond_protocol::GraphGoal;
    for goal in [
        GraphGoal::Dir { deg: 90.0 },
        GraphGoal::Hand,
        GraphGoal::Off,
        GraphGoal::Pose { joints_deg: [[12.0, -5.0, 0.0]; 4] },
        GraphGoal::Frame { frame: 600 },
    ] {
        changes.insert(0, stage_command(4, Input(StageInput::GraphGoal(goal)), None));
    }
    let ((), allocations) = count_allocations(|| {
        for i in 0..10_000 {
            now += 1_000_000;
            engine.tick(now);
            if i % 1000 == 0
                && let Some(c) = changes.pop()
            {
                cmd_tx.send(c).unwrap();
            }
        }
    });
    assert_eq!(allocations, 0, "allocations in live-stage ticks");
    // The stages really ran: playback frames (element 0), the field's frames (field 40: one
    // frame, not one pose per plant), leaf frames (1).
    let mut elements = std::collections::HashSet::new();
    while let Ok(p) = sub_rx.try_recv() {
        elements.insert(p.element.get());
    }
    assert!(elements.contains(&0) && elements.contains(&1), "{elements:?}");
    assert!(!elements.contains(&40), "no pose per plant: {elements:?}");
    let fields: Vec<_> = field_frames.field_frames().try_iter().collect();
    assert!(fields.len() >= 100 && fields.iter().all(|f| f.field == ids[0]), "{} field frames", fields.len());
    assert!(fields.windows(2).all(|w| w[1].seq >= w[0].seq + 16 && w[1].tau_s >= w[0].tau_s));
    assert!(fields.iter().all(|f| f.poses == 16), "numbers kept for the 16 announced plants' poses");
    assert!((60..64).all(|id| elements.contains(&id)), "graph walkers: {elements:?}");
    let sim = frondd::stage::StageReport::describe(&*sim_report);
    assert!(
        sim.contains("at 10.5 s") || sim.contains("at 10.4 s"),
        "the plant simulated the counted ticks: {sim}"
    );
    let walk = frondd::stage::StageReport::describe(&*graph_report);
    assert!(walk.contains("goal pose of frame 600") && !walk.contains("planning"), "{walk}");
    assert_eq!(report.controls.load().unwrap().direction_deg, 180.0, "the keys reached the field");
    // Every applied command came back to be dropped off the loop.
    assert_eq!(garbage_rx.try_iter().filter(|g| matches!(g, frondd::handoff::Garbage::Stage(_))).count(), 14);
}

/// Counts the poses a subscriber reads (into `count` as it goes) and checks they are consecutive
/// from its Hello on.
fn read_poses(
    mut s: std::os::unix::net::UnixStream,
    count: Arc<AtomicU64>,
) -> std::thread::JoinHandle<(u64, bool)> {
    std::thread::spawn(move || {
        use frond_protocol::{ServerMessage, read_frame};
        let mut buf = Vec::new();
        let Ok(ServerMessage::Hello(h)) = read_frame::<ServerMessage, _>(&mut s, &mut buf) else {
            return (0, false);
        };
        let (mut next, mut n) = (h.next_seq, 0u64);
        while let Ok(ServerMessage::Pose(p)) = read_frame::<ServerMessage, _>(&mut s, &mut buf) {
            if p.seq != next {
                return (n, false);
            }
            next += 1;
            n += 1;
            count.store(n, Relaxed);
        }
        (n, true)
    })
}

/// The loop's own writes to subscribers: admitting two, sending every frame to them, and moving
/// a third that never reads to the slow lane all happen inside the counted ticks, without an
/// allocation; the two readers see an unbroken sequence.
#[test]
fn direct_lanes_allocate_nothing_admitting_sending_and_demoting() {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    let (mut engine, ends) =
        Engine::with_channels(mapper, Some(scripted([1, 0, 2, 1, 1, 1, 0, 1], 0)), 250_000_000, 1 << 16, 16);
    let (a_daemon, a_sub) = subscriber_pair(false);
    let (b_daemon, b_sub) = subscriber_pair(false);
    let (stalled_daemon, _stalled_sub) = subscriber_pair(true);
    let counts = [Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0))];
    let (ra, rb) = (read_poses(a_sub, counts[0].clone()), read_poses(b_sub, counts[1].clone()));
    let mut now = 1_000_000_000u64;
    for _ in 0..100 {
        now += 1_000_000;
        engine.tick(now);
    }
    for (id, s) in [(1, a_daemon), (2, b_daemon), (3, stalled_daemon)] {
        ends.commands.send(new_lane(id, s, Arc::default())).unwrap();
    }
    let first = engine.next_seq();
    let ((), allocations) = count_allocations(|| {
        for _ in 0..5_000 {
            now += 1_000_000;
            engine.tick(now);
            // Wait for the readers when they are a few dozen frames behind, so they stay on
            // their lanes however loaded the machine is (bounded: a failure shows in the asserts
            // below); sleeping allocates nothing.
            let mut waited = 0;
            while counts.iter().any(|c| first + c.load(Relaxed) + 32 < engine.next_seq()) && waited < 100_000
            {
                std::thread::sleep(std::time::Duration::from_micros(50));
                waited += 1;
            }
        }
    });
    assert_eq!(allocations, 0, "allocations while serving direct lanes");
    assert_eq!(engine.lanes().ids().collect::<Vec<_>>(), vec![1, 2]);
    assert_eq!(engine.lanes().demoted(), 1);
    let slow = ends.slow.try_recv().expect("the stalled subscriber went to the slow lane");
    assert_eq!(slow.id, 3);
    assert!(slow.from_seq > 100 && slow.from_seq < engine.next_seq());
    let published = engine.next_seq() - first;
    drop(engine);
    for r in [ra, rb] {
        let (n, in_order) = r.join().unwrap();
        assert!(in_order, "a reader saw a gap or a bad frame");
        assert_eq!(n, published, "a reader got {n} of {published} frames");
    }
}

#[test]
fn two_hands_one_lost_allocate_nothing_and_the_other_keeps_flowing() {
    use frond_protocol::PoseFlags;
    use frondd::engine::HandInput;
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = || Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    // The left hand reports once per tick for ever; the right one fails at its 50th read and is
    // never handed back (its reopen thread keeps failing).
    let hands = vec![
        HandInput {
            mapper: mapper(),
            source: Some(scripted([1; 8], 0)),
            element: ElementId::GLOBAL,
            follows_setup: true,
        },
        HandInput {
            mapper: mapper(),
            source: Some(scripted([1; 8], 50)),
            element: ElementId::FIRST_LAYER,
            follows_setup: false,
        },
    ];
    let (mut engine, ends) = Engine::with_hands_and_channels(hands, 250_000_000, 1 << 16, 16);
    let mut now = 1_000_000_000u64;
    let ticks = 2_000u64;
    let ((), allocations) = count_allocations(|| {
        for _ in 0..ticks {
            now += 1_000_000;
            engine.tick(now);
        }
    });
    assert_eq!(allocations, 0);
    let lost = ends.reopen.try_recv().expect("the right hand's source went to the reopen thread");
    assert_eq!(lost.hand, 1);
    assert!(engine.needs_every_tick(), "two hands: every tick holds the other's frame");
    let frames: Vec<_> = ends.frames.try_iter().collect();
    // One frame per hand per tick, numbered without a gap.
    assert_eq!(frames.len() as u64, 2 * ticks);
    assert!(frames.windows(2).all(|w| w[1].seq == w[0].seq + 1), "a gap in the sequence");
    let (left, right): (Vec<&frond_protocol::Pose>, Vec<_>) =
        frames.iter().partition(|p| p.element.is_global());
    assert_eq!(left.len() as u64, ticks);
    assert!(
        left.iter().all(|p| !p.flags.contains(PoseFlags::HELD) && !p.flags.contains(PoseFlags::DEVICE_LOST)),
        "the left hand kept flowing: every frame fresh"
    );
    assert!(left.windows(2).all(|w| w[1].device_time_us == w[0].device_time_us + 1000));
    assert!(right.iter().all(|p| p.element == ElementId::FIRST_LAYER));
    assert_eq!(
        right.iter().filter(|p| !p.flags.contains(PoseFlags::HELD)).count(),
        49,
        "49 reads before the 50th failed"
    );
    assert!(right[49..].iter().all(|p| p.flags.contains(PoseFlags::HELD | PoseFlags::DEVICE_LOST)));
    let stats = &ends.stats;
    assert!(stats.hands[0].connected.load(Relaxed));
    assert!(!stats.hands[1].connected.load(Relaxed));
    assert_eq!(stats.hands[1].lost_events.load(Relaxed), 1);
    assert_eq!(stats.hands[0].lost_events.load(Relaxed), 0);
    assert_eq!(stats.hands[0].frames.load(Relaxed), ticks);
    assert_eq!(stats.hands[1].held_frames.load(Relaxed), ticks - 49);
}
