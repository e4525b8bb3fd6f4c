//! Where the wind comes from: the hand (through the root joint of the daemon's poses), or a
//! procedural wind with the same three parameters (direction, strength, frequency).
//!
//! Hand mapping: the root joint's rotation (`joints_deg[0]`, frond's convention: stem +Y, pitch
//! about +X, yaw about +Z) tilts the stem tip `R (0, 1, 0)`. The tip's sideways offset `x` is the
//! wind's horizontal component on the picture and its offset towards the viewer `z` the vertical
//! one (the picture is seen from slightly above: towards the viewer is down). The bend angle sets
//! the strength (`bend / FULL_BEND_DEG`, clamped to [0, 1]) and the sway rate (direction reversals
//! of the bend, with hysteresis) sets the interval between injections: a hand swaying at 1 Hz blows
//! a gust per second; a hand held still and bent blows a steady wind (interval 0).
//!
//! The two mappings are calibrated on each other: [`FULL_BEND_DEG`] is the bend of seed 003's
//! simulated plant (section 4.2) at rest in a steady wind of [`FULL_SIM_WIND_M_S`], the wind at
//! which the simulation mapping reaches full strength. A plant bent as that wind bends it blows the
//! picture as that wind does, so a simulated take (`frond take simulate`, or `frond sim start`
//! live) and `--wind-sim` of the same spec move the picture alike; a hand that bends the plant as
//! far is a wind that strong.
//!
//! Simulation mapping ([`SimWind`]): the wind that blows seed 003's simulated plant
//! (`frond_motion::sim::Wind`, the spec `frond take simulate --wind` and `frond sim start --wind`
//! take) blows the picture: its ground-plane velocity `(w_x, w_z)` is the direction (+X right,
//! +Z towards the viewer, i.e. down, as above) and `|w| / FULL_SIM_WIND_M_S` the strength,
//! injected continuously (interval 0): the gusts are in the velocity itself.

use frond_motion::sim::{Wind, WindSpec};
use frond_protocol::convention::joint_matrix;

use crate::params::WindParams;

/// Bend of the root joint at which the strength reaches 1, degrees: the root bend of seed 003's
/// simulated plant (section 4.2, Eq. 1-3: `frond_motion::sim` with the default `[sim]` of
/// frondd's default rig, grass) at rest in a steady wind of [`FULL_SIM_WIND_M_S`]. For small
/// angles the default `[sim]` bends every joint 0.15 rad per 5 m/s, which would be 17.2 degrees
/// at 10 m/s; the simulation settles at 15.07. A test runs the simulation to rest and checks this
/// value; the embedded flower and shrub rigs (default `[sim]` too) settle within 0.2 degrees of it.
pub const FULL_BEND_DEG: f32 = 15.075;
/// A reversal counts only after the bend came back this far from its extreme.
const REVERSAL_HYSTERESIS_DEG: f32 = 2.0;
/// Without a reversal for this long, the wind is steady.
const SWAY_TIMEOUT_S: f64 = 3.0;

/// The stem tip `R (0, 1, 0)` of a root joint rotation (the rotation matrix's second column).
fn stem_tip(root_deg: [f32; 3]) -> [f64; 3] {
    let m = joint_matrix(root_deg);
    [m[0][1], m[1][1], m[2][1]]
}

/// How far a root joint rotation tilts the stem from upright, degrees (0..=180).
pub fn root_bend_deg(root_deg: [f32; 3]) -> f32 {
    stem_tip(root_deg)[1].clamp(-1.0, 1.0).acos().to_degrees() as f32
}

/// Direction (degrees, 0 = right, 90 = down) and strength in [0, 1] (`bend / FULL_BEND_DEG`)
/// from a root joint rotation.
pub fn hand_to_wind(root_deg: [f32; 3]) -> (f32, f32) {
    let tip = stem_tip(root_deg);
    let (x, z) = (tip[0] as f32, tip[2] as f32);
    let direction = if x.abs() + z.abs() < 1e-9 { 0.0 } else { z.atan2(x).to_degrees() };
    (direction, (root_bend_deg(root_deg) / FULL_BEND_DEG).clamp(0.0, 1.0))
}

/// Measures how fast the hand sways from the root joint's bend over time.
#[derive(Debug, Clone, Default)]
pub struct SwayMeter {
    /// Bend along the main axis at the last extreme, and whether it was a maximum.
    extreme: Option<(f32, bool)>,
    last_reversal_s: Option<f64>,
    half_period_s: Option<f64>,
}

impl SwayMeter {
    /// A meter that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds the signed bend (degrees along the current wind axis) at time `t_s`.
    pub fn push(&mut self, t_s: f64, bend_deg: f32) {
        match self.extreme {
            None => self.extreme = Some((bend_deg, true)),
            Some((ext, rising)) => {
                if (rising && bend_deg >= ext) || (!rising && bend_deg <= ext) {
                    self.extreme = Some((bend_deg, rising));
                } else if (ext - bend_deg).abs() >= REVERSAL_HYSTERESIS_DEG {
                    if let Some(prev) = self.last_reversal_s {
                        let half = (t_s - prev).max(1e-3);
                        self.half_period_s = Some(match self.half_period_s {
                            Some(h) => 0.5 * h + 0.5 * half,
                            None => half,
                        });
                    }
                    self.last_reversal_s = Some(t_s);
                    self.extreme = Some((bend_deg, !rising));
                }
            }
        }
        if self.last_reversal_s.is_some_and(|r| t_s - r > SWAY_TIMEOUT_S) {
            self.half_period_s = None;
            self.last_reversal_s = None;
        }
    }

    /// Interval between injections: one sway period, or 0 (steady) without swaying.
    pub fn interval_s(&self) -> f32 {
        self.half_period_s.map_or(0.0, |h| (2.0 * h).clamp(0.05, 10.0) as f32)
    }
}

/// Turns root-joint rotations over time into wind parameters.
#[derive(Debug, Clone, Default)]
pub struct HandWind {
    sway: SwayMeter,
}

impl HandWind {
    /// A fresh mapping.
    pub fn new() -> Self {
        Self::default()
    }

    /// Updates `wind` (direction, strength, interval; the source is kept) from the root joint at
    /// time `t_s`.
    pub fn update(&mut self, t_s: f64, root_deg: [f32; 3], wind: &mut WindParams) {
        let (direction, strength) = hand_to_wind(root_deg);
        // Signed bend along a fixed axis (sideways): reversals of a sway show up there.
        let m = joint_matrix(root_deg);
        let signed = (m[0][1] as f32).asin().to_degrees() + (m[2][1] as f32).asin().to_degrees();
        self.sway.push(t_s, signed);
        wind.direction_deg = direction;
        wind.strength = strength;
        wind.interval_s = self.sway.interval_s();
    }
}

/// Wind speed of the simulation at which the picture's wind strength reaches 1, m/s (a strong
/// breeze, Beaufort 5-6); the simulated plant's bend in it is [`FULL_BEND_DEG`].
pub const FULL_SIM_WIND_M_S: f64 = 10.0;

/// Direction (degrees, 0 = right, 90 = down) and strength in [0, 1] of a simulation wind
/// velocity `[x, y, z]` in m/s (the vertical component does not show on the picture).
pub fn sim_to_wind(velocity_m_s: [f64; 3]) -> (f32, f32) {
    let [x, _, z] = velocity_m_s;
    let speed = x.hypot(z);
    let direction = if speed < 1e-12 { 0.0 } else { z.atan2(x).to_degrees() as f32 };
    (direction, (speed / FULL_SIM_WIND_M_S).clamp(0.0, 1.0) as f32)
}

/// The simulation's wind over time as the warp's wind settings.
#[derive(Debug, Clone)]
pub struct SimWind {
    wind: Wind,
}

impl SimWind {
    /// The wind of `spec` (same spec, same gusts as the simulated plant's).
    pub fn new(spec: WindSpec) -> Self {
        SimWind { wind: Wind::new(spec) }
    }

    /// The spec.
    pub fn spec(&self) -> &WindSpec {
        self.wind.spec()
    }

    /// Updates `wind` (direction, strength, interval 0; the source is kept) for time `t_s`.
    pub fn update(&self, t_s: f64, wind: &mut WindParams) {
        let (direction, strength) = sim_to_wind(self.wind.velocity_m_s(t_s).to_array());
        wind.direction_deg = direction;
        wind.strength = strength;
        wind.interval_s = 0.0;
    }
}

/// Deterministic gusts for when no hand drives the wind: each injection's strength and direction
/// vary a little around the user's settings, from a seeded hash (same seed, same wind).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProceduralWind {
    /// Seed of the variation.
    pub seed: u64,
}

impl ProceduralWind {
    /// `(direction_deg, strength)` of injection number `k` for the user's `base` settings:
    /// strength scaled by [0.6, 1], direction turned by up to +-12 degrees.
    pub fn gust(&self, k: u64, base: &WindParams) -> (f32, f32) {
        let a = unit(splitmix(self.seed ^ k.wrapping_mul(0x9E37_79B9_7F4A_7C15)));
        let b = unit(splitmix(self.seed.wrapping_add(0x5851_F42D) ^ k.wrapping_mul(0xD1B5_4A32_D192_ED03)));
        (base.direction_deg + (b * 2.0 - 1.0) * 12.0, base.strength * (0.6 + 0.4 * a))
    }
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn unit(x: u64) -> f32 {
    (x >> 40) as f32 / (1u64 << 24) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use frond_formats::rig_toml::RigText;

    #[test]
    fn upright_root_is_calm_and_bends_map_to_directions() {
        assert_eq!(hand_to_wind([0.0, 0.0, 0.0]).1, 0.0);
        // Yaw about +Z by -6 degrees tips the stem towards +X: wind to the right, 6/15.075 of
        // the full strength.
        let (dir, s) = hand_to_wind([0.0, -6.0, 0.0]);
        assert!(dir.abs() < 1e-3 && (s - 6.0 / 15.075).abs() < 1e-4, "{dir} {s}");
        // Pitch about +X by +6 degrees tips it towards +Z (the viewer): wind downwards.
        let (dir, s) = hand_to_wind([6.0, 0.0, 0.0]);
        assert!((dir - 90.0).abs() < 1e-3 && (s - 6.0 / 15.075).abs() < 1e-4, "{dir} {s}");
        // Beyond the full bend the strength saturates at 1.
        assert_eq!(hand_to_wind([0.0, 20.0, 0.0]).1, 1.0);
        assert!((root_bend_deg([0.0, -6.0, 0.0]) - 6.0).abs() < 1e-4);
    }

    /// The root joint of `rig_toml`'s plant (its `[sim]`), simulated from rest in a steady
    /// `FULL_SIM_WIND_M_S` wind for 20 s, at its last frame; checked to be at rest (the last two
    /// seconds within 0.001 degrees of it).
    fn root_at_rest_in_the_full_wind(rig_toml: &str) -> [f32; 3] {
        let rig = frond_motion::rig::Rig::from_toml_str(rig_toml).unwrap();
        let spec = format!("speed={FULL_SIM_WIND_M_S},dir=0,gust=0,seed=0").parse().unwrap();
        let poses = frond_motion::sim::simulate(&rig, &rig.sim, spec, 20.0, 10.0).unwrap();
        let bends: Vec<f32> = poses.iter().map(|p| root_bend_deg(p.joints_deg[0])).collect();
        let rest = bends[bends.len() - 1];
        let settled = &bends[bends.len() - 21..];
        assert!(settled.iter().all(|b| (b - rest).abs() < 1e-3), "not at rest: {settled:?}");
        poses[poses.len() - 1].joints_deg[0]
    }

    #[test]
    fn full_strength_is_the_simulated_plants_bend_in_the_full_wind() {
        // Seed 003, section 4.2: frondd's default rig (grass) with its default [sim].
        let root = root_at_rest_in_the_full_wind(include_str!("../../../rig-files/plants/grass.toml"));
        let rest = root_bend_deg(root);
        assert!((rest - FULL_BEND_DEG).abs() < 0.01, "the plant rests at {rest} degrees");
        // So a plant bent by the full wind blows the picture at the full wind's strength.
        assert!((hand_to_wind(root).1 - 1.0).abs() < 1e-3, "{:?}", hand_to_wind(root));
        assert_eq!(sim_to_wind([FULL_SIM_WIND_M_S, 0.0, 0.0]).1, 1.0);
        // The other embedded rigs' plants rest close by.
        for rig in [
            include_str!("../../../rig-files/plants/flower.toml"),
            include_str!("../../../rig-files/plants/shrub.toml"),
        ] {
            let rest = root_bend_deg(root_at_rest_in_the_full_wind(rig));
            assert!((rest - FULL_BEND_DEG).abs() < 0.2, "a plant rests at {rest} degrees");
        }
    }

    #[test]
    fn sway_rate_sets_injection_interval() {
        let mut hw = HandWind::new();
        let mut wind = WindParams::default();
        // 1 Hz sway of +-25 degrees yaw, sampled at 100 Hz for 5 s.
        for k in 0..500 {
            let t = k as f64 / 100.0;
            let yaw = 25.0 * (std::f64::consts::TAU * t).sin() as f32;
            hw.update(t, [0.0, yaw, 0.0], &mut wind);
        }
        assert!((wind.interval_s - 1.0).abs() < 0.05, "interval {}", wind.interval_s);
        // Held still and bent: steady wind after the timeout.
        for k in 0..400 {
            hw.update(5.0 + k as f64 / 100.0, [0.0, -12.0, 0.0], &mut wind);
        }
        assert_eq!(wind.interval_s, 0.0);
        assert!((wind.strength - 12.0 / 15.075).abs() < 1e-4);
    }

    #[test]
    fn the_simulation_wind_maps_to_direction_and_strength() {
        // By hand: 5 m/s towards +X is half strength to the right; towards +Z is down.
        assert_eq!(sim_to_wind([5.0, 0.0, 0.0]), (0.0, 0.5));
        let (d, s) = sim_to_wind([0.0, 3.0, 20.0]);
        assert!((d - 90.0).abs() < 1e-5 && s == 1.0, "{d} {s}");
        assert_eq!(sim_to_wind([0.0; 3]), (0.0, 0.0));
        // A steady spec is steady; `until` releases it; gusts vary around the speed.
        let mut w = WindParams::default();
        SimWind::new("speed=3,dir=45,gust=0,seed=0,until=2".parse().unwrap()).update(1.0, &mut w);
        assert!((w.direction_deg - 45.0).abs() < 1e-4 && (w.strength - 0.3).abs() < 1e-6, "{w:?}");
        assert_eq!(w.interval_s, 0.0);
        SimWind::new("speed=3,dir=45,gust=0,seed=0,until=2".parse().unwrap()).update(2.5, &mut w);
        assert_eq!(w.strength, 0.0);
        let gusty = SimWind::new("speed=5,dir=0,gust=0.8,seed=4".parse().unwrap());
        let strengths: Vec<f32> = (0..100)
            .map(|k| {
                gusty.update(k as f64 * 0.1, &mut w);
                w.strength
            })
            .collect();
        let (lo, hi) = strengths.iter().fold((1.0f32, 0.0f32), |(l, h), &s| (l.min(s), h.max(s)));
        assert!(hi - lo > 0.1 && lo >= 0.0 && hi <= 1.0, "gusts {lo}..{hi}");
    }

    #[test]
    fn procedural_gusts_are_deterministic_and_near_the_settings() {
        let base = WindParams { direction_deg: 30.0, strength: 0.5, ..WindParams::default() };
        let p = ProceduralWind { seed: 7 };
        for k in 0..50 {
            let (d, s) = p.gust(k, &base);
            assert_eq!((d, s), p.gust(k, &base));
            assert!((18.0..=42.0).contains(&d) && (0.3..=0.5).contains(&s), "{d} {s}");
        }
        assert_ne!(p.gust(1, &base), ProceduralWind { seed: 8 }.gust(1, &base));
    }
}
