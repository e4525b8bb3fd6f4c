//! The realtime rule, proven: a steady-state loop tick allocates nothing.
//!
//! A counting global allocator counts allocations made on the thread that runs the ticks (other
//! threads, such as the subscriber drain below, are not counted). The engine is driven through
//! every steady-state path: fresh reports (one and several per tick), held ticks, device loss,
//! subscribers (draining and full), recording, and live filter/calibration changes.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use crossbeam_channel::bounded;
use frond_device::{DeviceSample, HandSource, SourceCounters, SourceError, SourceKind};
use frond_motion::{CalibrationParams, FilterSpec, HandSample, Mapper, Rig};
use frondd::engine::{Engine, EngineLinks, LoopCommand};
use frondd::publisher::{Outbound, SubscriberCounters, SubscriberSlot};
use frondd::stats::LoopStats;

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: delegates every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Relaxed);
        }
        // SAFETY: same contract as our caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as our caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Relaxed);
        }
        // SAFETY: same contract as our caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

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

#[test]
fn steady_state_ticks_allocate_nothing() {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(
        rig.mapping(),
        cal.params(),
        FilterSpec::OneEuro { min_cutoff: 1.0, beta: 0.01, d_cutoff: 1.0 },
    );
    let (cmd_tx, cmd_rx) = bounded(64);
    let (rec_tx, rec_rx) = bounded(100_000);
    let (reopen_tx, reopen_rx) = bounded(1);
    let (garbage_tx, _garbage_rx) = bounded(64);
    let stats = Arc::new(LoopStats::default());
    let source = Scripted {
        tick: 0,
        seq: 0,
        counters: Arc::new(SourceCounters::default()),
        pattern: [1, 1, 0, 3, 1, 0, 1, 2],
        fail_every: 0,
    };
    let mut engine = Engine::new(
        mapper,
        Some(Box::new(source)),
        250_000_000,
        EngineLinks {
            commands: cmd_rx,
            recorder: rec_tx,
            reopen: reopen_tx,
            garbage: garbage_tx,
            stats: stats.clone(),
        },
    );

    // One subscriber drained by another thread, one never drained (its queue fills up).
    let (fast_tx, fast_rx) = bounded::<Outbound>(1024);
    let (stuck_tx, _stuck_rx) = bounded::<Outbound>(16);
    let drained = Arc::new(AtomicU64::new(0));
    let drain_count = drained.clone();
    let drain = std::thread::spawn(move || {
        while let Ok(_msg) = fast_rx.recv() {
            drain_count.fetch_add(1, Relaxed);
        }
    });
    let fast_counters = Arc::new(SubscriberCounters::default());
    for (id, tx, counters) in
        [(1, fast_tx, fast_counters.clone()), (2, stuck_tx, Arc::new(SubscriberCounters::default()))]
    {
        cmd_tx.send(LoopCommand::AddSubscriber(SubscriberSlot { id, tx, counters })).unwrap();
    }
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
    COUNTING.with(|c| c.set(true));
    for _ in 0..20_000 {
        now += 1_000_000;
        engine.tick(now);
    }
    COUNTING.with(|c| c.set(false));
    let allocations = ALLOCATIONS.load(Relaxed);
    let published = engine.next_seq() - before_seq;
    let total_published = engine.next_seq();

    assert_eq!(allocations, 0, "{allocations} allocations in 20000 ticks");
    // The ticks did real work: at least one frame per tick, more when several reports arrived.
    assert!(published > 20_000, "published {published}");
    assert!(stats.held_ticks.load(Relaxed) > 0);
    assert!(stats.publish_drops.load(Relaxed) > 0, "the stuck subscriber's drops are counted");
    assert!(!rec_rx.is_empty(), "frames reached the recorder queue");
    assert!(reopen_rx.is_empty());
    drop(engine);
    drop(cmd_tx);
    drain.join().unwrap();
    // Every frame offered to the drained subscriber was either delivered or counted as dropped
    // (plus the Start message that precedes the poses).
    let dropped = fast_counters.dropped.load(Relaxed);
    assert_eq!(drained.load(Relaxed) + dropped, total_published + 1);
}

#[test]
fn device_loss_and_reopen_allocate_nothing_in_the_loop() {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    let (cmd_tx, cmd_rx) = bounded(64);
    let (rec_tx, _rec_rx) = bounded(16);
    let (reopen_tx, reopen_rx) = bounded::<Box<dyn HandSource>>(1);
    let (garbage_tx, _garbage_rx) = bounded(64);
    let stats = Arc::new(LoopStats::default());
    let source = Scripted {
        tick: 0,
        seq: 0,
        counters: Arc::new(SourceCounters::default()),
        pattern: [1; 8],
        fail_every: 500,
    };
    let mut engine = Engine::new(
        mapper,
        Some(Box::new(source)),
        250_000_000,
        EngineLinks {
            commands: cmd_rx,
            recorder: rec_tx,
            reopen: reopen_tx,
            garbage: garbage_tx,
            stats: stats.clone(),
        },
    );
    let mut now = 1_000_000_000u64;
    COUNTING.with(|c| c.set(true));
    for _ in 0..5_000 {
        now += 1_000_000;
        engine.tick(now);
        // The "reopen thread": hand the source straight back (moving a Box allocates nothing).
        if let Ok(src) = reopen_rx.try_recv() {
            cmd_tx.send(LoopCommand::ReplaceSource(src)).unwrap();
        }
    }
    COUNTING.with(|c| c.set(false));
    assert_eq!(ALLOCATIONS.load(Relaxed), 0);
    assert!(stats.device_lost_events.load(Relaxed) >= 9, "{}", stats.device_lost_events.load(Relaxed));
}
