//! [`InProcessGlove`]: the virtual glove's report generator running inside the process, used
//! when no device node can be created. The generator thread `try_send`s the same 64-byte reports
//! into a bounded lock-free queue; the realtime loop parses them with the same [`ReportParser`].
//! After each report (and at an unplug) it signals an `eventfd`, the source's ready descriptor,
//! so the loop wakes when a report is queued as it would on a kernel hidraw node.

use std::os::fd::RawFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender, TrySendError};

use crate::generator::{Generator, ReportSink, VhidError, VhidStats, VirtualGloveConfig, spawn_generator};
use crate::glove::REPORT_LEN;
use frond_device::doorbell::Doorbell;
use frond_device::profile::DeviceProfile;
use frond_device::report::{DeviceSample, ReportParser, SourceCounters};
use frond_device::source::{HandSource, SourceError, SourceKind};

/// Reports buffered between the generator and the reader.
const QUEUE_LEN: usize = 256;

#[derive(Debug, Default)]
struct Plug {
    plugged: AtomicBool,
    /// Bumped at each unplug, so a reader opened before it sees the disconnect.
    generation: AtomicU64,
    /// Reports lost because the queue was full.
    overflow: AtomicU64,
}

struct QueueSink {
    tx: Sender<[u8; REPORT_LEN]>,
    plug: Arc<Plug>,
    bell: Arc<Doorbell>,
}

impl ReportSink for QueueSink {
    fn send(&mut self, report: &[u8; REPORT_LEN]) {
        match self.tx.try_send(*report) {
            Ok(()) => self.bell.ring(),
            Err(TrySendError::Disconnected(_)) => {}
            Err(TrySendError::Full(_)) => {
                self.plug.overflow.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    fn set_plugged(&mut self, plugged: bool) {
        if !plugged {
            self.plug.generation.fetch_add(1, Ordering::AcqRel);
        }
        self.plug.plugged.store(plugged, Ordering::Release);
        self.bell.ring();
    }
}

/// The virtual glove inside the process, read as a [`HandSource`] of kind `in-process`.
pub struct InProcessGlove {
    rx: Receiver<[u8; REPORT_LEN]>,
    plug: Arc<Plug>,
    open_generation: Option<u64>,
    bell: Arc<Doorbell>,
    parser: ReportParser,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    stats: Arc<VhidStats>,
    describe: String,
}

impl InProcessGlove {
    /// Starts the generator thread for `config`.
    pub fn new(config: VirtualGloveConfig) -> Result<Self, VhidError> {
        let generator = Generator::prepare(&config)?;
        let (tx, rx) = crossbeam_channel::bounded(QUEUE_LEN);
        let plug = Arc::new(Plug { plugged: AtomicBool::new(true), ..Plug::default() });
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(VhidStats::default());
        let bell = Arc::new(Doorbell::new().map_err(VhidError::EventFd)?);
        let sink = Box::new(QueueSink { tx, plug: Arc::clone(&plug), bell: Arc::clone(&bell) });
        let thread = spawn_generator(generator, sink, Arc::clone(&stop), Arc::clone(&stats))?;
        let describe = match &config.source {
            crate::generator::GloveSource::Sway { rate_hz } => format!("virtual glove sway at {rate_hz} Hz"),
            crate::generator::GloveSource::Jsonl { path, .. } => {
                format!("virtual glove playing {}", path.display())
            }
        };
        Ok(Self {
            rx,
            plug,
            open_generation: Some(0),
            bell,
            parser: ReportParser::new(&DeviceProfile::frond_glove()),
            stop,
            thread: Some(thread),
            stats,
            describe,
        })
    }

    /// What the generator did so far.
    pub fn stats(&self) -> Arc<VhidStats> {
        Arc::clone(&self.stats)
    }

    /// Reports lost because the reader did not keep up (queue full).
    pub fn overflow(&self) -> u64 {
        self.plug.overflow.load(Ordering::Relaxed)
    }
}

impl HandSource for InProcessGlove {
    fn kind(&self) -> SourceKind {
        SourceKind::InProcess
    }

    fn describe(&self) -> &str {
        &self.describe
    }

    fn ready_fd(&self) -> Option<RawFd> {
        self.open_generation.map(|_| self.bell.fd())
    }

    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        // Reset the doorbell before looking at the queue: a report queued after this rings it
        // again, so none waits for the next tick.
        self.bell.drain();
        let generation = self.plug.generation.load(Ordering::Acquire);
        if self.open_generation != Some(generation) || !self.plug.plugged.load(Ordering::Acquire) {
            self.open_generation = None;
            return Err(SourceError::Disconnected {
                what: self.describe.clone(),
                reason: "virtual glove unplugged".into(),
            });
        }
        let mut n = 0;
        while n < out.len() {
            let Ok(report) = self.rx.try_recv() else {
                break;
            };
            if let Ok(s) = self.parser.parse(&report) {
                out[n] = s;
                n += 1;
            }
        }
        Ok(n)
    }

    fn counters(&self) -> Arc<SourceCounters> {
        self.parser.counters()
    }

    fn reopen(&mut self) -> Result<(), SourceError> {
        let generation = self.plug.generation.load(Ordering::Acquire);
        if !self.plug.plugged.load(Ordering::Acquire) {
            return Err(SourceError::NotFound {
                what: self.describe.clone(),
                reason: "virtual glove unplugged".into(),
            });
        }
        // Reports queued before the unplug belong to the old connection.
        while self.rx.try_recv().is_ok() {}
        self.open_generation = Some(generation);
        Ok(())
    }
}

impl Drop for InProcessGlove {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
