//! Typed, validated parameters of the simulation and the warp (seed 001, sections III-C to III-E).
//!
//! Raw values (from the command line, the web page or a test) are checked with `validate` on the
//! aggregate types ([`LayerParams::validate`], [`WindParams::validate`], [`SceneParams::validate`]); every problem is reported with the parameter's name, its value and the allowed
//! range, all at once.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// One rejected parameter.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamProblem {
    /// Parameter name as the user spells it (e.g. `layer[0].gamma`).
    pub name: String,
    /// The rejected value, as text.
    pub value: String,
    /// What would have been accepted.
    pub allowed: String,
}

impl std::fmt::Display for ParamProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} = {} is out of range (allowed: {})", self.name, self.value, self.allowed)
    }
}

/// Every bad parameter of one validation.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{} invalid parameter(s):\n  {}", .0.len(), .0.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("\n  "))]
pub struct InvalidParams(pub Vec<ParamProblem>);

/// Collects problems while checking values.
#[derive(Debug, Default)]
pub struct Checker {
    problems: Vec<ParamProblem>,
}

impl Checker {
    /// An empty checker.
    pub fn new() -> Self {
        Self::default()
    }

    /// Checks `lo <= value <= hi` and finiteness.
    pub fn range_f32(&mut self, name: &str, value: f32, lo: f32, hi: f32) {
        if !value.is_finite() || value < lo || value > hi {
            self.problems.push(ParamProblem {
                name: name.to_string(),
                value: value.to_string(),
                allowed: format!("{lo} to {hi}"),
            });
        }
    }

    /// Checks `lo <= value <= hi` for integers.
    pub fn range_i64(&mut self, name: &str, value: i64, lo: i64, hi: i64) {
        if value < lo || value > hi {
            self.problems.push(ParamProblem {
                name: name.to_string(),
                value: value.to_string(),
                allowed: format!("{lo} to {hi}"),
            });
        }
    }

    /// Records a free-form problem.
    pub fn push(&mut self, name: &str, value: impl ToString, allowed: impl ToString) {
        self.problems.push(ParamProblem {
            name: name.to_string(),
            value: value.to_string(),
            allowed: allowed.to_string(),
        });
    }

    /// Adds the problems of another checker with a name prefix (e.g. `layer[1].`).
    pub fn extend_prefixed(&mut self, prefix: &str, other: Checker) {
        for mut p in other.problems {
            p.name = format!("{prefix}{}", p.name);
            self.problems.push(p);
        }
    }

    /// Adds `other`'s problems with each name passed through `rename` (a library path such as
    /// `interval_s` to the flag a user typed, `--interval`).
    pub fn extend_renamed(&mut self, other: Checker, rename: impl Fn(&str) -> String) {
        for mut p in other.problems {
            p.name = rename(&p.name);
            self.problems.push(p);
        }
    }

    /// `Ok` when nothing was wrong.
    pub fn finish(self) -> Result<(), InvalidParams> {
        if self.problems.is_empty() { Ok(()) } else { Err(InvalidParams(self.problems)) }
    }
}

/// Where the vegetation is fixed (seed 001, Eq. 6 and Figs. 3-4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Horizon {
    /// Roots visible at the bottom of the layer: the bottom moves least.
    #[default]
    Bottom,
    /// Field seen from above: the top (far away) moves least.
    Top,
    /// Every part can move: `R = 1`.
    None,
}

/// A horizon name that is not `bottom`, `top` or `none`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("horizon `{0}` is not one of bottom, top, none")]
pub struct UnknownHorizon(pub String);

impl std::str::FromStr for Horizon {
    type Err = UnknownHorizon;
    fn from_str(s: &str) -> Result<Self, UnknownHorizon> {
        match s {
            "bottom" => Ok(Horizon::Bottom),
            "top" => Ok(Horizon::Top),
            "none" => Ok(Horizon::None),
            other => Err(UnknownHorizon(other.to_string())),
        }
    }
}

/// Per-layer parameters: vegetation dynamics (Eq. 3-4) and warping (Eq. 5-8).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LayerParams {
    /// Wave damping gamma in [0.01, 1] (seed 001, Eq. 4), the damping ratio of the vegetation
    /// oscillator: larger is more rigid and decays faster (1 = critically damped).
    pub gamma: f32,
    /// Wave speed c in [1, 10] (Eq. 3), in wave-grid cells per second.
    pub c: f32,
    /// Stiffness of the harmonic oscillator that pulls the vegetation velocity towards the wind,
    /// in Hz, [0.1, 10].
    pub stiffness_hz: f32,
    /// Rigidity r in [0, 10] (Eq. 6).
    pub rigidity: f32,
    /// Horizon position (Eq. 6).
    pub horizon: Horizon,
    /// Grid cell width s_x in pixels, [2, 256] (Eq. 7).
    pub cell_x: u32,
    /// Grid cell height s_y in pixels, [2, 256] (Eq. 7).
    pub cell_y: u32,
    /// Scale factor lambda_x in [0, 1000] (Eq. 5).
    pub lambda_x: f32,
    /// Scale factor lambda_y in [0, 1000] (Eq. 5).
    pub lambda_y: f32,
    /// Wave grid resolution (cells per side), [4, 256].
    pub wave_grid: u32,
    /// Pixels around the mask the layer may sway into, [0, 64]. 0 keeps every pixel outside the
    /// mask untouched.
    pub sway_margin_px: u32,
}

impl Default for LayerParams {
    fn default() -> Self {
        LayerParams {
            gamma: 0.05,
            c: 4.0,
            stiffness_hz: 1.2,
            rigidity: 1.5,
            horizon: Horizon::Bottom,
            cell_x: 16,
            cell_y: 16,
            lambda_x: 12.0,
            lambda_y: 4.0,
            wave_grid: 48,
            sway_margin_px: 0,
        }
    }
}

impl LayerParams {
    /// Checks every range; names are relative (`gamma`, `cell_x`, ...).
    pub fn check(&self) -> Checker {
        let mut c = Checker::new();
        c.range_f32("gamma", self.gamma, 0.01, 1.0);
        c.range_f32("c", self.c, 1.0, 10.0);
        c.range_f32("stiffness_hz", self.stiffness_hz, 0.1, 10.0);
        c.range_f32("rigidity", self.rigidity, 0.0, 10.0);
        c.range_i64("cell_x", self.cell_x as i64, 2, 256);
        c.range_i64("cell_y", self.cell_y as i64, 2, 256);
        c.range_f32("lambda_x", self.lambda_x, 0.0, 1000.0);
        c.range_f32("lambda_y", self.lambda_y, 0.0, 1000.0);
        c.range_i64("wave_grid", self.wave_grid as i64, 4, 256);
        c.range_i64("sway_margin_px", self.sway_margin_px as i64, 0, 64);
        c
    }

    /// Validates this layer's parameters on their own.
    pub fn validate(&self) -> Result<(), InvalidParams> {
        self.check().finish()
    }
}

/// Where wind is injected.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
#[derive(Default)]
pub enum WindSource {
    /// A disc around a point, coordinates as fractions of the image ([0, 1], y down).
    Point {
        /// Horizontal position, 0 = left edge.
        x: f32,
        /// Vertical position, 0 = top edge.
        y: f32,
    },
    /// The border the wind comes from, chosen from the wind direction (upwind border).
    #[default]
    Border,
}

/// User forces on the wind field (seed 001, section III-C).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WindParams {
    /// Direction the wind blows towards, degrees: 0 = to the right (+x), 90 = down (+y).
    pub direction_deg: f32,
    /// Strength in [0, 1]: the injected velocity magnitude.
    pub strength: f32,
    /// Interval between injections in seconds, [0, 10] (0 = every step): the wind "frequency".
    pub interval_s: f32,
    /// Where the wind is injected.
    pub source: WindSource,
    /// Radius of a point source as a fraction of the image size, [0.01, 0.5]; also the depth of a
    /// border source.
    pub radius: f32,
}

impl Default for WindParams {
    fn default() -> Self {
        WindParams {
            direction_deg: 0.0,
            strength: 0.6,
            interval_s: 0.8,
            source: WindSource::Border,
            radius: 0.08,
        }
    }
}

impl WindParams {
    /// Checks every range.
    pub fn check(&self) -> Checker {
        let mut c = Checker::new();
        c.range_f32("direction_deg", self.direction_deg, -360.0, 360.0);
        c.range_f32("strength", self.strength, 0.0, 1.0);
        c.range_f32("interval_s", self.interval_s, 0.0, 10.0);
        c.range_f32("radius", self.radius, 0.01, 0.5);
        if let WindSource::Point { x, y } = self.source {
            c.range_f32("source.x", x, 0.0, 1.0);
            c.range_f32("source.y", y, 0.0, 1.0);
        }
        c
    }

    /// Validates the wind parameters.
    pub fn validate(&self) -> Result<(), InvalidParams> {
        self.check().finish()
    }
}

/// Stable-fluids solver parameters (seed 001, section III-C; Stam 1999).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FluidParams {
    /// Cells per side of the square wind grid, [8, 256] (default 64, as in the seed).
    pub grid: u32,
    /// Kinematic viscosity in domain units^2/s, [0, 0.01].
    pub viscosity: f32,
}

impl Default for FluidParams {
    fn default() -> Self {
        FluidParams { grid: 64, viscosity: 0.0001 }
    }
}

impl FluidParams {
    /// Checks every range.
    pub fn check(&self) -> Checker {
        let mut c = Checker::new();
        c.range_i64("grid", self.grid as i64, 8, 256);
        c.range_f32("viscosity", self.viscosity, 0.0, 0.01);
        c
    }
}

/// Everything that shapes one animation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct SceneParams {
    /// Wind forces.
    pub wind: WindParams,
    /// Wind grid.
    pub fluid: FluidParams,
    /// One entry per vegetation layer (missing entries use the defaults).
    pub layers: Vec<LayerParams>,
    /// Seed of the procedural wind's gusts.
    pub seed: u64,
}

impl SceneParams {
    /// Validates everything and names each problem with its path (`wind.strength`,
    /// `layer[1].gamma`, ...).
    pub fn validate(&self) -> Result<(), InvalidParams> {
        let mut all = Checker::new();
        all.extend_prefixed("wind.", self.wind.check());
        all.extend_prefixed("fluid.", self.fluid.check());
        for (i, l) in self.layers.iter().enumerate() {
            all.extend_prefixed(&format!("layer[{i}]."), l.check());
        }
        all.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        let p = SceneParams { layers: vec![LayerParams::default()], ..Default::default() };
        p.validate().unwrap();
    }

    #[test]
    fn every_bad_parameter_is_named_with_its_range() {
        let mut p = SceneParams {
            layers: vec![LayerParams::default(), LayerParams::default()],
            ..Default::default()
        };
        p.wind.strength = 1.5;
        p.fluid.grid = 4;
        p.layers[1].gamma = 0.0;
        p.layers[1].c = 11.0;
        p.layers[1].rigidity = f32::NAN;
        let err = p.validate().unwrap_err();
        let names: Vec<_> = err.0.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(
            names,
            ["wind.strength", "fluid.grid", "layer[1].gamma", "layer[1].c", "layer[1].rigidity"]
        );
        let text = err.to_string();
        assert!(text.contains("layer[1].gamma = 0 is out of range (allowed: 0.01 to 1)"), "{text}");
        assert!(text.contains("wind.strength = 1.5 is out of range (allowed: 0 to 1)"), "{text}");
        assert!(text.starts_with("5 invalid parameter(s)"), "{text}");
    }
}
