//! Lock-free statistics written by the realtime loop and read by the status thread.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering::Relaxed};

use frond_protocol::{HistogramBucket, LatencySummary};

const SUB_BITS: u32 = 4;
const SUB: usize = 1 << SUB_BITS;
const GROUPS: usize = 64 - SUB_BITS as usize + 1;

/// A log-linear histogram of nanosecond values (about 6% resolution), updated without locks.
///
/// Only one thread records (the loop), any thread may read. Values are bucketed by their highest
/// set bit, then by the next `SUB_BITS` bits.
pub struct LatencyHistogram {
    buckets: Box<[AtomicU64]>,
    max_ns: AtomicU64,
    count: AtomicU64,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyHistogram {
    /// An empty histogram (allocates once, here).
    pub fn new() -> Self {
        LatencyHistogram {
            buckets: (0..GROUPS * SUB).map(|_| AtomicU64::new(0)).collect(),
            max_ns: AtomicU64::new(0),
            count: AtomicU64::new(0),
        }
    }

    fn index(v: u64) -> usize {
        if v < SUB as u64 {
            return v as usize;
        }
        let msb = 63 - v.leading_zeros();
        let group = (msb - SUB_BITS + 1) as usize;
        let sub = ((v >> (msb - SUB_BITS)) & (SUB as u64 - 1)) as usize;
        group * SUB + sub
    }

    /// Lower bound of the values that land in bucket `i`.
    fn lower(i: usize) -> u64 {
        let (group, sub) = (i / SUB, (i % SUB) as u64);
        if group == 0 {
            return sub;
        }
        let shift = group as u32 - 1;
        ((SUB as u64) | sub) << shift
    }

    /// Records one value. Never allocates.
    pub fn record(&self, v: u64) {
        self.buckets[Self::index(v)].fetch_add(1, Relaxed);
        self.count.fetch_add(1, Relaxed);
        self.max_ns.fetch_max(v, Relaxed);
    }

    /// Number of values recorded.
    pub fn count(&self) -> u64 {
        self.count.load(Relaxed)
    }

    /// The value at quantile `q` (0..=1), as the midpoint of its bucket; 0 when empty.
    pub fn quantile_ns(&self, q: f64) -> u64 {
        let counts: Vec<u64> = self.buckets.iter().map(|b| b.load(Relaxed)).collect();
        let total: u64 = counts.iter().sum();
        if total == 0 {
            return 0;
        }
        let rank = ((q.clamp(0.0, 1.0) * total as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, c) in counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                let lo = Self::lower(i);
                let hi = if i + 1 < counts.len() { Self::lower(i + 1) } else { lo };
                return (lo + hi.saturating_sub(1).max(lo)) / 2;
            }
        }
        self.max_ns.load(Relaxed)
    }

    /// The values in log2 buckets of microseconds: upper bounds 1, 2, 4, ... up to 2^20 us (about
    /// 1 s), then one unbounded bucket; each fine bucket counted in the coarse one that holds its
    /// middle.
    pub fn log2_buckets_us(&self) -> Vec<HistogramBucket> {
        const TOP: u32 = 20;
        let mut counts = vec![0u64; TOP as usize + 2];
        for (i, b) in self.buckets.iter().enumerate() {
            let n = b.load(Relaxed);
            if n == 0 {
                continue;
            }
            // The fine bucket's middle, as `quantile_ns` reports it; the smallest k with
            // middle <= 2^k us.
            let lo = Self::lower(i);
            let hi = if i + 1 < self.buckets.len() { Self::lower(i + 1) } else { lo };
            let mid = (lo + hi.saturating_sub(1).max(lo)) / 2;
            let k = (0..=TOP).find(|&k| mid <= 1000u64 << k).unwrap_or(TOP + 1);
            counts[k as usize] += n;
        }
        counts
            .iter()
            .enumerate()
            .map(|(k, &count)| HistogramBucket {
                le_us: (k as u32 <= TOP).then(|| f64::from(1u32 << k)),
                count,
            })
            .collect()
    }

    /// p50/p99/p99.9/max in microseconds.
    pub fn summary(&self) -> LatencySummary {
        let us = |ns: u64| ns as f64 / 1000.0;
        let max = self.max_ns.load(Relaxed);
        LatencySummary {
            p50_us: us(self.quantile_ns(0.5).min(max)),
            p99_us: us(self.quantile_ns(0.99).min(max)),
            p999_us: us(self.quantile_ns(0.999).min(max)),
            max_us: us(max),
            samples: self.count(),
        }
    }
}

/// The latest raw hand sample, published by the loop through a sequence lock (no mutex) for
/// `frond calibrate`.
#[derive(Default)]
pub struct RawSampleCell {
    version: AtomicU64,
    t_bits: AtomicU64,
    values: [AtomicU32; 6],
    fresh: AtomicBool,
}

impl RawSampleCell {
    /// Publishes a sample (loop thread only).
    pub fn store(&self, t: f64, wrist: [f32; 3], thumb: [f32; 3]) {
        self.version.fetch_add(1, std::sync::atomic::Ordering::AcqRel);
        self.t_bits.store(t.to_bits(), Relaxed);
        for (cell, v) in self.values.iter().zip(wrist.iter().chain(thumb.iter())) {
            cell.store(v.to_bits(), Relaxed);
        }
        self.fresh.store(true, Relaxed);
        self.version.fetch_add(1, std::sync::atomic::Ordering::AcqRel);
    }

    /// Marks the value stale (device lost).
    pub fn set_stale(&self) {
        self.fresh.store(false, Relaxed);
    }

    /// Reads a consistent copy: `(t, wrist, thumb, fresh)`, or `None` before the first sample.
    pub fn load(&self) -> Option<(f64, [f32; 3], [f32; 3], bool)> {
        loop {
            let v1 = self.version.load(std::sync::atomic::Ordering::Acquire);
            if v1 == 0 {
                return None;
            }
            if v1 % 2 == 1 {
                std::hint::spin_loop();
                continue;
            }
            let t = f64::from_bits(self.t_bits.load(Relaxed));
            let vals: [f32; 6] = std::array::from_fn(|i| f32::from_bits(self.values[i].load(Relaxed)));
            let fresh = self.fresh.load(Relaxed);
            if self.version.load(std::sync::atomic::Ordering::Acquire) == v1 {
                return Some((t, [vals[0], vals[1], vals[2]], [vals[3], vals[4], vals[5]], fresh));
            }
        }
    }
}

/// Counters shared between the loop (writer) and the status/housekeeping threads (readers).
#[derive(Default)]
pub struct LoopStats {
    /// Ticks run.
    pub ticks: AtomicU64,
    /// Ticks that republished a held pose.
    pub held_ticks: AtomicU64,
    /// Times the device's ready descriptor woke the loop between ticks.
    pub device_wakes: AtomicU64,
    /// Next pose sequence number.
    pub next_seq: AtomicU64,
    /// Frames not handed to a subscriber queue or the recorder because it was full.
    pub publish_drops: AtomicU64,
    /// Frames the recorder queue refused.
    pub record_drops: AtomicU64,
    /// Frames handed to the recorder.
    pub recorded_frames: AtomicU64,
    /// Ticks where the loop woke more than one period late and skipped deadlines.
    pub overruns: AtomicU64,
    /// True while the loop forwards frames to the recorder.
    pub recording: AtomicBool,
    /// Wake-up lateness.
    pub lateness: LatencyHistogram,
    /// Each hand source's own counters, by its index in the configuration (only the first
    /// `hands` configured are used).
    pub hands: [HandStats; crate::handoff::MAX_HANDS],
}

/// One hand source's counters, written by the loop.
#[derive(Default)]
pub struct HandStats {
    /// True while the source delivers reports.
    pub connected: AtomicBool,
    /// Times the source was declared lost.
    pub lost_events: AtomicU64,
    /// Times the source stalled (open, but no reports).
    pub stall_events: AtomicU64,
    /// Frames published from its reports.
    pub frames: AtomicU64,
    /// Held frames published for it (a period without a report).
    pub held_frames: AtomicU64,
    /// Reports whose time broke the timeline (jumped, went back, repeated): filter reset.
    pub discontinuities: AtomicU64,
    /// Stale reports skipped when the loop resumed after a pause (SIGSTOP, an overloaded host).
    pub stale_skipped: AtomicU64,
    /// Latest raw sample, for calibration.
    pub raw: RawSampleCell,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log2_buckets_count_every_value_once_where_it_falls() {
        let h = LatencyHistogram::new();
        for ns in [400, 700, 3_000, 3_000, 900_000, 5_000_000_000] {
            h.record(ns);
        }
        let b = h.log2_buckets_us();
        assert_eq!(b.len(), 22);
        assert_eq!(b.iter().map(|x| x.count).sum::<u64>(), 6);
        assert_eq!((b[0].le_us, b[0].count), (Some(1.0), 2), "0.4 and 0.7 us");
        assert_eq!((b[2].le_us, b[2].count), (Some(4.0), 2), "3 us twice");
        assert_eq!(b[10].count, 1, "900 us is at most 1024 us");
        assert_eq!((b[21].le_us, b[21].count), (None, 1), "5 s past the last bound");
    }

    #[test]
    fn bucket_bounds_contain_their_values() {
        for v in [0u64, 1, 15, 16, 17, 31, 32, 1000, 123_456, 10_000_000_000] {
            let i = LatencyHistogram::index(v);
            assert!(LatencyHistogram::lower(i) <= v, "v={v}");
            assert!(LatencyHistogram::lower(i + 1) > v, "v={v}");
        }
    }

    #[test]
    fn quantiles_of_a_known_distribution() {
        let h = LatencyHistogram::new();
        // 1..=1000 microseconds, once each: p50 ~ 500 us, p99 ~ 990 us within the 6% resolution.
        for us in 1..=1000u64 {
            h.record(us * 1000);
        }
        let s = h.summary();
        assert!((s.p50_us - 500.0).abs() < 500.0 * 0.07, "{s:?}");
        assert!((s.p99_us - 990.0).abs() < 990.0 * 0.07, "{s:?}");
        assert_eq!(s.max_us, 1000.0);
        assert_eq!(s.samples, 1000);
    }

    #[test]
    fn raw_cell_round_trips() {
        let c = RawSampleCell::default();
        assert!(c.load().is_none());
        c.store(1.5, [1.0, 2.0, 3.0], [4.0, 5.0, 6.0]);
        assert_eq!(c.load(), Some((1.5, [1.0, 2.0, 3.0], [4.0, 5.0, 6.0], true)));
        c.set_stale();
        assert!(!c.load().unwrap().3);
    }
}
