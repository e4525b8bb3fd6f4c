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
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::sample::HandSample;

/// Default low-pass cutoff, Hz: removes tremor (8-12 Hz physiological tremor) while keeping
/// deliberate plant sway (well under 3 Hz).
pub const DEFAULT_LOWPASS_CUTOFF_HZ: f32 = 5.0;
/// Default 1€ minimum cutoff, Hz (Casiez et al. 2012 suggest starting at 1 Hz).
pub const DEFAULT_ONE_EURO_MIN_CUTOFF: f32 = 1.0;
/// Default 1€ speed coefficient, 1/degree (tuned for angles in degrees).
pub const DEFAULT_ONE_EURO_BETA: f32 = 0.007;
/// Default 1€ derivative cutoff, Hz (Casiez et al. 2012 use 1 Hz).
pub const DEFAULT_ONE_EURO_D_CUTOFF: f32 = 1.0;

/// Which filter to run, with its parameters. Text form (for configs, the CLI and rig files):
/// `none`, `lowpass`, `lowpass:cutoff_hz=8`, `one-euro`,
/// `one-euro:min_cutoff=1.0,beta=0.007,d_cutoff=1.0`. Missing keys take the `DEFAULT_*` values.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum FilterSpec {
    /// Identity.
    #[default]
    None,
    /// First-order exponential low-pass.
    LowPass {
        /// Cutoff frequency, Hz (> 0).
        cutoff_hz: f32,
    },
    /// 1€ filter (Casiez et al. 2012).
    OneEuro {
        /// Cutoff at zero speed, Hz (> 0).
        min_cutoff: f32,
        /// Cutoff increase per unit of speed (degrees/second), >= 0.
        beta: f32,
        /// Cutoff of the derivative's low-pass, Hz (> 0).
        d_cutoff: f32,
    },
}

impl FilterSpec {
    /// The low-pass with its default cutoff.
    pub const LOWPASS_DEFAULT: FilterSpec = FilterSpec::LowPass { cutoff_hz: DEFAULT_LOWPASS_CUTOFF_HZ };
    /// The 1€ filter with its default parameters.
    pub const ONE_EURO_DEFAULT: FilterSpec = FilterSpec::OneEuro {
        min_cutoff: DEFAULT_ONE_EURO_MIN_CUTOFF,
        beta: DEFAULT_ONE_EURO_BETA,
        d_cutoff: DEFAULT_ONE_EURO_D_CUTOFF,
    };

    /// The filter's name in the text form: `none`, `lowpass` or `one-euro`.
    pub fn kind(&self) -> &'static str {
        match self {
            FilterSpec::None => "none",
            FilterSpec::LowPass { .. } => "lowpass",
            FilterSpec::OneEuro { .. } => "one-euro",
        }
    }

    /// Checks the parameters (what [`FromStr`] enforces), for specs built in code.
    pub fn validate(&self) -> Result<(), FilterSpecError> {
        let check = |key: &'static str, v: f32, allow_zero: bool| {
            let ok = v.is_finite() && (v > 0.0 || (allow_zero && v == 0.0));
            if ok {
                Ok(())
            } else {
                Err(FilterSpecError::OutOfRange {
                    key,
                    value: v.to_string(),
                    requirement: if allow_zero { "a finite number >= 0" } else { "a finite number > 0" },
                })
            }
        };
        match *self {
            FilterSpec::None => Ok(()),
            FilterSpec::LowPass { cutoff_hz } => check("cutoff_hz", cutoff_hz, false),
            FilterSpec::OneEuro { min_cutoff, beta, d_cutoff } => {
                check("min_cutoff", min_cutoff, false)?;
                check("beta", beta, true)?;
                check("d_cutoff", d_cutoff, false)
            }
        }
    }
}

/// Why a filter spec text was refused.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FilterSpecError {
    /// Not `none`, `lowpass` or `one-euro`.
    #[error("unknown filter `{0}` (expected none, lowpass or one-euro)")]
    UnknownKind(String),
    /// A parameter the filter does not have.
    #[error("filter {filter}: unknown parameter `{key}` (expected {expected})")]
    UnknownKey {
        /// The filter kind.
        filter: &'static str,
        /// The key given.
        key: String,
        /// The keys this filter accepts.
        expected: &'static str,
    },
    /// A parameter given twice.
    #[error("parameter `{0}` given more than once")]
    DuplicateKey(String),
    /// An item that is not `key=value`.
    #[error("parameter `{0}` is not of the form key=value")]
    NotKeyValue(String),
    /// A value that is not a number.
    #[error("parameter `{key}`: `{value}` is not a number")]
    BadNumber {
        /// The key.
        key: String,
        /// The text given.
        value: String,
    },
    /// A number outside its range.
    #[error("parameter `{key}`: {value} must be {requirement}")]
    OutOfRange {
        /// The key.
        key: &'static str,
        /// The number given.
        value: String,
        /// The rule it breaks.
        requirement: &'static str,
    },
}

fn parse_params<const N: usize>(
    filter: &'static str,
    params: &str,
    keys: [&'static str; N],
    expected: &'static str,
    values: &mut [f32; N],
) -> Result<(), FilterSpecError> {
    let mut seen = [false; N];
    for item in params.split(',') {
        let item = item.trim();
        let (key, value) =
            item.split_once('=').ok_or_else(|| FilterSpecError::NotKeyValue(item.to_string()))?;
        let (key, value) = (key.trim(), value.trim());
        let k = keys.iter().position(|&k| k == key).ok_or_else(|| FilterSpecError::UnknownKey {
            filter,
            key: key.to_string(),
            expected,
        })?;
        if seen[k] {
            return Err(FilterSpecError::DuplicateKey(key.to_string()));
        }
        seen[k] = true;
        values[k] = value
            .parse()
            .map_err(|_| FilterSpecError::BadNumber { key: key.to_string(), value: value.to_string() })?;
    }
    Ok(())
}

impl FromStr for FilterSpec {
    type Err = FilterSpecError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        let (kind, params) = match s.split_once(':') {
            Some((k, p)) => (k.trim(), Some(p)),
            None => (s, None),
        };
        let spec = match kind {
            "none" => {
                if let Some(p) = params {
                    let key = p.split('=').next().unwrap_or("").trim().to_string();
                    return Err(FilterSpecError::UnknownKey {
                        filter: "none",
                        key,
                        expected: "no parameters",
                    });
                }
                FilterSpec::None
            }
            "lowpass" => {
                let mut v = [DEFAULT_LOWPASS_CUTOFF_HZ];
                if let Some(p) = params {
                    parse_params("lowpass", p, ["cutoff_hz"], "cutoff_hz", &mut v)?;
                }
                FilterSpec::LowPass { cutoff_hz: v[0] }
            }
            "one-euro" => {
                let mut v = [DEFAULT_ONE_EURO_MIN_CUTOFF, DEFAULT_ONE_EURO_BETA, DEFAULT_ONE_EURO_D_CUTOFF];
                if let Some(p) = params {
                    parse_params(
                        "one-euro",
                        p,
                        ["min_cutoff", "beta", "d_cutoff"],
                        "min_cutoff, beta, d_cutoff",
                        &mut v,
                    )?;
                }
                FilterSpec::OneEuro { min_cutoff: v[0], beta: v[1], d_cutoff: v[2] }
            }
            other => return Err(FilterSpecError::UnknownKind(other.to_string())),
        };
        spec.validate()?;
        Ok(spec)
    }
}

/// Prints the full text form with every parameter (`f32` `Display` is shortest round-trip, so
/// `s.parse::<FilterSpec>()` gives back the identical spec).
impl fmt::Display for FilterSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            FilterSpec::None => f.write_str("none"),
            FilterSpec::LowPass { cutoff_hz } => write!(f, "lowpass:cutoff_hz={cutoff_hz}"),
            FilterSpec::OneEuro { min_cutoff, beta, d_cutoff } => {
                write!(f, "one-euro:min_cutoff={min_cutoff},beta={beta},d_cutoff={d_cutoff}")
            }
        }
    }
}

impl TryFrom<String> for FilterSpec {
    type Error = FilterSpecError;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl From<FilterSpec> for String {
    fn from(s: FilterSpec) -> String {
        s.to_string()
    }
}

/// Bound on derivative magnitudes, so sums and products stay finite in `f64`.
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
    fn parse_forms_and_defaults() {
        assert_eq!("none".parse::<FilterSpec>().unwrap(), FilterSpec::None);
        assert_eq!("lowpass".parse::<FilterSpec>().unwrap(), FilterSpec::LowPass { cutoff_hz: 5.0 });
        assert_eq!(
            " lowpass : cutoff_hz = 8 ".parse::<FilterSpec>().unwrap(),
            FilterSpec::LowPass { cutoff_hz: 8.0 }
        );
        assert_eq!(
            "one-euro".parse::<FilterSpec>().unwrap(),
            FilterSpec::OneEuro { min_cutoff: 1.0, beta: 0.007, d_cutoff: 1.0 }
        );
        assert_eq!(
            "one-euro:beta=0.01".parse::<FilterSpec>().unwrap(),
            FilterSpec::OneEuro { min_cutoff: 1.0, beta: 0.01, d_cutoff: 1.0 }
        );
        assert_eq!(
            "one-euro:min_cutoff=0.5,beta=0,d_cutoff=2".parse::<FilterSpec>().unwrap(),
            FilterSpec::OneEuro { min_cutoff: 0.5, beta: 0.0, d_cutoff: 2.0 }
        );
    }

    #[test]
    fn display_round_trips() {
        for s in [
            "none",
            "lowpass",
            "lowpass:cutoff_hz=8",
            "lowpass:cutoff_hz=0.1",
            "one-euro",
            "one-euro:min_cutoff=1.0,beta=0.007,d_cutoff=1.0",
            "one-euro:min_cutoff=0.3333333,beta=1e-5,d_cutoff=123.25",
        ] {
            let spec: FilterSpec = s.parse().unwrap();
            let text = spec.to_string();
            assert_eq!(text.parse::<FilterSpec>().unwrap(), spec, "{s} -> {text}");
        }
        assert_eq!(FilterSpec::ONE_EURO_DEFAULT.to_string(), "one-euro:min_cutoff=1,beta=0.007,d_cutoff=1");
        assert_eq!(FilterSpec::LOWPASS_DEFAULT.to_string(), "lowpass:cutoff_hz=5");
    }

    #[test]
    fn errors_name_the_key() {
        let cases = [
            ("kalman", "unknown filter `kalman`"),
            ("", "unknown filter ``"),
            ("lowpass:cutoff=8", "filter lowpass: unknown parameter `cutoff`"),
            ("one-euro:gamma=1", "filter one-euro: unknown parameter `gamma`"),
            ("none:x=1", "filter none: unknown parameter `x`"),
            ("lowpass:cutoff_hz=abc", "parameter `cutoff_hz`: `abc` is not a number"),
            ("lowpass:cutoff_hz=0", "parameter `cutoff_hz`: 0 must be a finite number > 0"),
            ("lowpass:cutoff_hz=-3", "parameter `cutoff_hz`: -3 must be a finite number > 0"),
            ("lowpass:cutoff_hz=inf", "parameter `cutoff_hz`: inf must be a finite number > 0"),
            ("one-euro:min_cutoff=0", "parameter `min_cutoff`: 0 must be"),
            ("one-euro:d_cutoff=-1", "parameter `d_cutoff`: -1 must be"),
            ("one-euro:beta=-0.1", "parameter `beta`: -0.1 must be a finite number >= 0"),
            ("one-euro:beta=NaN", "parameter `beta`: NaN must be"),
            ("one-euro:beta=1,beta=2", "parameter `beta` given more than once"),
            ("lowpass:", "parameter `` is not of the form key=value"),
            ("lowpass:8", "parameter `8` is not of the form key=value"),
        ];
        for (text, want) in cases {
            let e = text.parse::<FilterSpec>().unwrap_err().to_string();
            assert!(e.starts_with(want), "{text:?}: got {e:?}, want {want:?}");
        }
    }

    #[test]
    fn serde_uses_the_text_form() {
        #[derive(Serialize, Deserialize, PartialEq, Debug)]
        struct Doc {
            filter: FilterSpec,
        }
        let d: Doc = toml::from_str("filter = \"one-euro:beta=0.01\"").unwrap();
        assert_eq!(d.filter, FilterSpec::OneEuro { min_cutoff: 1.0, beta: 0.01, d_cutoff: 1.0 });
        let text = toml::to_string(&d).unwrap();
        assert_eq!(toml::from_str::<Doc>(&text).unwrap(), d);
        let e = toml::from_str::<Doc>("filter = \"lowpass:cutoff_hz=-1\"").unwrap_err();
        assert!(e.to_string().contains("cutoff_hz"), "{e}");
    }

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
