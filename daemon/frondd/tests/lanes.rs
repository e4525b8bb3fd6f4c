//! A subscriber moves from its direct lane (the loop writes to it) to the publisher's slow lane
//! when its socket fills, and its stream stays whole: every frame once, in order, from the
//! sequence number its `Hello` announced.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

use frond_device::{DeviceSample, HandSource, SourceCounters, SourceError, SourceKind};
use frond_motion::{FilterSpec, HandSample, Mapper, Rig};
use frond_protocol::{ServerMessage, read_frame};
use frondd::engine::Engine;
use frondd::publisher::{PublisherConfig, SubscriberCounters, spawn_publisher};

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

#[test]
fn a_subscriber_that_falls_behind_moves_to_the_slow_lane_without_losing_a_frame() {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    let source = Box::new(Steady { seq: 0, counters: Arc::default() });
    let (mut engine, mut ends) = Engine::with_channels(mapper, Some(source), 250_000_000, 1 << 16, 16);
    let config = PublisherConfig {
        queue_frames: 100_000,
        write_timeout: Duration::from_secs(30),
        max_subscribers: 64,
    };
    let frames = std::mem::replace(&mut ends.frames, crossbeam_channel::never());
    let slow = std::mem::replace(&mut ends.slow, crossbeam_channel::never());
    let publisher =
        spawn_publisher(frames, ends.publish_wake.clone(), slow, Default::default(), config).unwrap();

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
