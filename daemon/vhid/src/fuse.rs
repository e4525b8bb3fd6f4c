//! The virtual glove as a FUSE file that behaves as a hidraw node.
//!
//! Where `/dev/uhid` is absent but `/dev/fuse` is usable (this machine and CI, as root), a small
//! FUSE filesystem is mounted on a directory; it holds one file, [`NODE_NAME`], that unmodified
//! hidapi 2.6.7 opens by path like `/dev/hidrawN`:
//!
//! - The restricted ioctls `HIDIOCGRDESCSIZE`, `HIDIOCGRDESC`, `HIDIOCGRAWINFO` (and the name,
//!   phys and uniq strings) are answered; hidapi's `open_path` checks `HIDIOCGRDESCSIZE`.
//! - Files are opened with `FOPEN_DIRECT_IO` (without it the page cache answers reads with 0
//!   bytes) and `FOPEN_NONSEEKABLE`.
//! - `poll` is implemented with notifications (without it read timeouts are not honoured).
//! - Each open file handle has its own report queue (64 reports, newest dropped when full, like
//!   hidraw). Blocking reads are parked and answered from the report thread; `O_NONBLOCK` reads
//!   get `EAGAIN` when the queue is empty.
//! - Unplugging removes the file from the directory; open handles then poll `POLLERR|POLLHUP` and
//!   read `EIO`, as a hidraw node of a removed device does. Replugging makes the file reappear.
//!
//! The node has `st_rdev == 0`, so hidapi's device-info and string getters fail on it: the
//! daemon must not use them for a device opened by path.

use std::collections::{HashMap, VecDeque};
use std::ffi::{OsStr, OsString};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, SystemTime};

use fuser::{
    BackgroundSession, Config, Errno, FileAttr, FileHandle, FileType, Filesystem, FopenFlags, Generation,
    INodeNo, IoctlFlags, LockOwner, MountOption, OpenFlags, PollEvents, PollFlags, PollNotifier, ReplyAttr,
    ReplyData, ReplyDirectory, ReplyEmpty, ReplyEntry, ReplyIoctl, ReplyOpen, ReplyPoll, Request, SessionACL,
};

use crate::generator::{Generator, ReportSink, VhidError, VhidStats, VirtualGloveConfig, spawn_generator};
use crate::glove::{PRODUCT_ID, REPORT_DESCRIPTOR, REPORT_LEN, VENDOR_ID};

/// File name of the node inside the mount directory.
pub const NODE_NAME: &str = "hidraw-frond";
/// Reports buffered per open handle (hidraw's `HIDRAW_BUFFER_SIZE`).
const QUEUE_LEN: usize = 64;
const NODE_INO: INodeNo = INodeNo(2);
const TTL: Duration = Duration::ZERO;
/// `BUS_VIRTUAL` from linux/input.h.
const BUS_VIRTUAL: u32 = 0x06;
const DEVICE_NAME: &[u8] = b"frond virtual glove";

/// `_IOR('H', nr, size)` on Linux (x86, arm, riscv encoding).
const fn hid_ior(nr: u32, size: u32) -> u32 {
    (2 << 30) | (size << 16) | ((b'H' as u32) << 8) | nr
}
const HIDIOCGRDESCSIZE: u32 = hid_ior(0x01, 4);
/// `struct hidraw_report_descriptor { __u32 size; __u8 value[4096]; }`
const HIDIOCGRDESC: u32 = hid_ior(0x02, 4 + 4096);
/// `struct hidraw_devinfo { __u32 bustype; __s16 vendor; __s16 product; }`
const HIDIOCGRAWINFO: u32 = hid_ior(0x03, 8);
const NR_RAWNAME: u32 = 0x04;
const NR_RAWPHYS: u32 = 0x05;
const NR_RAWUNIQ: u32 = 0x08;

struct Handle {
    queue: VecDeque<[u8; REPORT_LEN]>,
    /// Parked blocking reads and their requested size.
    reads: VecDeque<(ReplyData, u32)>,
    /// The kernel's poll handle for this file (one per open file), to notify on new data.
    poll: Option<PollNotifier>,
    /// Opened before an unplug: the device it refers to is gone.
    dead: bool,
}

#[derive(Default)]
struct FsState {
    plugged: bool,
    next_fh: u64,
    handles: HashMap<u64, Handle>,
}

fn lock(state: &Mutex<FsState>) -> MutexGuard<'_, FsState> {
    state.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

struct HidrawFs {
    state: Arc<Mutex<FsState>>,
    name: OsString,
    uid: u32,
    gid: u32,
    created: SystemTime,
}

impl HidrawFs {
    fn attr(&self, ino: INodeNo) -> FileAttr {
        let dir = ino == INodeNo::ROOT;
        FileAttr {
            ino,
            size: 0,
            blocks: 0,
            atime: self.created,
            mtime: self.created,
            ctime: self.created,
            crtime: self.created,
            kind: if dir { FileType::Directory } else { FileType::RegularFile },
            perm: if dir { 0o755 } else { 0o666 },
            nlink: if dir { 2 } else { 1 },
            uid: self.uid,
            gid: self.gid,
            rdev: 0,
            blksize: 4096,
            flags: 0,
        }
    }
}

fn name_ioctl(value: &[u8], len: u32, reply: ReplyIoctl) {
    let mut buf = value.to_vec();
    buf.push(0);
    buf.truncate(len as usize);
    reply.ioctl(buf.len() as i32, &buf);
}

impl Filesystem for HidrawFs {
    fn lookup(&self, _req: &Request, parent: INodeNo, name: &OsStr, reply: ReplyEntry) {
        if parent == INodeNo::ROOT && name == self.name && lock(&self.state).plugged {
            reply.entry(&TTL, &self.attr(NODE_INO), Generation(0));
        } else {
            reply.error(Errno::ENOENT);
        }
    }

    fn getattr(&self, _req: &Request, ino: INodeNo, _fh: Option<FileHandle>, reply: ReplyAttr) {
        if ino == INodeNo::ROOT || ino == NODE_INO {
            reply.attr(&TTL, &self.attr(ino));
        } else {
            reply.error(Errno::ENOENT);
        }
    }

    fn open(&self, _req: &Request, ino: INodeNo, _flags: OpenFlags, reply: ReplyOpen) {
        let mut st = lock(&self.state);
        if ino != NODE_INO || !st.plugged {
            drop(st);
            reply.error(Errno::ENOENT);
            return;
        }
        st.next_fh += 1;
        let fh = st.next_fh;
        st.handles.insert(
            fh,
            Handle {
                queue: VecDeque::with_capacity(QUEUE_LEN),
                reads: VecDeque::new(),
                poll: None,
                dead: false,
            },
        );
        drop(st);
        reply.opened(FileHandle(fh), FopenFlags::FOPEN_DIRECT_IO | FopenFlags::FOPEN_NONSEEKABLE);
    }

    fn read(
        &self,
        _req: &Request,
        _ino: INodeNo,
        fh: FileHandle,
        _offset: u64,
        size: u32,
        flags: OpenFlags,
        _lock_owner: Option<LockOwner>,
        reply: ReplyData,
    ) {
        let mut st = lock(&self.state);
        let Some(h) = st.handles.get_mut(&fh.0) else {
            drop(st);
            reply.error(Errno::EBADF);
            return;
        };
        if h.dead {
            drop(st);
            reply.error(Errno::EIO);
        } else if let Some(report) = h.queue.pop_front() {
            drop(st);
            reply.data(&report[..REPORT_LEN.min(size as usize)]);
        } else if flags.0 & libc::O_NONBLOCK != 0 {
            drop(st);
            reply.error(Errno::EAGAIN);
        } else {
            h.reads.push_back((reply, size));
        }
    }

    /// `close(2)` on a hidraw node has nothing to flush; answering avoids fuser's
    /// "not implemented" warning on every close.
    fn flush(
        &self,
        _req: &Request,
        _ino: INodeNo,
        _fh: FileHandle,
        _lock_owner: LockOwner,
        reply: ReplyEmpty,
    ) {
        reply.ok();
    }

    fn release(
        &self,
        _req: &Request,
        _ino: INodeNo,
        fh: FileHandle,
        _flags: OpenFlags,
        _lock_owner: Option<LockOwner>,
        _flush: bool,
        reply: ReplyEmpty,
    ) {
        let removed = lock(&self.state).handles.remove(&fh.0);
        if let Some(h) = removed {
            for (r, _) in h.reads {
                r.error(Errno::EIO);
            }
        }
        reply.ok();
    }

    fn readdir(&self, _req: &Request, ino: INodeNo, _fh: FileHandle, offset: u64, mut reply: ReplyDirectory) {
        if ino != INodeNo::ROOT {
            reply.error(Errno::ENOTDIR);
            return;
        }
        let plugged = lock(&self.state).plugged;
        let mut entries: Vec<(INodeNo, FileType, &OsStr)> = vec![
            (INodeNo::ROOT, FileType::Directory, OsStr::new(".")),
            (INodeNo::ROOT, FileType::Directory, OsStr::new("..")),
        ];
        if plugged {
            entries.push((NODE_INO, FileType::RegularFile, self.name.as_os_str()));
        }
        for (i, (ino, kind, name)) in entries.into_iter().enumerate().skip(offset as usize) {
            if reply.add(ino, (i + 1) as u64, kind, name) {
                break;
            }
        }
        reply.ok();
    }

    fn ioctl(
        &self,
        _req: &Request,
        _ino: INodeNo,
        _fh: FileHandle,
        _flags: IoctlFlags,
        cmd: u32,
        _in_data: &[u8],
        _out_size: u32,
        reply: ReplyIoctl,
    ) {
        match cmd {
            HIDIOCGRDESCSIZE => {
                reply.ioctl(0, &(REPORT_DESCRIPTOR.len() as i32).to_ne_bytes());
            }
            HIDIOCGRDESC => {
                let mut out = Vec::with_capacity(4 + REPORT_DESCRIPTOR.len());
                out.extend_from_slice(&(REPORT_DESCRIPTOR.len() as u32).to_ne_bytes());
                out.extend_from_slice(&REPORT_DESCRIPTOR);
                reply.ioctl(0, &out);
            }
            HIDIOCGRAWINFO => {
                let mut out = [0u8; 8];
                out[..4].copy_from_slice(&BUS_VIRTUAL.to_ne_bytes());
                out[4..6].copy_from_slice(&(VENDOR_ID as i16).to_ne_bytes());
                out[6..8].copy_from_slice(&(PRODUCT_ID as i16).to_ne_bytes());
                reply.ioctl(0, &out);
            }
            _ if cmd & 0xC000_FFFF == hid_ior(NR_RAWNAME, 0) => {
                name_ioctl(DEVICE_NAME, (cmd >> 16) & 0x3FFF, reply)
            }
            _ if cmd & 0xC000_FFFF == hid_ior(NR_RAWPHYS, 0) => {
                name_ioctl(b"frond-vhid/fuse", (cmd >> 16) & 0x3FFF, reply)
            }
            _ if cmd & 0xC000_FFFF == hid_ior(NR_RAWUNIQ, 0) => name_ioctl(b"", (cmd >> 16) & 0x3FFF, reply),
            _ => reply.error(Errno::EINVAL),
        }
    }

    fn poll(
        &self,
        _req: &Request,
        _ino: INodeNo,
        fh: FileHandle,
        ph: PollNotifier,
        _events: PollEvents,
        _flags: PollFlags,
        reply: ReplyPoll,
    ) {
        let mut st = lock(&self.state);
        let always = PollEvents::POLLOUT | PollEvents::POLLWRNORM;
        let revents = match st.handles.get_mut(&fh.0) {
            None => PollEvents::POLLERR | PollEvents::POLLNVAL,
            Some(h) if h.dead => PollEvents::POLLERR | PollEvents::POLLHUP,
            Some(h) if !h.queue.is_empty() => always | PollEvents::POLLIN | PollEvents::POLLRDNORM,
            Some(h) => {
                // The kernel's handle is per open file: keep only the latest.
                h.poll = Some(ph);
                always
            }
        };
        drop(st);
        reply.poll(revents);
    }
}

/// Feeds generated reports into every open handle.
struct FuseSink {
    state: Arc<Mutex<FsState>>,
}

impl ReportSink for FuseSink {
    fn send(&mut self, report: &[u8; REPORT_LEN]) {
        let mut st = lock(&self.state);
        for h in st.handles.values_mut().filter(|h| !h.dead) {
            if let Some((reply, size)) = h.reads.pop_front() {
                reply.data(&report[..REPORT_LEN.min(size as usize)]);
            } else if h.queue.len() < QUEUE_LEN {
                h.queue.push_back(*report);
            }
            if let Some(p) = h.poll.take() {
                let _ = p.notify();
            }
        }
    }

    fn set_plugged(&mut self, plugged: bool) {
        let mut st = lock(&self.state);
        st.plugged = plugged;
        if !plugged {
            kill_handles(&mut st);
        }
    }
}

/// Marks every open handle as referring to a removed device and wakes its waiters.
fn kill_handles(st: &mut FsState) {
    for h in st.handles.values_mut() {
        h.dead = true;
        h.queue.clear();
        for (r, _) in h.reads.drain(..) {
            r.error(Errno::EIO);
        }
        if let Some(p) = h.poll.take() {
            let _ = p.notify();
        }
    }
}

/// A mounted virtual glove. Dropping it stops the reports and unmounts the node.
pub struct VirtualGloveHandle {
    node: PathBuf,
    dir: PathBuf,
    state: Arc<Mutex<FsState>>,
    session: Option<BackgroundSession>,
    stop: Arc<AtomicBool>,
    generator: Option<JoinHandle<()>>,
    stats: Arc<VhidStats>,
    remove_dir: bool,
}

impl std::fmt::Debug for VirtualGloveHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VirtualGloveHandle").field("node", &self.node).finish_non_exhaustive()
    }
}

/// Mounts the virtual glove in `dir` (created if missing; must be empty) and starts its reports.
/// The node is `<dir>/hidraw-frond`.
pub fn mount_fuse(dir: &Path, config: VirtualGloveConfig) -> Result<VirtualGloveHandle, VhidError> {
    mount_fuse_node(&dir.join(NODE_NAME), config)
}

/// Like [`mount_fuse`], with the node at `node` (its parent directory becomes the mount point).
pub fn mount_fuse_node(node: &Path, config: VirtualGloveConfig) -> Result<VirtualGloveHandle, VhidError> {
    let generator = Generator::prepare(&config)?;
    let (dir, name) = match (node.parent(), node.file_name()) {
        (Some(d), Some(n)) if !d.as_os_str().is_empty() => (d.to_owned(), n.to_owned()),
        _ => {
            return Err(VhidError::Config(format!(
                "node path {} needs a parent directory and a file name",
                node.display()
            )));
        }
    };
    if !Path::new("/dev/fuse").exists() {
        return Err(VhidError::NoFuse("/dev/fuse does not exist".into()));
    }
    clear_stale_mount(&dir);
    let remove_dir = !dir.exists();
    std::fs::create_dir_all(&dir).map_err(|source| VhidError::Mount { dir: dir.clone(), source })?;
    let non_empty = std::fs::read_dir(&dir)
        .map_err(|source| VhidError::Mount { dir: dir.clone(), source })?
        .next()
        .is_some();
    if non_empty {
        return Err(VhidError::MountDirNotEmpty(dir));
    }

    let state = Arc::new(Mutex::new(FsState { plugged: true, ..FsState::default() }));
    // SAFETY: getuid/getgid/geteuid have no preconditions and cannot fail.
    let (uid, gid, euid) = unsafe { (libc::getuid(), libc::getgid(), libc::geteuid()) };
    let fs = HidrawFs { state: Arc::clone(&state), name, uid, gid, created: SystemTime::now() };
    let mut options = Config::default();
    options.mount_options = vec![
        MountOption::FSName("frond-vhid".into()),
        MountOption::NoSuid,
        MountOption::NoExec,
        MountOption::NoDev,
    ];
    // As root, let other users (a service account running frondd) open the node.
    options.acl = if euid == 0 { SessionACL::All } else { SessionACL::Owner };
    let session = match fuser::spawn_mount(fs, &dir, &options) {
        Ok(s) => s,
        Err(source) => {
            if remove_dir {
                let _ = std::fs::remove_dir(&dir);
            }
            return Err(match source.raw_os_error() {
                Some(libc::EPERM) | Some(libc::EACCES) => VhidError::NoFuse(format!(
                    "not permitted to mount {} ({source}); run as root or allow FUSE mounts",
                    dir.display()
                )),
                _ => VhidError::Mount { dir, source },
            });
        }
    };
    let stop = Arc::new(AtomicBool::new(false));
    let stats = Arc::new(VhidStats::default());
    let mut handle = VirtualGloveHandle {
        node: node.to_owned(),
        dir,
        state: Arc::clone(&state),
        session: Some(session),
        stop: Arc::clone(&stop),
        generator: None,
        stats: Arc::clone(&stats),
        remove_dir,
    };
    let sink = Box::new(FuseSink { state });
    handle.generator = Some(spawn_generator(generator, sink, stop, stats)?);
    tracing::info!(node = %handle.node.display(), "virtual glove mounted (FUSE hidraw node)");
    Ok(handle)
}

/// A FUSE mount left by a killed process answers every access with ENOTCONN: detach it.
fn clear_stale_mount(dir: &Path) {
    if let Err(e) = std::fs::metadata(dir)
        && e.raw_os_error() == Some(libc::ENOTCONN)
    {
        tracing::warn!(dir = %dir.display(), "detaching a stale FUSE mount");
        let _ = lazy_unmount(dir);
    }
}

fn lazy_unmount(dir: &Path) -> std::io::Result<()> {
    let c = std::ffi::CString::new(dir.as_os_str().as_encoded_bytes())
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))?;
    // SAFETY: `c` is a valid NUL-terminated path that outlives the call.
    let r = unsafe { libc::umount2(c.as_ptr(), libc::MNT_DETACH) };
    if r == 0 { Ok(()) } else { Err(std::io::Error::last_os_error()) }
}

impl VirtualGloveHandle {
    /// Path of the hidraw-like node.
    pub fn node_path(&self) -> &Path {
        &self.node
    }

    /// The mount directory.
    pub fn mount_dir(&self) -> &Path {
        &self.dir
    }

    /// What the report generator did so far.
    pub fn stats(&self) -> Arc<VhidStats> {
        Arc::clone(&self.stats)
    }

    /// Whether a non-looping JSONL file has been played to the end.
    pub fn is_finished(&self) -> bool {
        self.stats.finished.load(Ordering::Acquire)
    }

    /// Stops the reports and unmounts, reporting failures (dropping does the same silently).
    pub fn unmount(mut self) -> Result<(), VhidError> {
        self.shutdown()
    }

    fn shutdown(&mut self) -> Result<(), VhidError> {
        self.stop.store(true, Ordering::Release);
        if let Some(g) = self.generator.take() {
            let _ = g.join();
        }
        {
            let mut st = lock(&self.state);
            st.plugged = false;
            kill_handles(&mut st);
        }
        let Some(session) = self.session.take() else {
            return Ok(());
        };
        let result = match session.umount_and_join() {
            Ok(()) => Ok(()),
            Err(e) => {
                // EBUSY: a reader still holds the node open. Detach the mount from the namespace
                // now; the kernel drops it once the last file is closed.
                tracing::debug!(error = %e, "umount failed, detaching lazily");
                match lazy_unmount(&self.dir) {
                    Ok(()) => Ok(()),
                    Err(e) if e.raw_os_error() == Some(libc::EINVAL) => Ok(()), // already gone
                    Err(source) => Err(VhidError::Unmount { dir: self.dir.clone(), source }),
                }
            }
        };
        if self.remove_dir {
            let _ = std::fs::remove_dir(&self.dir);
        }
        result
    }
}

impl Drop for VirtualGloveHandle {
    fn drop(&mut self) {
        if let Err(e) = self.shutdown() {
            tracing::warn!(error = %e, "virtual glove unmount failed");
        }
    }
}
