//! A device that delivers a full batch of reports and then fails within one tick is lost: its
//! frames after that are flagged `device_lost` until the reopened device is handed back. (The
//! reports before the failure used to mark it connected again; the soak saw unplugs that no
//! subscriber could see.)

use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;

use frond_device::{DeviceSample, HandSource, SourceCounters, SourceError, SourceKind};
use frond_formats::rig_toml::RigText;
use frond_motion::{FilterSpec, HandSample, Mapper, Rig};
use frond_protocol::PoseFlags;
use frondd::engine::{Engine, LoopCommand};

/// Full batches for `good_reads` calls, then an error on every call.
struct FailsAfter {
    good_reads: u32,
    seq: u32,
    counters: Arc<SourceCounters>,
}

impl HandSource for FailsAfter {
    fn kind(&self) -> SourceKind {
        SourceKind::InProcess
    }
    fn describe(&self) -> &str {
        "fails after a batch"
    }
    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        if self.good_reads == 0 {
            return Err(SourceError::Disconnected { what: "test".into(), reason: "unplugged".into() });
        }
        self.good_reads -= 1;
        for slot in out.iter_mut() {
            self.seq += 1;
            *slot = DeviceSample {
                device_seq: self.seq,
                device_time_us: u64::from(self.seq),
                raw: HandSample { t: f64::from(self.seq) * 1e-6, ..HandSample::default() },
                ..DeviceSample::default()
            };
        }
        Ok(out.len())
    }
    fn counters(&self) -> Arc<SourceCounters> {
        self.counters.clone()
    }
    fn reopen(&mut self) -> Result<(), SourceError> {
        self.good_reads = 1000;
        Ok(())
    }
}

#[test]
fn reports_then_an_error_in_one_tick_leave_the_device_lost() {
    let rig = Rig::from_toml_str(include_str!("../../../rig-files/plants/grass.toml")).unwrap();
    let cal = frond_motion::Calibration::neutral_for(&rig);
    let mapper = Mapper::new(rig.mapping(), cal.params(), FilterSpec::None);
    let source = Box::new(FailsAfter { good_reads: 1, seq: 0, counters: Arc::default() });
    let (mut engine, ends) = Engine::with_channels(mapper, Some(source), 250_000_000, 1 << 16, 16);
    let mut now = 1_000_000_000u64;
    now += 1_000_000;
    engine.tick(now); // 64 reports, then the error, in one tick
    assert!(!ends.stats.hands[0].connected.load(Relaxed), "the device is lost after its failed read");
    assert_eq!(ends.stats.hands[0].lost_events.load(Relaxed), 1);
    let lost = ends.reopen.try_recv().expect("handed to the reopen thread");
    assert_eq!(lost.hand, 0);
    let mut src = lost.source;
    for _ in 0..5 {
        now += 1_000_000;
        engine.tick(now);
    }
    let frames: Vec<_> = ends.frames.try_iter().collect();
    assert_eq!(frames.len(), 64 + 5);
    assert!(frames[64..].iter().all(|p| p.flags.contains(PoseFlags::DEVICE_LOST | PoseFlags::HELD)));
    // Handed back, it reports again and is connected.
    src.reopen().unwrap();
    ends.commands.send(LoopCommand::ReplaceSource(0, src)).unwrap();
    now += 1_000_000;
    engine.tick(now);
    assert!(ends.stats.hands[0].connected.load(Relaxed));
}
