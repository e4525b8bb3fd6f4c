//! Issue 14, points 6 and 12: time is untrusted input. One OSC sample stamped `t = 1e9` (or a
//! tracker restarting its clock) starts a new timeline instead of freezing the live filter, live
//! and in `frond map` alike; a daemon paused with SIGSTOP resumes at the present, flagged, with
//! no burst of stale reports and no gap for a healthy subscriber.

use std::net::UdpSocket;
use std::time::Duration;

use frond_e2e::{Daemon, fresh_poses, frond_map, repo_root, send_osc_pitches, wait_for};
use frond_protocol::PoseFlags;
use frond_sdk::{Event, Subscriber};

#[test]
fn a_timestamp_that_jumps_or_goes_back_resets_the_filter_live_and_offline() {
    let dir = tempfile::tempdir().unwrap();
    let port = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let rig = repo_root().join("rig-files/plants/grass.toml");
    let source = format!("osc://127.0.0.1:{port}");
    let filter = "lowpass:cutoff_hz=1";
    let daemon =
        Daemon::start(dir.path(), &["--source", &source, "--rig", rig.to_str().unwrap(), "--filter", filter]);
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    // 20 samples at 10 deg, one absurd `t = 1e9` at 50 deg, then the tracker's clock is back
    // (restarted) with 20 samples at 20 deg.
    let mut samples: Vec<(f64, f32)> = (0..20).map(|k| (f64::from(k) * 0.005, 10.0)).collect();
    samples.push((1e9, 50.0));
    samples.extend((0..20).map(|k| (0.2 + f64::from(k) * 0.005, 20.0)));
    send_osc_pitches(port, &samples, Duration::from_millis(5));
    let fresh = fresh_poses(&mut sub, samples.len(), Duration::from_secs(20));
    assert_eq!(fresh.len(), samples.len(), "every sample published");
    let flagged: Vec<usize> =
        (0..fresh.len()).filter(|&i| fresh[i].flags.contains(PoseFlags::DISCONTINUITY)).collect();
    assert_eq!(flagged, [20, 21], "the jump to 1e9 and the step back are the two discontinuities");
    assert_eq!(fresh[20].hand.wrist_deg[0], 50.0, "the filter was reset: the sample passes through");
    // Before the fix the filter held 50 deg for ever (every later step went backwards).
    for p in &fresh[21..] {
        assert_eq!(p.hand.wrist_deg[0], 20.0, "{p:?}");
    }
    let status = daemon.status();
    assert_eq!(status.hands[0].discontinuities, 2, "{:?}", status.hands[0]);
    assert!(wait_for(Duration::from_secs(2), || daemon
        .status()
        .device_events
        .iter()
        .any(|e| e.contains("device time discontinuous"))));

    // `frond map` maps the same lines the same way and says where the time broke.
    let jsonl: String = samples
        .iter()
        .map(|(t, p)| format!("{{\"t\":{t},\"wrist\":[{p},0,0],\"thumb\":[0,0,0]}}\n"))
        .collect();
    let out = frond_map(&["--filter", filter, "--rig", rig.to_str().unwrap()], &jsonl);
    assert!(out.status.success(), "{out:?}");
    let lines: Vec<serde_json::Value> =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    for (line, pose) in lines.iter().zip(&fresh) {
        for (j, joint) in pose.joints_deg.iter().enumerate() {
            let offline = line["joints"][j][0].as_f64().unwrap();
            assert!((offline - f64::from(joint[0])).abs() < 1e-4, "{line} vs {pose:?}");
        }
    }
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("line 21: t = 1000000000") && err.contains("line 22: t = 0.2"), "{err}");
}

#[test]
fn a_replayed_file_whose_time_jumps_repeats_or_goes_back_keeps_playing() {
    // `frondd --replay` of t = 0 then t = 1e15 used to wait 1e15 s for the second sample,
    // logging only "device stalled (no reports)"; a step back was refused at start-up.
    let dir = tempfile::tempdir().unwrap();
    // 1 s at 100 Hz from t = 10 (the subscriber connects meanwhile), then a jump to 1e15, the
    // same time again, 0.125 s on (1e15 + 0.125 is exact in f64), back to 2 and on in 0.01 s
    // steps.
    let mut times: Vec<f64> = (0..100).map(|k| 10.0 + f64::from(k) * 0.01).collect();
    let before_jump = times[99];
    times.extend([1e15, 1e15, 1e15 + 0.125, 2.0, 2.01, 2.02]);
    let file = dir.path().join("hand.jsonl");
    let text: String =
        times.iter().map(|t| format!("{{\"t\":{t},\"wrist\":[10,0,0],\"thumb\":[0,0,0]}}\n")).collect();
    std::fs::write(&file, text).unwrap();
    let rig = repo_root().join("rig-files/plants/grass.toml");
    let daemon = Daemon::start(
        dir.path(),
        &["--replay", file.to_str().unwrap(), "--rig", rig.to_str().unwrap(), "--filter", "none"],
    );
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let mut fresh = Vec::new();
    while fresh.last().is_none_or(|p: &frond_sdk::Pose| p.hand.t != 2.02) {
        assert!(
            std::time::Instant::now() < deadline,
            "the replay stopped after t = {:?}",
            fresh.last().map(|p| p.hand.t)
        );
        fresh.extend(fresh_poses(&mut sub, 1, Duration::from_secs(1)));
    }
    let from = fresh.iter().position(|p| p.hand.t == 1e15).expect("the jump was published");
    let tail: Vec<(f64, bool)> =
        fresh[from..].iter().map(|p| (p.hand.t, p.flags.contains(PoseFlags::DISCONTINUITY))).collect();
    assert_eq!(
        tail,
        [(1e15, true), (1e15, true), (1e15 + 0.125, false), (2.0, true), (2.01, false), (2.02, false)],
        "the jump, the repeat and the step back are the discontinuities"
    );
    assert!(
        from > 0 && fresh[from - 1].hand.t == before_jump,
        "the samples before the jump: {:?}",
        &fresh[..from]
    );
    assert!(!fresh[from - 1].flags.contains(PoseFlags::DISCONTINUITY), "{:?}", fresh[from - 1]);
    assert_eq!(daemon.status().hands[0].discontinuities, 3);
    assert!(wait_for(Duration::from_secs(2), || daemon
        .status()
        .device_events
        .iter()
        .any(|e| e.contains("device time discontinuous"))));
}

#[test]
fn after_sigstop_the_daemon_resumes_at_the_present_without_a_burst_or_a_gap() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process"]);
    let mut sub = Subscriber::connect(&daemon.socket_dir).unwrap();
    let mut last_seq = None;
    let mut next_pose = |sub: &mut Subscriber| loop {
        match sub.next_event().unwrap() {
            Event::Pose(p) => {
                if let Some(prev) = last_seq {
                    assert_eq!(p.seq, prev + 1, "a gap in the pose stream");
                }
                last_seq = Some(p.seq);
                return p;
            }
            Event::Elements(_) => {}
            other => panic!("unexpected {other:?}"),
        }
    };
    let monotonic_ns = || {
        let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
        // SAFETY: a valid timespec to write into.
        unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
        ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
    };
    let mut before = None;
    for _ in 0..500 {
        let p = next_pose(&mut sub);
        if !p.flags.contains(PoseFlags::HELD) {
            before = Some(p.device_time_us);
        }
    }
    let pid = daemon.proc.child.id() as i32;
    let stopped_at = monotonic_ns();
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(pid, libc::SIGSTOP) };
    std::thread::sleep(Duration::from_secs(2));
    let continued_at = monotonic_ns();
    // SAFETY: as above.
    unsafe { libc::kill(pid, libc::SIGCONT) };
    // Frames published before the stop may still be in the socket: judge by publish time. The
    // first fresh report published after the pause is about 2 s of device time after the last
    // one before it (the glove samples the present), flagged as a discontinuity; none of the
    // 2000 missed ones is replayed.
    let first_after = loop {
        let p = next_pose(&mut sub);
        if p.flags.contains(PoseFlags::HELD) {
            continue;
        }
        if p.host_monotonic_ns < stopped_at {
            before = Some(p.device_time_us);
        } else if p.host_monotonic_ns > continued_at {
            break p;
        }
    };
    let jump_ms = (first_after.device_time_us - before.unwrap()) as f64 / 1000.0;
    assert!(jump_ms > 1500.0, "stale reports were replayed: the next one is only {jump_ms} ms later");
    assert!(first_after.flags.contains(PoseFlags::DISCONTINUITY), "{first_after:?}");
    // The stream goes on at the loop's rate with no gap for this healthy subscriber.
    for _ in 0..2000 {
        next_pose(&mut sub);
    }
    assert_eq!(sub.stats().gaps, 0);
    let status = daemon.status();
    assert!(status.hands[0].discontinuities >= 1, "{:?}", status.hands[0]);
}
