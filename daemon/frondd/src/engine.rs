//! The realtime loop's per-tick work, separate from the thread that paces it so that tests can
//! drive it tick by tick (the counting-allocator test does).
//!
//! One tick: apply pending commands, let every live stage publish its own elements
//! ([`crate::stage`]), read every pending report of every hand source (up to [`MAX_HANDS`], each
//! with its own rig, calibration, filter and element), and for each report calibrate -> filter
//! -> map (the same [`Mapper::process`] as `frond map`), let the stages transform it (the primary
//! hand's only), and publish a frame; for a hand with no report this period, republish its last
//! pose flagged `held`. One hand lost or stalled never holds up the others. Frames go to the
//! direct lanes, the publisher's queue and the recorder's wait-free ring; a full queue or ring
//! costs a frame (counted), never the loop a wait. Nothing here allocates, locks or blocks.

use std::sync::Arc;
use std::sync::atomic::Ordering::{Relaxed, Release};

use crossbeam_channel::{Receiver, Sender};
use frond_device::{DeviceSample, HandSource};
use frond_motion::clip::Joints;
use frond_motion::take::TakeFrame;
use frond_motion::{FilterSpec, HandSample, Mapper, PoseFrame};
use frond_protocol::field::FieldFrame;
use frond_protocol::{ElementId, HandWire, Pose, PoseFlags};

use crate::clock::monotonic_ns;
use crate::handoff::{
    ELEMENTS_FRAME_MAX, ElementsCell, Garbage, LostSource, PublishQueue, PublisherWake, SlowLane,
};
/// Re-exported where the configuration's limits and `frond bench` have always named them.
pub use crate::handoff::{LoopCommand, MAX_HANDS, MAX_SUBSCRIBERS};
use crate::lanes::Lanes;
use crate::stage::{FrameSink, LiveStage, MAX_STAGES, StageAction, StageCommand, TickContext};
use crate::stats::LoopStats;

/// Reports read from the device per `read_pending` call.
const SAMPLE_BATCH: usize = 64;
/// `read_pending` calls per tick at most (a burst beyond this waits for the next tick).
const MAX_READS_PER_TICK: usize = 16;

/// One hand as the engine is given it: its mapper (rig, calibration, filter), source and element.
pub struct HandInput {
    /// Calibrate -> filter -> map, with this hand's rig and calibration.
    pub mapper: Mapper,
    /// Its source; `None` while the device is awaited.
    pub source: Option<Box<dyn HandSource>>,
    /// The element it is published as (0: the global element; `k + 1`: the rig's layer `k`).
    pub element: ElementId,
    /// Whether the daemon's rig, calibration and filter apply to it ([`LoopCommand::SetMapping`]
    /// and its kin); a hand with a rig of its own keeps it.
    pub follows_setup: bool,
}

impl HandInput {
    /// The one hand of a single-source daemon: element 0, following the daemon's setup.
    pub fn single(mapper: Mapper, source: Option<Box<dyn HandSource>>) -> Self {
        HandInput { mapper, source, element: ElementId::GLOBAL, follows_setup: true }
    }
}

/// Channels and shared state the engine talks through.
pub struct EngineLinks {
    /// Commands in.
    pub commands: Receiver<LoopCommand>,
    /// Frames out, to the publisher thread.
    pub publish: PublishQueue,
    /// Subscribers moved off their direct lane, to the publisher thread.
    pub slow: Sender<SlowLane>,
    /// Frames to the recorder: a wait-free ring it polls.
    pub recorder: rtrb::Producer<TakeFrame>,
    /// A source that failed, for the reopen thread.
    pub reopen: Sender<LostSource>,
    /// Things to drop elsewhere.
    pub garbage: Sender<Garbage>,
    /// Counters read by status.
    pub stats: Arc<LoopStats>,
    /// The element table for the slow lane; the loop marks each table applied in it.
    pub elements: Arc<ElementsCell>,
}

/// The far ends of an engine's channels, from [`Engine::with_channels`].
pub struct EngineEnds {
    /// Send commands to the loop.
    pub commands: Sender<LoopCommand>,
    /// Frames the loop publishes.
    pub frames: Receiver<Pose>,
    /// Wakes whoever waits on `frames` through it (see [`crate::publisher::spawn_publisher`]).
    pub publish_wake: Arc<PublisherWake>,
    /// Subscribers the loop moved to the slow lane.
    pub slow: Receiver<SlowLane>,
    /// Frames the loop hands to the recorder.
    pub recorder: rtrb::Consumer<TakeFrame>,
    /// Sources the loop gives up as lost.
    pub reopen: Receiver<LostSource>,
    /// What the loop may not drop itself.
    pub garbage: Receiver<Garbage>,
    /// The loop's counters.
    pub stats: Arc<LoopStats>,
    /// The element table cell the loop marks applied tables in.
    pub elements: Arc<ElementsCell>,
}

/// The loop's outputs: sequence numbers, lanes, queues. Apart from the stages, so that a stage
/// can publish through it while the engine walks its stages.
struct Output {
    lanes: Lanes,
    links: EngineLinks,
    seq: u64,
    recording: bool,
    /// The element table in force, encoded (sent after a Hello that carries an older one),
    /// followed by the running fields' table.
    elements_frame: Vec<u8>,
    /// Where the field table starts in `elements_frame` (its length when it holds none): a
    /// Hello carries the element table but not the fields', which follows every Hello.
    fields_at: usize,
    /// Its version.
    elements_version: u64,
}

impl Output {
    /// Stamps `frame` with the next sequence number and the host time, sends it to the direct
    /// lanes and hands it to the publisher thread (a full queue drops it, counted). Returns the
    /// stamped frame.
    fn publish(&mut self, mut frame: Pose) -> Pose {
        frame.seq = self.seq;
        frame.host_monotonic_ns = monotonic_ns();
        self.seq += 1;
        self.links.stats.next_seq.store(self.seq, Relaxed);
        self.lanes.send(&frame, &self.links.garbage);
        if !self.links.publish.offer(frame) {
            self.links.stats.publish_drops.fetch_add(1, Relaxed);
        }
        frame
    }

    /// Numbers and stamps a field frame like a pose (its numbers are those of its announced
    /// plants' poses, [`FieldFrame::poses`]) and sends it the same ways.
    fn publish_field(&mut self, frame: &mut FieldFrame) {
        frame.seq = self.seq;
        frame.host_monotonic_ns = monotonic_ns();
        self.seq += u64::from(frame.poses).max(1);
        self.links.stats.next_seq.store(self.seq, Relaxed);
        self.lanes.send_field(frame, &self.links.garbage);
        if !self.links.publish.offer_field(*frame) {
            self.links.stats.publish_drops.fetch_add(1, Relaxed);
        }
    }
}

/// Where the second frame of `frames` (one or more encoded frames) starts: the field table after
/// the element table. `frames.len()` when it holds one frame.
fn second_frame_at(frames: &[u8]) -> usize {
    let Some(len) = frames.first_chunk::<4>() else { return frames.len() };
    (u32::from_le_bytes(*len) as usize).saturating_add(4).min(frames.len())
}

/// Where the stages' own frames go: published, flagged `playback`.
struct StageSink<'a> {
    out: &'a mut Output,
    device_time_us: u64,
    /// The primary hand's device time this tick, seconds: a stage's frames carry it as their
    /// `hand.t`, so every element's frames share one timeline (receivers key them by it).
    hand_t: f64,
}

impl FrameSink for StageSink<'_> {
    fn emit(&mut self, element: ElementId, joints_deg: Joints) {
        let mut flags = PoseFlags::PLAYBACK;
        flags.set(PoseFlags::RECORDING, self.out.recording);
        self.out.publish(Pose {
            element,
            joints_deg,
            flags,
            device_time_us: self.device_time_us,
            hand: HandWire { t: self.hand_t, ..HandWire::default() },
            ..Pose::default()
        });
    }

    fn emit_field(&mut self, frame: &mut FieldFrame) {
        frame.device_time_us = self.device_time_us;
        frame.hand_t = self.hand_t;
        frame.flags = PoseFlags::PLAYBACK;
        frame.flags.set(PoseFlags::RECORDING, self.out.recording);
        self.out.publish_field(frame);
    }
}

/// One hand's state in the loop.
struct Hand {
    mapper: Mapper,
    source: Option<Box<dyn HandSource>>,
    element: ElementId,
    follows_setup: bool,
    last: Pose,
    last_hand: HandSample,
    last_report_ns: u64,
    lost: bool,
    /// Reports published by [`Engine::device_ready`] since the last tick.
    fresh_since_tick: usize,
}

/// The realtime loop's state. Allocates only in [`Engine::new`].
pub struct Engine {
    hands: Box<[Hand]>,
    /// The hand stages act on (`on_hand`, a layer's relabelling): the first that drives the
    /// global element, else the first.
    primary: usize,
    /// Descriptors of the hands' sources, for the loop's `ppoll` (filled by [`Engine::ready_fds`]).
    pollfds: [libc::pollfd; MAX_HANDS],
    samples: Box<[DeviceSample]>,
    out: Output,
    stages: Box<[Option<Box<dyn LiveStage>>]>,
    /// Whether some stage has work at every tick.
    stages_every_tick: bool,
    /// The element the primary hand is published as while a stage relabels it (a layer).
    stage_hand_element: Option<ElementId>,
    stall_after_ns: u64,
    /// When the loop last ran (a tick or a device wake), host ns; 0 before the first.
    last_run_ns: u64,
}

impl Engine {
    /// A new engine with one hand: the given mapper and (optional) source.
    pub fn new(
        mapper: Mapper,
        source: Option<Box<dyn HandSource>>,
        stall_after_ns: u64,
        links: EngineLinks,
    ) -> Self {
        Self::with_hands(vec![HandInput::single(mapper, source)], stall_after_ns, links)
    }

    /// A new engine reading every hand of `hands` (beyond [`MAX_HANDS`] are ignored; the
    /// configuration refuses more).
    ///
    /// # Panics
    /// If `hands` is empty (a caller's bug: every configuration has at least one hand).
    pub fn with_hands(hands: Vec<HandInput>, stall_after_ns: u64, links: EngineLinks) -> Self {
        assert!(!hands.is_empty(), "an engine needs at least one hand");
        let now = monotonic_ns();
        let hands: Box<[Hand]> = hands
            .into_iter()
            .take(MAX_HANDS)
            .enumerate()
            .map(|(i, h)| {
                let lost = h.source.is_none();
                links.stats.hands[i].connected.store(!lost, Relaxed);
                let mut last = Pose { element: h.element, ..Pose::default() };
                last.flags.set(PoseFlags::DEVICE_LOST, lost);
                Hand {
                    mapper: h.mapper,
                    source: h.source,
                    element: h.element,
                    follows_setup: h.follows_setup,
                    last,
                    last_hand: HandSample::default(),
                    last_report_ns: now,
                    lost,
                    fresh_since_tick: 0,
                }
            })
            .collect();
        Engine {
            primary: primary_of(&hands),
            hands,
            pollfds: [libc::pollfd { fd: -1, events: libc::POLLIN, revents: 0 }; MAX_HANDS],
            samples: vec![DeviceSample::default(); SAMPLE_BATCH].into_boxed_slice(),
            out: Output {
                lanes: Lanes::new(links.slow.clone(), links.publish.wake()),
                links,
                seq: 0,
                recording: false,
                elements_frame: Vec::with_capacity(ELEMENTS_FRAME_MAX),
                fields_at: 0,
                elements_version: 0,
            },
            stages: (0..MAX_STAGES).map(|_| None).collect(),
            stages_every_tick: false,
            stage_hand_element: None,
            stall_after_ns,
            last_run_ns: 0,
        }
    }

    /// An engine with fresh bounded channels (`publish_frames` and `recorder_frames` deep), for
    /// driving it tick by tick without the daemon's threads: tests and `frond bench`.
    pub fn with_channels(
        mapper: Mapper,
        source: Option<Box<dyn HandSource>>,
        stall_after_ns: u64,
        publish_frames: usize,
        recorder_frames: usize,
    ) -> (Engine, EngineEnds) {
        Self::with_hands_and_channels(
            vec![HandInput::single(mapper, source)],
            stall_after_ns,
            publish_frames,
            recorder_frames,
        )
    }

    /// [`Engine::with_channels`] for several hands.
    pub fn with_hands_and_channels(
        hands: Vec<HandInput>,
        stall_after_ns: u64,
        publish_frames: usize,
        recorder_frames: usize,
    ) -> (Engine, EngineEnds) {
        let (cmd_tx, cmd_rx) = crossbeam_channel::bounded(256);
        let (publish, frames) = PublishQueue::new(publish_frames);
        let (rec_tx, rec_rx) = crate::recorder::frame_ring(recorder_frames);
        let (reopen_tx, reopen_rx) = crossbeam_channel::bounded(MAX_HANDS);
        let (garbage_tx, garbage_rx) = crossbeam_channel::bounded(256);
        let (slow_tx, slow_rx) = crossbeam_channel::bounded(MAX_SUBSCRIBERS);
        let stats = Arc::new(LoopStats::default());
        let elements = Arc::new(ElementsCell::default());
        let publish_wake = publish.wake();
        let links = EngineLinks {
            commands: cmd_rx,
            publish,
            slow: slow_tx,
            recorder: rec_tx,
            reopen: reopen_tx,
            garbage: garbage_tx,
            stats: stats.clone(),
            elements: elements.clone(),
        };
        let ends = EngineEnds {
            commands: cmd_tx,
            frames,
            publish_wake,
            slow: slow_rx,
            recorder: rec_rx,
            reopen: reopen_rx,
            garbage: garbage_rx,
            stats,
            elements,
        };
        (Engine::with_hands(hands, stall_after_ns, links), ends)
    }

    /// The ready descriptors of every hand source that has one, for `ppoll` (the array is the
    /// engine's own: nothing is allocated). Empty when no source has one.
    pub fn ready_fds(&mut self) -> &mut [libc::pollfd] {
        let mut n = 0;
        for hand in self.hands.iter() {
            if let Some(fd) = hand.source.as_ref().and_then(|s| s.ready_fd()) {
                self.pollfds[n] = libc::pollfd { fd, events: libc::POLLIN, revents: 0 };
                n += 1;
            }
        }
        &mut self.pollfds[..n]
    }

    /// Whether every tick does work of its own, so that a tick may not be skipped even when a
    /// report already covered its period: a stage publishes at ticks (a looped take, a field),
    /// or several hands are read (a report of one does not cover the others' held frames).
    pub fn needs_every_tick(&self) -> bool {
        self.stages_every_tick || self.hands.len() > 1
    }

    /// Between ticks, when a source's ready descriptor woke the loop: applies pending commands
    /// and publishes every pending report of every hand at once, instead of at the next tick.
    /// Returns the number of reports published; the next [`Engine::tick`] counts them as
    /// fresh, so it publishes no held frame for the period they arrived in.
    pub fn device_ready(&mut self, now_ns: u64) -> usize {
        self.apply_commands(now_ns);
        self.resume_after_pause(now_ns);
        let mut total = 0;
        for i in 0..self.hands.len() {
            let fresh = self.read_device(i, now_ns, Reports::Publish);
            self.note_fresh(i, fresh, now_ns);
            self.hands[i].fresh_since_tick += fresh;
            total += fresh;
        }
        total
    }

    /// The loop's bookkeeping after a [`Engine::device_ready`] that published reports, when
    /// [`Engine::needs_every_tick`] is false: the reports belong to a period whose tick is
    /// covered by them, so they must not count for the next tick. `count_tick` when this
    /// covers the upcoming tick (the loop then skips it and waits for the one after).
    pub fn cover_tick(&mut self, count_tick: bool) {
        for hand in self.hands.iter_mut() {
            hand.fresh_since_tick = 0;
        }
        if count_tick {
            self.out.links.stats.ticks.fetch_add(1, Relaxed);
        }
    }

    /// Reports arrived: the device is there again, unless the same read lost it (reports, then
    /// an error, in one call of `read_device`): then it stays lost until it is handed back.
    fn note_fresh(&mut self, i: usize, fresh: usize, now_ns: u64) {
        if fresh > 0 {
            self.hands[i].last_report_ns = now_ns;
            if self.hands[i].lost && self.hands[i].source.is_some() {
                self.set_device_lost(i, false);
            }
        }
    }

    /// Runs one tick at host time `now_ns`. Publishes at least one frame per hand.
    pub fn tick(&mut self, now_ns: u64) {
        self.apply_commands(now_ns);
        self.resume_after_pause(now_ns);
        self.tick_stages(now_ns);
        let mut held_any = false;
        for i in 0..self.hands.len() {
            let read = self.read_device(i, now_ns, Reports::Publish);
            self.note_fresh(i, read, now_ns);
            let fresh = read + std::mem::take(&mut self.hands[i].fresh_since_tick);
            if fresh == 0 {
                self.publish_held(i, now_ns);
                held_any = true;
            }
        }
        if held_any {
            self.out.links.stats.held_ticks.fetch_add(1, Relaxed);
        }
        self.out.links.stats.ticks.fetch_add(1, Relaxed);
    }

    /// After the loop itself was paused for longer than the stall window (SIGSTOP, an
    /// overloaded host), what the sources queued meanwhile is stale: it is skipped (counted), so
    /// the stream resumes at the present instead of bursting through old reports, and each
    /// hand's next report starts a new timeline (flagged `discontinuity`, filter reset).
    fn resume_after_pause(&mut self, now_ns: u64) {
        let paused = self.last_run_ns != 0 && now_ns.saturating_sub(self.last_run_ns) > self.stall_after_ns;
        self.last_run_ns = now_ns;
        if !paused {
            return;
        }
        for i in 0..self.hands.len() {
            let skipped = self.read_device(i, now_ns, Reports::Skip);
            let hand = &mut self.hands[i];
            hand.mapper.break_timeline();
            // The stall window restarts now: the source had no chance to report while paused.
            hand.last_report_ns = now_ns;
            self.out.links.stats.hands[i].stale_skipped.fetch_add(skipped as u64, Relaxed);
        }
    }

    /// Republishes hand `i`'s last pose flagged `held` (and `device_lost` once it stalled).
    fn publish_held(&mut self, i: usize, now_ns: u64) {
        let hand = &self.hands[i];
        let stalled =
            hand.source.is_some() && now_ns.saturating_sub(hand.last_report_ns) > self.stall_after_ns;
        if stalled && !hand.lost {
            self.out.links.stats.hands[i].stall_events.fetch_add(1, Relaxed);
            self.set_device_lost(i, true);
        }
        let hand = &self.hands[i];
        let mut held = hand.last;
        held.flags.insert(PoseFlags::HELD);
        held.flags.set(PoseFlags::DEVICE_LOST, hand.lost);
        held.flags.set(PoseFlags::RECORDING, self.out.recording);
        held.element = self.element_of(i);
        self.out.links.stats.hands[i].held_frames.fetch_add(1, Relaxed);
        self.out.publish(held);
    }

    /// The element hand `i` is published as now.
    fn element_of(&self, i: usize) -> ElementId {
        match self.stage_hand_element {
            Some(element) if i == self.primary => element,
            _ => self.hands[i].element,
        }
    }

    fn apply_commands(&mut self, now_ns: u64) {
        while let Ok(cmd) = self.out.links.commands.try_recv() {
            match cmd {
                LoopCommand::SetMapping(m) => {
                    for hand in self.hands.iter_mut().filter(|h| h.follows_setup) {
                        hand.mapper.set_mapping(m);
                    }
                }
                LoopCommand::SetCalibration(c) => {
                    for hand in self.hands.iter_mut().filter(|h| h.follows_setup) {
                        hand.mapper.set_calibration(c);
                    }
                }
                LoopCommand::SetFilter(f) => {
                    for hand in self.hands.iter_mut().filter(|h| h.follows_setup) {
                        hand.mapper.set_filter(f);
                    }
                }
                LoopCommand::SetHandElement { hand, element } => {
                    if let Some(h) = self.hands.get_mut(hand) {
                        h.element = element;
                        h.last.element = element;
                    }
                    self.primary = primary_of(&self.hands);
                }
                LoopCommand::SetRecording(on) => {
                    self.out.recording = on;
                    // Release: the recorder's stop, seeing `false`, also sees every frame
                    // pushed before it.
                    self.out.links.stats.recording.store(on, Release);
                }
                LoopCommand::Stage(cmd) => self.apply_stage(cmd),
                LoopCommand::AddSubscriber(mut new) => {
                    let out = &mut self.out;
                    // A table changed since the acceptor encoded the Hello follows it; the
                    // running fields' table (which no Hello carries) always does.
                    let table: &[u8] = if new.hello.elements_version() == out.elements_version {
                        &out.elements_frame[out.fields_at..]
                    } else {
                        &out.elements_frame
                    };
                    out.lanes.admit(&mut new, out.seq, table, &out.links.garbage);
                    // What is left (the encoded Hello) is freed elsewhere.
                    let _ = out.links.garbage.try_send(Garbage::Admitted(new));
                }
                LoopCommand::Freeze(ms) => {
                    std::thread::sleep(std::time::Duration::from_millis(u64::from(ms)))
                }
                LoopCommand::ReplaceSource(i, src) => {
                    let Some(hand) = self.hands.get_mut(i) else {
                        let _ = self.out.links.garbage.try_send(Garbage::Source(src));
                        continue;
                    };
                    if let Some(old) = hand.source.replace(src) {
                        let _ = self.out.links.garbage.try_send(Garbage::Source(old));
                    }
                    // Give the reopened device the full stall window before judging it.
                    hand.last_report_ns = now_ns;
                }
            }
        }
    }

    /// Installs, removes or steers a stage and sends a new element table, between two frames;
    /// what it replaces goes back in the command, to housekeeping.
    fn apply_stage(&mut self, mut cmd: Box<StageCommand>) {
        let slot = cmd.slot.min(MAX_STAGES - 1);
        match &mut cmd.action {
            StageAction::Install(stage) => {
                std::mem::swap(&mut self.stages[slot], stage);
                self.stages_every_tick = self.stages.iter().flatten().any(|s| s.every_tick());
                self.stage_hand_element = self.stages.iter().flatten().find_map(|s| s.hand_element());
            }
            StageAction::Input(input) => {
                if let Some(s) = self.stages[slot].as_mut() {
                    s.input(*input);
                }
            }
            StageAction::Announce => {}
        }
        if let Some(frame) = cmd.elements_frame.as_mut() {
            let out = &mut self.out;
            out.lanes.send_table(frame, cmd.elements_version, out.seq, &out.links.garbage);
            std::mem::swap(&mut out.elements_frame, frame);
            out.fields_at = second_frame_at(&out.elements_frame);
            out.elements_version = cmd.elements_version;
            // The slow lane sends it before this frame number too.
            out.links.elements.applied(cmd.elements_version, out.seq);
        }
        cmd.applied.store(true, Release);
        if let Err(e) = self.out.links.garbage.try_send(Garbage::Stage(cmd)) {
            // Housekeeping is gone (shutdown): dropping here is all that is left.
            drop(e.into_inner());
        }
    }

    /// Lets every stage publish its own elements for this tick.
    fn tick_stages(&mut self, now_ns: u64) {
        let primary = &self.hands[self.primary];
        let ctx =
            TickContext { now_ns, device_time_us: primary.last.device_time_us, hand: primary.last_hand };
        let mut sink =
            StageSink { out: &mut self.out, device_time_us: ctx.device_time_us, hand_t: ctx.hand.t };
        for stage in self.stages.iter_mut().flatten() {
            stage.tick(&ctx, &mut sink);
        }
    }

    /// Reads every pending report of hand `i` and publishes one frame per valid report (or,
    /// with [`Reports::Skip`], drops them). Returns the count.
    fn read_device(&mut self, i: usize, now_ns: u64, reports: Reports) -> usize {
        let mut fresh = 0;
        for _ in 0..MAX_READS_PER_TICK {
            let Some(source) = self.hands[i].source.as_mut() else { break };
            match source.read_pending(&mut self.samples) {
                Ok(n) => {
                    if reports == Reports::Publish {
                        for k in 0..n {
                            let sample = self.samples[k];
                            self.publish_sample(i, &sample);
                        }
                    }
                    fresh += n;
                    if n < self.samples.len() {
                        break;
                    }
                }
                Err(_) => {
                    self.lose_source(i, now_ns);
                    break;
                }
            }
        }
        fresh
    }

    fn lose_source(&mut self, i: usize, _now_ns: u64) {
        if let Some(source) = self.hands[i].source.take()
            && let Err(e) = self.out.links.reopen.try_send(LostSource { hand: i, source })
        {
            // The reopen thread is gone (shutdown): keep the source and stay lost.
            self.hands[i].source = Some(e.into_inner().source);
        }
        if !self.hands[i].lost {
            self.set_device_lost(i, true);
        }
    }

    fn set_device_lost(&mut self, i: usize, lost: bool) {
        self.hands[i].lost = lost;
        let stats = &self.out.links.stats.hands[i];
        stats.connected.store(!lost, Relaxed);
        if lost {
            stats.lost_events.fetch_add(1, Relaxed);
            stats.raw.set_stale();
        }
    }

    fn publish_sample(&mut self, i: usize, sample: &DeviceSample) {
        let hand_stats = &self.out.links.stats.hands[i];
        hand_stats.raw.store(sample.raw.t, sample.raw.wrist_deg, sample.raw.thumb_deg);
        hand_stats.frames.fetch_add(1, Relaxed);
        let mut element = self.element_of(i);
        let hand_state = &mut self.hands[i];
        let (hand, mut pose): (HandSample, PoseFrame) = hand_state.mapper.process(&sample.raw);
        let filtered = hand_state.mapper.filter_spec() != FilterSpec::None;
        let discontinuity = hand_state.mapper.discontinuity();
        if discontinuity {
            hand_stats.discontinuities.fetch_add(1, Relaxed);
        }
        if i == self.primary {
            for stage in self.stages.iter_mut().flatten() {
                stage.on_hand(&hand, &mut pose, &mut element);
            }
        }
        let mut flags = PoseFlags::default();
        flags.set(PoseFlags::FILTERED, filtered);
        flags.set(PoseFlags::DISCONTINUITY, discontinuity);
        flags.set(PoseFlags::RECORDING, self.out.recording);
        let frame = Pose {
            seq: 0,
            device_time_us: sample.device_time_us,
            host_monotonic_ns: 0,
            flags,
            element,
            joints_deg: pose.joints_deg,
            hand: HandWire { t: hand.t, wrist_deg: hand.wrist_deg, thumb_deg: hand.thumb_deg },
        };
        self.hands[i].last = frame;
        self.hands[i].last_hand = hand;
        let published = self.out.publish(frame);
        if self.out.recording {
            let take_frame = TakeFrame {
                seq: published.seq,
                device_time_us: published.device_time_us,
                host_ns: published.host_monotonic_ns,
                flags: published.flags.0,
                element,
                pose,
                hand,
            };
            let stats = &self.out.links.stats;
            match self.out.links.recorder.push(take_frame) {
                Ok(()) => stats.recorded_frames.fetch_add(1, Relaxed),
                Err(_) => stats.record_drops.fetch_add(1, Relaxed),
            };
        }
    }

    /// Next sequence number.
    pub fn next_seq(&self) -> u64 {
        self.out.seq
    }

    /// The direct lanes (for tests and the bench).
    pub fn lanes(&self) -> &Lanes {
        &self.out.lanes
    }
}

/// What [`Engine::read_device`] does with the reports it reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reports {
    /// Publish one frame per report.
    Publish,
    /// Drop them (stale after a pause).
    Skip,
}

fn primary_of(hands: &[Hand]) -> usize {
    primary_hand(hands.iter().map(|h| h.element))
}

/// The hand stages act on, given each hand's element in order: the first that drives the
/// global element (0), else the first. The loop and the control side share this rule.
pub fn primary_hand(elements: impl IntoIterator<Item = ElementId>) -> usize {
    elements.into_iter().position(ElementId::is_global).unwrap_or(0)
}
