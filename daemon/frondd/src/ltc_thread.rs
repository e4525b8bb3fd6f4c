//! The `frond-ltc` thread: the stage's timecode from LTC audio (issue 46), decoded off the
//! realtime thread.
//!
//! It owns the input (`ltc_input`: a FIFO a capture streams into, or a file played as the
//! stage's clock; `ltc_alsa`: an ALSA capture device), reads it in chunks of [`CHUNK_MS`] (a
//! FIFO or a device as the samples come, waiting at most [`LTC_POLL`]; a file paced in real
//! time), feeds [`LtcDecoder`], and maps each frame's end to CLOCK_MONOTONIC: the time its
//! chunk was read, less the samples after the frame's end (read, or still waiting in the FIFO
//! or the device's buffer) at the sample rate. The stage clock and the state
//! (searching, locked, lost, ended) go to [`LtcLink`], which status and a take's start read.
//! It never touches the realtime loop, logs loss and jumps at most 10 times in 10 s, and ends
//! within [`LTC_POLL`] of `stop`.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::thread;
use std::time::Duration;

use frond_ltc::{FrameRate, LtcDecoder, LtcEvent};
use tracing::{info, warn};

use crate::clock::monotonic_ns;
use crate::config::LtcConfig;
use crate::error::DaemonError;
use crate::log_limit::LogLimit;
use crate::ltc_alsa::AlsaCapture;
use crate::ltc_input::{InputKind, LtcInput, LtcInputError, LtcSource, Read16};
use crate::ltc_link::{LtcLink, LtcState, MAX_EXTRAPOLATION_NS};

/// Longest wait for input: how soon the thread sees `stop`.
pub const LTC_POLL: Duration = Duration::from_millis(100);

/// Longest wait for the thread at shutdown.
pub const STOP_WAIT: Duration = Duration::from_secs(1);

/// Samples read at most at a time, in milliseconds of audio (a quarter of a frame at 25 fps).
pub const CHUNK_MS: u32 = 10;

/// The input opened at start-up (so a bad path fails the start) and what status shows.
pub struct BoundLtc {
    /// Shared with the control context.
    pub link: Arc<LtcLink>,
    input: Input,
    expected: Option<FrameRate>,
    /// The input as configured, for logs.
    name: String,
}

/// An open input of either kind.
enum Input {
    /// A file or FIFO.
    Fd(LtcInput),
    /// An ALSA capture device.
    Alsa(AlsaCapture),
}

impl Input {
    fn open(source: &LtcSource, sample_rate_hz: u32) -> Result<Input, LtcInputError> {
        Ok(match source {
            LtcSource::Path(path) => Input::Fd(LtcInput::open(path, sample_rate_hz)?),
            LtcSource::Alsa(device) => Input::Alsa(AlsaCapture::open(device, sample_rate_hz)?),
        })
    }

    /// What it is, for the log.
    fn kind(&self) -> &'static str {
        match self {
            Input::Fd(input) if input.kind() == InputKind::Fifo => "FIFO",
            Input::Fd(_) => "file",
            Input::Alsa(_) => "ALSA capture device",
        }
    }

    fn sample_rate_hz(&self) -> u32 {
        match self {
            Input::Fd(input) => input.sample_rate_hz(),
            Input::Alsa(capture) => capture.rate_hz(),
        }
    }

    /// Reads into `out` (a device's read waits for its samples; a closed device sleeps up
    /// to [`LTC_POLL`] before it is tried again).
    fn read(&mut self, out: &mut [i16]) -> Result<Read16, String> {
        match self {
            Input::Fd(input) => input.read(out).map_err(|e| e.to_string()),
            Input::Alsa(capture) => match capture.read(out, LTC_POLL) {
                Ok(0) => Ok(Read16::Nothing),
                Ok(n) => Ok(Read16::Samples(n)),
                Err(e) => Err(e.to_string()),
            },
        }
    }

    fn queued_samples(&self) -> u64 {
        match self {
            Input::Fd(input) => input.queued_samples(),
            Input::Alsa(capture) => capture.queued_samples(),
        }
    }
}

/// A running LTC thread.
pub struct LtcThread {
    stop: Arc<AtomicBool>,
    handle: thread::JoinHandle<()>,
}

impl LtcThread {
    /// Ends the thread (within [`LTC_POLL`]) and waits for it, at most [`STOP_WAIT`]: an input
    /// whose read blocks anyway (an ALSA plugin reading a stalled pipe) must not keep the
    /// daemon from stopping, so such a thread is left to end with the process, and said.
    pub fn stop(self) {
        self.stop.store(true, Relaxed);
        match frond_device::join::join_within(self.handle, STOP_WAIT) {
            None => {
                warn!(thread = "frond-ltc", "did not stop within 1 s (its input's read blocks); leaving it")
            }
            Some(Err(_)) => tracing::error!(thread = "frond-ltc", "thread panicked"),
            Some(Ok(())) => {}
        }
    }
}

/// Opens what `config` names: `None` without `ltc.input`.
pub fn open_ltc(config: &LtcConfig) -> Result<Option<BoundLtc>, DaemonError> {
    let Some(source) = &config.input else { return Ok(None) };
    let input = Input::open(source, config.sample_rate_hz)?;
    let link = Arc::new(LtcLink::new(&source.to_string(), input.sample_rate_hz()));
    info!(
        input = %source,
        kind = input.kind(),
        sample_rate_hz = input.sample_rate_hz(),
        expected_fps = ?config.fps.map(|r| r.to_string()),
        "reading the stage's timecode (LTC)"
    );
    Ok(Some(BoundLtc { link, input, expected: config.fps, name: source.to_string() }))
}

impl BoundLtc {
    /// Starts the `frond-ltc` thread.
    pub fn start(self) -> Result<LtcThread, DaemonError> {
        let stop = Arc::new(AtomicBool::new(false));
        let rate = self.input.sample_rate_hz();
        let name = self.name;
        let decoder = LtcDecoder::new(rate).map_err(|e| {
            DaemonError::Ltc(LtcInputError::Format { path: name.clone().into(), why: e.to_string() })
        })?;
        let chunk = (rate * CHUNK_MS / 1000) as usize;
        let mut reader = LtcReader {
            name,
            input: self.input,
            decoder,
            link: self.link,
            expected: self.expected,
            buf: vec![0; chunk],
            events: Vec::with_capacity(64),
            fed: 0,
            locked: None,
            last_frame_ns: None,
            stalls: 0,
            carried: frond_ltc::LtcCounters::default(),
            file_start_ns: None,
            file_samples: 0,
            ended: false,
        };
        let flag = stop.clone();
        let handle = thread::Builder::new().name("frond-ltc".into()).spawn(move || {
            while !flag.load(Relaxed) {
                reader.step();
            }
        })?;
        Ok(LtcThread { stop, handle })
    }
}

/// The reader and its bookkeeping.
struct LtcReader {
    /// The input as configured, for logs.
    name: String,
    input: Input,
    decoder: LtcDecoder,
    link: Arc<LtcLink>,
    expected: Option<FrameRate>,
    buf: Vec<i16>,
    events: Vec<LtcEvent>,
    /// Samples given to `decoder` (its sample positions count from its first).
    fed: u64,
    /// The rate the decoder is locked at, if it is (at the expected rate, if one is set).
    locked: Option<FrameRate>,
    /// Monotonic ns the last frame ended at.
    last_frame_ns: Option<u64>,
    /// Locks lost because the input stopped (the decoder counts the others).
    stalls: u64,
    /// The counts of decoders replaced after a stall.
    carried: frond_ltc::LtcCounters,
    /// A file: when its first sample was read (pacing counts from it), and samples read since.
    file_start_ns: Option<u64>,
    file_samples: u64,
    /// A file read to its end.
    ended: bool,
}

impl LtcReader {
    /// One wait and one read, at most [`LTC_POLL`] long.
    fn step(&mut self) {
        if self.ended {
            thread::sleep(LTC_POLL);
            return;
        }
        match &self.input {
            Input::Fd(input) if input.kind() == InputKind::Fifo => input.wait(LTC_POLL),
            Input::Fd(_) => {
                if !self.file_due() {
                    return;
                }
            }
            // The read waits for the device.
            Input::Alsa(_) => {}
        }
        match self.input.read(&mut self.buf) {
            Ok(Read16::Samples(n)) => {
                let now = monotonic_ns();
                if matches!(&self.input, Input::Fd(i) if i.kind() == InputKind::File)
                    && self.file_start_ns.is_none()
                {
                    // The first chunk's last sample plays now: sample `s` at start + s / rate.
                    let rate = u64::from(self.input.sample_rate_hz());
                    self.file_start_ns = Some(now.saturating_sub(n as u64 * 1_000_000_000 / rate));
                }
                self.file_samples += n as u64;
                let queued = self.input.queued_samples();
                self.feed(n, now, queued);
            }
            Ok(Read16::Nothing) => {}
            Ok(Read16::End) => self.end(),
            Err(text) => {
                static ERRORS: LogLimit = LogLimit::new();
                ERRORS.log("LTC log lines", || warn!(input = %self.name, error = %text, "reading LTC"));
                self.link.update(|s| s.last_error = Some(text));
                thread::sleep(LTC_POLL);
            }
        }
        self.check_stall(monotonic_ns());
    }

    /// A file is read in real time: sleeps (at most [`LTC_POLL`]) until the next chunk has
    /// played; whether it has.
    fn file_due(&self) -> bool {
        let Some(start) = self.file_start_ns else { return true };
        let rate = u64::from(self.input.sample_rate_hz());
        let due = start + (self.file_samples + self.buf.len() as u64) * 1_000_000_000 / rate;
        let now = monotonic_ns();
        if now >= due {
            return true;
        }
        crate::clock::sleep_until_ns(due.min(now + LTC_POLL.as_nanos() as u64));
        monotonic_ns() >= due
    }

    /// A file's end: said once, and the clock is no longer used.
    fn end(&mut self) {
        info!(input = %self.name, "LTC input ended (end of file)");
        self.ended = true;
        self.locked = None;
        self.link.set_state(LtcState::Ended);
    }

    /// Decodes the first `n` samples of the buffer, read at monotonic `read_ns` with `queued`
    /// more samples waiting behind them (a FIFO's backlog: the last one read played that long
    /// before `read_ns`).
    fn feed(&mut self, n: usize, read_ns: u64, queued: u64) {
        let LtcReader { decoder, events, buf, .. } = self;
        decoder.process_i16(&buf[..n], |e| events.push(e));
        let after = self.fed + n as u64;
        // The sample that plays at `read_ns`, in the decoder's count.
        let now_sample = (after + queued) as f64;
        let rate = f64::from(self.input.sample_rate_hz());
        let ns_of =
            |sample: f64| read_ns.saturating_sub(((now_sample - sample).max(0.0) * 1e9 / rate) as u64);
        let events = std::mem::take(&mut self.events);
        for event in &events {
            match *event {
                LtcEvent::Frame(mut frame) => {
                    if let Some(taken) = frame.rate.and_then(|r| r.read_as(self.expected)) {
                        frame.rate = Some(taken);
                    }
                    let end_ns = ns_of(frame.end_sample);
                    self.last_frame_ns = Some(end_ns);
                    self.link.on_frame(&frame, end_ns, self.locked.is_some());
                }
                LtcEvent::Locked { rate, .. } => self.on_locked(rate),
                LtcEvent::Lost { last, .. } => {
                    static LOST: LogLimit = LogLimit::new();
                    LOST.log(
                        "LTC log lines",
                        || warn!(last = %last, "LTC lost (no frame in time, or one that cannot follow)"),
                    );
                    self.lose();
                }
                LtcEvent::Jump { expected, found, .. } => {
                    static JUMPS: LogLimit = LogLimit::new();
                    JUMPS.log(
                        "LTC log lines",
                        || warn!(%expected, %found, "LTC jumped (the master clock was re-jammed?)"),
                    );
                }
            }
        }
        self.events = events;
        self.events.clear();
        self.fed = after;
        self.publish_counts();
    }

    /// The decoder locked at `rate`: the clock is used, at the rate `ltc.fps` declares (29.97
    /// for LTC read as 30: the same labels, `FrameRate::read_as`), unless it declares another.
    fn on_locked(&mut self, rate: FrameRate) {
        let Some(taken) = rate.read_as(self.expected) else {
            static WRONG: LogLimit = LogLimit::new();
            let expected = self.expected.map_or_else(String::new, |e| e.to_string());
            let text = format!("LTC at {rate} fps, but ltc.fps expects {expected}: not used");
            WRONG.log("LTC log lines", || warn!("{text}"));
            self.link.update(|s| s.last_error = Some(text));
            return;
        };
        info!(fps = %taken, "LTC locked");
        self.locked = Some(taken);
        self.link.set_state(LtcState::Locked);
    }

    /// The lock is gone (the decoder said so, or the input stopped).
    fn lose(&mut self) {
        if self.locked.take().is_some() {
            self.link.set_state(LtcState::Lost);
        }
    }

    /// A lock with no frame for [`MAX_EXTRAPOLATION_NS`] of wall time (the input stopped: a
    /// FIFO's writer went away, a capture stalled) is lost, and decoding starts afresh.
    fn check_stall(&mut self, now_ns: u64) {
        let Some(last) = self.last_frame_ns else { return };
        if self.locked.is_none() || now_ns.saturating_sub(last) <= MAX_EXTRAPOLATION_NS {
            return;
        }
        static STALLED: LogLimit = LogLimit::new();
        STALLED.log("LTC log lines", || warn!(input = %self.name, "LTC input stopped: lock lost"));
        self.stalls += 1;
        self.lose();
        if let Ok(fresh) = LtcDecoder::new(self.input.sample_rate_hz()) {
            let before = self.decoder.counters();
            self.decoder = fresh;
            self.carried = add(self.carried, before);
        }
        self.fed = 0;
        self.publish_counts();
    }

    /// Copies the decoder's counts to status.
    fn publish_counts(&self) {
        let c = add(self.carried, self.decoder.counters());
        let stalls = self.stalls;
        let overruns = match &self.input {
            Input::Alsa(capture) => capture.overruns(),
            _ => 0,
        };
        self.link.update(|s| {
            s.frames = c.frames;
            s.locks = c.locks;
            s.losses = c.losses + stalls;
            s.jumps = c.jumps;
            s.overruns = overruns;
        });
    }
}

/// Two decoders' counts added (a decoder replaced after a stall keeps counting on).
fn add(a: frond_ltc::LtcCounters, b: frond_ltc::LtcCounters) -> frond_ltc::LtcCounters {
    frond_ltc::LtcCounters {
        frames: a.frames + b.frames,
        bad_frames: a.bad_frames + b.bad_frames,
        bit_errors: a.bit_errors + b.bit_errors,
        locks: a.locks + b.locks,
        losses: a.losses + b.losses,
        jumps: a.jumps + b.jumps,
    }
}
