//! frond's pages' HTTP/1.1, one request per connection (`Connection: close`): the request head
//! parsed by `httparse`, bounded before anything is allocated for it (head 16 KiB, 48 headers,
//! body 64 KiB) and read whole within one deadline, and the WebSocket upgrade handed to
//! `tungstenite`. Small on purpose: a page makes a handful of requests, live data goes over one
//! WebSocket or a polled endpoint.
//!
//! Nothing from a request reaches a response head unchecked: a header value is a
//! [`HeaderValue`], which only visible ASCII and inner spaces make (RFC 9110, section 5.5, less
//! `obs-text`), so no CR or LF from a request can split a response.

use std::fmt;
use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::time::Instant;

use thiserror::Error;

/// Largest request head, bytes.
pub const MAX_HEAD_BYTES: usize = 16 * 1024;
/// Most request headers.
pub const MAX_HEADERS: usize = 48;
/// Largest request body, bytes.
pub const MAX_BODY_BYTES: usize = 64 * 1024;

/// A request that could not be read.
#[derive(Debug, Error)]
pub enum HttpError {
    /// The connection failed or timed out.
    #[error("reading the request: {0}")]
    Io(#[from] io::Error),
    /// The head or body is not HTTP/1.1 as this server takes it.
    #[error("{0}")]
    Bad(String),
    /// The head or body is larger than allowed.
    #[error("{0}")]
    TooLarge(String),
    /// The whole request did not arrive before its deadline.
    #[error("the request did not arrive in time")]
    Timeout,
}

impl HttpError {
    /// The status to answer with (none for a dead connection).
    pub fn status(&self) -> Option<u16> {
        match self {
            HttpError::Io(_) => None,
            HttpError::Bad(_) => Some(400),
            HttpError::TooLarge(_) => Some(413),
            HttpError::Timeout => Some(408),
        }
    }
}

/// One request.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Request {
    /// `GET`, `POST`, ...
    pub method: String,
    /// The path without the query (`/api/status`).
    pub path: String,
    /// Query parameters, percent-decoded.
    pub query: Vec<(String, String)>,
    /// Headers, names in lower case.
    pub headers: Vec<(String, String)>,
    /// The body (`Content-Length` bytes).
    pub body: Vec<u8>,
}

impl Request {
    /// A header's value by lower-case name.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }

    /// A query parameter's value.
    pub fn param(&self, name: &str) -> Option<&str> {
        self.query.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }

    /// Whether this is a WebSocket upgrade.
    pub fn is_websocket(&self) -> bool {
        self.header("upgrade").is_some_and(|u| u.eq_ignore_ascii_case("websocket"))
            && self.header("connection").is_some_and(|c| c.to_ascii_lowercase().contains("upgrade"))
    }
}

/// Percent-decodes a query component (`+` is a space); bad escapes stay as they are.
fn decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match b[i] {
            b'%' if i + 2 < b.len() => match (hex(b[i + 1]), hex(b[i + 2])) {
                (Some(h), Some(l)) => {
                    out.push((h * 16 + l) as u8);
                    i += 3;
                    continue;
                }
                _ => out.push(b'%'),
            },
            b'+' => out.push(b' '),
            c => out.push(c),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Splits a request target into path and decoded query pairs.
pub fn split_target(target: &str) -> (String, Vec<(String, String)>) {
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let pairs = query
        .split('&')
        .filter(|kv| !kv.is_empty())
        .map(|kv| {
            let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
            (decode(k), decode(v))
        })
        .collect();
    (path.to_string(), pairs)
}

/// Parses a complete head (through the blank line) and the declared body length, refusing a
/// body over [`MAX_BODY_BYTES`].
pub fn parse_head(head: &[u8]) -> Result<(Request, usize), HttpError> {
    parse_head_with(head, MAX_BODY_BYTES)
}

/// [`parse_head`] with a body limit of `max_body` bytes.
pub fn parse_head_with(head: &[u8], max_body: usize) -> Result<(Request, usize), HttpError> {
    if let Some(at) = bare_line_feed(head) {
        return Err(bare_line_feed_error(at));
    }
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let mut req = httparse::Request::new(&mut headers);
    match req.parse(head) {
        Ok(httparse::Status::Complete(_)) => {}
        Ok(httparse::Status::Partial) => return Err(HttpError::Bad("the request head is incomplete".into())),
        Err(httparse::Error::TooManyHeaders) => {
            return Err(HttpError::TooLarge(format!("more than {MAX_HEADERS} request headers")));
        }
        Err(e) => return Err(HttpError::Bad(format!("not an HTTP request: {e}"))),
    }
    let (method, target) = (req.method.unwrap_or_default(), req.path.unwrap_or_default());
    let (path, query) = split_target(target);
    let mut out = Request { method: method.to_string(), path, query, ..Default::default() };
    for h in req.headers.iter() {
        let value = std::str::from_utf8(h.value)
            .map_err(|_| HttpError::Bad(format!("header {} is not UTF-8", h.name)))?;
        out.headers.push((h.name.to_ascii_lowercase(), value.trim().to_string()));
    }
    for name in SINGLE_HEADERS {
        let n = out.headers.iter().filter(|(h, _)| h == name).count();
        if n > 1 {
            return Err(HttpError::Bad(format!(
                "the request has {n} {name} headers; a request carries one (RFC 9110, RFC 9112 section 3.2)"
            )));
        }
    }
    let len = body_length(&out)?;
    if len > max_body {
        return Err(HttpError::TooLarge(format!("the body is {len} bytes; the limit is {max_body}")));
    }
    Ok((out, len))
}

/// Headers a request carries at most once: two `Host`s (RFC 9112, section 3.2) or two
/// `Origin`s leave it open which one a check read and which one the answer used, so neither is
/// taken. (`Content-Length` has its own rule, [`body_length`].)
/// Where `head` has a line feed that no carriage return precedes. httparse takes such a line
/// end, but [`read_request`] finds the head's end by its `CRLF CRLF`: were both accepted, a head
/// ended by `LF LF` would be parsed up to there while its body was taken after a later `CRLF
/// CRLF`, two readings of one request (request smuggling's root). HTTP/1.1 lines end with CRLF
/// (RFC 9112, section 2.2), which every browser sends, so a bare LF is refused.
fn bare_line_feed(head: &[u8]) -> Option<usize> {
    head.iter().enumerate().position(|(i, &c)| c == b'\n' && (i == 0 || head[i - 1] != b'\r'))
}

fn bare_line_feed_error(at: usize) -> HttpError {
    HttpError::Bad(format!(
        "the request head has a line ending in a bare LF (byte {at}): HTTP/1.1 lines end with CRLF \
         (RFC 9112, section 2.2)"
    ))
}

const SINGLE_HEADERS: [&str; 4] = ["host", "origin", "authorization", "cookie"];

/// The declared body length: one `Content-Length` of decimal digits (RFC 9110, section 8.6), or
/// none (no body). A second `Content-Length`, or one beside `Transfer-Encoding`, is refused: two
/// readers could take different bodies from the same bytes (request smuggling, RFC 9112,
/// section 6.3), so the server takes neither.
fn body_length(req: &Request) -> Result<usize, HttpError> {
    let lengths: Vec<&str> =
        req.headers.iter().filter(|(n, _)| n == "content-length").map(|(_, v)| v.as_str()).collect();
    if req.header("transfer-encoding").is_some() {
        if !lengths.is_empty() {
            return Err(HttpError::Bad(
                "the request has both Transfer-Encoding and Content-Length, so its body's length is \
                 ambiguous; send Content-Length alone"
                    .into(),
            ));
        }
        return Err(HttpError::Bad("chunked request bodies are not taken; send Content-Length".into()));
    }
    let v = match lengths.as_slice() {
        [] => return Ok(0),
        [v] => *v,
        many => {
            return Err(HttpError::Bad(format!(
                "the request has {} Content-Length headers ({}); send exactly one",
                many.len(),
                many.join(", ")
            )));
        }
    };
    if v.is_empty() || !v.bytes().all(|b| b.is_ascii_digit()) {
        return Err(HttpError::Bad(format!("Content-Length {v:?} is not a number of bytes")));
    }
    // Only digits: a parse failure is an overflow.
    v.parse::<usize>()
        .map_err(|_| HttpError::TooLarge(format!("the body is {v} bytes; the limit is {MAX_BODY_BYTES}")))
}

/// Reads one request from `stream`, all of it (head and body) before `deadline`: a client that
/// trickles bytes cannot hold the connection longer than that, however it paces them.
/// The body may be `max_body` bytes at most.
pub fn read_request(
    stream: &mut TcpStream,
    deadline: Instant,
    max_body: usize,
) -> Result<Request, HttpError> {
    let mut buf = vec![0u8; 2048];
    let mut have = 0;
    let end = loop {
        let end = buf[..have].windows(4).position(|w| w == b"\r\n\r\n").map(|i| i + 4);
        // Refused as soon as it arrives: a head of bare LFs has no CRLF CRLF to wait for.
        if let Some(at) = bare_line_feed(&buf[..end.unwrap_or(have)]) {
            return Err(bare_line_feed_error(at));
        }
        if let Some(end) = end {
            break end;
        }
        if have == MAX_HEAD_BYTES {
            return Err(HttpError::TooLarge(format!("the request head passes {MAX_HEAD_BYTES} bytes")));
        }
        if have == buf.len() {
            buf.resize((buf.len() * 2).min(MAX_HEAD_BYTES), 0);
        }
        let n = read_before(stream, &mut buf[have..], deadline)?;
        if n == 0 {
            return Err(HttpError::Io(io::ErrorKind::UnexpectedEof.into()));
        }
        have += n;
    };
    let (mut req, len) = parse_head_with(&buf[..end], max_body)?;
    let mut body = buf[end..have].to_vec();
    body.truncate(len);
    let mut got = body.len();
    body.resize(len, 0);
    while got < len {
        match read_before(stream, &mut body[got..], deadline)? {
            0 => return Err(HttpError::Io(io::ErrorKind::UnexpectedEof.into())),
            n => got += n,
        }
    }
    req.body = body;
    Ok(req)
}

/// One `read` that returns by `deadline`: [`HttpError::Timeout`] once it has passed.
fn read_before(stream: &mut TcpStream, buf: &mut [u8], deadline: Instant) -> Result<usize, HttpError> {
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(HttpError::Timeout);
        }
        stream.set_read_timeout(Some(left))?;
        match stream.read(buf) {
            Ok(n) => return Ok(n),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                return Err(HttpError::Timeout);
            }
            Err(e) => return Err(e.into()),
        }
    }
}

/// A response header's value: visible ASCII with inner spaces or tabs (RFC 9110, section 5.5,
/// `field-value` without `obs-text`), at most [`MAX_HEADER_VALUE_BYTES`]. The only way into a
/// response head, so that no byte a request sent (a CR, a LF, a NUL) is ever written there raw.
#[derive(Clone, PartialEq, Eq)]
pub struct HeaderValue(std::borrow::Cow<'static, str>);

/// Longest response header value, bytes.
pub const MAX_HEADER_VALUE_BYTES: usize = 4096;

/// A value [`HeaderValue`] refuses.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("not a header value ({0}): only visible ASCII and inner spaces are written into a response head")]
pub struct BadHeaderValue(&'static str);

/// Why `v` is not a header value, or `None` when it is one.
const fn header_value_fault(v: &[u8]) -> Option<&'static str> {
    if v.len() > MAX_HEADER_VALUE_BYTES {
        return Some("too long");
    }
    if let [first, .., last] | [first @ last] = v
        && (matches!(*first, b' ' | b'\t') || matches!(*last, b' ' | b'\t'))
    {
        return Some("space at an end");
    }
    let mut i = 0;
    while i < v.len() {
        let c = v[i];
        if !(c == b' ' || c == b'\t' || (c > 0x20 && c < 0x7f)) {
            return Some(if c == b'\r' || c == b'\n' {
                "a line break"
            } else {
                "a control or non-ASCII byte"
            });
        }
        i += 1;
    }
    None
}

impl HeaderValue {
    /// A value built at run time, checked.
    pub fn new(value: impl Into<String>) -> Result<HeaderValue, BadHeaderValue> {
        let value = value.into();
        match header_value_fault(value.as_bytes()) {
            Some(why) => Err(BadHeaderValue(why)),
            None => Ok(HeaderValue(value.into())),
        }
    }

    /// A value written in the source; checked when compiled if used in a `const`, else it
    /// panics (a programmer's error, found by any test that builds the response).
    pub const fn from_static(value: &'static str) -> HeaderValue {
        if header_value_fault(value.as_bytes()).is_some() {
            panic!("not a header value");
        }
        HeaderValue(std::borrow::Cow::Borrowed(value))
    }

    /// A number.
    pub fn number(n: impl Into<u64>) -> HeaderValue {
        HeaderValue(n.into().to_string().into())
    }

    /// The value.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl fmt::Debug for HeaderValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&*self.0, f)
    }
}

impl fmt::Display for HeaderValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// A download's `Content-Disposition: attachment; filename="NAME"`, or `None` when `name`
/// holds anything but letters, digits and `-_.` (a name that could close the quotes).
pub fn attachment(name: &str) -> Option<HeaderValue> {
    let plain = !name.is_empty() && name.bytes().all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b));
    if !plain {
        return None;
    }
    HeaderValue::new(format!("attachment; filename=\"{name}\"")).ok()
}

/// The reason phrase of the statuses the console answers with.
pub fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        204 => "No Content",
        400 => "Bad Request",
        401 => "Unauthorized",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        409 => "Conflict",
        413 => "Content Too Large",
        426 => "Upgrade Required",
        502 => "Bad Gateway",
        503 => "Service Unavailable",
        _ => "Error",
    }
}

/// An answer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Response {
    /// Status code.
    pub status: u16,
    /// `Content-Type`.
    pub content_type: &'static str,
    /// More headers.
    pub headers: Vec<(&'static str, HeaderValue)>,
    /// The body.
    pub body: Vec<u8>,
}

impl Response {
    /// A response with this body.
    pub fn new(status: u16, content_type: &'static str, body: impl Into<Vec<u8>>) -> Response {
        Response { status, content_type, headers: Vec::new(), body: body.into() }
    }

    /// A JSON body.
    pub fn json(status: u16, value: &serde_json::Value) -> Response {
        Response::new(status, "application/json; charset=utf-8", value.to_string())
    }

    /// An error as JSON `{"error": message}`.
    pub fn error(status: u16, message: impl Into<String>) -> Response {
        Response::json(status, &serde_json::json!({ "error": message.into() }))
    }

    /// Adds a header.
    pub fn with(mut self, name: &'static str, value: HeaderValue) -> Response {
        self.headers.push((name, value));
        self
    }

    /// Writes the response and ends the exchange.
    pub fn write_to(&self, w: &mut impl Write) -> io::Result<()> {
        w.write_all(self.head().as_bytes())?;
        w.write_all(&self.body)?;
        w.flush()
    }

    /// Writes the response as the answer to a `method` request: without its body for `HEAD`,
    /// whose answer is GET's head alone, `Content-Length` included (RFC 9110, section 9.3.2).
    pub fn write_for(&self, method: &str, w: &mut impl Write) -> io::Result<()> {
        if method == "HEAD" {
            w.write_all(self.head().as_bytes())?;
            w.flush()
        } else {
            self.write_to(w)
        }
    }

    /// The status line and headers through the blank line. `Connection: close`,
    /// `Cache-Control: no-store`, and headers that keep the page out of other pages' frames and
    /// its address out of `Referer`s, unless the response sets its own.
    fn head(&self) -> String {
        let mut head = format!(
            "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\n\
             X-Content-Type-Options: nosniff\r\n",
            self.status,
            reason(self.status),
            self.content_type,
            self.body.len()
        );
        // Never framed by another page (clickjacking), and no address of ours (with a token in
        // it) handed to another site as a Referer.
        for (name, default) in [
            ("Connection", "close"),
            ("Cache-Control", "no-store"),
            ("X-Frame-Options", "DENY"),
            ("Content-Security-Policy", "frame-ancestors 'none'"),
            ("Referrer-Policy", "no-referrer"),
        ] {
            if !self.headers.iter().any(|(n, _)| n.eq_ignore_ascii_case(name)) {
                head.push_str(&format!("{name}: {default}\r\n"));
            }
        }
        for (n, v) in &self.headers {
            head.push_str(&format!("{n}: {v}\r\n"));
        }
        head.push_str("\r\n");
        head
    }
}

/// The WebSocket version this server speaks (RFC 6455).
pub const WEBSOCKET_VERSION: &str = "13";

/// Why a WebSocket upgrade is refused (RFC 6455, section 4.2.1): the page's opening handshake
/// is not one this server can complete.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum HandshakeError {
    /// The upgrade is not a `GET`.
    #[error("a WebSocket upgrade is a GET request, not {0}")]
    NotGet(String),
    /// No `Sec-WebSocket-Version`.
    #[error("the WebSocket upgrade has no Sec-WebSocket-Version; this server speaks version 13")]
    NoVersion,
    /// A version other than 13.
    #[error("Sec-WebSocket-Version {0:?} is not spoken here; this server speaks version 13 (RFC 6455)")]
    Version(String),
    /// No `Sec-WebSocket-Key`.
    #[error("the WebSocket upgrade has no Sec-WebSocket-Key")]
    NoKey,
    /// A key that is not 16 bytes in base64.
    #[error("Sec-WebSocket-Key {0:?} is not the base64 of 16 bytes (RFC 6455, section 4.1)")]
    BadKey(String),
}

impl HandshakeError {
    /// The answer: 426 Upgrade Required naming the version spoken for another version
    /// (RFC 6455, section 4.2.2; RFC 9110, section 15.5.22), 400 for the rest.
    pub fn response(&self) -> Response {
        match self {
            HandshakeError::Version(_) => Response::error(426, self.to_string())
                .with("Sec-WebSocket-Version", HeaderValue::from_static(WEBSOCKET_VERSION))
                .with("Upgrade", HeaderValue::from_static("websocket"))
                .with("Connection", HeaderValue::from_static("Upgrade, close")),
            _ => Response::error(400, self.to_string()),
        }
    }
}

/// Whether `key` is the base64 (RFC 4648, section 4, padded) of exactly 16 bytes: 22 characters
/// of the alphabet and `==`. The two spare bits of the last character are not checked.
fn is_websocket_key(key: &str) -> bool {
    let b = key.as_bytes();
    b.len() == 24
        && b[..22].iter().all(|c| c.is_ascii_alphanumeric() || *c == b'+' || *c == b'/')
        && &b[22..] == b"=="
}

/// Checks a WebSocket upgrade's opening handshake (RFC 6455, section 4.2.1): a `GET`, version
/// 13, and a key of 16 bytes in base64; the key when it is right. (`Upgrade` and `Connection`
/// are [`Request::is_websocket`]'s, `Host` the access check's.)
pub fn check_websocket(req: &Request) -> Result<&str, HandshakeError> {
    if req.method != "GET" {
        return Err(HandshakeError::NotGet(req.method.clone()));
    }
    match req.header("sec-websocket-version") {
        None => return Err(HandshakeError::NoVersion),
        Some(v) if v != WEBSOCKET_VERSION => return Err(HandshakeError::Version(v.to_string())),
        Some(_) => {}
    }
    let key = req.header("sec-websocket-key").ok_or(HandshakeError::NoKey)?;
    if !is_websocket_key(key) {
        return Err(HandshakeError::BadKey(key.to_string()));
    }
    Ok(key)
}

/// Answers a WebSocket upgrade with 101; one that [`check_websocket`] refuses with its answer.
pub fn accept_websocket(req: &Request, w: &mut impl Write) -> io::Result<bool> {
    let key = match check_websocket(req) {
        Ok(key) => key,
        Err(e) => {
            e.response().write_to(w)?;
            return Ok(false);
        }
    };
    let accept = tungstenite::handshake::derive_accept_key(key.as_bytes());
    write!(
        w,
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n"
    )?;
    w.flush()?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heads_parse_into_path_query_and_lower_case_headers() {
        let (r, len) = parse_head(
            b"POST /api/mark?token=a%20b&x HTTP/1.1\r\nHost: 127.0.0.1:1\r\nContent-Length: 5\r\nX-Y: z \r\n\r\n",
        )
        .unwrap();
        assert_eq!((r.method.as_str(), r.path.as_str(), len), ("POST", "/api/mark", 5));
        assert_eq!(r.param("token"), Some("a b"));
        assert_eq!(r.param("x"), Some(""));
        assert_eq!(r.header("x-y"), Some("z"));
        assert_eq!(r.header("host"), Some("127.0.0.1:1"));
        assert!(!r.is_websocket());
    }

    #[test]
    fn bad_and_huge_heads_are_refused_with_their_reason() {
        let e = parse_head(b"\x01\x02 nonsense\r\n\r\n").unwrap_err();
        assert_eq!(e.status(), Some(400), "{e}");
        let e = parse_head(b"POST / HTTP/1.1\r\nContent-Length: 99999999\r\n\r\n").unwrap_err();
        assert_eq!(e.status(), Some(413));
        assert!(e.to_string().contains("99999999"), "{e}");
        let e = parse_head(b"POST / HTTP/1.1\r\nContent-Length: -1\r\n\r\n").unwrap_err();
        assert!(e.to_string().contains("\"-1\""), "{e}");
        let e = parse_head(b"POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n").unwrap_err();
        assert_eq!(e.status(), Some(400));
        let many: String = (0..60).map(|i| format!("H{i}: v\r\n")).collect();
        let e = parse_head(format!("GET / HTTP/1.1\r\n{many}\r\n").as_bytes()).unwrap_err();
        assert_eq!(e.status(), Some(413), "{e}");
    }

    #[test]
    fn percent_decoding_keeps_bad_escapes() {
        assert_eq!(decode("a%2Fb+c%zz%4"), "a/b c%zz%4");
        assert_eq!(decode("%"), "%");
    }

    #[test]
    fn the_websocket_accept_key_is_the_rfc_6455_example() {
        // RFC 6455, section 1.3: key "dGhlIHNhbXBsZSBub25jZQ==" gives "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=".
        let (mut r, _) =
            parse_head(b"GET /ws HTTP/1.1\r\nUpgrade: websocket\r\nConnection: keep-alive, Upgrade\r\n\r\n")
                .unwrap();
        r.headers.push(("sec-websocket-key".into(), "dGhlIHNhbXBsZSBub25jZQ==".into()));
        r.headers.push(("sec-websocket-version".into(), "13".into()));
        assert!(r.is_websocket());
        let mut out = Vec::new();
        assert!(accept_websocket(&r, &mut out).unwrap());
        let text = String::from_utf8(out).unwrap();
        assert!(text.contains("Sec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"), "{text}");
    }

    /// The status and text of `head`'s refusal.
    fn refusal(head: &str) -> (Option<u16>, String) {
        let e = parse_head(head.as_bytes()).unwrap_err();
        (e.status(), e.to_string())
    }

    #[test]
    fn a_body_length_must_be_said_once_and_alone() {
        // RFC 9110, section 8.6 and RFC 9112, section 6.3: differing Content-Lengths (and any
        // Content-Length beside Transfer-Encoding) are an unrecoverable framing error, 400.
        let (status, text) =
            refusal("POST /api/mark HTTP/1.1\r\nContent-Length: 2\r\nContent-Length: 10\r\n\r\n");
        assert_eq!(status, Some(400), "{text}");
        assert!(text.contains("2 Content-Length headers (2, 10)"), "{text}");
        // Identical duplicates too: taking one of them would be taking a side.
        let (status, text) = refusal("POST / HTTP/1.1\r\nContent-Length: 5\r\ncontent-length: 5\r\n\r\n");
        assert_eq!(status, Some(400), "{text}");
        let (status, text) =
            refusal("POST / HTTP/1.1\r\nContent-Length: 5\r\nTransfer-Encoding: chunked\r\n\r\n");
        assert_eq!(status, Some(400), "{text}");
        assert!(text.contains("both Transfer-Encoding and Content-Length"), "{text}");
        // Content-Length = 1*DIGIT: no sign, no list, no blank.
        for bad in ["+5", "5, 5", "", " 0x5"] {
            let (status, text) = refusal(&format!("POST / HTTP/1.1\r\nContent-Length: {bad}\r\n\r\n"));
            assert_eq!(status, Some(400), "{bad:?}: {text}");
            assert!(text.contains("Content-Length"), "{text}");
        }
        let (status, _) = refusal("POST / HTTP/1.1\r\nContent-Length: 99999999999999999999999\r\n\r\n");
        assert_eq!(status, Some(413));
        assert_eq!(parse_head(b"POST / HTTP/1.1\r\nContent-Length: 0010\r\n\r\n").unwrap().1, 10);
    }

    #[test]
    fn a_head_answer_is_gets_head_without_the_body() {
        let r = Response::new(200, "text/plain", "hello").with("X-A", HeaderValue::from_static("b"));
        let (mut get, mut head) = (Vec::new(), Vec::new());
        r.write_for("GET", &mut get).unwrap();
        r.write_for("HEAD", &mut head).unwrap();
        let get = String::from_utf8(get).unwrap();
        let head = String::from_utf8(head).unwrap();
        assert!(get.ends_with("\r\n\r\nhello"), "{get}");
        assert_eq!(head, get.strip_suffix("hello").unwrap());
        assert!(head.contains("Content-Length: 5\r\n") && head.ends_with("\r\n\r\n"), "{head}");
    }

    fn upgrade(method: &str, version: Option<&str>, key: Option<&str>) -> Request {
        let mut text = format!(
            "{method} /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        );
        if let Some(v) = version {
            text.push_str(&format!("Sec-WebSocket-Version: {v}\r\n"));
        }
        if let Some(k) = key {
            text.push_str(&format!("Sec-WebSocket-Key: {k}\r\n"));
        }
        text.push_str("\r\n");
        parse_head(text.as_bytes()).unwrap().0
    }

    #[test]
    fn websocket_handshakes_are_checked_as_rfc_6455_says() {
        const KEY: &str = "dGhlIHNhbXBsZSBub25jZQ=="; // "the sample nonce", 16 bytes
        assert_eq!(check_websocket(&upgrade("GET", Some("13"), Some(KEY))), Ok(KEY));
        // Section 4.2.2: another version gets 426 with the versions spoken.
        let e = check_websocket(&upgrade("GET", Some("99"), Some(KEY))).unwrap_err();
        let mut out = Vec::new();
        assert!(!accept_websocket(&upgrade("GET", Some("99"), Some(KEY)), &mut out).unwrap());
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("HTTP/1.1 426 Upgrade Required\r\n"), "{text}");
        assert!(text.contains("\r\nSec-WebSocket-Version: 13\r\n"), "{text}");
        assert!(text.contains("\r\nUpgrade: websocket\r\n"), "{text}");
        assert!(!text.contains("Sec-WebSocket-Accept"), "{text}");
        assert_eq!(e.response().status, 426);
        assert!(e.to_string().contains("\"99\""), "{e}");
        // Section 4.1: the key is 16 random bytes in base64, so 24 characters ending "==".
        for bad in [
            "x",
            "AAAAAAAAAAAAAAAAAAAA",         // 15 bytes
            "AAAAAAAAAAAAAAAAAAAAAAA=",     // 17 bytes
            "AAAAAAAAAAAAAAAAAAAAAAAAAAAA", // 21 bytes
            "dGhlIHNhbXBsZSBub25jZQ=!",
            "dGhlIHNhbXBsZSBub25jZ*==",
        ] {
            let e = check_websocket(&upgrade("GET", Some("13"), Some(bad))).unwrap_err();
            assert_eq!(e, HandshakeError::BadKey(bad.into()));
            assert_eq!(e.response().status, 400, "{bad}");
        }
        for (req, want) in [
            (upgrade("GET", None, Some(KEY)), HandshakeError::NoVersion),
            (upgrade("GET", Some("13"), None), HandshakeError::NoKey),
            (upgrade("POST", Some("13"), Some(KEY)), HandshakeError::NotGet("POST".into())),
        ] {
            let e = check_websocket(&req).unwrap_err();
            assert_eq!(e, want);
            assert_eq!(e.response().status, 400, "{e}");
        }
    }

    #[test]
    fn header_values_refuse_line_breaks_and_controls() {
        // RFC 9110, section 5.5: field-value = *field-content; no CR, LF or NUL, ever.
        for bad in ["a\r\nSet-Cookie: x=1", "a\nb", "a\rb", "a\0b", "\u{7f}", "é", " lead", "trail\t"] {
            assert!(HeaderValue::new(bad).is_err(), "{bad:?}");
        }
        for good in ["", "a", "attachment; filename=\"t.glb\"", "a b\tc", "x=1; Path=/"] {
            assert_eq!(HeaderValue::new(good).unwrap().as_str(), good);
        }
        assert!(HeaderValue::new("x".repeat(MAX_HEADER_VALUE_BYTES + 1)).is_err());
        assert_eq!(HeaderValue::number(42u64).as_str(), "42");
        // A download's name that could leave its quotes gets no header at all.
        assert_eq!(attachment("take-1.glb").unwrap().as_str(), "attachment; filename=\"take-1.glb\"");
        for bad in ["a\"b", "a\r\nb", "a;b", "", "a b"] {
            assert!(attachment(bad).is_none(), "{bad:?}");
        }
    }

    #[test]
    fn a_response_head_holds_only_checked_values() {
        let r = Response::new(200, "text/plain", "x").with("Set-Cookie", HeaderValue::new("a=b").unwrap());
        let mut out = Vec::new();
        r.write_to(&mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        let head = text.split("\r\n\r\n").next().unwrap();
        assert_eq!(head.lines().filter(|l| l.starts_with("Set-Cookie")).count(), 1, "{head}");
    }

    #[test]
    fn a_second_host_or_origin_is_refused() {
        // RFC 9112, section 3.2: a request with more than one Host is answered 400.
        for name in ["Host", "Origin", "Authorization", "Cookie"] {
            let (status, text) = refusal(&format!("GET / HTTP/1.1\r\n{name}: a\r\n{name}: a\r\n\r\n"));
            assert_eq!(status, Some(400), "{name}: {text}");
            assert!(text.contains(&format!("2 {} headers", name.to_ascii_lowercase())), "{text}");
        }
    }

    #[test]
    fn a_bare_line_feed_in_the_head_is_refused() {
        for head in [
            "GET / HTTP/1.1\nHost: 127.0.0.1\n\n",
            "GET / HTTP/1.1\r\nHost: 127.0.0.1\nX: y\r\n\r\n",
            "POST / HTTP/1.1\nHost: 127.0.0.1\nContent-Length: 4\n\nABCD\r\n\r\n",
        ] {
            let (status, text) = refusal(head);
            assert_eq!(status, Some(400), "{head:?}: {text}");
            assert!(text.contains("bare LF"), "{text}");
        }
        // A body may hold line feeds of its own.
        let (r, len) =
            parse_head(b"POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 3\r\n\r\n").unwrap();
        assert_eq!((r.method.as_str(), len), ("POST", 3));
    }

    /// A head ended by `LF LF` is refused at once, not read until the deadline, and its body is
    /// never taken from after a later `CRLF CRLF` (the two ends disagreed).
    #[test]
    fn a_head_of_bare_line_feeds_is_refused_at_once() {
        use std::net::TcpListener;
        use std::time::Duration;
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let mut client = TcpStream::connect(l.local_addr().unwrap()).unwrap();
        let (mut server, _) = l.accept().unwrap();
        client
            .write_all(
                b"POST /api/takes/repair HTTP/1.1\nHost: 127.0.0.1\nContent-Length: 4\n\nABCD\r\n\r\n{\"take\"",
            )
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(30);
        let e = read_request(&mut server, deadline, MAX_BODY_BYTES).unwrap_err();
        assert_eq!(e.status(), Some(400), "{e}");
        assert!(e.to_string().contains("bare LF"), "{e}");
        let mut client = TcpStream::connect(l.local_addr().unwrap()).unwrap();
        let (mut server, _) = l.accept().unwrap();
        client.write_all(b"GET / HTTP/1.1\nHost: 127.0.0.1\n\n").unwrap();
        let e = read_request(&mut server, deadline, MAX_BODY_BYTES).unwrap_err();
        assert_eq!(e.status(), Some(400), "{e}");
        assert!(Instant::now() + Duration::from_secs(20) < deadline, "waited for the deadline");
    }

    #[test]
    fn a_request_trickled_past_its_deadline_times_out() {
        use std::net::TcpListener;
        use std::time::Duration;
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let mut client = TcpStream::connect(l.local_addr().unwrap()).unwrap();
        let (mut server, _) = l.accept().unwrap();
        let writer = std::thread::spawn(move || {
            // One byte every 20 ms: each read succeeds well within any per-read timeout.
            for b in b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa" {
                if client.write_all(&[*b]).is_err() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        let start = Instant::now();
        let e = read_request(&mut server, start + Duration::from_millis(300), MAX_BODY_BYTES).unwrap_err();
        assert!(matches!(e, HttpError::Timeout), "{e}");
        assert_eq!(e.status(), Some(408));
        drop(server);
        writer.join().unwrap();
    }
}
