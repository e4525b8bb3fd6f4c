//! Helpers shared by frond-warp's integration tests: running the binary, and writing takes.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use frond_formats::take::{TakeRecord, encode_file_start, encode_record};
use frond_motion::take::{TakeFrame, TakeHeader};
use frond_motion::{HandSample, PoseFrame};

/// The binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_frond-warp"))
}

/// Runs it with `args`.
pub fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run frond-warp")
}

/// Its standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A path as an argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A take of `frames` frames at 100 Hz on the grass rig whose root joint's yaw is `yaw(t)`
/// degrees (the hand's wrist yaw the same), other joints still.
pub fn write_take_with(path: &Path, frames: u64, yaw: impl Fn(f64) -> f32) {
    write_take_on(path, "grass", frames, yaw)
}

/// [`write_take_with`] with a header that names rig `rig`.
pub fn write_take_on(path: &Path, rig: &str, frames: u64, yaw: impl Fn(f64) -> f32) {
    write_poses(
        path,
        rig,
        (0..frames).map(|k| {
            let t = k as f64 / 100.0;
            let yaw = yaw(t);
            let pose = PoseFrame { t, joints_deg: [[0.0, yaw, 0.0], [0.0; 3], [0.0; 3], [0.0; 3]] };
            (pose, HandSample { t, wrist_deg: [0.0, yaw, 0.0], thumb_deg: [0.0; 3] })
        }),
    );
}

/// A take on rig `rig` of `frames` (pose and hand sample), 100 Hz apart (frame `k` recorded at
/// `k / 100` s).
pub fn write_poses(path: &Path, rig: &str, frames: impl Iterator<Item = (PoseFrame, HandSample)>) {
    let mut out = Vec::new();
    encode_file_start(&mut out);
    encode_record(
        &TakeRecord::Header(TakeHeader {
            joint_names: vec!["root".into(), "j1".into(), "j2".into(), "top".into()],
            ..TakeHeader::offline("sway", rig, 100)
        }),
        &mut out,
    );
    let mut written = 0;
    for (k, (pose, hand)) in (0u64..).zip(frames) {
        let frame = TakeFrame {
            seq: k,
            device_time_us: k * 10_000,
            host_ns: k * 10_000_000,
            pose,
            hand,
            ..TakeFrame::default()
        };
        encode_record(&TakeRecord::Frame(frame), &mut out);
        written = k + 1;
    }
    encode_record(&TakeRecord::End { frames: written }, &mut out);
    std::fs::write(path, out).unwrap();
}
