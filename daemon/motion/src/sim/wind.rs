//! The wind that drives the simulated plant (seed 003, section 4.2: "wind causes the skeleton to
//! bend"): a spec string `speed=S,dir=DEG,gust=G,seed=N[,until=S]` and its seeded, smooth field.
//!
//! The wind is uniform in space. Its velocity at time `t` is
//! `S * [(1 + G g₁(t)) ê + 0.3 G g₂(t) ê⊥]` for `t < until` and zero afterwards, with `ê` the
//! horizontal direction (`dir` 0 degrees towards +X, 90 towards +Z), `ê⊥` the horizontal
//! perpendicular, and `g₁`, `g₂` turbulences: each a sum of [`GUST_PARTIALS`] sinusoids with
//! frequencies, phases and weights drawn from [`SeededRng`] (weights summing to 1, so
//! `|g| <= 1` and the speed along `ê` never turns negative for `G <= 1`). Smooth in time and the
//! same for the same seed on every run.

use std::fmt;
use std::str::FromStr;

use glam::DVec3;
use thiserror::Error;

use crate::rng::SeededRng;

/// Largest wind speed, m/s (a hurricane is about 70).
pub const MAX_WIND_SPEED_M_S: f64 = 100.0;
/// Largest gust strength (relative to the speed).
pub const MAX_GUST: f64 = 1.0;
/// Largest `until`, seconds (a day).
pub const MAX_UNTIL_S: f64 = 86_400.0;
/// Sinusoids per turbulence component.
pub const GUST_PARTIALS: usize = 6;
/// Frequency band of the gust sinusoids, Hz: slow swells to quick flutters.
pub const GUST_BAND_HZ: (f64, f64) = (0.05, 2.0);

/// A parsed, validated wind spec.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindSpec {
    /// Mean speed, m/s, in `0..=100`.
    pub speed_m_s: f64,
    /// Direction in the ground plane, degrees: 0 towards +X, 90 towards +Z; within ±360.
    pub dir_deg: f64,
    /// Relative strength of the turbulence, `0..=1`; 0 is a steady wind.
    pub gust: f64,
    /// Seed of the turbulence.
    pub seed: u64,
    /// The wind stops at this time, seconds; `None`: it never stops.
    pub until_s: Option<f64>,
}

impl WindSpec {
    /// No wind at all.
    pub const CALM: WindSpec = WindSpec { speed_m_s: 0.0, dir_deg: 0.0, gust: 0.0, seed: 0, until_s: None };

    /// A steady wind of `speed_m_s` towards `dir_deg`.
    pub fn steady(speed_m_s: f64, dir_deg: f64) -> WindSpec {
        WindSpec { speed_m_s, dir_deg, gust: 0.0, seed: 0, until_s: None }
    }
}

/// Why a wind spec was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum WindSpecError {
    /// An item that is not `key=value`.
    #[error("wind: `{0}` is not of the form key=value")]
    NotKeyValue(String),
    /// A key the wind does not have.
    #[error("wind: unknown key `{0}` (expected speed, dir, gust, seed, until)")]
    UnknownKey(String),
    /// A key given twice.
    #[error("wind: `{0}` given more than once")]
    DuplicateKey(&'static str),
    /// A required key missing.
    #[error("wind: `{0}` is missing (expected speed=S,dir=DEG,gust=G,seed=N[,until=S])")]
    MissingKey(&'static str),
    /// A value that is not a number (or, for `seed`, not a whole number from 0 to 2^64 - 1).
    #[error("wind: `{key}`: `{value}` is not {expected}")]
    BadNumber {
        /// The key.
        key: &'static str,
        /// The text given.
        value: String,
        /// What was expected.
        expected: &'static str,
    },
    /// A number outside its range.
    #[error("wind: `{key}`: {value} must be {requirement}")]
    OutOfRange {
        /// The key.
        key: &'static str,
        /// The number given.
        value: f64,
        /// The rule it breaks.
        requirement: &'static str,
    },
}

const KEYS: [&str; 5] = ["speed", "dir", "gust", "seed", "until"];

impl FromStr for WindSpec {
    type Err = WindSpecError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut values: [Option<&str>; 5] = [None; 5];
        for item in s.split(',') {
            let item = item.trim();
            let (key, value) =
                item.split_once('=').ok_or_else(|| WindSpecError::NotKeyValue(item.to_string()))?;
            let (key, value) = (key.trim(), value.trim());
            let k = KEYS
                .iter()
                .position(|&k| k == key)
                .ok_or_else(|| WindSpecError::UnknownKey(key.to_string()))?;
            if values[k].replace(value).is_some() {
                return Err(WindSpecError::DuplicateKey(KEYS[k]));
            }
        }
        let number = |k: usize| -> Result<f64, WindSpecError> {
            let text = values[k].ok_or(WindSpecError::MissingKey(KEYS[k]))?;
            let v: f64 = text.parse().map_err(|_| WindSpecError::BadNumber {
                key: KEYS[k],
                value: text.to_string(),
                expected: "a number",
            })?;
            Ok(v)
        };
        let ranged = |k: usize, lo: f64, hi: f64, requirement: &'static str| -> Result<f64, WindSpecError> {
            let v = number(k)?;
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(v)
            } else {
                Err(WindSpecError::OutOfRange { key: KEYS[k], value: v, requirement })
            }
        };
        let speed_m_s = ranged(0, 0.0, MAX_WIND_SPEED_M_S, "between 0 and 100 m/s")?;
        let dir_deg = ranged(1, -360.0, 360.0, "between -360 and 360 degrees")?;
        let gust = ranged(2, 0.0, MAX_GUST, "between 0 and 1")?;
        let seed_text = values[3].ok_or(WindSpecError::MissingKey("seed"))?;
        let seed = seed_text.parse().map_err(|_| WindSpecError::BadNumber {
            key: "seed",
            value: seed_text.to_string(),
            expected: "a whole number from 0 to 18446744073709551615",
        })?;
        let until_s = match values[4] {
            None => None,
            Some(_) => Some(ranged(4, 0.0, MAX_UNTIL_S, "between 0 and 86400 seconds")?),
        };
        Ok(WindSpec { speed_m_s, dir_deg, gust, seed, until_s })
    }
}

impl fmt::Display for WindSpec {
    /// The spec string; [`WindSpec::from_str`] reads it back identically (shortest round-trip
    /// float formatting).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "speed={},dir={},gust={},seed={}", self.speed_m_s, self.dir_deg, self.gust, self.seed)?;
        if let Some(u) = self.until_s {
            write!(f, ",until={u}")?;
        }
        Ok(())
    }
}

/// One turbulence component: `sum_i a_i sin(2 pi f_i t + phi_i)`, `sum_i a_i = 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Turbulence {
    amplitude: [f64; GUST_PARTIALS],
    omega_rad_s: [f64; GUST_PARTIALS],
    phase_rad: [f64; GUST_PARTIALS],
}

impl Turbulence {
    fn draw(rng: &mut SeededRng) -> Turbulence {
        let mut t = Turbulence {
            amplitude: [0.0; GUST_PARTIALS],
            omega_rad_s: [0.0; GUST_PARTIALS],
            phase_rad: [0.0; GUST_PARTIALS],
        };
        let (lo, hi) = GUST_BAND_HZ;
        for i in 0..GUST_PARTIALS {
            // Log-uniform frequencies; weights falling with frequency (slow swells dominate).
            let f_hz = lo * (hi / lo).powf(rng.unit());
            t.omega_rad_s[i] = std::f64::consts::TAU * f_hz;
            t.phase_rad[i] = rng.range(0.0, std::f64::consts::TAU);
            t.amplitude[i] = rng.range(0.5, 1.0) / (1.0 + f_hz);
        }
        let sum: f64 = t.amplitude.iter().sum();
        for a in &mut t.amplitude {
            *a /= sum;
        }
        t
    }

    fn at(&self, t_s: f64) -> f64 {
        (0..GUST_PARTIALS)
            .map(|i| self.amplitude[i] * (self.omega_rad_s[i] * t_s + self.phase_rad[i]).sin())
            .sum()
    }
}

/// The wind field of a [`WindSpec`], ready to sample without allocating.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wind {
    spec: WindSpec,
    along: DVec3,
    across: DVec3,
    gusts: [Turbulence; 2],
}

impl Wind {
    /// The field of `spec` (the turbulence drawn from `SeededRng::new(spec.seed)`).
    pub fn new(spec: WindSpec) -> Wind {
        let dir = spec.dir_deg.to_radians();
        let along = DVec3::new(dir.cos(), 0.0, dir.sin());
        let across = DVec3::new(-dir.sin(), 0.0, dir.cos());
        let mut rng = SeededRng::new(spec.seed);
        let gusts = [Turbulence::draw(&mut rng), Turbulence::draw(&mut rng)];
        Wind { spec, along, across, gusts }
    }

    /// The spec this field was made from.
    pub fn spec(&self) -> &WindSpec {
        &self.spec
    }

    /// The wind velocity at time `t_s`, m/s (uniform in space).
    pub fn velocity_m_s(&self, t_s: f64) -> DVec3 {
        let s = &self.spec;
        if s.until_s.is_some_and(|u| t_s >= u) || s.speed_m_s == 0.0 {
            return DVec3::ZERO;
        }
        if s.gust == 0.0 {
            return self.along * s.speed_m_s;
        }
        let g1 = self.gusts[0].at(t_s);
        let g2 = self.gusts[1].at(t_s);
        s.speed_m_s * ((1.0 + s.gust * g1) * self.along + 0.3 * s.gust * g2 * self.across)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sim_wind_spec_parses_round_trips_and_names_errors() {
        let w: WindSpec = "speed=5,dir=90,gust=0.3,seed=7".parse().unwrap();
        assert_eq!(w, WindSpec { speed_m_s: 5.0, dir_deg: 90.0, gust: 0.3, seed: 7, until_s: None });
        assert_eq!(w.to_string(), "speed=5,dir=90,gust=0.3,seed=7");
        let w: WindSpec =
            " seed=18446744073709551615, until=2.5 ,gust=0,dir=-12.25,speed=0.1".parse().unwrap();
        assert_eq!(w.seed, u64::MAX);
        assert_eq!(w.until_s, Some(2.5));
        assert_eq!(w.to_string().parse::<WindSpec>().unwrap(), w);
        assert_eq!(w.to_string(), "speed=0.1,dir=-12.25,gust=0,seed=18446744073709551615,until=2.5");

        let err = |s: &str| s.parse::<WindSpec>().unwrap_err();
        assert_eq!(err("speed=5,dir=0,gust=0"), WindSpecError::MissingKey("seed"));
        assert_eq!(err("speed=5,dir=0,seed=1"), WindSpecError::MissingKey("gust"));
        assert_eq!(err(""), WindSpecError::NotKeyValue(String::new()));
        assert_eq!(err("speed=5,speed=6"), WindSpecError::DuplicateKey("speed"));
        assert_eq!(err("speed=5,dir=0,gust=0,seed=1,gusts=2"), WindSpecError::UnknownKey("gusts".into()));
        assert!(matches!(
            err("speed=fast,dir=0,gust=0,seed=1"),
            WindSpecError::BadNumber { key: "speed", .. }
        ));
        assert!(matches!(err("speed=5,dir=0,gust=0,seed=-1"), WindSpecError::BadNumber { key: "seed", .. }));
        assert!(matches!(err("speed=5,dir=0,gust=0,seed=1.5"), WindSpecError::BadNumber { key: "seed", .. }));
        assert!(matches!(
            err("speed=101,dir=0,gust=0,seed=1"),
            WindSpecError::OutOfRange { key: "speed", .. }
        ));
        assert!(matches!(
            err("speed=nan,dir=0,gust=0,seed=1"),
            WindSpecError::OutOfRange { key: "speed", .. }
        ));
        assert!(matches!(err("speed=1,dir=inf,gust=0,seed=1"), WindSpecError::OutOfRange { key: "dir", .. }));
        assert!(matches!(
            err("speed=1,dir=0,gust=1.5,seed=1"),
            WindSpecError::OutOfRange { key: "gust", .. }
        ));
        assert!(matches!(
            err("speed=1,dir=0,gust=0,seed=1,until=-1"),
            WindSpecError::OutOfRange { key: "until", .. }
        ));
        assert_eq!(
            err("speed=-1,dir=0,gust=0,seed=1").to_string(),
            "wind: `speed`: -1 must be between 0 and 100 m/s"
        );
    }

    #[test]
    fn sim_wind_direction_steadiness_and_until_by_hand() {
        // dir 0: towards +X; dir 90: towards +Z; steady = exactly speed * direction.
        let w = Wind::new("speed=3,dir=0,gust=0,seed=1".parse().unwrap());
        assert_eq!(w.velocity_m_s(12.3), DVec3::new(3.0, 0.0, 0.0));
        let w = Wind::new("speed=2,dir=90,gust=0,seed=1,until=1.5".parse().unwrap());
        assert!((w.velocity_m_s(0.2) - DVec3::new(0.0, 0.0, 2.0)).length() < 1e-12);
        assert_eq!(w.velocity_m_s(1.5), DVec3::ZERO);
        assert_eq!(w.velocity_m_s(7.0), DVec3::ZERO);
    }

    #[test]
    fn sim_wind_gusts_are_seeded_smooth_and_bounded() {
        let spec: WindSpec = "speed=10,dir=30,gust=1,seed=42".parse().unwrap();
        let (a, b) = (Wind::new(spec), Wind::new(spec));
        let c = Wind::new(WindSpec { seed: 43, ..spec });
        let along = DVec3::new(30f64.to_radians().cos(), 0.0, 30f64.to_radians().sin());
        let mut differs = false;
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        let mut prev = a.velocity_m_s(0.0);
        for k in 1..20_000 {
            let t = k as f64 * 0.001;
            let v = a.velocity_m_s(t);
            assert_eq!(v, b.velocity_m_s(t), "same seed, same wind");
            differs |= (v - c.velocity_m_s(t)).length() > 1e-3;
            assert_eq!(v.y, 0.0, "horizontal");
            let s = v.dot(along);
            // |g| <= 1: the speed along the direction stays within speed * (1 ± gust).
            assert!((0.0..=20.0).contains(&s), "{s}");
            (lo, hi) = (lo.min(s), hi.max(s));
            // Smooth: the largest slope is 10 m/s * 2 pi * 2 Hz (plus the cross term), so a
            // 1 ms step changes the velocity by well under 0.2 m/s.
            assert!((v - prev).length() < 0.2, "jump at {t}: {prev} -> {v}");
            prev = v;
        }
        assert!(differs, "another seed gives another wind");
        assert!(hi - lo > 2.0, "the gusts vary the speed: {lo}..{hi}");
    }

    proptest::proptest! {
        /// Any text: an error or a spec, never a panic; every spec printed reads back as itself.
        #[test]
        fn sim_wind_spec_parser_never_panics_and_round_trips(text in "\\PC{0,60}") {
            if let Ok(w) = text.parse::<WindSpec>() {
                proptest::prop_assert_eq!(w.to_string().parse::<WindSpec>().unwrap(), w);
            }
        }

        #[test]
        fn sim_wind_spec_values_round_trip(
            speed in 0.0f64..=100.0, dir in -360.0f64..=360.0, gust in 0.0f64..=1.0,
            seed in proptest::num::u64::ANY, until in proptest::option::of(0.0f64..=86_400.0),
        ) {
            let w = WindSpec { speed_m_s: speed, dir_deg: dir, gust, seed, until_s: until };
            proptest::prop_assert_eq!(w.to_string().parse::<WindSpec>().unwrap(), w);
        }
    }
}
