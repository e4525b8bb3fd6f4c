//! Frames a fake daemon or a fake bridge sends: a hello and poses whose values follow from
//! their sequence numbers.
#![allow(dead_code)] // each test binary uses its own part

use frond_protocol::ElementId;
use frond_protocol::{HandWire, ServerMessage, encode_frame};
use frond_sdk::{Hello, Pose, PoseFlags};

pub fn hello(next_seq: u64) -> Hello {
    Hello {
        protocol_version: frond_protocol::PROTOCOL_VERSION,
        daemon_version: "0.0.0-test".into(),
        rig_name: "grass".into(),
        joint_names: ["root", "j1", "j2", "top"].map(String::from).to_vec(),
        tick_rate_hz: 1000,
        elements: Default::default(),
        next_seq,
    }
}

pub fn pose(seq: u64) -> Pose {
    let a = seq as f32;
    Pose {
        seq,
        device_time_us: seq * 1000,
        host_monotonic_ns: 5_000_000 + seq,
        flags: PoseFlags::FILTERED,
        element: ElementId::GLOBAL,
        joints_deg: [[a, -a, 0.5], [1.0, 2.0, 3.0], [a * 0.25, 0.0, -1.5], [0.0, 0.0, a]],
        hand: HandWire { t: seq as f64 / 1000.0, wrist_deg: [a, 0.0, 1.0], thumb_deg: [2.0, 3.0, 4.0] },
    }
}

pub fn frame(msg: &ServerMessage) -> Vec<u8> {
    let mut out = Vec::new();
    encode_frame(msg, &mut out);
    out
}

pub fn hello_frame(next_seq: u64) -> Vec<u8> {
    frame(&ServerMessage::Hello(hello(next_seq)))
}

pub fn pose_frame(seq: u64) -> Vec<u8> {
    frame(&ServerMessage::Pose(pose(seq)))
}

/// A Zenoh peer that plays a bridge: listening on a free loopback port, with multicast
/// scouting off so that only this test's subscriber finds it. Returns it and its endpoint.
#[cfg(feature = "zenoh")]
pub fn hand_made_bridge() -> (zenoh::Session, String) {
    use frond_sdk::zenoh::{config, open_session};
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let hermetic = [("scouting/multicast/enabled", "false")];
    let session =
        open_session(config(None, None, &[], std::slice::from_ref(&endpoint), &hermetic).unwrap()).unwrap();
    (session, endpoint)
}
