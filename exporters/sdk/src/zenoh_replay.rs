//! Recovery of lost poses from a bridge's replay ring, and the per-peer loss reports a bridge
//! keeps (issue 43).
//!
//! A `frond-zenoh` bridge publishes poses with congestion control *drop*, so a slow or far peer
//! never backs it up: a pose is lost for a peer whose link's queue is full. The bridge also
//! keeps the last poses it published (and the element tables between them) in a ring and answers
//! queries on `frond/<stage>/<source>/replay` from it. A subscriber that asks for reliable
//! delivery ([`crate::SubscriberOptions::reliable`], as a stage recorder does) fills every gap
//! it sees from that ring before it passes the pose after the gap on, so it gets every frame
//! while its link is up and it keeps within the ring (10 s at 1 kHz by default): nobody else
//! waits for it. What the ring no longer holds is a gap as before.
//!
//! Every SDK subscriber also tells the bridge, about once a second, how many frames it got and
//! missed and how many it recovered (a request with an empty range): the bridge's per-peer
//! counts (`frond-zenoh --stats`, the `.../peers` queryable, [`query_peers`]), which Zenoh does
//! not give the publisher.
//!
//! The wire, little-endian, so any Zenoh client can use it:
//!
//! - request (the query's payload): `from: u64`, `to: u64` (poses `from..to`; `to <= from`: a
//!   report only, nothing is answered), the asker's own counts `frames`, `missing` and
//!   `recovered` (`u64` each), then its name (UTF-8, at most [`MAX_PEER_NAME`] bytes: the
//!   subscriber's Zenoh id);
//! - replies, on the `replay` key: the payload is frames of the socket protocol back to back
//!   (poses and element tables in the order they were published), at most [`REPLY_FRAMES`]; the
//!   attachment is the oldest pose sequence number the ring holds (`u64`), then each frame's stage
//!   time (`u64`, 0 for an element table). A request the ring holds nothing of is answered by one
//!   reply of no frames, so the asker learns what is gone.

use std::time::{Duration, Instant};

use frond_protocol::field::FieldMessage;
use frond_protocol::{ElementTable, ServerMessage, decode_frame};

/// Longest peer name in a request, bytes.
pub const MAX_PEER_NAME: usize = 64;
/// Most frames in one reply.
pub const REPLY_FRAMES: usize = 64;
/// Most poses one request is answered with; a longer range is asked for again from where the
/// answer ended.
pub const MAX_REQUEST_POSES: u64 = 2048;
/// The replay key below a source's key.
pub const REPLAY: &str = "replay";
/// The per-peer report key below a source's key (a queryable answering JSON).
pub const PEERS: &str = "peers";

/// A request to the replay queryable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReplayRequest {
    /// First pose wanted.
    pub from: u64,
    /// One past the last pose wanted; `to <= from` is a report only.
    pub to: u64,
    /// The asker's own count of poses it passed on.
    pub frames: u64,
    /// Poses it never got (gaps it could not fill).
    pub missing: u64,
    /// Poses it got from the replay ring.
    pub recovered: u64,
    /// Who asks (the subscriber's Zenoh id).
    pub peer: String,
}

impl ReplayRequest {
    /// The request's bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(40 + self.peer.len());
        for v in [self.from, self.to, self.frames, self.missing, self.recovered] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let mut end = self.peer.len().min(MAX_PEER_NAME);
        while !self.peer.is_char_boundary(end) {
            end -= 1;
        }
        out.extend_from_slice(&self.peer.as_bytes()[..end]);
        out
    }

    /// Reads a request; `None` for anything that is not one (shorter than 40 bytes, a name that
    /// is too long or not UTF-8 or has control characters).
    pub fn decode(bytes: &[u8]) -> Option<ReplayRequest> {
        if bytes.len() < 40 || bytes.len() > 40 + MAX_PEER_NAME {
            return None;
        }
        let u = |i: usize| u64::from_le_bytes(bytes[i * 8..i * 8 + 8].try_into().expect("8 bytes"));
        let peer = std::str::from_utf8(&bytes[40..]).ok()?;
        if peer.chars().any(char::is_control) {
            return None;
        }
        Some(ReplayRequest {
            from: u(0),
            to: u(1),
            frames: u(2),
            missing: u(3),
            recovered: u(4),
            peer: peer.to_owned(),
        })
    }

    /// Whether only counts are reported, no pose asked for.
    pub fn report_only(&self) -> bool {
        self.to <= self.from
    }
}

/// The attachment of a reply: the ring's oldest pose, then each frame's stage time.
pub fn reply_attachment(oldest: u64, stage_ns: &[u64]) -> Vec<u8> {
    let mut out = Vec::with_capacity(8 + 8 * stage_ns.len());
    out.extend_from_slice(&oldest.to_le_bytes());
    for s in stage_ns {
        out.extend_from_slice(&s.to_le_bytes());
    }
    out
}

/// One reply read back: its frames with their stage times (`None` for an element table, or
/// when the attachment does not say), and the ring's oldest pose.
#[derive(Debug, Default)]
pub struct ReplyChunk {
    /// The frames in the order the bridge published them.
    pub frames: Vec<(ServerMessage, Option<u64>)>,
    /// The oldest pose the ring held when it answered.
    pub oldest: Option<u64>,
}

/// Reads one reply; frames that do not decode end it (the rest of the chunk is not trusted).
pub fn decode_reply(payload: &[u8], attachment: Option<&[u8]>) -> ReplyChunk {
    let word = |i: usize| -> Option<u64> {
        let a = attachment?;
        Some(u64::from_le_bytes(a.get(i * 8..i * 8 + 8)?.try_into().ok()?))
    };
    let mut chunk = ReplyChunk { frames: Vec::new(), oldest: word(0) };
    let mut at = 0;
    while at < payload.len() && chunk.frames.len() < REPLY_FRAMES {
        let Ok(Some((msg, used))) = decode_frame::<ServerMessage>(&payload[at..]) else { break };
        at += used;
        let stage = word(1 + chunk.frames.len()).filter(|s| *s != 0);
        chunk.frames.push((msg, stage));
    }
    chunk
}

/// The sequence numbers a message takes in the stream, `(first, count)`: one for a pose, a field
/// frame's own and its announced plants' ([`frond_protocol::field::FieldFrame::poses`], at
/// least one); `None` for anything else (tables, hellos).
pub(crate) fn numbered(msg: &ServerMessage) -> Option<(u64, u64)> {
    match msg {
        ServerMessage::Pose(p) => Some((p.seq, 1)),
        ServerMessage::Field(FieldMessage::Frame(f)) => Some((f.seq, u64::from(f.poses).max(1))),
        _ => None,
    }
}

/// How long a subscriber tries to fill one gap before it passes it on as a gap.
pub const RECOVERY_TIME: Duration = Duration::from_secs(1);
/// How long one replay query waits for its answers.
pub const QUERY_TIMEOUT: Duration = Duration::from_millis(300);

/// Fills `from..to` by asking `ask` (one replay query: the request, answered by its replies)
/// until every pose came back, the ring says they are gone, or `time` runs out (at least one
/// query is asked).
/// Returns the frames to pass on in order (poses and field frames of the range, element tables
/// published between them that differ from `table`, and field tables that differ from the one
/// before them), and how many sequence numbers of the range came back.
pub(crate) fn fill(
    from: u64,
    to: u64,
    table: Option<&ElementTable>,
    time: Duration,
    mut ask: impl FnMut(u64, u64) -> Option<Vec<ReplyChunk>>,
) -> (Vec<(ServerMessage, Option<u64>)>, u64) {
    let deadline = Instant::now() + time;
    let mut out = Vec::new();
    let mut last_table = table.cloned();
    let mut last_fields = None;
    let mut cursor = from;
    let mut got = 0;
    let mut first = true;
    while cursor < to && (first || Instant::now() < deadline) {
        first = false;
        let asked_to = to.min(cursor.saturating_add(MAX_REQUEST_POSES));
        let Some(chunks) = ask(cursor, asked_to) else {
            // Nothing in time (or the query could not be sent): ask again, without spinning.
            std::thread::sleep(Duration::from_millis(10));
            continue;
        };
        let before = cursor;
        let mut oldest = None;
        'chunks: for chunk in chunks {
            oldest = oldest.max(chunk.oldest);
            for (msg, stage) in chunk.frames {
                match (numbered(&msg), msg) {
                    (Some((seq, span)), msg) if seq == cursor && cursor < to => {
                        out.push((msg, stage));
                        cursor = cursor.saturating_add(span);
                        got += span;
                    }
                    (Some((seq, _)), _) if seq < cursor => {}
                    // A reply was dropped on the way (replies are dropped like poses when the
                    // link is full): ask again from the cursor.
                    (Some(_), _) => break 'chunks,
                    (None, ServerMessage::Elements(t)) if last_table.as_ref() != Some(&t) => {
                        last_table = Some(t.clone());
                        out.push((ServerMessage::Elements(t), None));
                    }
                    (None, ServerMessage::Field(FieldMessage::Table(t)))
                        if last_fields.as_ref() != Some(&t) =>
                    {
                        last_fields = Some(t.clone());
                        out.push((ServerMessage::Field(FieldMessage::Table(t)), None));
                    }
                    _ => {}
                }
            }
        }
        if cursor == before {
            match oldest {
                // The ring no longer holds the cursor's pose: those are lost; go on from its oldest.
                Some(oldest) if oldest > cursor => cursor = oldest.min(to),
                // The bridge answered but has none of them (it has not got them, or stands by).
                Some(_) => break,
                // No reply carried the ring's state: ask again.
                None => {}
            }
        }
    }
    (out, got)
}

/// One replay query: the request's answers, or `None` when nothing came back in time. Asked
/// with congestion *drop* (its replies travel the same way), at the data priority, below the
/// live poses'.
pub(crate) fn ask(session: &::zenoh::Session, key: &str, request: &ReplayRequest) -> Option<Vec<ReplyChunk>> {
    use ::zenoh::Wait;
    let replies = session
        .get(key)
        .payload(request.encode())
        .congestion_control(::zenoh::qos::CongestionControl::Drop)
        // Every chunk comes on the same key: Zenoh's default would keep only one of them.
        .consolidation(::zenoh::query::ConsolidationMode::None)
        .timeout(QUERY_TIMEOUT)
        .wait()
        .ok()?;
    let mut chunks = Vec::new();
    while let Ok(reply) = replies.recv() {
        if let Ok(sample) = reply.result() {
            let attachment = sample.attachment().map(|a| a.to_bytes());
            chunks.push(decode_reply(&sample.payload().to_bytes(), attachment.as_deref()));
        }
    }
    (!chunks.is_empty()).then_some(chunks)
}

/// How often a subscription reports its counts to its bridge.
pub const REPORT_EVERY: Duration = Duration::from_secs(1);

/// Sends a report-only request without waiting for anything; one that cannot be sent now is
/// sent again at the next report.
pub(crate) fn report(session: &::zenoh::Session, key: &str, request: &ReplayRequest) {
    use ::zenoh::Wait;
    let _ = session
        .get(key)
        .payload(request.encode())
        .congestion_control(::zenoh::qos::CongestionControl::Drop)
        .timeout(REPORT_EVERY)
        .callback(|_| {})
        .wait();
}

/// One peer's counts as a bridge keeps them (the `.../peers` queryable's JSON, one object a
/// peer).
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct PeerReport {
    /// The peer's name (its Zenoh id).
    pub peer: String,
    /// Poses it passed on, by its own count.
    pub frames: u64,
    /// Poses it never got.
    pub missing: u64,
    /// Poses it recovered from the ring.
    pub recovered: u64,
    /// Poses the bridge sent it from the ring.
    pub replayed: u64,
    /// Since the peer last reported, milliseconds.
    pub seen_ms_ago: u64,
}

/// Asks the bridge of `key` (one concrete source key) for its peers' reports.
pub fn query_peers(
    session: &::zenoh::Session,
    key: &str,
    timeout: Duration,
) -> Result<Vec<PeerReport>, crate::SdkError> {
    use ::zenoh::Wait;
    let zerr = |reason: String| crate::SdkError::Zenoh { source_key: key.to_owned(), reason };
    let replies = session
        .get(crate::zenoh_keys::keys::under(key, PEERS))
        .timeout(timeout)
        .wait()
        .map_err(|e| zerr(e.to_string()))?;
    let mut out = Vec::new();
    while let Ok(reply) = replies.recv() {
        let Ok(sample) = reply.result() else { continue };
        let peers: Vec<PeerReport> =
            serde_json::from_slice(&sample.payload().to_bytes()).map_err(|e| zerr(e.to_string()))?;
        out.extend(peers);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_protocol::Pose;
    use frond_protocol::field::{FieldFrame, FieldTable};

    fn pose(seq: u64) -> ServerMessage {
        ServerMessage::Pose(Pose { seq, ..Pose::default() })
    }

    fn chunk(seqs: std::ops::Range<u64>, oldest: u64) -> ReplyChunk {
        ReplyChunk { frames: seqs.map(|s| (pose(s), Some(s * 10))).collect(), oldest: Some(oldest) }
    }

    fn seqs(out: &[(ServerMessage, Option<u64>)]) -> Vec<u64> {
        out.iter()
            .filter_map(|(m, _)| match m {
                ServerMessage::Pose(p) => Some(p.seq),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn requests_and_replies_read_back() {
        let req =
            ReplayRequest { from: 5, to: 9, frames: 100, missing: 2, recovered: 7, peer: "a1b2".into() };
        assert_eq!(ReplayRequest::decode(&req.encode()), Some(req.clone()));
        assert!(!req.report_only());
        assert!(ReplayRequest { to: 5, ..req.clone() }.report_only());
        assert_eq!(ReplayRequest::decode(&[0; 39]), None);
        assert_eq!(ReplayRequest::decode(&[0; 40 + MAX_PEER_NAME + 1]), None);
        let mut bad = req.encode();
        bad.push(b'\n');
        assert_eq!(ReplayRequest::decode(&bad), None);
        let long = ReplayRequest { peer: "é".repeat(40), ..req };
        assert_eq!(ReplayRequest::decode(&long.encode()).unwrap().peer.len(), 64);

        let mut payload = Vec::new();
        frond_protocol::encode_frame(&pose(3), &mut payload);
        frond_protocol::encode_frame(&ServerMessage::Elements(ElementTable::default()), &mut payload);
        frond_protocol::encode_frame(&pose(4), &mut payload);
        let read = decode_reply(&payload, Some(&reply_attachment(2, &[30, 0, 40])));
        assert_eq!(read.oldest, Some(2));
        assert_eq!(read.frames.iter().map(|f| f.1).collect::<Vec<_>>(), [Some(30), None, Some(40)]);
        assert_eq!(seqs(&read.frames), [3, 4]);
        // A torn frame ends the chunk; a short attachment loses only stage times.
        let torn = decode_reply(&payload[..payload.len() - 1], Some(&2u64.to_le_bytes()));
        assert_eq!((seqs(&torn.frames), torn.frames[0].1), (vec![3], None));
    }

    #[test]
    fn fill_asks_again_after_a_dropped_reply_and_skips_what_is_gone() {
        // First answer: 10..13 then a jump (a chunk lost), second: the rest.
        let mut asked = Vec::new();
        let (out, got) = fill(10, 20, None, RECOVERY_TIME, |from, to| {
            asked.push((from, to));
            Some(match asked.len() {
                1 => vec![chunk(10..13, 0), chunk(15..20, 0)],
                _ => vec![chunk(from..to, 0)],
            })
        });
        assert_eq!(asked, [(10, 20), (13, 20)]);
        assert_eq!((seqs(&out), got), ((10..20).collect(), 10));

        // The ring's oldest is 15: 10..15 are gone, 15..20 come back.
        let (out, got) =
            fill(10, 20, None, RECOVERY_TIME, |from, to| Some(vec![chunk(from.max(15)..to, 15)]));
        assert_eq!((seqs(&out), got), ((15..20).collect(), 5));

        // The bridge has none of them and holds older ones: it never got them; stop.
        let mut calls = 0;
        let (out, _) = fill(10, 20, None, RECOVERY_TIME, |_, _| {
            calls += 1;
            Some(vec![chunk(0..0, 3)])
        });
        assert_eq!((out.len(), calls), (0, 1));

        // Nobody answers: asked again until the time is up, then nothing.
        let t = Instant::now();
        let (out, _) = fill(10, 20, None, RECOVERY_TIME, |_, _| {
            std::thread::sleep(Duration::from_millis(50));
            None
        });
        assert!(out.is_empty() && t.elapsed() >= RECOVERY_TIME);
    }

    #[test]
    fn fill_counts_a_field_frame_with_its_announced_plants_numbers() {
        // Pose 10, a field frame 11 whose 3 announced plants take 11..14, a field table, pose 14.
        let frame = |seq, poses| {
            ServerMessage::Field(FieldMessage::Frame(FieldFrame { seq, poses, ..Default::default() }))
        };
        let table = FieldTable { elements_version: 4, fields: vec![] };
        let published = vec![
            (pose(10), None),
            (frame(11, 3), None),
            (ServerMessage::Field(FieldMessage::Table(table.clone())), None),
            (pose(14), None),
            (frame(15, 0), None),
        ];
        let mut asked = Vec::new();
        let (out, got) = fill(10, 16, None, RECOVERY_TIME, |from, to| {
            asked.push((from, to));
            Some(vec![ReplyChunk { frames: published.clone(), oldest: Some(0) }])
        });
        assert_eq!(asked, [(10, 16)], "one answer fills the range");
        assert_eq!(got, 6);
        assert_eq!(
            out.iter().map(|(m, _)| numbered(m)).collect::<Vec<_>>(),
            [Some((10, 1)), Some((11, 3)), None, Some((14, 1)), Some((15, 1))]
        );
        assert!(matches!(&out[2].0, ServerMessage::Field(FieldMessage::Table(t)) if *t == table));
    }

    #[test]
    fn fill_passes_on_only_tables_that_changed() {
        let old = ElementTable::default();
        let new = ElementTable { version: 2, ..ElementTable::default() };
        let (out, _) = fill(1, 3, Some(&old), RECOVERY_TIME, |_, _| {
            Some(vec![ReplyChunk {
                frames: vec![
                    (ServerMessage::Elements(old.clone()), None),
                    (pose(1), None),
                    (ServerMessage::Elements(new.clone()), None),
                    (pose(2), None),
                ],
                oldest: Some(0),
            }])
        });
        assert!(matches!(
            &out[..],
            [(ServerMessage::Pose(_), _), (ServerMessage::Elements(t), _), (ServerMessage::Pose(_), _)]
                if *t == new
        ));
    }
}
