//! A camera hand tracker's 21 hand landmarks as a frond hand sample (issue 47): the wrist's
//! pitch, yaw and roll from the palm's orientation and the thumb's three joint bends, the
//! measurements seed 000 drives a plant with (section 5.1: "the wrist's motions and the thumb
//! joints' bending angles"; Eq. 2-4 map them). Pure: landmarks in, a [`HandSample`] or a
//! [`LandmarkError`] out.
//!
//! **Layout.** The 21 points of MediaPipe Hands ([`landmark`]): the wrist, the thumb's CMC, MCP,
//! IP and tip, then the index, middle, ring and little finger's MCP, PIP, DIP and tip.
//!
//! **Frame: the selfie view.** Points are what the model returns for a camera frame mirrored
//! left-right (as MediaPipe's handedness expects, and as the operator sees themself): +x the
//! user's right, +y down, +z away from the camera. Either metric world landmarks
//! ([`HandPoints::world`], metres about the hand's centre) or image landmarks
//! ([`HandPoints::image`]: x, y normalised to the frame, z the depth relative to the wrist in
//! the x scale), which are unprojected through a pinhole [`CameraModel`] first.
//!
//! **Angles.** The palm's direction `d` runs from the wrist to the middle finger's MCP, its
//! normal `n` points out of the palm (`d` crossed with the index-to-little-finger knuckle line,
//! in the order that makes it point out of the palm for the given [`Handedness`]: the two hands
//! are mirror images). The rest pose is the hand held up, palm to the camera, fingers up: there
//! pitch, yaw and roll are 0. The device frame turns that pose into the Leap Motion's rest pose
//! (palm down, fingers forward), so that the angles are the Leap SDK's own ([`palm_angles_deg`],
//! which the Leap backend uses too): pitch positive as the fingers tip back towards the user
//! (the wrist extends), yaw positive as they lean to the user's right, roll positive as the palm
//! turns to the user's right. The thumb's bends are the angles between successive segments of
//! the chain wrist, CMC, MCP, IP, tip ([`bend_deg`]): g1 at the CMC, g2 at the MCP, g3 at the IP.
//!
//! **No wild angles.** Every coordinate is checked finite and in range, every segment used must
//! have a length, the palm must span a plane, and the fingers must point up out of the wrist by
//! at least [`MIN_UPWARD`] (pitch and yaw turn over where they are level): otherwise the answer is
//! a [`LandmarkError`] ("no hand"), never an angle.

use glam::DVec3;

use crate::HandSample;

/// Landmarks of a hand.
pub const LANDMARKS: usize = 21;

/// Indices of the 21 landmarks (MediaPipe Hands' layout).
pub mod landmark {
    /// The wrist.
    pub const WRIST: usize = 0;
    /// The thumb's carpometacarpal joint.
    pub const THUMB_CMC: usize = 1;
    /// The thumb's metacarpophalangeal joint.
    pub const THUMB_MCP: usize = 2;
    /// The thumb's interphalangeal joint.
    pub const THUMB_IP: usize = 3;
    /// The thumb's tip.
    pub const THUMB_TIP: usize = 4;
    /// The index finger's knuckle (MCP); its PIP, DIP and tip are 6, 7, 8.
    pub const INDEX_MCP: usize = 5;
    /// The middle finger's knuckle; its PIP, DIP and tip are 10, 11, 12.
    pub const MIDDLE_MCP: usize = 9;
    /// The ring finger's knuckle; its PIP, DIP and tip are 14, 15, 16.
    pub const RING_MCP: usize = 13;
    /// The little finger's knuckle; its PIP, DIP and tip are 18, 19, 20.
    pub const PINKY_MCP: usize = 17;
}

/// World landmarks farther than this from their origin (metres) are refused: a hand is about
/// 0.2 m long and MediaPipe centres its world landmarks on it.
pub const MAX_WORLD_M: f64 = 1.0;
/// Image landmarks' x and y may lie a frame outside the image (a hand half out of view is
/// still tracked), no farther: `[-1, 2]`.
pub const IMAGE_XY_RANGE: (f64, f64) = (-1.0, 2.0);
/// Image landmarks' relative depth, at most this in the x scale either way.
pub const MAX_IMAGE_Z: f64 = 2.0;
/// A segment shorter than this share of the palm's length (wrist to middle knuckle) counts as
/// no length.
pub const MIN_BONE_FRACTION: f64 = 0.05;
/// The palm's length below this (in the input's units after unprojection) is no palm.
pub const MIN_PALM: f64 = 1e-4;
/// The knuckle line must make at least this angle with the palm's direction (sine), or the
/// palm spans no plane.
pub const MIN_SPREAD_SIN: f64 = 0.17;
/// The fingers must point up out of the wrist by at least this (the sine of about 5.7°): level
/// or lower, pitch and yaw turn over.
pub const MIN_UPWARD: f64 = 0.1;

/// Which hand the landmarks are of (the model's handedness in the selfie view).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Handedness {
    /// The user's left hand.
    Left,
    /// The user's right hand.
    Right,
}

/// Why landmarks give no hand sample.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum LandmarkError {
    /// A coordinate is NaN or infinite.
    #[error("landmark {index} is not a finite number")]
    NotFinite {
        /// The landmark.
        index: usize,
    },
    /// A coordinate is outside the range a tracked hand can have.
    #[error("landmark {index} is out of range")]
    OutOfRange {
        /// The landmark.
        index: usize,
    },
    /// A segment the angles need has no length (two landmarks on one point).
    #[error("landmarks {from} and {to} are on one point")]
    ShortBone {
        /// Its first landmark.
        from: usize,
        /// Its second landmark.
        to: usize,
    },
    /// The index and little finger knuckles lie in line with the wrist and middle knuckle.
    #[error("the palm spans no plane (its knuckles are in line with the wrist)")]
    FlatPalm,
    /// The fingers point level with the wrist or down, where pitch and yaw turn over.
    #[error("the fingers do not point up out of the wrist")]
    FingersDown,
    /// The sample's time is not a finite number of seconds.
    #[error("the time is not a finite number")]
    BadTime,
    /// The camera model is not a camera.
    #[error("camera: {0}")]
    BadCamera(&'static str),
}

/// A pinhole camera, for unprojecting image landmarks: the frame's size and its horizontal
/// field of view (a laptop webcam's is 60° to 80°).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraModel {
    /// Frame width, pixels.
    pub width_px: u32,
    /// Frame height, pixels.
    pub height_px: u32,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f64,
}

impl CameraModel {
    /// The focal length in pixels, once the model is checked (sizes 1 to 16384, field of view
    /// 20° to 170°).
    pub fn focal_px(&self) -> Result<f64, LandmarkError> {
        let sizes = 1..=16384;
        if !sizes.contains(&self.width_px) || !sizes.contains(&self.height_px) {
            return Err(LandmarkError::BadCamera("frame size must be 1 to 16384 pixels"));
        }
        if !(20.0..=170.0).contains(&self.hfov_deg) {
            return Err(LandmarkError::BadCamera("horizontal field of view must be 20 to 170 degrees"));
        }
        Ok(f64::from(self.width_px) / 2.0 / (self.hfov_deg.to_radians() / 2.0).tan())
    }
}

/// 21 checked points of one hand in the selfie view's 3D frame (any unit: angles only).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandPoints {
    points: [DVec3; LANDMARKS],
}

/// Checks each landmark finite and in `range` per axis.
fn checked(raw: &[[f64; 3]; LANDMARKS], range: [(f64, f64); 3]) -> Result<[DVec3; LANDMARKS], LandmarkError> {
    for (index, p) in raw.iter().enumerate() {
        if p.iter().any(|c| !c.is_finite()) {
            return Err(LandmarkError::NotFinite { index });
        }
        if p.iter().zip(range).any(|(c, (lo, hi))| !(lo..=hi).contains(c)) {
            return Err(LandmarkError::OutOfRange { index });
        }
    }
    Ok(raw.map(DVec3::from_array))
}

impl HandPoints {
    /// World landmarks (metres, the selfie view's axes), each coordinate within
    /// [`MAX_WORLD_M`].
    pub fn world(raw: &[[f64; 3]; LANDMARKS]) -> Result<HandPoints, LandmarkError> {
        let r = (-MAX_WORLD_M, MAX_WORLD_M);
        Ok(HandPoints { points: checked(raw, [r; 3])? })
    }

    /// Image landmarks (x, y normalised to the frame, z the depth relative to the wrist in the
    /// x scale, smaller nearer), unprojected through `camera`: a point's depth is the wrist's
    /// times `1 + z * width / focal`, and its x and y follow from its pixel through the pinhole.
    /// The result is in units of the wrist's depth (angles need no scale).
    pub fn image(raw: &[[f64; 3]; LANDMARKS], camera: &CameraModel) -> Result<HandPoints, LandmarkError> {
        let focal = camera.focal_px()?;
        let xy = IMAGE_XY_RANGE;
        let points = checked(raw, [xy, xy, (-MAX_IMAGE_Z, MAX_IMAGE_Z)])?;
        let (w, h) = (f64::from(camera.width_px), f64::from(camera.height_px));
        let mut out = [DVec3::ZERO; LANDMARKS];
        for (index, (p, o)) in points.iter().zip(&mut out).enumerate() {
            let depth = 1.0 + p.z * w / focal;
            if depth < 0.1 {
                // At or behind the camera: not a hand in front of it.
                return Err(LandmarkError::OutOfRange { index });
            }
            let (u, v) = (p.x * w - w / 2.0, p.y * h - h / 2.0);
            *o = DVec3::new(u / focal * depth, v / focal * depth, depth);
        }
        Ok(HandPoints { points: out })
    }

    /// The points, in the selfie view's frame.
    pub fn points(&self) -> [[f64; 3]; LANDMARKS] {
        self.points.map(|p| p.to_array())
    }
}

/// Wrist `[pitch, yaw, roll]`, degrees, from the palm's direction (towards the fingers) and
/// normal (out of the palm), both in the Leap Motion's frame (+x right, +y up, +z towards the
/// user; the rest pose palm down, fingers forward): the Leap SDK's definitions,
/// `atan2(d.y, -d.z)`, `atan2(d.x, -d.z)`, `atan2(n.x, -n.y)`.
pub fn palm_angles_deg(direction: [f64; 3], palm_normal: [f64; 3]) -> [f32; 3] {
    let [dx, dy, dz] = direction;
    let [nx, ny, _] = palm_normal;
    [dy.atan2(-dz), dx.atan2(-dz), nx.atan2(-ny)].map(|a| a.to_degrees() as f32)
}

/// The angle between two directions, degrees (0 when they agree): a joint's bend between the
/// bone before it and the bone after it. Either may be of any non-zero length.
pub fn bend_deg(a: [f64; 3], b: [f64; 3]) -> f32 {
    let (a, b) = (DVec3::from_array(a).normalize(), DVec3::from_array(b).normalize());
    a.dot(b).clamp(-1.0, 1.0).acos().to_degrees() as f32
}

/// The selfie view's frame to the Leap Motion's device frame, so that the camera's rest pose
/// (palm to the camera, fingers up) is the Leap's (palm down, fingers forward): (x, z, y).
fn to_device(v: DVec3) -> [f64; 3] {
    [v.x, v.z, v.y]
}

/// The segment from landmark `from` to `to`, refused when shorter than `min`.
fn segment(p: &[DVec3; LANDMARKS], from: usize, to: usize, min: f64) -> Result<DVec3, LandmarkError> {
    let v = p[to] - p[from];
    if v.length() < min { Err(LandmarkError::ShortBone { from, to }) } else { Ok(v) }
}

/// The hand sample of `points` (a `hand` hand) at time `t_s` seconds: wrist angles from the
/// palm, thumb bends from the thumb's chain; an error instead of any angle from landmarks that
/// make no hand.
pub fn hand_sample(points: &HandPoints, hand: Handedness, t_s: f64) -> Result<HandSample, LandmarkError> {
    use landmark::*;
    if !t_s.is_finite() {
        return Err(LandmarkError::BadTime);
    }
    let p = &points.points;
    let palm = p[MIDDLE_MCP] - p[WRIST];
    if palm.length() < MIN_PALM {
        return Err(LandmarkError::ShortBone { from: WRIST, to: MIDDLE_MCP });
    }
    let min = palm.length() * MIN_BONE_FRACTION;
    let d = palm.normalize();
    let across = segment(p, PINKY_MCP, INDEX_MCP, min)?;
    let side = d.cross(across);
    if side.length() < MIN_SPREAD_SIN * across.length() {
        return Err(LandmarkError::FlatPalm);
    }
    // Out of the palm: d x across for a right hand, across x d for a left (mirror images).
    let n = match hand {
        Handedness::Right => side,
        Handedness::Left => -side,
    }
    .normalize();
    if -d.y < MIN_UPWARD {
        return Err(LandmarkError::FingersDown);
    }
    let chain = [WRIST, THUMB_CMC, THUMB_MCP, THUMB_IP, THUMB_TIP];
    let mut bones = [DVec3::ZERO; 4];
    for (i, bone) in bones.iter_mut().enumerate() {
        *bone = segment(p, chain[i], chain[i + 1], min)?;
    }
    Ok(HandSample {
        t: t_s,
        wrist_deg: palm_angles_deg(to_device(d), to_device(n)),
        thumb_deg: std::array::from_fn(|i| bend_deg(bones[i].to_array(), bones[i + 1].to_array())),
    })
}

#[cfg(test)]
#[path = "hand_landmarks_tests.rs"]
mod tests;
