//! The simulated plant of seed 003 (section 4) running in the loop, published every tick as the
//! global element (flagged `playback`), so every subscriber and the recorder take it as any
//! stream. The hand blows it: while the root is bent by more than
//! [`super::graph::HAND_GOAL_MIN_BEND_DEG`], the wind turns to the bend's direction (0 deg
//! towards +X, 90 towards +Z) at [`HAND_WIND_M_S_PER_DEG`] metres per second per degree of bend
//! (at most [`MAX_HAND_WIND_M_S`]), keeping the spec's gusts; below it the spec's wind blows.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use frond_motion::sim::{PlantSim, WindSpec};
use frond_motion::{HandSample, PoseFrame, Rig};
use frond_protocol::{ElementInfo, ElementKind};

use super::graph::bend_direction_deg;
use super::{
    BuildContext, BuildError, BuiltStage, FrameSink, LiveStage, StageInfo, StageReport, TickContext, no_input,
};
use crate::clock::NS_PER_S;

/// Wind speed per degree of the hand's bend, metres per second.
pub const HAND_WIND_M_S_PER_DEG: f64 = 0.2;
/// Strongest wind the hand makes, metres per second.
pub const MAX_HAND_WIND_M_S: f64 = 12.0;
/// Most simulation steps per tick (after a stall the simulation skips ahead instead).
pub const MAX_STEPS_PER_TICK: u32 = 50;

/// What `frond status` says of the simulation.
pub struct SimReport {
    base: String,
    speed_m_s: AtomicU64,
    dir_deg: AtomicU64,
    t_s: AtomicU64,
    diverged: AtomicU64,
}

impl StageReport for SimReport {
    fn describe(&self) -> String {
        let f = |a: &AtomicU64| f64::from_bits(a.load(Relaxed));
        let state = if self.diverged.load(Relaxed) == 1 { "; diverged, stopped" } else { "" };
        format!(
            "simulated plant ({}): wind {:.1} m/s towards {:.0} deg at {:.1} s{state}",
            self.base,
            f(&self.speed_m_s),
            f(&self.dir_deg),
            f(&self.t_s)
        )
    }
}

/// The simulation in the loop.
pub struct SimStage {
    plant: PlantSim,
    base: WindSpec,
    wind: WindSpec,
    t0_ns: u64,
    skipped_s: f64,
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
        });
        let pose = plant.pose();
        let stage = SimStage {
            plant,
            base: wind,
            wind,
            t0_ns,
            skipped_s: 0.0,
            pose,
            diverged: false,
            report: report.clone(),
        };
        (stage, report)
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
    fn on_hand(&mut self, _hand: &HandSample, pose: &mut PoseFrame, _element: &mut u16) {
        let w = hand_wind(self.base, pose.joints_deg[0]);
        self.set_wind(w);
    }

    fn tick(&mut self, ctx: &TickContext, out: &mut dyn FrameSink) {
        let t = ctx.now_ns.saturating_sub(self.t0_ns) as f64 / NS_PER_S as f64 - self.skipped_s;
        let h = self.plant.params().timestep_s;
        let mut steps = 0;
        while !self.diverged && self.plant.time_s() + 0.5 * h <= t {
            if steps == MAX_STEPS_PER_TICK {
                self.skipped_s += t - self.plant.time_s();
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
        out.emit(0, self.pose.joints_deg);
    }

    fn every_tick(&self) -> bool {
        true
    }
}

/// Builds the simulation of `rig_toml`'s plant (or the active rig's) in `wind`.
pub fn build(rig_toml: Option<&str>, wind: &str, ctx: &BuildContext) -> Result<BuiltStage, BuildError> {
    let wind: WindSpec = wind.parse().map_err(|e| BuildError::invalid(format!("wind {wind:?}: {e}")))?;
    let rig = match rig_toml {
        Some(text) => Rig::from_toml_str(text).map_err(|e| BuildError::invalid(format!("rig: {e}")))?,
        None => ctx.rig.clone(),
    };
    let plant = PlantSim::from_rig(&rig, wind)
        .map_err(|e| BuildError::invalid(format!("rig {:?}: {e}", rig.name)))?;
    let (stage, report) = SimStage::new(plant, wind, ctx.now_ns, &format!("rig {}, wind {wind}", rig.name));
    Ok(BuiltStage {
        stage: Box::new(stage),
        info: StageInfo {
            kind: "sim",
            report,
            elements: vec![ElementInfo {
                id: 0,
                name: format!("sim-{}", rig.name),
                kind: ElementKind::Playback,
                source: ctx.name.to_string(),
                rig: rig.name.clone(),
            }],
            hand_element: None,
            accepts: no_input,
            rig: super::rig_info(&rig),
        },
    })
}

#[cfg(test)]
mod tests {
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
}
