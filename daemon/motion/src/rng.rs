//! The one seeded random number generator of the motion toolkit.
//!
//! ChaCha8 (a fixed, specified stream cipher) seeded with `seed_from_u64`, and every draw derived
//! from whole `u64` outputs with integer arithmetic or exact scaling, so the same seed gives the
//! same animation on every run and platform (no float-dependent rejection loops, no
//! platform-sized integers).

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{RngCore, SeedableRng};

/// A deterministic random source. `Clone` so a playback can be forked; no heap.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SeededRng(ChaCha8Rng);

impl SeededRng {
    /// A generator from a user seed (`--seed S`).
    pub fn new(seed: u64) -> Self {
        SeededRng(ChaCha8Rng::seed_from_u64(seed))
    }

    /// The next raw 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `[0, 1)`, 53 random bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[lo, hi)` (or `lo` when the range is empty).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// An index in `0..n` (0 when `n` is 0), by the multiply-shift method (bias below 2^-32 for
    /// any `n` that fits in 32 bits).
    pub fn below(&mut self, n: usize) -> usize {
        ((self.next_u64() as u128 * n as u128) >> 64) as usize
    }

    /// A fair coin.
    pub fn coin(&mut self) -> bool {
        self.next_u64() >> 63 == 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream_different_seed_different_stream() {
        let a: Vec<u64> = (0..8).scan(SeededRng::new(7), |r, _| Some(r.next_u64())).collect();
        let b: Vec<u64> = (0..8).scan(SeededRng::new(7), |r, _| Some(r.next_u64())).collect();
        let c: Vec<u64> = (0..8).scan(SeededRng::new(8), |r, _| Some(r.next_u64())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn draws_stay_in_range_and_cover_it() {
        let mut r = SeededRng::new(1);
        let mut seen = [0usize; 5];
        let mut heads = 0;
        for _ in 0..5000 {
            let u = r.unit();
            assert!((0.0..1.0).contains(&u));
            let x = r.range(0.9, 1.1);
            assert!((0.9..1.1).contains(&x));
            seen[r.below(5)] += 1;
            heads += r.coin() as usize;
        }
        assert!(seen.iter().all(|&n| n > 800), "{seen:?}");
        assert!((2300..2700).contains(&heads), "{heads}");
        assert_eq!(r.below(0), 0);
    }
}
