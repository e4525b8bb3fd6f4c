//! The wire format against the published examples, written here by hand from the vendors'
//! pages (not from the crate's code): Vicon's "UDP capture broadcast/trigger" start example,
//! a stop as public senders built on that page write it, Rokoko Studio's start and stop, a
//! minimal one from StretchSense's notes, and NOKOV's; then garbage, and properties.

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use frond_ltc::SmpteTime;
use frond_triggers::{
    DecodeError, Leader, MAX_DATAGRAM_BYTES, StopResult, TriggerFields, TriggerMessage, TriggerSocket,
    decode, encode,
};
use proptest::prelude::*;

/// Vicon's start example with the white space between tokens removed, as the page says the
/// real packet is, and NUL-terminated ("the packet contents are null terminated").
const VICON_START: &[u8] = b"<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStart>\
<Name VALUE=\"dance\"/><Notes VALUE=\"The pets ants crime deer jump. \"/>\
<Description VALUE=\"The crowd pencil pets alert fold deer. With welcome practice representative complete great? \
Or jolly tiny memorise thread. However wool insect pipe! \"/><DatabasePath VALUE=\"D:/Jeremy/Susan/Captures/Take\"/>\
<Delay VALUE=\"33\"/><PacketID VALUE=\"33360\"/></CaptureStart>\0";

const VICON_STOP: &[u8] =
    b"<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStop RESULT=\"SUCCESS\">\
<Name VALUE=\"dance\"/><DatabasePath VALUE=\"D:/Jeremy/Susan/Captures/Take\"/><Delay VALUE=\"0\"/>\
<PacketID VALUE=\"33361\"/></CaptureStop>\0";

const ROKOKO_START: &str = r#"<?xml version="1.0" encoding="UTF-8" standalone="no" ?>
<CaptureStart>
    <Name VALUE="RemoteTriggerTest_take01"/>
    <TimeCode VALUE="00:00:00:00"/>
    <PacketID VALUE="0"/>
    <ProcessID VALUE="optional process id" />
</CaptureStart>"#;

const ROKOKO_STOP: &str = r#"<?xml version="1.0" encoding="utf-8"?>
<CaptureStop>
    <Name VALUE="TakeName" />
    <TimeCode VALUE="01:02:03:04" />
    <SetActiveClip VALUE="False"/>
    <ProcessID VALUE="optional process id" />
</CaptureStop>"#;

fn vicon_start_message() -> TriggerMessage {
    TriggerMessage::Start(TriggerFields {
        name: Some("dance".into()),
        notes: Some("The pets ants crime deer jump. ".into()),
        description: Some(
            "The crowd pencil pets alert fold deer. With welcome practice representative complete great? Or jolly \
             tiny memorise thread. However wool insect pipe! "
                .into(),
        ),
        database_path: Some("D:/Jeremy/Susan/Captures/Take".into()),
        delay_ms: Some(33),
        packet_id: Some(33360),
        ..TriggerFields::default()
    })
}

#[test]
fn vicons_published_start_decodes_and_encodes_to_the_same_bytes() {
    let message = decode(VICON_START).unwrap();
    assert_eq!(message, vicon_start_message());
    let mut buf = Vec::new();
    encode(&message, &mut buf).unwrap();
    assert_eq!(buf, VICON_START, "{}", String::from_utf8_lossy(&buf));
    // The page's indented rendering is the same message.
    let indented = String::from_utf8_lossy(VICON_START).replace("><", ">\n  <").replace('\0', "\n");
    assert_eq!(decode(indented.as_bytes()).unwrap(), message);
}

#[test]
fn a_vicon_stop_round_trips_byte_for_byte() {
    let message = decode(VICON_STOP).unwrap();
    let TriggerMessage::Stop { fields, result } = &message else { panic!("{message:?}") };
    assert_eq!(*result, StopResult::Success);
    assert_eq!(
        (fields.name.as_deref(), fields.packet_id, fields.delay_ms),
        (Some("dance"), Some(33361), Some(0))
    );
    let mut buf = vec![0xAA; 3]; // a used buffer is cleared and reused
    encode(&message, &mut buf).unwrap();
    assert_eq!(buf, VICON_STOP);
}

#[test]
fn rokoko_stretchsense_and_nokov_examples_decode() {
    let TriggerMessage::Start(f) = decode(ROKOKO_START.as_bytes()).unwrap() else { panic!() };
    assert_eq!(f.name.as_deref(), Some("RemoteTriggerTest_take01"));
    assert_eq!(f.timecode, None, "00:00:00:00 means no timecode");
    assert_eq!((f.packet_id, f.process_id.as_deref()), (Some(0), Some("optional process id")));
    let TriggerMessage::Stop { fields, result } = decode(ROKOKO_STOP.as_bytes()).unwrap() else { panic!() };
    assert_eq!(result, StopResult::Unspecified);
    assert_eq!(
        fields.timecode,
        Some(SmpteTime { hours: 1, minutes: 2, seconds: 3, frames: 4, drop_frame: false })
    );
    assert_eq!(fields.packet_id, None);
    let minimal = r#"<?xml version="1.0" encoding="UTF-8" standalone="no" ?> <CaptureStart> <Name VALUE="RemoteTriggerTest_take01"/> </CaptureStart>"#;
    assert!(matches!(decode(minimal.as_bytes()).unwrap(), TriggerMessage::Start(_)));
    let nokov = "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\" ?>\n<CaptureStart>\n\
        <Name VALUE=\"RemoteTriggerTest_take0116\" />\n<DatabasePath VALUE=\"F:\\20230712\\test1\" />\n\
        <Notes VALUE=\"This is Beijing NOKOV Science &amp; Technology Co., Ltd Motion Capture Start Msg\" />\n\
        <Description VALUE=\"NULL\" />\n<Delay VALUE=\"33\" />\n<PacketID VALUE=\"10028\" />\n</CaptureStart>";
    let TriggerMessage::Start(f) = decode(nokov.as_bytes()).unwrap() else { panic!() };
    assert!(f.notes.unwrap().contains("Science & Technology"));
    let df = r#"<CaptureStart><Name VALUE="a"/><TimeCode VALUE="10:00:00;02"/></CaptureStart>"#;
    let TriggerMessage::Start(f) = decode(df.as_bytes()).unwrap() else { panic!() };
    assert!(f.timecode.unwrap().drop_frame);
}

#[test]
fn garbage_is_refused_with_the_problem_named() {
    let start = |inner: &str| format!("<CaptureStart>{inner}</CaptureStart>");
    let laughs = r#"<?xml version="1.0"?><!DOCTYPE l [<!ENTITY a "aaaaaaaa"><!ENTITY b "&a;&a;&a;&a;">]><CaptureStart><Name VALUE="&b;"/></CaptureStart>"#;
    let many: String = start(&"<X VALUE=\"1\"/>".repeat(100));
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (vec![b'<'; MAX_DATAGRAM_BYTES + 1], "over the 16384-byte limit"),
        (b"\0\0\n".to_vec(), "datagram is empty"),
        (b"<CaptureStart>\xff</CaptureStart>".to_vec(), "not UTF-8"),
        (laughs.into(), "document type declaration is refused"),
        (b"<CaptureComplete/>".to_vec(), "<CaptureComplete> is not a capture trigger"),
        (b"<?xml version=\"1.0\"?>".to_vec(), "no CaptureStart or CaptureStop"),
        (many.into(), "more than 64 elements"),
        (start("<Name VALUE=\"a\"><Name VALUE=\"b\"/></Name>").into(), "nested inside a field"),
        (start("<Name VALUE=\"a\"/><Name VALUE=\"b\"/>").into(), "<Name> appears twice"),
        (start("<Name/>").into(), "<Name> has no VALUE"),
        (start(&format!("<Name VALUE=\"{}\"/>", "n".repeat(2000))).into(), "<Name> VALUE is 2000 bytes"),
        (start("<Delay VALUE=\"-1\"/>").into(), "<Delay> VALUE \"-1\" is not a whole number"),
        (start("<Delay VALUE=\"3600000\"/>").into(), "from 0 to 60000"),
        (start("<PacketID VALUE=\"99999999999999999999999\"/>").into(), "<PacketID>"),
        (start("<TimeCode VALUE=\"25:00:00:00\"/>").into(), "<TimeCode>: timecode hours 25"),
        (b"<CaptureStop RESULT=\"MAYBE\"/>".to_vec(), "RESULT \"MAYBE\""),
        (b"<CaptureStart/><CaptureStop/>".to_vec(), "content after the end"),
        (b"<CaptureStart><Name VALUE=\"a\"/>".to_vec(), "ends before its root element closes"),
        (b"<CaptureStart><Name VALUE=\"&undefined;\"/></CaptureStart>".to_vec(), "malformed XML"),
    ];
    for (bytes, expected) in cases {
        let err = decode(&bytes).expect_err(expected).to_string();
        assert!(err.contains(expected), "expected {expected:?}, got {err:?}");
    }
    assert_eq!(
        decode(&vec![b' '; MAX_DATAGRAM_BYTES + 1]),
        Err(DecodeError::Oversized(MAX_DATAGRAM_BYTES + 1))
    );
}

#[test]
fn the_socket_hears_a_senders_datagram_and_frond_leading_sends_the_format() {
    let mut frond = TriggerSocket::bind((Ipv4Addr::LOCALHOST, 0).into()).unwrap();
    let stage = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
    stage.send_to(VICON_START, frond.local_addr().unwrap()).unwrap();
    let deadline = Instant::now() + Duration::from_secs(5);
    let (from, message) = loop {
        if let Some(got) = frond.recv().unwrap() {
            break (got.from, decode(got.bytes).unwrap());
        }
        assert!(Instant::now() < deadline, "nothing received");
        std::thread::sleep(Duration::from_millis(5));
    };
    assert_eq!((from, message), (stage.local_addr().unwrap(), vicon_start_message()));
    // Oversized datagrams arrive cut at one byte over the limit, so they are refused as such.
    stage.send_to(&vec![b'x'; MAX_DATAGRAM_BYTES + 100], frond.local_addr().unwrap()).unwrap();
    let len = loop {
        if let Some(got) = frond.recv().unwrap() {
            break got.bytes.len();
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    assert_eq!(len, MAX_DATAGRAM_BYTES + 1);

    // frond leads: the stage's receiver checks the bytes against the published shape.
    let mut leader = Leader::new(4242, 500);
    let stage_addr: SocketAddr = stage.local_addr().unwrap();
    frond.send_to(leader.start("wind_01", None, 33).unwrap(), stage_addr).unwrap();
    frond.send_to(leader.stop("wind_01", None).unwrap(), stage_addr).unwrap();
    stage.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut buf = [0u8; 2048];
    let n = stage.recv(&mut buf).unwrap();
    assert_eq!(
        &buf[..n],
        b"<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStart><Name VALUE=\"wind_01\"/>\
<Delay VALUE=\"33\"/><PacketID VALUE=\"500\"/><ProcessID VALUE=\"4242\"/></CaptureStart>\0"
    );
    let n = stage.recv(&mut buf).unwrap();
    assert_eq!(
        &buf[..n],
        b"<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?><CaptureStop RESULT=\"SUCCESS\">\
<Name VALUE=\"wind_01\"/><PacketID VALUE=\"501\"/><ProcessID VALUE=\"4242\"/></CaptureStop>\0"
    );
}

fn text() -> impl Strategy<Value = Option<String>> {
    proptest::option::of("[ -~\t\n\r\u{e9}\u{4e2d}]{0,40}")
}

fn fields() -> impl Strategy<Value = TriggerFields> {
    let tc = (0u8..24, 0u8..60, 0u8..60, 1u8..30, any::<bool>()).prop_map(
        |(hours, minutes, seconds, frames, drop_frame)| SmpteTime {
            hours,
            minutes,
            seconds,
            frames,
            drop_frame,
        },
    );
    (
        text(),
        text(),
        text(),
        text(),
        proptest::option::of(tc),
        proptest::option::of(0u32..=60_000),
        any::<Option<u64>>(),
        text(),
    )
        .prop_map(
            |(name, notes, description, database_path, timecode, delay_ms, packet_id, process_id)| {
                TriggerFields {
                    name,
                    notes,
                    description,
                    database_path,
                    timecode,
                    delay_ms,
                    packet_id,
                    process_id,
                }
            },
        )
}

proptest! {
    #[test]
    fn encode_then_decode_is_the_identity(f in fields(), stop in any::<bool>(), cancel in any::<bool>()) {
        let message = if stop {
            TriggerMessage::Stop { fields: f, result: if cancel { StopResult::Cancel } else { StopResult::Success } }
        } else {
            TriggerMessage::Start(f)
        };
        let mut buf = Vec::new();
        encode(&message, &mut buf).unwrap();
        prop_assert_eq!(decode(&buf).unwrap(), message);
    }

    #[test]
    fn decode_never_panics_on_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let _ = decode(&bytes);
    }

    #[test]
    fn decode_never_panics_on_damaged_messages(cut in 0..VICON_START.len(), at in 0..VICON_START.len(), b in any::<u8>()) {
        let mut bytes = VICON_START.to_vec();
        bytes[at] = b;
        bytes.truncate(cut.max(at + 1));
        let _ = decode(&bytes);
    }
}
