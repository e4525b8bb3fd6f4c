//! The webcam backend against a hostile helper: a script in frond-hands' place that prints a
//! good frame, then an oversized line, garbage, frames with a capture time in the future or too
//! old, NaN, a hand of no shape, an empty frame, another good frame, and dies with an error.
//! Only the good frames become samples; everything else is counted by reason; the helper is
//! started again. And the camera's preview picture: where the helper is told to keep it, named
//! in status, gone with the camera's last source.

use std::time::{Duration, Instant};

use super::WebcamSource;
use crate::report::DeviceSample;
use crate::source::HandSource;

const SCRIPT: &str = r#"#!/usr/bin/env python3
import json, sys, time
def now():
    return time.monotonic_ns() // 1000
world = [0.0, 0.08, 0.0, -0.03, 0.06, -0.01, -0.05, 0.03, -0.015, -0.06, 0.0, -0.02, -0.065, -0.02, -0.02]
for f, x in enumerate([-0.025, 0.0, 0.018, 0.035]):
    for j in range(4):
        world += [x, -0.01 - 0.03 * j - 0.002 * f, 0.0]
hand = {"side": "left", "score": 0.9, "world": world, "image": [0.5] * 63}
def frame(seq, t, hands):
    print(json.dumps({"v": 1, "seq": seq, "t_us": t, "model_us": 1000, "w": 640, "h": 480, "hands": hands}))
print(json.dumps({"v": 1, "hello": "frond-hands", "model": "a hostile test script"}))
frame(0, now(), [hand])
print("x" * 20000)
print("not json")
frame(1, now() + 10_000_000, [hand])
frame(2, now() - 5_000_000, [hand])
print(json.dumps({"v": 1, "seq": 3, "t_us": now(), "model_us": 1, "w": 640, "h": 480,
                  "hands": [dict(hand, world=[float("nan")] * 63)]}))
frame(4, now(), [dict(hand, world=[0.0] * 63)])
frame(5, now(), [])
frame(6, now(), [hand])
print(json.dumps({"v": 1, "error": "the camera was unplugged"}))
sys.stdout.flush()
sys.exit(1)
"#;

#[test]
fn a_hostile_helper_gives_only_its_good_frames_and_is_started_again() {
    let dir = std::env::temp_dir().join(format!("frond-webcam-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let script = dir.join("frond-hands");
    std::fs::write(&script, SCRIPT).unwrap();
    let chmod = std::process::Command::new("chmod").arg("+x").arg(&script).status().unwrap();
    assert!(chmod.success());
    let address = format!("webcam:{}?hand=left", dir.join("clip.mp4").display()).parse().unwrap();
    let mut src = WebcamSource::open_with_helper(&address, &script, None).unwrap();
    let mut buf = [DeviceSample::default(); 16];
    let mut samples = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    // Two good frames a run; the helper is started again after a second.
    while samples.len() < 4 && Instant::now() < deadline {
        let n = src.read_pending(&mut buf).unwrap();
        samples.extend_from_slice(&buf[..n]);
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(samples.iter().map(|s| s.device_seq).collect::<Vec<_>>(), [0, 6, 0, 6]);
    assert!(samples.iter().all(|s| s.raw.wrist_deg.iter().chain(&s.raw.thumb_deg).all(|a| a.is_finite())));
    let c = src.counters().snapshot();
    // Per run: the 20,000-byte line; "not json" and the NaN line; the future and the old time
    // and the hand of no shape.
    assert_eq!((c.reports, c.oversized, c.malformed, c.out_of_range), (4, 2, 4, 6), "{c:?}");
    let camera = src.stats();
    assert_eq!((camera.starts, camera.frames, camera.empty_frames), (2, 8, 2), "{camera:?}");
    drop(src);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A helper that writes down its arguments and keeps a picture where `--preview` says.
const PREVIEW_SCRIPT: &str = r#"#!/usr/bin/env python3
import json, os, sys, time
args = sys.argv[1:]
with open(os.path.join(os.path.dirname(sys.argv[0]), "args.json"), "w") as f:
    json.dump(args, f)
with open(args[args.index("--preview") + 1], "wb") as f:
    f.write(b"\xff\xd8\xff")
print(json.dumps({"v": 1, "hello": "frond-hands", "model": "a test script"}), flush=True)
time.sleep(30)
"#;

#[test]
fn the_helper_keeps_the_cameras_picture_where_status_names_it_until_the_camera_is_dropped() {
    let base = std::env::temp_dir().join(format!("frond-webcam-preview-{}", std::process::id()));
    std::fs::create_dir_all(&base).unwrap();
    let dir = &base;
    let script = dir.join("frond-hands");
    std::fs::write(&script, PREVIEW_SCRIPT).unwrap();
    let chmod = std::process::Command::new("chmod").arg("+x").arg(&script).status().unwrap();
    assert!(chmod.success());
    let socket_dir = dir.join("run");
    std::fs::create_dir(&socket_dir).unwrap();
    let clip = dir.join("clip.mp4");
    let left = format!("webcam:{}?hand=left", clip.display()).parse().unwrap();
    let right = format!("webcam:{}?hand=right", clip.display()).parse().unwrap();
    let a = WebcamSource::open_with_helper(&left, &script, Some(&socket_dir)).unwrap();
    let b = WebcamSource::open_with_helper(&right, &script, Some(&socket_dir)).unwrap();
    let args = dir.join("args.json");
    let deadline = Instant::now() + Duration::from_secs(10);
    while !args.exists() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    let args: Vec<String> = serde_json::from_str(&std::fs::read_to_string(&args).unwrap()).unwrap();
    // Both hands of the camera name its one picture, the one its helper was told to keep.
    let name = a.counters().camera.status().and_then(|s| s.preview).expect("status names the picture");
    assert!(frond_protocol::paths::is_camera_preview_name(&name), "{name}");
    assert_eq!(b.counters().camera.status().and_then(|s| s.preview).as_deref(), Some(name.as_str()));
    let picture = socket_dir.join(&name);
    let at = args.iter().position(|a| a == "--preview").expect("--preview given");
    assert_eq!(std::path::Path::new(&args[at + 1]), picture, "{args:?}");
    assert!(picture.is_file());
    // Without a directory the helper is asked for no picture, and status names none.
    let other = format!("webcam:{}", dir.join("other.mp4").display()).parse().unwrap();
    let c = WebcamSource::open_with_helper(&other, "/nonexistent/frond-hands", None).unwrap();
    assert_eq!(c.counters().camera.preview.get(), None);
    // The picture goes with the camera's last source.
    drop(a);
    assert!(picture.is_file(), "the right hand still reads the camera");
    drop(b);
    assert!(!picture.exists(), "no picture of a camera nobody reads");
    drop(c);
    let _ = std::fs::remove_dir_all(&base);
}
