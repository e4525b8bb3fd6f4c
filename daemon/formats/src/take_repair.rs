//! Repairing a take (`frond take repair`, the console's Repair): the readable records, byte
//! for byte, without damaged stretches, non-finite frames and a torn tail, closed with an End
//! record counting what is kept. Pure: the callers read and write the file.

use std::time::Duration;

use crate::take::{RecordAt, TakeError, TakeRecord, encode_record};
use crate::take::{scan_take, scan_take_salvaging};
use frond_motion::take::Skipped;

/// A take without an End record modified more recently than this may still be recording:
/// repair leaves it alone.
pub const MAY_BE_RECORDING: Duration = Duration::from_secs(5);

/// What `repair` did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Repaired {
    /// Torn bytes cut from the end.
    pub dropped_bytes: u64,
    /// Damaged stretches and non-finite frames left out.
    pub skipped: Vec<Skipped>,
    /// Frames lost: non-finite frames left out, plus those the End record counted that could not
    /// be read.
    pub lost_frames: u64,
    /// Frames kept.
    pub frames: u64,
    /// Whether an End record was added to a take that had none.
    pub closed: bool,
}

/// Why a take cannot be repaired. The take's own [`TakeError`] is part of the text, not a
/// `source`, so that a report printing the chain does not say it twice.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RepairError {
    /// The file holds no bytes at all.
    #[error("the take is empty (0 bytes): nothing was ever written, there is nothing to keep; delete it")]
    Empty,
    /// Even salvaging, the take cannot be read (its signature or header is bad).
    #[error("{0}; this cannot be repaired")]
    Unreadable(TakeError),
    /// The readable part is shorter than the 8-byte signature.
    #[error("the take is too short to hold even its 8-byte signature; nothing can be kept")]
    TooShort,
    /// A bug: the scan said the take ends with an End record that is not there.
    #[error("internal error: the take's End record is not where the reader ended")]
    EndMisplaced,
    /// A bug: the repaired bytes do not read as a take.
    #[error("internal error: the repaired take does not read back: {0}")]
    NoReadBack(TakeError),
    /// A bug: the repaired bytes read as a different take.
    #[error("internal error: the repaired take does not read back identically")]
    NotIdentical,
}

/// The repaired bytes: the readable records, byte for byte, without damaged stretches,
/// non-finite frames and the torn tail, closed with an End record counting what is kept.
/// `None` when there is nothing to repair.
pub fn repaired_bytes(bytes: &[u8]) -> Result<Option<(Vec<u8>, Repaired)>, RepairError> {
    if bytes.is_empty() {
        return Err(RepairError::Empty);
    }
    let scan = scan_take_salvaging(bytes).map_err(RepairError::Unreadable)?;
    if scan.torn_bytes == 0 && scan.ended && scan.skipped.is_empty() {
        return Ok(None);
    }
    if scan.valid_len < crate::take::MAGIC.len() as u64 {
        return Err(RepairError::TooShort);
    }
    // The readable part, without the old End record (its count no longer holds).
    let mut keep_until = scan.valid_len as usize;
    if scan.ended {
        let end_at = keep_until - crate::take::RECORD_HEAD_LEN - 9;
        match crate::take::read_record_at(bytes, end_at) {
            Ok(RecordAt::Record { record: TakeRecord::End { .. }, next }) if next == keep_until => {
                keep_until = end_at
            }
            _ => return Err(RepairError::EndMisplaced),
        }
    }
    let mut out = Vec::with_capacity(keep_until);
    let mut at = 0usize;
    for s in &scan.skipped {
        out.extend_from_slice(&bytes[at..s.offset as usize]);
        at = (s.offset + s.len) as usize;
    }
    out.extend_from_slice(&bytes[at..keep_until]);
    let frames = scan.frames.len() as u64;
    encode_record(&TakeRecord::End { frames }, &mut out);
    // The result must read back as a complete, sound take with the same frames.
    let check = scan_take(&out).map_err(RepairError::NoReadBack)?;
    if !check.ended || check.torn_bytes != 0 || !check.skipped.is_empty() || check.frames != scan.frames {
        return Err(RepairError::NotIdentical);
    }
    let repaired = Repaired {
        dropped_bytes: scan.torn_bytes,
        lost_frames: scan.lost_frames() + scan.missing_frames(),
        skipped: scan.skipped,
        frames,
        closed: !scan.ended,
    };
    Ok(Some((out, repaired)))
}

impl Repaired {
    /// Whether the take had its End record already (so no recorder is appending to it).
    pub fn closed_before(&self) -> bool {
        !self.closed
    }

    /// `frond take repair`'s report of what was dropped, for the take at `path`.
    pub fn report(&self, path: &str) -> String {
        let r = self;
        let mut dropped = Vec::new();
        for s in &r.skipped {
            dropped.push(format!("{s}"));
        }
        if r.dropped_bytes > 0 {
            dropped.push(format!("{} torn bytes at the end", r.dropped_bytes));
        }
        let lost = if r.lost_frames > 0 || !r.skipped.is_empty() {
            format!("; {} frame{} lost", r.lost_frames, if r.lost_frames == 1 { "" } else { "s" })
        } else {
            String::new()
        };
        // A take cut off by a crash has no torn tail and no damage: only its End is missing.
        let dropped = if dropped.is_empty() {
            "nothing dropped".to_string()
        } else {
            format!("dropped {}", dropped.join(", "))
        };
        format!(
            "repaired {}: {dropped}{lost}; kept {} frames{}",
            path,
            r.frames,
            if r.closed { ", closed with an End record" } else { "" }
        )
    }
}
