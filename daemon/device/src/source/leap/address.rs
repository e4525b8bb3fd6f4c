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

impl std::str::FromStr for LeapAddress {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let rest = s.strip_prefix("leap://").ok_or_else(|| format!("{s:?}: expected leap://HOST:PORT"))?;
        let (host_port, query) = rest.split_once('?').unwrap_or((rest, ""));
        let hand = match query {
            "" | "hand=right" => Chirality::Right,
            "hand=left" => Chirality::Left,
            other => {
                return Err(format!("{s:?}: unknown option {other:?} (expected hand=left or hand=right)"));
            }
        };
        let port_ok =
            host_port.rsplit_once(':').is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok());
        if !port_ok {
            return Err(format!("{s:?}: expected leap://HOST:PORT, e.g. leap://127.0.0.1:6437"));
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
