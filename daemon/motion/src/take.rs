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
//! reported in `torn_bytes`. A damaged record followed by valid-looking data means the middle of
//! the file is corrupt, and that is an error naming the byte offset, as are a bad magic, an
//! unknown record kind and records that break the file's structure.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::sample::{HandSample, JOINTS, PoseFrame};

/// The 8 bytes every take starts with.
pub const MAGIC: &[u8; 8] = b"FRONDTK1";
/// Bytes before a record's kind byte: `len` and `crc`.
pub const RECORD_HEAD_LEN: usize = 8;
/// Largest accepted `len` (kind + payload); longer claims are treated as damage.
pub const MAX_RECORD_LEN: u32 = 1 << 20;
/// Size of a Frame payload.
pub const FRAME_PAYLOAD_LEN: usize = 8 + 8 + 8 + 4 + 2 + 8 + 4 * 3 * JOINTS + 8 + 4 * 3 + 4 * 3;
/// Upper bound on the number of frames [`resample`] produces (about 6 days at 30 FPS).
pub const MAX_RESAMPLED_FRAMES: usize = 1 << 24;

const KIND_HEADER: u8 = 1;
const KIND_FRAME: u8 = 2;
const KIND_MARKER: u8 = 3;
const KIND_END: u8 = 4;

/// Take metadata, the first record (JSON, so it can grow; unknown fields are ignored).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TakeHeader {
    /// Take name (file stem).
    pub name: String,
    /// Rig the take was recorded with.
    pub rig_name: String,
    /// Calibration id (`none` for the neutral default).
    pub calibration_id: String,
    /// Filter spec text (`FilterSpec` display form).
    pub filter: String,
    /// Daemon tick rate, Hz.
    pub tick_rate_hz: u32,
    /// Creation time, Unix seconds.
    pub created_unix_s: u64,
    /// `frondd` version.
    pub daemon_version: String,
    /// Rig joint names, root first.
    pub joint_names: Vec<String>,
}

/// One recorded tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TakeFrame {
    /// Published sequence number.
    pub seq: u64,
    /// Device timestamp, microseconds.
    pub device_time_us: u64,
    /// Host CLOCK_MONOTONIC, nanoseconds.
    pub host_ns: u64,
    /// Protocol pose flags (`held`, `device_lost`, `filtered`, ...).
    pub flags: u32,
    /// 0 for the main skeleton, `k + 1` for secondary element `k` of the rig.
    pub element: u16,
    /// The mapped pose.
    pub pose: PoseFrame,
    /// The calibrated and filtered hand sample it came from.
    pub hand: HandSample,
}

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
            out.extend_from_slice(&f.element.to_le_bytes());
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
        element,
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

/// Everything read from a take.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TakeScan {
    /// The header, if the file got that far.
    pub header: Option<TakeHeader>,
    /// All frames, in file order.
    pub frames: Vec<TakeFrame>,
    /// Markers as `(seq, label)`, in file order.
    pub markers: Vec<(u64, String)>,
    /// True when the End record was read (the take was closed cleanly).
    pub ended: bool,
    /// Bytes up to the end of the last good record (0 if even the magic is incomplete).
    pub valid_len: u64,
    /// Bytes after `valid_len` that do not form a whole record (torn or still being written).
    pub torn_bytes: u64,
}

impl TakeScan {
    /// The poses of the main skeleton (element 0), in order.
    pub fn poses(&self) -> Vec<PoseFrame> {
        self.frames.iter().filter(|f| f.element == 0).map(|f| f.pose).collect()
    }
}

/// Reads a whole take (or the part written so far). See the module docs for what is an error
/// and what is a torn tail.
pub fn scan_take(bytes: &[u8]) -> Result<TakeScan, TakeError> {
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
    while at < bytes.len() {
        let (record, next) = match read_record_at(bytes, at)? {
            RecordAt::Record { record, next } => (record, next),
            RecordAt::Invalid { reason } => {
                if let Some(p) = (at + 1..bytes.len()).find(|&p| looks_valid(bytes, p)) {
                    return Err(TakeError::Corrupt { offset: at as u64, reason, resumes_at: p as u64 });
                }
                break;
            }
        };
        let structure = |reason: String| TakeError::Structure { offset: at as u64, reason };
        if let Some(e) = end_at {
            return Err(structure(format!("record after the End record at offset {e}")));
        }
        match record {
            TakeRecord::Header(h) => {
                if at != MAGIC.len() {
                    return Err(structure("a Header may only be the first record".to_string()));
                }
                scan.header = Some(h);
            }
            TakeRecord::Frame(f) => scan.frames.push(f),
            TakeRecord::Marker { seq, label } => scan.markers.push((seq, label)),
            TakeRecord::End { frames } => {
                if frames != scan.frames.len() as u64 {
                    return Err(structure(format!(
                        "End record says {frames} frames, the take has {}",
                        scan.frames.len()
                    )));
                }
                scan.ended = true;
                end_at = Some(at);
            }
        }
        at = next;
    }
    scan.valid_len = at as u64;
    scan.torn_bytes = (bytes.len() - at) as u64;
    Ok(scan)
}

/// Resamples poses at a fixed rate by linear interpolation of every angle.
///
/// Output frame `k` has `t = k / fps`, relative to the first input frame, for every
/// `k / fps <= duration` up to a twentieth of a frame (the one rule of
/// [`crate::clip::frame_count`]), so the take's whole duration is covered, the output starts at
/// 0, and `n` frames at `fps` with rounded time stamps resample to `n` frames.
/// Input times must be non-decreasing (as recorded); a frame whose time is not after the
/// previous one is skipped. Empty input gives empty output; one frame gives one frame at `t = 0`;
/// a non-positive or non-finite `fps` gives empty output. At most [`MAX_RESAMPLED_FRAMES`].
pub fn resample(frames: &[PoseFrame], fps: f64) -> Vec<PoseFrame> {
    let Some(first) = frames.first() else {
        return Vec::new();
    };
    if !(fps.is_finite() && fps > 0.0) {
        return Vec::new();
    }
    let t0 = first.t;
    let duration = frames.last().map_or(0.0, |l| l.t - t0);
    let count = crate::clip::frame_count(duration, fps);
    let mut out = Vec::with_capacity(count);
    let mut j = 0; // frames[j] is the last frame at or before the target time
    for k in 0..count {
        let t = k as f64 / fps;
        while j + 1 < frames.len() && frames[j + 1].t - t0 <= t {
            j += 1;
        }
        let a = &frames[j];
        let mut joints_deg = a.joints_deg;
        if let Some(b) = frames[j + 1..].iter().find(|b| b.t > a.t) {
            let u = ((t - (a.t - t0)) / (b.t - a.t)).clamp(0.0, 1.0);
            for (o, (pa, pb)) in joints_deg.iter_mut().zip(a.joints_deg.iter().zip(&b.joints_deg)) {
                for c in 0..3 {
                    let (x, y) = (pa[c] as f64, pb[c] as f64);
                    o[c] = (x + u * (y - x)) as f32;
                }
            }
        }
        out.push(PoseFrame { t, joints_deg });
    }
    out
}

#[cfg(test)]
mod tests {
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
            element: 2,
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

    fn pose(t: f64, v: f32) -> PoseFrame {
        PoseFrame { t, joints_deg: [[v, -v, 2.0 * v]; JOINTS] }
    }

    #[test]
    fn resample_by_hand() {
        // Frames at t = 10.0, 10.1, 10.2 with value 0, 1, 4. At 20 FPS: targets 0, 0.05, 0.1,
        // 0.15, 0.2 -> values 0, 0.5, 1, 2.5, 4.
        let frames = [pose(10.0, 0.0), pose(10.1, 1.0), pose(10.2, 4.0)];
        let out = resample(&frames, 20.0);
        let got: Vec<(f64, f32)> = out.iter().map(|p| (p.t, p.joints_deg[1][0])).collect();
        let want = [(0.0, 0.0), (0.05, 0.5), (0.1, 1.0), (0.15, 2.5), (0.2, 4.0)];
        assert_eq!(got.len(), want.len(), "{got:?}");
        for ((t, v), (wt, wv)) in got.iter().zip(want) {
            assert!((t - wt).abs() < 1e-12);
            assert!((v - wv).abs() < 1e-5, "{got:?}");
        }
        assert!((out[3].joints_deg[2][1] + 2.5).abs() < 1e-5);
        assert!((out[3].joints_deg[0][2] - 5.0).abs() < 1e-5);
    }

    #[test]
    fn resample_edge_cases() {
        assert!(resample(&[], 30.0).is_empty());
        let one = resample(&[pose(5.0, 3.0)], 30.0);
        assert_eq!(one, vec![pose(0.0, 3.0)]);
        assert!(resample(&[pose(0.0, 1.0), pose(1.0, 2.0)], 0.0).is_empty());
        assert!(resample(&[pose(0.0, 1.0), pose(1.0, 2.0)], f64::NAN).is_empty());
        // Duplicate timestamps: the later frame wins, no NaN from a zero-length interval.
        let out = resample(&[pose(0.0, 1.0), pose(0.5, 2.0), pose(0.5, 3.0), pose(1.0, 4.0)], 4.0);
        let v: Vec<f32> = out.iter().map(|p| p.joints_deg[0][0]).collect();
        // t = 0, .25, .5, .75, 1 -> 1, 1.5, 3, 3.5, 4
        assert_eq!(v.len(), 5);
        for (a, b) in v.iter().zip([1.0, 1.5, 3.0, 3.5, 4.0]) {
            assert!((a - b).abs() < 1e-6, "{v:?}");
        }
    }
}
