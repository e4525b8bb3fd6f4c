//! The allocation-free OSC decoder ([`super::osc_wire`]) against the reference one
//! ([`super::osc::decode_hand_packet`], rosc): both agree on every packet rosc can encode, and
//! neither panics on arbitrary bytes. Apart from both, so that neither file imports the other.

use frond_motion::HandSample;

use super::osc::tests::{hand_bytes, nested_bundles};
use super::osc::{OscHandError, decode_hand_packet};
use super::osc_wire::{MAX_BUNDLE_DEPTH, Reject, for_each_hand};
use proptest::prelude::*;
use rosc::{OscBundle, OscMessage, OscPacket, OscTime, OscType};

fn ours(datagram: &[u8]) -> Vec<Result<HandSample, Reject>> {
    let mut out = Vec::new();
    for_each_hand(datagram, &mut |r| out.push(r));
    out
}

fn reference(datagram: &[u8]) -> Vec<Result<HandSample, Reject>> {
    decode_hand_packet(datagram)
        .into_iter()
        .map(|r| {
            r.map_err(|e| match e {
                OscHandError::Malformed(_) => Reject::Malformed,
                OscHandError::OtherAddress(_) => Reject::OtherAddress,
                OscHandError::OutOfRange(_) => Reject::OutOfRange,
            })
        })
        .collect()
}

#[test]
fn a_hand_written_message_and_bundle() {
    let want = HandSample { t: 0.5, wrist_deg: [10.0, -20.0, 30.0], thumb_deg: [1.0, 2.0, 3.0] };
    assert_eq!(ours(&hand_bytes()), [Ok(want)]);
    let mut bundle = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
    for _ in 0..2 {
        bundle.extend_from_slice(&(hand_bytes().len() as u32).to_be_bytes());
        bundle.extend_from_slice(&hand_bytes());
    }
    assert_eq!(ours(&bundle), [Ok(want), Ok(want)]);
    // A size running past the end: the whole datagram is malformed, as rosc says.
    let n = bundle.len();
    bundle[n - hand_bytes().len() - 1] += 1;
    assert_eq!(ours(&bundle), [Err(Reject::Malformed)]);
    assert_eq!(ours(b"garbage"), [Err(Reject::Malformed)]);
    assert_eq!(ours(b""), [Err(Reject::Malformed)]);
}

#[test]
fn nesting_deeper_than_the_limit_is_malformed() {
    assert!(matches!(&ours(&nested_bundles(MAX_BUNDLE_DEPTH))[..], [Ok(_)]));
    assert_eq!(ours(&nested_bundles(MAX_BUNDLE_DEPTH + 1)), [Err(Reject::Malformed)]);
    assert_eq!(ours(&nested_bundles(3000)), [Err(Reject::Malformed)]);
}

fn arg() -> impl Strategy<Value = OscType> {
    prop_oneof![
        any::<f32>().prop_map(OscType::Float),
        (-400.0f32..400.0).prop_map(OscType::Float),
        (-400.0f64..400.0).prop_map(OscType::Double),
        any::<f64>().prop_map(OscType::Double),
        (-500i32..500).prop_map(OscType::Int),
        "[a-z]{0,5}".prop_map(OscType::String),
        Just(OscType::Bool(true)),
        any::<i64>().prop_map(OscType::Long),
    ]
}

fn message_strategy() -> impl Strategy<Value = OscPacket> {
    let addr = prop_oneof![4 => Just("/frond/hand".to_string()), 1 => "/[a-z]{1,12}"];
    let args = prop_oneof![
        4 => proptest::collection::vec((0.0f32..100.0).prop_map(OscType::Float), 7),
        2 => proptest::collection::vec(arg(), 7),
        1 => proptest::collection::vec(arg(), 0..10),
    ];
    (addr, args).prop_map(|(addr, args)| OscPacket::Message(OscMessage { addr, args }))
}

fn packet() -> impl Strategy<Value = OscPacket> {
    message_strategy().prop_recursive(3, 24, 6, |inner| {
        proptest::collection::vec(inner, 0..6)
            .prop_map(|content| OscPacket::Bundle(OscBundle { timetag: OscTime::from((1, 2)), content }))
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2048, ..ProptestConfig::default() })]

    /// Both decoders agree on every packet rosc encodes: the same samples and the same
    /// reasons, in the same order.
    #[test]
    fn agrees_with_the_rosc_reference(p in packet()) {
        let bytes = rosc::encoder::encode(&p).unwrap();
        prop_assert_eq!(ours(&bytes), reference(&bytes));
    }

    /// Issue 14, point 11: the live OSC path and the offline hand-file parser (`frond map`,
    /// `--replay`) accept exactly the same samples, and exactly those the documented rule
    /// (written out again here) allows: `t` finite and not negative, every angle finite and
    /// within ±360 degrees.
    #[test]
    fn live_and_offline_accept_the_same_hands(
        t in prop_oneof![Just(0.0f64), Just(-0.0), 0.0f64..1e6, -1.0f64..0.0, any::<f64>()],
        angles in proptest::collection::vec(
            prop_oneof![Just(360.0f32), Just(-360.0), Just(360.00003), -400.0f32..400.0, any::<f32>()],
            6,
        ),
    ) {
        let mut args = vec![OscType::Double(t)];
        args.extend(angles.iter().map(|&a| OscType::Float(a)));
        let packet = OscPacket::Message(OscMessage { addr: "/frond/hand".into(), args });
        let live = ours(&rosc::encoder::encode(&packet).unwrap());
        let fmt = |v: &[f32]| v.iter().map(|a| a.to_string()).collect::<Vec<_>>().join(",");
        let line = format!(r#"{{"t":{t},"wrist":[{}],"thumb":[{}]}}"#, fmt(&angles[..3]), fmt(&angles[3..]));
        let offline = frond_formats::parse_hand_line(&line);
        let rule = t.is_finite() && t >= 0.0 && angles.iter().all(|a| a.is_finite() && a.abs() <= 360.0);
        prop_assert_eq!(matches!(live[..], [Ok(_)]), rule, "live {:?}", live);
        prop_assert_eq!(offline.is_ok(), rule, "{} -> {:?}", line, offline);
        if let (Ok(off), [Ok(on)]) = (offline, &live[..]) {
            // serde_json's float parsing may be one unit in the last place off for `t`.
            prop_assert!((off.t - on.t).abs() <= on.t.abs() * 1e-15, "{} vs {}", off.t, on.t);
            prop_assert_eq!((off.wrist_deg, off.thumb_deg), (on.wrist_deg, on.thumb_deg));
        }
    }

    /// Arbitrary bytes never panic, and a message or malformed verdict always comes out.
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        prop_assert!(!ours(&bytes).is_empty());
    }
}
