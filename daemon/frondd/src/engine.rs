//! The realtime loop's per-tick work, separate from the thread that paces it so that tests can
//! drive it tick by tick (the counting-allocator test does).
//!
//! One tick: apply pending commands, read every pending device report, and for each report
//! calibrate -> filter -> map (the same [`Mapper::process`] as `frond map`) and publish a frame;
//! when no report arrived, republish the last pose flagged `held`. Frames go to the publisher
//! thread and to the recorder with `try_send` on bounded queues; a full queue costs a frame
//! (counted), never the loop a wait. Nothing here allocates, locks or blocks.

use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;

use crossbeam_channel::{Receiver, Sender};
use frond_device::{DeviceSample, HandSource};
use frond_motion::take::TakeFrame;
use frond_motion::{CalibrationParams, FilterSpec, HandSample, Mapper, MappingParams, PoseFrame};
use frond_protocol::{HandWire, Pose, PoseFlags};

use crate::clock::{NS_PER_S, monotonic_ns};
use crate::lanes::{Lane, Lanes, NewLane, SlowLane};
use crate::live::{FIELD_PUBLISH_HZ, LiveField, LivePlayback, MAX_FIELD_PLANTS};
use crate::publisher::PublishQueue;
use crate::recorder::RecorderMsg;
use crate::stats::LoopStats;
use frond_motion::controls::ControlKey;
use frond_motion::guided::GuidedLive;
use frond_protocol::FIELD_ELEMENT_BASE;

/// Most subscribers served at once.
pub const MAX_SUBSCRIBERS: usize = 64;
/// Reports read from the device per `read_pending` call.
const SAMPLE_BATCH: usize = 64;
/// `read_pending` calls per tick at most (a burst beyond this waits for the next tick).
const MAX_READS_PER_TICK: usize = 16;

/// Requests to the loop from the control and housekeeping threads.
pub enum LoopCommand {
    /// New mapping scales and tau (from a rig).
    SetMapping(MappingParams),
    /// New calibration.
    SetCalibration(CalibrationParams),
    /// New jitter filter (state is reset).
    SetFilter(FilterSpec),
    /// Start or stop forwarding frames to the recorder.
    SetRecording(bool),
    /// A (re)opened hand source.
    ReplaceSource(Box<dyn HandSource>),
    /// Testing aid (`frondd --test-hooks`): block the loop for this many milliseconds, as a hung
    /// loop would, so tests can check that the watchdog pings stop.
    Freeze(u32),
    /// Loop a take on the stream as element 0 (or stop, with `None`).
    SetPlayback(Option<Box<LivePlayback>>),
    /// Play a field (or stop, with `None`).
    SetField(Option<Box<LiveField>>),
    /// A field control key.
    FieldKey(ControlKey),
    /// Guided procedural motion on the live mapping (or off, with `None`).
    SetGuided(Option<Box<GuidedLive>>),
    /// Element id of the hand's frames: 0 for the global element, `k + 1` for a secondary layer.
    SetLayer(u16),
    /// A new pose subscriber, for a direct lane (see [`crate::lanes`]).
    AddSubscriber(Box<NewLane>),
}

/// Things the loop must not drop itself (dropping may free memory): handed to housekeeping.
pub enum Garbage {
    /// A source replaced by a newer one.
    Source(Box<dyn HandSource>),
    /// A finished playback, field or guided stage.
    Live(Box<dyn std::any::Any + Send>),
    /// A subscriber that left its direct lane (hung up, or no room anywhere).
    Lane(Lane),
}

/// Channels and shared state the engine talks through.
pub struct EngineLinks {
    /// Commands in.
    pub commands: Receiver<LoopCommand>,
    /// Frames out, to the publisher thread.
    pub publish: PublishQueue,
    /// Subscribers moved off their direct lane, to the publisher thread.
    pub slow: Sender<SlowLane>,
    /// Frames (and nothing else from the loop) to the recorder.
    pub recorder: Sender<RecorderMsg>,
    /// A source that failed, for the reopen thread.
    pub reopen: Sender<Box<dyn HandSource>>,
    /// Things to drop elsewhere.
    pub garbage: Sender<Garbage>,
    /// Counters read by status.
    pub stats: Arc<LoopStats>,
}

/// The far ends of an engine's channels, from [`Engine::with_channels`].
pub struct EngineEnds {
    /// Send commands to the loop.
    pub commands: Sender<LoopCommand>,
    /// Frames the loop publishes.
    pub frames: Receiver<Pose>,
    /// Wakes whoever waits on `frames` through it (see [`crate::publisher::spawn_publisher`]).
    pub publish_wake: Arc<crate::publisher::PublisherWake>,
    /// Subscribers the loop moved to the slow lane.
    pub slow: Receiver<SlowLane>,
    /// Frames the loop hands to the recorder.
    pub recorder: Receiver<RecorderMsg>,
    /// Sources the loop gives up as lost.
    pub reopen: Receiver<Box<dyn HandSource>>,
    /// What the loop may not drop itself.
    pub garbage: Receiver<Garbage>,
    /// The loop's counters.
    pub stats: Arc<LoopStats>,
}

/// The realtime loop's state. Allocates only in [`Engine::new`].
pub struct Engine {
    mapper: Mapper,
    source: Option<Box<dyn HandSource>>,
    samples: Box<[DeviceSample]>,
    lanes: Lanes,
    links: EngineLinks,
    recording: bool,
    seq: u64,
    last: Pose,
    last_report_ns: u64,
    stall_after_ns: u64,
    device_lost: bool,
    playback: Option<Box<LivePlayback>>,
    field: Option<Box<LiveField>>,
    guided: Option<Box<GuidedLive>>,
    layer: u16,
    /// Reports published by [`Engine::device_ready`] since the last tick.
    fresh_since_tick: usize,
}

impl Engine {
    /// A new engine with the given mapper and (optional) source.
    pub fn new(
        mapper: Mapper,
        source: Option<Box<dyn HandSource>>,
        stall_after_ns: u64,
        links: EngineLinks,
    ) -> Self {
        let now = monotonic_ns();
        let device_lost = source.is_none();
        links.stats.device_connected.store(!device_lost, Relaxed);
        let mut last = Pose::default();
        last.flags.set(PoseFlags::DEVICE_LOST, device_lost);
        Engine {
            mapper,
            source,
            samples: vec![DeviceSample::default(); SAMPLE_BATCH].into_boxed_slice(),
            lanes: Lanes::new(links.slow.clone(), links.publish.wake()),
            links,
            recording: false,
            seq: 0,
            last,
            last_report_ns: now,
            stall_after_ns,
            device_lost,
            playback: None,
            field: None,
            guided: None,
            layer: 0,
            fresh_since_tick: 0,
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
        let (cmd_tx, cmd_rx) = crossbeam_channel::bounded(256);
        let (publish, frames) = PublishQueue::new(publish_frames);
        let (rec_tx, rec_rx) = crossbeam_channel::bounded(recorder_frames);
        let (reopen_tx, reopen_rx) = crossbeam_channel::bounded(1);
        let (garbage_tx, garbage_rx) = crossbeam_channel::bounded(256);
        let (slow_tx, slow_rx) = crossbeam_channel::bounded(MAX_SUBSCRIBERS);
        let stats = Arc::new(LoopStats::default());
        let publish_wake = publish.wake();
        let links = EngineLinks {
            commands: cmd_rx,
            publish,
            slow: slow_tx,
            recorder: rec_tx,
            reopen: reopen_tx,
            garbage: garbage_tx,
            stats: stats.clone(),
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
        };
        (Engine::new(mapper, source, stall_after_ns, links), ends)
    }

    fn discard<T: Send + 'static>(&self, old: Option<Box<T>>) {
        if let Some(old) = old {
            let _ = self.links.garbage.try_send(Garbage::Live(old));
        }
    }

    /// The source's ready descriptor (see [`HandSource::ready_fd`]), if it has one.
    pub fn ready_fd(&self) -> Option<std::os::fd::RawFd> {
        self.source.as_ref()?.ready_fd()
    }

    /// Whether every tick does work of its own (a looped take or a field is playing), so that a
    /// tick may not be skipped even when a report already covered its period.
    pub fn needs_every_tick(&self) -> bool {
        self.playback.is_some() || self.field.is_some()
    }

    /// Between ticks, when the source's ready descriptor woke the loop: applies pending commands
    /// and publishes every pending report at once, instead of at the next tick. Returns the
    /// number of reports published; the next [`Engine::tick`] counts them as fresh, so it
    /// publishes no held frame for the period they arrived in.
    pub fn device_ready(&mut self, now_ns: u64) -> usize {
        self.apply_commands(now_ns);
        let fresh = self.read_device(now_ns);
        self.note_fresh(fresh, now_ns);
        self.fresh_since_tick += fresh;
        fresh
    }

    /// The loop's bookkeeping after a [`Engine::device_ready`] that published reports, when
    /// [`Engine::needs_every_tick`] is false: the reports belong to a period whose tick is
    /// covered by them, so they must not count for the next tick. `count_tick` when this
    /// covers the upcoming tick (the loop then skips it and waits for the one after).
    pub fn cover_tick(&mut self, count_tick: bool) {
        self.fresh_since_tick = 0;
        if count_tick {
            self.links.stats.ticks.fetch_add(1, Relaxed);
        }
    }

    fn note_fresh(&mut self, fresh: usize, now_ns: u64) {
        if fresh > 0 {
            self.last_report_ns = now_ns;
            if self.device_lost {
                self.set_device_lost(false);
            }
        }
    }

    /// Runs one tick at host time `now_ns`. Publishes at least one frame.
    pub fn tick(&mut self, now_ns: u64) {
        self.apply_commands(now_ns);
        self.play_live(now_ns);
        let read = self.read_device(now_ns);
        self.note_fresh(read, now_ns);
        let fresh = read + std::mem::take(&mut self.fresh_since_tick);
        if fresh == 0 {
            let stalled =
                self.source.is_some() && now_ns.saturating_sub(self.last_report_ns) > self.stall_after_ns;
            if stalled && !self.device_lost {
                self.links.stats.stall_events.fetch_add(1, Relaxed);
                self.set_device_lost(true);
            }
            self.links.stats.held_ticks.fetch_add(1, Relaxed);
            let mut held = self.last;
            held.flags.insert(PoseFlags::HELD);
            held.flags.set(PoseFlags::DEVICE_LOST, self.device_lost);
            held.flags.set(PoseFlags::RECORDING, self.recording);
            self.publish(held);
        }
        self.links.stats.ticks.fetch_add(1, Relaxed);
    }

    fn apply_commands(&mut self, now_ns: u64) {
        while let Ok(cmd) = self.links.commands.try_recv() {
            match cmd {
                LoopCommand::SetMapping(m) => self.mapper.set_mapping(m),
                LoopCommand::SetCalibration(c) => self.mapper.set_calibration(c),
                LoopCommand::SetFilter(f) => self.mapper.set_filter(f),
                LoopCommand::SetRecording(on) => {
                    self.recording = on;
                    self.links.stats.recording.store(on, Relaxed);
                }
                LoopCommand::SetPlayback(p) => {
                    let old = std::mem::replace(&mut self.playback, p);
                    self.discard(old);
                }
                LoopCommand::SetField(f) => {
                    let old = std::mem::replace(&mut self.field, f);
                    self.discard(old);
                    self.publish_field_controls();
                }
                LoopCommand::FieldKey(key) => {
                    if let Some(f) = self.field.as_mut() {
                        let mut c = f.player.controls();
                        c.key(key);
                        f.player.set_controls(c);
                    }
                    self.publish_field_controls();
                }
                LoopCommand::SetGuided(g) => {
                    let old = std::mem::replace(&mut self.guided, g);
                    self.discard(old);
                }
                LoopCommand::SetLayer(layer) => self.layer = layer,
                LoopCommand::AddSubscriber(mut new) => {
                    self.lanes.admit(&mut new, self.seq, &self.links.garbage);
                    // What is left (the encoded Hello) is freed elsewhere.
                    let _ = self.links.garbage.try_send(Garbage::Live(new));
                }
                LoopCommand::Freeze(ms) => {
                    std::thread::sleep(std::time::Duration::from_millis(u64::from(ms)))
                }
                LoopCommand::ReplaceSource(src) => {
                    if let Some(old) = self.source.replace(src) {
                        let _ = self.links.garbage.try_send(Garbage::Source(old));
                    }
                    // Give the reopened device the full stall window before judging it.
                    self.last_report_ns = now_ns;
                }
            }
        }
    }

    /// Publishes the looped take's pose (every tick) and field plants (at [`FIELD_PUBLISH_HZ`]).
    fn play_live(&mut self, now_ns: u64) {
        let recording = self.recording;
        let device_time_us = self.last.device_time_us;
        let frame = |element: u16, joints_deg: [[f32; 3]; 4]| {
            let mut flags = PoseFlags::PLAYBACK;
            flags.set(PoseFlags::RECORDING, recording);
            Pose { element, joints_deg, flags, device_time_us, ..Pose::default() }
        };
        if let Some(pb) = self.playback.as_mut() {
            let t = now_ns.saturating_sub(pb.t0_ns) as f64 / NS_PER_S as f64;
            let joints = pb.playback.pose_at(t);
            self.publish(frame(0, joints));
        }
        let mut plants = [[[0.0f32; 3]; 4]; MAX_FIELD_PLANTS];
        let mut n = 0;
        if let Some(f) = self.field.as_mut()
            && now_ns >= f.next_ns
        {
            let period = NS_PER_S / u64::from(FIELD_PUBLISH_HZ);
            f.next_ns = (f.next_ns + period).max(now_ns);
            let t = now_ns.saturating_sub(f.t0_ns) as f64 / NS_PER_S as f64;
            f.player.frame(t, &mut f.out);
            n = f.publish;
            plants[..n].copy_from_slice(&f.out[..n]);
        }
        for (i, joints) in plants[..n].iter().enumerate() {
            self.publish(frame(FIELD_ELEMENT_BASE + i as u16, *joints));
        }
    }

    fn publish_field_controls(&self) {
        let c = self.field.as_ref().map(|f| f.player.controls());
        self.links.stats.field_controls.store(c);
    }

    /// Reads every pending report and publishes one frame per valid report. Returns the count.
    fn read_device(&mut self, now_ns: u64) -> usize {
        let mut fresh = 0;
        for _ in 0..MAX_READS_PER_TICK {
            let Some(source) = self.source.as_mut() else { break };
            match source.read_pending(&mut self.samples) {
                Ok(n) => {
                    for i in 0..n {
                        let sample = self.samples[i];
                        self.publish_sample(&sample);
                    }
                    fresh += n;
                    if n < self.samples.len() {
                        break;
                    }
                }
                Err(_) => {
                    self.lose_source(now_ns);
                    break;
                }
            }
        }
        fresh
    }

    fn lose_source(&mut self, _now_ns: u64) {
        if let Some(src) = self.source.take()
            && let Err(e) = self.links.reopen.try_send(src)
        {
            // The reopen thread is gone (shutdown): keep the source and stay lost.
            self.source = Some(e.into_inner());
        }
        if !self.device_lost {
            self.set_device_lost(true);
        }
    }

    fn set_device_lost(&mut self, lost: bool) {
        self.device_lost = lost;
        self.links.stats.device_connected.store(!lost, Relaxed);
        if lost {
            self.links.stats.device_lost_events.fetch_add(1, Relaxed);
            self.links.stats.raw.set_stale();
        }
    }

    fn publish_sample(&mut self, sample: &DeviceSample) {
        self.links.stats.raw.store(sample.raw.t, sample.raw.wrist_deg, sample.raw.thumb_deg);
        let (hand, mut pose): (HandSample, PoseFrame) = self.mapper.process(&sample.raw);
        if let Some(g) = self.guided.as_mut() {
            pose = g.apply(&pose, &hand);
        }
        if let Some(f) = self.field.as_mut()
            && let Some(swipe) = f.swipe.push(&hand)
        {
            let mut c = f.player.controls();
            c.swipe(&swipe, f.base_speed_m_s);
            f.player.set_controls(c);
            self.links.stats.field_controls.store(Some(c));
        }
        let mut flags = PoseFlags::default();
        flags.set(PoseFlags::FILTERED, self.mapper.filter_spec() != FilterSpec::None);
        flags.set(PoseFlags::RECORDING, self.recording);
        let frame = Pose {
            seq: 0,
            device_time_us: sample.device_time_us,
            host_monotonic_ns: 0,
            flags,
            element: self.layer,
            joints_deg: pose.joints_deg,
            hand: HandWire { t: hand.t, wrist_deg: hand.wrist_deg, thumb_deg: hand.thumb_deg },
        };
        self.last = frame;
        let published = self.publish(frame);
        if self.recording {
            let take_frame = TakeFrame {
                seq: published.seq,
                device_time_us: published.device_time_us,
                host_ns: published.host_monotonic_ns,
                flags: published.flags.0,
                element: self.layer,
                pose,
                hand,
            };
            match self.links.recorder.try_send(RecorderMsg::Frame(take_frame)) {
                Ok(()) => {
                    self.links.stats.recorded_frames.fetch_add(1, Relaxed);
                }
                Err(_) => {
                    self.links.stats.record_drops.fetch_add(1, Relaxed);
                }
            }
        }
    }

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

    /// Next sequence number.
    pub fn next_seq(&self) -> u64 {
        self.seq
    }

    /// The direct lanes (for tests and the bench).
    pub fn lanes(&self) -> &Lanes {
        &self.lanes
    }
}
