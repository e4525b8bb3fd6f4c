//! The soak's faults beyond the glove's own unplugs and corrupt reports (issue 14): the glove's
//! clock jumping for a while (`frond-vhid --time-jump-*`), the daemon paused (SIGSTOP, then
//! SIGCONT), and a full disk under the recording (the takes directory is a small tmpfs, filled
//! until the take hits its end, then freed).
//!
//! What must hold: each time jump starts a new timeline (counted as discontinuities); after the
//! pause the daemon resumes at the present, skipping what the glove queued meanwhile, and a
//! healthy subscriber sees no gap; the take cut by the full disk keeps every frame written
//! before the fault, is closed cleanly once space returns, and `record stop` reports the error
//! once; the take recorded after it is complete.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use serde::Serialize;

use super::takes::TakeFigures;

/// The glove's clock is off from this many milliseconds after its first report...
pub const TIME_JUMP_AT_MS: u64 = 2_500;
/// ...for this long...
pub const TIME_JUMP_MS: u64 = 1_000;
/// ...by this many seconds: one jump forward at the start, one back at the end.
pub const TIME_JUMP_S: f64 = 1_000.0;
/// The daemon is paused this long after it started...
pub const PAUSE_AT: Duration = Duration::from_secs(5);
/// ...for this long (longer than the stall window, so the resume logic runs).
pub const PAUSE: Duration = Duration::from_secs(1);
/// The disk is left room for about this fraction of the run's recording...
pub const DISK_FULL_AT: f64 = 0.4;
/// ...and freed at this fraction of the run.
pub const DISK_FREED_AT: f64 = 0.7;
/// Size of the tmpfs holding the takes.
const TMPFS_SIZE: &str = "64m";
/// A take grows by about this much a second at 1 kHz (a frame record is 127 bytes).
const TAKE_BYTES_PER_S: f64 = 1000.0 * 130.0;
/// The filler file that takes the room.
const FILLER: &str = "filler.bin";

/// What the faults did and what the daemon said about them.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FaultFigures {
    /// Discontinuities the daemon counted for the hand (the time jump: 2 expected).
    pub discontinuities: u64,
    /// How long the daemon was really paused, milliseconds.
    pub pause_ms: Option<f64>,
    /// Stale reports the daemon skipped when it resumed.
    pub stale_skipped: u64,
    /// Bytes of the filler that left the recording little room.
    pub disk_filler_bytes: u64,
    /// The recorder error `frond status` showed while the disk was full (the first one seen).
    pub disk_error: Option<String>,
    /// Seconds into the run when the status first showed it.
    pub disk_error_at_s: Option<f64>,
    /// Seconds into the run when the filler was removed.
    pub disk_freed_at_s: Option<f64>,
    /// What `record stop` said for the take the full disk cut (an error, reported once).
    pub first_take_stop: Option<String>,
    /// The take the full disk cut, read back.
    pub first_take: TakeFigures,
}

/// A tmpfs mounted at a directory, unmounted (lazily) when dropped.
pub struct Tmpfs(PathBuf);

impl Tmpfs {
    /// Mounts a small tmpfs at `dir` (created if missing).
    pub fn mount(dir: &Path) -> anyhow::Result<Tmpfs> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={TMPFS_SIZE},mode=0700"), "tmpfs"])
            .arg(dir)
            .output()
            .context("cannot run mount")?;
        if !out.status.success() {
            bail!(
                "the soak's full-disk phase needs a tmpfs (root): mount at {} failed: {}",
                dir.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            );
        }
        Ok(Tmpfs(dir.to_owned()))
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// Free bytes on the file system holding `dir`.
fn free_bytes(dir: &Path) -> anyhow::Result<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).context("path with a NUL")?;
    // SAFETY: statvfs is plain data; the call only writes into it.
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: `c` is a valid NUL-terminated path and `s` a valid statvfs to write into.
    if unsafe { libc::statvfs(c.as_ptr(), &mut s) } != 0 {
        return Err(std::io::Error::last_os_error()).with_context(|| format!("statvfs {}", dir.display()));
    }
    Ok(s.f_bavail as u64 * s.f_frsize as u64)
}

/// Fills the file system of `dir` so that about `DISK_FULL_AT` of a `duration` run's recording
/// still fits; returns the filler's size.
pub fn fill_disk(dir: &Path, duration: Duration) -> anyhow::Result<u64> {
    let room = (TAKE_BYTES_PER_S * duration.as_secs_f64() * DISK_FULL_AT) as u64;
    let free = free_bytes(dir)?;
    let size = free.saturating_sub(room);
    let file = std::fs::File::create(dir.join(FILLER)).context("creating the filler")?;
    // Written, not a sparse `set_len`: tmpfs counts only pages that hold data.
    let chunk = vec![0x5Au8; 1 << 20];
    let mut left = size;
    let mut w = std::io::BufWriter::new(file);
    while left > 0 {
        let n = left.min(chunk.len() as u64) as usize;
        std::io::Write::write_all(&mut w, &chunk[..n]).context("writing the filler")?;
        left -= n as u64;
    }
    std::io::Write::flush(&mut w).context("writing the filler")?;
    Ok(size)
}

/// Removes the filler: the disk has room again.
pub fn free_disk(dir: &Path) -> anyhow::Result<()> {
    std::fs::remove_file(dir.join(FILLER)).context("removing the filler")
}

/// Pauses process `pid` for `PAUSE` (SIGSTOP, SIGCONT); returns how long it really was.
pub fn pause(pid: u32) -> f64 {
    let start = Instant::now();
    // SAFETY: kill(2) on our own child process.
    unsafe { libc::kill(pid as libc::pid_t, libc::SIGSTOP) };
    std::thread::sleep(PAUSE);
    // SAFETY: as above.
    unsafe { libc::kill(pid as libc::pid_t, libc::SIGCONT) };
    start.elapsed().as_secs_f64() * 1000.0
}

/// The verdict on the faults, appended to `f`.
pub fn verdict(x: &FaultFigures, f: &mut Vec<String>) {
    if x.discontinuities < 2 {
        f.push(format!(
            "the glove's clock jumped forward and back, but the daemon counted {} discontinuities (2 expected)",
            x.discontinuities
        ));
    }
    if x.pause_ms.is_none() {
        f.push("the daemon was never paused".into());
    } else if x.stale_skipped == 0 && x.discontinuities < 3 {
        // Resuming after a pause skips what is queued and starts a new timeline (the third
        // discontinuity, after the time jump's two). Neither means the pause went unnoticed and
        // the queued reports were replayed as new. A glove that happened to have nothing queued
        // when the daemon resumed (seen under load) still gets its new timeline.
        f.push("after the pause the daemon neither skipped stale reports nor started a new timeline (it replayed them?)".into());
    }
    if x.disk_error.is_none() {
        f.push("the disk never filled: frond status showed no recorder error".into());
    }
    match &x.first_take_stop {
        Some(m) if m.contains("refused") => {}
        other => f.push(format!("record stop after the full disk did not report the error: {other:?}")),
    }
    let t = &x.first_take;
    if let Some(e) = &t.error {
        f.push(format!("take cut by the full disk {}: {e}", t.path));
    } else if !t.ended || t.torn_bytes > 0 || t.seq_breaks > 0 || t.frames == 0 {
        f.push(format!(
            "take cut by the full disk: {} frames, ended {}, torn {} bytes, {} breaks against what a \
             subscriber saw before the fault",
            t.frames, t.ended, t.torn_bytes, t.seq_breaks
        ));
    }
}
