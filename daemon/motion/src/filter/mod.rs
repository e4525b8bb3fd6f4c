//! Jitter filters for the hand sample, applied before mapping (seed 000, section 7.2: "we can
//! apply a low-pass filter ... when processing the hand gestures").
//!
//! Two per-channel filters, both driven by the sample timestamps (no assumed rate):
//! - [`LowPass`]: first-order exponential smoothing, `y += alpha * (x - y)`,
//!   `alpha = 1 / (1 + tau / dt)`, `tau = 1 / (2 pi cutoff_hz)`.
//! - [`OneEuro`]: the 1€ filter of Casiez, Roussel and Vogel (CHI 2012): a low-pass whose cutoff
//!   rises with the (low-passed) speed, `fc = min_cutoff + beta * |dx_hat|`, so slow motion is
//!   smoothed hard and fast motion lags little.
//!
//! Rules shared by both: the first sample passes through unchanged; a sample whose time does not
//! advance (`dt <= 0`, or a non-finite `t` or value) holds the previous output and leaves the state
//! alone, so duplicate or backwards timestamps and NaN inputs never poison the filter. State is
//! kept in `f64`; all arithmetic is saturated so that finite input gives finite output.
//!
//! [`HandFilter`] runs six channels (wrist pitch/yaw/roll, thumb g1..g3) with no heap use, and is
//! `Copy` so the realtime loop can hold it by value.

use std::f64::consts::PI;

use crate::sample::HandSample;

mod spec;

pub use spec::*;

const SPEED_LIMIT: f64 = 1e300;

/// Smoothing factor of a first-order low-pass with cutoff `fc` over a step `dt` (both > 0):
/// `alpha = 1 / (1 + tau / dt)`, `tau = 1 / (2 pi fc)` (Casiez et al. 2012, Eq. for alpha).
/// Always in `[0, 1]` for positive inputs, including infinities.
pub fn smoothing_alpha(dt_s: f64, cutoff_hz: f64) -> f64 {
    let tau = 1.0 / (2.0 * PI * cutoff_hz);
    let a = 1.0 / (1.0 + tau / dt_s);
    if a.is_nan() { 1.0 } else { a.clamp(0.0, 1.0) }
}

/// Returns the step if `t` is a usable successor of `t_prev`, else `None` (hold).
fn step(t_prev: f64, t: f64) -> Option<f64> {
    let dt = t - t_prev;
    (dt.is_finite() && dt > 0.0).then_some(dt)
}

/// Saturating conversion of a finite `f64` to a finite `f32`.
fn to_f32(v: f64) -> f32 {
    (v as f32).clamp(-f32::MAX, f32::MAX)
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct LowPassState {
    t: f64,
    y: f64,
}

/// One channel of first-order exponential low-pass, rate from timestamps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowPass {
    cutoff_hz: f32,
    state: Option<LowPassState>,
}

impl LowPass {
    /// A low-pass with the given cutoff (Hz). Non-positive cutoffs are refused by
    /// [`FilterSpec::validate`]; here they make `alpha` 1 or 0 but never NaN.
    pub fn new(cutoff_hz: f32) -> Self {
        LowPass { cutoff_hz, state: None }
    }

    /// Forgets the history; the next sample passes through.
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// Filters `x` taken at time `t` (seconds).
    pub fn filter(&mut self, t: f64, x: f32) -> f32 {
        let x = x as f64;
        match self.state {
            None => {
                if x.is_finite() && t.is_finite() {
                    self.state = Some(LowPassState { t, y: x });
                }
                x as f32
            }
            Some(s) => {
                let Some(dt) = step(s.t, t).filter(|_| x.is_finite()) else {
                    return s.y as f32;
                };
                let a = smoothing_alpha(dt, self.cutoff_hz as f64);
                // Convex combination of two finite values: stays finite.
                let y = a * x + (1.0 - a) * s.y;
                self.state = Some(LowPassState { t, y });
                to_f32(y)
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct OneEuroState {
    t: f64,
    x_hat: f64,
    dx_hat: f64,
}

/// One channel of the 1€ filter (Casiez, Roussel, Vogel, CHI 2012), rate from timestamps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneEuro {
    min_cutoff: f32,
    beta: f32,
    d_cutoff: f32,
    state: Option<OneEuroState>,
}

impl OneEuro {
    /// A 1€ filter with the given parameters (see [`FilterSpec::OneEuro`]).
    pub fn new(min_cutoff: f32, beta: f32, d_cutoff: f32) -> Self {
        OneEuro { min_cutoff, beta, d_cutoff, state: None }
    }

    /// Forgets the history; the next sample passes through.
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// Filters `x` taken at time `t` (seconds).
    ///
    /// `Te = t - t_prev`; `dx = (x - x_hat_prev) / Te`; `dx_hat = lowpass(dx, d_cutoff)`;
    /// `fc = min_cutoff + beta * |dx_hat|`; `x_hat = lowpass(x, fc)`.
    pub fn filter(&mut self, t: f64, x: f32) -> f32 {
        let x = x as f64;
        match self.state {
            None => {
                if x.is_finite() && t.is_finite() {
                    self.state = Some(OneEuroState { t, x_hat: x, dx_hat: 0.0 });
                }
                x as f32
            }
            Some(s) => {
                let Some(te) = step(s.t, t).filter(|_| x.is_finite()) else {
                    return s.x_hat as f32;
                };
                let dx = ((x - s.x_hat) / te).clamp(-SPEED_LIMIT, SPEED_LIMIT);
                let a_d = smoothing_alpha(te, self.d_cutoff as f64);
                let dx_hat = a_d * dx + (1.0 - a_d) * s.dx_hat;
                let fc = self.min_cutoff as f64 + self.beta as f64 * dx_hat.abs();
                let a = smoothing_alpha(te, fc);
                let x_hat = a * x + (1.0 - a) * s.x_hat;
                self.state = Some(OneEuroState { t, x_hat, dx_hat });
                to_f32(x_hat)
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Channels {
    None,
    LowPass([LowPass; 6]),
    OneEuro([OneEuro; 6]),
}

/// The six-channel hand filter (wrist pitch/yaw/roll, thumb g1..g3). `Copy`, no heap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandFilter {
    spec: FilterSpec,
    channels: Channels,
}

impl HandFilter {
    /// A fresh filter for `spec`.
    pub fn new(spec: FilterSpec) -> Self {
        let channels = match spec {
            FilterSpec::None => Channels::None,
            FilterSpec::LowPass { cutoff_hz } => Channels::LowPass([LowPass::new(cutoff_hz); 6]),
            FilterSpec::OneEuro { min_cutoff, beta, d_cutoff } => {
                Channels::OneEuro([OneEuro::new(min_cutoff, beta, d_cutoff); 6])
            }
        };
        HandFilter { spec, channels }
    }

    /// The spec this filter runs.
    pub fn spec(&self) -> FilterSpec {
        self.spec
    }

    /// False for `none` (the output is the input).
    pub fn is_active(&self) -> bool {
        !matches!(self.spec, FilterSpec::None)
    }

    /// Forgets the history of every channel.
    pub fn reset(&mut self) {
        *self = HandFilter::new(self.spec);
    }

    /// Filters one sample; `t` is unchanged.
    pub fn apply(&mut self, s: &HandSample) -> HandSample {
        let mut out = *s;
        match &mut self.channels {
            Channels::None => {}
            Channels::LowPass(ch) => run(ch, s, &mut out, |c, t, x| c.filter(t, x)),
            Channels::OneEuro(ch) => run(ch, s, &mut out, |c, t, x| c.filter(t, x)),
        }
        out
    }
}

fn run<C>(ch: &mut [C; 6], s: &HandSample, out: &mut HandSample, mut f: impl FnMut(&mut C, f64, f32) -> f32) {
    let (wrist, thumb) = ch.split_at_mut(3);
    for k in 0..3 {
        out.wrist_deg[k] = f(&mut wrist[k], s.t, s.wrist_deg[k]);
        out.thumb_deg[k] = f(&mut thumb[k], s.t, s.thumb_deg[k]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_by_hand() {
        // fc = 1/(2 pi) Hz -> tau = 1 s; dt = 1 s -> alpha = 1/(1+1) = 0.5.
        let a = smoothing_alpha(1.0, 1.0 / (2.0 * PI));
        assert!((a - 0.5).abs() < 1e-15);
        // dt = 3 s -> alpha = 1/(1+1/3) = 0.75.
        let a = smoothing_alpha(3.0, 1.0 / (2.0 * PI));
        assert!((a - 0.75).abs() < 1e-15);
        // Extremes stay in [0, 1].
        assert_eq!(smoothing_alpha(f64::MIN_POSITIVE, 1e-300), 0.0);
        assert_eq!(smoothing_alpha(1e300, f64::INFINITY), 1.0);
    }

    #[test]
    fn lowpass_holds_on_non_advancing_time() {
        let mut lp = LowPass::new(1.0);
        assert_eq!(lp.filter(1.0, 10.0), 10.0);
        let y = lp.filter(1.1, 0.0);
        assert!(y < 10.0 && y > 0.0);
        assert_eq!(lp.filter(1.1, 50.0), y); // duplicate time
        assert_eq!(lp.filter(0.5, 50.0), y); // backwards
        assert_eq!(lp.filter(f64::NAN, 50.0), y);
        assert_eq!(lp.filter(1.2, f32::NAN), y); // NaN input does not poison the state
        assert_eq!(lp.filter(1.2, f32::INFINITY), y);
        assert!(lp.filter(1.3, 0.0) < y);
    }

    #[test]
    fn one_euro_holds_on_non_advancing_time() {
        let mut f = OneEuro::new(1.0, 0.007, 1.0);
        assert_eq!(f.filter(0.0, 1.0), 1.0);
        let y = f.filter(0.001, 2.0);
        assert!(y > 1.0 && y < 2.0);
        assert_eq!(f.filter(0.001, 9.0), y);
        assert_eq!(f.filter(-5.0, 9.0), y);
        assert_eq!(f.filter(0.002, f32::NAN), y);
        let z = f.filter(0.002, 2.0);
        assert!(z.is_finite() && z > y);
    }

    #[test]
    fn hand_filter_none_is_identity_and_inactive() {
        let mut f = HandFilter::new(FilterSpec::None);
        assert!(!f.is_active());
        for k in 0..50 {
            let s = HandSample {
                t: k as f64 * 0.001,
                wrist_deg: [k as f32, -(k as f32) * 0.5, 3.0],
                thumb_deg: [(k * k) as f32, 0.25, -7.0],
            };
            assert_eq!(f.apply(&s), s);
        }
    }

    #[test]
    fn hand_filter_channels_are_independent() {
        let mut f = HandFilter::new(FilterSpec::LowPass { cutoff_hz: 2.0 });
        assert!(f.is_active());
        let s0 = HandSample { t: 0.0, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3] };
        f.apply(&s0);
        let s1 = HandSample { t: 0.01, wrist_deg: [0.0, 10.0, 0.0], thumb_deg: [0.0, 0.0, 0.0] };
        let y = f.apply(&s1);
        assert_eq!(y.t, 0.01);
        assert_eq!(y.wrist_deg[0], 0.0);
        assert!(y.wrist_deg[1] > 0.0 && y.wrist_deg[1] < 10.0);
        assert_eq!(y.thumb_deg, [0.0; 3]);
        f.reset();
        assert_eq!(f.apply(&s1), s1); // first sample after reset passes through
    }
}
