//! [`ReplaySource`]: a JSONL hand recording played at its timestamps against the host monotonic
//! clock. The file is loaded up front; reads do no I/O and no allocation.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use frond_motion::HandSample;

use super::{HandSource, SourceError, SourceKind};
use crate::jsonl::{HandFileError, load_hand_file};
use crate::report::{DeviceSample, SourceCounters};

/// Plays a hand recording: sample `i` becomes pending once `t_i - t_0` seconds have passed since
/// the first read (or [`ReplaySource::start`]).
pub struct ReplaySource {
    samples: Vec<HandSample>,
    next: usize,
    start: Option<Instant>,
    describe: String,
    counters: Arc<SourceCounters>,
}

impl ReplaySource {
    /// Loads `path` (see [`crate::jsonl`] for the format).
    pub fn load(path: &Path) -> Result<Self, HandFileError> {
        let samples = load_hand_file(path)?;
        Ok(Self::from_samples(samples, path.display().to_string()))
    }

    /// A replay of samples already in memory (must be non-empty, times non-decreasing).
    pub fn from_samples(samples: Vec<HandSample>, describe: String) -> Self {
        Self { samples, next: 0, start: None, describe, counters: Arc::new(SourceCounters::default()) }
    }

    /// Starts the clock now (otherwise the first `read_pending` starts it).
    pub fn start(&mut self) {
        self.start = Some(Instant::now());
    }

    /// Whether every sample has been delivered.
    pub fn finished(&self) -> bool {
        self.next >= self.samples.len()
    }

    /// Number of samples in the recording.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether the recording is empty.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

impl HandSource for ReplaySource {
    fn kind(&self) -> SourceKind {
        SourceKind::Replay
    }

    fn describe(&self) -> &str {
        &self.describe
    }

    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        let start = *self.start.get_or_insert_with(Instant::now);
        let Some(first) = self.samples.first() else {
            return Ok(0);
        };
        let elapsed_s = start.elapsed().as_secs_f64();
        let t0 = first.t;
        let mut n = 0;
        while n < out.len() && self.next < self.samples.len() {
            let s = self.samples[self.next];
            if s.t - t0 > elapsed_s {
                break;
            }
            // The file's time is kept as is so poses match an offline mapping of the file.
            out[n] = DeviceSample {
                device_seq: self.next as u32,
                device_time_us: (s.t * 1e6).round().max(0.0) as u64,
                raw: s,
                flex_deg: [0.0; 4],
                status: 1,
            };
            self.counters.reports.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            self.next += 1;
            n += 1;
        }
        Ok(n)
    }

    fn counters(&self) -> Arc<SourceCounters> {
        Arc::clone(&self.counters)
    }

    /// Restarts the recording from the beginning.
    fn reopen(&mut self) -> Result<(), SourceError> {
        self.next = 0;
        self.start = None;
        Ok(())
    }
}
