//! The simulated plant of seed 003 (section 4) running in the loop, published every tick as the
//! global element (flagged `playback`), so every subscriber and the recorder take it as any
//! stream. The hand blows it: while the root is bent by more than
//! [`super::graph::HAND_GOAL_MIN_BEND_DEG`], the wind turns to the bend's direction (0 deg
//! towards +X, 90 towards +Z) at [`HAND_WIND_M_S_PER_DEG`] metres per second per degree of bend
//! (at most [`MAX_HAND_WIND_M_S`]), keeping the spec's gusts; below it the spec's wind blows.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use frond_motion::sim::{PlantSim, WindSpec};
use frond_motion::{HandSample, PoseFrame};
use frond_protocol::control::StageKind;
use frond_protocol::{ElementId, ElementInfo, ElementKind};

use super::budget::{self, TickWork};
use super::error::BuildError;
use super::graph::bend_direction_deg;
use super::live::{
    BuildContext, BuiltStage, FrameSink, LiveStage, StageInfo, StageReport, TickContext, no_input,
};
use crate::clock::NS_PER_S;

/// Wind speed per degree of the hand's bend, metres per second.
pub const HAND_WIND_M_S_PER_DEG: f64 = 0.2;
/// Strongest wind the hand makes, metres per second.
pub const MAX_HAND_WIND_M_S: f64 = 12.0;
/// Most simulation steps per tick at the default 1 kHz tick ([`budget::units_per_tick`] of
/// [`budget::SIM_STEP_NS`]); a stage built for another rate gets its own from
/// [`SimStage::with_step_budget`]. Behind by more (the loop was late, the host stalled), the
/// simulation skips ahead to the present and counts the steps it dropped.
pub const MAX_STEPS_PER_TICK: u32 = 2;

/// What `frond status` says of the simulation.
pub struct SimReport {
    base: String,
    speed_m_s: AtomicU64,
    dir_deg: AtomicU64,
    t_s: AtomicU64,
    diverged: AtomicU64,
    dropped_steps: AtomicU64,
    late_ticks: AtomicU64,
}

impl StageReport for SimReport {
    fn describe(&self) -> String {
        let f = |a: &AtomicU64| f64::from_bits(a.load(Relaxed));
        let state = if self.diverged.load(Relaxed) == 1 { "; diverged, stopped" } else { "" };
        let late = match self.late_ticks.load(Relaxed) {
            0 => String::new(),
            n => format!(
                "; BEHIND: {} steps dropped in {n} ticks over the budget (kept real time)",
                self.dropped_steps.load(Relaxed)
            ),
        };
        format!(
            "simulated plant ({}): wind {:.1} m/s towards {:.0} deg at {:.1} s{state}{late}",
            self.base,
            f(&self.speed_m_s),
            f(&self.dir_deg),
            f(&self.t_s)
        )
    }

    fn dropped_work(&self) -> u64 {
        self.dropped_steps.load(Relaxed)
    }
}

/// The simulation in the loop.
pub struct SimStage {
    plant: PlantSim,
    base: WindSpec,
    wind: WindSpec,
    t0_ns: u64,
    max_steps: u32,
    pose: PoseFrame,
    diverged: bool,
    report: Arc<SimReport>,
}

impl SimStage {
    /// `plant` blown by `wind`, from host time `t0_ns`.
    pub fn new(plant: PlantSim, wind: WindSpec, t0_ns: u64, base: &str) -> (Self, Arc<SimReport>) {
        let report = Arc::new(SimReport {
            base: base.to_string(),
            speed_m_s: AtomicU64::new(wind.speed_m_s.to_bits()),
            dir_deg: AtomicU64::new(wind.dir_deg.to_bits()),
            t_s: AtomicU64::new(0f64.to_bits()),
            diverged: AtomicU64::new(0),
            dropped_steps: AtomicU64::new(0),
            late_ticks: AtomicU64::new(0),
        });
        let pose = plant.pose();
        let stage = SimStage {
            plant,
            base: wind,
            wind,
            t0_ns,
            max_steps: MAX_STEPS_PER_TICK,
            pose,
            diverged: false,
            report: report.clone(),
        };
        (stage, report)
    }

    /// The same stage doing at most `steps` simulation steps per tick (at least 1).
    pub fn with_step_budget(mut self, steps: u32) -> Self {
        self.max_steps = steps.max(1);
        self
    }

    fn set_wind(&mut self, w: WindSpec) {
        if (w.speed_m_s - self.wind.speed_m_s).abs() < 0.1 && (w.dir_deg - self.wind.dir_deg).abs() < 1.0 {
            return;
        }
        self.wind = w;
        self.plant.set_wind(w);
        self.report.speed_m_s.store(w.speed_m_s.to_bits(), Relaxed);
        self.report.dir_deg.store(w.dir_deg.to_bits(), Relaxed);
    }
}

/// The wind the hand's root bend makes of `base` (see the module doc).
pub fn hand_wind(base: WindSpec, root_deg: [f32; 3]) -> WindSpec {
    match bend_direction_deg(root_deg) {
        Some(dir_deg) => {
            let bend = f64::from(root_deg[0].hypot(root_deg[1]));
            WindSpec {
                speed_m_s: (bend * HAND_WIND_M_S_PER_DEG).min(MAX_HAND_WIND_M_S),
                dir_deg,
                until_s: None,
                ..base
            }
        }
        None => base,
    }
}

impl LiveStage for SimStage {
    fn on_hand(&mut self, _hand: &HandSample, pose: &mut PoseFrame, _element: &mut ElementId) {
        let w = hand_wind(self.base, pose.joints_deg[0]);
        self.set_wind(w);
    }

    fn tick(&mut self, ctx: &TickContext, out: &mut dyn FrameSink) {
        let t = ctx.now_ns.saturating_sub(self.t0_ns) as f64 / NS_PER_S as f64;
        let h = self.plant.params().timestep_s;
        let mut steps = 0;
        while !self.diverged && self.plant.time_s() + 0.5 * h <= t {
            if steps == self.max_steps {
                // Over budget: the steps left are dropped and the plant's clock jumps to the
                // present, so that it keeps real time (the wind with it) and the loop its rate.
                let dropped = ((t - self.plant.time_s()) / h + 0.5).floor().max(1.0) as u64;
                self.plant.skip_to(t);
                self.report.dropped_steps.fetch_add(dropped, Relaxed);
                self.report.late_ticks.fetch_add(1, Relaxed);
                break;
            }
            if self.plant.step().is_err() {
                self.diverged = true;
                self.report.diverged.store(1, Relaxed);
            }
            steps += 1;
        }
        if steps > 0 {
            self.pose = self.plant.pose();
            self.report.t_s.store(self.plant.time_s().to_bits(), Relaxed);
        }
        out.emit(ElementId::GLOBAL, self.pose.joints_deg);
    }

    fn every_tick(&self) -> bool {
        true
    }
}

/// Builds the simulation of `rig_toml`'s plant (or the active rig's) in `wind`.
pub fn build(rig_toml: Option<&str>, wind: &str, ctx: &BuildContext) -> Result<BuiltStage, BuildError> {
    let wind: WindSpec = wind.parse().map_err(|e| BuildError::invalid(format!("wind {wind:?}: {e}")))?;
    let rig = match rig_toml {
        Some(text) => super::live::rig_from_request(text, "the simulated plant's")?,
        None => ctx.rig.clone(),
    };
    let plant = PlantSim::from_rig(&rig, wind)
        .map_err(|e| BuildError::invalid(format!("rig {:?}: {e}", rig.name)))?;
    let work = step_work(rig.sim.timestep_s, ctx.tick_rate_hz);
    work.check(ctx.tick_rate_hz)?;
    let budget =
        budget::units_per_tick(ctx.tick_rate_hz, budget::SIM_STEP_NS).min(u64::from(u32::MAX)) as u32;
    let (stage, report) = SimStage::new(plant, wind, ctx.now_ns, &format!("rig {}, wind {wind}", rig.name));
    let stage = stage.with_step_budget(budget);
    Ok(BuiltStage {
        stage: Box::new(stage),
        info: StageInfo {
            kind: StageKind::Sim,
            report,
            elements: vec![ElementInfo {
                id: ElementId::GLOBAL,
                name: format!("sim-{}", rig.name),
                kind: ElementKind::Playback,
                source: ctx.name.to_string(),
                rig: rig.name.clone(),
            }],
            hand_element: None,
            accepts: no_input,
            rig: super::live::rig_info(&rig),
            work,
        },
    })
}

/// The simulation's work per tick: the steps of `timestep_s` one tick at `tick_rate_hz` needs.
pub fn step_work(timestep_s: f64, tick_rate_hz: u32) -> TickWork {
    let units = budget::steps_per_tick(timestep_s, tick_rate_hz);
    let fit = budget::units_per_tick(tick_rate_hz, budget::SIM_STEP_NS);
    // Rounded up to the microsecond, so that the value suggested fits.
    let min_step_s = (1e6 / (f64::from(tick_rate_hz.max(1)) * fit as f64)).ceil() / 1e6;
    TickWork {
        asked_by: format!("sim.timestep_s = {timestep_s} s"),
        unit: "simulation steps",
        units,
        unit_ns: budget::SIM_STEP_NS,
        extra_ns: 0,
        fix: format!(
            "use a sim.timestep_s of at least {min_step_s} s (shorter steps cannot keep real time \
             in a stage's share of the loop; `frond take simulate` has no such limit)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use frond_formats::rig_toml::RigText;
    use frond_motion::Rig;

    use super::*;

    #[test]
    fn the_hand_bend_sets_the_wind() {
        let base: WindSpec = "speed=1,dir=0,gust=0.5,seed=3,until=9".parse().unwrap();
        // A 30 degree pitch: towards +Z at 6 m/s, gusts kept, no end.
        let w = hand_wind(base, [30.0, 0.0, 0.0]);
        assert!((w.dir_deg - 90.0).abs() < 1e-9 && (w.speed_m_s - 6.0).abs() < 1e-6, "{w}");
        assert_eq!((w.gust, w.seed, w.until_s), (0.5, 3, None));
        assert!((hand_wind(base, [0.0, 90.0, 0.0]).speed_m_s - MAX_HAND_WIND_M_S).abs() < 1e-9);
        assert_eq!(hand_wind(base, [1.0, 1.0, 0.0]), base, "a small bend leaves the spec's wind");
    }

    const GRASS: &str = include_str!("../../../../rig-files/plants/grass.toml");

    fn build_with(rig_toml: &str, tick_rate_hz: u32) -> Result<BuiltStage, BuildError> {
        let rig = Rig::from_toml_str(GRASS).unwrap();
        let ctx = BuildContext {
            takes_dir: std::path::Path::new("/nonexistent"),
            rig: &rig,
            g3_range_deg: 60.0,
            tick_rate_hz,
            now_ns: 0,
            free_ids: &[ElementId::new(33), ElementId::new(34)],
            name: "sim",
        };
        let spec = frond_protocol::StageSpec::Sim {
            rig_toml: Some(rig_toml.into()),
            wind: "speed=1,dir=0,gust=0,seed=1".into(),
        };
        super::super::build(&spec, &ctx)
    }

    #[test]
    fn a_rig_text_past_the_limit_or_not_a_rig_is_refused_before_a_plant_is_made() {
        let huge = format!("{GRASS}\n# {}\n", "x".repeat(frond_protocol::MAX_STAGE_RIG_BYTES));
        let e = build_with(&huge, 1000).err().expect("a rig text past 64 KiB is refused");
        assert_eq!(e.kind, frond_protocol::ControlErrorKind::Invalid);
        let want =
            format!("the simulated plant's rig is {} bytes of text; a rig file is at most 65536", huge.len());
        assert_eq!(e.message, want);
        let e = build_with("name = [", 1000).err().expect("not a rig");
        assert!(e.message.starts_with("the simulated plant's rig: TOML parse error"), "{}", e.message);
        // The limit itself is a rig file's size: GRASS padded to it plays.
        let fits = format!("{GRASS}\n#{}", " ".repeat(frond_protocol::MAX_STAGE_RIG_BYTES - GRASS.len() - 2));
        assert_eq!(fits.len(), frond_protocol::MAX_STAGE_RIG_BYTES);
        assert!(build_with(&fits, 1000).is_ok());
    }

    #[test]
    fn a_timestep_that_asks_for_more_steps_than_a_tick_allows_is_refused_with_the_reason() {
        // 1 ms at 1 kHz over a 10 us step: 100 steps a tick. A stage's share of a 1 ms tick is
        // 1 ms / 16 = 62.5 us, two steps of 30 us: the smallest step that fits is 0.5 ms.
        let e = build_with(&format!("{GRASS}\n[sim]\ntimestep_s = 0.00001\n"), 1000).err().unwrap();
        assert!(
            e.message.starts_with(
                "sim.timestep_s = 0.00001 s asks for 100 simulation steps per tick at 1000 Hz (about 3000 us), \
                 more than the tick allows a stage: at most 2 (62 us of the 1000 us tick); use a \
                 sim.timestep_s of at least 0.0005 s"
            ),
            "{}",
            e.message
        );
        // 0.4 ms needs 3 steps (2.5 rounded up): refused; 0.5 ms needs 2: accepted, as is the
        // default 1 ms step.
        assert!(build_with(&format!("{GRASS}\n[sim]\ntimestep_s = 0.0004\n"), 1000).is_err());
        assert!(build_with(&format!("{GRASS}\n[sim]\ntimestep_s = 0.0005\n"), 1000).is_ok());
        assert!(build_with(GRASS, 1000).is_ok());
        // At 100 Hz a tick is 10 ms and the share 625 us, 20 steps: 0.5 ms still the floor.
        assert!(build_with(&format!("{GRASS}\n[sim]\ntimestep_s = 0.0005\n"), 100).is_ok());
        assert!(build_with(&format!("{GRASS}\n[sim]\ntimestep_s = 0.0004\n"), 100).is_err());
    }

    struct Count(usize);
    impl FrameSink for Count {
        fn emit(&mut self, _element: ElementId, _joints_deg: frond_motion::clip::Joints) {
            self.0 += 1;
        }
    }

    #[test]
    fn a_simulation_behind_its_budget_keeps_real_time_and_status_says_so() {
        let rig = Rig::from_toml_str(GRASS).unwrap();
        let wind: WindSpec = "speed=2,dir=0,gust=0,seed=1".parse().unwrap();
        let plant = PlantSim::from_rig(&rig, wind).unwrap();
        assert_eq!(plant.params().timestep_s, 0.001);
        let (stage, report) = SimStage::new(plant, wind, 0, "grass");
        let mut stage = stage.with_step_budget(2);
        let mut sink = Count(0);
        let at = |ns: u64| TickContext { now_ns: ns, device_time_us: 0, hand: HandSample::default() };
        // On time: one 1 ms step a tick, nothing dropped.
        for k in 1..=10u64 {
            stage.tick(&at(k * 1_000_000), &mut sink);
        }
        assert!((stage.plant.time_s() - 0.010).abs() < 1e-9, "{}", stage.plant.time_s());
        assert!(!report.describe().contains("BEHIND"), "{}", report.describe());
        // A 2 s stall: 1990 steps due, 2 taken, 1988 dropped; the plant is at the present.
        stage.tick(&at(2_000_000_000), &mut sink);
        assert!(
            (stage.plant.time_s() - 2.0).abs() < 1e-9,
            "the plant keeps real time: {}",
            stage.plant.time_s()
        );
        let said = report.describe();
        assert!(said.contains("at 2.0 s"), "{said}");
        assert!(said.contains("BEHIND: 1988 steps dropped in 1 ticks over the budget"), "{said}");
        assert_eq!(report.dropped_work(), 1988);
        // And carries on one step a tick.
        stage.tick(&at(2_001_000_000), &mut sink);
        assert!((stage.plant.time_s() - 2.001).abs() < 1e-9, "{}", stage.plant.time_s());
        assert_eq!(sink.0, 12, "one frame a tick");
    }
}
