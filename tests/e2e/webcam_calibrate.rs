//! Issue 47: `frond calibrate` on a camera's hand, like any source. The camera is a clip made
//! here from fingerpose 0.1.0's three photographs of a real hand (no curl, half curl, full
//! curl), each also turned 25 degrees either way in the picture's plane, a frame each, played
//! in a loop (0.3 s); so each step of the guided calibration sees every pose several times, even
//! when a busy machine slows the helper. The calibration
//! `frond calibrate` writes is checked against the angles a second implementation
//! (`webcam::expected_sample`) computes from the landmarks the model finds in the same clip.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use frond_e2e::{Daemon, wait_for};
use frond_formats::rig_toml::CalibrationText;
use frond_motion::calibration::Calibration;

use crate::webcam::{expected_sample, hands_venv, run_offline, use_static_helper, world_of};

/// Frames in the clip: 3 photographs x 3 turns.
const FRAMES: u32 = 9;

/// The clip (MJPG, 30 frames a second, 480x640), made by OpenCV.
fn poses_clip(dir: &Path) -> PathBuf {
    let out = dir.join("poses.avi");
    let assets = hands_venv().join("fingerpose/package/assets");
    let code = format!(
        "import cv2\n\
         w = cv2.VideoWriter({o:?}, cv2.VideoWriter_fourcc(*'MJPG'), 30, (480, 640))\n\
         for name in ('nocurl', 'halfcurl', 'fullcurl'):\n\
         \x20   im = cv2.resize(cv2.imread({a:?} + '/' + name + '.jpg'), (480, 640))\n\
         \x20   for turn in (0, -25, 25):\n\
         \x20       m = cv2.getRotationMatrix2D((240, 320), turn, 1.0)\n\
         \x20       frame = cv2.warpAffine(im, m, (480, 640), borderMode=cv2.BORDER_REPLICATE)\n\
         \x20       w.write(frame)\n\
         w.release()\n",
        o = out.to_str().unwrap(),
        a = assets.to_str().unwrap()
    );
    let ok = Command::new(hands_venv().join("bin/python")).args(["-c", &code]).status().unwrap();
    assert!(ok.success());
    out
}

#[test]
fn frond_calibrate_measures_a_hand_seen_by_a_camera() {
    let dir = tempfile::tempdir().unwrap();
    let clip = poses_clip(dir.path());
    // The clip's frames as the model sees them, and their angles by the second implementation.
    let lines = run_offline(&clip, FRAMES);
    let want: Vec<[f64; 6]> = lines[1..].iter().map(|f| expected_sample(&world_of(f), true)).collect();
    assert_eq!(want.len(), FRAMES as usize);
    let lo = |k: usize| want.iter().map(|w| w[k]).fold(f64::MAX, f64::min);
    let hi = |k: usize| want.iter().map(|w| w[k]).fold(f64::MIN, f64::max);
    for k in 0..6 {
        assert!(hi(k) - lo(k) > 6.0, "the clip moves every angle: axis {k} {} to {}", lo(k), hi(k));
    }

    use_static_helper(dir.path());
    let source = format!("webcam:{}?hand=left", clip.to_str().unwrap());
    let daemon = Daemon::start(dir.path(), &["--source", &source, "--rig", "flower", "--filter", "none"]);
    assert!(
        wait_for(Duration::from_secs(30), || daemon.status().source.reports >= FRAMES as u64),
        "{:?}",
        daemon.status().source
    );
    let file = dir.path().join("cam.toml");
    let out = daemon
        .frond()
        .args(["calibrate", "--user", "cam", "--yes", "--seconds-per-step", "1.5", "--apply", "-o"])
        .arg(&file)
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("applied to the running daemon"), "{stdout}");
    let cal = Calibration::from_toml_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    assert_eq!(cal.id, "cam");
    // The hand moved in every step (the clip loops all poses), and the tool says so.
    assert!(stderr.contains("moved") && stderr.contains("during the neutral step"), "{stderr}");
    let near = |a: f32, b: f64| (f64::from(a) - b).abs() < 0.02;
    for k in 0..3 {
        // The neutral is a mean of the poses seen: between the least and the most.
        for (v, axis) in [(cal.neutral_wrist_deg[k], k), (cal.neutral_thumb_deg[k], 3 + k)] {
            assert!(v as f64 > lo(axis) - 0.02 && (v as f64) < hi(axis) + 0.02, "{cal:?} axis {axis}");
        }
        // Each thumb range reaches the most bent pose of the clip (seed 000, Eq. 3).
        assert!(near(cal.neutral_thumb_deg[k] + cal.thumb_range_deg[k], hi(3 + k)), "{cal:?} {}", hi(3 + k));
    }
    // The wrist's extremes: every axis swept the clip's whole range in its step.
    let ranges = cal.wrist_range_deg.unwrap_or_else(|| panic!("wrist ranges stored: {stderr}"));
    for (k, [a, b]) in ranges.iter().enumerate() {
        assert!(near(*a, lo(k)) && near(*b, hi(k)), "wrist axis {k}: {ranges:?} vs {} to {}", lo(k), hi(k));
    }
    assert_eq!(daemon.status().calibration_id, "cam");
}
