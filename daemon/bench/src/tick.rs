//! Section 3: per-tick cost of calibrate + filter + map, of a whole engine tick, and allocations
//! per tick.

use std::hint::black_box;

use crossbeam_channel::Receiver;
use frond_motion::HandSample;
use frond_protocol::{Pose, ServerMessage, encode_frame};
use frondd::clock::monotonic_ns;
use frondd::engine::{Engine, EngineEnds};
use serde_json::json;

use crate::Options;
use crate::alloc::{count_allocations, counting_installed};
use crate::error::BenchError;
use crate::report::{Bound, Measurement, Section};
use crate::rig::{TickGlove, mapper};
use crate::timing::SUBSCRIBERS;

/// Median of `v` (sorted in place).
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() { 0.0 } else { v[v.len() / 2] }
}

/// Nanoseconds per call of `f`, median over `batches` batches of `n` calls.
fn ns_per_call(batches: usize, n: u64, mut f: impl FnMut(u64)) -> f64 {
    let mut per = Vec::with_capacity(batches);
    let mut k = 0u64;
    for _ in 0..batches {
        let start = monotonic_ns();
        for _ in 0..n {
            f(k);
            k += 1;
        }
        per.push((monotonic_ns() - start) as f64 / n as f64);
    }
    median(&mut per)
}

fn hand(k: u64) -> HandSample {
    let t = k as f64 * 0.001;
    HandSample {
        t,
        wrist_deg: [(t * 1.7).sin() as f32 * 20.0, (t * 0.9).cos() as f32 * 10.0, 3.0],
        thumb_deg: [20.0 + (t * 2.3).sin() as f32 * 10.0, 25.0, (t * 3.1).cos() as f32 * 15.0 + 20.0],
    }
}

/// An engine on the one-report-per-tick glove with [`SUBSCRIBERS`] subscribers on its direct
/// lanes (socket pairs read to the end by their own threads), its publisher queue drained by the
/// caller, and the other ends of its channels.
struct TickRig {
    engine: Engine,
    rx: Receiver<Pose>,
    _ends: EngineEnds,
    _readers: Vec<std::thread::JoinHandle<()>>,
    /// The daemon ends of the subscriber sockets (clones), to see what the readers have not read.
    daemon_ends: Vec<std::os::unix::net::UnixStream>,
}

impl TickRig {
    /// Waits (at most 2 s) until the readers have read everything sent, so the next batch of
    /// ticks finds room in every socket as a live subscriber's would.
    fn settle(&self) {
        use std::os::fd::AsRawFd;
        let unread = |s: &std::os::unix::net::UnixStream| {
            let mut n: libc::c_int = 0;
            // SAFETY: SIOCOUTQ writes one c_int (bytes not yet read by the peer) into `n`.
            let rc = unsafe { libc::ioctl(s.as_raw_fd(), libc::TIOCOUTQ, &mut n) };
            if rc == 0 { n } else { 0 }
        };
        let deadline = monotonic_ns() + 2_000_000_000;
        while self.daemon_ends.iter().any(|s| unread(s) > 0) && monotonic_ns() < deadline {
            std::thread::sleep(std::time::Duration::from_micros(50));
        }
    }
}

fn engine() -> Result<TickRig, BenchError> {
    use std::io::Read;
    let (mut engine, mut ends) = Engine::with_channels(
        mapper(),
        Some(Box::new(TickGlove::new())),
        250_000_000,
        1024 * SUBSCRIBERS,
        16,
    );
    let hello = frond_protocol::PatchableHello::new(&frond_protocol::Hello {
        protocol_version: frond_protocol::PROTOCOL_VERSION,
        daemon_version: env!("CARGO_PKG_VERSION").into(),
        rig_name: "grass".into(),
        joint_names: crate::rig::grass().joint_names(),
        tick_rate_hz: 1000,
        elements: Default::default(),
        next_seq: 0,
    });
    let mut readers = Vec::new();
    let mut daemon_ends = Vec::new();
    for id in 0..SUBSCRIBERS as u64 {
        let (daemon_end, mut sub_end) = std::os::unix::net::UnixStream::pair()?;
        daemon_ends.push(daemon_end.try_clone()?);
        readers.push(std::thread::spawn(move || {
            let mut buf = [0u8; 16 * 1024];
            while matches!(sub_end.read(&mut buf), Ok(n) if n > 0) {}
        }));
        let lane = frondd::lanes::NewLane::new(id, daemon_end, Default::default(), hello.clone());
        ends.commands
            .send(frondd::engine::LoopCommand::AddSubscriber(Box::new(lane)))
            .map_err(|_| BenchError::EngineGone)?;
    }
    engine.tick(monotonic_ns());
    if engine.lanes().len() != SUBSCRIBERS {
        return Err(BenchError::NoData(format!(
            "{} of {SUBSCRIBERS} subscribers on direct lanes",
            engine.lanes().len()
        )));
    }
    let rx = std::mem::replace(&mut ends.frames, crossbeam_channel::never());
    Ok(TickRig { engine, rx, _ends: ends, _readers: readers, daemon_ends })
}

/// Empties the publisher queue (the loop also offers every frame there, for the slow lane).
fn drain(rx: &Receiver<Pose>) {
    while rx.try_recv().is_ok() {}
}

/// Section 3.
pub fn tick_cost(o: &Options) -> Result<Section, BenchError> {
    let (batches, n) = if o.quick { (15, 20_000) } else { (41, 200_000) };
    // calibrate + filter (One Euro) + map, the loop's per-report work.
    let mut m = mapper();
    for k in 0..10_000 {
        black_box(m.process(&hand(k)));
    }
    let clock = ns_per_call(batches, n, |_| {
        black_box(monotonic_ns());
    });
    let map_ns = ns_per_call(batches, n, |k| {
        black_box(m.process(black_box(&hand(k))));
    });
    let clock2 = ns_per_call(batches, n, |_| {
        black_box(monotonic_ns());
    });
    let clock_ns = (clock + clock2) / 2.0;

    // A whole engine tick: read one report, calibrate, filter, map, stamp, encode, send to the 8
    // subscribers' sockets, offer to the publisher queue.
    let mut rig = engine()?;
    // 100 frames fit in a socket's send buffer (each ~230-byte frame is accounted as ~1 KiB).
    let tick_batch = 100u64;
    let mut now = monotonic_ns();
    let mut tick_times = Vec::new();
    for _ in 0..batches * (n as usize / 20_000).max(1) {
        let start = monotonic_ns();
        for _ in 0..tick_batch {
            now += 1_000_000;
            rig.engine.tick(now);
        }
        tick_times.push((monotonic_ns() - start) as f64 / tick_batch as f64);
        drain(&rig.rx);
        rig.settle();
    }
    let lanes_after_ticks = rig.engine.lanes().len();
    let tick_ns = median(&mut tick_times);

    let mut measurements = vec![
        Measurement::new(
            "calibrate_filter_map_ns",
            "ns",
            map_ns,
            "one CLOCK_MONOTONIC read (vDSO)",
            clock_ns,
        )
        .with_target("calibrate + filter + map under 1 us per tick", Bound::MaxMeasured, 1000.0),
        Measurement::new(
            "engine_tick_8_subscribers_ns",
            "ns",
            tick_ns,
            "one CLOCK_MONOTONIC read (vDSO)",
            clock_ns,
        ),
    ];
    let mut details = json!({
        "filter": "one-euro:min_cutoff=1,beta=0.007,d_cutoff=1",
        "rig": "grass",
        "batches": batches,
        "calls_per_batch": n,
        "clock_read_ns_before_after": [clock, clock2],
        "subscribers": SUBSCRIBERS,
        "subscribers_on_direct_lanes_after_timed_ticks": lanes_after_ticks,
    });
    if let Some(m) = allocations_per_tick(o, &mut rig, now, tick_batch, &mut details) {
        measurements.push(m);
    }
    Ok(Section::ok(
        "tick_cost",
        "per-tick cost of calibrate + filter + map, of a whole engine tick, and allocations per tick",
        measurements,
        details,
    ))
}

/// Allocations per engine tick (the realtime rule: none) against a naive publisher's, when
/// this process counts allocations (the `frond-bench` binary installs the counting allocator);
/// `None`, and the reason in `details`, when it does not. `now` is the engine's clock so far.
fn allocations_per_tick(
    o: &Options,
    rig: &mut TickRig,
    mut now: u64,
    tick_batch: u64,
    details: &mut serde_json::Value,
) -> Option<Measurement> {
    if !counting_installed() {
        details["allocations"] = json!({"status": "not available", "reason": "the counting allocator is not installed in this process (the frond binary installs it)"});
        return None;
    }
    let ticks = if o.quick { 20_000u64 } else { 200_000 };
    let mut allocations = 0;
    let mut done = 0;
    while done < ticks {
        let (_, a) = count_allocations(|| {
            for _ in 0..tick_batch {
                now += 1_000_000;
                rig.engine.tick(now);
            }
        });
        allocations += a;
        done += tick_batch;
        drain(&rig.rx);
        rig.settle();
    }
    details["subscribers_on_direct_lanes_after_allocation_ticks"] = json!(rig.engine.lanes().len());
    // Baseline: the same frames published the naive way, encoding each one into a fresh
    // buffer per subscriber (what a loop without preallocated buffers does).
    let pose = Pose::default();
    let naive_frames = 2_000u64;
    let (_, naive) = count_allocations(|| {
        for _ in 0..naive_frames {
            for _ in 0..SUBSCRIBERS {
                let mut buf = Vec::new();
                encode_frame(&ServerMessage::Pose(pose), &mut buf);
                black_box(&buf);
            }
        }
    });
    let m = Measurement::new(
        "allocations_per_tick",
        "allocations/tick",
        allocations as f64 / ticks as f64,
        "naive publish (a fresh buffer per encoded frame per subscriber), allocations/tick",
        naive as f64 / naive_frames as f64,
    )
    .with_target("zero allocations per tick", Bound::MaxMeasured, 0.0);
    details["allocation_ticks"] = json!(ticks);
    details["allocations"] = json!(allocations);
    Some(m)
}
