//! The recorder thread: writes takes off the realtime thread.
//!
//! A take file is append-only (see `frond_motion::take`): every record is length-prefixed and
//! checksummed, so a reader can follow it while it grows and a crash leaves at most a torn tail.
//! Durability policy: every batch is `write`n at once (so `kill -9` of the daemon loses nothing
//! the loop handed over: the kernel has it), and the file is `fdatasync`ed at least every
//! `fsync_interval` (1 s by default), bounding what a power loss can take to that window.
//!
//! Frames arrive from the realtime loop through a wait-free single-producer ring ([`rtrb`]) that
//! this thread polls every [`RECORDER_POLL`] while a take is open: the loop never takes a lock
//! or wakes a thread to hand a frame over (a channel whose receiver parks costs the sender a
//! futex call per frame). Requests (start, marker, stop) come on a channel from the control side.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::thread;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use frond_motion::take::{TakeFrame, TakeHeader, TakeRecord, encode_file_start, encode_record};
use rtrb::{Consumer, Producer, RingBuffer};
use tracing::{error, info, warn};

/// Frames the loop may get ahead of the recorder (16 s at 1 kHz) before it drops them, counted.
pub const RECORDER_RING_FRAMES: usize = 16_384;
/// How often the recorder empties the ring while a take is open.
pub const RECORDER_POLL: Duration = Duration::from_millis(5);
/// Bytes encoded before they are written out, at most.
const WRITE_BATCH: usize = 192 * 1024;

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
        reply: Sender<Result<(), String>>,
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
        reply: Sender<Result<u64, String>>,
    },
}

/// Counters of the current take, read by status.
#[derive(Default)]
pub struct RecorderCounters {
    /// Frames written to the current take.
    pub frames: AtomicU64,
    /// Write errors since start.
    pub write_errors: AtomicU64,
}

struct Open {
    file: File,
    path: PathBuf,
    frames: u64,
    last_sync: Instant,
}

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
            while let Some(msg) = next.take() {
                // Frames the loop handed over before this request belong before it (a marker
                // after them, a take's end after its last frame).
                drain(&mut frames, &mut open, &mut buf, &counters, fsync_interval);
                handle(msg, &mut open, &mut buf, &counters);
                next = rx.try_recv().ok();
            }
            drain(&mut frames, &mut open, &mut buf, &counters, fsync_interval);
            flush(&mut open, &mut buf, &counters, fsync_interval);
        }
        drain(&mut frames, &mut open, &mut buf, &counters, fsync_interval);
        if let Some(o) = open.take() {
            let path = o.path.clone();
            match finish(o, &mut buf) {
                Ok(frames) => info!(path = %path.display(), frames, "take finished at shutdown"),
                Err(e) => error!(path = %path.display(), error = %e, "finishing the take at shutdown failed"),
            }
        }
    })
}

/// Moves every frame in the ring into the take's buffer (writing it out when it grows large);
/// frames with no take open are discarded.
fn drain(
    frames: &mut Consumer<TakeFrame>,
    open: &mut Option<Open>,
    buf: &mut Vec<u8>,
    counters: &RecorderCounters,
    fsync_interval: Duration,
) {
    while let Ok(frame) = frames.pop() {
        if let Some(o) = open.as_mut() {
            encode_record(&TakeRecord::Frame(frame), buf);
            o.frames += 1;
            counters.frames.store(o.frames, Relaxed);
        }
        if buf.len() >= WRITE_BATCH {
            flush(open, buf, counters, fsync_interval);
        }
    }
}

fn handle(msg: RecorderMsg, open: &mut Option<Open>, buf: &mut Vec<u8>, counters: &RecorderCounters) {
    match msg {
        RecorderMsg::Mark { seq, label } => {
            if open.is_some() {
                encode_record(&TakeRecord::Marker { seq, label }, buf);
            }
        }
        RecorderMsg::Start { path, header, elements, reply } => {
            if open.is_some() {
                let _ = reply.send(Err("a take is already being recorded".into()));
                return;
            }
            let result = OpenOptions::new().write(true).create_new(true).open(&path).and_then(|mut file| {
                let mut head = Vec::new();
                encode_file_start(&mut head);
                frond_motion::layers::encode_header(&header, &elements, &mut head);
                file.write_all(&head)?;
                file.sync_data()?;
                Ok(file)
            });
            match result {
                Ok(file) => {
                    counters.frames.store(0, Relaxed);
                    *open = Some(Open { file, path, frames: 0, last_sync: Instant::now() });
                    let _ = reply.send(Ok(()));
                }
                Err(e) => {
                    let _ = reply.send(Err(format!("cannot create {}: {e}", path.display())));
                }
            }
        }
        RecorderMsg::Stop { reply } => {
            let Some(o) = open.take() else {
                let _ = reply.send(Err("no take is being recorded".into()));
                return;
            };
            let _ = reply.send(finish(o, buf).map_err(|e| e.to_string()));
        }
    }
}

/// Writes what is buffered, then the End record, and syncs.
fn finish(mut o: Open, buf: &mut Vec<u8>) -> std::io::Result<u64> {
    encode_record(&TakeRecord::End { frames: o.frames }, buf);
    o.file.write_all(buf)?;
    buf.clear();
    o.file.sync_all()?;
    Ok(o.frames)
}

fn flush(open: &mut Option<Open>, buf: &mut Vec<u8>, counters: &RecorderCounters, fsync_interval: Duration) {
    let Some(o) = open.as_mut() else {
        buf.clear();
        return;
    };
    if !buf.is_empty() {
        if let Err(e) = o.file.write_all(buf) {
            counters.write_errors.fetch_add(1, Relaxed);
            warn!(path = %o.path.display(), error = %e, "writing the take failed; frames kept in memory are retried");
            if buf.len() > 64 * 1024 * 1024 {
                error!(path = %o.path.display(), "take buffer over 64 MiB with the disk failing: dropping it");
                buf.clear();
            }
            return;
        }
        buf.clear();
    }
    if o.last_sync.elapsed() >= fsync_interval {
        if let Err(e) = o.file.sync_data() {
            counters.write_errors.fetch_add(1, Relaxed);
            warn!(path = %o.path.display(), error = %e, "fdatasync of the take failed");
        }
        o.last_sync = Instant::now();
    }
}
