//! `--rate` resampling: send at most one frame per output tick, always the newest one, and never a
//! frame that was already sent.
//!
//! The daemon publishes at its tick rate (1 kHz by default); a DCC tool usually wants 30-120 Hz.
//! At each output tick the newest pose received since the previous tick is emitted (per element);
//! the ones it replaced are counted as `superseded`. When nothing new arrived (the daemon stalled,
//! or publishes slower than `--rate`) the tick emits nothing and is counted as `idle`: a stale
//! frame is never replayed as if it were new, so a receiver's own hold logic sees the truth. The
//! poses are forwarded unchanged (their `seq`, times and flags are the daemon's), so held or
//! device-lost frames keep their flags.
//!
//! Ticks are on an absolute schedule (`start + k * period`); after a stall longer than one period
//! the schedule skips the missed ticks instead of bursting.

use frond_protocol::Pose;

/// Counters of the resampler.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ResampleCounters {
    /// Poses pushed in.
    pub received: u64,
    /// Poses emitted.
    pub emitted: u64,
    /// Poses replaced by a newer one before their tick.
    pub superseded: u64,
    /// Ticks with nothing new to send.
    pub idle_ticks: u64,
    /// Ticks skipped because the caller polled late by more than a period.
    pub missed_ticks: u64,
}

#[derive(Debug, Clone, Copy)]
struct Slot {
    pose: Pose,
    fresh: bool,
}

/// Keeps the newest pose per element and releases it on an output clock.
#[derive(Debug, Clone)]
pub struct Resampler {
    period_ns: u64,
    next_tick_ns: Option<u64>,
    slots: Vec<Slot>,
    counters: ResampleCounters,
}

/// Output ticks: at most 10 kHz, at least 0.1 Hz.
pub const RATE_RANGE_HZ: std::ops::RangeInclusive<f64> = 0.1..=10_000.0;

impl Resampler {
    /// A resampler emitting at `rate_hz` (must be within [`RATE_RANGE_HZ`]; checked by the caller).
    pub fn new(rate_hz: f64) -> Resampler {
        let rate_hz = rate_hz.clamp(*RATE_RANGE_HZ.start(), *RATE_RANGE_HZ.end());
        Resampler {
            period_ns: (1e9 / rate_hz).round() as u64,
            next_tick_ns: None,
            slots: Vec::with_capacity(4),
            counters: ResampleCounters::default(),
        }
    }

    /// The output period, nanoseconds.
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// Counters so far.
    pub fn counters(&self) -> ResampleCounters {
        self.counters
    }

    /// When the next tick is due (monotonic ns), once the first pose has arrived.
    pub fn next_tick_ns(&self) -> Option<u64> {
        self.next_tick_ns
    }

    /// Takes a pose received at `now_ns`. The first pose starts the output clock: it is due at
    /// once.
    pub fn push(&mut self, pose: Pose, now_ns: u64) {
        self.counters.received += 1;
        if self.next_tick_ns.is_none() {
            self.next_tick_ns = Some(now_ns);
        }
        match self.slots.iter_mut().find(|s| s.pose.element == pose.element) {
            Some(slot) => {
                if slot.fresh {
                    self.counters.superseded += 1;
                }
                *slot = Slot { pose, fresh: true };
            }
            None => self.slots.push(Slot { pose, fresh: true }),
        }
    }

    /// At `now_ns`: if a tick is due, calls `emit` with each element's pose that is new since the
    /// previous tick (element order of first appearance) and returns true.
    pub fn poll(&mut self, now_ns: u64, mut emit: impl FnMut(&Pose)) -> bool {
        let Some(due) = self.next_tick_ns else { return false };
        if now_ns < due {
            return false;
        }
        let late_periods = (now_ns - due) / self.period_ns;
        self.counters.missed_ticks += late_periods;
        self.next_tick_ns = Some(due + (late_periods + 1) * self.period_ns);
        let mut any = false;
        for slot in self.slots.iter_mut().filter(|s| s.fresh) {
            slot.fresh = false;
            any = true;
            self.counters.emitted += 1;
            emit(&slot.pose);
        }
        if !any {
            self.counters.idle_ticks += 1;
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_protocol::ElementId;

    fn pose(seq: u64) -> Pose {
        Pose { seq, ..Pose::default() }
    }

    fn collect(r: &mut Resampler, now: u64) -> Vec<u64> {
        let mut out = Vec::new();
        r.poll(now, |p| out.push(p.seq));
        out
    }

    const MS: u64 = 1_000_000;

    #[test]
    fn newest_frame_per_tick_and_no_replay() {
        let mut r = Resampler::new(100.0); // 10 ms
        assert_eq!(r.period_ns(), 10 * MS);
        assert!(!r.poll(0, |_| panic!("nothing yet")));
        r.push(pose(1), 5 * MS);
        assert_eq!(collect(&mut r, 5 * MS), [1], "the first frame goes out at once");
        for seq in 2..=10 {
            r.push(pose(seq), 5 * MS + seq * MS);
        }
        assert_eq!(collect(&mut r, 14 * MS), [] as [u64; 0], "not due before 15 ms");
        assert_eq!(collect(&mut r, 15 * MS), [10], "the newest received by then");
        r.push(pose(11), 16 * MS);
        assert_eq!(collect(&mut r, 24 * MS), [] as [u64; 0]);
        assert_eq!(collect(&mut r, 25 * MS), [11]);
        // Nothing new: the tick emits nothing rather than replaying 11.
        assert_eq!(collect(&mut r, 35 * MS), [] as [u64; 0]);
        assert_eq!(collect(&mut r, 45 * MS), [] as [u64; 0]);
        let c = r.counters();
        assert_eq!((c.received, c.emitted, c.idle_ticks), (11, 3, 2));
        // 2..=9 were replaced before their tick (10 was emitted, 11 was emitted later).
        assert_eq!(c.superseded, 8);
    }

    #[test]
    fn late_polls_skip_ticks_instead_of_bursting() {
        let mut r = Resampler::new(1000.0); // 1 ms
        r.push(pose(1), 0);
        assert_eq!(collect(&mut r, 0), [1]);
        r.push(pose(2), MS / 2);
        // Polled 5.5 ms late: one emission, 4 missed ticks (1..=4 ms), next due at 6 ms.
        assert_eq!(collect(&mut r, 5 * MS + MS / 2), [2]);
        assert_eq!(r.counters().missed_ticks, 4);
        assert_eq!(r.next_tick_ns(), Some(6 * MS));
    }

    #[test]
    fn elements_are_resampled_separately() {
        let mut r = Resampler::new(50.0);
        r.push(Pose { seq: 1, element: ElementId::GLOBAL, ..Pose::default() }, 0);
        r.push(Pose { seq: 1, element: ElementId::new(3), ..Pose::default() }, 0);
        r.push(Pose { seq: 2, element: ElementId::GLOBAL, ..Pose::default() }, 1);
        let mut got = Vec::new();
        r.poll(2, |p| got.push((p.element.get(), p.seq)));
        assert_eq!(got, [(0, 2), (3, 1)]);
    }
}
