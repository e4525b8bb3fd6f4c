//! What the control side and the trigger thread (`trigger_thread`) share about a mocap stage's
//! capture triggers (issue 46): the counts and last message that status shows, and the leader,
//! which sends frond's own `CaptureStart` / `CaptureStop` when `frond record start` / `stop`
//! (CLI, console, remote: every one ends in `ControlContext::handle`) starts or stops a take.
//!
//! Sending never blocks the control thread: the socket is non-blocking, and a send that fails
//! (a full buffer, no route) is counted and logged (rate-limited), never retried. A take started
//! by a trigger is not led (no echo between two systems that both follow and lead), and frond's
//! own messages heard back on its listening port (a broadcast reaches its sender too) are
//! recognised by their bytes and ignored.

use std::collections::VecDeque;
use std::net::{SocketAddr, UdpSocket};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::time::{Instant, SystemTime};

use frond_protocol::{TriggerLast, TriggerStatus};
use frond_triggers::Leader;
use tracing::{info, warn};

use crate::log_limit::LogLimit;

/// frond's own messages remembered to recognise them when they come back.
const OWN_MESSAGES_KEPT: usize = 8;

/// The trigger state status shows, and the leader: one per daemon, shared by the control
/// threads (which lead) and the trigger thread (which follows).
pub struct TriggerLink {
    book: Mutex<Book>,
    lead: Option<Mutex<Lead>>,
    /// Following is paused: the trigger thread hears starts and does not follow them.
    paused: AtomicBool,
}

/// What status reads, kept by the trigger thread and the leader.
struct Book {
    status: TriggerStatus,
    /// When the last message arrived, monotonic ns.
    last_at_ns: Option<u64>,
    /// frond's recent messages, as sent.
    sent: VecDeque<Vec<u8>>,
    /// The take frond led the stage into (its stop is led too).
    led_take: Option<String>,
}

/// The leader and where it sends.
struct Lead {
    leader: Leader,
    socket: UdpSocket,
    to: SocketAddr,
}

impl TriggerLink {
    /// A link listening on `listen` (the bound address, if frond follows) for `allow` (empty:
    /// any host), leading to `lead` through `socket` (non-blocking, broadcast allowed).
    pub fn new(
        listen: Option<SocketAddr>,
        allow: &[std::net::IpAddr],
        lead: Option<(UdpSocket, SocketAddr)>,
    ) -> Self {
        let status = TriggerStatus {
            listen: listen.map(|a| a.to_string()),
            allow: allow.iter().map(ToString::to_string).collect(),
            lead: lead.as_ref().map(|(_, to)| to.to_string()),
            ..TriggerStatus::default()
        };
        let lead = lead.map(|(socket, to)| {
            Mutex::new(Lead { leader: Leader::new(std::process::id(), first_packet_id()), socket, to })
        });
        TriggerLink {
            book: Mutex::new(Book { status, last_at_ns: None, sent: VecDeque::new(), led_take: None }),
            lead,
            paused: AtomicBool::new(false),
        }
    }

    /// Whether frond listens for triggers (and so can follow or pause).
    pub fn listens(&self) -> bool {
        self.book().status.listen.is_some()
    }

    /// Pauses following (`false`) or resumes it (`true`): what `frond triggers pause|follow`
    /// and the console's switch ask. Returns whether anything changed.
    pub fn set_following(&self, follow: bool) -> bool {
        let changed = self.paused.swap(!follow, Relaxed) == follow;
        self.book().status.paused = !follow;
        if changed {
            // A client toggling in a loop must not fill the log.
            static TOGGLED: LogLimit = LogLimit::new();
            TOGGLED.log("capture-trigger log lines", || {
                info!(follow, "capture triggers {}", if follow { "followed again" } else { "paused" })
            });
        }
        changed
    }

    /// Whether following is paused.
    pub fn paused(&self) -> bool {
        self.paused.load(Relaxed)
    }

    fn book(&self) -> std::sync::MutexGuard<'_, Book> {
        self.book.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The status section, the last message's age measured at `now_ns` (monotonic).
    pub fn status(&self, now_ns: u64) -> TriggerStatus {
        let book = self.book();
        let mut status = book.status.clone();
        if let (Some(last), Some(at)) = (status.last.as_mut(), book.last_at_ns) {
            last.age_s = now_ns.saturating_sub(at) as f64 / 1e9;
        }
        status
    }

    /// Lets the trigger thread change what status shows.
    pub fn update(&self, change: impl FnOnce(&mut TriggerStatus)) {
        change(&mut self.book().status);
    }

    /// Records the last message heard (from the follower's `LastMessage`).
    pub fn set_last(&self, last: &frond_triggers::LastMessage) {
        let mut book = self.book();
        book.last_at_ns = Some(last.at_ns);
        book.status.last = Some(TriggerLast {
            kind: last.kind.to_string(),
            name: last.name.clone(),
            from: last.from.to_string(),
            packet_id: last.packet_id,
            age_s: 0.0,
        });
    }

    /// Whether `bytes` is one of frond's own recent messages (heard back from a broadcast).
    pub fn is_own(&self, bytes: &[u8]) -> bool {
        let mut book = self.book();
        let own = book.sent.iter().any(|m| m == bytes);
        if own {
            book.status.own_echoes += 1;
        }
        own
    }

    /// Leads the stage into take `name` (frond's own `record start`): sends its `CaptureStart`.
    pub fn lead_start(&self, name: &str) {
        if self.send("CaptureStart", name, |leader| leader.start(name, None, 0)) {
            self.book().led_take = Some(name.to_string());
        }
    }

    /// Leads the stage out of take `name` (frond's own `record stop`), if frond led it in.
    pub fn lead_stop(&self, name: &str) {
        if self.lead.is_some() && self.book().led_take.take().as_deref() == Some(name) {
            self.send("CaptureStop", name, |leader| leader.stop(name, None));
        }
    }

    /// Encodes one message with the leader and sends it (never blocking), remembering its bytes
    /// first (so its echo is known whenever it comes back), counting and logging the outcome;
    /// `false` when frond does not lead.
    fn send(
        &self,
        kind: &str,
        name: &str,
        encode: impl FnOnce(&mut Leader) -> Result<&[u8], frond_triggers::EncodeError>,
    ) -> bool {
        static FAILED: LogLimit = LogLimit::new();
        let Some(lead) = &self.lead else { return false };
        let mut lead = lead.lock().unwrap_or_else(|e| e.into_inner());
        let Lead { leader, socket, to } = &mut *lead;
        let to = *to;
        let sent = match encode(leader) {
            Ok(bytes) => {
                self.remember(bytes);
                socket.send_to(bytes, to).map(drop).map_err(|e| e.to_string())
            }
            Err(e) => Err(e.to_string()),
        };
        let mut book = self.book();
        match sent {
            Ok(()) => {
                book.status.lead_sent += 1;
                info!(%kind, take = %name, %to, "capture trigger sent");
            }
            Err(error) => {
                book.status.lead_failed += 1;
                if FAILED.check(Instant::now()).log {
                    warn!(%kind, take = %name, %to, %error, "capture trigger not sent");
                }
            }
        }
        true
    }

    /// Keeps `bytes` among frond's recent messages.
    fn remember(&self, bytes: &[u8]) {
        let mut book = self.book();
        if book.sent.len() == OWN_MESSAGES_KEPT {
            book.sent.pop_front();
        }
        book.sent.push_back(bytes.to_vec());
    }
}

/// The first packet id frond leads with: from the wall clock (seconds, within 31 bits, as a
/// receiver may read it as a signed 32-bit number), so a restarted frond does not repeat the ids
/// a follower remembers.
fn first_packet_id() -> u64 {
    let s = SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(1);
    s & 0x7fff_ffff
}
