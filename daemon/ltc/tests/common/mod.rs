//! What the decoding and allocation tests share beside the crate's encoder
//! (`frond_ltc::encode`, written from the SMPTE 12M layout): noise.

#![allow(dead_code)]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub fn add_noise(samples: &mut [f32], level: f32, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for s in samples {
        *s += rng.random_range(-level..=level);
    }
}
