//! The take file codec (pure: bytes in, bytes out).
//!
//! A take is append-only, length-prefixed and checksummed, so it can be read while it is being
//! written and a crash leaves at most a torn tail:
//!
//! ```text
//! file   = b"FRONDTK1" record*
//! record = len: u32 LE | crc: u32 LE | kind: u8 | payload      (len = 1 + payload length,
//!                                                                crc = CRC-32 of kind + payload)
//! kind 1 Header  payload = JSON TakeHeader (first record only)
//! kind 2 Frame   payload = 118 bytes, little-endian, see `FRAME_PAYLOAD_LEN`
//! kind 3 Marker  payload = seq: u64 | label: UTF-8 bytes
//! kind 4 End     payload = frames: u64 (last record; equals the number of Frame records)
//! ```
//!
//! Frame payload layout: `seq u64, device_time_us u64, host_ns u64, flags u32, element u16,
//! pose.t f64, pose.joints_deg 12 x f32, hand.t f64, hand.wrist_deg 3 x f32,
//! hand.thumb_deg 3 x f32`.
//!
//! Reading ([`scan_take`]): a record that is incomplete, or damaged with nothing valid after it,
//! ends the scan as a torn tail (a crash mid-write, or a writer still appending): not an error,
//! reported in `torn_bytes`. A damaged record followed by valid data (a flipped bit, a torn write
//! in the middle) is skipped: the reader resynchronises at the next offset where a record's length
//! and checksum agree, and lists what it skipped in [`TakeScan::skipped`], so every record before
//! and after the damage is still read. Errors, naming the byte offset, are a bad magic, a
//! checksummed record of an unknown kind or with a malformed payload, records that break the
//! file's structure, and a frame holding a non-finite number (NaN or infinite), named by frame
//! ([`scan_take_salvaging`] skips those frames instead, for repair).
//!
//! The take as data ([`TakeHeader`], [`TakeFrame`], [`TakeScan`]) and its resampling are
//! `frond_motion::take`; this module is its bytes.

use frond_motion::sample::{HandSample, JOINTS, PoseFrame};
use frond_motion::take::{Skipped, TakeFrame, TakeHeader, TakeScan};
use thiserror::Error;

/// The 8 bytes every take starts with.
pub const MAGIC: &[u8; 8] = b"FRONDTK1";
/// Bytes before a record's kind byte: `len` and `crc`.
pub const RECORD_HEAD_LEN: usize = 8;
/// Largest accepted `len` (kind + payload); longer claims are treated as damage.
pub const MAX_RECORD_LEN: u32 = 1 << 20;
/// Size of a Frame payload.
pub const FRAME_PAYLOAD_LEN: usize = 8 + 8 + 8 + 4 + 2 + 8 + 4 * 3 * JOINTS + 8 + 4 * 3 + 4 * 3;

const KIND_HEADER: u8 = 1;
const KIND_FRAME: u8 = 2;
const KIND_MARKER: u8 = 3;
const KIND_END: u8 = 4;

/// One record of a take file.
#[derive(Debug, Clone, PartialEq)]
pub enum TakeRecord {
    /// Metadata; the first record.
    Header(TakeHeader),
    /// A frame.
    Frame(TakeFrame),
    /// A user marker at pose `seq`.
    Marker {
        /// Sequence number it refers to.
        seq: u64,
        /// Label text.
        label: String,
    },
    /// Clean end of the take with the number of frames written.
    End {
        /// Frames in the take.
        frames: u64,
    },
}

/// What went wrong reading a take. Offsets are byte offsets from the start of the file.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum TakeError {
    /// The file does not start with `FRONDTK1`.
    #[error("not a frond take: bad magic at offset 0 (found {found:02x?})")]
    BadMagic {
        /// The first bytes found.
        found: Vec<u8>,
    },
    /// A damaged record (bad length or checksum) with valid records after it.
    #[error("corrupt record at offset {offset}: {reason}; valid data resumes at offset {resumes_at}")]
    Corrupt {
        /// Where the damaged record starts.
        offset: u64,
        /// What is wrong with it.
        reason: String,
        /// Where the next valid-looking record starts.
        resumes_at: u64,
    },
    /// A checksummed record of a kind this version does not know.
    #[error("unknown record kind {kind} at offset {offset}")]
    UnknownKind {
        /// Record offset.
        offset: u64,
        /// The kind byte.
        kind: u8,
    },
    /// A checksummed record whose payload is malformed.
    #[error("bad {kind} record at offset {offset}: {reason}")]
    BadRecord {
        /// Record offset.
        offset: u64,
        /// Record kind name.
        kind: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A checksummed frame holding NaN or an infinite value.
    #[error(
        "frame {frame} (seq {seq}, record at offset {offset}) holds a non-finite value ({value}) in \
         {field}; `frond take repair` drops such frames"
    )]
    NonFinite {
        /// Index of the frame among the take's frames, from 0.
        frame: u64,
        /// Its sequence number.
        seq: u64,
        /// Record offset.
        offset: u64,
        /// Which value (`pose.t`, `pose joint 2`, `hand.wrist_deg`, ...).
        field: &'static str,
        /// The value, as text (`NaN`, `inf`, `-inf`).
        value: String,
    },
    /// A record in a place the format does not allow it.
    #[error("misplaced record at offset {offset}: {reason}")]
    Structure {
        /// Record offset.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
}

/// Writes the file magic.
pub fn encode_file_start(out: &mut Vec<u8>) {
    out.extend_from_slice(MAGIC);
}

fn put_f32s(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// Appends one record. Frame, Marker and End records never allocate when `out` has room;
/// the Header is JSON.
pub fn encode_record(record: &TakeRecord, out: &mut Vec<u8>) {
    let start = out.len();
    out.extend_from_slice(&[0; RECORD_HEAD_LEN]);
    match record {
        TakeRecord::Header(h) => {
            out.push(KIND_HEADER);
            // A struct of strings and integers always serializes.
            let _ = serde_json::to_writer(&mut *out, h);
        }
        TakeRecord::Frame(f) => {
            out.push(KIND_FRAME);
            out.extend_from_slice(&f.seq.to_le_bytes());
            out.extend_from_slice(&f.device_time_us.to_le_bytes());
            out.extend_from_slice(&f.host_ns.to_le_bytes());
            out.extend_from_slice(&f.flags.to_le_bytes());
            out.extend_from_slice(&f.element.get().to_le_bytes());
            out.extend_from_slice(&f.pose.t.to_le_bytes());
            for j in &f.pose.joints_deg {
                put_f32s(out, j);
            }
            out.extend_from_slice(&f.hand.t.to_le_bytes());
            put_f32s(out, &f.hand.wrist_deg);
            put_f32s(out, &f.hand.thumb_deg);
        }
        TakeRecord::Marker { seq, label } => {
            out.push(KIND_MARKER);
            out.extend_from_slice(&seq.to_le_bytes());
            // Labels longer than a record can hold are cut at a character boundary.
            let max = MAX_RECORD_LEN as usize - 1 - 8;
            let mut end = label.len().min(max);
            while !label.is_char_boundary(end) {
                end -= 1;
            }
            out.extend_from_slice(&label.as_bytes()[..end]);
        }
        TakeRecord::End { frames } => {
            out.push(KIND_END);
            out.extend_from_slice(&frames.to_le_bytes());
        }
    }
    let body = &out[start + RECORD_HEAD_LEN..];
    let len = body.len() as u32;
    let crc = crc32fast::hash(body);
    out[start..start + 4].copy_from_slice(&len.to_le_bytes());
    out[start + 4..start + 8].copy_from_slice(&crc.to_le_bytes());
}

/// The result of reading one record at an offset.
#[derive(Debug, Clone, PartialEq)]
// A take holds one header record; boxing it would cost every reader an indirection for nothing.
#[allow(clippy::large_enum_variant)]
pub enum RecordAt {
    /// A complete, checksummed record and the offset after it.
    Record {
        /// The record.
        record: TakeRecord,
        /// Offset of the next record.
        next: usize,
    },
    /// The bytes at the offset are not (yet) a whole valid record: incomplete, or damaged.
    Invalid {
        /// Why (for error messages).
        reason: String,
    },
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut a = [0; N];
        a.copy_from_slice(&self.b[self.at..self.at + N]);
        self.at += N;
        a
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
    fn f32x3(&mut self) -> [f32; 3] {
        [0; 3].map(|_| f32::from_le_bytes(self.take()))
    }
}

fn decode_frame(p: &[u8]) -> TakeFrame {
    let mut r = Reader { b: p, at: 0 };
    let seq = r.u64();
    let device_time_us = r.u64();
    let host_ns = r.u64();
    let flags = r.u32();
    let element = r.u16();
    let pose_t = r.f64();
    let joints_deg = [0; JOINTS].map(|_| r.f32x3());
    let hand_t = r.f64();
    let wrist_deg = r.f32x3();
    let thumb_deg = r.f32x3();
    TakeFrame {
        seq,
        device_time_us,
        host_ns,
        flags,
        element: element.into(),
        pose: PoseFrame { t: pose_t, joints_deg },
        hand: HandSample { t: hand_t, wrist_deg, thumb_deg },
    }
}

fn known_kind(kind: u8) -> bool {
    (KIND_HEADER..=KIND_END).contains(&kind)
}

/// Reads the record at `offset` of a whole file `bytes`. A complete record with a good checksum
/// but an unknown kind or a malformed payload is an error; anything incomplete or damaged is
/// [`RecordAt::Invalid`] (the caller decides whether that is a torn tail).
pub fn read_record_at(bytes: &[u8], offset: usize) -> Result<RecordAt, TakeError> {
    let invalid = |reason: String| Ok(RecordAt::Invalid { reason });
    let rest = bytes.get(offset..).unwrap_or(&[]);
    if rest.len() < RECORD_HEAD_LEN {
        return invalid(format!("incomplete record head ({} of 8 bytes)", rest.len()));
    }
    let len = u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]);
    let crc = u32::from_le_bytes([rest[4], rest[5], rest[6], rest[7]]);
    if len == 0 || len > MAX_RECORD_LEN {
        return invalid(format!("implausible record length {len}"));
    }
    let body_end = RECORD_HEAD_LEN + len as usize;
    if rest.len() < body_end {
        return invalid(format!("incomplete record ({} of {} bytes)", rest.len(), body_end));
    }
    let body = &rest[RECORD_HEAD_LEN..body_end];
    if crc32fast::hash(body) != crc {
        return invalid("checksum mismatch".to_string());
    }
    let off = offset as u64;
    let (kind, payload) = (body[0], &body[1..]);
    let bad = |kind: &'static str, reason: String| TakeError::BadRecord { offset: off, kind, reason };
    let record = match kind {
        KIND_HEADER => {
            TakeRecord::Header(serde_json::from_slice(payload).map_err(|e| bad("header", e.to_string()))?)
        }
        KIND_FRAME => {
            if payload.len() != FRAME_PAYLOAD_LEN {
                return Err(bad(
                    "frame",
                    format!("payload is {} bytes, expected {FRAME_PAYLOAD_LEN}", payload.len()),
                ));
            }
            TakeRecord::Frame(decode_frame(payload))
        }
        KIND_MARKER => {
            if payload.len() < 8 {
                return Err(bad(
                    "marker",
                    format!("payload is {} bytes, expected at least 8", payload.len()),
                ));
            }
            let mut r = Reader { b: payload, at: 0 };
            let seq = r.u64();
            let label = std::str::from_utf8(&payload[8..])
                .map_err(|e| bad("marker", format!("label is not UTF-8: {e}")))?
                .to_string();
            TakeRecord::Marker { seq, label }
        }
        KIND_END => {
            if payload.len() != 8 {
                return Err(bad("end", format!("payload is {} bytes, expected 8", payload.len())));
            }
            TakeRecord::End { frames: Reader { b: payload, at: 0 }.u64() }
        }
        kind => return Err(TakeError::UnknownKind { offset: off, kind }),
    };
    Ok(RecordAt::Record { record, next: offset + body_end })
}

/// Whether a complete record with a good checksum and a known kind starts at `offset`.
fn looks_valid(bytes: &[u8], offset: usize) -> bool {
    let Some(rest) = bytes.get(offset..) else {
        return false;
    };
    if rest.len() < RECORD_HEAD_LEN + 1 {
        return false;
    }
    let len = u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]);
    let body_end = RECORD_HEAD_LEN + len as usize;
    if len == 0 || len > MAX_RECORD_LEN || rest.len() < body_end || !known_kind(rest[8]) {
        return false;
    }
    let crc = u32::from_le_bytes([rest[4], rest[5], rest[6], rest[7]]);
    crc32fast::hash(&rest[RECORD_HEAD_LEN..body_end]) == crc
}

/// Reads a whole take (or the part written so far), skipping damaged records (listed in
/// [`TakeScan::skipped`]). See the module docs for what is an error and what is a torn tail.
pub fn scan_take(bytes: &[u8]) -> Result<TakeScan, TakeError> {
    scan(bytes, false)
}

/// Like [`scan_take`], but a frame holding a non-finite value is skipped (listed in
/// [`TakeScan::skipped`] with `frames: 1`) instead of refused: what `take repair` keeps.
pub fn scan_take_salvaging(bytes: &[u8]) -> Result<TakeScan, TakeError> {
    scan(bytes, true)
}

/// The first non-finite value of a frame: which one, and its text.
fn non_finite(f: &TakeFrame) -> Option<(&'static str, String)> {
    const JOINT: [&str; JOINTS] = ["pose joint 0", "pose joint 1", "pose joint 2", "pose joint 3"];
    let bad = |x: f64| (!x.is_finite()).then(|| x.to_string());
    if let Some(v) = bad(f.pose.t) {
        return Some(("pose.t", v));
    }
    for (name, j) in JOINT.iter().zip(&f.pose.joints_deg) {
        if let Some(v) = j.iter().find_map(|&x| bad(x as f64)) {
            return Some((name, v));
        }
    }
    if let Some(v) = bad(f.hand.t) {
        return Some(("hand.t", v));
    }
    if let Some(v) = f.hand.wrist_deg.iter().find_map(|&x| bad(x as f64)) {
        return Some(("hand.wrist_deg", v));
    }
    f.hand.thumb_deg.iter().find_map(|&x| bad(x as f64)).map(|v| ("hand.thumb_deg", v))
}

fn scan(bytes: &[u8], skip_non_finite: bool) -> Result<TakeScan, TakeError> {
    let mut scan = TakeScan::default();
    let head = &bytes[..bytes.len().min(MAGIC.len())];
    if head != &MAGIC[..head.len()] {
        return Err(TakeError::BadMagic { found: head.to_vec() });
    }
    if bytes.len() < MAGIC.len() {
        scan.torn_bytes = bytes.len() as u64;
        return Ok(scan);
    }
    let mut at = MAGIC.len();
    let mut end_at: Option<usize> = None;
    // Frame records read, skipped non-finite ones included (the index errors name).
    let mut frame_index = 0u64;
    while at < bytes.len() {
        let (record, next) = match read_record_at(bytes, at)? {
            RecordAt::Record { record, next } => (record, next),
            RecordAt::Invalid { reason } => {
                // Resynchronise: the next offset where a whole record's length and checksum
                // agree. Nothing valid after it: a torn tail.
                let Some(p) = (at + 1..bytes.len()).find(|&p| looks_valid(bytes, p)) else {
                    break;
                };
                scan.skipped.push(Skipped { offset: at as u64, len: (p - at) as u64, reason, frames: 0 });
                at = p;
                continue;
            }
        };
        let structure = |reason: String| TakeError::Structure { offset: at as u64, reason };
        if let Some(e) = end_at {
            return Err(structure(format!("record after the End record at offset {e}")));
        }
        match record {
            TakeRecord::Header(h) => {
                // The first record read (damage may have come before it).
                if scan.header.is_some() || frame_index > 0 || !scan.markers.is_empty() {
                    return Err(structure("a Header may only be the first record".to_string()));
                }
                scan.header = Some(h);
            }
            TakeRecord::Frame(f) => {
                let index = frame_index;
                frame_index += 1;
                if let Some((field, value)) = non_finite(&f) {
                    if !skip_non_finite {
                        return Err(TakeError::NonFinite {
                            frame: index,
                            seq: f.seq,
                            offset: at as u64,
                            field,
                            value,
                        });
                    }
                    scan.skipped.push(Skipped {
                        offset: at as u64,
                        len: (next - at) as u64,
                        reason: format!("frame {index} (seq {}) holds {value} in {field}", f.seq),
                        frames: 1,
                    });
                } else {
                    scan.frames.push(f);
                }
            }
            TakeRecord::Marker { seq, label } => scan.markers.push((seq, label)),
            TakeRecord::End { frames } => {
                // Frames in skipped stretches were counted by the writer but not read here.
                let read = scan.frames.len() as u64;
                let fits = if scan.skipped.is_empty() {
                    frames == read
                } else {
                    frames >= read + scan.lost_frames()
                };
                if !fits {
                    return Err(structure(format!("End record says {frames} frames, the take has {read}")));
                }
                scan.ended = true;
                scan.end_frames = Some(frames);
                end_at = Some(at);
            }
        }
        at = next;
    }
    scan.valid_len = at as u64;
    scan.torn_bytes = (bytes.len() - at) as u64;
    Ok(scan)
}

#[cfg(test)]
mod tests {
    use frond_protocol::ElementId;

    use super::*;

    #[test]
    fn frame_payload_len_is_118() {
        assert_eq!(FRAME_PAYLOAD_LEN, 118);
        let mut out = Vec::new();
        encode_record(&TakeRecord::Frame(TakeFrame::default()), &mut out);
        assert_eq!(out.len(), RECORD_HEAD_LEN + 1 + 118);
    }

    #[test]
    fn record_layout_by_hand() {
        let mut out = Vec::new();
        encode_record(&TakeRecord::End { frames: 3 }, &mut out);
        // len = 9 (kind + u64), crc over [4, 3, 0, 0, 0, 0, 0, 0, 0].
        let body = [4u8, 3, 0, 0, 0, 0, 0, 0, 0];
        let mut want = vec![9, 0, 0, 0];
        want.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
        want.extend_from_slice(&body);
        assert_eq!(out, want);
    }

    #[test]
    fn frame_round_trip_bits() {
        let f = TakeFrame {
            seq: u64::MAX - 1,
            device_time_us: 123_456_789,
            host_ns: 987_654_321_012,
            flags: 0b101,
            element: ElementId::new(2),
            pose: PoseFrame {
                t: 1.5,
                joints_deg: [[1.0, -2.0, 3.5], [f32::MAX, -0.0, 1e-40], [7.0; 3], [-8.25; 3]],
            },
            hand: HandSample { t: 1.5, wrist_deg: [0.1, 0.2, 0.3], thumb_deg: [-1.0, f32::MIN, 2.0] },
        };
        let mut out = Vec::new();
        encode_record(&TakeRecord::Frame(f), &mut out);
        let RecordAt::Record { record, next } = read_record_at(&out, 0).unwrap() else {
            panic!("expected a record");
        };
        assert_eq!(next, out.len());
        assert_eq!(record, TakeRecord::Frame(f));
    }

    #[test]
    fn long_marker_labels_are_cut_on_a_char_boundary() {
        let label = "é".repeat(MAX_RECORD_LEN as usize); // 2 bytes each
        let mut out = Vec::new();
        encode_record(&TakeRecord::Marker { seq: 1, label: label.clone() }, &mut out);
        let RecordAt::Record { record: TakeRecord::Marker { label: got, .. }, .. } =
            read_record_at(&out, 0).unwrap()
        else {
            panic!("expected a marker");
        };
        assert!(label.starts_with(&got));
        assert!(got.len() <= MAX_RECORD_LEN as usize - 9);
    }
}
