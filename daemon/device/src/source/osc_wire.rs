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
