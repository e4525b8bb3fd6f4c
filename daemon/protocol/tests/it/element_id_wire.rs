//! Element ids on the wire: a [`Pose`]'s element and an [`ElementTable`]'s ids encode as plain
//! MessagePack unsigned integers, byte for byte what a bare `u16` gave before [`ElementId`]
//! existed (the expected bytes below were taken from that encoder, commit b151c7a).

use frond_protocol::{
    ElementId, ElementInfo, ElementKind, ElementTable, HandWire, Pose, PoseFlags, RigInfo, ServerMessage,
    decode_frame, encode_frame,
};

fn pose(element: u16) -> ServerMessage {
    ServerMessage::Pose(Pose {
        seq: 7,
        device_time_us: 1,
        host_monotonic_ns: 2,
        flags: PoseFlags::PLAYBACK,
        element: ElementId::new(element),
        joints_deg: [[0.0; 3]; 4],
        hand: HandWire { t: 0.5, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3] },
    })
}

fn table() -> ServerMessage {
    let info = |id: u16, name: &str, kind| ElementInfo {
        id: ElementId::new(id),
        name: name.into(),
        kind,
        source: "s".into(),
        rig: "grass".into(),
    };
    ServerMessage::Elements(ElementTable {
        version: 3,
        rigs: vec![RigInfo { name: "grass".into(), joint_names: vec!["j0".into()] }],
        elements: vec![
            info(0, "grass", ElementKind::Hand),
            info(32, "leaf", ElementKind::Layer),
            info(200, "field/plant0", ElementKind::FieldPlant),
            info(65535, "field/plant1", ElementKind::FieldPlant),
        ],
    })
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// `Pose` frames whose element is 0, 33, 200, 300 and 65535: the element is MessagePack's
/// smallest unsigned form (positive fixint, `uint 8`, `uint 16`), as for a `u16`.
#[test]
fn pose_element_encodes_as_the_bare_number() {
    const HEAD: &str = "0000000381a4506f736587a373657107ae6465766963655f74696d655f757301b1686f73745f6d6f6e6f746f6e69635f6e7302a5666c61677310a7656c656d656e74";
    const TAIL: &str = "aa6a6f696e74735f6465679493ca00000000ca00000000ca0000000093ca00000000ca00000000ca0000000093ca00000000ca00000000ca0000000093ca00000000ca00000000ca00000000a468616e6483a174cb3fe0000000000000a977726973745f64656793ca00000000ca00000000ca00000000a97468756d625f64656793ca00000000ca00000000ca00000000";
    for (element, len, field) in [
        (0u16, "d1", "00"),
        (33, "d1", "21"),
        (200, "d2", "ccc8"),
        (300, "d3", "cd012c"),
        (65535, "d3", "cdffff"),
    ] {
        let mut out = Vec::new();
        encode_frame(&pose(element), &mut out);
        assert_eq!(hex(&out), format!("{len}{HEAD}{field}{TAIL}"), "element {element}");
        let (back, _) = decode_frame::<ServerMessage>(&out).unwrap().unwrap();
        assert_eq!(back, pose(element));
    }
}

/// An `Elements` table with ids 0, 32, 200 and 65535.
#[test]
fn element_table_ids_encode_as_bare_numbers() {
    const TABLE: &str = "140100000381a8456c656d656e747383a776657273696f6e03a4726967739182a46e616d65a56772617373ab6a6f696e745f6e616d657391a26a30a8656c656d656e74739485a2696400a46e616d65a56772617373a46b696e64a468616e64a6736f75726365a173a3726967a5677261737385a2696420a46e616d65a46c656166a46b696e64a56c61796572a6736f75726365a173a3726967a5677261737385a26964ccc8a46e616d65ac6669656c642f706c616e7430a46b696e64ab6669656c642d706c616e74a6736f75726365a173a3726967a5677261737385a26964cdffffa46e616d65ac6669656c642f706c616e7431a46b696e64ab6669656c642d706c616e74a6736f75726365a173a3726967a56772617373";
    let mut out = Vec::new();
    encode_frame(&table(), &mut out);
    assert_eq!(hex(&out), TABLE);
    let (back, _) = decode_frame::<ServerMessage>(&out).unwrap().unwrap();
    assert_eq!(back, table());
}
