//! Fuzzes the wire protocol: `decode_frame` and `read_frame` for pose-socket messages, control
//! requests and control replies.
//!
//! Besides "no panic, no hang, typed errors", every input is checked against a second reader:
//! `read_frame` over the same bytes must agree with `decode_frame` (same message, same error),
//! and an accepted message must re-encode to a frame that decodes to the same bytes again.

use frond_fuzz::{Rng, Target, assert_message, fuzz};
use frond_protocol::{
    ControlError, ControlErrorKind, ControlReply, ControlRequest, DecodeError, ElementId, HEADER_LEN,
    HandWire, Hello, Pose, PoseFlags, ReadError, RecordingStatus, ServerMessage, decode_frame, encode_frame,
    read_frame,
};
use serde::Serialize;
use serde::de::DeserializeOwned;

fn frame<T: Serialize>(msg: &T) -> Vec<u8> {
    let mut out = Vec::new();
    encode_frame(msg, &mut out);
    out
}

/// A frame around an already encoded MessagePack body.
fn raw_frame(body: &[u8]) -> Vec<u8> {
    let mut out = ((body.len() + 1) as u32).to_le_bytes().to_vec();
    out.push(frond_protocol::PROTOCOL_VERSION);
    out.extend_from_slice(body);
    out
}

/// MessagePack tokens: type markers with huge length claims, deep nesting, field and variant names.
fn msgpack_dict(names: &[&str]) -> Vec<Vec<u8>> {
    let mut d: Vec<Vec<u8>> = vec![
        vec![0xc0],
        vec![0xc2],
        vec![0xc3],
        vec![0xdc, 0xff, 0xff],
        vec![0xdd, 0xff, 0xff, 0xff, 0xff],
        vec![0xde, 0xff, 0xff],
        vec![0xdf, 0xff, 0xff, 0xff, 0xff],
        vec![0xd9, 0xff],
        vec![0xda, 0xff, 0xff],
        vec![0xdb, 0xff, 0xff, 0xff, 0xff],
        vec![0xc4, 0xff],
        vec![0xc6, 0xff, 0xff, 0xff, 0xff],
        vec![0xcf, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff],
        vec![0xd3, 0x80, 0, 0, 0, 0, 0, 0, 0],
        vec![0xca, 0x7f, 0xc0, 0, 0],
        vec![0xcb, 0x7f, 0xf0, 0, 0, 0, 0, 0, 0],
        vec![0xd4, 0x01, 0x00],
        vec![0xc7, 0xff, 0x01],
        vec![0x81],
        vec![0x94],
        vec![0x91; 64],
        vec![0x91; 2000],
        [0x81, 0xa0].repeat(500),
        vec![0x02, 0, 0, 0, 0x01],
        vec![0xff, 0xff, 0xff, 0xff, 0x01],
        vec![0x00, 0x00, 0x10, 0x00, 0x01],
        vec![0x01, 0x00, 0x10, 0x00, 0x01],
    ];
    for n in names {
        let mut s = vec![0xa0 | n.len() as u8];
        s.extend_from_slice(n.as_bytes());
        d.push(s);
    }
    d
}

const NAMES: &[&str] = &[
    "Hello",
    "Pose",
    "protocol_version",
    "daemon_version",
    "rig_name",
    "joint_names",
    "tick_rate_hz",
    "next_seq",
    "seq",
    "device_time_us",
    "host_monotonic_ns",
    "flags",
    "element",
    "joints_deg",
    "hand",
    "t",
    "wrist_deg",
    "thumb_deg",
    "Status",
    "SetRig",
    "SetCalibration",
    "SetFilter",
    "RecordStart",
    "RecordStop",
    "Mark",
    "RawSample",
    "FreezeLoop",
    "name",
    "toml",
    "id",
    "spec",
    "label",
    "ms",
    "Ok",
    "Recording",
    "Error",
    "kind",
    "message",
    "BadRequest",
    "fresh",
    "frames",
    "dropped",
    "active",
    "path",
];

/// Makes the first frame's length prefix match the input (and usually the version byte valid),
/// so that most mutations reach the MessagePack decoder.
#[allow(clippy::ptr_arg)] // the signature of `Target::fixup`
fn fix_length(v: &mut Vec<u8>, rng: &mut Rng) {
    if v.len() < HEADER_LEN {
        return;
    }
    let len = (v.len() - 4) as u32;
    v[..4].copy_from_slice(&len.to_le_bytes());
    if rng.chance(7, 8) {
        v[4] = frond_protocol::PROTOCOL_VERSION;
    }
}

/// The checks shared by the three message types.
fn check<T: DeserializeOwned + Serialize + std::fmt::Debug>(bytes: &[u8]) -> &'static str {
    let decoded = decode_frame::<T>(bytes);
    let label = match &decoded {
        Ok(Some(_)) => "ok",
        Ok(None) => "incomplete",
        Err(DecodeError::Malformed(_) | DecodeError::TrailingBytes(_)) => "body refused",
        Err(_) => "header refused",
    };
    let mut cursor: &[u8] = bytes;
    let read = read_frame::<T, _>(&mut cursor, &mut Vec::new());
    if let Err(e) = &read {
        assert_message(e);
    }
    match &decoded {
        Ok(Some((msg, used))) => {
            assert!(*used >= HEADER_LEN && *used <= bytes.len(), "used {used} of {}", bytes.len());
            let again = frame(msg);
            let (msg2, used2) =
                decode_frame::<T>(&again).expect("re-encoded frame decodes").expect("whole frame");
            assert_eq!(used2, again.len());
            assert_eq!(frame(&msg2), again, "decode(encode(msg)) changed the message");
            let by_read = read.expect("read_frame refused a frame decode_frame accepted");
            assert_eq!(frame(&by_read), again, "read_frame and decode_frame disagree");
            assert_eq!(bytes.len() - cursor.len(), *used, "read_frame consumed a different length");
        }
        Ok(None) => {
            assert!(
                matches!(read, Err(ReadError::Closed | ReadError::Truncated { .. })),
                "incomplete frame, but read_frame said {read:?}"
            );
        }
        Err(e) => {
            assert_message(e);
            if bytes.len() >= HEADER_LEN {
                match read {
                    Err(ReadError::Decode(e2)) => assert_eq!(&e2, e, "read_frame and decode_frame disagree"),
                    Err(ReadError::Truncated { .. }) if !matches!(e, DecodeError::Malformed(_)) => {}
                    other => panic!("decode_frame said {e:?}, read_frame {other:?}"),
                }
            }
        }
    }
    // A stream of frames: each decoded frame consumes bytes, so the loop ends.
    let mut rest = bytes;
    while let Ok(Some((_, used))) = decode_frame::<T>(rest) {
        assert!(used > 0 && used <= rest.len());
        rest = &rest[used..];
    }
    label
}

fn run<T: DeserializeOwned + Serialize + std::fmt::Debug + 'static>(target: Target) {
    let report = fuzz(target.dict(msgpack_dict(NAMES)).fixup(fix_length), check::<T>);
    // Enough inputs get past the frame header to test the MessagePack decoding itself.
    report.assert_reaches("ok", 10);
    report.assert_reaches("body refused", 300);
}

fn pose(seq: u64, flags: PoseFlags) -> ServerMessage {
    ServerMessage::Pose(Pose {
        seq,
        device_time_us: seq.wrapping_mul(1000).wrapping_add(17),
        host_monotonic_ns: seq.wrapping_add(123_456_789_000),
        flags,
        element: ElementId::GLOBAL,
        joints_deg: [[1.5, -2.25, 0.0], [3.0, -4.5, 0.1], [6.0, -9.0, 0.2], [-180.0, 180.0, 1e-3]],
        hand: HandWire {
            t: seq as f64 / 1000.0,
            wrist_deg: [10.0, -20.0, 5.0],
            thumb_deg: [30.0, 0.0, -12.5],
        },
    })
}

#[test]
fn fuzz_server_messages() {
    let hello = ServerMessage::Hello(Hello {
        protocol_version: 1,
        daemon_version: "0.1.0".into(),
        rig_name: "grass".into(),
        joint_names: ["root", "low", "high", "tip"].map(String::from).to_vec(),
        tick_rate_hz: 1000,
        elements: Default::default(),
        next_seq: 42,
    });
    let mut stream = frame(&hello);
    for s in 42..46 {
        stream.extend(frame(&pose(s, PoseFlags::HELD | PoseFlags::RECORDING)));
    }
    let seeds = vec![
        frame(&hello),
        frame(&pose(0, PoseFlags::default())),
        frame(&pose(u64::MAX, PoseFlags::DEVICE_LOST | PoseFlags::HELD)),
        frame(&pose(7, PoseFlags(u32::MAX))),
        stream,
    ];
    run::<ServerMessage>(Target::new("protocol-server").seeds(seeds));
}

#[test]
fn fuzz_control_requests() {
    let reqs = [
        ControlRequest::Status,
        ControlRequest::SetRig {
            name: "grass".into(),
            toml: include_str!("../../../rig-files/plants/grass.toml").into(),
        },
        ControlRequest::SetCalibration {
            id: "example".into(),
            toml: include_str!("../../../rig-files/calibrations/example-user.toml").into(),
        },
        ControlRequest::SetFilter { spec: "one-euro:min_cutoff=1,beta=0.007,d_cutoff=1".into() },
        ControlRequest::RecordStart { name: "take-01".into() },
        ControlRequest::RecordStart { name: "../../etc/passwd".into() },
        ControlRequest::RecordStop,
        ControlRequest::Mark { label: "cue \u{1F331}".into() },
        ControlRequest::RawSample,
    ];
    let mut seeds: Vec<Vec<u8>> = reqs.iter().map(frame).collect();
    seeds.push(reqs.iter().flat_map(frame).collect());
    run::<ControlRequest>(Target::new("protocol-control-request").seeds(seeds).max_len(6000));
}

#[test]
fn fuzz_control_replies() {
    let replies = [
        ControlReply::Ok,
        ControlReply::Recording(RecordingStatus {
            name: "t".into(),
            path: "/var/lib/frond/takes/t.take".into(),
            frames: 12_345,
            dropped: 0,
            active: true,
        }),
        ControlReply::RawSample {
            t: 1.5,
            wrist_deg: [1.0, 2.0, 3.0],
            thumb_deg: [4.0, 5.0, 6.0],
            fresh: true,
        },
        ControlReply::Error(ControlError { kind: ControlErrorKind::BadName, message: "no `..`".into() }),
    ];
    let mut seeds: Vec<Vec<u8>> = replies.iter().map(frame).collect();
    // A status reply, written as a MessagePack map so the seed survives new optional fields.
    let status = serde_json::json!({ "Status": {
        "daemon_version": "0.1.0", "uptime_s": 12.5,
        "source": { "kind": "fuse-hidraw", "path": "/run/vhid/hidraw-frond", "connected": true,
                    "reports": 1000, "rejected": 3, "device_seq_gaps": 1 },
        "rig_name": "grass", "calibration_id": "none", "filter": "none", "tick_rate_hz": 1000,
        "achieved_rate_hz": 999.8, "ticks": 12500, "held_ticks": 10, "publish_drops": 0,
        "lateness": { "p50_us": 50.0, "p99_us": 120.0, "p999_us": 300.0, "max_us": 900.0, "samples": 12500 },
        "subscribers": [ { "id": 1, "connected_s": 3.0, "sent": 3000, "dropped": 0 } ],
        "recording": { "name": "t", "path": "/tmp/t.take", "frames": 10, "dropped": 0, "active": true },
        "device_events": ["device lost", "device reopened after 120 ms (2 attempts)"],
        "realtime": "SCHED_OTHER"
    }});
    let body = rmp_serde::to_vec_named(&status).expect("encode status seed");
    let status_frame = raw_frame(&body);
    assert!(
        matches!(decode_frame::<ControlReply>(&status_frame), Ok(Some((ControlReply::Status(_), _)))),
        "the status seed must be a valid reply"
    );
    seeds.push(status_frame);
    run::<ControlReply>(Target::new("protocol-control-reply").seeds(seeds));
}
