//! Tests of [`super`]: landmarks made here by forward kinematics of known wrist and thumb
//! angles (a second implementation: the palm's direction and normal are solved from the angles,
//! the thumb is bent joint by joint with Rodrigues' formula), as world landmarks and projected
//! through a pinhole camera with noise; the angles must come back within 1 degree, for either
//! hand. Degenerate landmarks must give an error, never an angle.

use super::*;
use proptest::prelude::*;

type V = [f64; 3];

fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V, k: f64) -> V {
    a.map(|c| c * k)
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V, b: V) -> V {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn unit(a: V) -> V {
    scale(a, 1.0 / dot(a, a).sqrt())
}
/// Rodrigues: `v` turned by `angle` about the unit `axis`.
fn rotate(v: V, axis: V, angle: f64) -> V {
    let (s, c) = angle.sin_cos();
    add(add(scale(v, c), scale(cross(axis, v), s)), scale(axis, dot(axis, v) * (1.0 - c)))
}

/// What the hand does: wrist pitch, yaw, roll and the thumb's bends, degrees.
#[derive(Debug, Clone, Copy)]
struct Pose {
    wrist: [f64; 3],
    bends: [f64; 3],
    /// Hand-frame vectors the thumb's joints bend about (made perpendicular to each bone).
    hinges: [V; 3],
}

/// The palm's direction and normal in the Leap device frame with the Leap SDK's pitch, yaw and
/// roll, solved from them: `d` along `(tan yaw, tan pitch, -1)`; `n` along `(sin roll, -cos
/// roll, z)` with `z` the one value that makes it perpendicular to `d`.
fn palm_in_device(pitch: f64, yaw: f64, roll: f64) -> (V, V) {
    let (tp, ty) = (pitch.to_radians().tan(), yaw.to_radians().tan());
    let (sr, cr) = roll.to_radians().sin_cos();
    (unit([ty, tp, -1.0]), unit([sr, -cr, sr * ty - cr * tp]))
}

/// 21 landmarks (metres, selfie view) of a hand in `pose`, its wrist at `at`.
fn hand(pose: &Pose, hand: Handedness, at: V) -> [V; LANDMARKS] {
    let [p, y, r] = pose.wrist;
    let (d, n) = palm_in_device(p, y, r);
    // Device frame (x, y, z) is the selfie view's (x, z, y).
    let (d, n) = ([d[0], d[2], d[1]], [n[0], n[2], n[1]]);
    // Towards the thumb: in the selfie view a right hand held up palm to the camera has its
    // thumb on the user's left (-x), a left hand on the user's right.
    let thumbward = match hand {
        Handedness::Right => scale(cross(d, n), -1.0),
        Handedness::Left => cross(d, n),
    };
    // A hand frame point: `along` the palm, `side` towards the thumb, `out` of the palm.
    let at_hand = |along: f64, side: f64, out: f64| {
        add(at, add(add(scale(d, along), scale(thumbward, side)), scale(n, out)))
    };
    let mut pts = [[0.0; 3]; LANDMARKS];
    pts[0] = at_hand(0.0, 0.0, 0.0);
    // Fingers, straight along the palm: knuckle (along, side), arched out of the palm alike.
    let fingers = [(0.085, 0.025), (0.09, 0.0), (0.085, -0.018), (0.075, -0.035)];
    for (f, &(along, side)) in fingers.iter().enumerate() {
        for j in 0..4 {
            pts[5 + 4 * f + j] = at_hand(along + 0.03 * j as f64, side, if f == 1 { 0.0 } else { -0.008 });
        }
    }
    // Thumb: the CMC near the wrist, then three bones each bent at its joint.
    pts[1] = at_hand(0.02, 0.025, -0.01);
    let mut dir = unit(add(pts[1], scale(pts[0], -1.0)));
    for (k, len) in [0.045, 0.032, 0.028].into_iter().enumerate() {
        let h = pose.hinges[k];
        let h = add(add(scale(d, h[0]), scale(thumbward, h[1])), scale(n, h[2]));
        let axis = unit(add(h, scale(dir, -dot(h, dir))));
        dir = rotate(dir, axis, pose.bends[k].to_radians());
        pts[2 + k] = add(pts[1 + k], scale(dir, len));
    }
    pts
}

/// A small noise in `[-1, 1]`, repeatable from `seed`.
fn jitter(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// An HD webcam: 1280x720, 65 degrees across.
const CAMERA: CameraModel = CameraModel { width_px: 1280, height_px: 720, hfov_deg: 65.0 };

/// The image landmarks of `pts` (selfie view, metres from the camera): each projected through
/// the pinhole, with up to `px` pixels of noise; z the depth relative to the wrist in the x
/// scale (MediaPipe's), with the same noise.
fn project(pts: &[V; LANDMARKS], px: f64, seed: &mut u64) -> [V; LANDMARKS] {
    let (w, h) = (1280.0, 720.0);
    let f = w / 2.0 / (65f64.to_radians() / 2.0).tan();
    let wrist_z = pts[0][2];
    pts.map(|[x, y, z]| {
        let u = w / 2.0 + f * x / z + px * jitter(seed);
        let v = h / 2.0 + f * y / z + px * jitter(seed);
        let dz = (z - wrist_z) * f / wrist_z / w + px / w * jitter(seed);
        [u / w, v / h, dz]
    })
}

fn assert_close(got: &HandSample, pose: &Pose, tol: f64) {
    let want = pose.wrist.iter().chain(&pose.bends);
    for (i, (g, w)) in got.wrist_deg.iter().chain(&got.thumb_deg).zip(want).enumerate() {
        assert!((f64::from(*g) - w).abs() <= tol, "angle {i}: got {g}, want {w} ({got:?}, {pose:?})");
    }
}

const HINGES: [V; 3] = [[0.2, -0.5, 1.0], [0.0, -0.3, 1.0], [0.1, -0.2, 1.0]];

#[test]
fn the_rest_pose_is_zero_and_tilts_are_worked_out_by_hand() {
    let rest = Pose { wrist: [0.0; 3], bends: [20.0, 15.0, 10.0], hinges: HINGES };
    let pts = hand(&rest, Handedness::Right, [0.0, 0.0, 0.5]);
    // Held up palm to the camera: fingers up (-y), the thumb on the user's left (-x).
    assert!(pts[9][1] < pts[0][1] && pts[5][0] < pts[17][0], "{pts:?}");
    let s = hand_sample(
        &HandPoints::world(&pts.map(|p| add(p, [0.0, 0.0, -0.5]))).unwrap(),
        Handedness::Right,
        2.5,
    )
    .unwrap();
    assert_eq!(s.t, 2.5);
    assert!(s.wrist_deg.iter().all(|a| a.abs() < 1e-4), "{s:?}");
    // Fingers tipped 30 degrees back towards the user (+z): pitch 30, by hand.
    let mut tipped = pts;
    let c = 30f64.to_radians();
    for p in &mut tipped {
        let (y, z) = (p[1], p[2] - 0.5);
        *p = [p[0], y * c.cos() + z * c.sin(), -y * c.sin() + z * c.cos()];
    }
    let s = hand_sample(&HandPoints::world(&tipped).unwrap(), Handedness::Right, 0.0).unwrap();
    assert!((s.wrist_deg[0] - 30.0).abs() < 1e-3 && s.wrist_deg[1].abs() < 1e-3, "{s:?}");
    // The same hand called a left hand has its palm the other way: rolled half a turn.
    let s = hand_sample(
        &HandPoints::world(&pts.map(|p| add(p, [0.0, 0.0, -0.5]))).unwrap(),
        Handedness::Left,
        0.0,
    )
    .unwrap();
    assert!((s.wrist_deg[2].abs() - 180.0).abs() < 1e-3, "{s:?}");
}

#[test]
fn either_hand_comes_back_from_world_and_image_landmarks_within_a_degree() {
    let mut seed = 7;
    for hand_is in [Handedness::Left, Handedness::Right] {
        for wrist in [[0.0, 0.0, 0.0], [35.0, -20.0, 40.0], [-40.0, 30.0, -60.0], [10.0, 45.0, 85.0]] {
            let pose = Pose { wrist, bends: [25.0, 40.0, 55.0], hinges: HINGES };
            let pts = hand(&pose, hand_is, [0.03, 0.06, 0.45]);
            // World landmarks about the hand's centre, 0.1 mm of noise.
            let world =
                pts.map(|p| p.map(|c| c + 1e-4 * jitter(&mut seed))).map(|p| add(p, [-0.03, -0.1, -0.45]));
            let s = hand_sample(&HandPoints::world(&world).unwrap(), hand_is, 1.0).unwrap();
            assert_close(&s, &pose, 1.0);
            // Through the camera, 0.2 pixels of noise.
            let image = project(&pts, 0.2, &mut seed);
            let s = hand_sample(&HandPoints::image(&image, &CAMERA).unwrap(), hand_is, 1.0).unwrap();
            assert_close(&s, &pose, 1.0);
        }
    }
}

#[test]
fn a_left_hand_is_a_right_hand_mirrored() {
    let pose = Pose { wrist: [20.0, 25.0, 30.0], bends: [10.0, 30.0, 50.0], hinges: HINGES };
    let right = hand(&pose, Handedness::Right, [0.0, 0.0, 0.4]);
    let mirrored = right.map(|[x, y, z]| [-x, y, z - 0.4]);
    let s = hand_sample(&HandPoints::world(&mirrored).unwrap(), Handedness::Left, 0.0).unwrap();
    let want = Pose { wrist: [20.0, -25.0, -30.0], ..pose };
    assert_close(&s, &want, 1e-3);
}

#[test]
fn degenerate_landmarks_are_no_hand() {
    let pose = Pose { wrist: [10.0, 10.0, 10.0], bends: [20.0, 20.0, 20.0], hinges: HINGES };
    let good = hand(&pose, Handedness::Right, [0.0, 0.0, 0.0]);
    let sample = |pts: &[V; LANDMARKS]| hand_sample(&HandPoints::world(pts)?, Handedness::Right, 0.0);
    assert!(sample(&good).is_ok());
    let with = |i: usize, p: V| {
        let mut pts = good;
        pts[i] = p;
        pts
    };
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        assert_eq!(sample(&with(20, [0.0, bad, 0.0])), Err(LandmarkError::NotFinite { index: 20 }));
    }
    assert_eq!(sample(&with(3, [0.0, 5.0, 0.0])), Err(LandmarkError::OutOfRange { index: 3 }));
    // Zero-length bones: the thumb's IP on its MCP, the knuckles on one point, no palm.
    assert_eq!(sample(&with(3, good[2])), Err(LandmarkError::ShortBone { from: 2, to: 3 }));
    assert_eq!(sample(&with(17, good[5])), Err(LandmarkError::ShortBone { from: 17, to: 5 }));
    assert_eq!(sample(&with(9, good[0])), Err(LandmarkError::ShortBone { from: 0, to: 9 }));
    assert_eq!(sample(&[[0.0; 3]; LANDMARKS]), Err(LandmarkError::ShortBone { from: 0, to: 9 }));
    // Collinear: the knuckles in line with the wrist and the middle knuckle.
    let on_line = |k: f64| scale(good[9], k);
    let mut flat = with(5, on_line(1.2));
    flat[17] = on_line(0.8);
    assert_eq!(sample(&flat), Err(LandmarkError::FlatPalm));
    // Fingers pointing down, or level at the camera.
    let down = good.map(|[x, y, z]| [x, -y, z]);
    assert_eq!(sample(&down), Err(LandmarkError::FingersDown));
    assert_eq!(
        hand_sample(&HandPoints::world(&good).unwrap(), Handedness::Right, f64::NAN),
        Err(LandmarkError::BadTime)
    );
    // Image landmarks behind the camera; cameras that are not cameras.
    let behind = with(0, [0.5, 0.5, -1.9]);
    assert_eq!(HandPoints::image(&behind, &CAMERA), Err(LandmarkError::OutOfRange { index: 0 }));
    let img = [[0.5; 3]; LANDMARKS];
    assert!(HandPoints::image(&img, &CameraModel { width_px: 0, ..CAMERA }).is_err());
    assert!(HandPoints::image(&img, &CameraModel { hfov_deg: f64::NAN, ..CAMERA }).is_err());
    assert!(HandPoints::image(&img, &CameraModel { hfov_deg: 180.0, ..CAMERA }).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Any pose a wrist and thumb can take comes back within a degree, through the camera (a
    /// hand 0.3 to 0.55 m away, 0.2 pixels of noise).
    #[test]
    fn any_pose_comes_back_within_a_degree(
        pitch in -60.0f64..60.0, yaw in -50.0f64..50.0, roll in -85.0f64..85.0,
        bends in proptest::array::uniform3(3.0f64..80.0),
        hinges in proptest::array::uniform3(proptest::array::uniform3(-0.4f64..0.4)),
        right in any::<bool>(), x in -0.1f64..0.1, y in -0.05f64..0.1, z in 0.3f64..0.55,
        seed in any::<u64>(),
    ) {
        let hinges = hinges.map(|h| add(h, [0.0, 0.0, 1.0]));
        let pose = Pose { wrist: [pitch, yaw, roll], bends, hinges };
        let which = if right { Handedness::Right } else { Handedness::Left };
        let pts = hand(&pose, which, [x, y, z]);
        let mut seed = seed;
        let image = project(&pts, 0.2, &mut seed);
        let s = hand_sample(&HandPoints::image(&image, &CAMERA).unwrap(), which, 0.0).unwrap();
        assert_close(&s, &pose, 1.0);
    }

    /// Any landmarks at all give an error or angles in their ranges, never a wild one.
    #[test]
    fn any_landmarks_give_no_hand_or_bounded_angles(
        raw in proptest::array::uniform21(proptest::array::uniform3(
            prop_oneof![any::<f64>(), -1.5f64..1.5, Just(0.0), Just(f64::NAN)])),
        image in any::<bool>(), right in any::<bool>(),
    ) {
        let which = if right { Handedness::Right } else { Handedness::Left };
        let points = if image { HandPoints::image(&raw, &CAMERA) } else { HandPoints::world(&raw) };
        if let Ok(s) = points.and_then(|p| hand_sample(&p, which, 0.0)) {
            prop_assert!(s.wrist_deg[..2].iter().all(|a| a.abs() < 90.0), "{s:?}");
            prop_assert!(s.wrist_deg[2].abs() <= 180.0, "{s:?}");
            prop_assert!(s.thumb_deg.iter().all(|a| (0.0..=180.0).contains(a)), "{s:?}");
        }
    }
}
