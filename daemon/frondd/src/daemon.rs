//! Starting, running and stopping the daemon: wires config, source, loop, sockets and threads.

use std::os::unix::fs::PermissionsExt;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender, bounded};
use frond_device::HandSource;
use frond_formats::rig_toml::CalibrationText;
use frond_motion::take::TakeFrame;
use frond_motion::{Calibration, FilterSpec, Mapper, Rig};
use frond_protocol::{CONTROL_SOCKET, ElementId, Hello, POSES_SOCKET, PROTOCOL_VERSION, Pose};
use tracing::{error, info, warn};

use crate::config::Config;
use crate::control::{AccessPolicy, ControlContext, DaemonState, HandState, Setup, spawn_control};
use crate::engine::{Engine, EngineEnds, HandInput};
use crate::error::DaemonError;
use crate::handoff::{Garbage, LoopCommand, LostSource, MAX_HANDS, PublisherWake, SlowLane};
use crate::notify::Notifier;
use crate::publisher::{
    HelloSource, PUBLISH_QUEUE_FRAMES, PublisherConfig, SubscriberRegistry, spawn_acceptor, spawn_publisher,
};
use crate::realtime::{lock_memory, spawn_loop};
use crate::recorder::{RecorderCounters, RecorderMsg, spawn_recorder};
use crate::source::{OpenedSource, SourceFactory, open_source};
use crate::stats::LoopStats;

/// Rigs built into the binary, by name.
pub use frond_formats::rig_files::EMBEDDED_RIGS;

/// Reloads the configuration on SIGHUP (re-reads the config file with the same overrides).
pub type ConfigLoader = Box<dyn Fn() -> Result<Config, crate::config::ConfigError> + Send>;

/// How the daemon was started, besides its configuration.
pub struct RunOptions {
    /// Socket and takes directories.
    pub dirs: Dirs,
    /// Set by SIGTERM/SIGINT: stop.
    pub stop: Arc<AtomicBool>,
    /// Set by SIGHUP: reload config, rig, calibration and filter.
    pub reload: Arc<AtomicBool>,
    /// Reads the configuration again.
    pub loader: ConfigLoader,
    /// Enable testing aids (`FreezeLoop`).
    pub test_hooks: bool,
}

/// Where the daemon puts things.
#[derive(Debug, Clone)]
pub struct Dirs {
    /// Socket directory.
    pub socket_dir: PathBuf,
    /// Takes directory.
    pub takes_dir: PathBuf,
}

/// Loads a rig by embedded name or path (the one rig loader, `frond_formats::rig_files`).
pub fn load_rig(spec: &str) -> Result<Rig, DaemonError> {
    Ok(frond_formats::rig_files::load_rig(spec)?.rig)
}

fn load_calibration(path: Option<&Path>, rig: &Rig) -> Result<Calibration, DaemonError> {
    let Some(path) = path else { return Ok(Calibration::neutral_for(rig)) };
    let text = frond_formats::rig_files::read_small_text(path, frond_formats::rig_files::MAX_RIG_FILE_BYTES)
        .map_err(DaemonError::CalibrationFile)?;
    let mut cal = Calibration::from_toml_str(&text)
        .map_err(|source| DaemonError::Calibration { path: path.to_path_buf(), source })?;
    if cal.id.is_empty() {
        cal.id = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    }
    Ok(cal)
}

/// Creates the socket directory (mode 0750) and refuses to start over a running daemon.
fn prepare_socket_dir(dir: &Path) -> Result<(), DaemonError> {
    std::fs::create_dir_all(dir).map_err(DaemonError::io("cannot create socket directory", dir))?;
    let _ = std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o750));
    let control = dir.join(CONTROL_SOCKET);
    if UnixStream::connect(&control).is_ok() {
        return Err(DaemonError::AlreadyRunning(dir.to_path_buf()));
    }
    for name in [CONTROL_SOCKET, POSES_SOCKET] {
        let path = dir.join(name);
        if path.exists() {
            std::fs::remove_file(&path).map_err(DaemonError::io("cannot remove stale socket", &path))?;
        }
    }
    Ok(())
}

/// A socket file this daemon created, known by its inode: the daemon removes it at the end only
/// if it is still that file (a daemon started since in a re-created directory keeps its own).
pub struct OwnedSocket {
    /// Its path.
    pub path: PathBuf,
    dev: u64,
    ino: u64,
}

impl OwnedSocket {
    fn new(path: PathBuf) -> Result<Self, DaemonError> {
        use std::os::unix::fs::MetadataExt;
        let meta = std::fs::symlink_metadata(&path).map_err(DaemonError::io("cannot stat", &path))?;
        Ok(OwnedSocket { path, dev: meta.dev(), ino: meta.ino() })
    }

    /// Whether the path still is the socket this daemon bound.
    pub fn still_ours(&self) -> bool {
        use std::os::unix::fs::MetadataExt;
        std::fs::symlink_metadata(&self.path).is_ok_and(|m| m.dev() == self.dev && m.ino() == self.ino)
    }

    /// Removes the socket file if it still is ours; says what it did.
    pub fn remove_if_ours(&self) -> bool {
        self.still_ours() && std::fs::remove_file(&self.path).is_ok()
    }
}

fn bind(dir: &Path, name: &str) -> Result<(UnixListener, OwnedSocket), DaemonError> {
    let path = dir.join(name);
    let listener = UnixListener::bind(&path).map_err(DaemonError::io("cannot bind", &path))?;
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o660))
        .map_err(DaemonError::io("cannot set the mode of", &path))?;
    Ok((listener, OwnedSocket::new(path)?))
}

/// The filter in force with `rig`: the configuration's override, else the rig's own.
fn filter_for(config: &Config, rig: &Rig) -> Result<FilterSpec, DaemonError> {
    match &config.filter {
        Some(spec) => spec.parse().map_err(|source| DaemonError::Filter { spec: spec.clone(), source }),
        None => Ok(rig.filter),
    }
}

/// A configured hand, resolved against the rigs: its element and, when it has a rig or
/// calibration of its own, that setup.
struct ResolvedHand {
    name: String,
    layer: Option<String>,
    element: ElementId,
    own: Option<Setup>,
}

/// Loads every hand's own rig and calibration and resolves the element each drives; refuses two
/// hands on one element.
fn set_up_hands(config: &Config, rig: &Rig) -> Result<Vec<ResolvedHand>, DaemonError> {
    let mut out: Vec<ResolvedHand> = Vec::with_capacity(config.hands.len());
    for hand in &config.hands {
        let own = if hand.follows_setup() {
            None
        } else {
            let own_rig = match &hand.rig {
                Some(spec) => load_rig(spec)?,
                None => rig.clone(),
            };
            let calibration = load_calibration(hand.calibration.as_deref(), &own_rig)?;
            let filter = filter_for(config, &own_rig)?;
            Some(Setup { rig: own_rig, calibration, filter })
        };
        let hand_rig = own.as_ref().map_or(rig, |o| &o.rig);
        let element = match &hand.element {
            Some(layer) => crate::stage::layer::layer_id(hand_rig, layer).map_err(|message| {
                DaemonError::Hand { hand: hand.name.clone(), message: message.to_string() }
            })?,
            None => ElementId::GLOBAL,
        };
        if let Some(other) = out.iter().find(|o| o.element == element) {
            return Err(DaemonError::Hand {
                hand: hand.name.clone(),
                message: format!(
                    "drives element {element} ({}), as hand {:?} does: give each hand its own element",
                    hand.element.as_deref().unwrap_or("global"),
                    other.name
                ),
            });
        }
        out.push(ResolvedHand { name: hand.name.clone(), layer: hand.element.clone(), element, own });
    }
    Ok(out)
}

/// Runs the daemon until `stop` is set (by SIGTERM/SIGINT in `main`): starts the loop, the
/// recorder and the threads around them, keeps house on this thread, then shuts down in order.
pub fn run(config: Config, options: RunOptions) -> Result<(), DaemonError> {
    let RunOptions { dirs, stop, reload, loader, test_hooks } = options;
    let started = Instant::now();
    let setup = load_setup(&config)?;
    let triggers = crate::trigger_thread::bind_triggers(&config.triggers, config.ltc.fps)?;
    let ltc = crate::ltc_thread::open_ltc(&config.ltc)?;
    prepare_socket_dir(&dirs.socket_dir)?;
    let memory = lock_memory(config.lock_memory);
    let hands = set_up_hands(&config, &setup.rig)?;
    let mut opened = open_sources(&config, &dirs.socket_dir)?;
    let (awaited, awaited_rx) = await_absent(&mut opened);
    let (engine, ends) = Engine::with_hands_and_channels(
        hand_inputs(&hands, &mut opened, &setup),
        config.stall.as_nanos() as u64,
        PUBLISH_QUEUE_FRAMES,
        crate::recorder::RECORDER_RING_FRAMES,
    );
    let EngineEnds {
        commands,
        frames,
        publish_wake,
        slow,
        recorder: recorder_frames,
        reopen,
        garbage,
        stats,
        elements,
    } = ends;
    let (rec_tx, rec_rx) = bounded::<RecorderMsg>(64);
    let realtime = start_realtime(&config, engine, &stats, recorder_frames, rec_rx, &memory)?;
    let state = initial_state(&setup, hands, &opened, &awaited, realtime.tuning.clone(), started);
    let ctx = Arc::new(ControlContext {
        state: Mutex::new(state),
        stats,
        registry: Arc::new(SubscriberRegistry::default()),
        recorder_counters: realtime.recorder_counters.clone(),
        commands: commands.clone(),
        recorder: rec_tx.clone(),
        started,
        takes_dir: dirs.takes_dir.clone(),
        tick_rate_hz: config.tick_rate_hz,
        access: access_policy(&config),
        test_hooks,
        elements_cell: elements,
        recording_session: Mutex::new(()),
        triggers: triggers.as_ref().map(|t| t.link.clone()),
        ltc: ltc.as_ref().map(|l| l.link.clone()),
    });
    // The one path for a rig, calibration and filter: here, on SIGHUP and on `frond rig set`.
    {
        let mut state = ctx.lock();
        ctx.apply_setup(&mut state, setup, true).map_err(|reply| {
            DaemonError::Setup(format!("applying the rig at start-up: {}", reply_text(&reply)))
        })?;
    }
    let serve_ends = ServeEnds { frames, publish_wake, slow, reopen, awaited: awaited_rx };
    let serving = serve(&config, &dirs.socket_dir, &ctx, serve_ends)?;
    let trigger_thread = triggers.map(|t| t.start(&ctx)).transpose()?.flatten();
    let ltc_thread = ltc.map(crate::ltc_thread::BoundLtc::start).transpose()?;

    let notifier = Notifier::from_env();
    notifier.notify(&format!("READY=1\nSTATUS=publishing on {}", dirs.socket_dir.display()));
    info!(socket_dir = %dirs.socket_dir.display(), takes_dir = %dirs.takes_dir.display(), "frondd ready");

    let reload_fn = |ctx: &ControlContext| reload_config(ctx, &loader, &config);
    let sockets = [&serving.pose_socket, &serving.control_socket];
    housekeeping(&ctx, &garbage, &notifier, &stop, &reload, &reload_fn, &sockets);

    notifier.notify("STOPPING=1");
    info!("stopping");
    shut_down(ctx, realtime, serving, (trigger_thread, ltc_thread), (commands, rec_tx), opened)
}

/// The rig, calibration and filter the configuration names.
fn load_setup(config: &Config) -> Result<Setup, DaemonError> {
    let rig = load_rig(&config.rig)?;
    let calibration = load_calibration(config.calibration.as_deref(), &rig)?;
    let filter = filter_for(config, &rig)?;
    Ok(Setup { rig, calibration, filter })
}

/// Opens every configured hand's source (one whose device is absent is awaited, not refused).
fn open_sources(config: &Config, socket_dir: &Path) -> Result<Vec<OpenedSource>, DaemonError> {
    let mut opened = Vec::with_capacity(config.hands.len());
    for (i, hand) in config.hands.iter().enumerate() {
        let source = open_source(config, i, hand, socket_dir)?;
        if source.source.is_some() {
            info!(hand = %hand.name, kind = %source.kind, path = %source.path, "hand source ready");
        }
        opened.push(source);
    }
    Ok(opened)
}

/// Takes the factories of the sources whose device is absent, for the reopen thread: the hands
/// awaited, and the channel that carries their factories.
fn await_absent(opened: &mut [OpenedSource]) -> (Vec<usize>, Receiver<(usize, SourceFactory)>) {
    let (await_tx, await_rx) = bounded::<(usize, SourceFactory)>(MAX_HANDS);
    let mut awaited = Vec::new();
    for (i, o) in opened.iter_mut().enumerate() {
        if let Some(factory) = o.pending.take() {
            let _ = await_tx.send((i, factory));
            awaited.push(i);
        }
    }
    (awaited, await_rx)
}

/// Every hand as the engine takes it: its mapper (its own setup, or the daemon's), its source
/// (taken from `opened`) and its element.
fn hand_inputs(hands: &[ResolvedHand], opened: &mut [OpenedSource], setup: &Setup) -> Vec<HandInput> {
    hands
        .iter()
        .zip(opened.iter_mut())
        .map(|(hand, o)| {
            let own = hand.own.as_ref().unwrap_or(setup);
            HandInput {
                mapper: Mapper::new(own.rig.mapping(), own.calibration.params(), own.filter),
                source: o.source.take(),
                element: hand.element,
                follows_setup: hand.own.is_none(),
            }
        })
        .collect()
}

/// The realtime loop's and the recorder's threads.
struct Realtime {
    /// The loop; gives the engine back when it ends.
    rt: thread::JoinHandle<Engine>,
    /// Set to end the loop.
    stop: Arc<AtomicBool>,
    /// The recorder.
    recorder: thread::JoinHandle<()>,
    /// The recorder's counters, for status.
    recorder_counters: Arc<RecorderCounters>,
    /// How the loop runs (scheduling, memory lock, CPU), for status.
    tuning: String,
}

/// Starts the recorder and the realtime loop (pinned to its CPU, if one is set) and says how the
/// loop runs.
fn start_realtime(
    config: &Config,
    engine: Engine,
    stats: &Arc<LoopStats>,
    recorder_frames: rtrb::Consumer<TakeFrame>,
    recorder_rx: Receiver<RecorderMsg>,
    memory: &str,
) -> Result<Realtime, DaemonError> {
    let recorder_counters = Arc::new(RecorderCounters::default());
    let recorder =
        spawn_recorder(recorder_rx, recorder_frames, recorder_counters.clone(), config.fsync_interval)?;
    let stop = Arc::new(AtomicBool::new(false));
    let (rt, rt_report) =
        spawn_loop(engine, config.tick_rate_hz, config.rt_priority, stats.clone(), stop.clone())?;
    let scheduling = rt_report.recv().unwrap_or_else(|_| "unknown".into());
    let pinning = crate::realtime::pin_thread(&rt, config.rt_cpu);
    info!(rate_hz = config.tick_rate_hz, %scheduling, memory_lock = %memory, cpu = %pinning, "realtime loop running");
    let tuning = format!("scheduling {scheduling}; memory lock {memory}; pinned to {pinning}");
    Ok(Realtime { rt, stop, recorder, recorder_counters, tuning })
}

/// The daemon's state at start-up: the setup, every hand with its first event.
fn initial_state(
    setup: &Setup,
    hands: Vec<ResolvedHand>,
    opened: &[OpenedSource],
    awaited: &[usize],
    realtime: String,
    started: Instant,
) -> DaemonState {
    let mut state = DaemonState {
        rig: setup.rig.clone(),
        calibration: setup.calibration.clone(),
        filter: setup.filter,
        hands: hands
            .into_iter()
            .zip(opened)
            .map(|(hand, o)| HandState {
                name: hand.name,
                kind: o.kind.clone(),
                path: o.path.clone(),
                counters: o.counters.clone(),
                events: Default::default(),
                layer: hand.layer,
                element: hand.element,
                own: hand.own,
            })
            .collect(),
        device_events: Default::default(),
        problems: Vec::new(),
        recording: None,
        achieved_rate_hz: 0.0,
        realtime,
        stages: Default::default(),
        layer_playback: false,
        elements: Default::default(),
    };
    for (i, o) in opened.iter().enumerate() {
        let first_event = if awaited.contains(&i) { "not present; waiting for it" } else { "opened" };
        state.push_event(started, i, format!("{} {} {first_event}", o.kind, o.path));
    }
    state
}

/// Who may use the control socket: this daemon's own user and group, and the configured ones.
fn access_policy(config: &Config) -> AccessPolicy {
    AccessPolicy {
        // SAFETY: geteuid has no preconditions and cannot fail.
        own_uid: unsafe { libc::geteuid() },
        // SAFETY: getegid has no preconditions and cannot fail.
        own_gid: unsafe { libc::getegid() },
        allowed_uids: config.allowed_uids.clone(),
        allowed_gids: config.allowed_gids.clone(),
    }
}

/// The loop's channel ends that the threads around the sockets take.
struct ServeEnds {
    /// Frames for the publisher.
    frames: Receiver<Pose>,
    /// How the loop wakes the publisher.
    publish_wake: Arc<PublisherWake>,
    /// Subscribers moved to the slow lane.
    slow: Receiver<SlowLane>,
    /// Sources the loop lost.
    reopen: Receiver<LostSource>,
    /// Sources absent at start-up, with their factories.
    awaited: Receiver<(usize, SourceFactory)>,
}

/// The threads that serve the sockets and reopen sources, and the sockets they serve.
struct Serving {
    /// Set to end the threads that do not take a peer's pace (accept, control, reopen).
    stop: Arc<AtomicBool>,
    publisher: thread::JoinHandle<()>,
    acceptor: thread::JoinHandle<()>,
    control: thread::JoinHandle<()>,
    reopener: thread::JoinHandle<()>,
    pose_socket: OwnedSocket,
    control_socket: OwnedSocket,
}

/// Binds both sockets and starts the publisher, the acceptor, the control thread and the reopen
/// thread.
fn serve(
    config: &Config,
    socket_dir: &Path,
    ctx: &Arc<ControlContext>,
    ends: ServeEnds,
) -> Result<Serving, DaemonError> {
    let stop = Arc::new(AtomicBool::new(false));
    let (pose_listener, pose_socket) = bind(socket_dir, POSES_SOCKET)?;
    let publisher_config = PublisherConfig {
        queue_frames: config.queue_frames,
        write_timeout: config.write_timeout,
        max_subscribers: config.max_subscribers,
    };
    let publisher = spawn_publisher(
        ends.frames,
        ends.publish_wake,
        ends.slow,
        ctx.elements_cell.clone(),
        publisher_config,
    )?;
    let acceptor = spawn_acceptor(
        pose_listener,
        publisher_config,
        ctx.commands.clone(),
        hello_source(ctx),
        ctx.registry.clone(),
        stop.clone(),
    )?;
    let (control_listener, control_socket) = bind(socket_dir, CONTROL_SOCKET)?;
    let control = spawn_control(control_listener, ctx.clone(), stop.clone())?;
    let reopener =
        spawn_reopener(ends.reopen, ends.awaited, ctx.commands.clone(), ctx.clone(), stop.clone())?;
    Ok(Serving { stop, publisher, acceptor, control, reopener, pose_socket, control_socket })
}

/// The `Hello` a new subscriber gets: the rig and element table in force when it connects.
fn hello_source(ctx: &Arc<ControlContext>) -> HelloSource {
    let ctx = ctx.clone();
    Arc::new(move || {
        let state = ctx.state.lock().unwrap_or_else(|e| e.into_inner());
        Hello {
            protocol_version: PROTOCOL_VERSION,
            daemon_version: env!("CARGO_PKG_VERSION").to_string(),
            rig_name: state.rig.name.clone(),
            joint_names: state.rig.joints.iter().map(|j| j.name.clone()).collect(),
            tick_rate_hz: ctx.tick_rate_hz,
            elements: state.elements.clone(),
            next_seq: 0,
        }
    })
}

/// Shuts down in order: finishes the take first (so every frame the loop produced is in it),
/// stops the loop and the threads, removes the sockets that are still this daemon's, then lets
/// the publisher and the recorder end and the sources close.
fn shut_down(
    ctx: Arc<ControlContext>,
    realtime: Realtime,
    serving: Serving,
    (trigger_thread, ltc_thread): (
        Option<crate::trigger_thread::TriggerThread>,
        Option<crate::ltc_thread::LtcThread>,
    ),
    (commands, rec_tx): (Sender<LoopCommand>, Sender<RecorderMsg>),
    opened: Vec<OpenedSource>,
) -> Result<(), DaemonError> {
    // No trigger may start a take after the last one is finished.
    if let Some(thread) = trigger_thread {
        thread.stop();
    }
    if let Some(thread) = ltc_thread {
        thread.stop();
    }
    if ctx.state.lock().unwrap_or_else(|e| e.into_inner()).recording.is_some() {
        match ctx.handle(frond_protocol::ControlRequest::RecordStop) {
            frond_protocol::ControlReply::Recording(r) => {
                info!(take = %r.name, frames = r.frames, "take finished")
            }
            other => warn!(?other, "finishing the take at shutdown"),
        }
    }
    let Serving { stop, publisher, acceptor, control, reopener, pose_socket, control_socket } = serving;
    realtime.stop.store(true, Relaxed);
    stop.store(true, Relaxed);
    wake_listeners(&[&pose_socket, &control_socket]);
    let engine = realtime.rt.join().map_err(|_| DaemonError::LoopPanicked)?;
    // The threads that take no peer's pace (each ends within its poll of `stop`), then the
    // sockets go: nobody new can connect, whatever the rest of the shutdown meets.
    for (name, handle) in [("accept", acceptor), ("control", control)] {
        if handle.join().is_err() {
            error!(thread = name, "thread panicked");
        }
    }
    for socket in [&pose_socket, &control_socket] {
        if !socket.remove_if_ours() {
            warn!(path = %socket.path.display(), "left the socket alone: it is no longer the one this daemon created");
        }
    }
    // Dropping the engine closes the hand sources (a source with a thread waits for it a
    // bounded time, never on its peer: `frond_device::LeapSource`) and the publisher's queue,
    // so that the publisher (its writes have a timeout) ends.
    drop(engine);
    // The reopener waits on the engine's channel of lost sources, which the drop just closed:
    // joined before it, it would sit out its whole STOP_POLL (half a second of every stop).
    if reopener.join().is_err() {
        error!(thread = "reopen", "thread panicked");
    }
    if publisher.join().is_err() {
        error!(thread = "publish", "thread panicked");
    }
    drop(commands);
    // Control connections still open hold senders of their own: tell the recorder to end.
    let _ = rec_tx.send(crate::recorder::RecorderMsg::Shutdown);
    drop(rec_tx);
    drop(ctx);
    if realtime.recorder.join().is_err() {
        error!("recorder thread panicked");
    }
    drop(opened); // unmounts the virtual glove nodes, if any
    info!("stopped");
    Ok(())
}

/// Connects once to each of the daemon's listening sockets that still is its own, so the threads
/// that wait on them see `stop` at once instead of at their next `STOP_POLL`. (A socket whose
/// path now belongs to another daemon is left alone: its thread sees `stop` at the next poll.)
fn wake_listeners(sockets: &[&OwnedSocket]) {
    for socket in sockets.iter().filter(|s| s.still_ours()) {
        let _ = std::os::unix::net::UnixStream::connect(&socket.path);
    }
}

/// A control reply's message, for errors outside the control socket.
fn reply_text(reply: &frond_protocol::ControlReply) -> String {
    match reply {
        frond_protocol::ControlReply::Error(e) => e.message.clone(),
        other => format!("{other:?}"),
    }
}

/// SIGHUP: re-reads the configuration and applies rig, calibration and filter live, keeping every
/// subscriber connected. Settings that need a restart (rate, source, sockets) are reported.
fn reload_config(ctx: &ControlContext, loader: &ConfigLoader, running: &Config) {
    let config = match loader() {
        Ok(c) => c,
        Err(errors) => {
            for e in &errors.problems {
                error!("reload refused: {e}");
            }
            return;
        }
    };
    let result = (|| -> Result<(), DaemonError> {
        let rig = load_rig(&config.rig)?;
        let calibration = load_calibration(config.calibration.as_deref(), &rig)?;
        let filter = filter_for(&config, &rig)?;
        let text = format!("rig {}, calibration {}, filter {filter}", rig.name, calibration.id);
        let mut state = ctx.lock();
        ctx.apply_setup(&mut state, Setup { rig, calibration, filter }, true)
            .map_err(|reply| DaemonError::Setup(reply_text(&reply)))?;
        info!("configuration reloaded: {text}");
        Ok(())
    })();
    if let Err(e) = result {
        error!("reload failed, keeping the running configuration: {e}");
        return;
    }
    let restart_needed: Vec<&str> = [
        (config.tick_rate_hz != running.tick_rate_hz, "tick_rate_hz"),
        (config.hands != running.hands, "source / hands (sources, their rigs, calibrations and elements)"),
        (config.queue_frames != running.queue_frames, "publisher.queue_frames"),
        (config.ltc != running.ltc, "ltc (input, sample_rate_hz, fps)"),
        (config.triggers != running.triggers, "triggers (listen, allow, lead, honour_delay, timecode_fps)"),
    ]
    .into_iter()
    .filter_map(|(changed, key)| changed.then_some(key))
    .collect();
    if !restart_needed.is_empty() {
        warn!(keys = ?restart_needed, "these settings take effect only after a restart");
    }
}

/// Runs on the main thread until `stop`: achieved rate, device events, garbage, watchdog, reload.
fn housekeeping(
    ctx: &ControlContext,
    garbage: &Receiver<Garbage>,
    notifier: &Notifier,
    stop: &AtomicBool,
    reload: &AtomicBool,
    reload_fn: &dyn Fn(&ControlContext),
    sockets: &[&OwnedSocket],
) {
    let mut keeper = Housekeeper::new(ctx, notifier);
    while !stop.load(Relaxed) {
        // Ten times a second: what it does is for people and for `frond status`, and every
        // wake-up of the daemon costs CPU the realtime loop could use.
        thread::sleep(Duration::from_millis(100));
        if reload.swap(false, Relaxed) {
            notifier.notify("RELOADING=1");
            reload_fn(ctx);
            notifier.notify("READY=1");
        }
        while garbage.try_recv().is_ok() {}
        keeper.tell_device_changes();
        keeper.check_sockets(sockets);
        keeper.tell_time_faults();
        keeper.measure_rate();
        keeper.feed_watchdog();
    }
}

/// What housekeeping remembers from one round to the next, by job.
struct Housekeeper<'a> {
    ctx: &'a ControlContext,
    notifier: &'a Notifier,
    /// Hands in the daemon.
    hands: usize,
    /// Each hand's connection and stall count as last told.
    connected: Vec<bool>,
    stalls: Vec<u64>,
    /// When the sockets were last checked, and whether one was found gone.
    sockets_checked_at: Instant,
    sockets_gone: bool,
    /// Time faults already told, per hand, and when last: one line, then at most one per 10 s.
    time_told: Vec<(u64, u64, Option<Instant>)>,
    /// Refusals already told, per hand.
    refusals_told: Vec<RefusalsTold>,
    /// Ticks and time at the last rate measurement.
    last_ticks: u64,
    last_rate_at: Instant,
    /// Half the service's watchdog interval, if it has one; the last ping and the ticks then.
    watchdog: Option<Duration>,
    last_ping: Instant,
    ticks_at_ping: u64,
}

impl<'a> Housekeeper<'a> {
    fn new(ctx: &'a ControlContext, notifier: &'a Notifier) -> Self {
        let stats = &ctx.stats;
        let hands = ctx.lock().hands.len();
        let last_ticks = stats.ticks.load(Relaxed);
        Housekeeper {
            ctx,
            notifier,
            hands,
            connected: stats.hands[..hands].iter().map(|h| h.connected.load(Relaxed)).collect(),
            stalls: stats.hands[..hands].iter().map(|h| h.stall_events.load(Relaxed)).collect(),
            sockets_checked_at: Instant::now(),
            sockets_gone: false,
            time_told: vec![(0, 0, None); hands],
            refusals_told: vec![RefusalsTold::default(); hands],
            last_ticks,
            last_rate_at: Instant::now(),
            watchdog: notifier.watchdog_interval().map(|d| d / 2),
            last_ping: Instant::now(),
            ticks_at_ping: last_ticks,
        }
    }

    /// Logs and records each hand whose device was lost, stalled or resumed since last round.
    fn tell_device_changes(&mut self) {
        let (ctx, stats) = (self.ctx, &self.ctx.stats);
        for i in 0..self.hands {
            let hand = &stats.hands[i];
            let now_connected = hand.connected.load(Relaxed);
            if now_connected == self.connected[i] {
                continue;
            }
            self.connected[i] = now_connected;
            let new_stalls = hand.stall_events.load(Relaxed);
            let what = if now_connected {
                "device reports resumed"
            } else if new_stalls != self.stalls[i] {
                "device stalled (no reports)"
            } else {
                "device lost"
            };
            self.stalls[i] = new_stalls;
            let mut state = ctx.lock();
            let name = state.hands[i].name.clone();
            if now_connected {
                info!(hand = %name, "{what}")
            } else {
                warn!(hand = %name, "{what}")
            }
            state.push_event(ctx.started, i, what.to_string());
        }
    }

    /// Once a second: whether the sockets are still this daemon's (a deleted directory makes
    /// the daemon unreachable); a problem for `frond status` while one is not.
    fn check_sockets(&mut self, sockets: &[&OwnedSocket]) {
        if self.sockets_checked_at.elapsed() < Duration::from_secs(1) {
            return;
        }
        self.sockets_checked_at = Instant::now();
        let gone = sockets.iter().find(|s| !s.still_ours());
        match (gone, self.sockets_gone) {
            (Some(s), false) => {
                self.sockets_gone = true;
                error!(
                    path = %s.path.display(),
                    "this daemon's socket was removed or replaced (its directory deleted?): new clients cannot reach it; restart frondd"
                );
                self.ctx.lock().problems.push(format!(
                    "socket {} was removed or replaced: new clients cannot connect; restart frondd",
                    s.path.display()
                ));
            }
            (None, true) => {
                self.sockets_gone = false;
                info!("this daemon's sockets are back in place");
                self.ctx.lock().problems.retain(|p| !p.starts_with("socket "));
            }
            _ => {}
        }
    }

    /// Logs and records each hand's new device-time faults, at most once per hand every 10 s.
    fn tell_time_faults(&mut self) {
        let (ctx, stats) = (self.ctx, &self.ctx.stats);
        for (i, told) in self.time_told.iter_mut().enumerate() {
            let hand = &stats.hands[i];
            let now = (hand.discontinuities.load(Relaxed), hand.stale_skipped.load(Relaxed));
            let due = told.2.is_none_or(|at| at.elapsed() >= Duration::from_secs(10));
            if (now.0, now.1) != (told.0, told.1) && due {
                let text = format!(
                    "device time discontinuous {} times (jumped, went back or repeated; filter reset), {} stale reports skipped after pauses",
                    now.0, now.1
                );
                let mut state = ctx.lock();
                warn!(hand = %state.hands[i].name, "{text}");
                state.push_event(ctx.started, i, text);
                *told = (now.0, now.1, Some(Instant::now()));
            }
        }
    }

    /// Once a second: the achieved rate for status, and the sources' refusals told.
    fn measure_rate(&mut self) {
        let elapsed = self.last_rate_at.elapsed();
        if elapsed < Duration::from_secs(1) {
            return;
        }
        tell_refusals(self.ctx, &mut self.refusals_told);
        let ticks = self.ctx.stats.ticks.load(Relaxed);
        let rate = (ticks - self.last_ticks) as f64 / elapsed.as_secs_f64();
        self.ctx.lock().achieved_rate_hz = rate;
        self.last_ticks = ticks;
        self.last_rate_at = Instant::now();
    }

    /// Feeds the service's watchdog only while the loop is really ticking: a hung loop stops
    /// the pings.
    fn feed_watchdog(&mut self) {
        let Some(interval) = self.watchdog else { return };
        let ticks = self.ctx.stats.ticks.load(Relaxed);
        if self.last_ping.elapsed() >= interval && ticks > self.ticks_at_ping {
            self.notifier.notify("WATCHDOG=1");
            self.last_ping = Instant::now();
            self.ticks_at_ping = ticks;
        }
    }
}

/// What a hand's source refused, as last said in the log, and when.
#[derive(Clone, Default)]
struct RefusalsTold {
    said: frond_device::CountersSnapshot,
    at: Option<Instant>,
}

/// Says in the log what each hand's source refused since it last said so, by reason: at most
/// one line per hand per [`crate::log_limit::WINDOW`], whatever a peer sends (the loop and the
/// sources count, they never log a refusal themselves).
fn tell_refusals(ctx: &ControlContext, told: &mut [RefusalsTold]) {
    let state = ctx.lock();
    for (hand, told) in state.hands.iter().zip(told.iter_mut()) {
        if told.at.is_some_and(|at| at.elapsed() < crate::log_limit::WINDOW) {
            continue;
        }
        let now = hand.counters.snapshot();
        if let Some(text) = refusals_since(&told.said, &now) {
            warn!(hand = %hand.name, source = %crate::log_limit::cut(&hand.path), "{text}");
            told.at = Some(Instant::now());
        }
        told.said = now;
    }
}

/// "refused N reports (reason n, ...)" for what `now` counts beyond `before`, with the
/// connections dropped; `None` when nothing is new. A counter that went back (a replaced
/// source starts at zero) counts from zero.
fn refusals_since(
    before: &frond_device::CountersSnapshot,
    now: &frond_device::CountersSnapshot,
) -> Option<String> {
    let new = |b: u64, n: u64| if n >= b { n - b } else { n };
    let reasons: Vec<(&str, u64)> = before
        .by_reason()
        .iter()
        .zip(now.by_reason())
        .map(|(&(_, b), (reason, n))| (reason, new(b, n)))
        .filter(|&(_, n)| n > 0)
        .collect();
    let dropped = new(before.peers_dropped, now.peers_dropped);
    let mut parts = Vec::new();
    if !reasons.is_empty() {
        let total: u64 = reasons.iter().map(|&(_, n)| n).sum();
        let each: Vec<String> = reasons.iter().map(|(reason, n)| format!("{reason} {n}")).collect();
        parts.push(format!("refused {total} reports ({})", each.join(", ")));
    }
    if dropped > 0 {
        parts.push(format!("dropped {dropped} connections to a service that did not read"));
    }
    (!parts.is_empty()).then(|| parts.join("; "))
}

/// A hand source the reopen thread is trying to (re)open.
enum Pending {
    /// Absent at start-up: opened by its factory.
    Awaited { hand: usize, factory: SourceFactory, since: Instant },
    /// Lost by the loop: reopened in place.
    Lost { hand: usize, source: Box<dyn HandSource>, since: Instant, attempts: u64 },
}

/// Hands a (re)opened source to the loop and records the event.
fn hand_back(
    commands: &Sender<LoopCommand>,
    ctx: &ControlContext,
    hand: usize,
    source: Box<dyn HandSource>,
    text: String,
) {
    {
        let mut state = ctx.lock();
        let name = state.hands.get(hand).map(|h| h.name.clone()).unwrap_or_default();
        info!(hand = %name, "{text}");
        if let Some(h) = state.hands.get_mut(hand) {
            h.counters = source.counters();
            h.kind = source.kind().to_string();
            h.path = source.describe().to_string();
        }
        state.push_event(ctx.started, hand, text);
    }
    if commands.send_timeout(LoopCommand::ReplaceSource(hand, source), Duration::from_secs(1)).is_err() {
        warn!(hand, "the loop did not take the device");
    }
}

/// Reopens lost sources off the realtime thread, each every 100 ms, and hands them back to the
/// loop; also opens devices that were absent at start-up. Several hands are retried side by
/// side: one that stays away never delays another's return.
fn spawn_reopener(
    rx: Receiver<LostSource>,
    awaited: Receiver<(usize, SourceFactory)>,
    commands: Sender<LoopCommand>,
    ctx: Arc<ControlContext>,
    stop: Arc<AtomicBool>,
) -> std::io::Result<thread::JoinHandle<()>> {
    thread::Builder::new().name("frond-reopen".into()).spawn(move || {
        let mut pending: Vec<Pending> = awaited
            .try_iter()
            .map(|(hand, factory)| Pending::Awaited { hand, factory, since: Instant::now() })
            .collect();
        while !stop.load(Relaxed) {
            // Wait for a newly lost source: 100 ms before the next attempt while some are
            // pending, else until one is lost (or `STOP_POLL`). The loop's end closes the
            // channel at shutdown.
            let wait =
                if pending.is_empty() { crate::publisher::STOP_POLL } else { Duration::from_millis(100) };
            match rx.recv_timeout(wait) {
                Ok(lost) => pending.push(Pending::Lost {
                    hand: lost.hand,
                    source: lost.source,
                    since: Instant::now(),
                    attempts: 0,
                }),
                Err(crossbeam_channel::RecvTimeoutError::Disconnected) => break,
                Err(crossbeam_channel::RecvTimeoutError::Timeout) => {}
            }
            let mut still = Vec::with_capacity(pending.len());
            for p in pending.drain(..) {
                match p {
                    Pending::Awaited { hand, mut factory, since } => match factory() {
                        Ok(source) => {
                            let text = format!(
                                "{} {} appeared after {:.1} s",
                                source.kind(),
                                source.describe(),
                                since.elapsed().as_secs_f64()
                            );
                            hand_back(&commands, &ctx, hand, source, text);
                        }
                        Err(_) => still.push(Pending::Awaited { hand, factory, since }),
                    },
                    Pending::Lost { hand, mut source, since, attempts } => match source.reopen() {
                        Ok(()) => {
                            let text = format!(
                                "device reopened after {:.0} ms ({} attempts)",
                                since.elapsed().as_secs_f64() * 1000.0,
                                attempts + 1
                            );
                            hand_back(&commands, &ctx, hand, source, text);
                        }
                        Err(_) => still.push(Pending::Lost { hand, source, since, attempts: attempts + 1 }),
                    },
                }
            }
            pending = still;
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_are_said_by_reason_once_each() {
        let before = frond_device::CountersSnapshot { malformed: 2, too_many: 1, ..Default::default() };
        let now = frond_device::CountersSnapshot {
            malformed: 5,
            too_many: 4001,
            oversized: 1,
            peers_dropped: 2,
            ..Default::default()
        };
        assert_eq!(
            refusals_since(&before, &now).as_deref(),
            Some(
                "refused 4004 reports (oversized 1, malformed 3, too_many 4000); dropped 2 connections to a service that did not read"
            )
        );
        assert_eq!(refusals_since(&now, &now), None);
        // A replaced source counts from zero again.
        let fresh = frond_device::CountersSnapshot { malformed: 1, ..Default::default() };
        assert_eq!(refusals_since(&now, &fresh).as_deref(), Some("refused 1 reports (malformed 1)"));
    }
}
