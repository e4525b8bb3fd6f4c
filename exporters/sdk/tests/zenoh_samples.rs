//! A subscriber over Zenoh against a hand-made bridge (a plain Zenoh session holding the
//! source's token, answering its hello and putting poses), with samples on the poses key that
//! are not one frame of frond's protocol put in between, as anyone who may put on the key can.

#![cfg(feature = "zenoh")]

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use common::{hello_frame, pose_frame};
use frond_sdk::{Event, Source, Subscriber};
use zenoh::Wait;

#[test]
fn samples_that_are_not_one_frame_are_skipped_and_counted_and_the_stream_goes_on() {
    let key = format!("frond/odd{}/glove", std::process::id());
    let (bridge, endpoint) = common::hand_made_bridge();
    let _token = bridge.liveliness().declare_token(format!("{key}/alive")).wait().unwrap();
    let _hello = bridge
        .declare_queryable(format!("{key}/hello"))
        .callback(|query| {
            let _ = query.reply(query.key_expr().clone(), hello_frame(0)).wait();
        })
        .wait()
        .unwrap();

    // Poses 0, 1, 2, ... every 2 ms; once the subscriber is in, after the pose 50 later, three
    // samples that are not one frame: text, a frame of another protocol version, a frame cut
    // short.
    let mut other_version = pose_frame(0);
    other_version[4] = other_version[4].wrapping_add(1);
    let cut = pose_frame(0)[..20].to_vec();
    let odd: Vec<Vec<u8>> = vec![b"not a frame".to_vec(), other_version, cut];
    let (stop, go) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicBool::new(false)));
    let odd_after = Arc::new(AtomicU64::new(u64::MAX));
    let putter = {
        let (session, key) = (bridge.clone(), key.clone());
        let (stop, go, odd_after) = (stop.clone(), go.clone(), odd_after.clone());
        std::thread::spawn(move || {
            let poses = session.declare_publisher(format!("{key}/poses")).wait().unwrap();
            let mut seq = 0;
            while !stop.load(Ordering::Relaxed) {
                poses.put(pose_frame(seq)).wait().unwrap();
                if go.load(Ordering::Relaxed) && odd_after.load(Ordering::Relaxed) == u64::MAX {
                    odd_after.store(seq + 50, Ordering::Relaxed);
                }
                if seq == odd_after.load(Ordering::Relaxed) {
                    for bytes in &odd {
                        poses.put(bytes.clone()).wait().unwrap();
                    }
                }
                seq += 1;
                std::thread::sleep(Duration::from_millis(2));
            }
        })
    };

    let source: Source = format!("zenoh:{key}?connect={endpoint}").parse().unwrap();
    let mut sub = Subscriber::options().hello_timeout(Duration::from_secs(10)).subscribe(&source).unwrap();
    go.store(true, Ordering::Relaxed);
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut last = None;
    while last.is_none_or(|seq| seq < odd_after.load(Ordering::Relaxed).saturating_add(100)) {
        assert!(Instant::now() < deadline, "the poses after the odd samples never came (last {last:?})");
        match sub.next_event() {
            Ok(Event::Pose(p)) => last = Some(p.seq),
            Ok(Event::Gap { .. }) => {}
            other => panic!("a bad sample must not reach the caller or end the stream: {other:?}"),
        }
    }
    stop.store(true, Ordering::Relaxed);
    putter.join().unwrap();
    let stats = sub.stats();
    assert_eq!(stats.rejected, 3, "{stats:?}");
    assert_eq!((stats.disconnects, stats.reconnects), (0, 0), "{stats:?}");
}
