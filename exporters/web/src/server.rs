//! The accept loop every page of frond's shares: one thread accepts, the [`Gate`] admits, each
//! admitted connection gets a short-lived thread that reads its request within the deadline,
//! checks it against the [`Access`] policy, and hands it to the [`Site`]; the answer is written
//! within the write deadline. WebSocket upgrades that pass the check are handed over whole.
//!
//! The server, not the site, sets the token cookie: only when the request presented the
//! configured token in `?token=` on the page (`/`), and with the configured token's bytes, never
//! the request's.

use std::io::{self, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::access::{Access, Grant, Purpose, Refusal, RequestMeta, TOKEN_COOKIE};
use crate::gate::{Gate, Limits, Ticket};
use crate::http::{self, HeaderValue, Request, Response};

/// What a server serves: the answers to requests that passed the access check.
pub trait Site: Send + Sync + 'static {
    /// The answer to `req` (a `HEAD` is answered with the head of this answer).
    fn answer(&self, req: &Request, grant: Grant) -> Response;

    /// A WebSocket upgrade that passed the access check: the connection is the site's (it
    /// checks the handshake, [`http::check_websocket`], and answers it). By default none is
    /// served.
    fn upgrade(&self, req: Request, mut stream: TcpStream) {
        let _ =
            Response::error(404, format!("no WebSocket at {}", req.path)).write_for(&req.method, &mut stream);
    }

    /// A request the access policy refused (for the site's counters).
    fn refused(&self, _refusal: &Refusal) {}
}

/// A [`Site`] made of one function from request to answer (no WebSockets).
pub struct Routes<F>(pub F);

impl<F: Fn(&Request) -> Response + Send + Sync + 'static> Site for Routes<F> {
    fn answer(&self, req: &Request, _grant: Grant) -> Response {
        (self.0)(req)
    }
}

/// How long a refusal or an error may take to be written to a peer that does not read.
const ERROR_WRITE: Duration = Duration::from_secs(1);

/// A running server's parts.
pub struct Server {
    access: Access,
    gate: Arc<Gate>,
    site: Arc<dyn Site>,
}

impl Server {
    /// A server for `site` under `access` and `limits`.
    pub fn new(access: Access, limits: Limits, site: Arc<dyn Site>) -> Arc<Server> {
        Arc::new(Server { access, gate: Gate::new(limits), site })
    }

    /// Its gate (for its counters).
    pub fn gate(&self) -> &Arc<Gate> {
        &self.gate
    }

    /// Serves `listener` until the process ends.
    pub fn serve(self: &Arc<Server>, listener: TcpListener) {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            let Ok(peer) = stream.peer_addr() else { continue };
            let ticket = match self.gate.admit(&stream, peer.ip()) {
                Ok(t) => t,
                Err(_) => {
                    let _ = stream.set_write_timeout(Some(ERROR_WRITE));
                    let _ = Response::error(503, "every connection is being answered; try again")
                        .write_to(&mut stream);
                    continue;
                }
            };
            let me = Arc::clone(self);
            // A thread that cannot be made drops the ticket and the stream with the closure.
            let _ = std::thread::Builder::new()
                .name("web-conn".into())
                .spawn(move || me.connection(stream, ticket));
        }
    }

    fn connection(&self, mut stream: TcpStream, mut ticket: Ticket) {
        let limits = self.gate.limits();
        let req = match http::read_request(
            &mut stream,
            Instant::now() + limits.request_deadline,
            limits.max_body_bytes,
        ) {
            Ok(r) => r,
            Err(e) => {
                if matches!(e, http::HttpError::Timeout) {
                    ticket.timed_out();
                }
                if let Some(status) = e.status() {
                    let _ = stream.set_write_timeout(Some(ERROR_WRITE));
                    let _ = Response::error(status, e.to_string()).write_to(&mut stream);
                }
                return;
            }
        };
        if !ticket.answering() {
            return; // evicted while its last bytes arrived
        }
        let purpose = match (req.method.as_str(), req.is_websocket()) {
            (_, true) => Purpose::Socket,
            ("POST", _) => Purpose::Control,
            _ => Purpose::Read,
        };
        let meta = RequestMeta {
            host: req.header("host"),
            origin: req.header("origin"),
            authorization: req.header("authorization"),
            cookie: req.header("cookie"),
            query_token: req.param("token"),
            fetch_site: req.header("sec-fetch-site"),
            fetch_mode: req.header("sec-fetch-mode"),
            fetch_dest: req.header("sec-fetch-dest"),
        };
        let grant = match self.access.check(&meta, purpose) {
            Ok(g) => g,
            Err(refusal) => {
                self.site.refused(&refusal);
                let _ = stream.set_write_timeout(Some(ERROR_WRITE));
                let _ = Response::error(refusal.status(), refusal.to_string())
                    .write_for(&req.method, &mut stream);
                return;
            }
        };
        if purpose == Purpose::Socket {
            ticket.release();
            self.site.upgrade(req, stream);
            return;
        }
        let mut resp = self.site.answer(&req, grant);
        if let Some(cookie) = self.cookie(&req, grant) {
            resp = resp.with("Set-Cookie", cookie);
        }
        ticket.writing(if req.method == "HEAD" { 0 } else { resp.body.len() });
        let mut out =
            DeadlineWriter { stream: &mut stream, deadline: Instant::now() + limits.write_deadline };
        let _ = resp.write_for(&req.method, &mut out);
    }

    /// The token cookie for the page opened as `/?token=T` with the configured token.
    fn cookie(&self, req: &Request, grant: Grant) -> Option<HeaderValue> {
        if req.path != "/" || !grant.token_matched || req.param("token").is_none() {
            return None;
        }
        let token = self.access.token.as_deref()?;
        HeaderValue::new(format!("{TOKEN_COOKIE}={token}; Path=/; HttpOnly; SameSite=Strict")).ok()
    }
}

/// Writes to a stream until one deadline for the whole answer (each write waits at most what is
/// left), so a peer that reads a byte now and then cannot hold the connection.
struct DeadlineWriter<'a> {
    stream: &'a mut TcpStream,
    deadline: Instant,
}

impl Write for DeadlineWriter<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(io::ErrorKind::TimedOut.into());
        }
        self.stream.set_write_timeout(Some(left))?;
        self.stream.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.stream.flush()
    }
}
