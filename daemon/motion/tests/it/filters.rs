//! Filters against hand-computed responses, and the 1€ filter's reason to exist: less lag than a
//! low-pass that removes the same amount of jitter.

use std::f64::consts::PI;

use frond_motion::filter::{LowPass, OneEuro};

#[test]
fn lowpass_step_response_by_hand() {
    // dt = 0.01 s and tau = 1/(2 pi fc) = 0.04 s give alpha = 1/(1 + tau/dt) = 1/(1+4) = 0.2.
    // After a unit step, y_n = 1 - (1 - alpha)^n = 1 - 0.8^n:
    // 0.2, 0.36, 0.488, 0.5904, 0.67232.
    let fc = 1.0 / (2.0 * PI * 0.04);
    let mut lp = LowPass::new(fc as f32);
    assert_eq!(lp.filter(0.0, 0.0), 0.0); // first sample passes through
    let want = [0.2, 0.36, 0.488, 0.5904, 0.67232];
    for (n, w) in want.iter().enumerate() {
        let y = lp.filter((n + 1) as f64 * 0.01, 1.0);
        assert!((y as f64 - w).abs() < 1e-6, "step {}: {y} != {w}", n + 1);
    }
}

#[test]
fn lowpass_rate_comes_from_timestamps() {
    // Same filter (tau = 0.04 s); steps of 0.01 s then 0.03 s.
    // alpha(0.01) = 0.2 -> 0.2; alpha(0.03) = 1/(1 + 4/3) = 3/7 -> 0.2 + 3/7 * 0.8 = 0.542857...
    let mut lp = LowPass::new((1.0 / (2.0 * PI * 0.04)) as f32);
    lp.filter(0.0, 0.0);
    assert!((lp.filter(0.01, 1.0) - 0.2).abs() < 1e-6);
    let y = lp.filter(0.04, 1.0) as f64;
    assert!((y - (0.2 + 3.0 / 7.0 * 0.8)).abs() < 1e-6, "{y}");
}

#[test]
fn one_euro_at_zero_beta_is_a_lowpass_at_min_cutoff() {
    // With beta = 0 the cutoff is always min_cutoff: the 1€ filter must equal the low-pass.
    let mut e = OneEuro::new(2.0, 0.0, 1.0);
    let mut lp = LowPass::new(2.0);
    for k in 0..500 {
        let t = k as f64 * 0.002;
        let x = (t * 7.0).sin() as f32 * 30.0 + if k % 2 == 0 { 0.5 } else { -0.5 };
        assert!((e.filter(t, x) - lp.filter(t, x)).abs() < 1e-4);
    }
}

/// xorshift64*, deterministic noise without a dependency.
struct Noise(u64);
impl Noise {
    /// Uniform in [-a, a].
    fn next(&mut self, a: f64) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let u = (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64;
        (2.0 * u - 1.0) * a
    }
}

const RATE_HZ: f64 = 1000.0;
const NOISE_DEG: f64 = 0.5;

/// Output standard deviation on a constant signal plus noise (after 2 s of settling).
fn jitter(mut f: impl FnMut(f64, f32) -> f32) -> f64 {
    let mut noise = Noise(0x9E37_79B9_7F4A_7C15);
    let mut ys = Vec::new();
    for k in 0..6000 {
        let t = k as f64 / RATE_HZ;
        let y = f(t, (10.0 + noise.next(NOISE_DEG)) as f32) as f64;
        if t >= 2.0 {
            ys.push(y);
        }
    }
    let mean = ys.iter().sum::<f64>() / ys.len() as f64;
    (ys.iter().map(|y| (y - mean).powi(2)).sum::<f64>() / ys.len() as f64).sqrt()
}

/// Mean lag in seconds on a noisy ramp of `slope` deg/s: mean(x_true - y) / slope over the
/// last second of a 3 s ramp.
fn lag(mut f: impl FnMut(f64, f32) -> f32, slope: f64) -> f64 {
    let mut noise = Noise(0xD1B5_4A32_D192_ED03);
    let (mut sum, mut n) = (0.0, 0);
    for k in 0..3000 {
        let t = k as f64 / RATE_HZ;
        let truth = slope * t;
        let y = f(t, (truth + noise.next(NOISE_DEG)) as f32) as f64;
        if t >= 2.0 {
            sum += truth - y;
            n += 1;
        }
    }
    sum / n as f64 / slope
}

#[test]
fn one_euro_lags_less_than_a_lowpass_of_equal_jitter() {
    let (min_cutoff, beta, d_cutoff) = (1.0, 0.05, 1.0);
    let euro_jitter = jitter({
        let mut f = OneEuro::new(min_cutoff, beta, d_cutoff);
        move |t, x| f.filter(t, x)
    });
    // Find the low-pass cutoff with the same output jitter (jitter rises with the cutoff).
    let (mut lo, mut hi) = (0.01f64, 100.0f64);
    for _ in 0..60 {
        let mid = (lo * hi).sqrt();
        let mut f = LowPass::new(mid as f32);
        if jitter(move |t, x| f.filter(t, x)) < euro_jitter {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let fc = lo;
    let mut check = LowPass::new(fc as f32);
    let lp_jitter = jitter(move |t, x| check.filter(t, x));
    assert!((lp_jitter / euro_jitter - 1.0).abs() < 0.01, "{lp_jitter} vs {euro_jitter}");
    // Both actually reduce the jitter (uniform noise of ±0.5 has std 0.289).
    assert!(euro_jitter < 0.1 * NOISE_DEG / 3f64.sqrt(), "{euro_jitter}");

    let slope = 60.0; // deg/s, a brisk wrist bend
    let euro_lag = lag(
        {
            let mut f = OneEuro::new(min_cutoff, beta, d_cutoff);
            move |t, x| f.filter(t, x)
        },
        slope,
    );
    let lp_lag = lag(
        {
            let mut f = LowPass::new(fc as f32);
            move |t, x| f.filter(t, x)
        },
        slope,
    );
    // A first-order low-pass lags a ramp by tau = 1/(2 pi fc): the measurement agrees.
    let tau = 1.0 / (2.0 * PI * fc);
    assert!((lp_lag / tau - 1.0).abs() < 0.05, "lowpass lag {lp_lag} vs tau {tau}");
    assert!(
        euro_lag < 0.5 * lp_lag,
        "one-euro lag {euro_lag:.4} s, low-pass lag {lp_lag:.4} s (fc {fc:.3} Hz, jitter {euro_jitter:.4})"
    );
    eprintln!(
        "jitter {euro_jitter:.4} deg: one-euro lag {euro_lag:.4} s, equal-jitter low-pass ({fc:.3} Hz) lag {lp_lag:.4} s"
    );
}
