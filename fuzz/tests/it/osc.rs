//! Fuzzes the OSC hand input (`frond_device::source::decode_hand_packet`), which decodes every UDP
//! datagram the daemon's OSC source receives. Accepted samples must hold the documented ranges
//! (`t` finite and >= 0, angles finite within +-360 degrees).

use frond_device::source::{OSC_HAND_ADDRESS, decode_hand_packet};
use frond_fuzz::{Target, fuzz};
use rosc::{OscBundle, OscMessage, OscPacket, OscTime, OscType, encoder};

fn hand(t: f32, v: f32) -> OscPacket {
    OscPacket::Message(OscMessage {
        addr: OSC_HAND_ADDRESS.into(),
        args: vec![
            OscType::Float(t),
            OscType::Float(v),
            OscType::Double(-f64::from(v)),
            OscType::Int(3),
            OscType::Float(10.0),
            OscType::Float(20.0),
            OscType::Float(30.0),
        ],
    })
}

fn bundle(content: Vec<OscPacket>) -> OscPacket {
    OscPacket::Bundle(OscBundle { timetag: OscTime { seconds: 0, fractional: 1 }, content })
}

/// Bundles nested `depth` deep around one hand message, built by hand (the size field of each
/// level covers the rest), as big as a UDP datagram allows: a stack-depth probe.
fn nested(depth: usize) -> Vec<u8> {
    let inner = encoder::encode(&hand(1.0, 2.0)).expect("encode");
    let mut out = inner;
    for _ in 0..depth {
        let mut b = b"#bundle\0".to_vec();
        b.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 1]);
        b.extend_from_slice(&(out.len() as u32).to_be_bytes());
        b.extend_from_slice(&out);
        out = b;
    }
    out
}

#[test]
fn fuzz_osc_hand_packets() {
    let mut seeds: Vec<Vec<u8>> = [
        hand(0.5, 12.5),
        hand(0.0, -360.0),
        bundle(vec![hand(1.0, 1.0), hand(1.001, 2.0)]),
        bundle(vec![
            bundle(vec![hand(2.0, 3.0)]),
            OscPacket::Message(OscMessage { addr: "/other".into(), args: vec![] }),
        ]),
    ]
    .iter()
    .map(|p| encoder::encode(p).expect("encode seed"))
    .collect();
    seeds.push(nested(8));
    // The deepest nesting a 64 KiB datagram can carry overflowed the stack in rosc's recursive
    // decoder (found here; the input is corpus/osc-hand/crash-nested-bundles). It is refused now.
    let deep = nested(3250);
    assert!(deep.len() <= 65_507);
    assert!(decode_hand_packet(&deep).iter().all(Result::is_err));
    let dict = [
        b"/frond/hand\0".to_vec(),
        b",fffffff\0".to_vec(),
        b",dddddddd".to_vec(),
        b",iiiiiii\0".to_vec(),
        b",sbTFNI[]\0\0".to_vec(),
        b"#bundle\0".to_vec(),
        vec![0x7f, 0xc0, 0, 0],
        vec![0xff, 0xff, 0xff, 0xff],
        vec![0, 0, 0, 0],
    ];
    let report = fuzz(Target::new("osc-hand").seeds(seeds).dict(dict).max_len(2048), |b| {
        let out = decode_hand_packet(b);
        // An empty bundle is valid OSC and carries nothing: no samples and no reasons.
        let mut label = if out.is_empty() { "empty" } else { "refused" };
        for r in &out {
            match r {
                Ok(h) => {
                    assert!(h.t.is_finite() && h.t >= 0.0, "t = {}", h.t);
                    for a in h.wrist_deg.iter().chain(&h.thumb_deg) {
                        assert!(a.is_finite() && a.abs() <= 360.0, "angle {a}");
                    }
                    label = "ok";
                }
                Err(e) => assert!(!format!("{e:?}").is_empty()),
            }
        }
        label
    });
    report.assert_reaches("ok", 50);
    report.assert_reaches("refused", 100);
}
