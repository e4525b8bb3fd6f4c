//! The follower driven by a stage master written here from the published format (Vicon's
//! "UDP capture broadcast/trigger" page: NUL-terminated XML, `Delay` in ms, `PacketID`
//! incremented per packet), not from the crate's encoder: start/stop, delay, name
//! sanitising, duplicates, reordering, foreign hosts, garbage and floods.

use std::net::{IpAddr, Ipv4Addr};

use frond_triggers::{
    Decision, Follower, FollowerConfig, FollowerState, Ignored, MAX_DATAGRAM_BYTES, MAX_SENDERS, StopResult,
};

const MASTER: IpAddr = IpAddr::V4(Ipv4Addr::new(10, 0, 0, 5));
const STRANGER: IpAddr = IpAddr::V4(Ipv4Addr::new(10, 0, 0, 66));
const MS: u64 = 1_000_000;

/// A stage master as the vendors' pages describe one.
struct Master {
    packet_id: u64,
}

impl Master {
    fn start(&mut self, name: &str, delay_ms: u32) -> Vec<u8> {
        self.packet_id += 1;
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStart><Name VALUE=\"{name}\"/>\
             <Notes VALUE=\"\"/><Description VALUE=\"\"/><DatabasePath VALUE=\"D:/Captures\"/>\
             <Delay VALUE=\"{delay_ms}\"/><PacketID VALUE=\"{}\"/><TimeCode VALUE=\"10:00:00:12\"/></CaptureStart>\0",
            self.packet_id
        )
        .into_bytes()
    }

    fn stop(&mut self, name: &str) -> Vec<u8> {
        self.packet_id += 1;
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStop RESULT=\"SUCCESS\">\
             <Name VALUE=\"{name}\"/><DatabasePath VALUE=\"D:/Captures\"/><Delay VALUE=\"0\"/>\
             <PacketID VALUE=\"{}\"/></CaptureStop>\0",
            self.packet_id
        )
        .into_bytes()
    }
}

fn follower(allow: Option<Vec<IpAddr>>, honour_delay: bool) -> Follower {
    Follower::new(FollowerConfig { allow, honour_delay })
}

#[test]
fn a_start_and_stop_round_trip() {
    let mut f = follower(Some(vec![MASTER]), true);
    let mut m = Master { packet_id: 100 };
    let Decision::Start(take) = f.on_datagram(MASTER, &m.start("dance", 0), 5 * MS) else { panic!() };
    assert_eq!((take.name.as_str(), take.start_at_ns, take.sender), ("dance", 5 * MS, MASTER));
    assert_eq!(take.timecode.unwrap().to_string(), "10:00:00:12");
    assert_eq!(f.state(), &FollowerState::Recording { name: "dance".into() });
    assert_eq!(
        f.on_datagram(MASTER, &m.stop("dance"), 9 * MS),
        Decision::Stop { name: "dance".into(), result: StopResult::Success }
    );
    assert_eq!(f.state(), &FollowerState::Idle);
    let c = f.counters();
    assert_eq!((c.received, c.started, c.stopped), (2, 1, 1));
    assert_eq!(f.last_message().unwrap().kind, "CaptureStop");
}

#[test]
fn the_delay_is_honoured_and_a_stop_before_it_cancels() {
    let mut f = follower(None, true);
    let mut m = Master { packet_id: 0 };
    assert_eq!(
        f.on_datagram(MASTER, &m.start("t1", 33), 1_000 * MS),
        Decision::Scheduled { at_ns: 1_033 * MS }
    );
    assert_eq!(f.next_deadline(), Some(1_033 * MS));
    assert_eq!(f.poll(1_032 * MS), None);
    let take = f.poll(1_033 * MS).unwrap();
    assert_eq!((take.name.as_str(), take.start_at_ns), ("t1", 1_033 * MS));
    assert_eq!(f.poll(1_034 * MS), None, "started once");
    assert!(matches!(f.on_datagram(MASTER, &m.stop("t1"), 2_000 * MS), Decision::Stop { .. }));

    assert!(matches!(f.on_datagram(MASTER, &m.start("t2", 500), 3_000 * MS), Decision::Scheduled { .. }));
    assert_eq!(f.on_datagram(MASTER, &m.stop("t2"), 3_100 * MS), Decision::CancelScheduled);
    assert_eq!(f.poll(4_000 * MS), None);
    assert_eq!(f.counters().cancelled, 1);

    let mut now = follower(None, false);
    assert!(
        matches!(now.on_datagram(MASTER, &m.start("t3", 500), 0), Decision::Start(t) if t.start_at_ns == 0)
    );
}

#[test]
fn names_are_made_safe_and_a_stop_matches_the_safe_name() {
    let mut f = follower(None, true);
    let mut m = Master { packet_id: 7 };
    let Decision::Start(take) = f.on_datagram(MASTER, &m.start("../Scene 4/take 2", 0), 0) else { panic!() };
    assert_eq!(take.name, "Scene_4_take_2");
    assert_eq!(take.sent_name.as_deref(), Some("../Scene 4/take 2"));
    assert!(
        matches!(f.on_datagram(MASTER, &m.stop("../Scene 4/take 2"), MS), Decision::Stop { name, .. } if name == "Scene_4_take_2")
    );
    let Decision::Start(take) = f.on_datagram(MASTER, &m.start("", 0), 2 * MS) else { panic!() };
    assert_eq!(take.name, "trigger-10", "an empty name falls back to the packet id");
}

#[test]
fn duplicates_and_reordered_packets_are_ignored() {
    let mut f = follower(None, true);
    let mut m = Master { packet_id: 4_000 };
    let start = m.start("a", 0);
    let stop = m.stop("a");
    assert!(matches!(f.on_datagram(MASTER, &start, 0), Decision::Start(_)));
    // The same packet over a second path.
    assert_eq!(f.on_datagram(MASTER, &start, MS), Decision::Ignored(Ignored::Duplicate));
    assert!(matches!(f.on_datagram(MASTER, &stop, 2 * MS), Decision::Stop { .. }));
    assert_eq!(f.on_datagram(MASTER, &stop, 3 * MS), Decision::Ignored(Ignored::Duplicate));
    // The start arriving late, after its stop: out of order, not a new take.
    assert_eq!(f.on_datagram(MASTER, &start, 4 * MS), Decision::Ignored(Ignored::OutOfOrder));
    assert_eq!(f.state(), &FollowerState::Idle);
    let c = f.counters();
    assert_eq!((c.duplicates, c.out_of_order, c.started), (2, 1, 1));
    // A master restarted from packet 1 (far below the last id, past the reorder window) is
    // followed again.
    let mut restarted = Master { packet_id: 0 };
    assert!(matches!(f.on_datagram(MASTER, &restarted.start("b", 0), 5 * MS), Decision::Start(_)));
}

#[test]
fn stops_for_nothing_or_another_take_and_starts_while_recording_are_harmless() {
    let mut f = follower(None, true);
    let mut m = Master { packet_id: 0 };
    assert_eq!(f.on_datagram(MASTER, &m.stop("x"), 0), Decision::Ignored(Ignored::NotRecording));
    assert!(matches!(f.on_datagram(MASTER, &m.start("x", 0), MS), Decision::Start(_)));
    assert_eq!(f.on_datagram(MASTER, &m.stop("y"), 2 * MS), Decision::Ignored(Ignored::OtherTake));
    assert_eq!(f.on_datagram(MASTER, &m.start("z", 0), 3 * MS), Decision::Ignored(Ignored::AlreadyRecording));
    assert_eq!(f.state(), &FollowerState::Recording { name: "x".into() });
    // The operator stopped the take in frond: the next start is followed.
    f.take_ended();
    assert!(matches!(f.on_datagram(MASTER, &m.start("z", 0), 4 * MS), Decision::Start(_)));
    let c = f.counters();
    assert_eq!((c.not_recording, c.other_take, c.already_recording), (1, 1, 1));
}

#[test]
fn foreign_hosts_are_ignored_unparsed_and_counted() {
    let mut f = follower(Some(vec![MASTER]), true);
    let mut m = Master { packet_id: 0 };
    assert_eq!(f.on_datagram(STRANGER, &m.start("evil", 0), 0), Decision::Ignored(Ignored::Foreign));
    assert_eq!(f.on_datagram(STRANGER, b"\xff garbage", 0), Decision::Ignored(Ignored::Foreign));
    assert_eq!(f.state(), &FollowerState::Idle);
    let c = f.counters();
    assert_eq!((c.foreign, c.malformed, c.received), (2, 0, 2));
    assert!(f.last_message().is_none());
}

#[test]
fn garbage_and_floods_are_refused_counted_and_bounded() {
    let mut f = follower(None, true);
    let huge = vec![b'<'; MAX_DATAGRAM_BYTES + 1];
    assert!(matches!(f.on_datagram(MASTER, &huge, 0), Decision::Refused(_)));
    for junk in [&b""[..], b"hello", b"<CaptureStart>", b"<Other/>"] {
        assert!(matches!(f.on_datagram(MASTER, junk, 0), Decision::Refused(_)), "{junk:?}");
    }
    let c = f.counters();
    assert_eq!((c.oversized, c.malformed), (1, 4));

    // A flood: many hosts, each its own packet ids; then the master still works, and a
    // repeated flood packet is still recognised from the most recent senders.
    let mut flood = Master { packet_id: 1_000 };
    let stop = flood.stop("nothing");
    for i in 0..10_000u32 {
        let host = IpAddr::V4(Ipv4Addr::from(0x0A01_0000 + i));
        assert_eq!(f.on_datagram(host, &stop, u64::from(i)), Decision::Ignored(Ignored::NotRecording));
    }
    let last_host = IpAddr::V4(Ipv4Addr::from(0x0A01_0000 + 9_999));
    assert_eq!(f.on_datagram(last_host, &stop, 20_000), Decision::Ignored(Ignored::Duplicate));
    // The first hosts were forgotten (at most MAX_SENDERS are remembered): their repeat is
    // treated as news, and answered harmlessly again.
    let first_host = IpAddr::V4(Ipv4Addr::from(0x0A01_0000));
    const { assert!(MAX_SENDERS < 10_000) };
    assert_eq!(f.on_datagram(first_host, &stop, 20_001), Decision::Ignored(Ignored::NotRecording));
    let mut m = Master { packet_id: 0 };
    assert!(matches!(f.on_datagram(MASTER, &m.start("after-flood", 0), 30_000), Decision::Start(_)));
    assert_eq!(f.counters().not_recording, 10_001);
}
