//! From audio samples to LTC bits: transitions, then biphase-mark bits from the intervals
//! between transitions.
//!
//! LTC is biphase mark code: the level changes at every bit boundary, and once more in the
//! middle of a `1`. So a `0` is one long interval between transitions and a `1` two short
//! ones; which level the signal sits at means nothing. Reading intervals rather than levels
//! is what makes the decoder indifferent to polarity (an inverted cable) and to level (a
//! quiet or hot feed): the threshold follows the signal's own envelope, and the moment of a
//! transition is where the signal crosses its running mean, interpolated between samples, so
//! that even at 8 kHz (under two samples a half bit) the intervals stay sharp.

/// Thresholds never fall below this (full scale is 1.0): digital silence makes no edges.
const MIN_THRESHOLD: f32 = 0.002;
/// The hysteresis threshold, as a fraction of the envelope.
const THRESHOLD_OF_ENVELOPE: f32 = 0.3;

/// Finds level transitions in a mono signal, with hysteresis around its running mean.
#[derive(Debug, Clone)]
pub(crate) struct EdgeDetector {
    mean: f32,
    mean_alpha: f32,
    envelope: f32,
    envelope_decay: f32,
    above: bool,
    prev: f32,
    pending: Option<f64>,
    index: u64,
}

impl EdgeDetector {
    /// A detector whose mean follows over about 8 bits and whose envelope over half a frame,
    /// for bits of `bit_samples` samples.
    pub(crate) fn new(bit_samples: f64) -> EdgeDetector {
        EdgeDetector {
            mean: 0.0,
            mean_alpha: (1.0 / (8.0 * bit_samples)) as f32,
            envelope: 0.0,
            envelope_decay: (-1.0 / (40.0 * bit_samples)).exp() as f32,
            above: false,
            prev: 0.0,
            pending: None,
            index: 0,
        }
    }

    /// Takes the next sample; returns the time (in samples since the first, fractional) of a
    /// transition it confirms.
    pub(crate) fn push(&mut self, x: f32) -> Option<f64> {
        let x = if x.is_finite() { x.clamp(-4.0, 4.0) } else { 0.0 };
        let i = self.index;
        self.index += 1;
        let c = x - self.mean;
        self.mean += self.mean_alpha * c;
        self.envelope = c.abs().max(self.envelope * self.envelope_decay);
        let threshold = (THRESHOLD_OF_ENVELOPE * self.envelope).max(MIN_THRESHOLD);
        let crossed_down = self.above && self.prev >= 0.0 && c < 0.0;
        let crossed_up = !self.above && self.prev <= 0.0 && c > 0.0;
        if crossed_down || crossed_up {
            // Linear interpolation of the crossing between samples i - 1 and i.
            let fraction = f64::from(self.prev) / f64::from(self.prev - c);
            self.pending = Some(i as f64 - 1.0 + fraction.clamp(0.0, 1.0));
        }
        self.prev = c;
        let confirmed = if self.above { c < -threshold } else { c > threshold };
        if confirmed {
            self.above = !self.above;
            return Some(self.pending.take().unwrap_or(i as f64));
        }
        None
    }

    /// Samples taken so far.
    pub(crate) fn samples(&self) -> u64 {
        self.index
    }
}

/// What an interval between two transitions meant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum BitEvent {
    /// Nothing yet (the first half of a `1`).
    None,
    /// A whole bit.
    Bit(bool),
    /// An interval no LTC bit has: the bit stream lost its phase.
    Invalid,
}

/// Turns transition times into bits, following the bit period as it drifts (tape speed,
/// clock differences) within the LTC rates' range.
#[derive(Debug, Clone)]
pub(crate) struct BitClock {
    last_edge: Option<f64>,
    period: f64,
    min_period: f64,
    max_period: f64,
    half_pending: bool,
}

impl BitClock {
    /// A clock for `sample_rate_hz`, starting between 24 fps (1920 bit/s) and 30 fps (2400).
    pub(crate) fn new(sample_rate_hz: u32) -> BitClock {
        let sr = f64::from(sample_rate_hz);
        BitClock {
            last_edge: None,
            period: sr / 2160.0,
            min_period: sr / 2700.0,
            max_period: sr / 1700.0,
            half_pending: false,
        }
    }

    /// The current estimate of a bit's length, in samples.
    pub(crate) fn period(&self) -> f64 {
        self.period
    }

    /// Takes the next transition time.
    pub(crate) fn edge(&mut self, t: f64) -> BitEvent {
        let Some(last) = self.last_edge.replace(t) else { return BitEvent::None };
        let interval = t - last;
        if !(interval > 0.3 * self.period && interval < 1.5 * self.period) {
            self.half_pending = false;
            return BitEvent::Invalid;
        }
        if interval >= 0.75 * self.period {
            self.follow(interval);
            // A long interval after a lone half means the halves were paired across a bit
            // boundary; this interval is still a whole `0`, and pairing restarts after it.
            self.half_pending = false;
            return BitEvent::Bit(false);
        }
        self.follow(2.0 * interval);
        if self.half_pending {
            self.half_pending = false;
            BitEvent::Bit(true)
        } else {
            self.half_pending = true;
            BitEvent::None
        }
    }

    fn follow(&mut self, measured: f64) {
        self.period = (self.period + 0.1 * (measured - self.period)).clamp(self.min_period, self.max_period);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_become_bits_whatever_the_polarity() {
        for sign in [1.0f32, -1.0] {
            // 48 kHz, 2000 bit/s: 24 samples a bit. Bits 0, 1, 1, 0 as levels; whether the first
            // level counts as a transition depends on the polarity, so only the last three bits,
            // whole in both, are compared.
            let levels: Vec<f32> =
                [(24, 1.0), (12, -1.0), (12, 1.0), (12, -1.0), (12, 1.0), (24, -1.0), (24, 1.0)]
                    .iter()
                    .flat_map(|&(n, v)| std::iter::repeat_n(v * sign * 0.5, n))
                    .collect();
            let mut edges = EdgeDetector::new(24.0);
            let mut clock = BitClock::new(48_000);
            let bits: Vec<bool> = levels
                .iter()
                .filter_map(|&x| edges.push(x))
                .filter_map(|t| match clock.edge(t) {
                    BitEvent::Bit(b) => Some(b),
                    _ => None,
                })
                .collect();
            assert!(bits.ends_with(&[true, true, false]), "sign {sign}: {bits:?}");
        }
    }

    #[test]
    fn an_impossible_interval_is_invalid() {
        let mut clock = BitClock::new(48_000);
        assert_eq!(clock.edge(0.0), BitEvent::None);
        assert_eq!(clock.edge(200.0), BitEvent::Invalid);
        assert_eq!(clock.edge(201.0), BitEvent::Invalid);
    }
}
