//! The console's HTTP/1.1, one request per connection (`Connection: close`): the request head
//! parsed by `httparse`, bounded before anything is allocated for it (head 16 KiB, 48 headers,
//! body 64 KiB), and the WebSocket upgrade handed to `tungstenite`. Small on purpose: the page
//! makes a handful of requests, the poses go over one WebSocket.

use std::io::{self, Read, Write};
use std::net::TcpStream;

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
}

impl HttpError {
    /// The status to answer with (none for a dead connection).
    pub fn status(&self) -> Option<u16> {
        match self {
            HttpError::Io(_) => None,
            HttpError::Bad(_) => Some(400),
            HttpError::TooLarge(_) => Some(413),
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

/// Parses a complete head (through the blank line) and the declared body length.
pub fn parse_head(head: &[u8]) -> Result<(Request, usize), HttpError> {
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
    if out.header("transfer-encoding").is_some() {
        return Err(HttpError::Bad("chunked request bodies are not taken; send Content-Length".into()));
    }
    let len = match out.header("content-length") {
        None => 0,
        Some(v) => {
            v.parse::<usize>().map_err(|_| HttpError::Bad(format!("Content-Length {v:?} is not a number")))?
        }
    };
    if len > MAX_BODY_BYTES {
        return Err(HttpError::TooLarge(format!("the body is {len} bytes; the limit is {MAX_BODY_BYTES}")));
    }
    Ok((out, len))
}

/// Reads one request from `stream` (its timeouts bound the wait).
pub fn read_request(stream: &mut TcpStream) -> Result<Request, HttpError> {
    let mut buf = vec![0u8; 2048];
    let mut have = 0;
    let end = loop {
        if let Some(i) = buf[..have].windows(4).position(|w| w == b"\r\n\r\n") {
            break i + 4;
        }
        if have == MAX_HEAD_BYTES {
            return Err(HttpError::TooLarge(format!("the request head passes {MAX_HEAD_BYTES} bytes")));
        }
        if have == buf.len() {
            buf.resize((buf.len() * 2).min(MAX_HEAD_BYTES), 0);
        }
        let n = stream.read(&mut buf[have..])?;
        if n == 0 {
            return Err(HttpError::Io(io::ErrorKind::UnexpectedEof.into()));
        }
        have += n;
    };
    let (mut req, len) = parse_head(&buf[..end])?;
    let mut body = buf[end..have].to_vec();
    body.truncate(len);
    if body.len() < len {
        let start = body.len();
        body.resize(len, 0);
        stream.read_exact(&mut body[start..])?;
    }
    req.body = body;
    Ok(req)
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
        409 => "Conflict",
        413 => "Payload Too Large",
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
    pub headers: Vec<(&'static str, String)>,
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
    pub fn with(mut self, name: &'static str, value: impl Into<String>) -> Response {
        self.headers.push((name, value.into()));
        self
    }

    /// Writes the response and ends the exchange.
    pub fn write_to(&self, w: &mut impl Write) -> io::Result<()> {
        let mut head = format!(
            "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nConnection: close\r\n\
             X-Content-Type-Options: nosniff\r\n",
            self.status,
            reason(self.status),
            self.content_type,
            self.body.len()
        );
        if !self.headers.iter().any(|(n, _)| n.eq_ignore_ascii_case("cache-control")) {
            head.push_str("Cache-Control: no-store\r\n");
        }
        for (n, v) in &self.headers {
            head.push_str(&format!("{n}: {v}\r\n"));
        }
        head.push_str("\r\n");
        w.write_all(head.as_bytes())?;
        w.write_all(&self.body)?;
        w.flush()
    }
}

/// Answers a WebSocket upgrade with 101 (the `Sec-WebSocket-Key` must be there).
pub fn accept_websocket(req: &Request, w: &mut impl Write) -> Result<(), HttpError> {
    let key = req.header("sec-websocket-key").ok_or_else(|| HttpError::Bad("no Sec-WebSocket-Key".into()))?;
    let accept = tungstenite::handshake::derive_accept_key(key.as_bytes());
    write!(
        w,
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n"
    )?;
    w.flush()?;
    Ok(())
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
        assert!(r.is_websocket());
        let mut out = Vec::new();
        accept_websocket(&r, &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.contains("Sec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"), "{text}");
    }
}
