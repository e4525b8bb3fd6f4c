//! Choosing and opening the hand source (off the realtime thread, at start-up).
//!
//! `auto` (the default) prefers a real glove matching the device profile, and otherwise starts the
//! virtual glove's built-in sway itself: as a FUSE hidraw node under the socket directory, opened
//! through the same hidapi path as a physical glove, or, where FUSE cannot be mounted, in-process
//! with the same report bytes. `frond status` says which.

use std::any::Any;
use std::os::unix::fs::MetadataExt;
use std::path::Path;
use std::sync::Arc;

use frond_device::{
    DeviceProfile, HandSource, HidSource, OscHandSource, ReplaySource, SourceCounters, SourceKind,
};
use frond_vhid::{InProcessGlove, VirtualGloveConfig};
use tracing::{info, warn};

use crate::config::{Config, HandConfig, SourceChoice};
use crate::error::DaemonError;

type Result<T> = std::result::Result<T, DaemonError>;

fn source_error(e: impl std::fmt::Display) -> DaemonError {
    DaemonError::Source(e.to_string())
}

/// Opens a source that is not there yet; called every 100 ms by the reopen thread, which keeps
/// trying while it fails with the device's own error.
pub type SourceFactory =
    Box<dyn FnMut() -> std::result::Result<Box<dyn HandSource>, frond_device::SourceError> + Send>;

/// An opened source (or one still awaited) and what must live as long as it.
pub struct OpenedSource {
    /// The source the loop reads; `None` while waiting for a device that has not appeared.
    pub source: Option<Box<dyn HandSource>>,
    /// How to open the awaited device, when `source` is `None`.
    pub pending: Option<SourceFactory>,
    /// Kind name for status.
    pub kind: String,
    /// Path or description.
    pub path: String,
    /// Its counters.
    pub counters: Arc<SourceCounters>,
    /// Keeps a virtual glove node mounted; dropping it unmounts.
    pub keepalive: Option<Box<dyn Any + Send>>,
}

fn opened(source: Box<dyn HandSource>, keepalive: Option<Box<dyn Any + Send>>) -> OpenedSource {
    OpenedSource {
        kind: source.kind().to_string(),
        path: source.describe().to_string(),
        counters: source.counters(),
        source: Some(source),
        pending: None,
        keepalive,
    }
}

fn load_profile(hand: &HandConfig) -> Result<DeviceProfile> {
    match &hand.profile {
        Some(path) => DeviceProfile::load(path).map_err(source_error),
        None => Ok(DeviceProfile::frond_glove()),
    }
}

/// A node served by FUSE has no device number; a kernel hidraw node has one.
fn kind_of_node(path: &Path) -> SourceKind {
    match std::fs::metadata(path) {
        Ok(m) if m.rdev() == 0 => SourceKind::FuseHidraw,
        _ => SourceKind::Hidraw,
    }
}

/// A node that is there but cannot be a glove: a character device outside the hidraw
/// subsystem (`/dev/null`), a directory, a FIFO. Refused at start instead of "waited for" for
/// ever. A missing path is fine (the device may appear); a FUSE node has no device number.
fn check_node(path: &Path) -> Result<()> {
    use std::os::unix::fs::FileTypeExt;
    let Ok(meta) = std::fs::metadata(path) else { return Ok(()) };
    let ft = meta.file_type();
    if ft.is_char_device() {
        let (major, minor) = (libc::major(meta.rdev()), libc::minor(meta.rdev()));
        let subsystem = std::fs::read_link(format!("/sys/dev/char/{major}:{minor}/subsystem"));
        let is_hidraw = subsystem.as_ref().is_ok_and(|l| l.file_name().is_some_and(|n| n == "hidraw"));
        if !is_hidraw && subsystem.is_ok() {
            return Err(DaemonError::Source(format!(
                "{} is a character device ({major}:{minor}) but not a hidraw node; give the glove's /dev/hidrawN",
                path.display()
            )));
        }
        return Ok(());
    }
    // A regular file is a FUSE-served node (the virtual glove) or a test double.
    match frond_formats::rig_files::not_regular(ft) {
        None => Ok(()),
        Some(what) => Err(DaemonError::Source(format!(
            "{} is not a hidraw node (it is {what}); give the glove's /dev/hidrawN",
            path.display()
        ))),
    }
}

fn open_path(profile: &DeviceProfile, path: &Path) -> Result<OpenedSource> {
    let src = HidSource::open_path(profile, path, kind_of_node(path)).map_err(source_error)?;
    Ok(opened(Box::new(src), None))
}

/// A device that is not there (yet): the daemon runs, flags frames `device_lost`, and the
/// reopen thread keeps trying.
fn awaited(profile: DeviceProfile, path: Option<std::path::PathBuf>, reason: String) -> OpenedSource {
    let (kind, describe) = match &path {
        Some(p) => (kind_of_node(p).to_string(), p.display().to_string()),
        None => (SourceKind::Hidraw.to_string(), profile.name.clone()),
    };
    warn!(device = %describe, %reason, "hand device not available; waiting for it (frames are flagged device_lost)");
    let factory: SourceFactory = Box::new(move || {
        let src = match &path {
            Some(p) => HidSource::open_path(&profile, p, kind_of_node(p)),
            None => HidSource::open(&profile),
        };
        src.map(|s| Box::new(s) as Box<dyn HandSource>)
    });
    OpenedSource {
        source: None,
        pending: Some(factory),
        kind,
        path: describe,
        counters: Arc::new(SourceCounters::default()),
        keepalive: None,
    }
}

fn open_virtual(
    config: &Config,
    index: usize,
    hand: &HandConfig,
    socket_dir: &Path,
    allow_fuse: bool,
) -> Result<OpenedSource> {
    let mut glove = VirtualGloveConfig::sway(f64::from(config.virtual_rate_hz));
    glove.clock = config.virtual_clock;
    if allow_fuse && Path::new("/dev/fuse").exists() {
        // The first hand's node where it always was; the others beside it, by name.
        let dir =
            if index == 0 { socket_dir.join("vhid") } else { socket_dir.join(format!("vhid-{}", hand.name)) };
        match frond_vhid::mount_fuse(&dir, glove.clone()) {
            Ok(handle) => {
                let node = handle.node_path().to_path_buf();
                let profile = DeviceProfile::frond_glove();
                match HidSource::open_path(&profile, &node, SourceKind::FuseHidraw) {
                    Ok(src) => return Ok(opened(Box::new(src), Some(Box::new(handle)))),
                    Err(e) => {
                        warn!(error = %e, "opening the virtual glove's FUSE node failed; using it in-process")
                    }
                }
            }
            Err(e) => warn!(error = %e, "cannot mount the virtual glove as a FUSE node; using it in-process"),
        }
    }
    let glove = InProcessGlove::new(glove).map_err(source_error)?;
    Ok(opened(Box::new(glove), None))
}

/// Opens the source of hand `index` of the configuration, `hand`.
pub fn open_source(
    config: &Config,
    index: usize,
    hand: &HandConfig,
    socket_dir: &Path,
) -> Result<OpenedSource> {
    let profile = load_profile(hand)?;
    match &hand.source {
        SourceChoice::Replay(path) => {
            let src = ReplaySource::load(path).map_err(source_error)?;
            Ok(opened(Box::new(src), None))
        }
        SourceChoice::Hid => match &hand.device_path {
            Some(path) => {
                check_node(path)?;
                Ok(open_path(&profile, path)
                    .unwrap_or_else(|e| awaited(profile.clone(), Some(path.clone()), e.to_string())))
            }
            None => match HidSource::open(&profile) {
                Ok(src) => Ok(opened(Box::new(src), None)),
                Err(e) => Ok(awaited(profile, None, e.to_string())),
            },
        },
        SourceChoice::Osc(addr) => {
            let src = OscHandSource::bind(addr).map_err(source_error)?;
            Ok(opened(Box::new(src), None))
        }
        SourceChoice::Leap(address) => {
            let src = frond_device::LeapSource::connect(address).map_err(source_error)?;
            Ok(opened(Box::new(src), None))
        }
        SourceChoice::Webcam(address) => {
            let src = frond_device::WebcamSource::open(address, Some(socket_dir)).map_err(source_error)?;
            Ok(opened(Box::new(src), None))
        }
        SourceChoice::InProcess => open_virtual(config, index, hand, socket_dir, false),
        SourceChoice::Virtual => open_virtual(config, index, hand, socket_dir, true),
        SourceChoice::Auto => {
            if let Some(path) = &hand.device_path {
                check_node(path)?;
                return Ok(open_path(&profile, path)
                    .unwrap_or_else(|e| awaited(profile.clone(), Some(path.clone()), e.to_string())));
            }
            match HidSource::open(&profile) {
                Ok(src) => Ok(opened(Box::new(src), None)),
                Err(e) => {
                    info!(hand = %hand.name, reason = %e, "no glove found; starting the built-in virtual glove");
                    open_virtual(config, index, hand, socket_dir, true)
                }
            }
        }
    }
}
