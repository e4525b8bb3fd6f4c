//! The virtual glove as a kernel HID device through `/dev/uhid` (a real `/dev/hidrawN`).
//!
//! Untested on machines without `/dev/uhid` (this one and CI); kept small. Events are written in
//! the layout of `struct uhid_event` (linux/uhid.h, packed): a `u32` type followed by the request.
//! The kernel zero-fills a short write, so only the used prefix is written.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::generator::{Generator, ReportSink, VhidError, VhidStats, VirtualGloveConfig, spawn_generator};
use crate::glove::{PRODUCT_ID, REPORT_DESCRIPTOR, REPORT_LEN, VENDOR_ID};

/// Path of the UHID character device.
pub const UHID_PATH: &str = "/dev/uhid";

const UHID_DESTROY: u32 = 1;
const UHID_CREATE2: u32 = 11;
const UHID_INPUT2: u32 = 12;
/// `sizeof(struct uhid_event)`: 4 + `sizeof(struct uhid_create2_req)` (the largest member).
const EVENT_LEN: usize = 4 + 128 + 64 + 64 + 2 + 2 + 4 + 4 + 4 + 4 + 4096;
const BUS_VIRTUAL: u16 = 0x06;

/// Whether UHID is available on this machine.
pub fn available() -> bool {
    Path::new(UHID_PATH).exists()
}

fn create2_event(uniq: &str) -> Vec<u8> {
    let mut e = vec![0u8; EVENT_LEN];
    e[0..4].copy_from_slice(&UHID_CREATE2.to_ne_bytes());
    let name = b"frond virtual glove";
    e[4..4 + name.len()].copy_from_slice(name);
    let phys = b"frond-vhid/uhid";
    e[132..132 + phys.len()].copy_from_slice(phys);
    let u = uniq.as_bytes();
    let n = u.len().min(63);
    e[196..196 + n].copy_from_slice(&u[..n]);
    e[260..262].copy_from_slice(&(REPORT_DESCRIPTOR.len() as u16).to_ne_bytes());
    e[262..264].copy_from_slice(&BUS_VIRTUAL.to_ne_bytes());
    e[264..268].copy_from_slice(&u32::from(VENDOR_ID).to_ne_bytes());
    e[268..272].copy_from_slice(&u32::from(PRODUCT_ID).to_ne_bytes());
    // version 272..276, country 276..280: 0
    e[280..280 + REPORT_DESCRIPTOR.len()].copy_from_slice(&REPORT_DESCRIPTOR);
    e
}

struct UhidSink {
    file: File,
    uniq: String,
    created: bool,
    sends: u32,
}

impl UhidSink {
    fn write_event(&mut self, e: &[u8]) {
        if let Err(err) = self.file.write_all(e) {
            tracing::warn!(error = %err, "uhid write failed");
        }
    }

    fn create(&mut self) {
        let e = create2_event(&self.uniq);
        self.write_event(&e);
        self.created = true;
    }

    fn destroy(&mut self) {
        if self.created {
            self.write_event(&UHID_DESTROY.to_ne_bytes());
            self.created = false;
        }
    }

    /// Discards kernel events (open, close, start, output...) so their queue never fills.
    fn drain(&mut self) {
        let mut buf = vec![0u8; EVENT_LEN];
        while matches!(self.file.read(&mut buf), Ok(n) if n > 0) {}
    }
}

impl ReportSink for UhidSink {
    fn send(&mut self, report: &[u8; REPORT_LEN]) {
        let mut e = [0u8; 4 + 2 + REPORT_LEN];
        e[0..4].copy_from_slice(&UHID_INPUT2.to_ne_bytes());
        e[4..6].copy_from_slice(&(REPORT_LEN as u16).to_ne_bytes());
        e[6..].copy_from_slice(report);
        self.write_event(&e);
        self.sends = self.sends.wrapping_add(1);
        if self.sends.is_multiple_of(32) {
            self.drain();
        }
    }

    fn set_plugged(&mut self, plugged: bool) {
        if plugged {
            self.create();
        } else {
            self.destroy();
        }
    }
}

impl Drop for UhidSink {
    fn drop(&mut self) {
        self.destroy();
    }
}

/// A virtual glove created through UHID. Dropping it destroys the device.
pub struct UhidGlove {
    node: PathBuf,
    stop: Arc<AtomicBool>,
    generator: Option<JoinHandle<()>>,
    stats: Arc<VhidStats>,
}

impl UhidGlove {
    /// Creates the device, waits for its hidraw node, and starts the reports.
    pub fn create(config: VirtualGloveConfig) -> Result<Self, VhidError> {
        let generator = Generator::prepare(&config)?;
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NONBLOCK | libc::O_CLOEXEC)
            .open(UHID_PATH)
            .map_err(|e| VhidError::Uhid(format!("cannot open {UHID_PATH}: {e}")))?;
        let uniq = format!("frond-vhid-{}", std::process::id());
        let mut sink = UhidSink { file, uniq: uniq.clone(), created: false, sends: 0 };
        sink.create();
        let node = find_hidraw(&uniq, Duration::from_secs(3))
            .ok_or_else(|| VhidError::Uhid("the kernel created no hidraw node for the UHID device".into()))?;
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(VhidStats::default());
        let generator = spawn_generator(generator, Box::new(sink), Arc::clone(&stop), Arc::clone(&stats))?;
        Ok(Self { node, stop, generator: Some(generator), stats })
    }

    /// The `/dev/hidrawN` node (after an unplug the kernel may pick another number; open by
    /// vendor/product id to follow it).
    pub fn node_path(&self) -> &Path {
        &self.node
    }

    /// What the report generator did so far.
    pub fn stats(&self) -> Arc<VhidStats> {
        Arc::clone(&self.stats)
    }

    /// Whether a non-looping JSONL file has been played to the end.
    pub fn is_finished(&self) -> bool {
        self.stats.finished.load(Ordering::Acquire)
    }
}

impl Drop for UhidGlove {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(g) = self.generator.take() {
            let _ = g.join(); // the sink's drop destroys the device
        }
    }
}

/// Finds `/dev/hidrawN` whose HID device has `HID_UNIQ=<uniq>` in its uevent.
fn find_hidraw(uniq: &str, timeout: Duration) -> Option<PathBuf> {
    let deadline = Instant::now() + timeout;
    let needle = format!("HID_UNIQ={uniq}");
    loop {
        if let Ok(entries) = std::fs::read_dir("/sys/class/hidraw") {
            for e in entries.flatten() {
                let uevent = e.path().join("device/uevent");
                let matches =
                    std::fs::read_to_string(&uevent).map(|s| s.lines().any(|l| l == needle)).unwrap_or(false);
                let dev = Path::new("/dev").join(e.file_name());
                if matches && dev.exists() {
                    return Some(dev);
                }
            }
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn create2_layout() {
        let e = create2_event("u1");
        assert_eq!(e.len(), 4376);
        assert_eq!(&e[0..4], &11u32.to_ne_bytes());
        assert_eq!(&e[196..198], b"u1");
        assert_eq!(u16::from_ne_bytes([e[260], e[261]]), 23);
        assert_eq!(u32::from_ne_bytes([e[264], e[265], e[266], e[267]]), 0x1209);
        assert_eq!(u32::from_ne_bytes([e[268], e[269], e[270], e[271]]), 0xF0D1);
        assert_eq!(&e[280..303], &REPORT_DESCRIPTOR);
    }
}
