//! Pose sequences in time: [`Clip`] (frames at a fixed rate, the seed's 30 FPS authoring rate)
//! and [`DelayLine`] (a fixed-capacity history of live poses). Both answer "the pose at time
//! `t`" with linear interpolation between frames, which is the one delayed-lookup mechanism of
//! seed 000: Eq. 6-7 (`F_B(t) = F_A(t - gamma_B)`), the rigidity delays `P_i(t - delta_i)` of
//! section 6.3 and Eq. 8 (`P_i(t) = P_0(t - s_g(i) G_3 sigma_i)`).

use crate::resample::resample;
pub use crate::resample::{FRAME_TOLERANCE, frame_count, frames_needed};
use crate::sample::{JOINTS, PoseFrame};

/// The 12 angles of one pose, per joint `[pitch, yaw, roll]`, degrees.
pub type Joints = [[f32; 3]; JOINTS];

/// `a + u (b - a)` per angle, computed in `f64`. `u = 0` gives `a` and `u = 1` gives `b` exactly.
pub fn lerp_joints(a: &Joints, b: &Joints, u: f64) -> Joints {
    if u == 0.0 {
        return *a;
    }
    if u == 1.0 {
        return *b;
    }
    let mut out = *a;
    for (o, (pa, pb)) in out.iter_mut().zip(a.iter().zip(b)) {
        for c in 0..3 {
            let (x, y) = (pa[c] as f64, pb[c] as f64);
            o[c] = (x + u * (y - x)) as f32;
        }
    }
    out
}

/// Euclidean distance between two poses' 12 angles (seed 000, Eq. 5's `||F_a - F_b||`), degrees.
pub fn pose_distance(a: &Joints, b: &Joints) -> f64 {
    let mut s = 0.0f64;
    for (pa, pb) in a.iter().zip(b) {
        for c in 0..3 {
            let d = pa[c] as f64 - pb[c] as f64;
            s += d * d;
        }
    }
    s.sqrt()
}

/// Poses at a fixed rate: frame `k` is at `t = k / fps` seconds.
#[derive(Debug, Clone, PartialEq)]
pub struct Clip {
    /// Frames per second (> 0).
    pub fps: f64,
    /// The poses, `frames[k].t == k / fps`.
    pub frames: Vec<PoseFrame>,
}

impl Clip {
    /// Resamples recorded poses (any times, e.g. 1 kHz ticks) to `fps`, starting at 0.
    pub fn from_poses(poses: &[PoseFrame], fps: f64) -> Clip {
        Clip { fps, frames: resample(poses, fps) }
    }

    /// Builds a clip from bare joint angles, stamping `t = k / fps`.
    pub fn from_joints(joints: impl IntoIterator<Item = Joints>, fps: f64) -> Clip {
        let frames = joints
            .into_iter()
            .enumerate()
            .map(|(k, j)| PoseFrame { t: k as f64 / fps, joints_deg: j })
            .collect();
        Clip { fps, frames }
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True when there are no frames.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Time of the last frame, seconds (0 for an empty or one-frame clip).
    pub fn duration_s(&self) -> f64 {
        self.frames.len().saturating_sub(1) as f64 / self.fps
    }

    /// The pose at fractional frame index `f`, linearly interpolated, clamped to the first and
    /// last frames (all zeros for an empty clip). Integer `f` gives that frame bit-exactly.
    pub fn at_index(&self, f: f64) -> Joints {
        let n = self.frames.len();
        if n == 0 {
            return [[0.0; 3]; JOINTS];
        }
        if f.is_nan() || f <= 0.0 {
            return self.frames[0].joints_deg;
        }
        let last = (n - 1) as f64;
        if f >= last {
            return self.frames[n - 1].joints_deg;
        }
        let k = f.floor();
        let i = k as usize;
        lerp_joints(&self.frames[i].joints_deg, &self.frames[i + 1].joints_deg, f - k)
    }

    /// The pose at time `t_s`, linearly interpolated between frames, clamped to the clip.
    pub fn at_time(&self, t_s: f64) -> Joints {
        self.at_index(t_s * self.fps)
    }
}

/// Most frames a [`DelayLine`] holds (2^22 frames, about 235 MB of poses: 70 minutes at 1 kHz,
/// 39 hours at 30 FPS). Callers size their history from quantities that come from outside
/// (delays, start frames) and must refuse those beyond their own documented limits before
/// asking for a line; this cap is the last guard, so that no request can make a line overflow
/// a `Vec`'s capacity or take the machine's memory.
pub const MAX_DELAY_LINE_FRAMES: usize = 1 << 22;

/// A fixed-capacity history of live poses (a ring buffer), for delayed lookups on the realtime
/// loop: [`DelayLine::push`] each tick, [`DelayLine::at_time`] for `P(t - delay)`. Allocates only
/// in [`DelayLine::new`]; push and lookup never allocate.
#[derive(Debug, Clone)]
pub struct DelayLine {
    buf: Vec<PoseFrame>,
    /// Index of the oldest frame.
    start: usize,
    len: usize,
}

impl DelayLine {
    /// A history holding the last `capacity` frames, clamped to `2..=`[`MAX_DELAY_LINE_FRAMES`].
    /// For a delay up to `D` seconds at a tick rate `R` Hz, use `ceil(D * R) + 2`
    /// ([`DelayLine::capacity_for`]).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.clamp(2, MAX_DELAY_LINE_FRAMES);
        DelayLine { buf: vec![PoseFrame::default(); capacity], start: 0, len: 0 }
    }

    /// The capacity for `max_delay_s` of history at `rate_hz` ticks a second, at most
    /// [`MAX_DELAY_LINE_FRAMES`].
    pub fn capacity_for(max_delay_s: f64, rate_hz: f64) -> usize {
        let n = (max_delay_s.max(0.0) * rate_hz.max(0.0)).ceil();
        if n.is_finite() && n < MAX_DELAY_LINE_FRAMES as f64 {
            (n as usize + 2).min(MAX_DELAY_LINE_FRAMES)
        } else if n.is_finite() {
            MAX_DELAY_LINE_FRAMES
        } else {
            2
        }
    }

    /// Frames this line can hold.
    pub fn capacity(&self) -> usize {
        self.buf.len()
    }

    /// Forgets everything.
    pub fn clear(&mut self) {
        self.start = 0;
        self.len = 0;
    }

    /// Number of frames held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing has been pushed since the last clear.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn get(&self, i: usize) -> &PoseFrame {
        &self.buf[(self.start + i) % self.buf.len()]
    }

    /// Appends a frame, dropping the oldest when full. A frame whose time is before the newest
    /// one's (or not finite) restarts the history, so lookups stay ordered.
    pub fn push(&mut self, frame: PoseFrame) {
        if !frame.t.is_finite() || (self.len > 0 && frame.t < self.get(self.len - 1).t) {
            self.clear();
        }
        let cap = self.buf.len();
        if self.len == cap {
            self.buf[self.start] = frame;
            self.start = (self.start + 1) % cap;
        } else {
            let i = (self.start + self.len) % cap;
            self.buf[i] = frame;
            self.len += 1;
        }
    }

    /// The newest frame.
    pub fn latest(&self) -> Option<&PoseFrame> {
        (self.len > 0).then(|| self.get(self.len - 1))
    }

    /// The pose at time `t_s`, linearly interpolated between the two frames around it; before
    /// the oldest frame held it is the oldest, after the newest the newest. `None` when empty.
    pub fn at_time(&self, t_s: f64) -> Option<Joints> {
        if self.len == 0 {
            return None;
        }
        let first = self.get(0);
        let last = self.get(self.len - 1);
        if t_s.is_nan() || t_s <= first.t {
            return Some(first.joints_deg);
        }
        if t_s >= last.t {
            return Some(last.joints_deg);
        }
        // Binary search for the last frame at or before t_s.
        let (mut lo, mut hi) = (0, self.len - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if self.get(mid).t <= t_s {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let (a, b) = (self.get(lo), self.get(hi));
        let span = b.t - a.t;
        let u = if span > 0.0 { ((t_s - a.t) / span).clamp(0.0, 1.0) } else { 1.0 };
        Some(lerp_joints(&a.joints_deg, &b.joints_deg, u))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn j(v: f32) -> Joints {
        [[v, -v, 0.5 * v]; JOINTS]
    }

    #[test]
    fn clip_lookup_by_hand() {
        // 10 FPS: frames 0, 10, 30 at t = 0, 0.1, 0.2.
        let c = Clip::from_joints([j(0.0), j(10.0), j(30.0)], 10.0);
        assert_eq!(c.at_time(0.0), j(0.0));
        assert_eq!(c.at_time(0.05)[0][0], 5.0);
        assert_eq!(c.at_time(0.15)[1][1], -20.0);
        assert_eq!(c.at_index(1.0), j(10.0));
        assert_eq!(c.at_time(-1.0), j(0.0));
        assert_eq!(c.at_time(9.0), j(30.0));
        assert_eq!(c.at_index(f64::NAN), j(0.0));
        assert!((c.duration_s() - 0.2).abs() < 1e-12);
        assert_eq!(Clip::from_joints([], 30.0).at_time(1.0), [[0.0; 3]; 4]);
    }

    #[test]
    fn pose_distance_by_hand() {
        // One angle differs by 3, another by 4: distance 5.
        let mut b = j(0.0);
        b[0][0] = 3.0;
        b[3][2] = -4.0;
        assert_eq!(pose_distance(&j(0.0), &b), 5.0);
    }

    #[test]
    fn delay_line_interpolates_and_forgets_the_oldest() {
        let mut d = DelayLine::new(3);
        assert_eq!(d.at_time(0.0), None);
        for (k, v) in [0.0, 10.0, 20.0, 40.0].into_iter().enumerate() {
            d.push(PoseFrame { t: k as f64, joints_deg: j(v) });
        }
        // Holds t = 1, 2, 3 (values 10, 20, 40).
        assert_eq!(d.len(), 3);
        assert_eq!(d.at_time(0.0), Some(j(10.0)));
        assert_eq!(d.at_time(1.5).unwrap()[0][0], 15.0);
        assert_eq!(d.at_time(2.25).unwrap()[0][0], 25.0);
        assert_eq!(d.at_time(5.0), Some(j(40.0)));
        // Time going backwards restarts the history.
        d.push(PoseFrame { t: 0.5, joints_deg: j(7.0) });
        assert_eq!(d.len(), 1);
        assert_eq!(d.at_time(3.0), Some(j(7.0)));
        assert_eq!(DelayLine::capacity_for(0.5, 1000.0), 502);
        // Absurd histories are capped rather than overflowing a Vec's capacity.
        assert_eq!(DelayLine::capacity_for(9.3e18, 30.0), 1 << 22);
        assert_eq!(DelayLine::capacity_for(f64::INFINITY, 30.0), 2);
        assert_eq!(DelayLine::capacity_for(f64::NAN, 30.0), 2);
    }
}
