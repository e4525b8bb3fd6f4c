//! frond following a stage master: what to do with each trigger datagram. Pure, no I/O.
//!
//! The caller (a listener thread in the daemon) hands every datagram with its sender and the
//! monotonic time to [`Follower::on_datagram`], acts on the [`Decision`], and calls
//! [`Follower::poll`] at [`Follower::next_deadline`] to start a take whose `Delay` has run.
//! Rules, from the issue and the published formats:
//! - a sender outside the allow-list is ignored and counted, and its bytes are not parsed;
//! - an oversized or malformed datagram is refused and counted;
//! - `PacketID`s are tracked per sender (and process id): a repeat is a duplicate, a lower one
//!   within [`REORDER_WINDOW`] is out of order, both ignored; a much lower one is a restarted
//!   sender and accepted;
//! - `CaptureStart` starts a take named by [`safe_take_name`], after `Delay` ms if honoured;
//!   while a take runs another start is ignored (a take is never cut short silently);
//! - `CaptureStop` stops the take it names (or any, if it names none); a stop while nothing
//!   is recording, or naming another take, is answered with nothing but a count;
//! - a stop before a delayed start cancels the start.

use std::net::IpAddr;

use frond_ltc::SmpteTime;

use crate::decode::{DecodeError, decode};
use crate::message::{MAX_DATAGRAM_BYTES, StopResult, TriggerFields, TriggerMessage};
use crate::take_name::safe_take_name;

/// How far below the last packet id a packet counts as reordered rather than a restarted
/// sender.
pub const REORDER_WINDOW: u64 = 1024;
/// Senders whose packet ids are remembered; the least recently heard is forgotten first.
pub const MAX_SENDERS: usize = 32;

/// What the follower follows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FollowerConfig {
    /// Hosts whose messages are followed; `None` follows any host.
    pub allow: Option<Vec<IpAddr>>,
    /// Whether a start waits for its `Delay`.
    pub honour_delay: bool,
}

/// A take to start.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StartTake {
    /// The take name, valid by frond's rule.
    pub name: String,
    /// The name as the master sent it.
    pub sent_name: Option<String>,
    /// The master's notes.
    pub notes: Option<String>,
    /// The master's description.
    pub description: Option<String>,
    /// The master's timecode at the start, if it sent one.
    pub timecode: Option<SmpteTime>,
    /// Who sent it.
    pub sender: IpAddr,
    /// When recording should begin (the message's time plus its delay), monotonic ns.
    pub start_at_ns: u64,
}

/// Why a message changed nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ignored {
    /// From a host outside the allow-list.
    Foreign,
    /// A packet id already seen.
    Duplicate,
    /// A packet id older than the last one.
    OutOfOrder,
    /// A stop while nothing is recording.
    NotRecording,
    /// A stop naming another take.
    OtherTake,
    /// A start while a take is recording or scheduled.
    AlreadyRecording,
}

/// What to do with one message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Decision {
    /// Start this take now.
    Start(StartTake),
    /// A start is scheduled at `at_ns`; [`Follower::poll`] then returns it.
    Scheduled {
        /// When, monotonic ns.
        at_ns: u64,
    },
    /// Stop the take recording.
    Stop {
        /// Its name.
        name: String,
        /// How the master's capture ended.
        result: StopResult,
    },
    /// A stop arrived before the delayed start: nothing will be recorded.
    CancelScheduled,
    /// Nothing to do.
    Ignored(Ignored),
    /// The datagram was refused.
    Refused(DecodeError),
}

/// Counts for status, the console and `frond doctor`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FollowerCounters {
    /// Datagrams received.
    pub received: u64,
    /// Takes started.
    pub started: u64,
    /// Takes stopped.
    pub stopped: u64,
    /// Delayed starts cancelled by a stop.
    pub cancelled: u64,
    /// From hosts outside the allow-list.
    pub foreign: u64,
    /// Over [`MAX_DATAGRAM_BYTES`].
    pub oversized: u64,
    /// Not a trigger message.
    pub malformed: u64,
    /// Repeated packet ids.
    pub duplicates: u64,
    /// Older packet ids.
    pub out_of_order: u64,
    /// Stops while nothing was recording.
    pub not_recording: u64,
    /// Stops naming another take.
    pub other_take: u64,
    /// Starts while a take was recording.
    pub already_recording: u64,
}

/// The last message followed or ignored (not refused), for status.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LastMessage {
    /// Sender.
    pub from: IpAddr,
    /// `CaptureStart` or `CaptureStop`.
    pub kind: &'static str,
    /// The name it carried.
    pub name: Option<String>,
    /// Its packet id.
    pub packet_id: Option<u64>,
    /// When it arrived, monotonic ns.
    pub at_ns: u64,
}

/// Where the follower is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FollowerState {
    /// No trigger take.
    Idle,
    /// A start waiting for its delay.
    Scheduled(StartTake),
    /// A trigger take recording.
    Recording {
        /// Its name.
        name: String,
    },
}

#[derive(Debug, Clone)]
struct Sender {
    host: IpAddr,
    process_id: Option<String>,
    last_packet_id: u64,
    heard_ns: u64,
}

/// The follower: configuration, state, per-sender packet ids, counters.
#[derive(Debug, Clone)]
pub struct Follower {
    config: FollowerConfig,
    state: FollowerState,
    senders: Vec<Sender>,
    counters: FollowerCounters,
    last: Option<LastMessage>,
}

impl Follower {
    /// An idle follower.
    pub fn new(config: FollowerConfig) -> Follower {
        Follower {
            config,
            state: FollowerState::Idle,
            senders: Vec::new(),
            counters: FollowerCounters::default(),
            last: None,
        }
    }

    /// Counts so far.
    pub fn counters(&self) -> FollowerCounters {
        self.counters
    }

    /// The last message followed or ignored.
    pub fn last_message(&self) -> Option<&LastMessage> {
        self.last.as_ref()
    }

    /// Where the follower is.
    pub fn state(&self) -> &FollowerState {
        &self.state
    }

    /// When [`Follower::poll`] should be called next, if a start is scheduled.
    pub fn next_deadline(&self) -> Option<u64> {
        match &self.state {
            FollowerState::Scheduled(take) => Some(take.start_at_ns),
            _ => None,
        }
    }

    /// The take the follower started has ended some other way (the operator stopped it, the
    /// disk failed): the next start is followed again.
    pub fn take_ended(&mut self) {
        self.state = FollowerState::Idle;
    }

    /// Starts a scheduled take whose time has come.
    pub fn poll(&mut self, now_ns: u64) -> Option<StartTake> {
        match &self.state {
            FollowerState::Scheduled(take) if now_ns >= take.start_at_ns => {
                let take = take.clone();
                self.state = FollowerState::Recording { name: take.name.clone() };
                self.counters.started += 1;
                Some(take)
            }
            _ => None,
        }
    }

    /// Decides what one datagram from `from`, received at `now_ns`, means.
    pub fn on_datagram(&mut self, from: IpAddr, datagram: &[u8], now_ns: u64) -> Decision {
        self.counters.received += 1;
        if let Some(allow) = &self.config.allow
            && !allow.contains(&from)
        {
            self.counters.foreign += 1;
            return Decision::Ignored(Ignored::Foreign);
        }
        if datagram.len() > MAX_DATAGRAM_BYTES {
            self.counters.oversized += 1;
            return Decision::Refused(DecodeError::Oversized(datagram.len()));
        }
        match decode(datagram) {
            Ok(message) => self.on_message(from, &message, now_ns),
            Err(e) => {
                self.counters.malformed += 1;
                Decision::Refused(e)
            }
        }
    }

    /// Decides what one decoded message means (the allow-list is [`Follower::on_datagram`]'s).
    pub fn on_message(&mut self, from: IpAddr, message: &TriggerMessage, now_ns: u64) -> Decision {
        let fields = message.fields();
        if let Some(ignored) = self.check_sequence(from, fields, now_ns) {
            return Decision::Ignored(ignored);
        }
        self.last = Some(LastMessage {
            from,
            kind: message.kind(),
            name: fields.name.clone(),
            packet_id: fields.packet_id,
            at_ns: now_ns,
        });
        match message {
            TriggerMessage::Start(fields) => self.start(from, fields, now_ns),
            TriggerMessage::Stop { fields, result } => self.stop(fields, *result),
        }
    }

    fn check_sequence(&mut self, from: IpAddr, fields: &TriggerFields, now_ns: u64) -> Option<Ignored> {
        let id = fields.packet_id?;
        let known = self.senders.iter().position(|s| s.host == from && s.process_id == fields.process_id);
        let Some(i) = known else {
            if self.senders.len() == MAX_SENDERS
                && let Some(oldest) = (0..self.senders.len()).min_by_key(|&i| self.senders[i].heard_ns)
            {
                self.senders.swap_remove(oldest);
            }
            let process_id = fields.process_id.clone();
            self.senders.push(Sender { host: from, process_id, last_packet_id: id, heard_ns: now_ns });
            return None;
        };
        let sender = &mut self.senders[i];
        let last = sender.last_packet_id;
        if id == last {
            self.counters.duplicates += 1;
            return Some(Ignored::Duplicate);
        }
        if id < last && last - id <= REORDER_WINDOW {
            self.counters.out_of_order += 1;
            return Some(Ignored::OutOfOrder);
        }
        sender.last_packet_id = id;
        sender.heard_ns = now_ns;
        None
    }

    fn start(&mut self, from: IpAddr, fields: &TriggerFields, now_ns: u64) -> Decision {
        if self.state != FollowerState::Idle {
            self.counters.already_recording += 1;
            return Decision::Ignored(Ignored::AlreadyRecording);
        }
        let fallback = format!("trigger-{}", fields.packet_id.unwrap_or(self.counters.started + 1));
        let name = safe_take_name(fields.name.as_deref().unwrap_or(""), &fallback).unwrap_or(fallback);
        let delay_ms = if self.config.honour_delay { fields.delay_ms.unwrap_or(0) } else { 0 };
        let take = StartTake {
            name,
            sent_name: fields.name.clone(),
            notes: fields.notes.clone(),
            description: fields.description.clone(),
            timecode: fields.timecode,
            sender: from,
            start_at_ns: now_ns.saturating_add(u64::from(delay_ms) * 1_000_000),
        };
        if delay_ms == 0 {
            self.state = FollowerState::Recording { name: take.name.clone() };
            self.counters.started += 1;
            return Decision::Start(take);
        }
        let at_ns = take.start_at_ns;
        self.state = FollowerState::Scheduled(take);
        Decision::Scheduled { at_ns }
    }

    fn stop(&mut self, fields: &TriggerFields, result: StopResult) -> Decision {
        let current = match &self.state {
            FollowerState::Idle => {
                self.counters.not_recording += 1;
                return Decision::Ignored(Ignored::NotRecording);
            }
            FollowerState::Scheduled(take) => &take.name,
            FollowerState::Recording { name } => name,
        };
        let names_it = match fields.name.as_deref() {
            None | Some("") => true,
            Some(sent) => safe_take_name(sent, "").as_deref() == Some(current.as_str()),
        };
        if !names_it {
            self.counters.other_take += 1;
            return Decision::Ignored(Ignored::OtherTake);
        }
        let name = current.clone();
        let was_scheduled = matches!(self.state, FollowerState::Scheduled(_));
        self.state = FollowerState::Idle;
        if was_scheduled {
            self.counters.cancelled += 1;
            return Decision::CancelScheduled;
        }
        self.counters.stopped += 1;
        Decision::Stop { name, result }
    }
}
