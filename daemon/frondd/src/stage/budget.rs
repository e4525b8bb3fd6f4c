//! The realtime loop's budget as a contract between the loop and its live stages.
//!
//! Every stage declares, when it is built, the most work it does in one tick ([`TickWork`]: a
//! count of its own work units and what one unit costs), and [`super::build`] refuses a stage
//! whose worst case does not fit in its share of a tick ([`stage_share_ns`]), naming the
//! parameter that asks for it, the work and the limit. The shares of all [`MAX_STAGES`] slots
//! add up to half a tick, so that stages at their worst leave the other half to the hand,
//! the mapping and publishing.
//!
//! At run time a stage never does more than its share: a stage that falls behind (the loop was
//! late, the host stalled) does what fits and skips the rest ahead in time (it keeps real time,
//! not its own slower clock) and counts what it dropped, which `frond status` shows.
//!
//! The unit costs are `cargo bench -p frond-motion --bench mapping` figures ("sim step",
//! "graph walk frame") on the reference host with a margin of about three times, so that a
//! slower host or a cold cache still fits.

use super::error::{BuildError, MAX_STAGES};

/// Nanoseconds in a second.
const NS_PER_S: u64 = 1_000_000_000;

/// Estimated cost of one simulation step (seed 003, section 4.2: one implicit Euler step, its
/// Newton iterations and conjugate gradients), nanoseconds (benchmark: 11.5 us).
pub const SIM_STEP_NS: u64 = 30_000;
/// Estimated cost of one walk frame of one plant on a motion graph (seed 003, section 6),
/// nanoseconds (benchmark: 26 ns on a plain frame; a transition's blend costs more).
pub const GRAPH_WALK_FRAME_NS: u64 = 100;
/// Estimated cost of one node of a pose goal's search or plan, nanoseconds.
pub const GRAPH_PLAN_NODE_NS: u64 = 20;
/// Estimated cost of one field plant's frame (seed 000, section 6), nanoseconds.
pub const FIELD_PLANT_NS: u64 = 300;
/// Estimated cost of one looped take frame or one hand transform, nanoseconds.
pub const SMALL_NS: u64 = 2_000;

/// The part of one tick a single stage may use at its worst, nanoseconds: the tick's period
/// divided among twice [`MAX_STAGES`] (all slots at their worst take half the tick).
pub fn stage_share_ns(tick_rate_hz: u32) -> u64 {
    NS_PER_S / u64::from(tick_rate_hz.max(1)) / (2 * MAX_STAGES as u64)
}

/// How many units of `unit_ns` fit in a stage's share of a tick at `tick_rate_hz` (at least
/// one: the smallest piece of work a stage can do).
pub fn units_per_tick(tick_rate_hz: u32, unit_ns: u64) -> u64 {
    (stage_share_ns(tick_rate_hz) / unit_ns.max(1)).max(1)
}

/// The most work a stage does in one tick, declared when it is built.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TickWork {
    /// The parameters that set it, as the user gave them (`sim.timestep_s = 0.00001 s`).
    pub asked_by: String,
    /// What one unit is, plural (`simulation steps`).
    pub unit: &'static str,
    /// Units per tick at worst.
    pub units: u64,
    /// Estimated cost of one unit, nanoseconds.
    pub unit_ns: u64,
    /// Work besides the units, nanoseconds (a graph's share for planning).
    pub extra_ns: u64,
    /// What to change for it to fit.
    pub fix: String,
}

impl TickWork {
    /// A stage whose work per tick is small and fixed (a looped take, a layer, guided motion).
    pub fn small(what: &'static str) -> TickWork {
        TickWork {
            asked_by: String::new(),
            unit: what,
            units: 1,
            unit_ns: SMALL_NS,
            extra_ns: 0,
            fix: String::new(),
        }
    }

    /// Its estimated cost per tick at worst, nanoseconds.
    pub fn cost_ns(&self) -> u64 {
        self.units.saturating_mul(self.unit_ns).saturating_add(self.extra_ns)
    }

    /// Refuses the work if it does not fit in a stage's share of a tick at `tick_rate_hz`,
    /// naming the parameter, the work it asks for and the limit.
    pub fn check(&self, tick_rate_hz: u32) -> Result<(), BuildError> {
        let share = stage_share_ns(tick_rate_hz);
        if self.cost_ns() <= share {
            return Ok(());
        }
        let fit = share.saturating_sub(self.extra_ns) / self.unit_ns.max(1);
        let by =
            if self.asked_by.is_empty() { String::new() } else { format!("{} asks for ", self.asked_by) };
        let fix = if self.fix.is_empty() { String::new() } else { format!("; {}", self.fix) };
        Err(BuildError::invalid(format!(
            "{by}{} {} per tick at {tick_rate_hz} Hz (about {} us), more than the tick allows a \
             stage: at most {fit} ({} us of the {} us tick){fix}",
            self.units,
            self.unit,
            self.cost_ns() / 1000,
            share / 1000,
            NS_PER_S / u64::from(tick_rate_hz.max(1)) / 1000,
        )))
    }
}

/// `true` when `steps` steps of `step_s` seconds cover `period_s`, with a little room for the
/// rounding of the two (`0.001 / 0.0001` is a hair above 10).
fn covers(steps: f64, step_s: f64, period_s: f64) -> bool {
    steps * step_s >= period_s * (1.0 - 1e-9)
}

/// How many steps of `step_s` seconds one tick at `tick_rate_hz` needs at most: enough to
/// cover the tick's period (a step of a tick or longer needs one).
pub fn steps_per_tick(step_s: f64, tick_rate_hz: u32) -> u64 {
    let period_s = 1.0 / f64::from(tick_rate_hz.max(1));
    if !(step_s.is_finite() && step_s > 0.0) {
        return u64::MAX;
    }
    let mut n = (period_s / step_s).floor().max(1.0);
    if !covers(n, step_s, period_s) {
        n += 1.0;
    }
    n.min(u64::MAX as f64) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_share_of_a_tick_is_its_period_over_twice_the_slots() {
        // 1 kHz: 1 ms over 16 = 62.5 us; 8 kHz: 125 us over 16 = 7.8 us.
        assert_eq!(stage_share_ns(1000), 62_500);
        assert_eq!(stage_share_ns(8000), 7_812);
        assert_eq!(units_per_tick(1000, 30_000), 2);
        assert_eq!(units_per_tick(8000, 30_000), 1, "at least one unit");
    }

    #[test]
    fn steps_per_tick_cover_the_period() {
        assert_eq!(steps_per_tick(0.001, 1000), 1);
        assert_eq!(steps_per_tick(0.0001, 1000), 10);
        assert_eq!(steps_per_tick(0.00001, 1000), 100);
        assert_eq!(steps_per_tick(0.0003, 1000), 4, "3.33 steps: 4 cover the tick");
        assert_eq!(steps_per_tick(0.05, 1000), 1);
        assert_eq!(steps_per_tick(0.001, 30), 34, "33.3 ms: 34 steps");
    }

    #[test]
    fn work_that_does_not_fit_is_refused_naming_the_parameter_the_work_and_the_limit() {
        let w = TickWork {
            asked_by: "sim.timestep_s = 0.00001 s".into(),
            unit: "simulation steps",
            units: 100,
            unit_ns: 30_000,
            extra_ns: 0,
            fix: "use a time step of at least 0.0005 s".into(),
        };
        let e = w.check(1000).unwrap_err().message;
        assert_eq!(
            e,
            "sim.timestep_s = 0.00001 s asks for 100 simulation steps per tick at 1000 Hz (about \
             3000 us), more than the tick allows a stage: at most 2 (62 us of the 1000 us tick); \
             use a time step of at least 0.0005 s"
        );
        assert!(TickWork { units: 2, ..w.clone() }.check(1000).is_ok());
        assert!(TickWork { units: 3, ..w }.check(1000).is_err());
    }
}
