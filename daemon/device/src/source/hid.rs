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
//! Opening by path uses `HidApi::open_path` and never calls the device-info or string getters:
//! they derive a sysfs path from `st_rdev`, which is 0 on the virtual glove's FUSE node.

use std::ffi::CString;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use hidapi::{HidApi, HidDevice};

use super::{HandSource, SourceError, SourceKind};
use crate::profile::DeviceProfile;
use crate::report::{DeviceSample, ReportParser, SourceCounters};

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
                    return Err(SourceError::Disconnected {
                        what: self.describe.clone(),
                        reason: e.to_string(),
                    });
                }
            }
        }
        Ok(n)
    }

    fn counters(&self) -> Arc<SourceCounters> {
        self.parser.counters()
    }

    fn reopen(&mut self) -> Result<(), SourceError> {
        self.device = None;
        if self.api.is_none() {
            self.api = Some(HidApi::new().map_err(|e| self.err_open(e.to_string()))?);
        }
        let device = match self.locator.clone() {
            Locator::Path(p) => {
                let c = CString::new(p.as_os_str().as_encoded_bytes())
                    .map_err(|_| self.err_open("path contains a NUL byte"))?;
                if !p.exists() {
                    return Err(SourceError::NotFound { what: self.describe.clone(), reason: String::new() });
                }
                let api = self.api.as_ref().ok_or_else(|| self.err_open("no hidapi"))?;
                api.open_path(&c).map_err(|e| self.err_open(e.to_string()))?
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
                info.open_device(api).map_err(|e| self.err_open(e.to_string()))?
            }
        };
        // hidapi opens with O_NONBLOCK; we always read with a zero timeout as well.
        device.set_blocking_mode(false).map_err(|e| self.err_open(e.to_string()))?;
        self.device = Some(device);
        Ok(())
    }
}
