//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::Path;
use std::time::{Duration, Instant};

use frond_device::{DeviceSample, HandSource, SourceError};

/// FUSE tests need /dev/fuse (present here and in CI, which run as root).
pub fn fuse_available() -> bool {
    if Path::new("/dev/fuse").exists() {
        true
    } else {
        eprintln!("skipping: /dev/fuse is missing, the virtual glove cannot be mounted");
        false
    }
}

/// Whether `dir` is a mount point (per /proc/self/mountinfo).
pub fn is_mounted(dir: &Path) -> bool {
    let info = std::fs::read_to_string("/proc/self/mountinfo").unwrap();
    let dir = dir.to_str().unwrap();
    info.lines().any(|l| l.split(' ').nth(4) == Some(dir))
}

/// A JSONL hand file of `n` samples at `rate_hz`, angles with two decimals (exact in
/// centidegrees) and times in whole microseconds (exact as device time). Returns the text.
pub fn hand_jsonl(n: usize, rate_hz: f64) -> String {
    let mut s = String::new();
    for i in 0..n {
        let t = i as f64 / rate_hz;
        let a = |k: usize| (((i * 37 + k * 101) % 9000) as f64 - 4500.0) / 100.0;
        s.push_str(&format!(
            "{{\"t\":{t:.6},\"wrist\":[{},{},{}],\"thumb\":[{},{},{}]}}\n",
            a(0),
            a(1),
            a(2),
            a(3),
            a(4),
            a(5)
        ));
    }
    s
}

/// Reads exactly `n` samples (fewer only if `timeout` passes first).
pub fn read_n(
    src: &mut dyn HandSource,
    n: usize,
    timeout: Duration,
) -> Result<Vec<DeviceSample>, SourceError> {
    let deadline = Instant::now() + timeout;
    let mut out = Vec::new();
    let mut buf = [DeviceSample::default(); 32];
    while out.len() < n && Instant::now() < deadline {
        // Ask for no more than is still wanted: the rest stays queued for the next read.
        let want = (n - out.len()).min(buf.len());
        let k = src.read_pending(&mut buf[..want])?;
        out.extend_from_slice(&buf[..k]);
        if k == 0 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    Ok(out)
}

/// Reads until the source reports a disconnect (or `timeout`).
pub fn read_until_disconnect(src: &mut dyn HandSource, timeout: Duration) -> Option<SourceError> {
    let deadline = Instant::now() + timeout;
    let mut buf = [DeviceSample::default(); 32];
    while Instant::now() < deadline {
        match src.read_pending(&mut buf) {
            Ok(0) => std::thread::sleep(Duration::from_millis(2)),
            Ok(_) => {}
            Err(e) => return Some(e),
        }
    }
    None
}
