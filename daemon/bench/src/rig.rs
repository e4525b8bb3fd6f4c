//! The in-process pieces the loop measurements share: the reference rig, a glove source that
//! delivers one fresh reference-glove report per tick, and a mapper like the daemon's.

use std::sync::Arc;

use frond_device::{
    DeviceProfile, DeviceSample, HandSource, ReportParser, SourceCounters, SourceError, SourceKind,
};
use frond_formats::rig_toml::RigText;
use frond_motion::{Calibration, FilterSpec, Mapper, Rig};
use frond_vhid::glove::{GloveReport, STATUS_TRACKING_OK, encode_report};
use frond_vhid::sway_sample;

/// The grass rig frondd embeds as its default.
pub fn grass() -> Rig {
    Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml"))
        .expect("the embedded grass rig is valid")
}

/// The daemon's mapper for the grass rig with the One Euro filter (the costliest filter).
pub fn mapper() -> Mapper {
    let rig = grass();
    let cal = Calibration::neutral_for(&rig);
    Mapper::new(
        rig.mapping(),
        cal.params(),
        FilterSpec::OneEuro { min_cutoff: 1.0, beta: 0.007, d_cutoff: 1.0 },
    )
}

/// A glove that has exactly one new report whenever it is read: the virtual glove's sway encoded
/// as the 64-byte reference report and parsed by the same [`ReportParser`] as a real device,
/// without a generator thread of its own (so only the loop under test wakes up).
pub struct TickGlove {
    parser: ReportParser,
    seq: u32,
}

impl Default for TickGlove {
    fn default() -> Self {
        Self::new()
    }
}

impl TickGlove {
    /// A glove at sequence 0.
    pub fn new() -> Self {
        TickGlove { parser: ReportParser::new(&DeviceProfile::frond_glove()), seq: 0 }
    }

    /// The next report's bytes (a 1 kHz schedule of the sway).
    pub fn next_report(&mut self) -> [u8; frond_vhid::glove::REPORT_LEN] {
        let t_us = u64::from(self.seq) * 1000;
        let (hand, flex) = sway_sample(t_us as f64 / 1e6);
        let (report, _) = GloveReport::from_degrees(self.seq, t_us as u32, &hand, flex, STATUS_TRACKING_OK);
        self.seq = self.seq.wrapping_add(1);
        encode_report(&report)
    }
}

impl HandSource for TickGlove {
    fn kind(&self) -> SourceKind {
        SourceKind::InProcess
    }
    fn describe(&self) -> &str {
        "bench glove (one reference report per read)"
    }
    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        if out.is_empty() {
            return Ok(0);
        }
        let bytes = self.next_report();
        match self.parser.parse(&bytes) {
            Ok(s) => {
                out[0] = s;
                Ok(1)
            }
            Err(_) => Ok(0),
        }
    }
    fn counters(&self) -> Arc<SourceCounters> {
        self.parser.counters()
    }
    fn reopen(&mut self) -> Result<(), SourceError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_glove_delivers_one_valid_report_per_read() {
        let mut g = TickGlove::new();
        let mut out = [DeviceSample::default(); 4];
        for i in 0..5u32 {
            assert_eq!(g.read_pending(&mut out).unwrap(), 1);
            assert_eq!(out[0].device_seq, i);
            assert_eq!(out[0].device_time_us, u64::from(i) * 1000);
        }
        assert_eq!(g.counters().snapshot().checksum, 0);
    }
}
