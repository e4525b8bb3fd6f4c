//! A subscriber moves from its direct lane (the loop writes to it) to the publisher's slow lane
//! when its socket fills, and its stream stays whole: every frame once, in order, from the
//! sequence number its `Hello` announced.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

use frond_device::{DeviceSample, HandSource, SourceCounters, SourceError, SourceKind};
use frond_formats::rig_toml::RigText;
use frond_motion::{FilterSpec, HandSample, Mapper, Rig};
use frond_protocol::{ElementId, ServerMessage, read_frame};
use frondd::engine::Engine;
use frondd::handoff::SubscriberCounters;
use frondd::publisher::{PublisherConfig, spawn_publisher};

mod common;
use common::{new_lane, subscriber_pair};

/// One report per read.
struct Steady {
    seq: u32,
    counters: Arc<SourceCounters>,
}

impl HandSource for Steady {
    fn kind(&self) -> SourceKind {
        SourceKind::InProcess
    }
    fn describe(&self) -> &str {
        "steady"
    }
    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        self.seq += 1;
        let t = f64::from(self.seq) * 0.001;
        out[0] = DeviceSample {
            device_seq: self.seq,
            device_time_us: u64::from(self.seq) * 1000,
            raw: HandSample {
                t,
                wrist_deg: [t.sin() as f32 * 20.0, 0.0, 0.0],
                thumb_deg: [10.0, 20.0, 30.0],
            },
            ..DeviceSample::default()
        };
        Ok(1)
    }
    fn counters(&self) -> Arc<SourceCounters> {
        self.counters.clone()
    }
    fn reopen(&mut self) -> Result<(), SourceError> {
        Ok(())
    }
}

/// An engine on the grass rig with a steady source, and the publisher thread serving its slow
/// lane (with the engine's element table cell).
fn engine_with_publisher() -> (Engine, frondd::engine::EngineEnds, std::thread::JoinHandle<()>) {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    let source = Box::new(Steady { seq: 0, counters: Arc::default() });
    let (engine, mut ends) = Engine::with_channels(mapper, Some(source), 250_000_000, 1 << 16, 16);
    let config = PublisherConfig {
        queue_frames: 100_000,
        write_timeout: Duration::from_secs(30),
        max_subscribers: 64,
    };
    let frames = std::mem::replace(&mut ends.frames, crossbeam_channel::never());
    let slow = std::mem::replace(&mut ends.slow, crossbeam_channel::never());
    let publisher =
        spawn_publisher(frames, ends.publish_wake.clone(), slow, ends.elements.clone(), config).unwrap();
    (engine, ends, publisher)
}

#[test]
fn a_subscriber_that_falls_behind_moves_to_the_slow_lane_without_losing_a_frame() {
    let (mut engine, ends, publisher) = engine_with_publisher();

    // The daemon's end gets a small send buffer, so the stall fills it within a few dozen frames.
    let (daemon_end, mut sub_end) = subscriber_pair(true);
    let read = Arc::new(AtomicU64::new(0));
    let read_count = read.clone();
    let reader = std::thread::spawn(move || {
        // Stalled for a while: the loop's sends start failing and it hands the subscriber over.
        std::thread::sleep(Duration::from_millis(300));
        let mut buf = Vec::new();
        let Ok(ServerMessage::Hello(h)) = read_frame::<ServerMessage, _>(&mut sub_end, &mut buf) else {
            panic!("no Hello first");
        };
        let mut next = h.next_seq;
        while let Ok(msg) = read_frame::<ServerMessage, _>(&mut sub_end, &mut buf) {
            let ServerMessage::Pose(p) = msg else { panic!("{msg:?} after the Hello") };
            assert_eq!(p.seq, next, "gap or repeat in the subscriber's stream");
            next += 1;
            read_count.fetch_add(1, Relaxed);
        }
        h.next_seq
    });

    let counters = Arc::new(SubscriberCounters::default());
    let mut now = 1_000_000_000u64;
    for _ in 0..50 {
        now += 1_000_000;
        engine.tick(now);
    }
    let first = engine.next_seq();
    ends.commands.send(new_lane(7, daemon_end, counters.clone())).unwrap();
    // ~0.6 s of ticks: the stall, the hand-over, and frames through the slow lane after it.
    for _ in 0..3000 {
        now += 1_000_000;
        engine.tick(now);
        std::thread::sleep(Duration::from_micros(200));
    }
    assert_eq!(engine.lanes().demoted(), 1, "the stalled subscriber was not moved to the slow lane");
    assert!(engine.lanes().is_empty());
    let published = engine.next_seq() - first;
    let deadline = Instant::now() + Duration::from_secs(30);
    while read.load(Relaxed) < published && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(read.load(Relaxed), published, "frames read of those published since it joined");
    assert_eq!(counters.dropped.load(Relaxed), 0);
    assert_eq!(counters.sent.load(Relaxed), published);
    drop(engine);
    publisher.join().unwrap();
    assert_eq!(reader.join().unwrap(), first, "the Hello announced the first frame it got");
}

/// Publishes element 40 at every tick (a stand-in for a stage with elements of its own).
struct Forty;

impl frondd::stage::LiveStage for Forty {
    fn tick(&mut self, _ctx: &frondd::stage::TickContext, out: &mut dyn frondd::stage::FrameSink) {
        out.emit(ElementId::new(40), [[1.0; 3]; 4]);
    }
    fn every_tick(&self) -> bool {
        true
    }
}

/// A subscriber on the slow lane gets a new element table exactly before the first frame
/// published under it: never before (while frames of the old table still come), never after a
/// frame of an element it announces.
#[test]
fn the_slow_lane_sends_a_new_table_right_before_its_first_frame() {
    use frond_protocol::{ElementInfo, ElementKind, ElementTable};
    let (mut engine, ends, publisher) = engine_with_publisher();
    let (daemon_end, mut sub_end) = subscriber_pair(true);
    // The reader waits, so the subscriber moves to the slow lane; then it reads everything.
    let last_seq = Arc::new(AtomicU64::new(0));
    let last = last_seq.clone();
    let go = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let start = go.clone();
    let reader = std::thread::spawn(move || {
        while !start.load(Relaxed) {
            std::thread::sleep(Duration::from_millis(1));
        }
        let mut buf = Vec::new();
        let mut seen = Vec::new();
        while let Ok(msg) = read_frame::<ServerMessage, _>(&mut sub_end, &mut buf) {
            if let ServerMessage::Pose(p) = &msg {
                last.store(p.seq, Relaxed);
            }
            seen.push(msg);
        }
        seen
    });
    let mut now = 1_000_000_000u64;
    ends.commands.send(new_lane(7, daemon_end, Arc::new(SubscriberCounters::default()))).unwrap();
    for _ in 0..200 {
        now += 1_000_000;
        engine.tick(now);
    }
    assert_eq!(engine.lanes().demoted(), 1, "the subscriber is on the slow lane");
    // As the control side does: the cell first, then the command that installs the stage.
    let table = ElementTable {
        version: 2,
        rigs: vec![],
        elements: vec![ElementInfo {
            id: ElementId::new(40),
            name: "forty".into(),
            kind: ElementKind::FieldPlant,
            source: "test".into(),
            rig: "grass".into(),
        }],
    };
    let mut frame = Vec::new();
    frond_protocol::encode_frame(&ServerMessage::Elements(table.clone()), &mut frame);
    ends.elements.store(2, &frame);
    // Frames published after the store but before the loop applies it are of the old table.
    for _ in 0..50 {
        now += 1_000_000;
        engine.tick(now);
        std::thread::sleep(Duration::from_micros(300));
    }
    ends.commands
        .send(frondd::engine::LoopCommand::Stage(Box::new(frondd::stage::StageCommand {
            slot: 0,
            action: frondd::stage::StageAction::Install(Some(Box::new(Forty))),
            elements_frame: Some(frame),
            elements_version: 2,
            applied: Arc::default(),
        })))
        .unwrap();
    for _ in 0..200 {
        now += 1_000_000;
        engine.tick(now);
        std::thread::sleep(Duration::from_micros(300));
    }
    let from_seq = ends.elements.load().from_seq;
    assert!(from_seq < engine.next_seq(), "the loop marked the table applied");
    // Let the reader catch up before the publisher (and its backlog) goes away.
    go.store(true, Relaxed);
    let deadline = Instant::now() + Duration::from_secs(20);
    while last_seq.load(Relaxed) + 1 < engine.next_seq() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    drop(engine);
    publisher.join().unwrap();
    let seen = reader.join().unwrap();
    let kinds: Vec<String> = seen
        .iter()
        .map(|m| match m {
            ServerMessage::Pose(p) => format!("{}:{}", p.seq, p.element),
            other => format!("{other:?}").chars().take(20).collect(),
        })
        .collect();
    let at = seen
        .iter()
        .position(|m| matches!(m, ServerMessage::Elements(_)))
        .unwrap_or_else(|| panic!("no table; it applies from {from_seq}: {kinds:?}"));
    assert_eq!(seen.iter().filter(|m| matches!(m, ServerMessage::Elements(_))).count(), 1);
    assert_eq!(seen[at], ServerMessage::Elements(table));
    for m in &seen[..at] {
        if let ServerMessage::Pose(p) = m {
            assert!(p.seq < from_seq && p.element.is_global(), "{p:?} came before its table");
        }
    }
    let ServerMessage::Pose(next) = &seen[at + 1] else { panic!("a pose follows the table") };
    assert_eq!(next.seq, from_seq, "the table comes right before the first frame under it");
    assert!(
        seen[at..].iter().any(|m| matches!(m, ServerMessage::Pose(p) if p.element == ElementId::new(40)))
    );
    // A stage's frames carry the device time of the hand sample their tick worked from (one
    // timeline for every element; receivers key frames by it).
    let mut hand_t = None;
    let mut stage_times = Vec::new();
    for m in &seen {
        match m {
            ServerMessage::Pose(p) if p.element.is_global() => hand_t = Some(p.hand.t),
            ServerMessage::Pose(p) if p.element == ElementId::new(40) => {
                assert_eq!(Some(p.hand.t), hand_t, "frame {} of the stage", p.seq);
                stage_times.push(p.hand.t);
            }
            _ => {}
        }
    }
    assert!(
        stage_times.windows(2).any(|w| w[1] > w[0]),
        "the stage's frames advance in time: {stage_times:?}"
    );
}
