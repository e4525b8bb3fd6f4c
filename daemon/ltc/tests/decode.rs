//! LTC audio made by the encoder in `common` (written from the SMPTE 12M bit layout, not from
//! the crate's code), decoded frame for frame at every rate and several sample rates, with
//! noise, inverted polarity, odd levels, a dropout and a jump.

mod common;

use common::add_noise;
use frond_ltc::encode::{edges, edges_at_speed, labels, render};
use frond_ltc::{FrameRate, LtcDecoder, LtcEvent, SmpteTime};

struct Decoded {
    frames: Vec<SmpteTime>,
    events: Vec<LtcEvent>,
}

fn decode(samples: &[f32], sample_rate: u32) -> Decoded {
    let mut d = LtcDecoder::new(sample_rate).unwrap();
    let mut events = Vec::new();
    // Feed in uneven blocks, as a capture device would.
    for chunk in samples.chunks(997) {
        d.process_f32(chunk, |e| events.push(e));
    }
    let frames = events
        .iter()
        .filter_map(|e| match e {
            LtcEvent::Frame(f) => Some(f.time),
            _ => None,
        })
        .collect();
    Decoded { frames, events }
}

/// The decoded labels are the sent ones, in order, missing at most the first `skip` (the
/// first frame's bits start before the decoder knows the bit length).
fn assert_frame_for_frame(sent: &[SmpteTime], got: &[SmpteTime], skip: usize, what: &str) {
    let first = sent.iter().position(|t| Some(t) == got.first());
    let Some(first) = first else { panic!("{what}: first decoded {:?} was never sent", got.first()) };
    assert!(first <= skip, "{what}: decoding started at frame {first}");
    assert_eq!(got, &sent[first..], "{what}");
}

#[test]
fn every_rate_at_several_sample_rates_decodes_frame_for_frame() {
    for rate in FrameRate::ALL {
        for sample_rate in [8_000, 44_100, 48_000, 96_000, 192_000] {
            // Start just before a minute boundary, so drop-frame skips labels on the way.
            let start = rate.frame_count(SmpteTime {
                hours: 10,
                minutes: 8,
                seconds: 59,
                frames: 20,
                drop_frame: false,
            });
            let sent = labels(rate, start, 40);
            let with_user: Vec<_> = sent.iter().map(|&t| (t, 0x1234_5678)).collect();
            let seconds = 40.5 / rate.fps();
            let samples = render(&edges(rate, &with_user), sample_rate, seconds, 0.5);
            let got = decode(&samples, sample_rate);
            let what = format!("{rate} at {sample_rate} Hz");
            assert_frame_for_frame(&sent, &got.frames, 1, &what);
            let locked: Vec<_> = got
                .events
                .iter()
                .filter_map(|e| if let LtcEvent::Locked { rate, .. } = e { Some(*rate) } else { None })
                .collect();
            // 29.97 non-drop-frame has 30's labels, 0.1 % slower: the reader locks it as 30,
            // and a stage that declares 29.97 takes it so (`FrameRate::read_as`).
            let read = if rate == FrameRate::Fps2997Ndf { FrameRate::Fps30 } else { rate };
            assert_eq!(locked, [read], "{what}");
            assert_eq!(read.read_as(Some(rate)), Some(rate), "{what}");
            let user = got
                .events
                .iter()
                .find_map(|e| if let LtcEvent::Frame(f) = e { Some(f.user_bits) } else { None });
            assert_eq!(user, Some(0x1234_5678), "{what}");
        }
    }
}

#[test]
fn noise_inverted_polarity_and_odd_levels_do_not_matter() {
    for (i, (amp, noise)) in
        [(0.9f32, 0.2f32), (-0.5, 0.1), (0.02, 0.004), (-0.01, 0.0)].into_iter().enumerate()
    {
        for rate in [FrameRate::Fps25, FrameRate::Fps2997Df] {
            let sent = labels(rate, 1_000, 30);
            let with_user: Vec<_> = sent.iter().map(|&t| (t, 0)).collect();
            let mut samples = render(&edges(rate, &with_user), 48_000, 30.5 / rate.fps(), amp);
            add_noise(&mut samples, noise, i as u64);
            let got = decode(&samples, 48_000);
            assert_frame_for_frame(&sent, &got.frames, 1, &format!("{rate} amp {amp} noise {noise}"));
        }
    }
}

#[test]
fn a_source_one_percent_off_speed_still_locks_at_its_rate() {
    for rate in [FrameRate::Fps24, FrameRate::Fps25, FrameRate::Fps30] {
        for speed in [0.99, 1.01] {
            let sent = labels(rate, 3_000, 30);
            let with_user: Vec<_> = sent.iter().map(|&t| (t, 0)).collect();
            let samples =
                render(&edges_at_speed(rate, &with_user, speed), 48_000, 30.5 / (rate.fps() * speed), 0.5);
            let got = decode(&samples, 48_000);
            assert_frame_for_frame(&sent, &got.frames, 1, &format!("{rate} at speed {speed}"));
            let locked: Vec<_> = got
                .events
                .iter()
                .filter_map(|e| if let LtcEvent::Locked { rate, .. } = e { Some(*rate) } else { None })
                .collect();
            assert_eq!(locked, [rate], "{rate} at speed {speed}");
        }
    }
}

#[test]
fn a_dropout_is_lost_then_locked_again() {
    let rate = FrameRate::Fps30;
    let sent = labels(rate, 5_000, 60);
    let with_user: Vec<_> = sent.iter().map(|&t| (t, 0)).collect();
    let sr = 48_000;
    let mut samples = render(&edges(rate, &with_user), sr, 60.5 / rate.fps(), 0.5);
    // Silence (with a little hiss) from frame 20 to frame 30.
    let frame_samples = f64::from(sr) / rate.fps();
    let (from, to) = ((20.0 * frame_samples) as usize, (30.0 * frame_samples) as usize);
    samples[from..to].iter_mut().for_each(|s| *s = 0.0);
    add_noise(&mut samples[from..to], 0.001, 7);
    let got = decode(&samples, sr);
    let kinds: Vec<&str> = got
        .events
        .iter()
        .filter_map(|e| match e {
            LtcEvent::Locked { .. } => Some("locked"),
            LtcEvent::Lost { .. } => Some("lost"),
            LtcEvent::Jump { .. } => Some("jump"),
            LtcEvent::Frame(_) => None,
        })
        .collect();
    assert_eq!(kinds, ["locked", "lost", "locked"]);
    // Every frame read is a frame sent, in order; the ones in the silence are missing.
    let mut it = sent.iter();
    for t in &got.frames {
        assert!(it.any(|s| s == t), "{t} decoded out of order or never sent");
    }
    assert!(got.frames.len() >= 60 - 10 - 4, "{} frames read", got.frames.len());
    assert!(!got.frames.contains(&sent[25]));
}

#[test]
fn a_jump_is_reported_and_followed() {
    let rate = FrameRate::Fps24;
    let mut sent = labels(rate, 100, 20);
    sent.extend(labels(rate, 50_000, 20));
    let with_user: Vec<_> = sent.iter().map(|&t| (t, 0)).collect();
    let samples = render(&edges(rate, &with_user), 44_100, 40.5 / rate.fps(), 0.3);
    let got = decode(&samples, 44_100);
    assert_frame_for_frame(&sent, &got.frames, 1, "jump");
    let jumps: Vec<_> = got
        .events
        .iter()
        .filter_map(|e| {
            if let LtcEvent::Jump { expected, found, .. } = e { Some((*expected, *found)) } else { None }
        })
        .collect();
    assert_eq!(jumps, [(rate.from_frame_count(120), rate.from_frame_count(50_000))]);
}

#[test]
fn sixteen_bit_samples_decode_like_floats() {
    let rate = FrameRate::Fps25;
    let sent = labels(rate, 77, 12);
    let with_user: Vec<_> = sent.iter().map(|&t| (t, 0)).collect();
    let samples = render(&edges(rate, &with_user), 48_000, 12.5 / rate.fps(), 0.7);
    let ints: Vec<i16> = samples.iter().map(|&s| (s * 32_767.0) as i16).collect();
    let mut d = LtcDecoder::new(48_000).unwrap();
    let mut got = Vec::new();
    d.process_i16(&ints, |e| {
        if let LtcEvent::Frame(f) = e {
            got.push(f.time)
        }
    });
    assert_frame_for_frame(&sent, &got, 1, "i16");
}

proptest::proptest! {
    /// Any samples at any supported rate: no panic, and every frame reported is a valid label.
    #[test]
    fn arbitrary_samples_never_panic(samples in proptest::collection::vec(proptest::num::i16::ANY, 0..4000),
                                     sample_rate in 8_000u32..=192_000) {
        let mut d = LtcDecoder::new(sample_rate).unwrap();
        d.process_i16(&samples, |e| {
            if let LtcEvent::Frame(f) = e {
                assert!(f.time.check_fields().is_ok());
            }
        });
    }
}
