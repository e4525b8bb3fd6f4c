//! A [`StageSubscriber`] against a Zenoh peer that holds a bridge's liveliness token but
//! answers no hello (a bridge that hangs while starting).

#![cfg(feature = "zenoh")]

mod common;

use std::time::{Duration, Instant};

use frond_sdk::zenoh_many::StageSubscriber;
use frond_sdk::{Source, Subscriber};
use zenoh::Wait;

#[test]
fn dropping_a_stage_subscriber_does_not_wait_for_a_source_that_never_says_hello() {
    let stage = format!("mute{}", std::process::id());
    let (mute, endpoint) = common::hand_made_bridge();
    let _token = mute.liveliness().declare_token(format!("frond/{stage}/glove/alive")).wait().unwrap();

    let Source::Zenoh(addr) = format!("zenoh:frond/{stage}/*?connect={endpoint}").parse::<Source>().unwrap()
    else {
        panic!("not a Zenoh address");
    };
    // The follower waits up to a minute for the hello that never comes.
    let subscriber =
        StageSubscriber::open(&addr, Subscriber::options().hello_timeout(Duration::from_secs(60))).unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    while subscriber.sources() != [format!("{stage}/glove")] {
        assert!(Instant::now() < deadline, "the token was never seen: {:?}", subscriber.sources());
        std::thread::sleep(Duration::from_millis(20));
    }
    // Dropping it returns long before that minute (it used to wait for the follower's open).
    let (done_tx, done) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        drop(subscriber);
        let _ = done_tx.send(());
    });
    done.recv_timeout(Duration::from_secs(20))
        .expect("dropping the stage subscriber hung on the opening follower");
}
