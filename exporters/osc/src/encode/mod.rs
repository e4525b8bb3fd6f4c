//! Pure functions that turn a [`Pose`](frond_protocol::Pose) into OSC datagrams, written into
//! reusable buffers ([`Datagrams`]): after the first frames have grown the buffers, encoding a frame
//! allocates nothing.
//!
//! Messages are encoded with the `rosc` crate from message templates built once (addresses and
//! strings preallocated; only the numeric arguments are overwritten per frame). Bundles are packed
//! here so that no datagram exceeds [`MAX_DATAGRAM_BYTES`]: messages go, in order, into the current
//! bundle until the next one would not fit, then a new bundle with the same timetag is started.
//!
//! # The `frond` namespace ([`FrondEncoder`])
//!
//! One OSC bundle per frame, timetagged with the frame's host time (see [timetag](#timetag)):
//!
//! | address | type tags | arguments |
//! |---|---|---|
//! | `/frond/pose` | `,idffffffffffff` | `seq` (low 32 bits, two's complement; wraps after 2^32 frames), `t` = device time of the hand sample in seconds (`Pose.hand.t`), then pitch, yaw, roll of joints 0 (root) .. 3 (top), degrees |
//! | `/frond/joint/<i>/quat` (`i` = 0..3) | `,ffff` | x, y, z, w: unit quaternion of joint `i` relative to its parent, in frond's convention (stem +Y, `R = R_yaw R_pitch R_roll`, right-handed; `frond_protocol::convention::joint_quat`) |
//! | `/frond/status` | `,i` | the pose flags bit field: held 1, device_lost 2, filtered 4, recording 8, playback 16 |
//!
//! `/frond/status` is in every bundle, so a receiver sees both the loss of the device (bit 2: hold
//! the pose) and its return. A pose of a secondary element (`Pose.element` = `e` > 0) is sent as
//! its own bundle with a single message `/frond/element/<e>/pose` carrying the same arguments as
//! `/frond/pose`.
//!
//! A running field goes out whole ([`FieldEncoder`], [`encode_definitions`]; seed 000, Eq.
//! 6-7): `/frond/fields ,i...` (the running fields' ids), per field `/frond/field/<f>/def`,
//! `/frond/field/<f>/joints` (timetag "immediately", when the fields change and every 2 s),
//! `/frond/field/<f>/layout ,iiib` (its plants' layout in chunks of [`LAYOUT_CHUNK_BYTES`]) and
//! one `/frond/field/<f>/frame ,hidddddfdddhb` per field frame (timetag its host time), so a
//! receiver evaluates every plant itself; the arguments are in the README.
//!
//! # VMC ([`VmcEncoder`])
//!
//! The Virtual Motion Capture protocol (sh-akira) as a performer sends it, one bundle per frame
//! (split at [`MAX_DATAGRAM_BYTES`]):
//! `/VMC/Ext/Root/Pos ,sfffffff "root" px py pz qx qy qz qw` (identity), one
//! `/VMC/Ext/Bone/Pos ,sfffffff name px py pz qx qy qz qw` per joint (local position relative to the
//! parent from the rig heights, local rotation), `/VMC/Ext/OK ,iiii 1 3 0 tracking` (loaded,
//! calibrated, normal mode, tracking 1 or 0 when the device is lost) and `/VMC/Ext/T ,f t`.
//! Positions and rotations are converted from frond's right-handed frame to Unity's left-handed
//! one by mirroring the X axis: `(x, y, z) -> (-x, y, z)`, quaternion `(x, y, z, w) ->
//! (x, -y, -z, w)` ([`unity_position`], [`unity_quat`]).
//!
//! # Timetag
//!
//! `Pose.host_monotonic_ns` is `CLOCK_MONOTONIC`, which has no fixed epoch, while an OSC timetag is
//! NTP time (seconds since 1900-01-01 UTC, 32.32 fixed point). frond-osc measures the offset
//! `CLOCK_REALTIME - CLOCK_MONOTONIC` once at start ([`ClockOffset::measure`]) and keeps it, so
//! that timetags advance exactly with the daemon's monotonic clock and never jump when the wall
//! clock is stepped: `unix_ns = host_monotonic_ns + offset`, `seconds = unix_ns / 10^9 +
//! 2_208_988_800` (NTP era 0, mod 2^32), `fraction = floor((unix_ns mod 10^9) * 2^32 / 10^9)`.
//! See [`timetag`].

mod field;
mod frond;
mod vmc;

pub use field::{
    ENTRY_BYTES, FieldEncoder, LAYOUT_CHUNK_BYTES, MAX_FIELD_NAME_BYTES, MAX_LAYOUT_CHUNKS,
    MAX_OSC_FIELD_PLANTS, encode_definitions, layout_chunks, layout_key,
};
pub use frond::FrondEncoder;
pub use vmc::{DEFAULT_HEIGHTS_M, HUMANOID_BONES, VmcEncoder, VmcRig};

/// [`HUMANOID_BONES`] as owned names.
pub fn vmc_humanoid_names() -> [String; 4] {
    HUMANOID_BONES.map(String::from)
}

use rosc::{OscPacket, OscTime};
use thiserror::Error;

/// Largest datagram frond-osc sends: 1200 bytes fits the IPv6 minimum MTU (1280) minus headers, so
/// no datagram is fragmented on any path.
pub const MAX_DATAGRAM_BYTES: usize = 1200;

/// Bytes of a bundle header: `#bundle\0` and the 8-byte timetag.
pub const BUNDLE_HEADER_BYTES: usize = 16;

/// Seconds from the NTP epoch (1900-01-01) to the Unix epoch (1970-01-01), RFC 5905.
pub const NTP_UNIX_OFFSET_S: u64 = 2_208_988_800;

/// Errors of the encoders.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum EncodeError {
    /// One message alone does not fit a datagram (only possible with absurdly long names).
    #[error(
        "OSC message `{address}` is {bytes} bytes, more than fits in one {MAX_DATAGRAM_BYTES}-byte bundle"
    )]
    MessageTooLarge {
        /// The message's address.
        address: String,
        /// Its encoded size.
        bytes: usize,
    },
}

/// The OSC timetag "immediately" (OSC 1.0: 63 zero bits and a one).
pub const IMMEDIATELY: OscTime = OscTime { seconds: 0, fractional: 1 };

/// What a bundle's timetag says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Timetags {
    /// The frame's host publish time (NTP, through [`ClockOffset`]): a receiver may schedule by it.
    #[default]
    Publish,
    /// [`IMMEDIATELY`]: apply on receipt (VMC receivers expect this; a receiver whose clock is
    /// behind would otherwise hold frames back).
    Immediately,
}

/// Offset `CLOCK_REALTIME - CLOCK_MONOTONIC` in nanoseconds, fixed for the life of the exporter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockOffset {
    /// Realtime minus monotonic, nanoseconds.
    pub realtime_minus_monotonic_ns: i128,
}

impl ClockOffset {
    /// A fixed offset (tests, replays).
    pub const fn fixed(realtime_minus_monotonic_ns: i128) -> ClockOffset {
        ClockOffset { realtime_minus_monotonic_ns }
    }

    /// Measures the offset now: reads the monotonic clock, the realtime clock and the monotonic
    /// clock again and pairs the realtime reading with the midpoint.
    pub fn measure() -> ClockOffset {
        let m0 = monotonic_ns();
        let real = clock_ns(libc::CLOCK_REALTIME);
        let m1 = monotonic_ns();
        let mid = i128::from(m0) + (i128::from(m1) - i128::from(m0)) / 2;
        ClockOffset { realtime_minus_monotonic_ns: i128::from(real) - mid }
    }

    /// The host monotonic time (ns) that a timetag made with this offset stands for, to within
    /// a nanosecond (the inverse of [`timetag`]; used by the latency bench).
    pub fn monotonic_ns_of(self, tag: OscTime) -> i128 {
        let secs = i128::from(tag.seconds) - i128::from(NTP_UNIX_OFFSET_S);
        let frac_ns = (i128::from(tag.fractional) * 1_000_000_000 + (1 << 31)) >> 32;
        secs * 1_000_000_000 + frac_ns - self.realtime_minus_monotonic_ns
    }
}

fn clock_ns(clock: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes one timespec into the valid, exclusively borrowed `ts`.
    let rc = unsafe { libc::clock_gettime(clock, &mut ts) };
    debug_assert_eq!(rc, 0, "clock_gettime failed");
    (ts.tv_sec as u64).wrapping_mul(1_000_000_000).wrapping_add(ts.tv_nsec as u64)
}

/// `CLOCK_MONOTONIC` now, nanoseconds: the clock of `Pose.host_monotonic_ns`.
pub fn monotonic_ns() -> u64 {
    clock_ns(libc::CLOCK_MONOTONIC)
}

/// The OSC timetag of a frame published at `host_monotonic_ns` (see the [module docs](self#timetag)).
/// Times before 1970 give the earliest representable non-special time (0 s, fraction 0).
pub fn timetag(host_monotonic_ns: u64, offset: ClockOffset) -> OscTime {
    let unix_ns = i128::from(host_monotonic_ns) + offset.realtime_minus_monotonic_ns;
    if unix_ns < 0 {
        return OscTime { seconds: 0, fractional: 0 };
    }
    let unix_ns = unix_ns as u128;
    let secs = unix_ns / 1_000_000_000 + u128::from(NTP_UNIX_OFFSET_S);
    let sub_ns = unix_ns % 1_000_000_000;
    OscTime { seconds: secs as u32, fractional: ((sub_ns << 32) / 1_000_000_000) as u32 }
}

/// `(x, y, z)` in frond's right-handed frame to Unity's left-handed frame (X mirrored). Adding
/// `+0.0` turns a mirrored `0.0` into `0.0` rather than `-0.0`, so a zero is encoded as zero bytes.
pub fn unity_position(p: [f32; 3]) -> [f32; 3] {
    [-p[0] + 0.0, p[1], p[2]]
}

/// A rotation quaternion `[x, y, z, w]` in frond's right-handed frame to Unity's left-handed frame
/// (X mirrored: the rotation axis, a pseudovector, becomes `(x, -y, -z)`, the angle is kept).
pub fn unity_quat(q: [f32; 4]) -> [f32; 4] {
    [q[0], -q[1] + 0.0, -q[2] + 0.0, q[3]]
}

/// The datagrams of one frame, in a buffer reused from frame to frame.
#[derive(Debug, Default, Clone)]
pub struct Datagrams {
    buf: Vec<u8>,
    ends: Vec<usize>,
    scratch: Vec<u8>,
    timetag: Option<OscTime>,
    open: bool,
}

impl Datagrams {
    /// Empty buffers.
    pub fn new() -> Datagrams {
        Datagrams {
            buf: Vec::with_capacity(2 * MAX_DATAGRAM_BYTES),
            ends: Vec::with_capacity(4),
            scratch: Vec::with_capacity(MAX_DATAGRAM_BYTES),
            timetag: None,
            open: false,
        }
    }

    /// Number of datagrams.
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// True when there is nothing to send.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// The datagrams, in sending order.
    pub fn iter(&self) -> impl Iterator<Item = &[u8]> + '_ {
        let starts = std::iter::once(0).chain(self.ends.iter().copied());
        starts.zip(self.ends.iter().copied()).map(|(s, e)| &self.buf[s..e])
    }

    /// The `i`-th datagram.
    pub fn get(&self, i: usize) -> Option<&[u8]> {
        let end = *self.ends.get(i)?;
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        Some(&self.buf[start..end])
    }

    /// Starts a frame: forgets the previous one and sets the timetag of its bundles.
    pub(crate) fn begin(&mut self, tag: OscTime) {
        self.buf.clear();
        self.ends.clear();
        self.timetag = Some(tag);
        self.open = false;
    }

    /// Encodes `packet` (a message) and appends it to the current bundle, or to a new one when it
    /// would not fit.
    pub(crate) fn push(&mut self, packet: &OscPacket) -> Result<(), EncodeError> {
        self.scratch.clear();
        let Ok(len) = rosc::encoder::encode_into(packet, &mut self.scratch);
        if BUNDLE_HEADER_BYTES + 4 + len > MAX_DATAGRAM_BYTES {
            let address = match packet {
                OscPacket::Message(m) => m.addr.clone(),
                OscPacket::Bundle(_) => "#bundle".to_string(),
            };
            return Err(EncodeError::MessageTooLarge { address, bytes: len });
        }
        let start = self.ends.last().copied().unwrap_or(0);
        if self.open && self.buf.len() - start + 4 + len > MAX_DATAGRAM_BYTES {
            self.close();
        }
        if !self.open {
            let tag = self.timetag.expect("begin() before push()");
            self.buf.extend_from_slice(b"#bundle\0");
            self.buf.extend_from_slice(&tag.seconds.to_be_bytes());
            self.buf.extend_from_slice(&tag.fractional.to_be_bytes());
            self.open = true;
        }
        self.buf.extend_from_slice(&(len as u32).to_be_bytes());
        self.buf.extend_from_slice(&self.scratch);
        Ok(())
    }

    /// Ends the frame's last bundle.
    pub(crate) fn finish(&mut self) {
        self.close();
    }

    fn close(&mut self) {
        if self.open {
            self.ends.push(self.buf.len());
            self.open = false;
        }
    }
}

/// Writes `value` into the `Float` argument `i` of a template message.
pub(crate) fn set_f32(packet: &mut OscPacket, i: usize, value: f32) {
    if let OscPacket::Message(m) = packet {
        m.args[i] = rosc::OscType::Float(value);
    }
}

/// A message template with `n` zero float arguments after the `head` arguments.
pub(crate) fn template(addr: String, head: Vec<rosc::OscType>, n: usize) -> OscPacket {
    let mut args = head;
    args.extend(std::iter::repeat_n(rosc::OscType::Float(0.0), n));
    OscPacket::Message(rosc::OscMessage { addr, args })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timetag_of_a_hand_computed_instant() {
        // Monotonic 1.5 s, wall clock 1_700_000_000.25 s since 1970 at that instant.
        let offset = ClockOffset::fixed(1_700_000_000_250_000_000 - 1_500_000_000);
        let tag = timetag(1_500_000_000, offset);
        // 1_700_000_000 + 2_208_988_800 = 3_908_988_800; 0.25 * 2^32 = 0x4000_0000.
        assert_eq!(tag, OscTime { seconds: 3_908_988_800, fractional: 0x4000_0000 });
        // One nanosecond is 4.294967296 units of 2^-32 s: floor gives 4.
        let tag = timetag(1_500_000_001, offset);
        assert_eq!(tag.fractional, 0x4000_0004);
        // 999_999_999 ns -> floor(0.999999999 * 2^32) = 4_294_967_291.
        let tag = timetag(2_249_999_999, offset);
        assert_eq!(tag, OscTime { seconds: 3_908_988_800, fractional: 4_294_967_291 });
    }

    #[test]
    fn timetag_round_trips_to_the_nanosecond() {
        let offset = ClockOffset::fixed(1_699_999_000_123_456_789);
        for ns in [0u64, 1, 999_999_999, 1_000_000_000, 123_456_789_012, 86_400_000_000_123] {
            assert_eq!(offset.monotonic_ns_of(timetag(ns, offset)), i128::from(ns), "{ns}");
        }
    }

    #[test]
    fn timetag_before_1970_is_clamped() {
        assert_eq!(timetag(5, ClockOffset::fixed(-10)), OscTime { seconds: 0, fractional: 0 });
    }

    #[test]
    fn measured_offset_is_near_the_wall_clock() {
        let offset = ClockOffset::measure();
        let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap();
        let tag = timetag(monotonic_ns(), offset);
        let diff = i128::from(tag.seconds) - i128::from(NTP_UNIX_OFFSET_S) - now.as_secs() as i128;
        assert!(diff.abs() <= 1, "{diff}");
    }

    #[test]
    fn unity_conversion_mirrors_x() {
        assert_eq!(unity_position([1.0, 2.0, 3.0]), [-1.0, 2.0, 3.0]);
        assert_eq!(unity_position([0.0, 0.5, 0.0])[0].to_bits(), 0, "no negative zero");
        assert_eq!(unity_quat([0.1, 0.2, 0.3, 0.9]), [0.1, -0.2, -0.3, 0.9]);
        assert_eq!(unity_quat([0.0, 0.0, 0.0, 1.0])[1].to_bits(), 0, "no negative zero");
    }

    /// A mirrored rotation applied to a mirrored vector is the mirror of the rotated vector.
    #[test]
    fn unity_quat_is_the_mirror_of_the_rotation() {
        use frond_protocol::convention::{joint_quat, quat_mul};
        let rotate = |q: [f32; 4], v: [f32; 3]| {
            let q = q.map(f64::from);
            let p = quat_mul(
                quat_mul(q, [f64::from(v[0]), f64::from(v[1]), f64::from(v[2]), 0.0]),
                [-q[0], -q[1], -q[2], q[3]],
            );
            [p[0] as f32, p[1] as f32, p[2] as f32]
        };
        for angles in [[30.0, 0.0, 0.0], [0.0, -45.0, 0.0], [10.0, 20.0, 70.0], [-80.0, 33.0, -12.0]] {
            let q = joint_quat(angles);
            for v in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.3, -0.4, 0.8]] {
                let expected = unity_position(rotate(q, v));
                let got = rotate(unity_quat(q), unity_position(v));
                for k in 0..3 {
                    assert!((expected[k] - got[k]).abs() < 1e-5, "{angles:?} {v:?}: {expected:?} vs {got:?}");
                }
            }
        }
    }
}
