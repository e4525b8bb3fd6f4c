//! Fuzzes the capture-trigger decoder (`frond_triggers::decode`), which reads every UDP datagram
//! frondd's trigger listener receives from the stage's network. It must refuse, never panic or
//! run long, and what it accepts must hold the documented bounds and survive frond's own
//! encoder: decode(encode(m)) == m.

use frond_fuzz::{Target, fuzz};
use frond_triggers::{
    MAX_DATAGRAM_BYTES, MAX_DELAY_MS, MAX_NAME_BYTES, MAX_PROCESS_ID_BYTES, MAX_TEXT_BYTES, decode, encode,
};

/// Vicon's published example (Shogun 1.7's "UDP capture broadcast/trigger" page), as bytes.
const VICON_START: &[u8] = b"<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\" ?><CaptureStart><Name VALUE=\"dance\"/><Notes VALUE=\"\"/><Description VALUE=\"\"/><DatabasePath VALUE=\"D:/Vicon/Project/Capture day 1/Session 1\"/><Delay VALUE=\"33\"/><PacketID VALUE=\"33360\"/></CaptureStart>\0";
const VICON_STOP: &[u8] = b"<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\" ?><CaptureStop RESULT=\"SUCCESS\"><Name VALUE=\"dance\"/><DatabasePath VALUE=\"D:/Vicon\"/><Delay VALUE=\"0\"/><PacketID VALUE=\"33361\"/></CaptureStop>\0";
/// Rokoko Studio's fields (its "UDP Trigger Messages" page): TimeCode and a free-text ProcessID.
const ROKOKO_START: &[u8] = b"<?xml version=\"1.0\" encoding=\"utf-8\"?><CaptureStart><Name VALUE=\"Take 12\"/><TimeCode VALUE=\"10:00:01:12\"/><PacketID VALUE=\"7\"/><ProcessID VALUE=\"studio-4\"/></CaptureStart>";
const ROKOKO_STOP: &[u8] = b"<?xml version=\"1.0\" encoding=\"utf-8\"?><CaptureStop><Name VALUE=\"Take 12\"/><TimeCode VALUE=\"10:00:09:00\"/><SetActiveClip VALUE=\"true\"/><ProcessID VALUE=\"studio-4\"/></CaptureStop>";

#[test]
fn fuzz_capture_triggers() {
    let seeds = vec![VICON_START.to_vec(), VICON_STOP.to_vec(), ROKOKO_START.to_vec(), ROKOKO_STOP.to_vec()];
    let dict: Vec<Vec<u8>> = [
        "<CaptureStart>",
        "</CaptureStart>",
        "<CaptureStop RESULT=\"CANCEL\">",
        "</CaptureStop>",
        "<Name VALUE=\"",
        "<Delay VALUE=\"",
        "<PacketID VALUE=\"",
        "<TimeCode VALUE=\"",
        "<ProcessID VALUE=\"",
        "\"/>",
        "<!--",
        "-->",
        "<![CDATA[",
        "&amp;",
        "&#x41;",
        "<!DOCTYPE x [<!ENTITY a \"aaaa\">]>",
        "18446744073709551615",
        "59:59:59:29",
        "00:00:00;00",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    let report = fuzz(Target::new("capture-trigger").seeds(seeds).dict(dict).max_len(4096), |bytes| {
        let message = match decode(bytes) {
            Ok(m) => m,
            Err(e) => {
                assert!(!e.to_string().is_empty());
                return "refused";
            }
        };
        assert!(bytes.len() <= MAX_DATAGRAM_BYTES);
        let f = message.fields();
        assert!(f.name.as_ref().is_none_or(|n| n.len() <= MAX_NAME_BYTES), "name {:?}", f.name);
        for text in [&f.notes, &f.description, &f.database_path] {
            assert!(text.as_ref().is_none_or(|t| t.len() <= MAX_TEXT_BYTES));
        }
        assert!(f.process_id.as_ref().is_none_or(|p| p.len() <= MAX_PROCESS_ID_BYTES));
        assert!(f.delay_ms.is_none_or(|d| d <= MAX_DELAY_MS), "delay {:?}", f.delay_ms);
        let mut out = Vec::new();
        match encode(&message, &mut out) {
            Ok(()) => {
                let again = decode(&out).unwrap_or_else(|e| {
                    panic!(
                        "frond's own encoding of {message:?} is refused: {e}\n{}",
                        String::from_utf8_lossy(&out)
                    )
                });
                assert_eq!(again, message, "changed through encode: {}", String::from_utf8_lossy(&out));
                "ok"
            }
            // A message frond cannot write (e.g. text with characters its encoder refuses).
            Err(_) => "unencodable",
        }
    });
    report.assert_reaches("ok", 20);
    report.assert_reaches("refused", 100);
}
