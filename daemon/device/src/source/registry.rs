//! The one table of hand sources a configuration can name ([`BACKENDS`]), and what reads it:
//! [`parse_spec`] for configurations, [`kind_names`] for help and errors.
//!
//! Adding a hand source: a module beside this one with its source type and its `BACKEND`
//! entry, one line in [`BACKENDS`], and a [`SourceSpec`] variant (ARCHITECTURE.md, "Adding a
//! hand source", walks through it).

use super::spec::{Backend, SourceSpec, SpecError, SpecInput};
use super::{glove_kinds, hid, leap, osc, replay, webcam};

/// Every hand source a configuration can name, in the order help and errors list them.
pub const BACKENDS: [Backend; 8] = [
    glove_kinds::AUTO,
    glove_kinds::VIRTUAL,
    glove_kinds::IN_PROCESS,
    hid::BACKEND,
    replay::BACKEND,
    osc::BACKEND,
    leap::BACKEND,
    webcam::BACKEND,
];

/// The kinds as help and errors list them: `auto, virtual, in-process, hid, replay,
/// osc://IP:PORT, leap://HOST:PORT, webcam[:DEVICE]`.
pub fn kind_names() -> String {
    BACKENDS.iter().map(|b| b.syntax).collect::<Vec<_>>().join(", ")
}

/// Parses a kind text with the first backend that takes it; a text no backend takes is
/// refused with the list of kinds.
pub fn parse_spec(kind: &str, input: &SpecInput<'_>) -> Result<SourceSpec, SpecError> {
    BACKENDS
        .iter()
        .find_map(|b| (b.parse)(kind, input))
        .unwrap_or_else(|| Err(SpecError::UnknownKind { key: input.key.to_string(), kind: kind.to_string() }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::{LeapAddress, WebcamAddress};

    fn input() -> SpecInput<'static> {
        SpecInput { key: "source.kind", replay: None, replay_key: "source.replay" }
    }

    #[test]
    fn the_names_are_the_documented_list() {
        assert_eq!(
            kind_names(),
            "auto, virtual, in-process, hid, replay, osc://IP:PORT, leap://HOST:PORT, webcam[:DEVICE]"
        );
    }

    #[test]
    fn each_kind_reaches_its_own_backend() {
        let with_replay = SpecInput { replay: Some("/r.jsonl"), ..input() };
        assert_eq!(parse_spec("auto", &input()), Ok(SourceSpec::Auto));
        assert_eq!(parse_spec("virtual", &input()), Ok(SourceSpec::Virtual));
        assert_eq!(parse_spec("in-process", &input()), Ok(SourceSpec::InProcess));
        assert_eq!(parse_spec("hid", &input()), Ok(SourceSpec::Hid));
        assert_eq!(parse_spec("replay", &with_replay), Ok(SourceSpec::Replay("/r.jsonl".into())));
        assert_eq!(
            parse_spec("osc://127.0.0.1:9001", &input()),
            Ok(SourceSpec::Osc("127.0.0.1:9001".into()))
        );
        let leap: LeapAddress = "leap://h:6437?hand=left".parse().unwrap();
        assert_eq!(parse_spec("leap://h:6437?hand=left", &input()), Ok(SourceSpec::Leap(leap)));
        let webcam: WebcamAddress = "webcam:/dev/video2?hand=left".parse().unwrap();
        assert_eq!(parse_spec("webcam:/dev/video2?hand=left", &input()), Ok(SourceSpec::Webcam(webcam)));
        let default: WebcamAddress = "webcam".parse().unwrap();
        assert_eq!(parse_spec("webcam", &input()), Ok(SourceSpec::Webcam(default)));
    }

    #[test]
    fn problems_name_their_key() {
        let text = |kind: &str| parse_spec(kind, &input()).unwrap_err().to_string();
        assert_eq!(text("replay"), "source.replay: required when source.kind = \"replay\"");
        assert_eq!(
            text("osc://nowhere"),
            "source.kind: \"osc://nowhere\": expected osc://IP:PORT, e.g. osc://127.0.0.1:9001"
        );
        assert_eq!(
            text("usb"),
            "source.kind: \"usb\" is not one of auto, virtual, in-process, hid, replay, osc://IP:PORT, leap://HOST:PORT, webcam[:DEVICE]"
        );
        assert_eq!(
            text("leap://nohost"),
            "source.kind: \"leap://nohost\": expected leap://HOST:PORT, e.g. leap://127.0.0.1:6437"
        );
        assert_eq!(
            text("webcam:/dev/video0?hand=both"),
            "source.kind: \"webcam:/dev/video0?hand=both\": unknown option \"hand=both\" (expected hand=left or hand=right)"
        );
        assert!(text("webcams").contains("is not one of"));
        assert_eq!(
            text("leap://h:1?hand=both"),
            "source.kind: \"leap://h:1?hand=both\": unknown option \"hand=both\" (expected hand=left or hand=right)"
        );
    }
}
