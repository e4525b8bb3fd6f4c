//! `frond record start NAME --stage STAGE`: records every source of a stage, on this host, each
//! to its own take `NAME-<source>`, with the take writer the daemon uses (`frond-recorder`).
//!
//! The recorder finds the stage's sources by their bridges' liveliness tokens (and keeps looking
//! while it runs, so a performer who joins later gets a take too), measures each source's clock
//! against this host's (`frond_sdk::stage_time`), subscribes with the SDK, and writes what
//! arrives. Each take's recording clock (`TakeHeader::clock`) is put on this host's clock: its
//! `unix_ns` is the first frame's stage time minus the measured offset, beside that frame's
//! monotonic stamp from the source host. So `frond take export --align` (and timecode) puts the
//! takes of one recording on one timeline, even when the performers' clocks disagree; the
//! measured offset and its uncertainty are kept in the header (`TakeHeader::stage`).
//!
//! A take holds what the daemon's own recorder would write: the fresh frames, not the held ones
//! (a tick with no new sample, republished with the last pose and flagged `held`), which are
//! counted instead. So a source's take here and the one its daemon records are the same frame
//! for frame, through a dropout too.
//!
//! It runs in the foreground until Ctrl-C (or SIGTERM, or `--for`), then closes every take and
//! prints what each holds.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

use anyhow::{Context, anyhow, bail};
use crossbeam_channel::bounded;
use frond_motion::take::{TakeClock, TakeHeader, TakeStage};
use frond_protocol::{ElementId, ElementKind, Hello, Pose, PoseFlags};
use frond_recorder::{
    RECORDER_RING_FRAMES, RecorderCounters, RecorderMsg, frame_ring, spawn_recorder, take_frame,
};
use frond_sdk::stage_time::ClockOffset;
use frond_sdk::zenoh_stage::Stage;
use frond_sdk::{Event, SdkError, Subscriber, ZenohAddr};

use crate::control::check_take_name;
use crate::error::{Interrupted, usage};
use crate::global::Global;
use crate::signals;

/// Clock exchanges per source (the shortest round trip wins).
const CLOCK_EXCHANGES: usize = 16;
/// How long a source has to answer the clock queries and the hello.
const SOURCE_TIMEOUT: Duration = Duration::from_secs(10);
/// How often the stage is looked at for sources that joined.
const REDISCOVER: Duration = Duration::from_secs(1);
/// Most takes one stage recording opens.
const MAX_TAKES: usize = 32;

/// What `frond record start` was asked (with `--stage`, a stage recording; without, the
/// daemon's own).
#[derive(Debug, clap::Args)]
pub struct RecordStart {
    /// Take name: letters, digits, '-', '_', '.'.
    pub name: String,
    /// Record every source of this Zenoh stage (its frond-zenoh bridges) instead of the
    /// local daemon; runs in the foreground.
    #[arg(long, value_name = "STAGE")]
    pub stage: Option<String>,
    /// Zenoh endpoint to connect to, e.g. tcp/10.0.0.5:7447 (repeatable; default: find the
    /// bridges by scouting).
    #[arg(long, value_name = "ENDPOINT", requires = "stage")]
    pub connect: Vec<String>,
    /// A Zenoh configuration file (mode, routers, TLS, credentials).
    #[arg(long, value_name = "FILE", requires = "stage")]
    pub zenoh_config: Option<PathBuf>,
    /// Stop after this many seconds (default: at Ctrl-C).
    #[arg(long = "for", value_name = "SECONDS", requires = "stage")]
    pub duration_s: Option<f64>,
    /// How long to wait for the stage's first source, seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0, requires = "stage")]
    pub wait: f64,
}

/// `frond record start --stage STAGE`: the durations checked, then [`run`].
pub(crate) fn start(g: &Global, stage: &str, a: &RecordStart) -> anyhow::Result<()> {
    let seconds = |what: &str, s: f64| match s {
        s if s.is_finite() && s > 0.0 && s <= 7.0 * 86_400.0 => Ok(Duration::from_secs_f64(s)),
        _ => usage(format!("{what} {s}: seconds, more than 0 and at most a week")),
    };
    let duration = a.duration_s.map(|s| seconds("--for", s)).transpose()?;
    let wait = seconds("--wait", a.wait)?;
    run(
        g,
        &StageRecord {
            name: &a.name,
            stage,
            connect: &a.connect,
            zenoh_config: a.zenoh_config.as_deref(),
            duration,
            wait,
        },
    )
}

/// What `frond record start NAME --stage STAGE` was given.
pub(crate) struct StageRecord<'a> {
    /// Take name prefix.
    pub name: &'a str,
    /// Stage name.
    pub stage: &'a str,
    /// Zenoh endpoints to connect to.
    pub connect: &'a [String],
    /// A Zenoh configuration file.
    pub zenoh_config: Option<&'a Path>,
    /// Stop after this long.
    pub duration: Option<Duration>,
    /// How long to wait for the first source.
    pub wait: Duration,
}

/// How one source's take ended.
struct Finished {
    path: PathBuf,
    frames: u64,
    gaps: u64,
    missing: u64,
    /// Poses lost on the way and fetched again from the bridge's replay ring.
    recovered: u64,
    dropped: u64,
    /// Held frames received and not written.
    held: u64,
}

/// Runs the stage recording (see the module doc).
pub(crate) fn run(g: &Global, a: &StageRecord) -> anyhow::Result<()> {
    check_take_name(a.name)?;
    if let Err(e) = frond_sdk::source::check_name("stage", a.stage) {
        return usage(e.to_string());
    }
    let takes_dir = frond_protocol::paths::takes_dir(g.takes_dir.clone());
    std::fs::create_dir_all(&takes_dir).with_context(|| format!("creating {}", takes_dir.display()))?;
    let mut template = ZenohAddr::new(a.stage, "any").map_err(|e| anyhow!("{e}"))?;
    template.connect = a.connect.to_vec();
    template.config = a.zenoh_config.map(Path::to_owned);
    let stage = Stage::open(a.stage, &template)?;
    signals::install().context("installing the signal handlers")?;

    let mut sources = first_sources(&stage, a)?;
    let stop = Arc::new(AtomicBool::new(false));
    let mut takes: BTreeMap<String, JoinHandle<anyhow::Result<Finished>>> = BTreeMap::new();
    let deadline = a.duration.map(|d| Instant::now() + d);
    let mut last_look = Instant::now();
    loop {
        for source in sources.drain(..) {
            if takes.contains_key(&source) {
                continue;
            }
            if takes.len() >= MAX_TAKES {
                frond_binmain::errln!(
                    "frond: warning: stage {}: more than {MAX_TAKES} sources; not recording {source}",
                    a.stage
                );
                continue;
            }
            if let Some(handle) = start_source(&stage, a, &takes_dir, &source, &stop)? {
                takes.insert(source, handle);
            }
        }
        if signals::interrupted() || deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        if takes.values().all(JoinHandle::is_finished) {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
        if last_look.elapsed() >= REDISCOVER {
            last_look = Instant::now();
            match stage.sources(Duration::from_millis(300)) {
                Ok(found) => sources = found,
                Err(e) => frond_binmain::errln!("frond: warning: looking for sources: {e}"),
            }
        }
    }
    stop.store(true, Ordering::SeqCst);
    finish(takes)
}

/// The stage's first sources: waits for at least one, at most `a.wait`.
fn first_sources(stage: &Stage, a: &StageRecord) -> anyhow::Result<Vec<String>> {
    let started = Instant::now();
    let mut sources = Vec::new();
    while sources.is_empty() {
        if signals::interrupted() {
            return Err(Interrupted.into());
        }
        if started.elapsed() >= a.wait {
            bail!(
                "no source on stage {:?} answered within {:?} (is a frond-zenoh bridge running with \
                 --stage {}, and reachable? give --connect tcp/HOST:PORT when scouting cannot find it)",
                a.stage,
                a.wait,
                a.stage
            );
        }
        sources = stage.sources(Duration::from_millis(500))?;
    }
    Ok(sources)
}

/// Starts recording `source` to its take `NAME-<source>` on a thread of its own; `None` (said
/// on stderr) when its clock cannot be read.
fn start_source(
    stage: &Stage,
    a: &StageRecord,
    takes_dir: &Path,
    source: &str,
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<Option<JoinHandle<anyhow::Result<Finished>>>> {
    let offset = match stage.clock_offset(source, CLOCK_EXCHANGES, SOURCE_TIMEOUT) {
        Ok(o) => o,
        Err(e) => {
            frond_binmain::errln!(
                "frond: warning: source {source}: no clock reading ({e}); not recording it"
            );
            return Ok(None);
        }
    };
    let addr = stage.source_addr(source)?;
    let take = format!("{}-{source}", a.name);
    let path = takes_dir.join(format!("{take}.take"));
    frond_binmain::outln!(
        "recording {source} to {} (its clock is {:+.3} ms from this host's, within {:.3} ms)",
        path.display(),
        offset.offset_ns as f64 / 1e6,
        offset.rtt_ns as f64 / 2e6
    )?;
    let job = SourceJob {
        stage: a.stage.to_owned(),
        source: source.to_owned(),
        addr,
        session: stage.session().clone(),
        take,
        path,
        offset,
    };
    let stop = stop.clone();
    let handle = std::thread::Builder::new()
        .name(format!("record-{source}"))
        .spawn(move || job.record(&stop))
        .context("starting a recording thread")?;
    Ok(Some(handle))
}

/// Waits for every source's recording to end and says how each went; an error if any failed.
fn finish(takes: BTreeMap<String, JoinHandle<anyhow::Result<Finished>>>) -> anyhow::Result<()> {
    let mut failed = 0;
    for (source, handle) in takes {
        match handle.join() {
            Ok(Ok(f)) => frond_binmain::outln!(
                "{}: {} frames, {} gaps ({} frames missing), {} recovered, {} dropped, {} held (not written)",
                f.path.display(),
                f.frames,
                f.gaps,
                f.missing,
                f.recovered,
                f.dropped,
                f.held
            )?,
            Ok(Err(e)) => {
                failed += 1;
                frond_binmain::errln!("frond: error: source {source}: {e:#}");
            }
            Err(_) => {
                failed += 1;
                frond_binmain::errln!("frond: error: source {source}: the recording thread panicked");
            }
        }
    }
    if failed > 0 {
        bail!("{failed} of the stage's sources were not recorded completely");
    }
    Ok(())
}

/// One source's take.
struct SourceJob {
    stage: String,
    source: String,
    addr: ZenohAddr,
    /// The stage's one session, shared by every source's subscription.
    session: frond_sdk::zenoh::Session,
    take: String,
    path: PathBuf,
    offset: ClockOffset,
}

impl SourceJob {
    fn record(self, stop: &AtomicBool) -> anyhow::Result<Finished> {
        let opts = Subscriber::options()
            .give_up_after(None)
            .hello_timeout(SOURCE_TIMEOUT)
            .read_timeout(Some(Duration::from_millis(200)))
            // A take must hold every frame: gaps are filled from the bridge's replay ring.
            .reliable(true);
        let mut sub = Subscriber::open_in_session(self.session.clone(), &self.addr, opts)?;
        let status = frond_sdk::zenoh::query_statuses_in(&self.session, &self.addr, Duration::from_secs(2))
            .ok()
            .and_then(|mut found| found.pop())
            .map(|(_, report)| report);
        // The first pose with a stage time fixes the take's clock.
        let (pose, stage_ns) = loop {
            if stop.load(Ordering::SeqCst) {
                bail!("stopped before the first pose arrived");
            }
            match sub.next_event() {
                Ok(Event::Pose(pose)) => {
                    if let Some(stage_ns) = sub.stage_time_ns() {
                        break (pose, stage_ns);
                    }
                    bail!("the bridge of {} does not stamp stage time (an older frond-zenoh?)", self.source);
                }
                Ok(_) | Err(SdkError::Timeout { .. }) => {}
                Err(e) => return Err(e.into()),
            }
        };
        let unix_ns =
            (i128::from(stage_ns) - i128::from(self.offset.offset_ns)).clamp(0, i128::from(u64::MAX));
        let header = self.header(
            sub.hello(),
            status.as_ref(),
            TakeClock { unix_ns: unix_ns as u64, host_ns: pose.host_monotonic_ns },
        );
        let layers = layer_names(sub.hello());

        let (mut ring, frames) = frame_ring(RECORDER_RING_FRAMES);
        let counters = Arc::new(RecorderCounters::default());
        let (tx, rx) = bounded(16);
        let writer = spawn_recorder(rx, frames, counters.clone(), Duration::from_secs(1))
            .context("starting the take writer")?;
        let (reply_tx, reply_rx) = bounded(1);
        tx.send(RecorderMsg::Start {
            path: self.path.clone(),
            header: Box::new(header),
            elements: layers,
            reply: reply_tx,
        })
        .map_err(|_| anyhow!("the take writer stopped"))?;
        reply_rx.recv().map_err(|_| anyhow!("the take writer stopped"))??;

        let (mut dropped, mut held) = (0u64, 0u64);
        let mut push = |pose: &Pose| {
            if pose.element.is_stage() {
                // Above the rig's layers (docs/protocol.md: 0 is the global element, `1..=32` the
                // rig's layers): live stages and field plants are not part of the performer's take.
                return;
            }
            if pose.flags.contains(PoseFlags::HELD) {
                // As the daemon's recorder: a held frame repeats the last pose; not written.
                held += 1;
                return;
            }
            if ring.push(take_frame(pose)).is_err() {
                dropped += 1;
            }
        };
        push(&pose);
        let result = loop {
            if stop.load(Ordering::SeqCst) {
                break Ok(());
            }
            match sub.next_event() {
                Ok(Event::Pose(pose)) => push(&pose),
                Ok(Event::Disconnected) => {
                    frond_binmain::errln!(
                        "frond: warning: {}: the source went away; waiting for it",
                        self.source
                    )
                }
                Ok(Event::Reconnected(_)) => {
                    frond_binmain::errln!("frond: {}: the source is back", self.source)
                }
                Ok(_) | Err(SdkError::Timeout { .. }) => {}
                Err(e) if e.is_fatal() => break Err(anyhow::Error::from(e)),
                Err(e) => frond_binmain::errln!("frond: warning: {}: {e}", self.source),
            }
        };
        let (stop_tx, stop_rx) = bounded(1);
        let _ = tx.send(RecorderMsg::Stop { reply: stop_tx });
        let frames = stop_rx.recv().map_err(|_| anyhow!("the take writer stopped"))??;
        let _ = tx.send(RecorderMsg::Shutdown);
        let _ = writer.join();
        result?;
        let stats = sub.stats();
        Ok(Finished {
            path: self.path,
            frames,
            gaps: stats.gaps,
            missing: stats.missing,
            recovered: stats.recovered,
            dropped,
            held,
        })
    }

    fn header(
        &self,
        hello: &Hello,
        status: Option<&frond_protocol::StatusReport>,
        clock: TakeClock,
    ) -> TakeHeader {
        TakeHeader {
            name: self.take.clone(),
            rig_name: hello.rig_name.clone(),
            calibration_id: status.map_or_else(|| "unknown".into(), |s| s.calibration_id.clone()),
            filter: status.map_or_else(|| "unknown".into(), |s| s.filter.clone()),
            tick_rate_hz: hello.tick_rate_hz,
            created_unix_s: SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0),
            daemon_version: hello.daemon_version.clone(),
            joint_names: hello.joint_names.clone(),
            clock: Some(clock),
            stage: Some(TakeStage {
                stage: self.stage.clone(),
                source: self.source.clone(),
                clock_offset_ns: self.offset.offset_ns,
                clock_uncertainty_ns: self.offset.rtt_ns / 2,
            }),
            stage_clock: None,
        }
    }
}

/// Names of the rig's secondary layers by element id (`k + 1` is layer `k`), from the hello's
/// element table.
fn layer_names(hello: &Hello) -> Vec<String> {
    let mut layers: Vec<(ElementId, String)> = hello
        .elements
        .elements
        .iter()
        .filter(|e| e.kind == ElementKind::Layer && e.id.is_rig_layer())
        .map(|e| (e.id, e.name.clone()))
        .collect();
    layers.sort();
    layers.into_iter().map(|(_, name)| name).collect()
}
