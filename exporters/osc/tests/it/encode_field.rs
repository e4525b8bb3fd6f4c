//! A running field in the `frond` namespace, byte by byte against packets written out by hand
//! from the OSC 1.0 spec and the README's table (`,h` big-endian i64, a blob is its i32 size,
//! its bytes and padding to 4; the blobs' own contents little-endian, as the layout the console
//! sends): the definitions bundle, a field frame, the layout chunks riding with frames.

use frond_osc::encode::{Datagrams, FieldEncoder, LAYOUT_CHUNK_BYTES, encode_definitions};
use frond_protocol::field::{FieldControlsWire, FieldDefinition, FieldFrame, FieldLayout, StreamFrame};
use frond_protocol::{ElementId, ElementTable, PoseFlags, RigInfo};

use crate::encode_bytes::{OFFSET, TIMETAG, assert_bytes_eq, bundle, floats, message};

fn be_f64(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_be_bytes()).collect()
}

fn known_frame() -> FieldFrame {
    let mut f = FieldFrame {
        seq: 9,
        host_monotonic_ns: 2_000_000_000,
        flags: PoseFlags::PLAYBACK,
        hand_t: 1.25,
        field: ElementId::new(40),
        tau_s: 3.5,
        controls: FieldControlsWire {
            direction_deg: 90.0,
            speed_m_s: 2.0,
            time_step: 1.0,
            scale: 0.5,
            delays_s: [0.1, 0.2, 0.3],
        },
        produced: 100,
        ..FieldFrame::default()
    };
    let joints = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0], [10.0, 11.0, 12.0]];
    assert!(f.entries.push(StreamFrame { index: 99, joints_deg: joints }));
    f
}

/// `/frond/field/40/frame ,hidddddfdddhb` of [`known_frame`], by hand.
fn known_frame_message() -> Vec<u8> {
    let mut args = 9i64.to_be_bytes().to_vec();
    args.extend(16i32.to_be_bytes()); // playback
    args.extend(be_f64(&[1.25, 3.5, 90.0, 2.0, 1.0]));
    args.extend(floats(&[0.5]));
    args.extend(be_f64(&[0.1, 0.2, 0.3]));
    args.extend(100i64.to_be_bytes());
    args.extend(56i32.to_be_bytes());
    args.extend(99u64.to_le_bytes());
    args.extend((1..=12).flat_map(|a| (a as f32).to_le_bytes()));
    message(b"/frond/field/40/frame\0\0\0", b",hidddddfdddhb\0\0", &args)
}

#[test]
fn a_field_frame_matches_the_hand_written_packet() {
    let mut enc = FieldEncoder::new(OFFSET);
    let mut out = Datagrams::new();
    // A field not set is not encoded.
    assert!(!enc.encode_frame(&known_frame(), None, &mut out).unwrap());
    assert!(out.is_empty());
    enc.set_fields([ElementId::new(40)]);
    assert!(enc.encode_frame(&known_frame(), None, &mut out).unwrap());
    let msg = known_frame_message();
    assert_eq!(msg.len(), 24 + 16 + 88 + 60);
    assert_eq!(out.len(), 1);
    assert_bytes_eq(out.get(0).unwrap(), &bundle(&[&msg]));
}

#[test]
fn layout_chunks_ride_with_a_frame_in_bundles_that_fit() {
    let mut enc = FieldEncoder::new(OFFSET);
    enc.set_fields([ElementId::new(40)]);
    // 2100 bytes: chunks of 1000, 1000 and 100.
    let layout: Vec<u8> = (0..2100u32).map(|i| (i % 251) as u8).collect();
    let mut out = Datagrams::new();
    assert!(enc.encode_frame(&known_frame(), Some((&layout, 0xCBF4_3926, 1..3)), &mut out).unwrap());
    let chunk = |index: i32, bytes: &[u8]| {
        let mut args = (0xCBF4_3926u32 as i32).to_be_bytes().to_vec();
        args.extend(index.to_be_bytes());
        args.extend(3i32.to_be_bytes());
        args.extend((bytes.len() as i32).to_be_bytes());
        args.extend(bytes);
        while !args.len().is_multiple_of(4) {
            args.push(0);
        }
        message(b"/frond/field/40/layout\0\0", b",iiib\0\0\0", &args)
    };
    let (one, two) = (chunk(1, &layout[1000..2000]), chunk(2, &layout[2000..]));
    assert_eq!(one.len(), 24 + 8 + 12 + 4 + LAYOUT_CHUNK_BYTES);
    // Frame + chunk 1 is 1260 bytes with the header, chunk 1 + chunk 2 is 1220: three bundles.
    assert_eq!(out.len(), 3);
    assert_bytes_eq(out.get(0).unwrap(), &bundle(&[&known_frame_message()]));
    assert_bytes_eq(out.get(1).unwrap(), &bundle(&[&one]));
    assert_bytes_eq(out.get(2).unwrap(), &bundle(&[&two]));
    assert!(out.iter().all(|d| d.len() <= 1200));
}

#[test]
fn the_definitions_bundle_matches_the_hand_written_packet() {
    let d = FieldDefinition {
        id: ElementId::new(40),
        source: "field".into(),
        rig: "grass".into(),
        layout: FieldLayout {
            version: 1,
            take: "sway".into(),
            fps: 30.0,
            frames: 60,
            rows: 1,
            cols: 2,
            cell_m: 0.5,
            speed_m_s: 1.0,
            direction_deg: 0.0,
            authored_direction_deg: 15.0,
            density: 1.0,
            seed: 1,
        },
        plants: 2,
        stream_fps: 30.0,
        history_frames: 64,
        publish_hz: 60,
        plant_elements: vec![ElementId::new(41)],
    };
    let table = ElementTable {
        version: 1,
        rigs: vec![RigInfo {
            name: "grass".into(),
            joint_names: ["root", "lower", "middle", "tip"].map(String::from).to_vec(),
        }],
        elements: vec![],
    };
    // CRC-32 of "123456789" is 0xCBF43926 (the algorithm's published check value).
    let layout = b"123456789";
    let mut out = Datagrams::new();
    encode_definitions(&[(&d, layout)], &table, &mut out).unwrap();

    let fields = message(b"/frond/fields\0\0\0", b",i\0\0", &40i32.to_be_bytes());
    let mut args = b"field\0\0\0grass\0\0\0".to_vec();
    for v in [2i32, 1, 2] {
        args.extend(v.to_be_bytes());
    }
    args.extend(30.0f64.to_be_bytes());
    args.extend(64i32.to_be_bytes());
    args.extend(15.0f64.to_be_bytes());
    for v in [60, 0xCBF4_3926u32 as i32, 9, 1000, 1] {
        args.extend(v.to_be_bytes());
    }
    args.extend(2i32.to_be_bytes());
    args.extend([41, 0, 0, 0]); // element 41 as u16 little-endian, padded
    let def = message(b"/frond/field/40/def\0", b",ssiiididiiiiib\0", &args);
    let joints =
        message(b"/frond/field/40/joints\0\0", b",ssss\0\0\0", b"root\0\0\0\0lower\0\0\0middle\0\0tip\0");
    let mut expected = bundle(&[&fields, &def, &joints]);
    expected[8..16].copy_from_slice(&[0, 0, 0, 0, 0, 0, 0, 1]); // timetag "immediately"
    assert_ne!(TIMETAG, [0, 0, 0, 0, 0, 0, 0, 1]);
    assert_eq!(out.len(), 1);
    assert_bytes_eq(out.get(0).unwrap(), &expected);

    // No field running: the empty list, so a receiver forgets the fields it had.
    encode_definitions(&[], &table, &mut out).unwrap();
    let mut empty = bundle(&[&message(b"/frond/fields\0\0\0", b",\0\0\0", &[])]);
    empty[8..16].copy_from_slice(&[0, 0, 0, 0, 0, 0, 0, 1]);
    assert_bytes_eq(out.get(0).unwrap(), &empty);
}
