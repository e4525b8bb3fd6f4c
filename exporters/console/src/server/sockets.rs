//! The pose and warp WebSockets of [`Console`]: each page's own thread, sending at its rate,
//! dropping (and counting) what a slow page cannot take, never blocking another page or the
//! subscription.

use std::io;
use std::net::{Shutdown, TcpStream};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use frond_protocol::Pose;
use serde_json::{Value, json};
use tungstenite::protocol::{Role, WebSocketConfig};
use tungstenite::{Message, WebSocket};

use super::{Console, MAX_QUEUED_BYTES, MAX_SOCKETS};
use crate::warp_panel::{self, WarpPanel};
use frond_web::http::{self, Request, Response};

mod fields;

/// Largest message (and frame) a page may send on its socket; a larger one closes it.
pub const MAX_PAGE_MESSAGE_BYTES: usize = 4096;

impl Console {
    /// A WebSocket upgrade: its path (404), its handshake (400, 426: [`http::check_websocket`]),
    /// room for it (503), then the socket until the page goes away.
    pub(super) fn socket(&self, req: Request, mut stream: TcpStream) {
        let warp = match (req.path.as_str(), &self.warp) {
            ("/ws", _) => None,
            ("/ws/warp", Some(w)) => Some(Arc::clone(w)),
            (p, _) => {
                let why = if p == "/ws/warp" {
                    "the warp panel is off (--no-warp)".to_string()
                } else {
                    format!("no WebSocket at {p}")
                };
                let _ = Response::error(404, why).write_for(&req.method, &mut stream);
                return;
            }
        };
        if let Err(e) = http::check_websocket(&req) {
            let _ = e.response().write_for(&req.method, &mut stream);
            return;
        }
        let Some(_page) = self.open_page(&stream) else {
            let _ = Response::error(503, "the page's socket could not be kept").write_to(&mut stream);
            return;
        };
        if http::accept_websocket(&req, &mut stream).unwrap_or(false) && stream.set_nonblocking(true).is_ok()
        {
            // A page sends nothing but control frames (a ping's payload is at most 125 bytes):
            // tungstenite's default took messages of 64 MiB, which the thread held while it
            // read them, 1 GiB over the 16 sockets.
            let config = WebSocketConfig::default()
                .max_write_buffer_size(MAX_QUEUED_BYTES * 2)
                .max_message_size(Some(MAX_PAGE_MESSAGE_BYTES))
                .max_frame_size(Some(MAX_PAGE_MESSAGE_BYTES));
            let mut ws = WebSocket::from_raw_socket(stream, Role::Server, Some(config));
            match warp {
                None => self.stream_poses(&mut ws),
                Some(w) => {
                    w.viewers.fetch_add(1, Ordering::AcqRel);
                    self.stream_warp(&mut ws, &w);
                    w.viewers.fetch_sub(1, Ordering::AcqRel);
                }
            }
        }
    }

    /// Counts `stream` among the open pages until the guard drops, first closing the oldest
    /// page when [`MAX_SOCKETS`] are open: a client that opens pages and keeps them (reading
    /// or not) kept every new page out (503) for as long as it liked.
    fn open_page(&self, stream: &TcpStream) -> Option<PageGuard<'_>> {
        let handle = stream.try_clone().ok()?;
        let mut pages = self.counters.pages.lock().unwrap_or_else(|e| e.into_inner());
        while pages.open.len() >= MAX_SOCKETS {
            let (_, oldest) = pages.open.remove(0);
            let _ = oldest.shutdown(Shutdown::Both);
            self.counters.pages_closed.fetch_add(1, Ordering::Relaxed);
        }
        let id = pages.next;
        pages.next += 1;
        pages.open.push((id, handle));
        self.counters.sockets.store(pages.open.len(), Ordering::Relaxed);
        Some(PageGuard { console: self, id })
    }

    /// Sends the page its poses until it goes away: at most `display_hz` messages a second, each
    /// with every element's latest pose it has not had; a page that reads too slowly loses
    /// messages (counted), never delays another.
    fn stream_poses(&self, ws: &mut WebSocket<TcpStream>) {
        let period = Duration::from_secs_f64(1.0 / f64::from(self.config.display_hz));
        let (mut sent, mut poses) = (Vec::new(), Vec::new());
        let mut version = u64::MAX;
        let mut field_cursor = fields::FieldCursor::default();
        let mut flow = fields::PageFlow::default();
        let mut next = Instant::now();
        loop {
            // Close frames and pings from the page (pongs are queued by tungstenite), and what
            // it says it has taken.
            if !self.drain_reads(ws, Some(&mut flow)) {
                return;
            }
            // A page slower than the stream gets the latest when it is ready, not a queue.
            if flow.behind() {
                if !self.flush(ws) {
                    return;
                }
                crate::pace(&mut next, period);
                continue;
            }
            let now_version = self.live.changed_since(&mut sent, &mut poses);
            if now_version != version {
                match flow.count(self.send(ws, self.hello_json().to_string())) {
                    Sent::Queued => version = now_version,
                    Sent::Dropped => {} // sent again next time
                    Sent::Gone => return,
                }
            }
            if !poses.is_empty() {
                let n = poses.len() as u64;
                let msg =
                    json!({ "type": "poses", "poses": poses.iter().map(pose_value).collect::<Vec<_>>() });
                match flow.count(self.send(ws, msg.to_string())) {
                    Sent::Queued => {
                        self.counters.poses_sent.fetch_add(n, Ordering::Relaxed);
                    }
                    // The page lost these: every element's latest pose goes again next time,
                    // so the latest frame always reaches it.
                    Sent::Dropped => sent.clear(),
                    Sent::Gone => return,
                }
            }
            if !self.send_fields(ws, &mut field_cursor, &mut flow) || !self.flush(ws) {
                return;
            }
            crate::pace(&mut next, period);
        }
    }

    /// Sends the warp panel's frames (binary JPEG messages, each new frame once) and its state
    /// (a text message twice a second) until the page goes away.
    fn stream_warp(&self, ws: &mut WebSocket<TcpStream>, panel: &WarpPanel) {
        let period = Duration::from_secs_f32(1.0 / warp_panel::WARP_FPS / 2.0);
        let (mut sent, mut last_state) = (0u64, Instant::now() - Duration::from_secs(1));
        loop {
            if !self.drain_reads(ws, None) {
                return;
            }
            let (number, jpeg, state) = panel.latest();
            if number != sent && number > 0 {
                sent = number;
                if self.queue(ws, Message::binary(jpeg.to_vec())) == Sent::Gone {
                    return;
                }
            }
            if last_state.elapsed() >= Duration::from_millis(500) && number > 0 {
                last_state = Instant::now();
                if self.send(ws, json!({ "type": "warp", "state": state }).to_string()) == Sent::Gone {
                    return;
                }
            }
            if !self.flush(ws) {
                return;
            }
            std::thread::sleep(period);
        }
    }

    /// Reads what the page sent (close frames, pings, what it has taken when `flow` is
    /// kept); false when it is gone.
    fn drain_reads(&self, ws: &mut WebSocket<TcpStream>, mut flow: Option<&mut fields::PageFlow>) -> bool {
        loop {
            match ws.read() {
                Ok(Message::Close(_)) => return false,
                Ok(Message::Text(text)) => {
                    if let Some(f) = flow.as_deref_mut() {
                        f.on_text(&text);
                    }
                }
                Ok(_) => {}
                Err(tungstenite::Error::Io(e)) if e.kind() == io::ErrorKind::WouldBlock => return true,
                Err(_) => return false,
            }
        }
    }

    /// Queues one text message.
    fn send(&self, ws: &mut WebSocket<TcpStream>, text: String) -> Sent {
        self.queue(ws, Message::text(text))
    }

    /// Queues one message; a page that has not taken what is queued loses it (counted).
    fn queue(&self, ws: &mut WebSocket<TcpStream>, msg: Message) -> Sent {
        match ws.send(msg) {
            // Queued (the rest goes out at the next flush when the socket is full).
            Ok(()) => {}
            Err(tungstenite::Error::Io(e)) if e.kind() == io::ErrorKind::WouldBlock => {}
            Err(tungstenite::Error::WriteBufferFull(_)) => {
                self.counters.dropped.fetch_add(1, Ordering::Relaxed);
                return Sent::Dropped;
            }
            Err(_) => return Sent::Gone,
        }
        self.counters.messages.fetch_add(1, Ordering::Relaxed);
        Sent::Queued
    }

    /// Sends what is queued as far as the socket takes it; false when the page is gone.
    fn flush(&self, ws: &mut WebSocket<TcpStream>) -> bool {
        match ws.flush() {
            Ok(()) => true,
            Err(tungstenite::Error::Io(e)) if e.kind() == io::ErrorKind::WouldBlock => true,
            Err(_) => false,
        }
    }
}

/// The open pages' sockets, oldest first.
#[derive(Debug, Default)]
pub(super) struct Pages {
    next: u64,
    open: Vec<(u64, TcpStream)>,
}

/// One open page; dropping it takes the page off the list.
struct PageGuard<'a> {
    console: &'a Console,
    id: u64,
}

impl Drop for PageGuard<'_> {
    fn drop(&mut self) {
        let c = &self.console.counters;
        let mut pages = c.pages.lock().unwrap_or_else(|e| e.into_inner());
        pages.open.retain(|(id, _)| *id != self.id);
        c.sockets.store(pages.open.len(), Ordering::Relaxed);
    }
}

/// What became of a message handed to the page's socket.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sent {
    /// On its way.
    Queued,
    /// Left out: the page has not taken what is queued.
    Dropped,
    /// The page is gone.
    Gone,
}

fn pose_value(p: &Pose) -> Value {
    json!({
        "e": p.element,
        "seq": p.seq,
        "j": p.joints_deg,
        "flags": p.flags.0,
        "dev_us": p.device_time_us,
        "host_ns": p.host_monotonic_ns,
    })
}
