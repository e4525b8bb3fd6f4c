//! The bridge's replay ring and its peers' loss reports (issue 43; the wire is
//! [`frond_sdk::zenoh_replay`]'s).
//!
//! Poses go out with congestion *drop*: a peer whose link's queue is full loses them, and Zenoh
//! tells the publisher nothing. So the bridge keeps the last poses it published, with the
//! element tables between them, in a bounded ring, and answers `.../replay` queries from it: a
//! reliable subscriber (a stage recorder) asks for what it missed, and gets it without anyone
//! else waiting. The same queries carry each SDK subscriber's own counts about once a second, so
//! the bridge knows every peer's losses: `frond-zenoh --stats` prints them and `.../peers`
//! answers them as JSON.

use std::collections::{HashMap, VecDeque};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use frond_sdk::zenoh_replay::{MAX_REQUEST_POSES, PeerReport, REPLY_FRAMES, ReplayRequest, reply_attachment};
use zenoh::bytes::ZBytes;

/// Poses the ring keeps by default: 10 s at 1 kHz.
pub const DEFAULT_REPLAY_FRAMES: usize = 10_000;
/// Most poses `--replay-frames` may ask the ring to keep (about 30 MB of frames).
pub const MAX_REPLAY_FRAMES: usize = 100_000;
/// Most peers the bridge keeps counts for; the one heard from longest ago makes room.
pub const MAX_PEERS: usize = 64;

/// One frame the bridge published.
struct Entry {
    /// A pose's sequence number; for an element table, the pose due after it.
    seq: u64,
    /// The frame, shared with the sample Zenoh sent.
    frame: ZBytes,
    /// The pose's stage time (0 for a table).
    stage_ns: u64,
    pose: bool,
}

/// One reply to a replay query: its payload and its attachment.
pub(crate) type Reply = (Vec<u8>, Vec<u8>);

/// The last poses published, with the tables between them.
pub(crate) struct Ring {
    entries: VecDeque<Entry>,
    /// Poses kept at most (tables come on top, at most one per pose).
    poses: usize,
    held: usize,
}

impl Ring {
    pub(crate) fn new(poses: usize) -> Ring {
        Ring { entries: VecDeque::new(), poses, held: 0 }
    }

    /// A new stream (another daemon, or the same restarted): its numbers start again.
    pub(crate) fn clear(&mut self) {
        self.entries.clear();
        self.held = 0;
    }

    pub(crate) fn push_pose(&mut self, seq: u64, frame: ZBytes, stage_ns: u64) {
        if self.poses == 0 {
            return;
        }
        if self.entries.back().is_some_and(|e| e.seq > seq) {
            self.clear();
        }
        self.entries.push_back(Entry { seq, frame, stage_ns, pose: true });
        self.held += 1;
        while self.held > self.poses {
            match self.entries.pop_front() {
                Some(e) if e.pose => self.held -= 1,
                Some(_) => {}
                None => break,
            }
        }
    }

    pub(crate) fn push_table(&mut self, next_seq: u64, frame: ZBytes) {
        if self.poses == 0 {
            return;
        }
        if self.entries.back().is_some_and(|e| e.seq > next_seq) {
            self.clear();
        }
        self.entries.push_back(Entry { seq: next_seq, frame, stage_ns: 0, pose: false });
    }

    /// The oldest pose held.
    fn oldest(&self) -> u64 {
        self.entries.iter().find(|e| e.pose).map_or(u64::MAX, |e| e.seq)
    }

    /// The replies to `from..to` (at most [`MAX_REQUEST_POSES`] poses): payloads of at most
    /// [`REPLY_FRAMES`] frames with their attachments (one empty reply when nothing matches),
    /// and how many poses they hold.
    pub(crate) fn answer(&self, from: u64, to: u64) -> (Vec<Reply>, u64) {
        let oldest = self.oldest();
        let to = to.min(from.saturating_add(MAX_REQUEST_POSES));
        let start = self.entries.partition_point(|e| e.seq < from);
        let mut replies = Vec::new();
        let (mut payload, mut stages) = (Vec::new(), Vec::new());
        let mut poses = 0;
        for e in self.entries.range(start..).take_while(|e| e.seq < to) {
            poses += u64::from(e.pose);
            payload.extend_from_slice(&e.frame.to_bytes());
            stages.push(e.stage_ns);
            if stages.len() == REPLY_FRAMES {
                replies.push((std::mem::take(&mut payload), reply_attachment(oldest, &stages)));
                stages.clear();
            }
        }
        if !stages.is_empty() || replies.is_empty() {
            replies.push((payload, reply_attachment(oldest, &stages)));
        }
        (replies, poses)
    }
}

/// What the bridge knows of one peer.
struct Peer {
    report: ReplayRequest,
    replayed: u64,
    seen: Instant,
}

/// Every peer's latest report, at most [`MAX_PEERS`].
#[derive(Default)]
pub(crate) struct Peers {
    peers: Mutex<HashMap<String, Peer>>,
    /// When a peer's loss was last logged.
    logged: Mutex<Option<Instant>>,
}

impl std::fmt::Debug for Peers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.reports()).finish()
    }
}

/// Least time between two logged peer losses.
const LOSS_LOG_EVERY: std::time::Duration = std::time::Duration::from_secs(10);

impl Peers {
    fn lock(&self) -> MutexGuard<'_, HashMap<String, Peer>> {
        self.peers.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Takes a peer's report; `replayed` poses were sent it for it. Returns how many more poses
    /// it says it missed than in its report before (to log).
    pub(crate) fn heard(&self, request: &ReplayRequest, replayed: u64) -> u64 {
        let mut peers = self.lock();
        if !peers.contains_key(&request.peer) && peers.len() >= MAX_PEERS {
            let stalest = peers.iter().min_by_key(|(_, p)| p.seen).map(|(k, _)| k.clone());
            if let Some(k) = stalest {
                peers.remove(&k);
            }
        }
        let peer = peers.entry(request.peer.clone()).or_insert_with(|| Peer {
            report: ReplayRequest { missing: 0, ..request.clone() },
            replayed: 0,
            seen: Instant::now(),
        });
        let more = request.missing.saturating_sub(peer.report.missing);
        peer.report = request.clone();
        peer.replayed += replayed;
        peer.seen = Instant::now();
        more
    }

    /// Whether a peer's loss may be logged now (at most once every 10 s).
    pub(crate) fn log_due(&self) -> bool {
        let mut logged = self.logged.lock().unwrap_or_else(PoisonError::into_inner);
        if logged.is_some_and(|t| t.elapsed() < LOSS_LOG_EVERY) {
            return false;
        }
        *logged = Some(Instant::now());
        true
    }

    /// Every peer's counts, by name.
    pub(crate) fn reports(&self) -> Vec<PeerReport> {
        let mut out: Vec<PeerReport> = self
            .lock()
            .values()
            .map(|p| PeerReport {
                peer: p.report.peer.clone(),
                frames: p.report.frames,
                missing: p.report.missing,
                recovered: p.report.recovered,
                replayed: p.replayed,
                seen_ms_ago: p.seen.elapsed().as_millis().try_into().unwrap_or(u64::MAX),
            })
            .collect();
        out.sort_by(|a, b| a.peer.cmp(&b.peer));
        out
    }
}

/// `peer frames/missing/recovered` for each peer, for the bridge's stats line.
pub(crate) fn summary(reports: &[PeerReport]) -> String {
    let parts: Vec<String> = reports
        .iter()
        .map(|p| format!("{}:{}/{}/{}", short_id(&p.peer), p.frames, p.missing, p.recovered))
        .collect();
    format!("[{}]", parts.join(" "))
}

fn short_id(id: &str) -> &str {
    id.get(..8).unwrap_or(id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_protocol::{ElementTable, Pose, ServerMessage};
    use frond_sdk::zenoh_replay::decode_reply;

    fn frame(msg: &ServerMessage) -> ZBytes {
        let mut out = Vec::new();
        frond_protocol::encode_frame(msg, &mut out);
        out.into()
    }

    fn pose(seq: u64) -> ZBytes {
        frame(&ServerMessage::Pose(Pose { seq, ..Pose::default() }))
    }

    fn answered(ring: &Ring, from: u64, to: u64) -> (Vec<Option<u64>>, u64, usize) {
        let (replies, poses) = ring.answer(from, to);
        let mut seqs = Vec::new();
        let mut oldest = 0;
        for (payload, attachment) in &replies {
            let chunk = decode_reply(payload, Some(attachment));
            oldest = chunk.oldest.unwrap();
            for (msg, _) in chunk.frames {
                seqs.push(match msg {
                    ServerMessage::Pose(p) => Some(p.seq),
                    _ => None,
                });
            }
        }
        assert_eq!(poses, seqs.iter().flatten().count() as u64);
        (seqs, oldest, replies.len())
    }

    #[test]
    fn the_ring_keeps_its_last_poses_with_the_tables_between_them() {
        let mut ring = Ring::new(100);
        for seq in 0..150 {
            if seq == 120 {
                ring.push_table(120, frame(&ServerMessage::Elements(ElementTable::default())));
            }
            ring.push_pose(seq, pose(seq), seq * 1000);
        }
        let (seqs, oldest, _) = answered(&ring, 118, 122);
        assert_eq!(seqs, [Some(118), Some(119), None, Some(120), Some(121)]);
        assert_eq!(oldest, 50);
        // Older than the ring: only what it still holds, and its oldest says the rest is gone.
        let (seqs, oldest, _) = answered(&ring, 10, 53);
        assert_eq!((seqs, oldest), (vec![Some(50), Some(51), Some(52)], 50));
        // Nothing matches: one empty reply.
        assert_eq!(answered(&ring, 500, 600), (vec![], 50, 1));
        // Chunks of REPLY_FRAMES, and at most MAX_REQUEST_POSES poses.
        let (seqs, _, replies) = answered(&ring, 50, 150);
        assert_eq!((seqs.len(), replies), (101, 101usize.div_ceil(REPLY_FRAMES)));
        // A new stream's numbers start again: the old one is forgotten.
        ring.push_pose(3, pose(3), 0);
        assert_eq!(answered(&ring, 0, 200).0, [Some(3)]);
        let mut off = Ring::new(0);
        off.push_pose(1, pose(1), 0);
        assert_eq!(answered(&off, 0, 10).0, []);
    }

    #[test]
    fn peers_are_counted_by_name_and_bounded() {
        let peers = Peers::default();
        let req = |peer: &str, missing| ReplayRequest {
            from: 0,
            to: 0,
            frames: 10,
            missing,
            recovered: 1,
            peer: peer.into(),
        };
        assert_eq!(peers.heard(&req("a", 3), 0), 3);
        assert_eq!(peers.heard(&req("a", 5), 4), 2);
        let r = peers.reports();
        assert_eq!((r.len(), r[0].missing, r[0].replayed), (1, 5, 4));
        for i in 0..MAX_PEERS + 5 {
            peers.heard(&req(&format!("p{i}"), 0), 0);
        }
        assert_eq!(peers.reports().len(), MAX_PEERS);
        assert!(peers.reports().iter().all(|p| p.peer != "a"), "the stalest peer made room");
        let one = PeerReport { peer: "0123456789".into(), frames: 10, recovered: 1, ..PeerReport::default() };
        assert_eq!(summary(&[one]), "[01234567:10/0/1]");
    }
}
