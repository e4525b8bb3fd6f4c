//! Who may use a page of frond's (the console, `frond-warp serve`): pure checks on a request's
//! headers, tested without a socket.
//!
//! - Bound to a loopback address (the default, `127.0.0.1`), every local request is allowed
//!   without a token, but the `Host` header must name this server by a loopback literal: an
//!   address of `127.0.0.0/8` written as four decimal numbers, `[::1]`, or `localhost`, each
//!   with the listening port. A page elsewhere cannot reach the server by pointing a DNS name at
//!   127.0.0.1 (DNS rebinding), whatever the name looks like (`127.0.0.1.evil.example`).
//! - Bound elsewhere, every request and WebSocket needs the token: `Authorization: Bearer T`,
//!   the `frond_token` cookie (set when the page is opened as `/?token=T`), or `?token=T`.
//! - Always: a request that carries an `Origin` must come from the console's own origin
//!   (`http://` + its `Host`); a WebSocket and a control action (any `POST`) must carry one
//!   unless they carry the token (a script, not a browser). So no other site's page can drive
//!   the daemon through an operator's browser.
//! - Always: a request the browser marks as made by another site's page (`Sec-Fetch-Site:
//!   cross-site` or `same-site`, Fetch Metadata) is refused unless it is a top-level
//!   navigation (a link followed: `Sec-Fetch-Mode: navigate`, `Sec-Fetch-Dest: document`), so
//!   another page cannot embed the console, load its GLB or takes, or make it bake, even where
//!   no `Origin` is sent (a `GET` of an image or a script).
//!
//! Tokens are compared in constant time.

use std::fmt;
use std::path::{Path, PathBuf};

/// Name of the cookie that carries the token.
pub const TOKEN_COOKIE: &str = "frond_token";
/// Shortest token accepted from a file, bytes.
pub const MIN_TOKEN_BYTES: usize = 16;
/// Longest token accepted from a file, bytes.
pub const MAX_TOKEN_BYTES: usize = 256;

/// A server's access policy.
#[derive(Clone, PartialEq, Eq)]
pub struct Access {
    /// Whether the server listens only on a loopback address.
    pub loopback: bool,
    /// The port it listens on: a loopback `Host` must name it.
    pub port: u16,
    /// The token; required for everything when not `loopback`.
    pub token: Option<String>,
}

impl fmt::Debug for Access {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Never print the token.
        f.debug_struct("Access")
            .field("loopback", &self.loopback)
            .field("port", &self.port)
            .field("token", &self.token.is_some())
            .finish()
    }
}

/// What a request is, for the policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    /// Reading: the page, its scripts, JSON state, the GLB.
    Read,
    /// The pose WebSocket.
    Socket,
    /// A control action on the daemon.
    Control,
}

/// The headers the policy looks at (raw values, as received).
#[derive(Debug, Clone, Copy, Default)]
pub struct RequestMeta<'a> {
    /// `Host`.
    pub host: Option<&'a str>,
    /// `Origin`.
    pub origin: Option<&'a str>,
    /// `Authorization`.
    pub authorization: Option<&'a str>,
    /// `Cookie`.
    pub cookie: Option<&'a str>,
    /// The `token` query parameter.
    pub query_token: Option<&'a str>,
    /// `Sec-Fetch-Site` (Fetch Metadata): who made the browser send it.
    pub fetch_site: Option<&'a str>,
    /// `Sec-Fetch-Mode`: `navigate` for a link followed or an address typed.
    pub fetch_mode: Option<&'a str>,
    /// `Sec-Fetch-Dest`: `document` for a top-level page.
    pub fetch_dest: Option<&'a str>,
}

/// Why a request is refused (the HTTP status and the words for the body).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refusal {
    /// 401: no token, or a wrong one.
    Token(&'static str),
    /// 403: another site's page, or a host name that is not this console's.
    Forbidden(String),
}

impl Refusal {
    /// The HTTP status code.
    pub fn status(&self) -> u16 {
        match self {
            Refusal::Token(_) => 401,
            Refusal::Forbidden(_) => 403,
        }
    }
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::Token(why) => write!(
                f,
                "{why}: this console listens beyond this machine, so every request needs the token \
                 frond-console printed at start (open /?token=TOKEN, or send `Authorization: Bearer TOKEN`)"
            ),
            Refusal::Forbidden(why) => f.write_str(why),
        }
    }
}

/// Equal in constant time (for equal lengths; the length is not secret).
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The token a request presents, if any: the header, then the cookie, then the query.
fn presented<'a>(m: &RequestMeta<'a>) -> Option<&'a str> {
    let bearer = m.authorization.and_then(|a| a.strip_prefix("Bearer ")).map(str::trim);
    let cookie = m.cookie.and_then(|c| {
        c.split(';').find_map(|kv| kv.trim().strip_prefix(TOKEN_COOKIE).and_then(|v| v.strip_prefix('=')))
    });
    bearer.or(cookie).or(m.query_token)
}

/// Whether `host` (a `Host` header) names a loopback server on `port` by a literal:
/// `127.a.b.c` (four decimal numbers, as `Ipv4Addr` reads them: no octal, no short forms),
/// `[::1]` or `localhost` (any case), then `:port` (the port may be left out only for port 80,
/// as a browser leaves it out). A DNS name is never a loopback literal, whatever it starts with.
pub fn is_loopback_host(host: &str, port: u16) -> bool {
    let (name, given_port) = match host.strip_prefix('[') {
        Some(rest) => match rest.split_once(']') {
            Some((inside, "")) => (inside, None),
            Some((inside, after)) => match after.strip_prefix(':') {
                Some(p) => (inside, Some(p)),
                None => return false,
            },
            None => return false,
        },
        None => match host.split_once(':') {
            Some((name, p)) => (name, Some(p)),
            None => (host, None),
        },
    };
    let port_ok = match given_port {
        None => port == 80,
        // 1*DIGIT, no sign or leading `+`; leading zeros are the same port.
        Some(p) => !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()) && p.parse::<u16>() == Ok(port),
    };
    let bracketed = host.starts_with('[');
    let name_ok = if bracketed {
        name.parse::<std::net::Ipv6Addr>().is_ok_and(|a| a == std::net::Ipv6Addr::LOCALHOST)
    } else {
        name.eq_ignore_ascii_case("localhost")
            || name.parse::<std::net::Ipv4Addr>().is_ok_and(|a| a.octets()[0] == 127)
    };
    port_ok && name_ok
}

/// What a request that passed [`Access::check`] may be given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Grant {
    /// It presented the configured token (which one, the server knows: only that one is ever
    /// set as the cookie, never the bytes the request sent).
    pub token_matched: bool,
}

impl Access {
    /// Checks one request; `Ok` lets it through, with what it may be given.
    pub fn check(&self, m: &RequestMeta<'_>, purpose: Purpose) -> Result<Grant, Refusal> {
        let Some(host) = m.host.filter(|h| !h.is_empty()) else {
            return Err(Refusal::Forbidden("the request has no Host header".into()));
        };
        if self.loopback && !is_loopback_host(host, self.port) {
            return Err(Refusal::Forbidden(format!(
                "Host {host:?} is not this server: it listens on loopback only, so a request names it \
                 http://127.0.0.1:{port}/, http://localhost:{port}/ or http://[::1]:{port}/ \
                 (or start it with --listen ADDR and a token to serve others)",
                port = self.port
            )));
        }
        if let Some(site @ ("cross-site" | "same-site")) = m.fetch_site {
            let navigation = purpose == Purpose::Read
                && m.fetch_mode == Some("navigate")
                && m.fetch_dest == Some("document");
            if !navigation {
                return Err(Refusal::Forbidden(format!(
                    "the browser says another site's page sent this request (Sec-Fetch-Site: {site}): \
                     only a link to the page itself may come from elsewhere"
                )));
            }
        }
        let token_ok = match (&self.token, presented(m)) {
            (Some(want), Some(got)) => {
                if !same(want, got) {
                    return Err(Refusal::Token("wrong token"));
                }
                true
            }
            _ => false,
        };
        if !self.loopback && !token_ok {
            return Err(Refusal::Token("no token"));
        }
        let own = format!("http://{host}");
        match m.origin {
            Some(o) if o != own => Err(Refusal::Forbidden(format!(
                "Origin {o:?} is not this server ({own:?}): another site's page may not use it"
            ))),
            None if purpose != Purpose::Read && !token_ok => Err(Refusal::Forbidden(
                "a WebSocket or a control action needs the page's Origin header (or the token)".into(),
            )),
            _ => Ok(Grant { token_matched: token_ok }),
        }
    }
}

/// Why a file's text is not a token ([`parse_token`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TokenError {
    /// Shorter than [`MIN_TOKEN_BYTES`] or longer than [`MAX_TOKEN_BYTES`] once trimmed.
    #[error("the token is {len} bytes; it must be {MIN_TOKEN_BYTES}-{MAX_TOKEN_BYTES}")]
    Length {
        /// The trimmed text's length in bytes.
        len: usize,
    },
    /// Holds a character a header or cookie cannot carry as is.
    #[error("the token holds {0:?}: use printable ASCII without spaces, ';' or ','")]
    Character(char),
}

/// Reads a token from a file's text: trimmed, printable ASCII without spaces, 16-256 bytes.
pub fn parse_token(text: &str) -> Result<String, TokenError> {
    let t = text.trim();
    if t.len() < MIN_TOKEN_BYTES || t.len() > MAX_TOKEN_BYTES {
        return Err(TokenError::Length { len: t.len() });
    }
    if let Some(c) = t.chars().find(|c| !c.is_ascii_graphic() || *c == ';' || *c == ',') {
        return Err(TokenError::Character(c));
    }
    Ok(t.to_string())
}

/// Longest token file read, bytes.
pub const MAX_TOKEN_FILE_BYTES: u64 = 4096;

/// Why a token file (`--token-file`) cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TokenFileError {
    /// It cannot be read, or is not a small regular text file.
    #[error("{}: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// Its group or other users may read or change it.
    #[error(
        "{path}: mode {mode:03o}: {who}; it holds the console's token, a secret: chmod 600 {path}",
        path = path.display()
    )]
    Exposed {
        /// The file.
        path: PathBuf,
        /// Its permission bits.
        mode: u32,
        /// Who may do what (`other users may read it`).
        who: String,
    },
    /// What it holds is not a token ([`parse_token`]).
    #[error("{}: {reason}", path.display())]
    Token {
        /// The file.
        path: PathBuf,
        /// Why (printed in this message, so not also a `source`).
        reason: TokenError,
    },
}

/// Who besides its owner may read or change a file of permission bits `mode`, in words, or
/// `None` for nobody (execute bits do not matter for a file that is read).
fn exposure(mode: u32) -> Option<String> {
    let who = |group: u32, others: u32| match (mode & group != 0, mode & others != 0) {
        (true, true) => Some("its group and other users"),
        (true, false) => Some("its group"),
        (false, true) => Some("other users"),
        (false, false) => None,
    };
    let said: Vec<String> = [(who(0o040, 0o004), "read"), (who(0o020, 0o002), "change")]
        .into_iter()
        .filter_map(|(who, what)| who.map(|w| format!("{w} may {what} it")))
        .collect();
    (!said.is_empty()).then(|| said.join(", and "))
}

/// Reads the token of `--token-file`: a small regular file that only its owner may read or
/// change (as `ssh` takes a private key, and `frond-zenoh --control` its allow-list), holding
/// one token ([`parse_token`]).
pub fn read_token_file(path: &Path) -> Result<String, TokenFileError> {
    use std::os::unix::fs::PermissionsExt;
    let read = |reason: String| TokenFileError::Read { path: path.to_path_buf(), reason };
    let text = frond_formats::rig_files::read_small_text(path, MAX_TOKEN_FILE_BYTES)
        .map_err(|e| read(e.reason()))?;
    let mode = std::fs::metadata(path).map_err(|e| read(e.to_string()))?.permissions().mode() & 0o777;
    if let Some(who) = exposure(mode) {
        return Err(TokenFileError::Exposed { path: path.to_path_buf(), mode, who });
    }
    parse_token(&text).map_err(|reason| TokenFileError::Token { path: path.to_path_buf(), reason })
}

/// A fresh random token: 32 hex digits from the operating system's generator.
pub fn new_token() -> String {
    let bytes: [u8; 16] = rand::random();
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: &str = "0123456789abcdef0123";

    fn meta<'a>(host: &'a str, origin: Option<&'a str>) -> RequestMeta<'a> {
        RequestMeta { host: Some(host), origin, ..Default::default() }
    }

    const OPEN: Grant = Grant { token_matched: false };
    const WITH_TOKEN: Grant = Grant { token_matched: true };

    #[test]
    fn loopback_reads_need_no_token_but_a_loopback_host() {
        let a = Access { loopback: true, port: 8790, token: None };
        for h in ["127.0.0.1:8790", "localhost:8790", "[::1]:8790", "127.0.0.2:8790"] {
            assert_eq!(a.check(&meta(h, None), Purpose::Read), Ok(OPEN), "{h}");
        }
        let e = a.check(&meta("evil.example:8790", None), Purpose::Read).unwrap_err();
        assert_eq!(e.status(), 403);
        assert!(e.to_string().contains("evil.example"), "{e}");
        assert_eq!(a.check(&RequestMeta::default(), Purpose::Read).unwrap_err().status(), 403);
    }

    #[test]
    fn control_and_sockets_need_the_own_origin_or_the_token() {
        let a = Access { loopback: true, port: 8790, token: Some(T.into()) };
        let own = meta("127.0.0.1:8790", Some("http://127.0.0.1:8790"));
        assert_eq!(a.check(&own, Purpose::Control), Ok(OPEN));
        assert_eq!(a.check(&own, Purpose::Socket), Ok(OPEN));
        let other = meta("127.0.0.1:8790", Some("http://evil.example"));
        for p in [Purpose::Read, Purpose::Socket, Purpose::Control] {
            assert_eq!(a.check(&other, p).unwrap_err().status(), 403, "{p:?}");
        }
        // No Origin: a script, allowed only with the token.
        let bare = meta("127.0.0.1:8790", None);
        assert_eq!(a.check(&bare, Purpose::Control).unwrap_err().status(), 403);
        let with = RequestMeta { authorization: Some("Bearer 0123456789abcdef0123"), ..bare };
        assert_eq!(a.check(&with, Purpose::Control), Ok(WITH_TOKEN));
    }

    #[test]
    fn beyond_loopback_every_request_needs_the_right_token() {
        let a = Access { loopback: false, port: 8790, token: Some(T.into()) };
        let m = meta("10.0.0.5:8790", None);
        assert_eq!(a.check(&m, Purpose::Read), Err(Refusal::Token("no token")));
        let wrong = RequestMeta { query_token: Some("0123456789abcdef0124"), ..m };
        assert_eq!(a.check(&wrong, Purpose::Read), Err(Refusal::Token("wrong token")));
        let short = RequestMeta { query_token: Some("0123"), ..m };
        assert_eq!(a.check(&short, Purpose::Read), Err(Refusal::Token("wrong token")));
        for ok in [
            RequestMeta { query_token: Some(T), ..m },
            RequestMeta { cookie: Some("a=b; frond_token=0123456789abcdef0123"), ..m },
            RequestMeta { authorization: Some("Bearer 0123456789abcdef0123"), ..m },
        ] {
            assert_eq!(a.check(&ok, Purpose::Control), Ok(WITH_TOKEN), "{ok:?}");
        }
        let e = a.check(&m, Purpose::Read).unwrap_err();
        assert!(e.to_string().contains("?token="), "{e}");
    }

    #[test]
    fn only_loopback_literals_with_the_listening_port_are_this_server() {
        // RFC 3986 host forms that name loopback: IPv4 dotted decimal in 127/8, [::1],
        // localhost; and the listening port (left out only for port 80, as browsers do).
        for (host, port) in [
            ("127.0.0.1:8790", 8790),
            ("127.255.3.4:8790", 8790),
            ("LOCALHOST:8790", 8790),
            ("[::1]:8790", 8790),
            ("[0:0:0:0:0:0:0:1]:8790", 8790),
            ("127.0.0.1:08790", 8790),
            ("127.0.0.1", 80),
            ("[::1]", 80),
            ("localhost", 80),
        ] {
            assert!(is_loopback_host(host, port), "{host} on {port}");
        }
        for (host, port) in [
            // DNS names that merely look like loopback (rebinding).
            ("127.0.0.1.evil.example:8790", 8790),
            ("127.evil.example:8790", 8790),
            ("127.0.0.1.nip.io:8790", 8790),
            ("localhost.evil.example:8790", 8790),
            ("localhost.:8790", 8790),
            // Not dotted decimal: other parsers read these as other addresses.
            ("127.1:8790", 8790),
            ("0x7f.0.0.1:8790", 8790),
            ("2130706433:8790", 8790),
            ("0177.0.0.1:8790", 8790),
            // Other addresses, other ports, malformed.
            ("10.0.0.1:8790", 8790),
            ("[::ffff:127.0.0.1]:8790", 8790),
            ("[::2]:8790", 8790),
            ("::1:8790", 8790),
            ("127.0.0.1:8791", 8790),
            ("127.0.0.1", 8790),
            ("127.0.0.1:", 8790),
            ("127.0.0.1:+8790", 8790),
            ("127.0.0.1:8790:8790", 8790),
            ("[::1]8790", 8790),
            ("[::1", 8790),
            ("", 8790),
        ] {
            assert!(!is_loopback_host(host, port), "{host} on {port}");
        }
        let a = Access { loopback: true, port: 8790, token: None };
        let e = a.check(&meta("127.0.0.1.evil.example:8790", None), Purpose::Read).unwrap_err();
        assert_eq!(e.status(), 403);
        assert!(e.to_string().contains("http://127.0.0.1:8790/"), "{e}");
    }

    #[test]
    fn another_sites_requests_are_refused_but_a_link_to_the_page() {
        // Fetch Metadata (W3C): Sec-Fetch-Site cross-site / same-site marks a request another
        // site's page made; only a top-level navigation may come from there.
        let a = Access { loopback: true, port: 8790, token: None };
        let from = |site, mode, dest| RequestMeta {
            fetch_site: Some(site),
            fetch_mode: Some(mode),
            fetch_dest: Some(dest),
            ..meta("127.0.0.1:8790", None)
        };
        assert_eq!(a.check(&from("cross-site", "navigate", "document"), Purpose::Read), Ok(OPEN));
        for (site, mode, dest) in [
            ("cross-site", "no-cors", "image"),
            ("cross-site", "no-cors", "script"),
            ("cross-site", "navigate", "iframe"),
            ("same-site", "cors", "empty"),
            ("same-site", "navigate", "frame"),
        ] {
            let e = a.check(&from(site, mode, dest), Purpose::Read).unwrap_err();
            assert_eq!(e.status(), 403, "{site} {mode} {dest}");
            assert!(e.to_string().contains(site), "{e}");
        }
        // A form POST is a navigation too, but not a read: refused.
        assert!(a.check(&from("cross-site", "navigate", "document"), Purpose::Control).is_err());
        // The page's own requests, and requests from no browser at all, pass.
        for own in [from("same-origin", "cors", "empty"), from("none", "navigate", "document")] {
            assert_eq!(a.check(&own, Purpose::Read), Ok(OPEN));
        }
    }

    #[test]
    fn tokens_from_files_are_checked_and_new_ones_are_random() {
        assert_eq!(parse_token(" 0123456789abcdef0123\n").unwrap(), T);
        assert!(parse_token("short").unwrap_err().to_string().contains("5 bytes"));
        assert!(parse_token("0123456789abcdef 0123").unwrap_err().to_string().contains("' '"));
        assert!(parse_token(&"x".repeat(300)).is_err());
        let (a, b) = (new_token(), new_token());
        assert_eq!(a.len(), 32);
        assert_ne!(a, b);
        assert!(parse_token(&a).is_ok());
        assert!(!format!("{:?}", Access { loopback: false, port: 1, token: Some(a.clone()) }).contains(&a));
    }

    #[test]
    fn a_token_file_others_may_read_or_change_is_refused_with_the_fix() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("token");
        std::fs::write(&path, format!("{T}\n")).unwrap();
        let shown = path.display().to_string();
        for (mode, who) in [
            (0o644, "its group and other users may read it"),
            (0o640, "its group may read it"),
            (0o604, "other users may read it"),
            (0o602, "other users may change it"),
            (0o666, "its group and other users may read it, and its group and other users may change it"),
        ] {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
            let e = read_token_file(&path).unwrap_err();
            assert_eq!(e, TokenFileError::Exposed { path: path.clone(), mode, who: who.into() });
            let text = e.to_string();
            assert!(text.contains(&format!("mode {mode:o}")), "{text}");
            assert!(text.ends_with(&format!("chmod 600 {shown}")), "{text}");
        }
        for mode in [0o600, 0o400, 0o700] {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
            assert_eq!(read_token_file(&path).unwrap(), T, "{mode:o}");
        }
        std::fs::write(&path, "short").unwrap();
        assert!(matches!(read_token_file(&path), Err(TokenFileError::Token { .. })));
        let e = read_token_file(&dir.path().join("missing")).unwrap_err();
        assert!(matches!(e, TokenFileError::Read { .. }), "{e}");
        let e = read_token_file(Path::new("/dev/zero")).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
    }
}
