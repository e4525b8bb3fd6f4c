//! Section 11: a camera frame -> pose at a subscriber through frondd's `webcam` source, beside
//! the landmark helper alone in the same run, so that the model's time and frond's own are
//! apart (issue 47). Both play the photograph of a hand the webcam tests use (fingerpose
//! 0.1.0's `nocurl.jpg`, MIT) at 30 frames a second through frond-hands (MediaPipe Hands
//! 0.10.21, installed by `daemon/device/tests/install-webcam.sh`, or `$FROND_HANDS`). Alone, its
//! lines are read here: capture -> line on the pipe, the model's time on each frame, its CPU.
//! Through frondd (1 kHz), a subscriber takes each fresh pose's device time (the frame's
//! capture, `CLOCK_MONOTONIC`) from its receipt time; frond's own share is the difference of the
//! two medians.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use frond_protocol::LatencySummary;
use frondd::clock::monotonic_ns;
use serde_json::json;

use crate::Options;
use crate::error::BenchError;
use crate::latency::Subscribers;
use crate::procs::{Daemon, process_cpu_ns};
use crate::report::{Measurement, Section, Status};

/// The section's title.
pub const TITLE: &str =
    "webcam frame -> subscriber receipt through frondd vs the hand model alone (frond-hands, 30 fps)";

/// The helper and the photograph, when installed.
fn helper_and_photo() -> Option<(PathBuf, PathBuf)> {
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/.venv-hands");
    let helper =
        std::env::var_os("FROND_HANDS").map(PathBuf::from).unwrap_or_else(|| venv.join("bin/frond-hands"));
    let photo = venv.join("fingerpose/package/assets/nocurl.jpg");
    (helper.exists() && photo.exists()).then_some((helper, photo))
}

/// Percentiles of microsecond values.
fn summary(mut v: Vec<u64>) -> LatencySummary {
    v.sort_unstable();
    let at = |q: f64| v.get(((v.len() as f64 - 1.0) * q).round() as usize).copied().unwrap_or(0) as f64;
    LatencySummary {
        p50_us: at(0.5),
        p99_us: at(0.99),
        p999_us: at(0.999),
        max_us: at(1.0),
        samples: v.len() as u64,
    }
}

/// What the helper does alone.
struct Alone {
    model: LatencySummary,
    to_line: LatencySummary,
    cpu_fraction: f64,
}

/// Runs the helper on `photo` for `frames` frames at 30 a second and reads its lines.
fn helper_alone(helper: &Path, photo: &Path, frames: u32) -> Result<Alone, BenchError> {
    let mut child = Command::new(helper)
        .arg("--file")
        .arg(photo)
        .args(["--fps", "30", "--frames", &frames.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(BenchError::start("frond-hands"))?;
    let pid = child.id();
    let out = child.stdout.take().ok_or_else(|| std::io::Error::other("no stdout"))?;
    let (mut model, mut to_line) = (Vec::new(), Vec::new());
    let mut cpu: Option<(u64, Instant)> = None;
    let mut cpu_fraction = 0.0;
    for line in BufReader::new(out).lines() {
        let line = line?;
        let now_us = monotonic_ns() / 1000;
        let v: serde_json::Value = serde_json::from_str(&line).unwrap_or_default();
        let (Some(t), Some(m)) = (v["t_us"].as_u64(), v["model_us"].as_u64()) else { continue };
        // The first frame finds the palm and warms up: measured from the second on.
        if cpu.is_none() {
            cpu = Some((process_cpu_ns(pid)?, Instant::now()));
            continue;
        }
        model.push(m);
        to_line.push(now_us.saturating_sub(t));
        if model.len() + 2 == frames as usize
            && let Some((start, at)) = cpu
        {
            cpu_fraction = (process_cpu_ns(pid)? - start) as f64 / at.elapsed().as_nanos() as f64;
        }
    }
    let status = child.wait()?;
    if !status.success() || model.is_empty() {
        return Err(BenchError::Io(std::io::Error::other(format!(
            "frond-hands ended with {status} after {} frames",
            model.len()
        ))));
    }
    Ok(Alone { model: summary(model), to_line: summary(to_line), cpu_fraction })
}

/// Section 11.
pub fn webcam(o: &Options) -> Result<Section, BenchError> {
    let Some((helper, photo)) = helper_and_photo() else {
        return Ok(Section::unavailable(
            "webcam",
            TITLE,
            Status::NotAvailable,
            "no frond-hands (run daemon/device/tests/install-webcam.sh, or set FROND_HANDS)",
        ));
    };
    let secs = if o.quick { 2 } else { 10 };
    let alone = helper_alone(&helper, &photo, 30 * secs)?;
    let source = format!("webcam:{}?hand=left", photo.display());
    let daemon = Daemon::start_with_env(
        o,
        &["--source", &source, "--rate", "1000"],
        &[("FROND_HANDS", helper.as_os_str())],
    )?;
    let mut subs = Subscribers::new(1);
    subs.grow_to(&daemon.poses_socket(), 1)?;
    // Let the helper start and find the hand.
    std::thread::sleep(Duration::from_secs(2));
    let (cpu0, t0) = (process_cpu_ns(daemon.proc.pid())?, Instant::now());
    subs.record(Some(0));
    std::thread::sleep(Duration::from_secs(u64::from(secs)));
    subs.record(None);
    let frondd_cpu = (process_cpu_ns(daemon.proc.pid())? - cpu0) as f64 / t0.elapsed().as_nanos() as f64;
    let total = subs.hists(0).glove_to_receipt.summary();
    let camera = daemon.status()?.source.camera;
    let alone_name = "frond-hands alone: frame capture -> its line on the pipe";
    let measurements = vec![
        Measurement::new("frame_to_subscriber_p50", "us", total.p50_us, alone_name, alone.to_line.p50_us),
        Measurement::new("frame_to_subscriber_p99", "us", total.p99_us, alone_name, alone.to_line.p99_us),
        Measurement::new(
            "model_p50",
            "us",
            alone.model.p50_us,
            "frond-hands alone: capture -> line, median",
            alone.to_line.p50_us,
        ),
        Measurement::new(
            "helper_cpu_30fps",
            "fraction_of_core",
            alone.cpu_fraction,
            "frondd at 1 kHz reading the camera, same run",
            frondd_cpu,
        ),
    ];
    let details = json!({
        // frond's own share, estimated as the difference of two runs' medians: not a row, since
        // under load the two runs differ by more than it (a CI run saw -2.9 ms).
        "frond_own_p50_us_estimate": total.p50_us - alone.to_line.p50_us,
        "frondd_frame_to_subscriber": total,
        "helper_capture_to_line": alone.to_line,
        "helper_model": alone.model,
        "helper_cpu_fraction": alone.cpu_fraction,
        "frondd_cpu_fraction": frondd_cpu,
        "camera_status": camera,
    });
    Ok(Section::ok("webcam", TITLE, measurements, details))
}
