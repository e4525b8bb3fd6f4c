//! Where a subscriber reads poses from: the daemon's socket directory on this host, or a
//! `frond-zenoh` bridge anywhere on the Zenoh network (`--from zenoh:frond/stage1/glove-a`).

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use thiserror::Error;

/// Prefix of a Zenoh source address.
pub const ZENOH_SCHEME: &str = "zenoh:";
/// First chunk of every key expression frond publishes.
pub const KEY_ROOT: &str = "frond";
/// Longest stage or source name (a key chunk).
pub const MAX_NAME_LEN: usize = 64;
/// Most endpoints one address may list.
pub const MAX_ENDPOINTS: usize = 16;

/// Where to subscribe. Parse one from a `--from` argument with [`str::parse`]:
///
/// - a directory: the daemon's socket directory on this host (`poses.sock` inside it);
/// - `zenoh:frond/<stage>/<source>`: the streams a `frond-zenoh` bridge publishes, reached over
///   Zenoh; `*` in place of the stage or the source matches any: a [`crate::Subscriber`]
///   follows one source and refuses a selector that several answer
///   ([`crate::SdkError::AmbiguousSource`]), a [`crate::zenoh_many::StageSubscriber`] follows
///   every source it matches (`frond tap`, `frond status`). `zenoh:` alone is `zenoh:frond/*/*`. Parameters after `?`, joined by `&`, say how
///   to reach the network, in Zenoh's endpoint syntax: `connect=tcp/10.0.0.1:7447` (repeat it or
///   separate endpoints with `,`), `listen=tcp/0.0.0.0:7447`, `config=/etc/frond/zenoh.json5`
///   (a Zenoh configuration file: mode, routers, TLS, credentials). Without any, the session is
///   a peer that finds the bridge by Zenoh's scouting on the local network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Source {
    /// The daemon's socket directory on this host.
    Socket(PathBuf),
    /// A bridge on the Zenoh network.
    Zenoh(ZenohAddr),
}

/// A Zenoh address of one source's streams (see [`Source`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ZenohAddr {
    /// Key expression of the source, `frond/<stage>/<source>` (the stream keys are below it).
    pub key: String,
    /// Endpoints to connect to (`tcp/ADDR:PORT`, ...).
    pub connect: Vec<String>,
    /// Endpoints to listen on.
    pub listen: Vec<String>,
    /// A Zenoh configuration file, applied before the endpoints above.
    pub config: Option<PathBuf>,
}

/// Why a `--from` address is not valid.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum SourceError {
    /// The key expression is not `frond/<stage>/<source>`.
    #[error(
        "{given:?}: a Zenoh source is frond/<stage>/<source> (three parts, `*` allowed for the \
         stage or the source), e.g. zenoh:frond/stage1/glove-a"
    )]
    BadKey {
        /// The key as given.
        given: String,
    },
    /// A stage or source name is not a plain key chunk.
    #[error("{what} name {name:?}: {why}")]
    BadName {
        /// `stage` or `source`.
        what: &'static str,
        /// The name.
        name: String,
        /// What is wrong with it.
        why: &'static str,
    },
    /// A parameter after `?` is unknown or malformed.
    #[error("{param:?}: {why} (known parameters: connect=ENDPOINT, listen=ENDPOINT, config=FILE)")]
    BadParameter {
        /// The parameter as given.
        param: String,
        /// What is wrong with it.
        why: &'static str,
    },
    /// An endpoint is not `PROTOCOL/ADDRESS`.
    #[error(
        "endpoint {endpoint:?}: expected Zenoh's endpoint syntax PROTOCOL/ADDRESS, e.g. tcp/10.0.0.1:7447"
    )]
    BadEndpoint {
        /// The endpoint.
        endpoint: String,
    },
    /// Too many endpoints.
    #[error("{count} endpoints given; at most {MAX_ENDPOINTS}")]
    TooManyEndpoints {
        /// How many were given.
        count: usize,
    },
}

/// Checks a stage or source name: one key chunk of letters, digits, `-`, `_` and `.`, so it can
/// never smuggle a `/`, a wildcard or Zenoh's `$`/`?`/`#` syntax into a key expression.
pub fn check_name(what: &'static str, name: &str) -> Result<(), SourceError> {
    let bad = |why| Err(SourceError::BadName { what, name: name.to_owned(), why });
    if name.is_empty() {
        return bad("empty");
    }
    if name.len() > MAX_NAME_LEN {
        return bad("longer than 64 bytes");
    }
    if !name.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.')) {
        return bad("only letters, digits, '-', '_' and '.' are allowed");
    }
    Ok(())
}

fn check_endpoint(endpoint: &str) -> Result<(), SourceError> {
    let ok = endpoint.split_once('/').is_some_and(|(proto, addr)| {
        !proto.is_empty() && proto.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-') && !addr.is_empty()
    }) && !endpoint.bytes().any(|b| b.is_ascii_whitespace() || b == b'"' || b == b'\\');
    if ok { Ok(()) } else { Err(SourceError::BadEndpoint { endpoint: endpoint.to_owned() }) }
}

impl ZenohAddr {
    /// The address of one bridge's source, `frond/<stage>/<source>`, with no endpoints.
    pub fn new(stage: &str, source: &str) -> Result<ZenohAddr, SourceError> {
        check_name("stage", stage)?;
        check_name("source", source)?;
        Ok(ZenohAddr {
            key: format!("{KEY_ROOT}/{stage}/{source}"),
            connect: Vec::new(),
            listen: Vec::new(),
            config: None,
        })
    }

    /// True when the key names one source (no wildcard).
    pub fn is_concrete(&self) -> bool {
        !self.key.contains('*')
    }

    fn parse(rest: &str) -> Result<ZenohAddr, SourceError> {
        let (key, params) = rest.split_once('?').unwrap_or((rest, ""));
        let key = if key.is_empty() { "frond/*/*" } else { key };
        let parts: Vec<&str> = key.split('/').collect();
        let [root, stage, source] = parts[..] else {
            return Err(SourceError::BadKey { given: key.to_owned() });
        };
        if root != KEY_ROOT {
            return Err(SourceError::BadKey { given: key.to_owned() });
        }
        for (what, name) in [("stage", stage), ("source", source)] {
            if name != "*" {
                check_name(what, name)?;
            }
        }
        let mut addr =
            ZenohAddr { key: key.to_owned(), connect: Vec::new(), listen: Vec::new(), config: None };
        for param in params.split('&').filter(|p| !p.is_empty()) {
            let Some((name, value)) = param.split_once('=') else {
                return Err(SourceError::BadParameter {
                    param: param.to_owned(),
                    why: "expected NAME=VALUE",
                });
            };
            if value.is_empty() {
                return Err(SourceError::BadParameter { param: param.to_owned(), why: "empty value" });
            }
            match name {
                "connect" | "listen" => {
                    for endpoint in value.split(',') {
                        check_endpoint(endpoint)?;
                        let list = if name == "connect" { &mut addr.connect } else { &mut addr.listen };
                        list.push(endpoint.to_owned());
                    }
                }
                "config" if addr.config.is_none() => addr.config = Some(PathBuf::from(value)),
                "config" => {
                    return Err(SourceError::BadParameter { param: param.to_owned(), why: "given twice" });
                }
                _ => {
                    return Err(SourceError::BadParameter {
                        param: param.to_owned(),
                        why: "unknown parameter",
                    });
                }
            }
        }
        let count = addr.connect.len() + addr.listen.len();
        if count > MAX_ENDPOINTS {
            return Err(SourceError::TooManyEndpoints { count });
        }
        Ok(addr)
    }
}

impl fmt::Display for ZenohAddr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{ZENOH_SCHEME}{}", self.key)?;
        let mut sep = '?';
        for (name, list) in [("connect", &self.connect), ("listen", &self.listen)] {
            if !list.is_empty() {
                write!(f, "{sep}{name}={}", list.join(","))?;
                sep = '&';
            }
        }
        if let Some(config) = &self.config {
            write!(f, "{sep}config={}", config.display())?;
        }
        Ok(())
    }
}

impl FromStr for Source {
    type Err = SourceError;

    fn from_str(s: &str) -> Result<Source, SourceError> {
        match s.strip_prefix(ZENOH_SCHEME) {
            Some(rest) => ZenohAddr::parse(rest).map(Source::Zenoh),
            None => Ok(Source::Socket(PathBuf::from(s))),
        }
    }
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::Socket(dir) => write!(f, "{}", dir.display()),
            Source::Zenoh(addr) => addr.fmt(f),
        }
    }
}

impl From<&Path> for Source {
    fn from(dir: &Path) -> Source {
        Source::Socket(dir.to_owned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn zenoh(s: &str) -> ZenohAddr {
        match s.parse::<Source>().unwrap() {
            Source::Zenoh(a) => a,
            other => panic!("{s} parsed as {other:?}"),
        }
    }

    #[test]
    fn socket_dirs_and_zenoh_keys() {
        assert_eq!("/run/frond".parse::<Source>().unwrap(), Source::Socket("/run/frond".into()));
        let a = zenoh("zenoh:frond/stage1/glove-a");
        assert_eq!(a.key, "frond/stage1/glove-a");
        assert!(a.is_concrete() && a.connect.is_empty() && a.config.is_none());
        assert_eq!(zenoh("zenoh:").key, "frond/*/*");
        assert!(!zenoh("zenoh:frond/stage1/*").is_concrete());
    }

    #[test]
    fn parameters_in_zenohs_endpoint_syntax() {
        let a = zenoh(
            "zenoh:frond/s/g?connect=tcp/10.0.0.1:7447,tcp/10.0.0.2:7447&listen=tcp/0.0.0.0:0&config=/etc/z.json5",
        );
        assert_eq!(a.connect, ["tcp/10.0.0.1:7447", "tcp/10.0.0.2:7447"]);
        assert_eq!(a.listen, ["tcp/0.0.0.0:0"]);
        assert_eq!(a.config.as_deref(), Some(Path::new("/etc/z.json5")));
        // Display gives back an equivalent address.
        assert_eq!(zenoh(&a.to_string()), a);
    }

    #[test]
    fn bad_addresses_say_what_is_wrong() {
        for (s, needle) in [
            ("zenoh:stage1/glove", "three parts"),
            ("zenoh:frond/a/b/c", "three parts"),
            ("zenoh:other/a/b", "three parts"),
            ("zenoh:frond/a b/c", "only letters"),
            ("zenoh:frond/**/c", "only letters"),
            ("zenoh:frond/$*/c", "only letters"),
            ("zenoh:frond//c", "empty"),
            ("zenoh:frond/a/b?connect", "NAME=VALUE"),
            ("zenoh:frond/a/b?connect=", "empty value"),
            ("zenoh:frond/a/b?connect=10.0.0.1:7447", "PROTOCOL/ADDRESS"),
            ("zenoh:frond/a/b?connect=tcp/\"x", "PROTOCOL/ADDRESS"),
            ("zenoh:frond/a/b?peer=tcp/x", "unknown parameter"),
            ("zenoh:frond/a/b?config=x&config=y", "given twice"),
        ] {
            let err = s.parse::<Source>().unwrap_err().to_string();
            assert!(err.contains(needle), "{s}: {err}");
        }
        let many = format!("zenoh:frond/a/b?connect={}", vec!["tcp/h:1"; 17].join(","));
        assert!(matches!(many.parse::<Source>(), Err(SourceError::TooManyEndpoints { count: 17 })));
        assert!(check_name("stage", &"x".repeat(65)).is_err());
        assert!(check_name("stage", "stage-1.a_b").is_ok());
    }
}
