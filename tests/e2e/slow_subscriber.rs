//! A subscriber that never reads must cost only itself: the healthy subscriber beside it sees
//! every frame, and the stalled one's drops are counted (then it is disconnected).

use std::os::unix::net::UnixStream;
use std::time::Duration;

use frond_e2e::{Daemon, wait_for};
use frond_sdk::{Event, Subscriber};

#[test]
fn stalled_subscriber_does_not_disturb_a_healthy_one() {
    let dir = tempfile::tempdir().unwrap();
    // A short queue and write timeout so the stall shows within a couple of seconds.
    let config = dir.path().join("frondd.toml");
    std::fs::write(&config, "[publisher]\nqueue_frames = 64\nwrite_timeout_ms = 1500\n").unwrap();
    let daemon = Daemon::start(dir.path(), &["--source", "in-process", "--config", config.to_str().unwrap()]);

    // The stalled client: connects and never reads a byte.
    let stalled = UnixStream::connect(daemon.socket_dir.join(frond_protocol::POSES_SOCKET)).unwrap();
    let mut healthy = Subscriber::connect(&daemon.socket_dir).expect("subscribe");

    // 3000 consecutive frames (3 s at 1 kHz) with no gap for the healthy subscriber.
    let mut poses = 0;
    let mut last = None;
    // The stalled subscriber's drops, sampled while it is still connected.
    let mut stalled_dropped = 0;
    while poses < 3000 {
        if poses % 250 == 0 {
            let s = daemon.status();
            if let Some(stalled) = s.subscribers.iter().find(|x| x.id == 1) {
                stalled_dropped = stalled_dropped.max(stalled.dropped);
            }
        }
        match healthy.next_event().expect("event") {
            Event::Pose(p) => {
                if let Some(prev) = last {
                    assert_eq!(p.seq, prev + 1, "healthy subscriber saw a gap");
                }
                last = Some(p.seq);
                poses += 1;
            }
            Event::Gap { expected, got } => panic!("healthy subscriber saw a gap {expected}..{got}"),
            other => panic!("unexpected event {other:?}"),
        }
    }
    // The stalled subscriber (id 1, it connected first) had its drops counted, then the daemon
    // let it go; the healthy one lost nothing, and the loop itself dropped nothing.
    let gone = wait_for(Duration::from_secs(10), || {
        let s = daemon.status();
        if let Some(stalled) = s.subscribers.iter().find(|x| x.id == 1) {
            stalled_dropped = stalled_dropped.max(stalled.dropped);
        }
        s.subscribers.len() == 1
    });
    let status = daemon.status();
    assert!(stalled_dropped > 0, "the stalled subscriber's drops were not counted: {status:?}");
    assert!(gone, "stalled subscriber not disconnected: {status:?}");
    assert_eq!(status.subscribers[0].id, 2);
    assert_eq!(status.subscribers[0].dropped, 0, "healthy subscriber lost frames: {status:?}");
    assert_eq!(status.publish_drops, 0, "the loop dropped frames: {status:?}");
    drop(stalled);
}
