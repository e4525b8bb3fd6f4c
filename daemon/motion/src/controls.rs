//! Animation controls (seed 000, section 6.3): bend direction, motion speed (time step), motion
//! scale, rigidity delays `P_i(t - delta_i)`, offline as [`retime`] and live as
//! [`FieldControls`] driven by keys ([`ControlKey`]) or a hand swipe ([`SwipeDetector`]).
//!
//! Directions are headings on the ground: the +X axis rotated about +Y (up) by the angle, so
//! 0 = +X, 90 = -Z, 180 = -X, 270 = +Z (counter-clockwise seen from above, glTF frame). A take
//! is taken to be authored with the force towards +X (the seed: "bending ... mostly towards
//! right"). A pose bends its stem towards `(x, z) = (-yaw, pitch)` (small angles; pitch tips +Y to
//! +Z, yaw tips +Y to -X), and rotating that bend vector by `a` about +Y gives
//! `pitch' = pitch cos a + yaw sin a`, `yaw' = yaw cos a - pitch sin a`.

use crate::clip::{Clip, Joints};
use crate::sample::{HandSample, JOINTS};

/// Rotates one joint's bending direction `(pitch, yaw)` by `deg` about the vertical (seed 000,
/// section 6.3 (1)(b)); roll is unchanged.
pub fn rotate_bend(angles: [f32; 3], deg: f64) -> [f32; 3] {
    if deg == 0.0 {
        return angles;
    }
    let (s, c) = deg.to_radians().sin_cos();
    let (p, y) = (angles[0] as f64, angles[1] as f64);
    [(p * c + y * s) as f32, (y * c - p * s) as f32, angles[2]]
}

/// Scale (section 6.3 (2)(e)) and bend rotation applied to a whole pose.
pub fn shape_pose(j: &Joints, scale: f32, rotate_deg: f64) -> Joints {
    let mut out = *j;
    for a in out.iter_mut() {
        *a = rotate_bend(a.map(|x| x * scale), rotate_deg);
    }
    out
}

/// Offline controls (`frond take retime`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Retime {
    /// Motion speed `K` (section 6.3 (2)(d)): the take advances `K` seconds per second (> 0).
    pub speed: f64,
    /// Motion scale (section 6.3 (2)(e)): every angle is multiplied by it.
    pub scale: f32,
    /// Bend direction rotation, degrees (section 6.3 (1)(b)).
    pub rotate_deg: f64,
    /// Rigidity delays `delta_1..delta_3`, seconds (section 6.3 (3)), >= 0.
    pub delays_s: [f64; 3],
}

impl Default for Retime {
    fn default() -> Self {
        Retime { speed: 1.0, scale: 1.0, rotate_deg: 0.0, delays_s: [0.0; 3] }
    }
}

/// A [`Retime`] parameter out of its range (named by its `frond take retime` option).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum RetimeError {
    /// The motion speed is not in `(0, 100]`.
    #[error("--speed must be in (0, 100], got {0}")]
    Speed(f64),
    /// The motion scale is not a finite number within +-100.
    #[error("--scale must be a finite number within +-100, got {0}")]
    Scale(f32),
    /// The bend rotation is not finite.
    #[error("--rotate must be finite, got {0}")]
    Rotate(f64),
    /// A rigidity delay is not between 0 and 60 seconds.
    #[error("--delay values must be between 0 and 60 seconds, got {0}")]
    Delay(f64),
    /// The output would be longer than [`crate::resample::MAX_RESAMPLED_FRAMES`] frames (a very
    /// slow speed): refused, never cut short.
    #[error(
        "the retimed clip would be {frames} frames ({seconds:.0} s at {fps} FPS), more than the {max} frames any output may have; use a faster --speed"
    )]
    TooLong {
        /// Frames the output would need.
        frames: u64,
        /// Its length, seconds.
        seconds: f64,
        /// The clip's rate.
        fps: f64,
        /// The limit.
        max: u64,
    },
}

/// Applies [`Retime`] to a clip: output frame `k` (at the same fps, `t = k / fps`) has joint `i`
/// from the source at time `K (t - delta_i)` (`delta_0 = 0`; before the start the first frame),
/// scaled and rotated. The output lasts `duration / K`. Errors name the bad parameter.
pub fn retime(clip: &Clip, r: &Retime) -> Result<Clip, RetimeError> {
    if !(r.speed.is_finite() && r.speed > 0.0 && r.speed <= 100.0) {
        return Err(RetimeError::Speed(r.speed));
    }
    if !(r.scale.is_finite() && r.scale.abs() <= 100.0) {
        return Err(RetimeError::Scale(r.scale));
    }
    if !r.rotate_deg.is_finite() {
        return Err(RetimeError::Rotate(r.rotate_deg));
    }
    if let Some(&d) = r.delays_s.iter().find(|d| !(d.is_finite() && **d >= 0.0 && **d <= 60.0)) {
        return Err(RetimeError::Delay(d));
    }
    let seconds = clip.duration_s() / r.speed;
    let frames = crate::resample::frames_needed(seconds, clip.fps);
    let max = crate::resample::MAX_RESAMPLED_FRAMES as u64;
    if frames > max {
        return Err(RetimeError::TooLong { frames, seconds, fps: clip.fps, max });
    }
    let count = crate::resample::frame_count(seconds, clip.fps);
    let frames = (0..count).map(|k| {
        let t = k as f64 / clip.fps;
        let mut j = [[0.0; 3]; JOINTS];
        for (i, o) in j.iter_mut().enumerate() {
            let delay = if i == 0 { 0.0 } else { r.delays_s[i - 1] };
            *o = clip.at_time(r.speed * (t - delay))[i];
        }
        shape_pose(&j, r.scale, r.rotate_deg)
    });
    Ok(Clip::from_joints(frames.collect::<Vec<_>>(), clip.fps))
}

/// Live field controls (section 6.3). `Copy`: the daemon swaps them by value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldControls {
    /// Force heading, degrees: propagation direction (1)(a); the bend follows it (1)(b).
    pub direction_deg: f64,
    /// Propagation speed `V_M`, m/s (2)(c).
    pub speed_m_s: f64,
    /// Motion speed `K` (time step multiplier) (2)(d).
    pub time_step: f64,
    /// Motion scale (2)(e).
    pub scale: f32,
    /// Rigidity delays `delta_1..delta_3`, seconds (3).
    pub delays_s: [f64; 3],
}

impl Default for FieldControls {
    fn default() -> Self {
        FieldControls { direction_deg: 0.0, speed_m_s: 1.0, time_step: 1.0, scale: 1.0, delays_s: [0.0; 3] }
    }
}

/// Keyboard controls of `frond control` (section 6.3, "Control interface").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlKey {
    /// Force towards the left of the screen (-X, heading 180).
    Left,
    /// Force towards the right (+X, heading 0).
    Right,
    /// Force away from the viewer (-Z, heading 90).
    Up,
    /// Force towards the viewer (+Z, heading 270).
    Down,
    /// Stronger force (`+`).
    Stronger,
    /// Weaker force (`-`).
    Weaker,
}

/// Limits of the live controls, so a held key cannot run away.
pub const TIME_STEP_RANGE: (f64, f64) = (0.25, 4.0);
/// Limits of the live motion scale.
pub const SCALE_RANGE: (f32, f32) = (0.25, 3.0);
/// Limits of the live propagation speed, m/s.
pub const SPEED_RANGE_M_S: (f64, f64) = (0.05, 20.0);
/// Factor one `+`/`-` press applies to `V_M` and the time step (the scale gets its square root).
pub const STRENGTH_STEP: f64 = 1.25;

impl FieldControls {
    fn strengthen(&mut self, f: f64) {
        self.speed_m_s = (self.speed_m_s * f).clamp(SPEED_RANGE_M_S.0, SPEED_RANGE_M_S.1);
        self.time_step = (self.time_step * f).clamp(TIME_STEP_RANGE.0, TIME_STEP_RANGE.1);
        self.scale = (self.scale * f.sqrt() as f32).clamp(SCALE_RANGE.0, SCALE_RANGE.1);
    }

    /// Applies a key: arrows set the force direction, `+`/`-` its strength (propagation speed,
    /// motion speed and, more gently, motion scale).
    pub fn key(&mut self, k: ControlKey) {
        match k {
            ControlKey::Right => self.direction_deg = 0.0,
            ControlKey::Up => self.direction_deg = 90.0,
            ControlKey::Left => self.direction_deg = 180.0,
            ControlKey::Down => self.direction_deg = 270.0,
            ControlKey::Stronger => self.strengthen(STRENGTH_STEP),
            ControlKey::Weaker => self.strengthen(1.0 / STRENGTH_STEP),
        }
    }

    /// Applies a swipe (section 6.3: "swipe direction -> direction of external forces, speed of
    /// swiping -> speed of motion propagation and speed of motion, length of swiping -> scale of
    /// motion"): `direction_deg = swipe.direction_deg`; `V_M = base_speed_m_s * v / 200 deg/s`;
    /// `K = v / 200 deg/s`; `scale = length / 45 deg`; each clamped to its range.
    pub fn swipe(&mut self, s: &Swipe, base_speed_m_s: f64) {
        let v = s.speed_deg_s / 200.0;
        self.direction_deg = s.direction_deg;
        self.speed_m_s = (base_speed_m_s * v).clamp(SPEED_RANGE_M_S.0, SPEED_RANGE_M_S.1);
        self.time_step = v.clamp(TIME_STEP_RANGE.0, TIME_STEP_RANGE.1);
        self.scale = ((s.length_deg / 45.0) as f32).clamp(SCALE_RANGE.0, SCALE_RANGE.1);
    }
}

/// A recognised swipe of the wrist.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Swipe {
    /// Heading the swipe points to (the bend direction of the wrist motion), degrees in [0, 360).
    pub direction_deg: f64,
    /// Mean angular speed, degrees per second.
    pub speed_deg_s: f64,
    /// Angle swept, degrees.
    pub length_deg: f64,
}

/// Thresholds of [`SwipeDetector`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwipeParams {
    /// A swipe starts when the smoothed wrist bend speed exceeds this, deg/s.
    pub start_deg_s: f64,
    /// It ends when the speed falls below this, deg/s.
    pub end_deg_s: f64,
    /// Shorter motions are not swipes, degrees.
    pub min_length_deg: f64,
    /// Longer motions are not swipes (slow authoring moves), seconds.
    pub max_duration_s: f64,
    /// Cut-off of the speed smoothing, Hz.
    pub smoothing_hz: f64,
}

impl Default for SwipeParams {
    fn default() -> Self {
        SwipeParams {
            start_deg_s: 150.0,
            end_deg_s: 50.0,
            min_length_deg: 20.0,
            max_duration_s: 0.6,
            smoothing_hz: 15.0,
        }
    }
}

/// Recognises quick wrist swipes in the calibrated hand stream (the glove has no hand position,
/// so a swipe is a fast flick of the wrist's pitch/yaw). Feed every sample to
/// [`SwipeDetector::push`]; no allocation, `Copy`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwipeDetector {
    params: SwipeParams,
    prev: Option<(f64, [f64; 2])>,
    speed: f64,
    active: Option<(f64, [f64; 2])>,
}

impl SwipeDetector {
    /// A detector with the given thresholds.
    pub fn new(params: SwipeParams) -> Self {
        SwipeDetector { params, prev: None, speed: 0.0, active: None }
    }

    /// Feeds one sample; returns a swipe when one has just ended.
    pub fn push(&mut self, h: &HandSample) -> Option<Swipe> {
        let pos = [h.wrist_deg[0] as f64, h.wrist_deg[1] as f64];
        let Some((t0, p0)) = self.prev else {
            self.prev = Some((h.t, pos));
            return None;
        };
        let dt = h.t - t0;
        if !(dt > 0.0 && dt.is_finite() && pos.iter().all(|x| x.is_finite())) {
            return None;
        }
        self.prev = Some((h.t, pos));
        let raw = ((pos[0] - p0[0]).powi(2) + (pos[1] - p0[1]).powi(2)).sqrt() / dt;
        let alpha = crate::filter::smoothing_alpha(dt, self.params.smoothing_hz);
        self.speed += alpha * (raw - self.speed);
        match self.active {
            None if self.speed > self.params.start_deg_s => {
                self.active = Some((t0, p0));
                None
            }
            Some((ts, ps)) if self.speed < self.params.end_deg_s => {
                self.active = None;
                let duration = h.t - ts;
                let (dp, dy) = (pos[0] - ps[0], pos[1] - ps[1]);
                let length = (dp * dp + dy * dy).sqrt();
                if length < self.params.min_length_deg
                    || duration > self.params.max_duration_s
                    || duration <= 0.0
                {
                    return None;
                }
                // Bend vector (x, z) = (-dyaw, dpitch); heading d has direction (cos d, -sin d).
                let dir = (-dp).atan2(-dy).to_degrees().rem_euclid(360.0);
                Some(Swipe { direction_deg: dir, speed_deg_s: length / duration, length_deg: length })
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::joint_rotation;
    use glam::{Quat, Vec3};

    #[test]
    fn rotate_bend_by_hand() {
        // yaw -30 bends towards +X; rotated 90 deg about +Y it bends towards -Z: pitch -30.
        let r = rotate_bend([0.0, -30.0, 5.0], 90.0);
        assert!((r[0] + 30.0).abs() < 1e-5 && r[1].abs() < 1e-5 && r[2] == 5.0, "{r:?}");
        // For a single-axis bend and quarter turns it is exactly the geometric rotation of the
        // stem about +Y; otherwise it rotates the bend heading approximately (small angles).
        let tip = |a: [f32; 3]| joint_rotation(a) * Vec3::Y;
        let heading = |v: Vec3| v.z.atan2(v.x).to_degrees();
        for (angles, a, tol) in [
            ([40.0, 0.0, 0.0], 90.0, 1e-4),
            ([0.0, -25.0, 0.0], -90.0, 1e-4),
            ([30.0, 0.0, 0.0], 180.0, 1e-4),
            ([20.0, 0.0, 0.0], 35.0, 2.0),
        ] {
            let want = Quat::from_rotation_y((a as f32).to_radians()) * tip(angles);
            let got = tip(rotate_bend(angles, a));
            let dh = (heading(got) - heading(want) + 540.0).rem_euclid(360.0) - 180.0;
            assert!(dh.abs() < tol, "{angles:?} {a}: {got:?} vs {want:?}");
            if tol < 1.0 {
                assert!((got - want).length() < 1e-5, "{got:?} vs {want:?}");
            }
        }
    }

    fn ramp() -> Clip {
        // 10 FPS, joint angles all equal to 10 t (t in frames/10): 0, 1, ..., 10 over 1 s.
        Clip::from_joints((0..=10).map(|k| [[k as f32; 3]; 4]), 10.0)
    }

    #[test]
    fn retime_by_hand() {
        // Speed 2: half as long (6 frames), frame k samples source time 0.2 k -> value 2 k.
        let c = retime(&ramp(), &Retime { speed: 2.0, ..Default::default() }).unwrap();
        assert_eq!(c.len(), 6);
        assert_eq!(c.frames[3].joints_deg[2][1], 6.0);
        // Scale 0.5 and rigidity delays 0.1, 0.2, 0.3 s at speed 1: frame 5 (t = 0.5) has
        // joint 0 = 5, joint 1 = 4, joint 2 = 3, joint 3 = 2, all halved; frame 0 clamps to 0.
        let c =
            retime(&ramp(), &Retime { scale: 0.5, delays_s: [0.1, 0.2, 0.3], ..Default::default() }).unwrap();
        let f = c.frames[5].joints_deg;
        assert_eq!([f[0][0], f[1][0], f[2][0], f[3][0]], [2.5, 2.0, 1.5, 1.0]);
        assert_eq!(c.frames[0].joints_deg, [[0.0; 3]; 4]);
        // Rotate 180: pitch and yaw flip sign, roll stays.
        let c = retime(&ramp(), &Retime { rotate_deg: 180.0, ..Default::default() }).unwrap();
        let f = c.frames[4].joints_deg[1];
        assert!((f[0] + 4.0).abs() < 1e-5 && (f[1] + 4.0).abs() < 1e-5 && f[2] == 4.0, "{f:?}");
        // 1 s at 10^-9 speed: 10^9 s, far past the cap: refused, not cut short.
        let e = retime(&ramp(), &Retime { speed: 1e-9, ..Default::default() }).unwrap_err();
        assert!(matches!(e, RetimeError::TooLong { max, .. } if max == 1 << 24), "{e}");
        let e = retime(&ramp(), &Retime { speed: 0.0, ..Default::default() }).unwrap_err();
        assert_eq!(e, RetimeError::Speed(0.0));
        assert_eq!(e.to_string(), "--speed must be in (0, 100], got 0");
        let e = retime(&ramp(), &Retime { delays_s: [0.0, -1.0, 0.0], ..Default::default() }).unwrap_err();
        assert_eq!(e, RetimeError::Delay(-1.0));
        assert!(e.to_string().contains("--delay"), "{e}");
    }

    #[test]
    fn keys_set_direction_and_strength_within_limits() {
        let mut c = FieldControls::default();
        c.key(ControlKey::Up);
        assert_eq!(c.direction_deg, 90.0);
        c.key(ControlKey::Left);
        assert_eq!(c.direction_deg, 180.0);
        c.key(ControlKey::Stronger);
        assert!((c.speed_m_s - 1.25).abs() < 1e-12 && (c.time_step - 1.25).abs() < 1e-12);
        for _ in 0..100 {
            c.key(ControlKey::Stronger);
        }
        assert_eq!((c.time_step, c.scale), (4.0, 3.0));
        for _ in 0..100 {
            c.key(ControlKey::Weaker);
        }
        assert_eq!((c.time_step, c.scale, c.speed_m_s), (0.25, 0.25, 0.05));
    }

    fn flick(detector: &mut SwipeDetector, dpitch: f32, dyaw: f32) -> Option<Swipe> {
        // 1 kHz: 300 ms still, a 100 ms flick (linear), 300 ms still.
        let mut found = None;
        for k in 0..700 {
            let t = k as f64 / 1000.0;
            let u = ((t - 0.3) / 0.1).clamp(0.0, 1.0) as f32;
            let h = HandSample { t, wrist_deg: [dpitch * u, dyaw * u, 0.0], thumb_deg: [0.0; 3] };
            if let Some(s) = detector.push(&h) {
                assert!(found.is_none(), "one flick, one swipe");
                found = Some(s);
            }
        }
        found
    }

    #[test]
    fn swipes_are_recognised_with_direction_speed_and_length() {
        let mut d = SwipeDetector::new(SwipeParams::default());
        // Yaw -40 deg in 0.1 s: the wrist bends towards +X -> heading 0, ~400 deg/s, ~40 deg.
        let s = flick(&mut d, 0.0, -40.0).unwrap();
        assert!(s.direction_deg < 2.0 || s.direction_deg > 358.0, "{s:?}");
        assert!((s.length_deg - 40.0).abs() < 8.0 && s.speed_deg_s > 250.0, "{s:?}");
        // Pitch +40: bends towards +Z -> heading 270.
        let s = flick(&mut SwipeDetector::new(SwipeParams::default()), 40.0, 0.0).unwrap();
        assert!((s.direction_deg - 270.0).abs() < 2.0, "{s:?}");
        // A slow authoring move (40 deg over 2 s) is not a swipe.
        let mut d = SwipeDetector::new(SwipeParams::default());
        assert!((0..3000).all(|k| {
            let t = k as f64 / 1000.0;
            d.push(&HandSample { t, wrist_deg: [0.0, (t as f32).min(2.0) * 20.0, 0.0], thumb_deg: [0.0; 3] })
                .is_none()
        }));
        // Mapping onto the controls.
        let mut c = FieldControls::default();
        c.swipe(&Swipe { direction_deg: 45.0, speed_deg_s: 400.0, length_deg: 90.0 }, 1.5);
        assert_eq!((c.direction_deg, c.speed_m_s, c.time_step, c.scale), (45.0, 3.0, 2.0, 2.0));
    }
}
