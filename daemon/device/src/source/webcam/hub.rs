//! One camera's landmark helper ([`Hub`]): starts `frond-hands` with its stdout a pipe only this
//! process holds, reads its lines on a thread (`frond-webcam`), turns each frame's hands into
//! the samples of the sources that asked for them, and starts the helper again when it exits.
//! Both hands of one camera share one hub (one process can open a camera once).

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStderr, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{Sender, TrySendError};
use frond_motion::hand_landmarks::Handedness;

use super::address::WebcamAddress;
use super::lines::{HelperLine, MAX_LINE_BYTES, frame_sample, parse_line};
use crate::doorbell::Doorbell;
use crate::log_limit::LogLimit;
use crate::report::{DeviceSample, SourceCounters};

/// The helper's command when `$FROND_HANDS` is not set.
pub const DEFAULT_HELPER: &str = "frond-hands";
/// First and longest wait before the helper is started again.
const RESTART: (Duration, Duration) = (Duration::from_secs(1), Duration::from_secs(5));
/// A capture time older than this when its line arrives, or in the future, is refused.
pub const MAX_AGE: Duration = Duration::from_secs(2);
/// Frames a second asked of the camera.
pub const FPS: u32 = 30;

/// A source's subscription to its camera: the hand it wants and where its samples go.
pub(super) struct Subscriber {
    pub(super) hand: Handedness,
    pub(super) tx: Sender<DeviceSample>,
    pub(super) bell: Arc<Doorbell>,
    pub(super) counters: Arc<SourceCounters>,
    pub(super) overflow: Arc<AtomicU64>,
}

/// One camera's helper and its reading thread, shared by the sources of that camera.
pub(super) struct Hub {
    input: String,
    /// Where the helper keeps the camera's preview picture, if anywhere.
    preview: Option<PathBuf>,
    subscribers: Arc<Mutex<Vec<Subscriber>>>,
    child: Arc<Mutex<Option<Child>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

/// The hubs alive, by camera.
static HUBS: Mutex<Vec<(String, Weak<Hub>)>> = Mutex::new(Vec::new());
/// Cameras given a preview picture so far in this process: the next one's number.
static PREVIEWS: AtomicU32 = AtomicU32::new(1);

/// Helper lines logged (its errors, its stderr): at most 10 in 10 s for all cameras.
static HELPER_LINES: LogLimit = LogLimit::new();

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Hub {
    /// The hub of `address`'s camera, started if it is not running, with `subscriber` added.
    /// `helper` is the command the hub starts if it starts one; with `preview_dir` (the
    /// daemon's socket directory: its own user and group only) the helper keeps the camera's
    /// preview picture there, as `webcam-N.jpg`, which the subscriber's status names.
    pub(super) fn join(
        address: &WebcamAddress,
        subscriber: Subscriber,
        helper: std::ffi::OsString,
        preview_dir: Option<&Path>,
    ) -> std::io::Result<Arc<Hub>> {
        let mut hubs = lock(&HUBS);
        hubs.retain(|(_, h)| h.strong_count() > 0);
        if let Some(hub) = hubs.iter().find(|(i, _)| *i == address.input).and_then(|(_, h)| h.upgrade()) {
            let mut subscribers = lock(&hub.subscribers);
            // The helper is already running: this source's status says so from the start.
            let starts = subscribers.iter().map(|s| s.counters.camera.starts.load(Ordering::Relaxed)).max();
            subscriber.counters.camera.starts.store(starts.unwrap_or(0), Ordering::Relaxed);
            if let Some(name) = hub.preview.as_deref().and_then(Path::file_name) {
                let _ = subscriber.counters.camera.preview.set(name.to_string_lossy().into_owned());
            }
            subscribers.push(subscriber);
            drop(subscribers);
            return Ok(hub);
        }
        let preview = preview_dir.map(|dir| {
            let name = frond_protocol::paths::camera_preview_name(PREVIEWS.fetch_add(1, Ordering::Relaxed));
            let path = dir.join(&name);
            let _ = subscriber.counters.camera.preview.set(name);
            path
        });
        let subscribers = Arc::new(Mutex::new(vec![subscriber]));
        let child = Arc::new(Mutex::new(None));
        let stop = Arc::new(AtomicBool::new(false));
        let reader = Reader {
            address: address.clone(),
            helper,
            preview: preview.clone(),
            subscribers: Arc::clone(&subscribers),
            child: Arc::clone(&child),
            stop: Arc::clone(&stop),
        };
        let thread = std::thread::Builder::new().name("frond-webcam".into()).spawn(move || reader.run())?;
        let hub = Arc::new(Hub {
            input: address.input.clone(),
            preview,
            subscribers,
            child,
            stop,
            thread: Some(thread),
        });
        hubs.push((address.input.clone(), Arc::downgrade(&hub)));
        Ok(hub)
    }

    /// Removes the subscription whose doorbell is `bell` (its source is being dropped).
    pub(super) fn leave(&self, bell: &Arc<Doorbell>) {
        lock(&self.subscribers).retain(|s| !Arc::ptr_eq(&s.bell, bell));
    }
}

impl Drop for Hub {
    /// Stops the helper (SIGKILL: it holds nothing worth saving) and the thread, which ends at
    /// the pipe's end.
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(child) = lock(&self.child).as_mut() {
            let _ = child.kill();
        }
        if let Some(t) = self.thread.take()
            && crate::join::join_within(t, Duration::from_millis(500)).is_none()
        {
            tracing::warn!(camera = %self.input, "the webcam thread did not stop within 500 ms; leaving it");
        }
        // No picture of a camera nobody reads any more.
        if let Some(path) = &self.preview {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// The hub's thread.
struct Reader {
    address: WebcamAddress,
    helper: std::ffi::OsString,
    preview: Option<PathBuf>,
    subscribers: Arc<Mutex<Vec<Subscriber>>>,
    child: Arc<Mutex<Option<Child>>>,
    stop: Arc<AtomicBool>,
}

/// The helper's command: `$FROND_HANDS`, or `frond-hands` on `PATH`.
pub fn helper_command() -> std::ffi::OsString {
    std::env::var_os("FROND_HANDS").filter(|v| !v.is_empty()).unwrap_or_else(|| DEFAULT_HELPER.into())
}

fn now_us() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes one timespec into `ts`, which we own.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000 + ts.tv_nsec as u64 / 1000
}

impl Reader {
    fn run(self) {
        let mut wait = RESTART.0;
        while !self.stop.load(Ordering::Acquire) {
            let started = Instant::now();
            match self.session() {
                Ok(()) => {}
                Err(why) => HELPER_LINES.log("webcam helper problems", || {
                    tracing::warn!(camera = %self.address.input, reason = %crate::log_limit::cut(&why), "the webcam's hand helper stopped; starting it again")
                }),
            }
            if started.elapsed() > Duration::from_secs(10) {
                wait = RESTART.0;
            }
            let until = Instant::now() + wait;
            while Instant::now() < until && !self.stop.load(Ordering::Acquire) {
                std::thread::sleep(Duration::from_millis(20));
            }
            wait = (wait * 2).min(RESTART.1);
        }
    }

    /// Starts the helper, reads it until its pipe ends; the reason it ended.
    fn session(&self) -> Result<(), String> {
        let mut cmd = Command::new(&self.helper);
        let source = if self.address.is_camera() { "--camera" } else { "--file" };
        let fps = FPS.to_string();
        cmd.args([source, self.address.input.as_str(), "--fps", fps.as_str()])
            .args(self.preview.iter().flat_map(|p| [std::ffi::OsStr::new("--preview"), p.as_os_str()]))
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        // SAFETY: between fork and exec only async-signal-safe calls: prctl asks the kernel to
        // end the helper if frondd dies, so no helper outlives the daemon.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
                Ok(())
            });
        }
        let mut child = cmd.spawn().map_err(|e| {
            format!("cannot start {:?} (install it: daemon/device/webcam/install.sh): {e}", self.helper)
        })?;
        let stdout = child.stdout.take();
        let stderr = child.stderr.take();
        *lock(&self.child) = Some(child);
        if self.stop.load(Ordering::Acquire) {
            // Dropped while starting: the drop may have found no child to kill.
            if let Some(c) = lock(&self.child).as_mut() {
                let _ = c.kill();
            }
        }
        self.each(|s| s.counters.camera.starts.fetch_add(1, Ordering::Relaxed));
        if let Some(err) = stderr {
            let camera = self.address.input.clone();
            let _ = std::thread::Builder::new()
                .name("frond-webcam-log".into())
                .spawn(move || log_stderr(err, &camera));
        }
        let said = match stdout {
            Some(out) => self.read_lines(out),
            None => Some("no stdout pipe".to_string()),
        };
        let status = lock(&self.child).take().map(|mut c| {
            let _ = c.kill();
            c.wait()
        });
        if self.stop.load(Ordering::Acquire) {
            return Ok(());
        }
        let status = match status {
            Some(Ok(s)) => s.to_string(),
            Some(Err(e)) => e.to_string(),
            None => "gone".into(),
        };
        Err(match said {
            Some(error) => format!("{error} ({status})"),
            None => format!("it ended ({status})"),
        })
    }

    /// Reads lines until the pipe ends; the helper's error line, if it said one.
    fn read_lines(&self, mut out: impl Read) -> Option<String> {
        let mut buf = vec![0u8; 64 << 10];
        let mut line: Vec<u8> = Vec::with_capacity(MAX_LINE_BYTES);
        let mut skipping = false;
        let mut said = None;
        let mut window = (Instant::now(), 0u64);
        let mut last_t = 0u64;
        loop {
            let n = match out.read(&mut buf) {
                Ok(0) | Err(_) => return said,
                Ok(n) => n,
            };
            for &b in &buf[..n] {
                if b != b'\n' {
                    if line.len() < MAX_LINE_BYTES {
                        line.push(b);
                    } else if !skipping {
                        skipping = true;
                        self.each(|s| s.counters.oversized.fetch_add(1, Ordering::Relaxed));
                    }
                    continue;
                }
                if !std::mem::take(&mut skipping) {
                    let text = String::from_utf8_lossy(&line);
                    if let Some(e) = self.take_line(&text, &mut last_t, &mut window) {
                        said = Some(e);
                    }
                }
                line.clear();
            }
        }
    }

    fn each(&self, f: impl Fn(&Subscriber) -> u64) {
        for s in lock(&self.subscribers).iter() {
            f(s);
        }
    }

    /// One whole line: a frame's hands to their sources. The helper's error text, if it is one.
    fn take_line(&self, text: &str, last_t: &mut u64, window: &mut (Instant, u64)) -> Option<String> {
        let frame = match parse_line(text) {
            Ok(HelperLine::Frame(f)) => f,
            Ok(HelperLine::Hello { model }) => {
                tracing::info!(camera = %self.address.input, %model, "webcam hand helper started");
                return None;
            }
            Ok(HelperLine::Error(e)) => return Some(e),
            Err(_) => {
                self.each(|s| s.counters.malformed.fetch_add(1, Ordering::Relaxed));
                return None;
            }
        };
        let now = now_us();
        // Untrusted time: in the last MAX_AGE, not in the future, never backwards.
        let max_age = MAX_AGE.as_micros() as u64;
        if frame.t_us > now || now - frame.t_us > max_age || frame.t_us < *last_t {
            self.each(|s| s.counters.out_of_range.fetch_add(1, Ordering::Relaxed));
            return None;
        }
        *last_t = frame.t_us;
        window.1 += 1;
        let span = window.0.elapsed();
        let fps_x100 = (span >= Duration::from_secs(1)).then(|| {
            let fps = (window.1 as f64 * 100.0 / span.as_secs_f64()) as u64;
            *window = (Instant::now(), 0);
            fps
        });
        for s in lock(&self.subscribers).iter() {
            let stats = &s.counters.camera;
            stats.frames.fetch_add(1, Ordering::Relaxed);
            stats.latency_us.store(now - frame.t_us, Ordering::Relaxed);
            stats.model_us.store(frame.model_us.min(max_age), Ordering::Relaxed);
            if frame.hands.is_empty() {
                stats.empty_frames.fetch_add(1, Ordering::Relaxed);
            }
            if let Some(fps) = fps_x100 {
                stats.fps_x100.store(fps, Ordering::Relaxed);
            }
        }
        for s in lock(&self.subscribers).iter() {
            match frame_sample(&frame, s.hand, frame.t_us as f64 / 1e6) {
                None => {}
                Some(Err(_)) => {
                    s.counters.out_of_range.fetch_add(1, Ordering::Relaxed);
                }
                Some(Ok(raw)) => {
                    let sample = DeviceSample {
                        device_seq: frame.seq as u32,
                        device_time_us: frame.t_us,
                        raw,
                        flex_deg: [0.0; 4],
                        status: 1,
                    };
                    match s.tx.try_send(sample) {
                        Ok(()) => {
                            s.counters.reports.fetch_add(1, Ordering::Relaxed);
                            s.bell.ring();
                        }
                        Err(TrySendError::Full(_)) => {
                            s.overflow.fetch_add(1, Ordering::Relaxed);
                        }
                        Err(TrySendError::Disconnected(_)) => {}
                    }
                }
            }
        }
        None
    }
}

/// The helper's stderr, a line at a time (each cut to 200 characters) at debug level, until
/// it closes.
fn log_stderr(err: ChildStderr, camera: &str) {
    use std::io::BufRead;
    let mut reader = std::io::BufReader::new(err);
    let mut line = Vec::new();
    loop {
        line.clear();
        match (&mut reader).take(4096).read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => return,
            Ok(_) => {
                let text = String::from_utf8_lossy(&line);
                tracing::debug!(%camera, line = %crate::log_limit::cut(text.trim_end()), "frond-hands");
            }
        }
    }
}
