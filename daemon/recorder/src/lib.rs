//! The recorder thread: writes takes off the realtime thread (frondd's recorder, and the stage
//! recorder of `frond record start NAME --stage STAGE`, which writes what it receives over Zenoh).
//!
//! A take file is append-only (see `frond_formats::take`): every record is length-prefixed and
//! checksummed, so a reader can follow it while it grows and a crash leaves at most a torn tail.
//! Durability policy: every batch is `write`n at once (so `kill -9` of the daemon loses nothing
//! the loop handed over: the kernel has it), and the file is `fdatasync`ed at least every
//! `fsync_interval` (1 s by default), bounding what a power loss can take to that window.
//!
//! Frames arrive from the realtime loop through a wait-free single-producer ring ([`rtrb`]) that
//! this thread polls every [`RECORDER_POLL`] while a take is open: the loop never takes a lock
//! or wakes a thread to hand a frame over (a channel whose receiver parks costs the sender a
//! futex call per frame). Requests (start, marker, stop) come on a channel from the control side.
//!
//! Disk faults (a full disk, an I/O error): every write is positioned (`pwrite` at the end of
//! the last whole record on disk), so a short write is resumed from the right offset and a
//! failed one never leaves a torn record in the middle: what a failed write got onto the disk is
//! cut back to its last whole record. After a failure the take stops growing (frames are counted
//! as lost, not buffered), the records already written are kept, and the records still in memory
//! plus the End record are written once space returns (retried every `fsync_interval`) or on
//! `record stop` (without them if they still do not fit). The fault is in [`RecorderCounters`]
//! for `frond status` and `record stop`, and logged once, then once a minute with a count.

#![warn(missing_docs)]

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::os::unix::fs::FileExt;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use frond_formats::take::{RECORD_HEAD_LEN, TakeRecord, encode_file_start, encode_record};
use frond_motion::take::{TakeFrame, TakeHeader};
use frond_motion::{HandSample, PoseFrame};
use rtrb::{Consumer, Producer, RingBuffer};
use tracing::{error, info, warn};

/// Frames the loop may get ahead of the recorder (16 s at 1 kHz) before it drops them, counted.
pub const RECORDER_RING_FRAMES: usize = 16_384;
/// How often the recorder empties the ring while a take is open.
pub const RECORDER_POLL: Duration = Duration::from_millis(5);
/// Bytes encoded before they are written out, at most.
const WRITE_BATCH: usize = 192 * 1024;
/// Size of the End record.
const END_RECORD_LEN: usize = RECORD_HEAD_LEN + 1 + 8;
/// While a write fault lasts, it is logged again this often (with the count of failed retries).
const FAULT_LOG_EVERY: Duration = Duration::from_secs(60);

/// A pose off the wire as a take stores it: the pose's time is the hand sample's (device) time,
/// as in the daemon's recorder. For writers of takes from a subscription (the stage recorder,
/// `frond-gltf live`).
pub fn take_frame(p: &frond_protocol::Pose) -> TakeFrame {
    TakeFrame {
        seq: p.seq,
        device_time_us: p.device_time_us,
        host_ns: p.host_monotonic_ns,
        flags: p.flags.0,
        element: p.element,
        pose: PoseFrame { t: p.hand.t, joints_deg: p.joints_deg },
        hand: HandSample { t: p.hand.t, wrist_deg: p.hand.wrist_deg, thumb_deg: p.hand.thumb_deg },
    }
}

/// The loop's end and the recorder's end of the frame ring.
pub fn frame_ring(frames: usize) -> (Producer<TakeFrame>, Consumer<TakeFrame>) {
    RingBuffer::new(frames)
}

/// Requests to the recorder, from the control side.
pub enum RecorderMsg {
    /// Open a new take file (never overwrites).
    Start {
        /// Path of the new take.
        path: PathBuf,
        /// Its header.
        header: Box<TakeHeader>,
        /// Names of the secondary layers (layer `k + 1` is `elements[k]`).
        elements: Vec<String>,
        /// Where to answer.
        reply: Sender<Result<(), RecorderError>>,
    },
    /// A marker at pose `seq`.
    Mark {
        /// Sequence number the marker belongs to.
        seq: u64,
        /// Label text.
        label: String,
    },
    /// Finish the take: End record, sync, close. Answers the frame count.
    Stop {
        /// Where to answer.
        reply: Sender<Result<u64, RecorderError>>,
    },
    /// The daemon's last message: write what the loop handed over, finish an open take, end the
    /// thread. (Waiting for the channel to close instead would wait for every control
    /// connection still open, each holding a sender, however idle.)
    Shutdown,
}

/// Why the recorder could not start or finish a take.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RecorderError {
    /// The take file could not be created.
    #[error("cannot create {}: {reason}", path.display())]
    Create {
        /// The take file.
        path: PathBuf,
        /// The I/O error, in words.
        reason: String,
    },
    /// A start arrived while a take is open.
    #[error("a take is already being recorded")]
    AlreadyRecording,
    /// A stop arrived with no take open.
    #[error("no take is being recorded")]
    NotRecording,
    /// The take met a write fault: the path, the error, what was kept and lost, and whether the
    /// take is closed, in words.
    #[error("{0}")]
    Fault(String),
}

/// Counters of the current take, read by status.
#[derive(Default)]
pub struct RecorderCounters {
    /// Frames written to the current take.
    pub frames: AtomicU64,
    /// Write errors since start.
    pub write_errors: AtomicU64,
    /// The current take's write fault, in words (path, error, what is kept and lost), until the
    /// take is stopped.
    fault: Mutex<Option<String>>,
}

impl RecorderCounters {
    /// The current take's write fault, if any.
    pub fn fault(&self) -> Option<String> {
        self.fault.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    fn set_fault(&self, text: Option<String>) {
        *self.fault.lock().unwrap_or_else(|p| p.into_inner()) = text;
    }
}

/// A write fault of the open take.
struct Fault {
    error: String,
    /// Frames handed over after the fault and not recorded.
    lost_frames: u64,
    /// Failed attempts since the last log line.
    unlogged_failures: u64,
    logged_at: Instant,
    next_retry: Instant,
}

struct Open {
    file: File,
    path: PathBuf,
    /// Bytes on disk: the file start and whole records only.
    disk_len: u64,
    /// Frame records on disk.
    disk_frames: u64,
    /// Frame records encoded in the buffer, not yet on disk.
    buf_frames: u64,
    last_sync: Instant,
    fault: Option<Fault>,
    /// The take was closed (End record written) after a fault; frames are discarded until stop.
    closed: bool,
}

impl Open {
    fn frames(&self) -> u64 {
        self.disk_frames + self.buf_frames
    }

    /// The fault in words, for status and (`stopped`) `record stop`.
    fn describe(&self, f: &Fault, stopped: bool) -> String {
        let state = match (self.closed, stopped) {
            (true, _) => "the take was closed with an End record",
            (false, false) => {
                "the take will be closed when the disk takes writes again, or on `frond record stop`"
            }
            (false, true) => {
                "it could not be closed (no End record: the disk is still failing); `frond take repair` \
                 closes it once it can be written"
            }
        };
        format!(
            "writing take {} failed: {}; recording stopped there: the take keeps its first {} frames \
             (every complete record), {} frames after the fault were not recorded{}; {state}",
            self.path.display(),
            f.error,
            self.disk_frames,
            f.lost_frames,
            if self.buf_frames > 0 && !self.closed {
                format!(", {} more wait in memory", self.buf_frames)
            } else {
                String::new()
            },
        )
    }

    fn publish(&self, counters: &RecorderCounters) {
        counters.frames.store(if self.fault.is_some() { self.disk_frames } else { self.frames() }, Relaxed);
        counters.set_fault(self.fault.as_ref().map(|f| self.describe(f, false)));
    }

    /// Writes `buf` at the end of the whole records on disk, resuming short writes. On an error,
    /// what got onto the disk is cut back to its last whole record; those records leave `buf`
    /// and the rest stays in it.
    fn write_out(&mut self, buf: &mut Vec<u8>) -> std::io::Result<()> {
        let mut done = 0;
        let mut error = None;
        while done < buf.len() {
            match self.file.write_at(&buf[done..], self.disk_len + done as u64) {
                Ok(0) => {
                    error =
                        Some(std::io::Error::new(std::io::ErrorKind::WriteZero, "the disk took no bytes"));
                    break;
                }
                Ok(n) => done += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    error = Some(e);
                    break;
                }
            }
        }
        let (keep, frames) = match error {
            None => (buf.len(), self.buf_frames),
            Some(_) => whole_records(buf, done),
        };
        if keep < done {
            // Free what a torn record took. If even that fails, the next write overwrites it
            // from the same offset, and readers stop at it as a torn tail meanwhile.
            let _ = self.file.set_len(self.disk_len + keep as u64);
        }
        self.disk_len += keep as u64;
        self.disk_frames += frames;
        self.buf_frames -= frames;
        buf.drain(..keep);
        error.map_or(Ok(()), Err)
    }

    /// Records a failed write or sync: the first one is logged, later ones counted and logged
    /// once a minute.
    fn failed(&mut self, e: &std::io::Error, what: &str, counters: &RecorderCounters, retry_every: Duration) {
        counters.write_errors.fetch_add(1, Relaxed);
        let now = Instant::now();
        match &mut self.fault {
            None => {
                self.fault = Some(Fault {
                    error: format!("{what}: {e}"),
                    lost_frames: 0,
                    unlogged_failures: 0,
                    logged_at: now,
                    next_retry: now + retry_every,
                });
                let text = self.describe(self.fault.as_ref().expect("just set"), false);
                warn!(path = %self.path.display(), "{text}");
            }
            Some(f) => {
                f.unlogged_failures += 1;
                f.next_retry = now + retry_every;
                if now.duration_since(f.logged_at) >= FAULT_LOG_EVERY {
                    warn!(
                        path = %self.path.display(),
                        error = %e,
                        failed_retries = f.unlogged_failures,
                        lost_frames = f.lost_frames,
                        "the take still cannot be written"
                    );
                    f.unlogged_failures = 0;
                    f.logged_at = now;
                }
            }
        }
        self.publish(counters);
    }
}

/// The length of the whole records at the start of `buf` within its first `n` bytes, and how
/// many of them are frames (`buf` starts at a record boundary).
fn whole_records(buf: &[u8], n: usize) -> (usize, u64) {
    let (mut at, mut frames) = (0, 0);
    while at + RECORD_HEAD_LEN < n {
        let len = u32::from_le_bytes([buf[at], buf[at + 1], buf[at + 2], buf[at + 3]]) as usize;
        let end = at + RECORD_HEAD_LEN + len;
        if end > n {
            break;
        }
        frames += u64::from(buf[at + RECORD_HEAD_LEN] == FRAME_KIND);
        at = end;
    }
    (at, frames)
}

/// The kind byte of a Frame record (`frond_motion::take`'s format).
const FRAME_KIND: u8 = 2;

/// Spawns the recorder thread. It ends when every sender is gone, finishing an open take first.
pub fn spawn_recorder(
    rx: Receiver<RecorderMsg>,
    mut frames: Consumer<TakeFrame>,
    counters: Arc<RecorderCounters>,
    fsync_interval: Duration,
) -> std::io::Result<thread::JoinHandle<()>> {
    thread::Builder::new().name("frond-recorder".into()).spawn(move || {
        let mut open: Option<Open> = None;
        let mut buf = Vec::with_capacity(256 * 1024);
        loop {
            let wait = if open.is_some() { RECORDER_POLL } else { fsync_interval };
            let mut next = match rx.recv_timeout(wait) {
                Ok(m) => Some(m),
                Err(RecvTimeoutError::Timeout) => None,
                Err(RecvTimeoutError::Disconnected) => break,
            };
            let mut shutdown = false;
            while let Some(msg) = next.take() {
                // Frames the loop handed over before this request belong before it (a marker
                // after them, a take's end after its last frame).
                drain(&mut frames, &mut open, &mut buf, &counters, fsync_interval);
                if matches!(msg, RecorderMsg::Shutdown) {
                    shutdown = true;
                    break;
                }
                handle(msg, &mut open, &mut buf, &counters, fsync_interval);
                next = rx.try_recv().ok();
            }
            if shutdown {
                break;
            }
            drain(&mut frames, &mut open, &mut buf, &counters, fsync_interval);
            flush(&mut open, &mut buf, &counters, fsync_interval);
        }
        drain(&mut frames, &mut open, &mut buf, &counters, fsync_interval);
        if let Some(o) = open.take() {
            let path = o.path.clone();
            match finish(o, &mut buf, &counters, fsync_interval) {
                Ok(frames) => info!(path = %path.display(), frames, "take finished at shutdown"),
                Err(e) => error!(path = %path.display(), "finishing the take at shutdown: {e}"),
            }
        }
    })
}

/// Moves every frame in the ring into the take's buffer (writing it out when it grows large);
/// frames with no take open are discarded, and so are those after a write fault (counted).
fn drain(
    frames: &mut Consumer<TakeFrame>,
    open: &mut Option<Open>,
    buf: &mut Vec<u8>,
    counters: &RecorderCounters,
    fsync_interval: Duration,
) {
    let mut lost = 0;
    while let Ok(frame) = frames.pop() {
        if let Some(o) = open.as_mut() {
            if o.fault.is_some() {
                lost += 1;
                continue;
            }
            encode_record(&TakeRecord::Frame(frame), buf);
            o.buf_frames += 1;
            counters.frames.store(o.frames(), Relaxed);
        }
        if buf.len() >= WRITE_BATCH {
            flush(open, buf, counters, fsync_interval);
        }
    }
    if let Some(o) = open.as_mut()
        && let Some(f) = o.fault.as_mut()
        && lost > 0
    {
        f.lost_frames += lost;
        o.publish(counters);
    }
}

fn handle(
    msg: RecorderMsg,
    open: &mut Option<Open>,
    buf: &mut Vec<u8>,
    counters: &RecorderCounters,
    fsync_interval: Duration,
) {
    match msg {
        RecorderMsg::Mark { seq, label } => {
            if let Some(o) = open
                && o.fault.is_none()
            {
                encode_record(&TakeRecord::Marker { seq, label }, buf);
            }
        }
        RecorderMsg::Start { path, header, elements, reply } => {
            if open.is_some() {
                let _ = reply.send(Err(RecorderError::AlreadyRecording));
                return;
            }
            let mut head = Vec::new();
            encode_file_start(&mut head);
            frond_formats::layers::encode_header(&header, &elements, &mut head);
            let result = OpenOptions::new().write(true).create_new(true).open(&path).and_then(|mut file| {
                let written = file.write_all(&head).and_then(|()| file.sync_data());
                if let Err(e) = written {
                    // Not even the header fits: leave no half-made take behind.
                    drop(file);
                    let _ = std::fs::remove_file(&path);
                    return Err(e);
                }
                Ok(file)
            });
            match result {
                Ok(file) => {
                    counters.frames.store(0, Relaxed);
                    counters.set_fault(None);
                    *open = Some(Open {
                        file,
                        path,
                        disk_len: head.len() as u64,
                        disk_frames: 0,
                        buf_frames: 0,
                        last_sync: Instant::now(),
                        fault: None,
                        closed: false,
                    });
                    let _ = reply.send(Ok(()));
                }
                Err(e) => {
                    let _ =
                        reply.send(Err(RecorderError::Create { path: path.clone(), reason: e.to_string() }));
                }
            }
        }
        // Taken by the thread's loop before it gets here.
        RecorderMsg::Shutdown => {}
        RecorderMsg::Stop { reply } => {
            let Some(o) = open.take() else {
                let _ = reply.send(Err(RecorderError::NotRecording));
                return;
            };
            let _ = reply.send(finish(o, buf, counters, fsync_interval));
        }
    }
}

/// Writes what is buffered and the End record, and syncs; true when the take is closed. With
/// `last_chance` (stop, shutdown), buffered records that do not fit are dropped (counted as
/// lost) and the End record is tried alone.
fn close(
    o: &mut Open,
    buf: &mut Vec<u8>,
    counters: &RecorderCounters,
    retry: Duration,
    last_chance: bool,
) -> bool {
    for attempt in 0..2 {
        if attempt == 1 {
            if !last_chance {
                return false;
            }
            if let Some(f) = o.fault.as_mut() {
                f.lost_frames += o.buf_frames;
            }
            o.buf_frames = 0;
            buf.clear();
        }
        encode_record(&TakeRecord::End { frames: o.frames() }, buf);
        match o.write_out(buf) {
            Ok(()) => {
                o.closed = true;
                if let Err(e) = o.file.sync_all() {
                    o.failed(&e, "fsync", counters, retry);
                }
                return true;
            }
            Err(e) => {
                // The End record did not get onto the disk whole: it is still at the buffer's end.
                buf.truncate(buf.len().saturating_sub(END_RECORD_LEN));
                o.failed(&e, "writing", counters, retry);
            }
        }
    }
    false
}

/// Finishes the take. `Ok(frames)` for a take written without a fault; otherwise the fault in
/// words (path, error, what was kept and lost, whether the take is closed).
fn finish(
    mut o: Open,
    buf: &mut Vec<u8>,
    counters: &RecorderCounters,
    retry: Duration,
) -> Result<u64, RecorderError> {
    let closed_before = o.closed;
    let closed = closed_before || close(&mut o, buf, counters, retry, true);
    buf.clear();
    counters.set_fault(None);
    let Some(f) = &o.fault else {
        return Ok(o.frames());
    };
    let text = o.describe(f, true);
    if !closed {
        warn!(path = %o.path.display(), "{text}");
    }
    if f.unlogged_failures > 0 && !closed_before {
        info!(path = %o.path.display(), failed_retries = f.unlogged_failures, "the take's write fault lasted until it was stopped");
    }
    Err(RecorderError::Fault(text))
}

fn flush(open: &mut Option<Open>, buf: &mut Vec<u8>, counters: &RecorderCounters, fsync_interval: Duration) {
    let Some(o) = open.as_mut() else {
        buf.clear();
        return;
    };
    if o.closed {
        return;
    }
    if let Some(f) = &o.fault {
        // Retry (once per interval) what was in memory, with the End record: the take is closed
        // as soon as the disk takes writes again.
        if Instant::now() >= f.next_retry && close(o, buf, counters, fsync_interval, false) {
            let (lost, retries) = o.fault.as_ref().map_or((0, 0), |f| (f.lost_frames, f.unlogged_failures));
            info!(
                path = %o.path.display(),
                frames = o.disk_frames,
                lost_frames = lost,
                failed_retries = retries,
                "the disk takes writes again: the take was closed with an End record"
            );
            o.publish(counters);
        }
        return;
    }
    if !buf.is_empty()
        && let Err(e) = o.write_out(buf)
    {
        o.failed(&e, "writing", counters, fsync_interval);
        return;
    }
    if o.last_sync.elapsed() >= fsync_interval {
        if let Err(e) = o.file.sync_data() {
            o.failed(&e, "fdatasync", counters, fsync_interval);
        }
        o.last_sync = Instant::now();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_records_stop_at_the_last_complete_one() {
        let mut buf = Vec::new();
        encode_record(&TakeRecord::Frame(TakeFrame::default()), &mut buf); // 127 bytes
        encode_record(&TakeRecord::Marker { seq: 1, label: "ab".into() }, &mut buf); // 19 bytes
        encode_record(&TakeRecord::Frame(TakeFrame::default()), &mut buf); // 127 bytes
        assert_eq!(buf.len(), 127 + 19 + 127);
        assert_eq!(whole_records(&buf, 0), (0, 0));
        assert_eq!(whole_records(&buf, 126), (0, 0));
        assert_eq!(whole_records(&buf, 127), (127, 1));
        assert_eq!(whole_records(&buf, 145), (127, 1));
        assert_eq!(whole_records(&buf, 146), (146, 1));
        assert_eq!(whole_records(&buf, 272), (146, 1));
        assert_eq!(whole_records(&buf, 273), (273, 2));
    }

    #[test]
    fn a_full_disk_keeps_whole_records_and_is_described_once() {
        // /dev/full takes no bytes (ENOSPC): the take stops growing, nothing in memory is lost
        // yet, the fault names the path and what is kept.
        let Ok(file) = OpenOptions::new().write(true).open("/dev/full") else {
            return; // no /dev/full here
        };
        let mut o = Open {
            file,
            path: PathBuf::from("/dev/full"),
            disk_len: 0,
            disk_frames: 0,
            buf_frames: 2,
            last_sync: Instant::now(),
            fault: None,
            closed: false,
        };
        let mut buf = Vec::new();
        encode_record(&TakeRecord::Frame(TakeFrame::default()), &mut buf);
        encode_record(&TakeRecord::Frame(TakeFrame::default()), &mut buf);
        let counters = RecorderCounters::default();
        let e = o.write_out(&mut buf).unwrap_err();
        assert_eq!(buf.len(), 254, "nothing was written, everything stays in memory");
        assert_eq!((o.disk_len, o.disk_frames, o.buf_frames), (0, 0, 2));
        o.failed(&e, "writing", &counters, Duration::from_secs(1));
        o.failed(&e, "writing", &counters, Duration::from_secs(1));
        assert_eq!(counters.write_errors.load(Relaxed), 2);
        assert_eq!(o.fault.as_ref().unwrap().unlogged_failures, 1);
        let text = counters.fault().unwrap();
        assert!(text.starts_with("writing take /dev/full failed: writing: "), "{text}");
        assert!(text.contains("keeps its first 0 frames"), "{text}");
        assert!(text.contains("2 more wait in memory"), "{text}");
        // Stopped with the disk still full: the two frames are lost, the take is left open.
        let err = finish(o, &mut buf, &counters, Duration::from_secs(1)).unwrap_err().to_string();
        assert!(err.contains("2 frames after the fault were not recorded"), "{err}");
        assert!(err.contains("it could not be closed"), "{err}");
        assert!(counters.fault().is_none(), "reported once, by the stop");
    }
}
