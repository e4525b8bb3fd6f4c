//! Several takes on one stage timeline (issue 20: several performers, one timeline).
//!
//! Every frame of a take carries its host's monotonic stamp (`TakeFrame::host_ns`), and a take
//! that knows its recording clock (`TakeHeader::clock`: a wall-clock time read beside a
//! monotonic one) places each frame at a wall-clock instant: `unix_ns + (host_ns - clock.host_ns)`.
//! Takes recorded by a stage recorder have that clock already corrected onto the recorder's
//! clock (the measured offset of each performer's clock is subtracted, see
//! `TakeHeader::stage`), and takes a daemon recorded on one host share that host's clock; either
//! way, the wall-clock instants of several takes are on one timeline, and [`align`] merges them.

use crate::take::FLAG_HELD;
use crate::take::{TakeFrame, TakeScan};

/// One frame on the stage timeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlignedFrame {
    /// Index of its take in the slice given to [`align`].
    pub take: usize,
    /// Its instant on the timeline, nanoseconds since 1970.
    pub stage_ns: u64,
    /// The frame as recorded.
    pub frame: TakeFrame,
}

/// Why takes cannot be aligned.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AlignError {
    /// A take has no recording clock (made offline, or before frond wrote one).
    #[error("take {take} has no recording clock (made offline?), so it has no place on a timeline")]
    NoClock {
        /// Index of the take.
        take: usize,
    },
}

/// The main-skeleton frames (a layer take's layer, [`crate::take::main_element`]) of every take (held frames only with `include_held`), each at its
/// instant on the stage timeline, in timeline order (ties: take order, then file order).
pub fn align(takes: &[&TakeScan], include_held: bool) -> Result<Vec<AlignedFrame>, AlignError> {
    let mut out = Vec::new();
    for (i, scan) in takes.iter().enumerate() {
        let clock = scan.header.as_ref().and_then(|h| h.clock).ok_or(AlignError::NoClock { take: i })?;
        let main = scan.main_element();
        out.extend(
            scan.frames
                .iter()
                .filter(|f| Some(f.element) == main && (include_held || f.flags & FLAG_HELD == 0))
                .map(|f| AlignedFrame { take: i, stage_ns: clock.unix_ns_of(f.host_ns), frame: *f }),
        );
    }
    // Stable: equal instants keep take order, then file order.
    out.sort_by_key(|a| (a.stage_ns, a.take));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::take::{TakeClock, TakeHeader};

    fn scan(clock: Option<TakeClock>, frames: &[(u64, u64, u32)]) -> TakeScan {
        TakeScan {
            header: Some(TakeHeader { clock, ..TakeHeader::offline("t", "grass", 1000) }),
            frames: frames
                .iter()
                .map(|&(seq, host_ns, flags)| TakeFrame { seq, host_ns, flags, ..TakeFrame::default() })
                .collect(),
            markers: vec![],
            ended: true,
            valid_len: 0,
            torn_bytes: 0,
            skipped: vec![],
            end_frames: None,
        }
    }

    #[test]
    fn two_hosts_frames_interleave_on_the_wall_clock() {
        // Host A: monotonic 5_000 was wall 1_000_000. Host B: monotonic 90_000 was wall 1_000_500.
        let a = scan(Some(TakeClock { unix_ns: 1_000_000, host_ns: 5_000 }), &[(1, 5_000, 0), (2, 6_000, 0)]);
        let b =
            scan(Some(TakeClock { unix_ns: 1_000_500, host_ns: 90_000 }), &[(7, 90_000, 0), (8, 90_400, 1)]);
        let got: Vec<(usize, u64, u64)> =
            align(&[&a, &b], false).unwrap().iter().map(|f| (f.take, f.frame.seq, f.stage_ns)).collect();
        // B's held frame 8 is left out.
        assert_eq!(got, vec![(0, 1, 1_000_000), (1, 7, 1_000_500), (0, 2, 1_001_000)]);
        let held: Vec<u64> = align(&[&a, &b], true).unwrap().iter().map(|f| f.frame.seq).collect();
        assert_eq!(held, vec![1, 7, 8, 2]);
    }

    #[test]
    fn a_take_without_a_clock_is_named() {
        let a = scan(Some(TakeClock { unix_ns: 1, host_ns: 1 }), &[(1, 1, 0)]);
        let b = scan(None, &[(1, 1, 0)]);
        assert_eq!(align(&[&a, &b], false), Err(AlignError::NoClock { take: 1 }));
    }
}
