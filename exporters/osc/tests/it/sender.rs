//! The sender against real loopback sockets: a target that is down (ICMP port unreachable) is
//! counted as refused and never stops the frames to the other targets.

use std::net::UdpSocket;
use std::time::Duration;

use frond_osc::encode::{ClockOffset, Datagrams, FrondEncoder};
use frond_osc::sender::Sender;
use frond_protocol::Pose;

#[test]
fn a_refused_target_never_blocks_the_others() {
    // A port with nobody listening: bind, note the port, close.
    let dead = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let live_a = UdpSocket::bind("127.0.0.1:0").unwrap();
    let live_b = UdpSocket::bind("127.0.0.1:0").unwrap();
    for s in [&live_a, &live_b] {
        s.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    }
    let targets = [live_a.local_addr().unwrap(), dead, live_b.local_addr().unwrap()];
    let mut sender = Sender::new(&targets, None).unwrap();
    let mut enc = FrondEncoder::new(ClockOffset::fixed(0));
    let mut out = Datagrams::new();
    const FRAMES: u64 = 50;
    for seq in 0..FRAMES {
        enc.encode(&Pose { seq, host_monotonic_ns: seq, ..Pose::default() }, &mut out).unwrap();
        sender.send(&out);
        // Give the kernel time to deliver the ICMP error for the dead target.
        std::thread::sleep(Duration::from_millis(2));
    }
    let mut buf = [0u8; 1500];
    for live in [&live_a, &live_b] {
        for seq in 0..FRAMES {
            let n = live.recv(&mut buf).expect("every frame reaches the live targets");
            let (_, packet) = rosc::decoder::decode_udp(&buf[..n]).unwrap();
            let rosc::OscPacket::Bundle(b) = packet else { panic!("bundle expected") };
            let rosc::OscPacket::Message(m) = &b.content[0] else { panic!("message expected") };
            assert_eq!(m.args[0], rosc::OscType::Int(seq as i32), "in order");
        }
    }
    let c = sender.targets().iter().map(|t| t.counters()).collect::<Vec<_>>();
    assert_eq!((c[0].frames_sent, c[0].refused), (FRAMES, 0));
    assert_eq!((c[2].frames_sent, c[2].refused), (FRAMES, 0));
    assert!(c[1].refused >= 1, "the dead target's refusals are counted: {:?}", c[1]);
    assert_eq!(c[1].frames_sent + c[1].refused + c[1].would_block + c[1].errors, FRAMES, "{:?}", c[1]);
}
