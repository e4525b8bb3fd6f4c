//! Byte-level checks of the encoders against packets written out by hand from the OSC 1.0 spec
//! (address and type-tag strings null-terminated and padded to 4 bytes, big-endian arguments,
//! `#bundle\0` + 8-byte timetag + `[u32 size][message]` elements), plus bundle splitting and
//! quaternion norms.

use frond_osc::encode::{
    ClockOffset, Datagrams, EncodeError, FrondEncoder, MAX_DATAGRAM_BYTES, VmcEncoder, VmcRig,
};
use frond_protocol::{ElementId, HandWire, Pose, PoseFlags};
use rosc::{OscPacket, OscType};

/// Monotonic 2.0 s is wall-clock 1_700_000_000.5 s since 1970.
pub(crate) const OFFSET: ClockOffset = ClockOffset::fixed(1_700_000_000_500_000_000 - 2_000_000_000);
/// 1_700_000_000 + 2_208_988_800 = 3_908_988_800 = 0xE8FE_6F80; 0.5 s = 0x8000_0000.
pub(crate) const TIMETAG: [u8; 8] = [0xE8, 0xFE, 0x6F, 0x80, 0x80, 0x00, 0x00, 0x00];

const S: f32 = std::f32::consts::FRAC_1_SQRT_2; // sin 45 = cos 45
const COS30: f32 = 0.866_025_4;

fn known_pose() -> Pose {
    Pose {
        seq: 7,
        device_time_us: 1_500_000,
        host_monotonic_ns: 2_000_000_000,
        flags: PoseFlags::FILTERED,
        element: ElementId::GLOBAL,
        // Joint 0 pitched 90, joint 1 untouched, joint 2 yawed -90, joint 3 rolled 60.
        joints_deg: [[90.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, -90.0, 0.0], [0.0, 0.0, 60.0]],
        hand: HandWire { t: 1.5, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3] },
    }
}

pub(crate) fn bundle(elements: &[&[u8]]) -> Vec<u8> {
    let mut out = b"#bundle\0".to_vec();
    out.extend_from_slice(&TIMETAG);
    for e in elements {
        out.extend_from_slice(&(e.len() as u32).to_be_bytes());
        out.extend_from_slice(e);
    }
    out
}

pub(crate) fn floats(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_be_bytes()).collect()
}

pub(crate) fn message(addr_padded: &[u8], tags_padded: &[u8], args: &[u8]) -> Vec<u8> {
    assert_eq!(addr_padded.len() % 4, 0, "test bug: address not padded");
    assert_eq!(tags_padded.len() % 4, 0, "test bug: tags not padded");
    [addr_padded, tags_padded, args].concat()
}

fn expected_pose_args(seq: i32, t: f64, joints: [f32; 12]) -> Vec<u8> {
    let mut a = seq.to_be_bytes().to_vec();
    a.extend_from_slice(&t.to_be_bytes());
    a.extend(floats(&joints));
    a
}

#[test]
fn frond_bundle_matches_the_hand_written_packet() {
    let pose_msg = message(
        b"/frond/pose\0",
        b",idffffffffffff\0",
        &expected_pose_args(7, 1.5, [90.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -90.0, 0.0, 0.0, 0.0, 60.0]),
    );
    assert_eq!(pose_msg.len(), 12 + 16 + 4 + 8 + 48);
    let q0 = message(b"/frond/joint/0/quat\0", b",ffff\0\0\0", &floats(&[S, 0.0, 0.0, S]));
    let q1 = message(b"/frond/joint/1/quat\0", b",ffff\0\0\0", &floats(&[0.0, 0.0, 0.0, 1.0]));
    let q2 = message(b"/frond/joint/2/quat\0", b",ffff\0\0\0", &floats(&[0.0, 0.0, -S, S]));
    let q3 = message(b"/frond/joint/3/quat\0", b",ffff\0\0\0", &floats(&[0.0, 0.5, 0.0, COS30]));
    // flags: filtered = 4
    let status = message(b"/frond/status\0\0\0", b",i\0\0", &[0, 0, 0, 4]);
    let expected = bundle(&[&pose_msg, &q0, &q1, &q2, &q3, &status]);
    assert_eq!(expected.len(), 328);

    let mut enc = FrondEncoder::new(OFFSET);
    let mut out = Datagrams::new();
    enc.encode(&known_pose(), &mut out).unwrap();
    assert_eq!(out.len(), 1);
    assert_bytes_eq(out.get(0).unwrap(), &expected);

    // A second frame reuses the buffers and replaces the first.
    let mut next = known_pose();
    next.seq = 8;
    enc.encode(&next, &mut out).unwrap();
    assert_eq!(out.len(), 1);
    assert_eq!(&out.get(0).unwrap()[16 + 4 + 28..16 + 4 + 32], &8i32.to_be_bytes());
}

#[test]
fn seq_is_sent_as_its_low_32_bits() {
    let mut pose = known_pose();
    pose.seq = (1u64 << 32) + 0xFFFF_FFFE; // low 32 bits = -2 as i32
    let mut out = Datagrams::new();
    FrondEncoder::new(OFFSET).encode(&pose, &mut out).unwrap();
    // bundle header 16, element size 4, address 12, tags 16
    assert_eq!(&out.get(0).unwrap()[48..52], &[0xFF, 0xFF, 0xFF, 0xFE]);
}

#[test]
fn device_lost_frames_carry_the_flag_in_frond_status() {
    let mut pose = known_pose();
    pose.flags = PoseFlags::DEVICE_LOST | PoseFlags::HELD;
    let mut out = Datagrams::new();
    FrondEncoder::new(OFFSET).encode(&pose, &mut out).unwrap();
    let d = out.get(0).unwrap();
    let status = message(b"/frond/status\0\0\0", b",i\0\0", &[0, 0, 0, 3]);
    let mut tail = 24u32.to_be_bytes().to_vec();
    tail.extend(status);
    assert!(d.ends_with(&tail), "status element at the end of the bundle");
}

#[test]
fn secondary_elements_get_their_own_message() {
    let mut pose = known_pose();
    pose.element = ElementId::new(2);
    let mut out = Datagrams::new();
    FrondEncoder::new(OFFSET).encode(&pose, &mut out).unwrap();
    let msg = message(
        b"/frond/element/2/pose\0\0\0",
        b",idffffffffffff\0",
        &expected_pose_args(7, 1.5, [90.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -90.0, 0.0, 0.0, 0.0, 60.0]),
    );
    assert_bytes_eq(out.get(0).unwrap(), &bundle(&[&msg]));
}

fn exact_rig() -> VmcRig {
    VmcRig {
        bone_names: ["joint0", "joint1", "joint2", "joint3"].map(String::from),
        heights_m: [0.0, 0.25, 0.5, 1.0],
    }
}

#[test]
fn vmc_bundle_matches_the_hand_written_packet() {
    let bone = |name: &[u8], pos: [f32; 3], rot: [f32; 4]| {
        message(
            b"/VMC/Ext/Bone/Pos\0\0\0",
            b",sfffffff\0\0\0",
            &[name, &floats(&pos), &floats(&rot)].concat(),
        )
    };
    let root = message(
        b"/VMC/Ext/Root/Pos\0\0\0",
        b",sfffffff\0\0\0",
        &[b"root\0\0\0\0".as_slice(), &floats(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])].concat(),
    );
    // Unity frame: positions (x, y, z) -> (-x, y, z), rotations (x, y, z, w) -> (x, -y, -z, w).
    let b0 = bone(b"joint0\0\0", [0.0, 0.0, 0.0], [S, 0.0, 0.0, S]);
    let b1 = bone(b"joint1\0\0", [0.0, 0.25, 0.0], [0.0, 0.0, 0.0, 1.0]);
    let b2 = bone(b"joint2\0\0", [0.0, 0.25, 0.0], [0.0, 0.0, S, S]);
    let b3 = bone(b"joint3\0\0", [0.0, 0.5, 0.0], [0.0, -0.5, 0.0, COS30]);
    // loaded 1, calibration state 3 (calibrated), mode 0 (normal), tracking 1 (ok)
    let ok = message(b"/VMC/Ext/OK\0", b",iiii\0\0\0", &[0, 0, 0, 1, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 1]);
    let t = message(b"/VMC/Ext/T\0\0", b",f\0\0", &floats(&[1.5]));
    let expected = bundle(&[&root, &b0, &b1, &b2, &b3, &ok, &t]);
    assert_eq!(expected.len(), 440);

    let mut enc = VmcEncoder::new(OFFSET, exact_rig());
    let mut out = Datagrams::new();
    enc.encode(&known_pose(), &mut out).unwrap();
    assert_eq!(out.len(), 1);
    assert_bytes_eq(out.get(0).unwrap(), &expected);

    // Device lost: tracking status 0.
    let mut lost = known_pose();
    lost.flags = PoseFlags::DEVICE_LOST;
    enc.encode(&lost, &mut out).unwrap();
    let ok_lost =
        message(b"/VMC/Ext/OK\0", b",iiii\0\0\0", &[0, 0, 0, 1, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 0]);
    assert_bytes_eq(out.get(0).unwrap(), &bundle(&[&root, &b0, &b1, &b2, &b3, &ok_lost, &t]));
}

fn decode_bundle(d: &[u8]) -> rosc::OscBundle {
    match rosc::decoder::decode_udp(d).expect("decodes").1 {
        OscPacket::Bundle(b) => b,
        OscPacket::Message(m) => panic!("expected a bundle, got message {}", m.addr),
    }
}

#[test]
fn vmc_bundles_are_split_at_1200_bytes() {
    let mut rig = exact_rig();
    // 250-byte names: each Bone/Pos message is 20 + 12 + 252 + 28 = 312 bytes.
    rig.bone_names = std::array::from_fn(|i| format!("{i}{}", "b".repeat(249)));
    let mut out = Datagrams::new();
    VmcEncoder::new(OFFSET, rig.clone()).encode(&known_pose(), &mut out).unwrap();
    // First: header 16 + root (4+68) + 3 bones (4+312) = 1036; a fourth bone would make 1352.
    // Second: header 16 + bone (4+312) + OK (4+36) + T (4+20) = 396.
    let sizes: Vec<usize> = out.iter().map(<[u8]>::len).collect();
    assert_eq!(sizes, [1036, 396]);
    let mut addrs = Vec::new();
    for d in out.iter() {
        assert!(d.len() <= MAX_DATAGRAM_BYTES);
        assert_eq!(&d[8..16], &TIMETAG, "every part carries the frame's timetag");
        for p in decode_bundle(d).content {
            let OscPacket::Message(m) = p else { panic!("nested bundle") };
            let name = match m.args.first() {
                Some(OscType::String(s)) => s.chars().next().unwrap().to_string(),
                _ => String::new(),
            };
            addrs.push(format!("{}{}", m.addr, name));
        }
    }
    assert_eq!(
        addrs,
        [
            "/VMC/Ext/Root/Posr",
            "/VMC/Ext/Bone/Pos0",
            "/VMC/Ext/Bone/Pos1",
            "/VMC/Ext/Bone/Pos2",
            "/VMC/Ext/Bone/Pos3",
            "/VMC/Ext/OK",
            "/VMC/Ext/T"
        ]
    );

    // A name so long that one message cannot fit any datagram is an error, not a bad packet.
    rig.bone_names[1] = "x".repeat(1200);
    let err = VmcEncoder::new(OFFSET, rig).encode(&known_pose(), &mut out).unwrap_err();
    assert!(
        matches!(err, EncodeError::MessageTooLarge { ref address, bytes } if address == "/VMC/Ext/Bone/Pos" && bytes > 1200),
        "{err}"
    );
}

#[test]
fn bundle_just_under_the_limit_is_not_split() {
    // With padded name length P, a bone message is 20 + 12 + P + 28 = 60 + P bytes and the whole
    // frame 16 (header) + 7 * 4 (sizes) + 68 (root) + 36 (OK) + 20 (T) + 4 * (60 + P) = 408 + 4P.
    // 195-byte names pad to P = 196: 1192 bytes, one datagram.
    let mut rig = exact_rig();
    rig.bone_names = std::array::from_fn(|i| format!("{i}{}", "n".repeat(194)));
    let mut out = Datagrams::new();
    VmcEncoder::new(OFFSET, rig.clone()).encode(&known_pose(), &mut out).unwrap();
    assert_eq!(out.iter().map(<[u8]>::len).collect::<Vec<_>>(), [1192]);
    // 197-byte names pad to P = 200: 1208 bytes, over the limit: split.
    rig.bone_names = std::array::from_fn(|i| format!("{i}{}", "n".repeat(196)));
    VmcEncoder::new(OFFSET, rig).encode(&known_pose(), &mut out).unwrap();
    assert_eq!(out.len(), 2);
    assert!(out.iter().all(|d| d.len() <= MAX_DATAGRAM_BYTES));
}

fn norm(q: &[f32]) -> f64 {
    q.iter().map(|c| f64::from(*c).powi(2)).sum::<f64>().sqrt()
}

fn floats_of(m: &rosc::OscMessage, skip: usize) -> Vec<f32> {
    m.args[skip..]
        .iter()
        .map(|a| match a {
            OscType::Float(f) => *f,
            other => panic!("{}: expected float, got {other:?}", m.addr),
        })
        .collect()
}

#[test]
fn quaternions_are_unit_in_both_dialects() {
    let mut frond = FrondEncoder::new(OFFSET);
    let mut vmc = VmcEncoder::new(OFFSET, exact_rig());
    let mut out = Datagrams::new();
    let mut checked = 0;
    for k in 0..200 {
        let a = |m: i32, o: i32| ((k * m + o) % 361 - 180) as f32 + 0.37;
        let mut pose = known_pose();
        pose.joints_deg = [
            [a(7, 1), a(13, 5), a(29, 11)],
            [a(3, 2), a(17, 3), a(5, 7)],
            [a(11, 1), a(19, 2), a(23, 3)],
            [a(31, 4), a(37, 6), a(41, 8)],
        ];
        frond.encode(&pose, &mut out).unwrap();
        for p in decode_bundle(out.get(0).unwrap()).content {
            let OscPacket::Message(m) = p else { unreachable!() };
            if m.addr.ends_with("/quat") {
                assert!((norm(&floats_of(&m, 0)) - 1.0).abs() < 1e-6, "{} {:?}", m.addr, m.args);
                checked += 1;
            }
        }
        vmc.encode(&pose, &mut out).unwrap();
        for p in decode_bundle(out.get(0).unwrap()).content {
            let OscPacket::Message(m) = p else { unreachable!() };
            if m.addr.ends_with("/Pos") {
                let f = floats_of(&m, 1);
                assert!((norm(&f[3..7]) - 1.0).abs() < 1e-6, "{} {:?}", m.addr, m.args);
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 200 * (4 + 5));
}

pub(crate) fn assert_bytes_eq(got: &[u8], expected: &[u8]) {
    if got != expected {
        let at = got.iter().zip(expected).position(|(a, b)| a != b).unwrap_or(got.len().min(expected.len()));
        let lo = at.saturating_sub(8);
        panic!(
            "packets differ at byte {at} (lengths {} vs {} expected)\n got      {:02x?}\n expected {:02x?}",
            got.len(),
            expected.len(),
            &got[lo..(at + 8).min(got.len())],
            &expected[lo..(at + 8).min(expected.len())]
        );
    }
}

#[test]
fn the_names_bundle_names_the_rig_and_every_element() {
    use frond_protocol::{ElementInfo, ElementKind, ElementTable, RigInfo};
    let names = |v: [&str; 4]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let table = ElementTable {
        version: 3,
        rigs: vec![RigInfo {
            name: "flower".into(),
            joint_names: names(["root", "stem_low", "stem_high", "head"]),
        }],
        elements: vec![
            ElementInfo {
                id: ElementId::GLOBAL,
                name: "flower".into(),
                kind: ElementKind::Hand,
                source: "hand".into(),
                rig: "flower".into(),
            },
            ElementInfo {
                id: ElementId::FIRST_LAYER,
                name: "leaf#1".into(),
                kind: ElementKind::Layer,
                source: "layer".into(),
                rig: "flower".into(),
            },
        ],
    };
    let mut out = Datagrams::new();
    let joints = names(["root", "stem_low", "stem_high", "head"]);
    FrondEncoder::new(OFFSET).encode_names("flower", &joints, &table, &mut out).unwrap();
    assert_eq!(out.len(), 1);
    let b = decode_bundle(out.get(0).unwrap());
    assert_eq!(b.timetag, rosc::OscTime { seconds: 0, fractional: 1 }, "immediately");
    let msgs: Vec<(String, Vec<String>)> = b
        .content
        .iter()
        .map(|p| match p {
            OscPacket::Message(m) => {
                (m.addr.clone(), m.args.iter().map(|a| a.clone().string().expect("string args")).collect())
            }
            OscPacket::Bundle(_) => panic!("nested bundle"),
        })
        .collect();
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    assert_eq!(
        msgs,
        vec![
            ("/frond/rig".to_string(), s(&["flower", "root", "stem_low", "stem_high", "head"])),
            (
                "/frond/element/1/info".to_string(),
                s(&["leaf#1", "layer", "flower", "root", "stem_low", "stem_high", "head"])
            ),
        ]
    );
    // The message bytes as the spec lays them out: address, ",sssss", padded strings.
    let raw = out.get(0).unwrap();
    let rig_msg = message(
        b"/frond/rig\0\0",
        b",sssss\0\0",
        b"flower\0\0root\0\0\0\0stem_low\0\0\0\0stem_high\0\0\0head\0\0\0\0",
    );
    assert!(raw.windows(rig_msg.len()).any(|w| w == rig_msg.as_slice()), "the /frond/rig bytes");
}
