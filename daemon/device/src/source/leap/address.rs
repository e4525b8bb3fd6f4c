//! [`LeapAddress`]: `leap://HOST:PORT[?hand=left|right]`, as configurations name a Leap service.

use super::frames::Chirality;

/// `leap://HOST:PORT[?hand=left|right]` parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LeapAddress {
    /// `HOST:PORT` of the tracking service.
    pub host_port: String,
    /// The hand that drives the plant (default right).
    pub hand: Chirality,
}

/// A text that is no `leap://HOST:PORT[?hand=left|right]`; each names the text given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LeapAddressError {
    /// The text does not start with `leap://`.
    #[error("{0:?}: expected leap://HOST:PORT")]
    NotLeap(String),
    /// A query other than `hand=left` or `hand=right`.
    #[error("{address:?}: unknown option {option:?} (expected hand=left or hand=right)")]
    UnknownOption {
        /// The address given.
        address: String,
        /// The query after `?`.
        option: String,
    },
    /// No host, or no port from 0 to 65535.
    #[error("{0:?}: expected leap://HOST:PORT, e.g. leap://127.0.0.1:6437")]
    BadHostPort(String),
}

impl std::str::FromStr for LeapAddress {
    type Err = LeapAddressError;

    fn from_str(s: &str) -> Result<Self, LeapAddressError> {
        let rest = s.strip_prefix("leap://").ok_or_else(|| LeapAddressError::NotLeap(s.to_string()))?;
        let (host_port, query) = rest.split_once('?').unwrap_or((rest, ""));
        let hand = match query {
            "" | "hand=right" => Chirality::Right,
            "hand=left" => Chirality::Left,
            other => {
                return Err(LeapAddressError::UnknownOption {
                    address: s.to_string(),
                    option: other.to_string(),
                });
            }
        };
        let port_ok =
            host_port.rsplit_once(':').is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok());
        if !port_ok {
            return Err(LeapAddressError::BadHostPort(s.to_string()));
        }
        Ok(LeapAddress { host_port: host_port.to_string(), hand })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_parse_with_the_hand() {
        let a: LeapAddress = "leap://127.0.0.1:6437".parse().unwrap();
        assert_eq!((a.host_port.as_str(), a.hand), ("127.0.0.1:6437", Chirality::Right));
        let a: LeapAddress = "leap://localhost:6437?hand=left".parse().unwrap();
        assert_eq!(a.hand, Chirality::Left);
        for bad in
            ["leap://", "leap://host", "leap://:1", "leap://h:99999", "leap://h:1?hand=both", "osc://h:1"]
        {
            assert!(bad.parse::<LeapAddress>().is_err(), "{bad}");
        }
    }
}
