//! Stage time: one timeline for every source of a stage (issue 20).
//!
//! A pose carries `host_monotonic_ns`, its host's `CLOCK_MONOTONIC`, which means nothing on
//! another host. A `frond-zenoh` bridge therefore stamps every pose sample it publishes with the
//! pose's **stage time**: the same instant on its host's realtime clock, nanoseconds since 1970
//! (`host_monotonic_ns` plus the host's realtime-minus-monotonic offset, read by the bridge),
//! carried as the sample's attachment, 8 bytes little-endian ([`encode_attachment`]).
//!
//! Realtime clocks of two hosts agree only as well as NTP or PTP keeps them. So a stage recorder
//! also measures each source's clock against its own, NTP-style, through the bridge's
//! `.../clock` queryable ([`ClockReading`]): it notes its realtime clock `t0`, asks, the bridge
//! answers its realtime clock `t1`, the answer arrives at `t2`; then the source's clock is ahead
//! by `t1 - (t0 + t2) / 2`, give or take half the round trip `t2 - t0`. Of several exchanges the
//! one with the shortest round trip wins ([`ClockOffset::estimate`]). Takes store that offset,
//! and `frond take export --align` subtracts it, putting every source on the recorder's clock.

use serde::{Deserialize, Serialize};

/// Bytes of a pose sample's attachment.
pub const ATTACHMENT_LEN: usize = 8;

/// The attachment of a pose sample: its stage time, `u64` little-endian.
pub fn encode_attachment(stage_ns: u64) -> [u8; ATTACHMENT_LEN] {
    stage_ns.to_le_bytes()
}

/// The stage time in a pose sample's attachment; `None` unless it is exactly 8 bytes.
pub fn decode_attachment(bytes: &[u8]) -> Option<u64> {
    Some(u64::from_le_bytes(bytes.try_into().ok()?))
}

/// `CLOCK_REALTIME` now, nanoseconds since 1970 (0 before 1970).
pub fn realtime_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::SystemTime::UNIX_EPOCH)
        .map(|d| d.as_nanos().min(u128::from(u64::MAX)) as u64)
        .unwrap_or(0)
}

/// A host's two clocks read back to back: the reply of a bridge's `.../clock` queryable, as
/// JSON `{"unix_ns": .., "monotonic_ns": ..}`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClockReading {
    /// `CLOCK_REALTIME`, nanoseconds since 1970.
    pub unix_ns: u64,
    /// `CLOCK_MONOTONIC`, nanoseconds.
    pub monotonic_ns: u64,
}

impl ClockReading {
    /// The stage time of an instant stamped `monotonic_ns` on this host.
    pub fn stage_ns_of(&self, monotonic_ns: u64) -> u64 {
        let d = i128::from(monotonic_ns) - i128::from(self.monotonic_ns);
        (i128::from(self.unix_ns) + d).clamp(0, i128::from(u64::MAX)) as u64
    }

    /// JSON text of the reading.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("two integers serialise")
    }

    /// Parses a reading; `None` for anything else (at most 256 bytes are looked at).
    pub fn from_json(bytes: &[u8]) -> Option<ClockReading> {
        if bytes.len() > 256 {
            return None;
        }
        serde_json::from_slice(bytes).ok()
    }
}

/// How far a source's realtime clock is ahead of ours, from one or more query exchanges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClockOffset {
    /// Source clock minus our clock, nanoseconds (negative: the source is behind).
    pub offset_ns: i64,
    /// Round trip of the exchange it comes from: the estimate is good to half of it.
    pub rtt_ns: u64,
}

impl ClockOffset {
    /// The estimate of one exchange: we read `sent_ns`, the source answered `source_ns`, the
    /// answer arrived at `received_ns` (ours). `None` when the answer arrived before it was sent.
    pub fn of_exchange(sent_ns: u64, source_ns: u64, received_ns: u64) -> Option<ClockOffset> {
        let rtt = received_ns.checked_sub(sent_ns)?;
        let midpoint = i128::from(sent_ns) + i128::from(rtt / 2);
        let offset = (i128::from(source_ns) - midpoint).clamp(i128::from(i64::MIN), i128::from(i64::MAX));
        Some(ClockOffset { offset_ns: offset as i64, rtt_ns: rtt })
    }

    /// Of several exchanges `(sent_ns, source_ns, received_ns)`, the one with the shortest
    /// round trip (the least room for asymmetry); `None` if none is usable.
    pub fn estimate(exchanges: &[(u64, u64, u64)]) -> Option<ClockOffset> {
        exchanges.iter().filter_map(|&(a, b, c)| Self::of_exchange(a, b, c)).min_by_key(|o| o.rtt_ns)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_attachment_is_eight_bytes_little_endian() {
        assert_eq!(encode_attachment(0x0102_0304_0506_0708), [8, 7, 6, 5, 4, 3, 2, 1]);
        assert_eq!(decode_attachment(&[8, 7, 6, 5, 4, 3, 2, 1]), Some(0x0102_0304_0506_0708));
        assert_eq!(decode_attachment(&[1, 2, 3]), None);
        assert_eq!(decode_attachment(&[0; 9]), None);
    }

    #[test]
    fn an_exchange_puts_the_source_clock_at_the_midpoint() {
        // Sent at 1000, received at 1400 (our clock): the source read its clock at our 1200,
        // and it said 251_200, so it is 250_000 ahead, give or take 200.
        let o = ClockOffset::of_exchange(1000, 251_200, 1400).unwrap();
        assert_eq!(o, ClockOffset { offset_ns: 250_000, rtt_ns: 400 });
        // A source behind us.
        assert_eq!(ClockOffset::of_exchange(10_000, 4_000, 10_000).unwrap().offset_ns, -6_000);
        // An answer that arrived before it was sent is no measurement.
        assert_eq!(ClockOffset::of_exchange(2000, 5, 1999), None);
    }

    #[test]
    fn the_shortest_round_trip_wins() {
        let exchanges = [(0, 600, 1000), (5000, 5350, 5100), (9000, 9900, 9300)];
        assert_eq!(ClockOffset::estimate(&exchanges), Some(ClockOffset { offset_ns: 300, rtt_ns: 100 }));
        assert_eq!(ClockOffset::estimate(&[]), None);
    }

    #[test]
    fn a_reading_maps_monotonic_stamps_to_stage_time_and_round_trips_as_json() {
        let r = ClockReading { unix_ns: 1_700_000_000_000_000_000, monotonic_ns: 5_000 };
        assert_eq!(r.stage_ns_of(6_000), 1_700_000_000_000_001_000);
        assert_eq!(r.stage_ns_of(4_000), 1_699_999_999_999_999_000);
        assert_eq!(ClockReading::from_json(r.to_json().as_bytes()), Some(r));
        assert_eq!(ClockReading::from_json(b"{\"unix_ns\": -1, \"monotonic_ns\": 0}"), None);
        assert_eq!(ClockReading::from_json(&[b' '; 300]), None);
    }
}
