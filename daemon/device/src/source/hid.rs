//! [`HidSource`]: a hidapi device (hidraw node) parsed by a [`DeviceProfile`].
//!
//! # Does a non-blocking read allocate? (hidapi 2.6.7, `linux-native-basic-udev`)
//!
//! `HidDevice::read_timeout(buf, 0)` (`src/linux_native.rs`) calls `nix::poll` on one
//! stack-allocated `PollFd` with a zero timeout, then `nix::unistd::read` into our buffer. On the
//! success paths (`Ok(0)` when nothing is pending, `Ok(n)` for a report, `EAGAIN` mapped to
//! `Ok(0)`) nothing is allocated: two syscalls, no heap. Only error paths allocate
//! (`HidError::HidApiError { message: String }` for POLLERR/POLLHUP, i.e. a disconnect), which is
//! the one-off transition we report as [`SourceError::Disconnected`]. So we use hidapi's
//! `read_timeout(buf, 0)` and do not read the fd directly. The `HidDevice` wrapper adds one
//! virtual call (`Box<dyn HidDeviceBackendBase>`), no allocation.
//!
//! # Waking on a report
//! hidapi keeps the descriptor of a device private, yet the realtime loop wants to `ppoll` it (a
//! report then wakes the loop at once; see [`HandSource::ready_fd`]). [`HidSource::reopen`] lists
//! `/proc/self/fd` before and after hidapi opens the node and keeps the one new descriptor that
//! refers to the node's inode (`fstat` device and inode equal to `stat(path)`). Reads still go
//! through hidapi; the loop only waits on the descriptor. If it cannot be identified (no
//! `/proc`, several candidates) the source has no ready descriptor and the loop polls at its ticks.
//!
//! Opening by path uses `HidApi::open_path` and never calls the device-info or string getters:
//! they derive a sysfs path from `st_rdev`, which is 0 on the virtual glove's FUSE node.

use std::ffi::CString;
use std::os::fd::RawFd;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use std::os::unix::ffi::OsStrExt;

use hidapi::{HidApi, HidDevice};

use frond_protocol::SourceKind;

use super::hand::{HandSource, SourceError};
use super::spec::{Backend, SourceSpec};
use crate::profile::DeviceProfile;
use crate::report::{DeviceSample, ReportParser, SourceCounters};

/// `hid`: a real glove only, matching the device profile (`path` names its node; without one
/// the first matching device is used).
pub(crate) const BACKEND: Backend =
    Backend { syntax: "hid", parse: |kind, _| (kind == "hid").then_some(Ok(SourceSpec::Hid)) };

/// How the device is found.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Locator {
    Path(PathBuf),
    Ids { vendor_id: u16, product_id: u16 },
}

/// A hand device read through hidapi.
pub struct HidSource {
    api: Option<HidApi>,
    device: Option<HidDevice>,
    locator: Locator,
    kind: SourceKind,
    describe: String,
    parser: ReportParser,
    /// One byte longer than the report so oversized reports are detected, not truncated.
    buf: Box<[u8]>,
    /// hidapi's descriptor for `device`, when identified (see the module docs).
    ready_fd: Option<RawFd>,
}

impl HidSource {
    /// Opens the device the profile names: by `path` if set, else the first hidraw device with
    /// its vendor/product id.
    pub fn open(profile: &DeviceProfile) -> Result<Self, SourceError> {
        let locator = match (&profile.path, profile.vendor_id, profile.product_id) {
            (Some(p), _, _) => Locator::Path(p.clone()),
            (None, Some(vendor_id), Some(product_id)) => Locator::Ids { vendor_id, product_id },
            _ => {
                return Err(SourceError::Open {
                    what: profile.name.clone(),
                    reason: "the profile gives neither a path nor vendor_id/product_id".into(),
                });
            }
        };
        Self::with_locator(profile, locator, SourceKind::Hidraw)
    }

    /// Opens the hidraw node at `path` (a kernel node or the virtual glove's FUSE node), parsed
    /// with `profile`. `kind` is reported by [`HandSource::kind`] (`Hidraw` or `FuseHidraw`).
    pub fn open_path(profile: &DeviceProfile, path: &Path, kind: SourceKind) -> Result<Self, SourceError> {
        Self::with_locator(profile, Locator::Path(path.to_owned()), kind)
    }

    fn with_locator(
        profile: &DeviceProfile,
        locator: Locator,
        kind: SourceKind,
    ) -> Result<Self, SourceError> {
        let describe = match &locator {
            Locator::Path(p) => p.display().to_string(),
            Locator::Ids { vendor_id, product_id } => {
                format!("{} ({vendor_id:04x}:{product_id:04x})", profile.name)
            }
        };
        let mut s = Self {
            api: None,
            device: None,
            locator,
            kind,
            describe,
            parser: ReportParser::new(profile),
            buf: vec![0u8; profile.report_len + 1].into_boxed_slice(),
            ready_fd: None,
        };
        s.reopen()?;
        Ok(s)
    }

    fn err_open(&self, reason: impl Into<String>) -> SourceError {
        SourceError::Open { what: self.describe.clone(), reason: reason.into() }
    }
}

impl HandSource for HidSource {
    fn kind(&self) -> SourceKind {
        self.kind
    }

    fn describe(&self) -> &str {
        &self.describe
    }

    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        let Some(device) = &self.device else {
            return Err(SourceError::Disconnected { what: self.describe.clone(), reason: "not open".into() });
        };
        let mut n = 0;
        // Bound the reads so a device flooding invalid reports cannot keep us here.
        let mut budget = out.len().saturating_mul(2).max(16);
        while n < out.len() && budget > 0 {
            budget -= 1;
            match device.read_timeout(&mut self.buf, 0) {
                Ok(0) => break,
                Ok(len) => {
                    if let Ok(s) = self.parser.parse(&self.buf[..len]) {
                        out[n] = s;
                        n += 1;
                    }
                }
                Err(e) => {
                    self.device = None;
                    self.ready_fd = None;
                    return Err(SourceError::Disconnected {
                        what: self.describe.clone(),
                        reason: e.to_string(),
                    });
                }
            }
        }
        Ok(n)
    }

    fn ready_fd(&self) -> Option<RawFd> {
        self.device.as_ref().and(self.ready_fd)
    }

    fn counters(&self) -> Arc<SourceCounters> {
        self.parser.counters()
    }

    fn reopen(&mut self) -> Result<(), SourceError> {
        self.device = None;
        self.ready_fd = None;
        let fds_before = open_fds();
        if self.api.is_none() {
            self.api = Some(HidApi::new().map_err(|e| self.err_open(e.to_string()))?);
        }
        let (device, node) = match self.locator.clone() {
            Locator::Path(p) => {
                let c = CString::new(p.as_os_str().as_encoded_bytes())
                    .map_err(|_| self.err_open("path contains a NUL byte"))?;
                if !p.exists() {
                    return Err(SourceError::NotFound { what: self.describe.clone(), reason: String::new() });
                }
                let api = self.api.as_ref().ok_or_else(|| self.err_open("no hidapi"))?;
                (api.open_path(&c).map_err(|e| self.err_open(e.to_string()))?, p)
            }
            Locator::Ids { vendor_id, product_id } => {
                let api = self
                    .api
                    .as_mut()
                    .ok_or_else(|| SourceError::Open { what: String::new(), reason: "no hidapi".into() })?;
                let found = api.reset_devices().and_then(|()| api.add_devices(vendor_id, product_id));
                if let Err(e) = found {
                    return Err(self.err_open(e.to_string()));
                }
                let api = self.api.as_ref().ok_or_else(|| self.err_open("no hidapi"))?;
                let Some(info) = api.device_list().next() else {
                    return Err(SourceError::NotFound { what: self.describe.clone(), reason: String::new() });
                };
                let node = PathBuf::from(std::ffi::OsStr::from_bytes(info.path().to_bytes()));
                (info.open_device(api).map_err(|e| self.err_open(e.to_string()))?, node)
            }
        };
        // hidapi opens with O_NONBLOCK; we always read with a zero timeout as well.
        device.set_blocking_mode(false).map_err(|e| self.err_open(e.to_string()))?;
        self.ready_fd = fds_before.and_then(|before| descriptor_of(&node, &before));
        self.device = Some(device);
        Ok(())
    }
}

/// A descriptor and the (device, inode) it refers to.
type FdIdentity = (RawFd, u64, u64);

/// This process's open descriptors with what they refer to, from `/proc/self/fd`; `None`
/// without `/proc`. (A number alone is not an identity: the listing's own directory descriptor
/// is closed again and its number is the next one `open` hands out.)
fn open_fds() -> Option<Vec<FdIdentity>> {
    let fds: Vec<RawFd> = std::fs::read_dir("/proc/self/fd")
        .ok()?
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse().ok())
        .collect();
    Some(fds.into_iter().filter_map(|fd| fstat_identity(fd).map(|(dev, ino)| (fd, dev, ino))).collect())
}

fn fstat_identity(fd: RawFd) -> Option<(u64, u64)> {
    // SAFETY: `stat` is plain data, fully written by a successful fstat; `fd` is only inspected
    // (a descriptor closed meanwhile makes fstat fail with EBADF).
    let mut st: libc::stat = unsafe { std::mem::zeroed() };
    // SAFETY: as above; `st` is a valid, writable stat buffer.
    if unsafe { libc::fstat(fd, &mut st) } != 0 {
        return None;
    }
    Some((st.st_dev as u64, st.st_ino as u64))
}

/// The one descriptor not in `before` that refers to `node`'s inode, if exactly one does.
fn descriptor_of(node: &Path, before: &[FdIdentity]) -> Option<RawFd> {
    use std::os::unix::fs::MetadataExt;
    let meta = std::fs::metadata(node).ok()?;
    let mut found = None;
    for (fd, dev, ino) in open_fds()?.into_iter().filter(|id| !before.contains(id)) {
        if dev == meta.dev() && ino == meta.ino() {
            if found.is_some() {
                return None;
            }
            found = Some(fd);
        }
    }
    found
}
