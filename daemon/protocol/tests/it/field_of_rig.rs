//! `StageSpec::FieldOfRig` was added within protocol 3 as a variant of its own (issue 48's mixed
//! rigs): a daemon from before, which knows only `Field`, must refuse a field of another rig by
//! name rather than play its own rig, and must still take a `Field` from this build. The daemon
//! from before is its `StageSpec` as it was, copied here.

use frond_protocol::{ControlRequest, StageSpec, decode_frame, encode_frame};
use serde::Deserialize;

/// `StageSpec` before `FieldOfRig` (the variants a field start needs; serde refuses others).
#[derive(Debug, Deserialize, PartialEq)]
#[allow(dead_code)]
enum SpecBefore {
    Playback { take: String, seed: u64 },
    Field { take: String, field_json: String, plants: u16, seed: u64 },
}

#[derive(Debug, Deserialize, PartialEq)]
#[allow(dead_code)]
enum RequestBefore {
    StageStart { name: Option<String>, spec: SpecBefore },
}

fn start(spec: StageSpec) -> Vec<u8> {
    let mut buf = Vec::new();
    encode_frame(&ControlRequest::StageStart { name: Some("flowers".into()), spec }, &mut buf);
    buf
}

#[test]
fn a_daemon_from_before_refuses_a_field_of_another_rig_by_name_and_takes_a_plain_field() {
    let of_rig = start(StageSpec::FieldOfRig {
        take: "sway".into(),
        field_json: "{}".into(),
        plants: 4,
        seed: 1,
        rig_toml: "name = \"flower\"".into(),
    });
    let e = decode_frame::<RequestBefore>(&of_rig).unwrap_err().to_string();
    assert!(e.contains("unknown variant `FieldOfRig`"), "{e}");

    let plain = start(StageSpec::Field { take: "sway".into(), field_json: "{}".into(), plants: 4, seed: 1 });
    let (got, _) = decode_frame::<RequestBefore>(&plain).unwrap().unwrap();
    let want = SpecBefore::Field { take: "sway".into(), field_json: "{}".into(), plants: 4, seed: 1 };
    assert_eq!(got, RequestBefore::StageStart { name: Some("flowers".into()), spec: want });

    // This build reads both back as they were sent.
    let (back, _) = decode_frame::<ControlRequest>(&of_rig).unwrap().unwrap();
    let ControlRequest::StageStart { spec: StageSpec::FieldOfRig { rig_toml, plants, .. }, .. } = back else {
        panic!("{back:?}")
    };
    assert_eq!((rig_toml.as_str(), plants), ("name = \"flower\"", 4));
}
