//! The filter spec: which filter with which parameters, and its text form for configs, the CLI
//! and rig files (`none`, `lowpass:cutoff_hz=8`, `one-euro:min_cutoff=1,beta=0.007,d_cutoff=1`).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

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
}
