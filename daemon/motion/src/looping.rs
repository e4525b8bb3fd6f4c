//! Animation looping (seed 000, section 6.1, Eq. 5): endless playback of a short take by jumping
//! between similar "transition" frames, as in video textures.
//!
//! With `m` frames `F_0..F_(m-1)` (12 joint angles each), a window `D`, `L` regions and `P`
//! frames per region:
//! - pivot = frame `m - 1 - D`;
//! - candidates `j` with `D <= j <= m - 1 - D` and `|j - pivot| > D`;
//! - `dist(j) = sum_(i=-D..D) C(2D, i + D) * ||F_(j+i) - F_(pivot+i)||` (binomial weights,
//!   Euclidean norm of the 12 angles);
//! - region `r` covers frames `[floor(r m / L), floor((r + 1) m / L))`; in each region the `P`
//!   candidates of smallest distance are kept (ties: lower index);
//! - transition frames = those plus the pivot (the last transition frame, since every candidate
//!   is below `pivot - D`).
//!
//! Playback ([`LoopPlayer`]): frames in order; at a transition frame other than the last, jump
//! with probability 1/2 to another transition frame chosen uniformly; at the last one always
//! jump. A frame reached by a jump is played and not jumped from again (except the last, which
//! always jumps), so playback moves on. Where the two frames of a jump differ by more than a
//! threshold (degrees, Euclidean over the 12 angles), `ceil(dist / threshold) - 1` linearly
//! interpolated frames (at most `max_inserted`) are inserted. The seeded generator makes the same
//! seed give the same output.

use serde::Serialize;
use thiserror::Error;

use crate::clip::{Clip, Joints, lerp_joints, pose_distance};
use crate::rng::SeededRng;

/// Parameters of the transition search (Eq. 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoopParams {
    /// `L`, number of regions (>= 1; the seed uses 2..5).
    pub regions: usize,
    /// `P`, transition frames kept per region (>= 1; the seed uses 1..3).
    pub per_region: usize,
    /// `D`, half-width of the comparison window, frames.
    pub window: usize,
}

impl Default for LoopParams {
    fn default() -> Self {
        LoopParams { regions: 3, per_region: 2, window: 2 }
    }
}

/// Why no loop could be made.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum LoopError {
    /// A parameter is out of range.
    #[error("{0}")]
    Invalid(String),
    /// The take is too short for the window.
    #[error("the take has {frames} frames; a window of {window} needs at least {need} (3 D + 2)")]
    TooShort {
        /// Frames in the take.
        frames: usize,
        /// `D`.
        window: usize,
        /// Frames needed.
        need: usize,
    },
}

/// The transition frames of a take (`--explain` prints this as JSON).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Transitions {
    /// The pivot frame `m - 1 - D`.
    pub pivot: usize,
    /// All transition frames, ascending, including the pivot (the last one).
    pub transitions: Vec<usize>,
}

impl Transitions {
    /// Whether frame `i` is a transition frame.
    pub fn contains(&self, i: usize) -> bool {
        self.transitions.binary_search(&i).is_ok()
    }
}

/// Binomial coefficient `C(n, k)` as `f64` (exact for the window sizes used).
pub fn binomial(n: usize, k: usize) -> f64 {
    if k > n {
        return 0.0;
    }
    let k = k.min(n - k);
    let mut c = 1.0f64;
    for i in 0..k {
        c = c * (n - i) as f64 / (i + 1) as f64;
    }
    c.round()
}

/// `dist(j)` of Eq. 5: `sum_(i=-D..D) C(2D, i+D) ||F_(j+i) - F_(pivot+i)||`. Both windows must be
/// inside `frames`.
pub fn window_distance(frames: &[Joints], j: usize, pivot: usize, window: usize) -> f64 {
    (0..=2 * window)
        .map(|k| {
            binomial(2 * window, k) * pose_distance(&frames[j + k - window], &frames[pivot + k - window])
        })
        .sum()
}

/// Finds the transition frames of a clip (Eq. 5; see the module docs).
pub fn find_transitions(clip: &Clip, p: &LoopParams) -> Result<Transitions, LoopError> {
    if p.regions == 0 || p.per_region == 0 {
        return Err(LoopError::Invalid(format!(
            "--regions and --per-region must be at least 1, got {} and {}",
            p.regions, p.per_region
        )));
    }
    let m = clip.len();
    let d = p.window;
    let need = 3usize.saturating_mul(d).saturating_add(2);
    if m < need {
        return Err(LoopError::TooShort { frames: m, window: d, need });
    }
    let frames: Vec<Joints> = clip.frames.iter().map(|f| f.joints_deg).collect();
    let pivot = m - 1 - d;
    let mut transitions = Vec::new();
    for r in 0..p.regions {
        let (lo, hi) = (r * m / p.regions, (r + 1) * m / p.regions);
        let mut scored: Vec<(f64, usize)> = (lo.max(d)..hi.min(pivot + 1))
            .filter(|&j| j.abs_diff(pivot) > d)
            .map(|j| (window_distance(&frames, j, pivot, d), j))
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        transitions.extend(scored.iter().take(p.per_region).map(|&(_, j)| j));
    }
    transitions.push(pivot);
    transitions.sort_unstable();
    transitions.dedup();
    Ok(Transitions { pivot, transitions })
}

/// One output frame of a loop: a frame of the clip, or an interpolated frame inserted into a
/// jump.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LoopStep {
    /// Frame `i` of the clip.
    Frame(usize),
    /// `lerp(F_from, F_to, u)`, inserted into the jump `from -> to`.
    Blend {
        /// Jump source.
        from: usize,
        /// Jump destination.
        to: usize,
        /// Interpolation parameter in `(0, 1)`.
        u: f64,
    },
}

impl LoopStep {
    /// The pose of this step in `clip`.
    pub fn joints(&self, clip: &Clip) -> Joints {
        match *self {
            LoopStep::Frame(i) => clip.frames[i].joints_deg,
            LoopStep::Blend { from, to, u } => {
                lerp_joints(&clip.frames[from].joints_deg, &clip.frames[to].joints_deg, u)
            }
        }
    }
}

/// Playback rules beyond Eq. 5.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaybackParams {
    /// Jumps between frames further apart than this (degrees, Euclidean over the 12 angles)
    /// get interpolated frames.
    pub threshold_deg: f64,
    /// Most frames inserted into one jump.
    pub max_inserted: usize,
}

impl Default for PlaybackParams {
    fn default() -> Self {
        PlaybackParams { threshold_deg: 8.0, max_inserted: 10 }
    }
}

/// Endless loop playback over a clip's transition frames (see the module docs). After
/// [`LoopPlayer::new`] it never allocates: [`LoopPlayer::next_step`] is safe on the realtime loop.
#[derive(Debug, Clone)]
pub struct LoopPlayer {
    transitions: Vec<usize>,
    rng: SeededRng,
    params: PlaybackParams,
    frames: usize,
    /// The next clip frame to play (when no blend is pending).
    next: usize,
    /// Whether `next` was reached by a jump.
    arrived: bool,
    /// A pending interpolated jump `(from, to, done, count)`.
    blend: Option<(usize, usize, usize, usize)>,
}

impl LoopPlayer {
    /// A player over a clip of `frames` frames, starting at frame `start` (clamped).
    pub fn new(
        frames: usize,
        transitions: &Transitions,
        seed: u64,
        params: PlaybackParams,
        start: usize,
    ) -> Self {
        LoopPlayer {
            transitions: transitions.transitions.clone(),
            rng: SeededRng::new(seed),
            params,
            frames,
            next: start.min(frames.saturating_sub(1)),
            arrived: false,
            blend: None,
        }
    }

    /// The next output step. `clip` must be the clip the transitions were found in.
    pub fn next_step(&mut self, clip: &Clip) -> LoopStep {
        if let Some((from, to, done, count)) = self.blend {
            if done < count {
                self.blend = Some((from, to, done + 1, count));
                return LoopStep::Blend { from, to, u: (done + 1) as f64 / (count + 1) as f64 };
            }
            self.blend = None;
        }
        let i = self.next;
        let arrived = self.arrived;
        self.arrived = false;
        let last = *self.transitions.last().unwrap_or(&i);
        let pos = self.transitions.binary_search(&i).ok();
        let n = self.transitions.len();
        let jump = match pos {
            Some(_) if n < 2 => false,
            Some(_) if i == last => true,
            Some(_) if arrived => false,
            Some(_) => self.rng.coin(),
            None => false,
        };
        if jump {
            let p = pos.unwrap_or(0);
            let mut k = self.rng.below(n - 1);
            if k >= p {
                k += 1;
            }
            let to = self.transitions[k];
            let d = pose_distance(&clip.frames[i].joints_deg, &clip.frames[to].joints_deg);
            let t = self.params.threshold_deg;
            let count = if t > 0.0 && d > t {
                ((d / t).ceil() as usize).saturating_sub(1).min(self.params.max_inserted)
            } else {
                0
            };
            if count > 0 {
                self.blend = Some((i, to, 0, count));
            }
            self.next = to;
            self.arrived = true;
        } else if i + 1 < self.frames {
            self.next = i + 1;
        } else {
            // Only reachable when starting after the pivot: go back to the first transition.
            self.next = self.transitions.first().copied().unwrap_or(0);
            self.arrived = true;
        }
        LoopStep::Frame(i)
    }
}

/// Renders `count` frames of loop playback of `clip` (at its frame rate) from `start`, and the
/// steps they came from.
pub fn loop_clip(
    clip: &Clip,
    transitions: &Transitions,
    seed: u64,
    params: PlaybackParams,
    start: usize,
    count: usize,
) -> (Clip, Vec<LoopStep>) {
    if clip.is_empty() {
        return (Clip { fps: clip.fps, frames: Vec::new() }, Vec::new());
    }
    let mut player = LoopPlayer::new(clip.len(), transitions, seed, params, start);
    let steps: Vec<LoopStep> = (0..count).map(|_| player.next_step(clip)).collect();
    let out = Clip::from_joints(steps.iter().map(|s| s.joints(clip)), clip.fps);
    (out, steps)
}

/// A live cursor over an endless loop: the pose at any time (e.g. every 1 kHz tick) from the
/// 30 FPS loop, interpolated between loop frames. For the daemon's "loop a global take on the
/// pose stream while a secondary layer is recorded". Owns its clip; allocation-free after
/// [`Playback::new`].
#[derive(Debug, Clone)]
pub struct Playback {
    clip: Clip,
    player: LoopPlayer,
    a: Joints,
    b: Joints,
    /// Output frame index of `a`.
    n: u64,
}

impl Playback {
    /// Starts playback of `clip` at loop frame 0 (time 0 = `clip.frames[start]`).
    pub fn new(
        clip: Clip,
        transitions: &Transitions,
        seed: u64,
        params: PlaybackParams,
        start: usize,
    ) -> Self {
        let mut player = LoopPlayer::new(clip.len(), transitions, seed, params, start);
        let (a, b) = if clip.is_empty() {
            ([[0.0; 3]; 4], [[0.0; 3]; 4])
        } else {
            (player.next_step(&clip).joints(&clip), player.next_step(&clip).joints(&clip))
        };
        Playback { clip, player, a, b, n: 0 }
    }

    /// The clip being looped.
    pub fn clip(&self) -> &Clip {
        &self.clip
    }

    /// The pose at `t_s` seconds after the start. Times must not go backwards (an earlier time
    /// gives the current frame); a jump far ahead plays through the frames in between, so the
    /// random path is the same whatever the call rate.
    pub fn pose_at(&mut self, t_s: f64) -> Joints {
        if self.clip.is_empty() {
            return self.a;
        }
        let f = (t_s * self.clip.fps).max(0.0);
        if !f.is_finite() {
            return self.a;
        }
        while (self.n + 1) as f64 <= f {
            self.a = self.b;
            self.b = self.player.next_step(&self.clip).joints(&self.clip);
            self.n += 1;
        }
        lerp_joints(&self.a, &self.b, (f - self.n as f64).clamp(0.0, 1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn clip_1d(values: &[f32]) -> Clip {
        Clip::from_joints(
            values.iter().map(|&v| {
                let mut j = [[0.0; 3]; 4];
                j[0][0] = v;
                j
            }),
            30.0,
        )
    }

    #[test]
    fn binomial_weights() {
        assert_eq!((0..=2).map(|k| binomial(2, k)).collect::<Vec<_>>(), [1.0, 2.0, 1.0]);
        assert_eq!((0..=4).map(|k| binomial(4, k)).collect::<Vec<_>>(), [1.0, 4.0, 6.0, 4.0, 1.0]);
        assert_eq!(binomial(3, 5), 0.0);
    }

    #[test]
    fn eq5_by_hand() {
        // m = 12, D = 1: pivot = 10, window F[9..=11] = (3, 2, 1). Candidates j = 1..=8.
        // dist(j) = |F[j-1] - 3| + 2 |F[j] - 2| + |F[j+1] - 1|:
        //   j:    1  2  3  4  5  6  7  8
        //   dist: 6  4  4  0  4  6  6  4
        // Regions (L = 3): [0,4) [4,8) [8,12).
        // P = 1: region 0 -> 2 (tie 2/3, lower index), region 1 -> 4, region 2 -> 8.
        let c = clip_1d(&[0.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.0, 1.0, 2.0, 3.0, 2.0, 1.0]);
        let frames: Vec<Joints> = c.frames.iter().map(|f| f.joints_deg).collect();
        let d: Vec<f64> = (1..=8).map(|j| window_distance(&frames, j, 10, 1)).collect();
        assert_eq!(d, [6.0, 4.0, 4.0, 0.0, 4.0, 6.0, 6.0, 4.0]);
        let t = find_transitions(&c, &LoopParams { regions: 3, per_region: 1, window: 1 }).unwrap();
        assert_eq!(t, Transitions { pivot: 10, transitions: vec![2, 4, 8, 10] });
        // P = 2: region 0 -> 2, 3; region 1 -> 4, 5; region 2 -> 8 (its only candidate).
        let t = find_transitions(&c, &LoopParams { regions: 3, per_region: 2, window: 1 }).unwrap();
        assert_eq!(t.transitions, [2, 3, 4, 5, 8, 10]);
    }

    #[test]
    fn eq5_uses_the_euclidean_norm_of_all_12_angles() {
        // D = 0: dist(j) = ||F_j - F_pivot||. Frame 0 differs from the pivot by (3, 4) in two
        // different joints: 5; frame 1 by 6 in one angle. Frame 0 is closer.
        let mut f = [[[0.0f32; 3]; 4]; 3];
        f[0][1][2] = 3.0;
        f[0][3][0] = 4.0;
        f[1][2][1] = 6.0;
        let c = Clip::from_joints(f, 30.0);
        let t = find_transitions(&c, &LoopParams { regions: 1, per_region: 1, window: 0 }).unwrap();
        assert_eq!(t.transitions, [0, 2]);
    }

    #[test]
    fn errors() {
        let c = clip_1d(&[0.0; 7]);
        assert_eq!(
            find_transitions(&c, &LoopParams { regions: 2, per_region: 1, window: 2 })
                .unwrap_err()
                .to_string(),
            "the take has 7 frames; a window of 2 needs at least 8 (3 D + 2)"
        );
        assert!(find_transitions(&c, &LoopParams { regions: 0, per_region: 1, window: 1 }).is_err());
    }

    #[test]
    fn playback_by_hand_and_seeded() {
        let c = clip_1d(&[0.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.0, 1.0, 2.0, 3.0, 2.0, 1.0]);
        let t = find_transitions(&c, &LoopParams { regions: 3, per_region: 1, window: 1 }).unwrap();
        let p = PlaybackParams { threshold_deg: 100.0, max_inserted: 0 };
        let (out, steps) = loop_clip(&c, &t, 42, p, 0, 200);
        assert_eq!(out.len(), 200);
        // Frames 0, 1, 2 always come first (2 may jump, but frame 2 itself is played).
        assert_eq!(&steps[..3], &[LoopStep::Frame(0), LoopStep::Frame(1), LoopStep::Frame(2)]);
        // The pivot (10) is always left by a jump: 11 never follows it.
        for w in steps.windows(2) {
            if w[0] == LoopStep::Frame(10) {
                assert_ne!(w[1], LoopStep::Frame(11));
            }
        }
        assert_eq!(loop_clip(&c, &t, 42, p, 0, 200).1, steps);
        assert_ne!(loop_clip(&c, &t, 43, p, 0, 200).1, steps);
    }

    #[test]
    fn interpolated_frames_fill_big_jumps() {
        // Frames 0..=4 at 0, then a ramp; transitions with D = 0, L = 1, P = 1: pivot 9 (value 50).
        let c = clip_1d(&[0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 45.0, 60.0, 70.0, 50.0]);
        let t = Transitions { pivot: 9, transitions: vec![1, 9] };
        // At 9 always jump to 1: |50 - 10| = 40 with threshold 10 -> 3 inserted frames 40, 30, 20.
        let p = PlaybackParams { threshold_deg: 10.0, max_inserted: 10 };
        let (out, steps) = loop_clip(&c, &t, 1, p, 8, 6);
        assert_eq!(steps[0], LoopStep::Frame(8));
        assert_eq!(steps[1], LoopStep::Frame(9));
        let v: Vec<f32> = out.frames.iter().map(|f| f.joints_deg[0][0]).collect();
        assert_eq!(v, [70.0, 50.0, 40.0, 30.0, 20.0, 10.0]);
    }

    #[test]
    fn playback_cursor_matches_the_offline_loop() {
        let c = clip_1d(&(0..40).map(|k| (k as f32 * 0.7).sin() * 20.0).collect::<Vec<_>>());
        let t = find_transitions(&c, &LoopParams::default()).unwrap();
        let (out, _) = loop_clip(&c, &t, 5, PlaybackParams::default(), 0, 100);
        let mut live = Playback::new(c.clone(), &t, 5, PlaybackParams::default(), 0);
        // Polled at 1 kHz: whole frames are exact, in between is interpolated.
        for tick in 0..3000u32 {
            let ts = tick as f64 / 1000.0;
            let got = live.pose_at(ts);
            let want = out.at_time(ts);
            assert!((got[0][0] - want[0][0]).abs() < 1e-4, "{ts}: {got:?} vs {want:?}");
        }
    }

    proptest! {
        #[test]
        fn loop_only_jumps_between_transition_frames(
            values in proptest::collection::vec(-45.0f32..45.0, 12..80),
            regions in 1usize..5, per_region in 1usize..4, window in 0usize..3, seed in any::<u64>(),
            threshold in 0.5f64..50.0,
        ) {
            let c = clip_1d(&values);
            let t = find_transitions(&c, &LoopParams { regions, per_region, window }).unwrap();
            prop_assert_eq!(*t.transitions.last().unwrap(), values.len() - 1 - window);
            let (out, steps) = loop_clip(&c, &t, seed, PlaybackParams { threshold_deg: threshold, max_inserted: 10 }, 0, 400);
            prop_assert_eq!(out.len(), 400);
            let mut prev: Option<usize> = None;
            for s in &steps {
                match *s {
                    LoopStep::Frame(i) => {
                        if let Some(p) = prev && i != p + 1 {
                            prop_assert!(t.contains(p) && t.contains(i) && p != i, "jump {} -> {} not between {:?}", p, i, t.transitions);
                        }
                        prev = Some(i);
                    }
                    LoopStep::Blend { from, to, u } => {
                        prop_assert!(t.contains(from) && t.contains(to) && u > 0.0 && u < 1.0);
                    }
                }
            }
        }
    }
}
