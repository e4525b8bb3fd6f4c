//! An LTC encoder written from the SMPTE 12M bit layout: frame labels to the biphase-mark
//! signal a timecode generator sends. The decoder's tests play it (with noise, speed errors and
//! dropouts added), and `frond bench` plays it to a daemon; it is not the decoder run backwards.
//!
//! 80 bits a frame, BCD fields least significant bit first (frame units 0-3, frame tens 8-9,
//! drop-frame flag 10, seconds 16-19 / 24-26, minutes 32-35 / 40-42, hours 48-51 / 56-57),
//! user bits in the 4-bit groups at 4, 12, ..., 60, the polarity-correction bit (27, or 59 at
//! 25 fps) making the count of ones even, and the sync word 0011 1111 1111 1101 in bits
//! 64-79; then biphase mark: the level flips at every bit start and in the middle of every 1;
//! edges rise over 40 us as SMPTE 12M allows (25 +- 5 us to 10-90 %, widened here so 8 kHz
//! still sees a slope).

use crate::{FrameRate, SmpteTime};

/// Frame labels at `rate` from frame count `start`, `n` of them, as the frame counter sees them.
pub fn labels(rate: FrameRate, start: u32, n: u32) -> Vec<SmpteTime> {
    (start..start + n).map(|c| rate.from_frame_count(c)).collect()
}

/// The 80 bits of frame `t` (with user bits `user`) in transmission order.
pub fn frame_bits(rate: FrameRate, t: SmpteTime, user: u32) -> [bool; 80] {
    let mut bits = [false; 80];
    let mut put = |at: usize, width: usize, value: u32| {
        for i in 0..width {
            bits[at + i] = value >> i & 1 == 1;
        }
    };
    let (f, s, m, h) = (u32::from(t.frames), u32::from(t.seconds), u32::from(t.minutes), u32::from(t.hours));
    put(0, 4, f % 10);
    put(8, 2, f / 10);
    put(10, 1, u32::from(rate == FrameRate::Fps2997Df));
    put(16, 4, s % 10);
    put(24, 3, s / 10);
    put(32, 4, m % 10);
    put(40, 3, m / 10);
    put(48, 4, h % 10);
    put(56, 2, h / 10);
    for (i, at) in [4, 12, 20, 28, 36, 44, 52, 60].into_iter().enumerate() {
        put(at, 4, user >> (4 * i) & 0xF);
    }
    for (i, b) in "0011111111111101".bytes().enumerate() {
        bits[64 + i] = b == b'1';
    }
    let parity_at = if rate == FrameRate::Fps25 { 59 } else { 27 };
    bits[parity_at] = bits.iter().filter(|&&b| b).count() % 2 == 1;
    bits
}

/// Transition times (seconds) of the biphase-mark signal for these frames, from time 0, and
/// the one that starts whatever follows them.
pub fn edges(rate: FrameRate, frames: &[(SmpteTime, u32)]) -> Vec<f64> {
    edges_at_speed(rate, frames, 1.0)
}

/// [`edges`] played `speed` times as fast (a generator or tape off its nominal speed).
pub fn edges_at_speed(rate: FrameRate, frames: &[(SmpteTime, u32)], speed: f64) -> Vec<f64> {
    let bit_s = 1.0 / (80.0 * rate.fps() * speed);
    let mut out = Vec::new();
    for (k, &(t, user)) in frames.iter().enumerate() {
        for (i, bit) in frame_bits(rate, t, user).into_iter().enumerate() {
            let start = (k * 80 + i) as f64 * bit_s;
            out.push(start);
            if bit {
                out.push(start + bit_s / 2.0);
            }
        }
    }
    // The transition that starts the bit after the last frame: without it the last bit of
    // the sync word (a 1) has no end, as on a signal that simply stopped.
    out.push((frames.len() * 80) as f64 * bit_s);
    out
}

/// Renders edges to samples: a square wave of amplitude `amp` starting low, each sample the
/// mean of the wave over a 40 us window (the edge's rise), measured on 16 sub-samples.
pub fn render(edges: &[f64], sample_rate: u32, seconds: f64, amp: f32) -> Vec<f32> {
    let n = (seconds * f64::from(sample_rate)) as usize;
    let dt = 1.0 / f64::from(sample_rate);
    let window = 40e-6_f64.max(dt);
    let mut next = 0;
    (0..n)
        .map(|i| {
            let t0 = i as f64 * dt - window / 2.0;
            while next < edges.len() && edges[next] < t0 {
                next += 1;
            }
            let mut sum = 0.0;
            for k in 0..16 {
                let t = t0 + window * (k as f64 + 0.5) / 16.0;
                let flips = next + edges[next..].iter().take_while(|&&e| e <= t).count();
                sum += if flips % 2 == 1 { 1.0 } else { -1.0 };
            }
            amp * (sum / 16.0) as f32
        })
        .collect()
}
