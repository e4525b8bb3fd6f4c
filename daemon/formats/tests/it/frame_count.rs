//! Every fixed-rate path keeps a take's frame count through a JSONL round trip: `n` frames at
//! `fps` whose times carry six decimals (what `frond take export --jsonl` prints for a recorded
//! take) are exported, imported back, then resampled (`take resample` / `export --fps`), turned
//! into a clip (`retime`, `loop`, `field`, `guided`, `align`) and retimed at speed 1; each gives
//! `n` frames, for every length 1..=400 at 24, 25, 30 and 60 FPS.

use frond_formats::import::{ImportKind, import_jsonl};
use frond_formats::write_pose_line;
use frond_motion::calibration::CalibrationParams;
use frond_motion::clip::{Clip, frame_count};
use frond_motion::controls::{Retime, retime};
use frond_motion::edit::resample_frames;
use frond_motion::layers::{GLOBAL_LAYER, Take};
use frond_motion::{FilterSpec, Mapper, MappingParams, PoseFrame, TakeHeader, resample};

/// Seconds rounded to the microsecond, written with six decimals and read back.
fn six_decimals(t: f64) -> f64 {
    format!("{t:.6}").parse().unwrap()
}

fn exported(n: usize, fps: f64) -> String {
    let mut text = String::new();
    for k in 0..n {
        let t = six_decimals(k as f64 / fps);
        let v = (k as f32 * 0.7).sin() * 30.0;
        write_pose_line(&PoseFrame { t, joints_deg: [[v, -v, 0.5 * v]; 4] }, Some(k as u64), &mut text);
        text.push('\n');
    }
    text
}

fn header() -> TakeHeader {
    TakeHeader::offline("t", "grass", 30)
}

#[test]
fn the_issue_case_six_decimals_200_frames_at_30_fps() {
    let text = exported(200, 30.0);
    assert!(text.lines().last().unwrap().contains("\"t\":6.633333"), "{}", text.lines().last().unwrap());
    let poses: Vec<PoseFrame> = text.lines().map(|l| frond_formats::parse_pose_line(l).unwrap()).collect();
    assert_eq!(resample(&poses, 30.0).len(), 200);
    assert_eq!(frame_count(6.633333, 30.0), 200);
}

#[test]
fn export_import_resample_keeps_the_count_for_every_length() {
    let mut mapper = Mapper::new(
        MappingParams::default(),
        CalibrationParams::neutral([60.0, 70.0, 60.0]),
        FilterSpec::None,
    );
    let mut failures = Vec::new();
    for fps in [24.0, 25.0, 30.0, 60.0] {
        for n in 1..=400usize {
            let text = exported(n, fps);
            let frames = import_jsonl(&text, ImportKind::Pose, &mut mapper).unwrap();
            assert_eq!(frames.len(), n);
            let resampled = resample_frames(&frames, fps).unwrap();
            let mut take = Take::new(header());
            take.set_layer(GLOBAL_LAYER, None, frames.iter().copied());
            let clip: Clip = take.clip(GLOBAL_LAYER, fps);
            let retimed = retime(&clip, &Retime::default()).unwrap();
            let poses: Vec<PoseFrame> = frames.iter().map(|f| f.pose).collect();
            let got = [resampled.len(), resample(&poses, fps).len(), clip.len(), retimed.len()];
            if got != [n; 4] {
                failures.push(format!("{n} frames at {fps} FPS -> {got:?}"));
            }
            // Identity resampling keeps the poses, too (the interpolation weight at a stamp off
            // by < 1 µs is tiny).
            for (a, b) in resampled.iter().zip(&frames) {
                for (x, y) in a.pose.joints_deg.iter().flatten().zip(b.pose.joints_deg.iter().flatten()) {
                    assert!((x - y).abs() < 1e-3, "{n} at {fps}: {x} vs {y}");
                }
            }
        }
    }
    assert!(failures.is_empty(), "{} lengths lost or gained frames: {failures:?}", failures.len());
}
