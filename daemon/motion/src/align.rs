//! Alignment of a secondary animation with the global one (seed 000, section 6.5).
//!
//! Per subsequence `j` of `window_s` seconds (2 s in the seed): for each of the 4 parts the bend
//! magnitude `b = sqrt(pitch^2 + yaw^2)`; the frequency `f` is the number of its local extrema
//! (sign changes of the non-zero differences), summed over parts; the amount `A` is the sum over
//! parts of `max(b) - min(b)`. The secondary subsequence is sped up by `r f_G / f_S` and its angles
//! scaled by `r A_G / A_S`, with one `r` uniform in `[0.9, 1.1]` per subsequence. Guards: when
//! `f_S = 0` (a still secondary) the speed is `r`; when `A_S = 0` the scale is `r`; speeds are
//! clamped to `[1/4, 4]` and scales to `[0, 10]`.
//!
//! Walk (the seed: "we count another 2 seconds of secondary data after the end of the processed
//! subsequence as the next; the process path is determined by the animation looping"): output
//! window `j` covers the same `window_s` as global window `j`; its statistics compare global
//! window `j` with the next `window_s` of the secondary stream from the cursor; the output plays
//! the stream from the cursor at the chosen speed (interpolated), so the window still lasts
//! `window_s` but uses `speed x` as many secondary frames, and the cursor moves past them. The
//! secondary stream is its loop playback (Eq. 5, seeded) when transitions are given, else the
//! secondary played once and repeated.

use serde::Serialize;

use crate::clip::{Clip, Joints, lerp_joints};
use crate::controls::shape_pose;
use crate::looping::{LoopPlayer, PlaybackParams, Transitions};
use crate::rng::SeededRng;

/// Range of the random factor `r`.
pub const R_RANGE: (f64, f64) = (0.9, 1.1);

/// Bend magnitude `sqrt(pitch^2 + yaw^2)` of one part, degrees.
pub fn bend_magnitude(a: [f32; 3]) -> f64 {
    (a[0] as f64).hypot(a[1] as f64)
}

/// Number of local extrema of a series: sign changes between consecutive non-zero differences.
pub fn count_extrema(series: &[f64]) -> usize {
    let mut prev = 0.0f64;
    let mut n = 0;
    for w in series.windows(2) {
        let d = w[1] - w[0];
        if d == 0.0 || d.is_nan() {
            continue;
        }
        if prev != 0.0 && (d > 0.0) != (prev > 0.0) {
            n += 1;
        }
        prev = d;
    }
    n
}

/// Frequency and amount of a subsequence (section 6.5).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MotionStats {
    /// Local extrema of the bend magnitude, summed over parts.
    pub frequency: usize,
    /// `max - min` of the bend magnitude, summed over parts, degrees.
    pub amount: f64,
}

/// Statistics of a run of poses.
pub fn motion_stats(frames: &[Joints]) -> MotionStats {
    let mut frequency = 0;
    let mut amount = 0.0;
    for part in 0..4 {
        let b: Vec<f64> = frames.iter().map(|f| bend_magnitude(f[part])).collect();
        frequency += count_extrema(&b);
        let (lo, hi) = b.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| (l.min(x), h.max(x)));
        if hi >= lo {
            amount += hi - lo;
        }
    }
    MotionStats { frequency, amount }
}

/// `(speed, scale) = (r f_G / f_S, r A_G / A_S)` with the guards of the module docs.
pub fn alignment_ratios(g: MotionStats, s: MotionStats, r: f64) -> (f64, f64) {
    let speed = if s.frequency == 0 { r } else { r * g.frequency as f64 / s.frequency as f64 };
    let scale = if s.amount <= 0.0 { r } else { r * g.amount / s.amount };
    (speed.clamp(0.25, 4.0), scale.clamp(0.0, 10.0))
}

/// What alignment did to one subsequence (printed by `frond take align --explain`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AlignStep {
    /// Subsequence index `j`.
    pub index: usize,
    /// Global statistics.
    pub global: MotionStats,
    /// Secondary statistics (before alignment).
    pub secondary: MotionStats,
    /// The random factor.
    pub r: f64,
    /// Speed applied.
    pub speed: f64,
    /// Angle scale applied.
    pub scale: f64,
    /// Secondary stream position at the start of the window, frames.
    pub source_frame: f64,
}

/// Why [`align`] refuses its input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LayerAlignError {
    /// A window that is not a positive number of seconds (the window given).
    #[error("--window must be > 0 seconds, got {0}")]
    BadWindow(f64),
    /// One of the takes has no frames.
    #[error("both takes need frames")]
    NoFrames,
}

/// Aligns `secondary` with `global` (same fps); the output has the global's length.
pub fn align(
    global: &Clip,
    secondary: &Clip,
    transitions: Option<&Transitions>,
    window_s: f64,
    seed: u64,
) -> Result<(Clip, Vec<AlignStep>), LayerAlignError> {
    if !(window_s.is_finite() && window_s > 0.0) {
        return Err(LayerAlignError::BadWindow(window_s));
    }
    if global.is_empty() || secondary.is_empty() {
        return Err(LayerAlignError::NoFrames);
    }
    let fps = global.fps;
    let w = ((window_s * fps).round() as usize).max(2);
    let mut rng = SeededRng::new(seed);
    let mut player =
        transitions.map(|t| LoopPlayer::new(secondary.len(), t, seed ^ 0x5eed, PlaybackParams::default(), 0));
    let mut stream: Vec<Joints> = Vec::new();
    let mut extend_to = |n: usize, stream: &mut Vec<Joints>| {
        while stream.len() < n {
            let j = match player.as_mut() {
                Some(p) => p.next_step(secondary).joints(secondary),
                None => secondary.frames[stream.len() % secondary.len()].joints_deg,
            };
            stream.push(j);
        }
    };
    let at = |stream: &[Joints], f: f64| {
        let k = f.floor() as usize;
        lerp_joints(&stream[k], &stream[(k + 1).min(stream.len() - 1)], f - k as f64)
    };
    let mut out: Vec<Joints> = Vec::with_capacity(global.len());
    let mut steps = Vec::new();
    let mut cursor = 0.0f64;
    let mut j = 0;
    while out.len() < global.len() {
        let g0 = out.len();
        let g1 = (g0 + w).min(global.len());
        let gs: Vec<Joints> = global.frames[g0..g1].iter().map(|f| f.joints_deg).collect();
        let start = cursor.floor() as usize;
        extend_to(start + w + 1, &mut stream);
        let s_stats = motion_stats(&stream[start..start + w]);
        let g_stats = motion_stats(&gs);
        let r = rng.range(R_RANGE.0, R_RANGE.1);
        let (speed, scale) = alignment_ratios(g_stats, s_stats, r);
        let n = g1 - g0;
        extend_to((cursor + speed * n as f64).ceil() as usize + 2, &mut stream);
        for k in 0..n {
            out.push(shape_pose(&at(&stream, cursor + speed * k as f64), scale as f32, 0.0));
        }
        steps.push(AlignStep {
            index: j,
            global: g_stats,
            secondary: s_stats,
            r,
            speed,
            scale,
            source_frame: cursor,
        });
        cursor += speed * n as f64;
        j += 1;
    }
    Ok((Clip::from_joints(out, fps), steps))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part0(values: &[f32]) -> Vec<Joints> {
        values.iter().map(|&v| [[v, 0.0, 0.0], [0.0; 3], [0.0; 3], [0.0; 3]]).collect()
    }

    #[test]
    fn extrema_and_amount_by_hand() {
        assert_eq!(count_extrema(&[0.0, 10.0, 0.0, 10.0, 0.0]), 3);
        // Plateaus are one extremum: up, flat, down.
        assert_eq!(count_extrema(&[0.0, 5.0, 5.0, 0.0]), 1);
        assert_eq!(count_extrema(&[1.0, 2.0, 3.0]), 0);
        assert_eq!(bend_magnitude([3.0, -4.0, 99.0]), 5.0);
        // Part 0 pitch 0, 10, 0, 10, 0: 3 extrema, amount 10; part 1 yaw 0, 3, 6, 3, 0 (via
        // pitch 0 and yaw): 1 extremum, amount 6. Totals f = 4, A = 16.
        let mut f = part0(&[0.0, 10.0, 0.0, 10.0, 0.0]);
        for (k, y) in [0.0, 3.0, 6.0, 3.0, 0.0].into_iter().enumerate() {
            f[k][1] = [0.0, y, 0.0];
        }
        assert_eq!(motion_stats(&f), MotionStats { frequency: 4, amount: 16.0 });
    }

    #[test]
    fn ratios_by_hand() {
        // f_G = 6, f_S = 3, A_G = 20, A_S = 40, r = 1.1: speed 2.2, scale 0.55.
        let (s, a) = alignment_ratios(
            MotionStats { frequency: 6, amount: 20.0 },
            MotionStats { frequency: 3, amount: 40.0 },
            1.1,
        );
        assert!((s - 2.2).abs() < 1e-12 && (a - 0.55).abs() < 1e-12, "{s} {a}");
        // Guards: a still secondary keeps r for both.
        assert_eq!(
            alignment_ratios(
                MotionStats { frequency: 6, amount: 20.0 },
                MotionStats { frequency: 0, amount: 0.0 },
                0.95
            ),
            (0.95, 0.95)
        );
        // Clamps.
        assert_eq!(
            alignment_ratios(
                MotionStats { frequency: 100, amount: 1e6 },
                MotionStats { frequency: 1, amount: 1.0 },
                1.0
            ),
            (4.0, 10.0)
        );
    }

    #[test]
    fn align_speeds_up_and_scales_a_slow_small_secondary() {
        // Global: a fast sway (period 0.5 s) of amplitude 20; secondary: a slow sway (period 2 s)
        // of amplitude 5. Aligned, the secondary sways about 4x as often and 4x as far.
        let g = Clip::from_joints(
            (0..240).map(|k| part0(&[20.0 * (k as f32 / 30.0 * std::f32::consts::TAU * 2.0).sin()])[0]),
            30.0,
        );
        let s = Clip::from_joints(
            (0..240).map(|k| part0(&[5.0 * (k as f32 / 30.0 * std::f32::consts::TAU * 0.5).sin()])[0]),
            30.0,
        );
        let (out, steps) = align(&g, &s, None, 2.0, 4).unwrap();
        assert_eq!(out.len(), 240);
        assert_eq!(steps.len(), 4);
        for st in &steps {
            assert!((R_RANGE.0..R_RANGE.1).contains(&st.r));
            assert!(st.speed > 2.0 && st.scale > 2.5, "{st:?}");
        }
        let stats = motion_stats(&out.frames.iter().map(|f| f.joints_deg).collect::<Vec<_>>());
        let g_stats = motion_stats(&g.frames.iter().map(|f| f.joints_deg).collect::<Vec<_>>());
        assert!(stats.frequency as f64 > 0.6 * g_stats.frequency as f64, "{stats:?} vs {g_stats:?}");
        assert_eq!(align(&g, &s, None, 2.0, 4).unwrap().1, steps);
        assert!(align(&g, &s, None, 0.0, 4).is_err());
    }
}
