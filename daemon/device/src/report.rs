//! Profile-driven parsing of HID input reports into [`DeviceSample`]s.
//!
//! The parser runs on the realtime loop: it never allocates and never panics, whatever the bytes.
//! Every rejected report is counted by kind in [`SourceCounters`], which the daemon's status thread
//! reads through an `Arc`.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use frond_motion::HandSample;

use crate::profile::{AngleUnit, Channel, ChannelId, ChecksumKind, DeviceProfile, TimeUnit};

/// One parsed device report.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeviceSample {
    /// Report sequence number from the device (or a local counter if the profile has none).
    pub device_seq: u32,
    /// Device time in microseconds, unwrapped to 64 bits.
    pub device_time_us: u64,
    /// The hand sample in degrees; `t` is `device_time_us / 1e6` seconds.
    pub raw: HandSample,
    /// Flex of index, middle, ring, little finger in degrees (0 when the profile has none).
    pub flex_deg: [f32; 4],
    /// Status byte (bit 0 = tracking ok); 1 when the profile has no status field.
    pub status: u8,
}

/// Why a report was rejected. Each kind has its own counter in [`SourceCounters`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ReportError {
    /// The first byte is not the profile's report id.
    #[error("report id {got:#04x}, expected {expected:#04x}")]
    WrongId {
        /// Report id the report carried.
        got: u8,
        /// Report id the profile expects.
        expected: u8,
    },
    /// The report is shorter than the profile's `report_len` (or empty).
    #[error("short report: {len} bytes, expected {expected}")]
    Short {
        /// Length of the report received, in bytes.
        len: usize,
        /// The profile's `report_len`, in bytes.
        expected: usize,
    },
    /// The report is longer than the profile's `report_len`.
    #[error("oversized report: {len} bytes, expected {expected}")]
    Oversized {
        /// Length of the report received, in bytes.
        len: usize,
        /// The profile's `report_len`, in bytes.
        expected: usize,
    },
    /// The report fails the profile's checksum (corrupted in transport).
    #[error("checksum mismatch")]
    Checksum,
    /// A channel value lies outside its profile `min..=max` (or is NaN).
    #[error("channel {0} out of its physical range")]
    OutOfRange(ChannelId),
}

/// Counters of one hand source, shared with the status thread.
#[derive(Debug, Default)]
pub struct SourceCounters {
    /// Reports accepted.
    pub reports: AtomicU64,
    /// Reports with the wrong report id.
    pub wrong_id: AtomicU64,
    /// Reports shorter than the profile's `report_len`.
    pub short: AtomicU64,
    /// Reports longer than the profile's `report_len`.
    pub oversized: AtomicU64,
    /// Reports whose checksum did not match.
    pub checksum: AtomicU64,
    /// Reports with a channel outside its physical range.
    pub out_of_range: AtomicU64,
    /// Messages that could not be decoded at all (OSC input: not OSC, wrong argument types).
    pub malformed: AtomicU64,
    /// Messages listing more than a frame may (a Leap frame of more than
    /// `frond_device::source::leap::frames::MAX_HANDS` hands), refused at the first item too many.
    pub too_many: AtomicU64,
    /// Connections to a hand service dropped because it did not read what frond must write (a
    /// service that floods pings and never reads the pongs): not reports, so not in
    /// [`CountersSnapshot::rejected`].
    pub peers_dropped: AtomicU64,
    /// Reports missing between consecutive accepted reports, from the sequence field (lost in
    /// transport or rejected above). A backwards jump is taken as a device restart, not a gap.
    pub seq_gaps: AtomicU64,
    /// A camera source's frames, rate and latency (`webcam`; untouched by other sources).
    pub camera: CameraCounters,
}

/// What a camera source's landmark helper does, for status and the bench: each of the camera's
/// sources has its copy ([`SourceCounters::camera`]), written by the webcam backend's thread.
#[derive(Debug, Default)]
pub struct CameraCounters {
    /// Frames the helper reported.
    pub frames: AtomicU64,
    /// Frames in which no hand was found.
    pub empty_frames: AtomicU64,
    /// The last frame's age when its line was read, capture to sample, microseconds.
    pub latency_us: AtomicU64,
    /// The model's time on the last frame, microseconds.
    pub model_us: AtomicU64,
    /// Times the helper was started.
    pub starts: AtomicU64,
    /// Frames a second over the last second, times 100.
    pub fps_x100: AtomicU64,
    /// The camera's preview picture's file name in the socket directory, once the hub names one.
    pub preview: std::sync::OnceLock<String>,
}

/// A plain copy of [`CameraCounters`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CameraSnapshot {
    /// Frames the helper reported.
    pub frames: u64,
    /// Frames in which no hand was found.
    pub empty_frames: u64,
    /// Capture to sample of the last frame, microseconds.
    pub latency_us: u64,
    /// The model's time on the last frame, microseconds.
    pub model_us: u64,
    /// Times the helper was started.
    pub starts: u64,
    /// Frames a second over the last second.
    pub fps: f64,
}

impl CameraCounters {
    /// The figures for `frond status`: `None` before the helper's first frame (and for sources
    /// that are no camera).
    pub fn status(&self) -> Option<frond_protocol::CameraStatus> {
        let s = self.snapshot();
        (s.starts > 0).then_some(frond_protocol::CameraStatus {
            frames: s.frames,
            empty_frames: s.empty_frames,
            fps: s.fps,
            latency_ms: s.latency_us as f64 / 1000.0,
            model_ms: s.model_us as f64 / 1000.0,
            helper_starts: s.starts,
            preview: self.preview.get().cloned(),
        })
    }

    /// A copy of the figures.
    pub fn snapshot(&self) -> CameraSnapshot {
        let r = |a: &AtomicU64| a.load(Ordering::Relaxed);
        CameraSnapshot {
            frames: r(&self.frames),
            empty_frames: r(&self.empty_frames),
            latency_us: r(&self.latency_us),
            model_us: r(&self.model_us),
            starts: r(&self.starts),
            fps: r(&self.fps_x100) as f64 / 100.0,
        }
    }
}

/// A plain copy of [`SourceCounters`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CountersSnapshot {
    /// Reports accepted.
    pub reports: u64,
    /// Reports with the wrong report id.
    pub wrong_id: u64,
    /// Reports shorter than the profile's `report_len`.
    pub short: u64,
    /// Reports longer than the profile's `report_len`.
    pub oversized: u64,
    /// Reports whose checksum did not match.
    pub checksum: u64,
    /// Reports with a channel outside its physical range.
    pub out_of_range: u64,
    /// Messages that could not be decoded at all (OSC input).
    pub malformed: u64,
    /// Messages listing more items than a frame may (Leap hands).
    pub too_many: u64,
    /// Connections to a hand service dropped because it did not read.
    pub peers_dropped: u64,
    /// Reports missing between consecutive accepted reports, from the sequence field.
    pub seq_gaps: u64,
}

impl SourceCounters {
    /// Reads every counter (relaxed; good for status displays).
    pub fn snapshot(&self) -> CountersSnapshot {
        let r = |a: &AtomicU64| a.load(Ordering::Relaxed);
        CountersSnapshot {
            reports: r(&self.reports),
            wrong_id: r(&self.wrong_id),
            short: r(&self.short),
            oversized: r(&self.oversized),
            checksum: r(&self.checksum),
            out_of_range: r(&self.out_of_range),
            malformed: r(&self.malformed),
            too_many: r(&self.too_many),
            peers_dropped: r(&self.peers_dropped),
            seq_gaps: r(&self.seq_gaps),
        }
    }

    pub(crate) fn bump(a: &AtomicU64, n: u64) {
        a.fetch_add(n, Ordering::Relaxed);
    }
}

impl CountersSnapshot {
    /// All rejected reports.
    pub fn rejected(&self) -> u64 {
        self.by_reason().iter().map(|&(_, n)| n).sum()
    }

    /// Rejected reports by reason, every reason (zero or not), in a fixed order: the names
    /// `frond status --json` shows them by.
    pub fn by_reason(&self) -> [(&'static str, u64); 7] {
        [
            ("wrong_id", self.wrong_id),
            ("short", self.short),
            ("oversized", self.oversized),
            ("checksum", self.checksum),
            ("out_of_range", self.out_of_range),
            ("malformed", self.malformed),
            ("too_many", self.too_many),
        ]
    }
}

/// Parses reports according to a [`DeviceProfile`]; keeps the sequence and time-unwrapping state.
#[derive(Debug)]
pub struct ReportParser {
    report_id: Option<u8>,
    report_len: usize,
    sequence: Option<(usize, crate::profile::FieldType)>,
    time: Option<crate::profile::TimeField>,
    checksum: Option<ChecksumKind>,
    status_offset: Option<usize>,
    /// Channels indexed by [`ChannelId::slot`].
    channels: [Option<Channel>; 10],
    counters: Arc<SourceCounters>,
    last_seq: Option<u32>,
    local_seq: u32,
    /// Last raw time value and the unwrapped microseconds it maps to.
    last_time: Option<(u32, u64)>,
    created: Instant,
}

impl ReportParser {
    /// A parser for `profile` with fresh counters.
    pub fn new(profile: &DeviceProfile) -> Self {
        Self::with_counters(profile, Arc::new(SourceCounters::default()))
    }

    /// A parser for `profile` that counts into `counters`.
    pub fn with_counters(profile: &DeviceProfile, counters: Arc<SourceCounters>) -> Self {
        let mut channels = [None; 10];
        for c in &profile.channels {
            channels[c.id.slot()] = Some(*c);
        }
        Self {
            report_id: profile.report_id,
            report_len: profile.report_len,
            sequence: profile.sequence.map(|s| (s.offset, s.ty)),
            time: profile.device_time,
            checksum: profile.checksum.map(|c| c.kind),
            status_offset: profile.status_offset,
            channels,
            counters,
            last_seq: None,
            local_seq: 0,
            last_time: None,
            created: Instant::now(),
        }
    }

    /// The counters this parser updates.
    pub fn counters(&self) -> Arc<SourceCounters> {
        Arc::clone(&self.counters)
    }

    /// Report length the profile expects (id byte included).
    pub fn report_len(&self) -> usize {
        self.report_len
    }

    /// Parses one report. Rejected reports are counted and returned as errors; accepted ones
    /// update the sequence-gap and time-unwrapping state. Never allocates, never panics.
    pub fn parse(&mut self, bytes: &[u8]) -> Result<DeviceSample, ReportError> {
        match self.parse_inner(bytes) {
            Ok(s) => {
                SourceCounters::bump(&self.counters.reports, 1);
                Ok(s)
            }
            Err(e) => {
                let c = &self.counters;
                let counter = match e {
                    ReportError::WrongId { .. } => &c.wrong_id,
                    ReportError::Short { .. } => &c.short,
                    ReportError::Oversized { .. } => &c.oversized,
                    ReportError::Checksum => &c.checksum,
                    ReportError::OutOfRange(_) => &c.out_of_range,
                };
                SourceCounters::bump(counter, 1);
                Err(e)
            }
        }
    }

    fn parse_inner(&mut self, bytes: &[u8]) -> Result<DeviceSample, ReportError> {
        let expected = self.report_len;
        if bytes.is_empty() {
            return Err(ReportError::Short { len: 0, expected });
        }
        if let Some(id) = self.report_id
            && bytes[0] != id
        {
            return Err(ReportError::WrongId { got: bytes[0], expected: id });
        }
        if bytes.len() < expected {
            return Err(ReportError::Short { len: bytes.len(), expected });
        }
        if bytes.len() > expected {
            return Err(ReportError::Oversized { len: bytes.len(), expected });
        }
        if let Some(ChecksumKind::Sum8) = self.checksum
            && sum8(bytes) != 0
        {
            return Err(ReportError::Checksum);
        }
        // Profile validation guarantees every offset + size <= report_len == bytes.len().
        let mut values = [0.0f32; 10];
        for c in self.channels.iter().flatten() {
            let v = c.ty.read_f64(bytes, c.offset) / c.divisor;
            // `!(a <= v && v <= b)` also rejects NaN.
            if !(c.min <= v && v <= c.max) {
                return Err(ReportError::OutOfRange(c.id));
            }
            values[c.id.slot()] = match c.unit {
                AngleUnit::Deg => v as f32,
                AngleUnit::Rad => v.to_degrees() as f32,
            };
        }
        let device_seq = match self.sequence {
            Some((offset, ty)) => {
                let seq = ty.read_u32(bytes, offset);
                self.track_seq(seq, ty.bits());
                seq
            }
            None => {
                self.local_seq = self.local_seq.wrapping_add(1);
                self.local_seq
            }
        };
        let device_time_us = match self.time {
            Some(tf) => {
                let raw = tf.ty.read_u32(bytes, tf.offset);
                let ticks = self.unwrap_time(raw, tf.ty.bits());
                match tf.unit {
                    TimeUnit::Us => ticks,
                    TimeUnit::Ms => ticks.saturating_mul(1000),
                }
            }
            // No device clock: fall back to host monotonic time since the parser was created.
            None => self.created.elapsed().as_micros() as u64,
        };
        let status = match self.status_offset {
            Some(o) => bytes[o],
            None => 1,
        };
        Ok(DeviceSample {
            device_seq,
            device_time_us,
            raw: HandSample {
                t: device_time_us as f64 / 1e6,
                wrist_deg: [values[0], values[1], values[2]],
                thumb_deg: [values[3], values[4], values[5]],
            },
            flex_deg: [values[6], values[7], values[8], values[9]],
            status,
        })
    }

    fn track_seq(&mut self, seq: u32, bits: u32) {
        let mask: u32 = if bits >= 32 { u32::MAX } else { (1u32 << bits) - 1 };
        if let Some(last) = self.last_seq {
            let diff = seq.wrapping_sub(last) & mask;
            let half = (mask >> 1) + 1;
            if diff > 1 && diff < half {
                SourceCounters::bump(&self.counters.seq_gaps, u64::from(diff - 1));
            }
        }
        self.last_seq = Some(seq);
    }

    fn unwrap_time(&mut self, raw: u32, bits: u32) -> u64 {
        let mask: u32 = if bits >= 32 { u32::MAX } else { (1u32 << bits) - 1 };
        let unwrapped = match self.last_time {
            None => u64::from(raw),
            Some((last_raw, last)) => {
                let delta = raw.wrapping_sub(last_raw) & mask;
                last.wrapping_add(u64::from(delta))
            }
        };
        self.last_time = Some((raw, unwrapped));
        unwrapped
    }

    /// Forgets sequence and time history (e.g. after the device was replugged and restarted).
    pub fn reset_history(&mut self) {
        self.last_seq = None;
        self.last_time = None;
    }
}

/// 8-bit wrapping sum of `bytes`: a report passes the `sum8` checksum when this is 0
/// (the reference glove's last byte makes it so).
pub fn sum8(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |s, b| s.wrapping_add(*b))
}
