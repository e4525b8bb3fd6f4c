//! Framing and message tests: round trips, fixed bytes, truncation, garbage, versions.

use frond_protocol::{
    ControlReply, ControlRequest, DecodeError, ElementId, FrameBuf, HandWire, Hello, PROTOCOL_VERSION, Pose,
    PoseFlags, ReadError, ServerMessage, decode_frame, encode_frame, read_frame,
};
use proptest::prelude::*;

fn sample_pose() -> Pose {
    Pose {
        seq: 42,
        device_time_us: 1_234_567,
        host_monotonic_ns: 9_876_543_210,
        flags: PoseFlags::HELD | PoseFlags::FILTERED,
        element: ElementId::GLOBAL,
        joints_deg: [[1.5, -2.0, 0.0], [3.0, 4.0, 0.0], [5.0, 6.0, 7.5], [8.0, 9.0, 7.5]],
        hand: HandWire { t: 1.234567, wrist_deg: [10.0, 20.0, 30.0], thumb_deg: [1.0, 2.0, 3.0] },
    }
}

#[test]
fn hello_encodes_to_these_exact_bytes() {
    // Hand-assembled MessagePack: {"Hello": {"protocol_version":1, "daemon_version":"0.1.0",
    // "rig_name":"grass", "joint_names":["j0"], "tick_rate_hz":1000, "next_seq":7}}
    let hello = ServerMessage::Hello(Hello {
        protocol_version: 1,
        daemon_version: "0.1.0".into(),
        rig_name: "grass".into(),
        joint_names: vec!["j0".into()],
        tick_rate_hz: 1000,
        elements: Default::default(),
        next_seq: 7,
    });
    let mut body = vec![0x81, 0xa5];
    body.extend_from_slice(b"Hello");
    body.push(0x87);
    body.extend_from_slice(&[0xb0]);
    body.extend_from_slice(b"protocol_version");
    body.push(0x01);
    body.push(0xae);
    body.extend_from_slice(b"daemon_version");
    body.push(0xa5);
    body.extend_from_slice(b"0.1.0");
    body.push(0xa8);
    body.extend_from_slice(b"rig_name");
    body.push(0xa5);
    body.extend_from_slice(b"grass");
    body.push(0xab);
    body.extend_from_slice(b"joint_names");
    body.extend_from_slice(&[0x91, 0xa2]);
    body.extend_from_slice(b"j0");
    body.push(0xac);
    body.extend_from_slice(b"tick_rate_hz");
    body.extend_from_slice(&[0xcd, 0x03, 0xe8]);
    // elements: {version: 0, rigs: [], elements: []}
    body.push(0xa8);
    body.extend_from_slice(b"elements");
    body.push(0x83);
    body.push(0xa7);
    body.extend_from_slice(b"version");
    body.push(0x00);
    body.push(0xa4);
    body.extend_from_slice(b"rigs");
    body.push(0x90);
    body.push(0xa8);
    body.extend_from_slice(b"elements");
    body.push(0x90);
    body.push(0xa8);
    body.extend_from_slice(b"next_seq");
    body.push(0x07);
    let mut expected = ((body.len() + 1) as u32).to_le_bytes().to_vec();
    expected.push(PROTOCOL_VERSION);
    expected.extend_from_slice(&body);

    let mut out = Vec::new();
    encode_frame(&hello, &mut out);
    assert_eq!(out, expected);
    let (back, used): (ServerMessage, usize) = decode_frame(&out).unwrap().unwrap();
    assert_eq!(used, out.len());
    assert_eq!(back, hello);
}

#[test]
fn pose_round_trips_and_reuses_the_buffer() {
    let msg = ServerMessage::Pose(sample_pose());
    let mut buf = FrameBuf::with_capacity(512);
    let first = buf.encode(&msg).to_vec();
    let ptr = buf.as_bytes().as_ptr();
    let second = buf.encode(&msg).to_vec();
    assert_eq!(first, second);
    assert_eq!(ptr, buf.as_bytes().as_ptr(), "re-encoding must not reallocate");
    let (back, _): (ServerMessage, usize) = decode_frame(&first).unwrap().unwrap();
    assert_eq!(back, msg);
}

#[test]
fn partial_frames_ask_for_more() {
    let mut out = Vec::new();
    encode_frame(&ServerMessage::Pose(sample_pose()), &mut out);
    for cut in 0..out.len() {
        assert_eq!(decode_frame::<ServerMessage>(&out[..cut]), Ok(None), "cut at {cut}");
    }
}

#[test]
fn newer_version_is_refused_with_a_clear_message() {
    let mut out = Vec::new();
    encode_frame(&ServerMessage::Pose(sample_pose()), &mut out);
    out[4] = PROTOCOL_VERSION + 1;
    let err = decode_frame::<ServerMessage>(&out).unwrap_err();
    assert_eq!(
        err,
        DecodeError::UnsupportedVersion { got: PROTOCOL_VERSION + 1, supported: PROTOCOL_VERSION }
    );
    assert!(err.to_string().contains("not supported"), "{err}");
}

#[test]
fn oversized_and_empty_lengths_are_refused_from_the_header() {
    let huge = (u32::MAX).to_le_bytes();
    assert!(matches!(decode_frame::<ServerMessage>(&huge), Err(DecodeError::TooLarge { .. })));
    assert_eq!(decode_frame::<ServerMessage>(&[0, 0, 0, 0]), Err(DecodeError::EmptyFrame));
}

#[test]
fn trailing_bytes_inside_a_frame_are_an_error() {
    let mut out = Vec::new();
    encode_frame(&ControlRequest::Status, &mut out);
    out.push(0xc0); // nil after the message
    let len = (out.len() - 4) as u32;
    out[..4].copy_from_slice(&len.to_le_bytes());
    assert_eq!(decode_frame::<ControlRequest>(&out), Err(DecodeError::TrailingBytes(1)));
}

#[test]
fn read_frame_reports_closed_and_truncated_streams() {
    let mut empty: &[u8] = &[];
    assert!(matches!(read_frame::<ControlRequest, _>(&mut empty, &mut Vec::new()), Err(ReadError::Closed)));
    let mut out = Vec::new();
    encode_frame(&ControlRequest::RecordStart { name: "t1".into() }, &mut out);
    let mut cut: &[u8] = &out[..out.len() - 2];
    assert!(matches!(
        read_frame::<ControlRequest, _>(&mut cut, &mut Vec::new()),
        Err(ReadError::Truncated { .. })
    ));
    let mut whole: &[u8] = &out;
    assert_eq!(
        read_frame::<ControlRequest, _>(&mut whole, &mut Vec::new()).unwrap(),
        ControlRequest::RecordStart { name: "t1".into() }
    );
}

#[test]
fn limited_reads_refuse_big_frames_before_reading_them() {
    let mut out = Vec::new();
    encode_frame(&ControlRequest::SetRig { name: "big".into(), toml: "x".repeat(10_000) }, &mut out);
    let mut r: &[u8] = &out;
    let err =
        frond_protocol::read_frame_limited::<ControlRequest, _>(&mut r, &mut Vec::new(), 1000).unwrap_err();
    assert!(matches!(err, ReadError::Decode(DecodeError::TooLarge { max: 1000, .. })), "{err}");
    // Only the header was consumed.
    assert_eq!(r.len(), out.len() - frond_protocol::HEADER_LEN);
    let mut r: &[u8] = &out;
    assert!(frond_protocol::read_frame_limited::<ControlRequest, _>(&mut r, &mut Vec::new(), 20_000).is_ok());
}

#[test]
fn a_control_request_is_not_a_server_message() {
    let mut out = Vec::new();
    encode_frame(&ControlRequest::Status, &mut out);
    assert!(matches!(decode_frame::<ServerMessage>(&out), Err(DecodeError::Malformed(_))));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 4096, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = decode_frame::<ServerMessage>(&bytes);
        let _ = decode_frame::<ControlRequest>(&bytes);
        let _ = decode_frame::<ControlReply>(&bytes);
        let mut r: &[u8] = &bytes;
        let _ = read_frame::<ControlRequest, _>(&mut r, &mut Vec::new());
    }

    #[test]
    fn valid_header_with_garbage_body_never_panics(body in proptest::collection::vec(any::<u8>(), 0..256)) {
        let mut frame = ((body.len() + 1) as u32).to_le_bytes().to_vec();
        frame.push(PROTOCOL_VERSION);
        frame.extend_from_slice(&body);
        let _ = decode_frame::<ServerMessage>(&frame);
        let _ = decode_frame::<ControlRequest>(&frame);
    }

    #[test]
    fn poses_round_trip(seq in any::<u64>(), t in any::<u64>(), flags in any::<u32>(),
                        joints in proptest::array::uniform12(-720.0f32..720.0)) {
        let mut pose = sample_pose();
        pose.seq = seq;
        pose.device_time_us = t;
        pose.flags = PoseFlags(flags);
        for (i, v) in joints.iter().enumerate() {
            pose.joints_deg[i / 3][i % 3] = *v;
        }
        let mut out = Vec::new();
        encode_frame(&ServerMessage::Pose(pose), &mut out);
        let (back, used): (ServerMessage, usize) = decode_frame(&out).unwrap().unwrap();
        prop_assert_eq!(used, out.len());
        prop_assert_eq!(back, ServerMessage::Pose(pose));
    }

    #[test]
    fn concatenated_frames_decode_in_order(names in proptest::collection::vec("[a-z]{1,12}", 1..8)) {
        let mut stream = Vec::new();
        for n in &names {
            encode_frame(&ControlRequest::RecordStart { name: n.clone() }, &mut stream);
        }
        let mut at = 0;
        for n in &names {
            let (msg, used): (ControlRequest, usize) = decode_frame(&stream[at..]).unwrap().unwrap();
            prop_assert_eq!(msg, ControlRequest::RecordStart { name: n.clone() });
            at += used;
        }
        prop_assert_eq!(at, stream.len());
    }
}
