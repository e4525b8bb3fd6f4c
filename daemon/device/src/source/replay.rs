//! [`ReplaySource`]: a JSONL hand recording played at its timestamps against the host monotonic
//! clock. The file is loaded up front; reads do no I/O and no allocation.
//!
//! The file's times are untrusted input: a step from one sample to the next that jumps forward
//! by more than [`MAX_TIME_STEP_S`] (1 s), goes back or repeats ([`breaks_timeline`], the rule the
//! mapper applies live and in `frond map`) is not waited out or bursted through. The sample
//! after such a step is due at the next read after its predecessor's (the realtime loop reads
//! once a tick), and the playback goes on from there at the file's pace. The times themselves
//! are delivered unchanged, so the daemon's mapper sees the same break: it resets the filter,
//! flags the pose `discontinuity`, counts it in the hand's `discontinuities` and the daemon
//! logs the count rate-limited ("device time discontinuous N times").

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use frond_motion::HandSample;
#[cfg(doc)]
use frond_motion::mapping::MAX_TIME_STEP_S;
use frond_motion::mapping::breaks_timeline;

use frond_protocol::SourceKind;

use super::hand::{HandSource, SourceError};
use super::spec::{Backend, SourceSpec, SpecError, SpecInput};
use crate::jsonl::{HandFileError, load_hand_recording};
use crate::report::{DeviceSample, SourceCounters};

/// `replay`: a JSONL hand recording, the file given under its own key.
pub(crate) const BACKEND: Backend = Backend { syntax: "replay", parse };

fn parse(kind: &str, input: &SpecInput<'_>) -> Option<Result<SourceSpec, SpecError>> {
    (kind == "replay").then(|| match input.replay {
        Some(path) => Ok(SourceSpec::Replay(path.into())),
        None => Err(SpecError::NoReplayFile {
            replay_key: input.replay_key.to_string(),
            key: input.key.to_string(),
        }),
    })
}

/// Plays a hand recording: from the first read (or [`ReplaySource::start`]) sample `i` becomes
/// pending once `t_i - t_0` seconds have passed, while the times follow one timeline; after a
/// break in the file's time (see the module documentation) the clock is set anew from the
/// sample after it.
pub struct ReplaySource {
    samples: Vec<HandSample>,
    next: usize,
    start: Option<Instant>,
    /// Where the current timeline sits on the replay clock: a sample at file time `t` on it is
    /// due `t - anchor.t` seconds after `anchor.elapsed_s`.
    anchor: Anchor,
    describe: String,
    counters: Arc<SourceCounters>,
}

/// A file time and the replay-clock time (seconds since the start) it is played at.
#[derive(Debug, Clone, Copy)]
struct Anchor {
    elapsed_s: f64,
    t: f64,
}

impl ReplaySource {
    /// Loads `path` (see [`crate::jsonl`] for the format; times in any order).
    pub fn load(path: &Path) -> Result<Self, HandFileError> {
        let samples = load_hand_recording(path)?;
        Ok(Self::from_samples(samples, path.display().to_string()))
    }

    /// A replay of samples already in memory (times as recorded, in any order).
    pub fn from_samples(samples: Vec<HandSample>, describe: String) -> Self {
        let anchor = Self::first_anchor(&samples);
        Self {
            samples,
            next: 0,
            start: None,
            anchor,
            describe,
            counters: Arc::new(SourceCounters::default()),
        }
    }

    fn first_anchor(samples: &[HandSample]) -> Anchor {
        Anchor { elapsed_s: 0.0, t: samples.first().map_or(0.0, |s| s.t) }
    }

    /// Starts the clock now (otherwise the first `read_pending` starts it).
    pub fn start(&mut self) {
        self.start = Some(Instant::now());
    }

    /// Whether every sample has been delivered.
    pub fn finished(&self) -> bool {
        self.next >= self.samples.len()
    }

    /// Number of samples in the recording.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether the recording is empty.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Moves the samples due `elapsed_s` seconds after the start into `out`; returns how many.
    /// A sample that breaks the timeline is only taken when nothing was taken before it in this
    /// call (so its predecessor went out in an earlier read), and re-anchors the clock there.
    fn take_due(&mut self, elapsed_s: f64, out: &mut [DeviceSample]) -> usize {
        let mut n = 0;
        while n < out.len() && self.next < self.samples.len() {
            let s = self.samples[self.next];
            let previous_t = self.next.checked_sub(1).map(|i| self.samples[i].t);
            if breaks_timeline(previous_t, s.t) {
                if n > 0 {
                    break;
                }
                self.anchor = Anchor { elapsed_s, t: s.t };
            } else if self.anchor.elapsed_s + (s.t - self.anchor.t) > elapsed_s {
                break;
            }
            // The file's time is kept as is so poses match an offline mapping of the file.
            out[n] = DeviceSample {
                device_seq: self.next as u32,
                device_time_us: (s.t * 1e6).round().max(0.0) as u64,
                raw: s,
                flex_deg: [0.0; 4],
                status: 1,
            };
            self.counters.reports.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            self.next += 1;
            n += 1;
        }
        n
    }
}

impl HandSource for ReplaySource {
    fn kind(&self) -> SourceKind {
        SourceKind::Replay
    }

    fn describe(&self) -> &str {
        &self.describe
    }

    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        let start = *self.start.get_or_insert_with(Instant::now);
        Ok(self.take_due(start.elapsed().as_secs_f64(), out))
    }

    fn counters(&self) -> Arc<SourceCounters> {
        Arc::clone(&self.counters)
    }

    /// Restarts the recording from the beginning.
    fn reopen(&mut self) -> Result<(), SourceError> {
        self.next = 0;
        self.start = None;
        self.anchor = Self::first_anchor(&self.samples);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use frond_motion::mapping::MAX_TIME_STEP_S;

    use super::*;

    /// Plays samples at `times` and reads once at each of `reads_s` (seconds on the replay
    /// clock): the times delivered by each read.
    fn play(times: &[f64], reads_s: &[f64]) -> Vec<Vec<f64>> {
        let samples = times.iter().map(|&t| HandSample { t, ..HandSample::default() }).collect();
        let mut src = ReplaySource::from_samples(samples, "test".into());
        let mut buf = [DeviceSample::default(); 8];
        reads_s
            .iter()
            .map(|&e| {
                let n = src.take_due(e, &mut buf);
                buf[..n].iter().map(|s| s.raw.t).collect()
            })
            .collect()
    }

    #[test]
    fn one_timeline_plays_at_the_file_pace() {
        // Due at 0, 0.5, 1.0 s; a late read takes everything due, in order.
        assert_eq!(play(&[0.0, 0.5, 1.0], &[0.0, 0.25, 0.5, 0.75]), [vec![0.0], vec![], vec![0.5], vec![]]);
        assert_eq!(play(&[10.0, 10.5, 11.0], &[0.0, 2.0]), [vec![10.0], vec![10.5, 11.0]]);
        // A step of exactly MAX_TIME_STEP_S is still one timeline: waited out.
        assert_eq!(MAX_TIME_STEP_S, 1.0);
        assert_eq!(play(&[0.0, 1.0], &[0.0, 0.5, 0.75, 1.0]), [vec![0.0], vec![], vec![], vec![1.0]]);
    }

    #[test]
    fn a_forward_jump_continues_at_the_next_read() {
        // 0, 0.25, then 1e15 (the old pacing waited 1e15 s for it), then 0.5 s later on the new
        // timeline, and a step of 1.5 s (over the bound): not waited out either.
        let times = [0.0, 0.25, 1e15, 1e15 + 0.5, 1e15 + 2.0];
        let got = play(&times, &[0.0, 0.25, 0.25, 0.5, 0.75, 0.8]);
        assert_eq!(got, [vec![0.0], vec![0.25], vec![1e15], vec![], vec![1e15 + 0.5], vec![1e15 + 2.0]]);
    }

    #[test]
    fn a_step_back_continues_at_the_next_read_and_the_pace_follows_it() {
        // 5, 5.5, back to 2 (a tracker restarting its clock), 2.5. Paced by `t - t_0` alone, 2
        // and 2.5 would go at once with 5.5 (both "overdue"); here 2 waits for the next read and
        // 2.5 comes half a second after it.
        let got = play(&[5.0, 5.5, 2.0, 2.5], &[0.0, 0.5, 0.5, 0.75, 1.0]);
        assert_eq!(got, [vec![5.0], vec![5.5], vec![2.0], vec![], vec![2.5]]);
    }

    #[test]
    fn repeated_times_come_one_read_apart_not_in_a_burst() {
        let got = play(&[1.0, 1.0, 1.0, 1.25], &[0.0, 0.0, 0.0, 0.125, 0.25]);
        assert_eq!(got, [vec![1.0], vec![1.0], vec![1.0], vec![], vec![1.25]]);
    }

    #[test]
    fn reopen_plays_from_the_start_with_a_fresh_clock() {
        let samples = [3.0, 1e9].iter().map(|&t| HandSample { t, ..HandSample::default() }).collect();
        let mut src = ReplaySource::from_samples(samples, "test".into());
        let mut buf = [DeviceSample::default(); 4];
        assert_eq!(src.take_due(0.0, &mut buf), 1);
        assert_eq!(src.take_due(0.0, &mut buf), 1);
        assert_eq!(buf[0].raw.t, 1e9);
        assert_eq!(buf[0].device_time_us, 1_000_000_000_000_000);
        assert!(src.finished());
        src.reopen().unwrap();
        assert_eq!(src.take_due(0.0, &mut buf), 1);
        assert_eq!((buf[0].raw.t, buf[0].device_seq), (3.0, 0));
    }
}
