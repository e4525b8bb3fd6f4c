//! Issue 43: on healthy links nothing is lost. A daemon at 1 kHz and its `frond-zenoh` bridge
//! on one "host" (network namespace), four `frond tap --from zenoh:...` subscribers on two
//! others: for 5 s of poses every subscriber gets every frame, in order, and reports no gap.
//!
//! Before the bridge stopped marking poses express, each pose took one of the two batches of a
//! link's real-time queue, and a transmit task held off the CPU for 3 ms (two busy cores) made
//! Zenoh drop poses after its 1 ms `wait_before_drop`: tens of frames in seconds under load.

use std::time::Duration;

use frond_e2e::{Daemon, bin, start_zenoh_bridge, wait_for};

use crate::stage_net::{PORT, Tapped, lan, lines, seq_of, tap};

/// Frames each subscriber must take without a gap: 5 s at 1 kHz.
const FRAMES: usize = 5000;

/// The sequence numbers `t` printed, and the first place one does not follow the one before.
fn first_break(t: &Tapped) -> Option<(u64, u64)> {
    let seqs: Vec<u64> = t.lines.iter().map(|(_, l)| seq_of(l)).collect();
    seqs.windows(2).find(|w| w[1] != w[0] + 1).map(|w| (w[0], w[1]))
}

#[test]
fn four_remote_subscribers_at_1khz_lose_no_frame_on_healthy_links() {
    let Some(lan) = lan(3) else { return };
    let performer = &lan.hosts[0];
    let dir = tempfile::tempdir().unwrap();
    let daemon = Daemon::start_on(performer, dir.path(), &["--source", "in-process"]);
    let _bridge = start_zenoh_bridge(
        performer.command(bin("frond-zenoh")),
        &daemon,
        "stage1",
        "glove-a",
        &["--listen", &performer.endpoint(PORT)],
    );
    let from = format!("zenoh:frond/stage1/glove-a?connect={}", performer.endpoint(PORT));
    let taps: Vec<_> = (0..4).map(|i| tap(Some(&lan.hosts[1 + i % 2]), &[], &["--from", &from])).collect();

    let done = wait_for(Duration::from_secs(60), || taps.iter().all(|(_, t)| lines(t) >= FRAMES));
    for (i, (_, t)) in taps.iter().enumerate() {
        let t = t.lock().unwrap();
        assert!(
            done,
            "subscriber {i}: {} of {FRAMES} frames within 60 s; stderr {:?}",
            t.lines.len(),
            t.stderr
        );
        let gaps: Vec<&String> = t.stderr.iter().filter(|l| l.contains("gap")).collect();
        assert!(gaps.is_empty(), "subscriber {i} reported gaps on a healthy link: {gaps:?}");
        assert_eq!(
            first_break(&t),
            None,
            "subscriber {i}: a frame is missing or out of order among {} (stderr {:?})",
            t.lines.len(),
            t.stderr
        );
    }
}
