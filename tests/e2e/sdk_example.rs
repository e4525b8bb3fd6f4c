//! The SDK's example exporter (`exporters/sdk/examples/print_poses.rs`, the README's "an exporter
//! in 40 lines") on a real daemon: it prints the daemon's rig and elements, then one line a pose,
//! numbered without a gap.

use std::process::Command;

use frond_e2e::{Daemon, bin};

#[test]
fn the_example_exporter_prints_the_daemons_poses() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let out = Command::new(bin("examples/print_poses"))
        .env("FROND_SOCKET_DIR", &daemon.socket_dir)
        .env("POSES", "300")
        .output()
        .expect("run the example");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}\n{}", text, String::from_utf8_lossy(&out.stderr));
    let status = daemon.status();
    let want = format!("# rig {} at {} Hz, joints [", status.rig_name, status.tick_rate_hz);
    assert!(text.starts_with(&want), "{text}");
    assert!(text.lines().any(|l| l.starts_with("# element 0 ")), "{text}");
    let poses: Vec<Vec<&str>> =
        text.lines().filter(|l| !l.starts_with('#')).map(|l| l.split(' ').collect()).collect();
    assert_eq!(poses.len(), 300, "{text}");
    let seqs: Vec<u64> = poses.iter().map(|p| p[1].parse().unwrap()).collect();
    for w in seqs.windows(2) {
        assert_eq!(w[1], w[0] + 1, "consecutive sequence numbers");
    }
    for p in &poses {
        assert_eq!(p[0], "0", "the main hand's plant");
        // Four joints of three angles each, as `[a, b, c]`.
        let angles: Vec<f32> = p[3..]
            .join(" ")
            .split(['[', ']', ',', ' '])
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(angles.len(), 12, "{p:?}");
        assert!(angles.iter().all(|a| a.is_finite() && a.abs() <= 360.0), "{p:?}");
    }
}
