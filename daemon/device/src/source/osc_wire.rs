//! `/frond/hand` straight from the datagram's bytes, allocation-free, for the realtime loop: the
//! fixed OSC 1.0 layout (an address string, a type tag string, big-endian arguments; bundles of
//! size-prefixed elements) walked in place. [`super::osc::decode_hand_packet`] is the reference
//! (rosc, allocating); the tests check that both agree on every packet rosc can encode.

use frond_motion::HandSample;

/// The OSC address of a hand sample.
pub const OSC_HAND_ADDRESS: &str = "/frond/hand";

/// Deepest bundle nesting accepted (trackers send flat bundles).
pub const MAX_BUNDLE_DEPTH: usize = 16;

/// Why one message was dropped (the counter it goes to).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reject {
    /// Not OSC, truncated, or `/frond/hand` without seven numbers.
    Malformed,
    /// Another address.
    OtherAddress,
    /// A sample outside the hand limits ([`HandSample::check_plausible`]): a non-finite value, a
    /// negative time, or an angle beyond ±[`frond_motion::plausible::MAX_HAND_ANGLE_DEG`].
    OutOfRange,
}

/// The OSC string at the start of `b` and the bytes after its padding (a string ends at its NUL
/// and is padded with NULs to a multiple of 4 bytes).
fn osc_string(b: &[u8]) -> Option<(&[u8], &[u8])> {
    let nul = b.iter().position(|&c| c == 0)?;
    let padded = (nul + 4) & !3;
    Some((&b[..nul], b.get(padded..)?))
}

/// One OSC message: `/frond/hand` with seven numbers becomes a sample.
fn message(b: &[u8]) -> Result<HandSample, Reject> {
    let (addr, rest) = osc_string(b).ok_or(Reject::Malformed)?;
    if addr != OSC_HAND_ADDRESS.as_bytes() {
        // rosc refuses an address that is not UTF-8 text; so do we, as malformed.
        return Err(if std::str::from_utf8(addr).is_ok() { Reject::OtherAddress } else { Reject::Malformed });
    }
    let (tags, mut args) = match osc_string(rest) {
        Some((tags, args)) if tags.first() == Some(&b',') => (&tags[1..], args),
        // No type tag string: a message without arguments.
        _ if rest.is_empty() => (&[][..], rest),
        _ => return Err(Reject::Malformed),
    };
    if tags.len() != 7 {
        return Err(Reject::Malformed);
    }
    let mut v = [0.0f64; 7];
    for (slot, tag) in v.iter_mut().zip(tags) {
        let (value, size) = match tag {
            b'f' => (f64::from(f32::from_be_bytes(*args.first_chunk::<4>().ok_or(Reject::Malformed)?)), 4),
            b'i' => (f64::from(i32::from_be_bytes(*args.first_chunk::<4>().ok_or(Reject::Malformed)?)), 4),
            b'd' => (f64::from_be_bytes(*args.first_chunk::<8>().ok_or(Reject::Malformed)?), 8),
            _ => return Err(Reject::Malformed),
        };
        *slot = value;
        args = &args[size..];
    }
    let hand = HandSample {
        t: v[0],
        wrist_deg: [v[1] as f32, v[2] as f32, v[3] as f32],
        thumb_deg: [v[4] as f32, v[5] as f32, v[6] as f32],
    };
    hand.check_plausible().map_err(|_| Reject::OutOfRange)?;
    Ok(hand)
}

/// Calls `f` for every message of one UDP datagram, in order: a sample, or why it was dropped.
/// A datagram that is not OSC, or whose bundles are truncated or nest deeper than
/// [`MAX_BUNDLE_DEPTH`], is one [`Reject::Malformed`] (nothing of it is used, as with rosc).
/// Never allocates, never panics.
pub fn for_each_hand(datagram: &[u8], f: &mut dyn FnMut(Result<HandSample, Reject>)) {
    if datagram.starts_with(b"#bundle\0") {
        if !bundle_is_well_formed(datagram, 1) {
            f(Err(Reject::Malformed));
            return;
        }
        visit_bundle(datagram, f);
    } else if datagram.first() == Some(&b'/') {
        f(message(datagram));
    } else {
        f(Err(Reject::Malformed));
    }
}

/// Whether a bundle and everything in it has sizes that fit, elements that are bundles or
/// messages, and at most [`MAX_BUNDLE_DEPTH`] levels.
fn bundle_is_well_formed(bundle: &[u8], depth: usize) -> bool {
    if depth > MAX_BUNDLE_DEPTH {
        return false;
    }
    let Some(mut rest) = bundle.get(16..) else { return false };
    while !rest.is_empty() {
        let Some(size) = rest.first_chunk::<4>().map(|s| u32::from_be_bytes(*s) as usize) else {
            return false;
        };
        let Some(element) = rest.get(4..4 + size) else { return false };
        let ok = if element.starts_with(b"#bundle\0") {
            bundle_is_well_formed(element, depth + 1)
        } else {
            element.first() == Some(&b'/') && osc_string(element).is_some()
        };
        if !ok {
            return false;
        }
        rest = &rest[4 + size..];
    }
    true
}

/// The messages of a well-formed bundle, in order.
fn visit_bundle(bundle: &[u8], f: &mut dyn FnMut(Result<HandSample, Reject>)) {
    let mut rest = &bundle[16..];
    while let Some(size) = rest.first_chunk::<4>().map(|s| u32::from_be_bytes(*s) as usize) {
        let element = &rest[4..4 + size];
        if element.starts_with(b"#bundle\0") {
            visit_bundle(element, f);
        } else {
            f(message(element));
        }
        rest = &rest[4 + size..];
    }
}

#[cfg(test)]
mod tests {
    use super::super::osc::tests::{hand_bytes, nested_bundles};
    use super::super::osc::{OscHandError, decode_hand_packet};
    use super::*;
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
}
