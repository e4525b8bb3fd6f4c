//! The frame loop: wind forces -> stable fluids -> per-layer wave -> grid warp -> composite.
//!
//! [`Animator`] owns every buffer; [`Animator::step`] allocates nothing (parameter changes that
//! resize a grid reallocate once, between frames). Given the same scene, parameters and sequence
//! of wind settings it produces the same bytes: the simulation is sequential and seeded.

use crate::fluid::Fluid;
use crate::layers::Scene;
use crate::params::{InvalidParams, LayerParams, SceneParams, WindParams, WindSource};
use crate::warp::{Warper, rigidity_factor};
use crate::wave::{Wave, WaveParams};
use crate::wind::ProceduralWind;

/// How long one injection lasts at most (a gust), seconds.
const GUST_S: f64 = 0.25;

struct LayerSim {
    params: LayerParams,
    wave: Wave,
    /// Pixels between wave nodes.
    spacing: f32,
    warper: Warper,
    region: Vec<u8>,
}

/// Animates one scene.
pub struct Animator {
    scene: Scene,
    params: SceneParams,
    fluid: Fluid,
    layers: Vec<LayerSim>,
    frame: Vec<u8>,
    time_s: f64,
    next_injection_s: f64,
    injection_k: u64,
    gust_until_s: f64,
    gust: (f32, f32),
    procedural: Option<ProceduralWind>,
}

impl Animator {
    /// Validates `params` (missing layer entries get defaults) and prepares the buffers.
    pub fn new(scene: Scene, mut params: SceneParams) -> Result<Animator, InvalidParams> {
        params.layers.resize(scene.layers.len().max(params.layers.len()), LayerParams::default());
        params.validate()?;
        let fluid = Fluid::new(params.fluid.grid as usize, params.fluid.viscosity);
        let frame = scene.background.clone();
        let mut a = Animator {
            scene,
            fluid,
            layers: Vec::new(),
            frame,
            time_s: 0.0,
            next_injection_s: 0.0,
            injection_k: 0,
            gust_until_s: f64::MIN,
            gust: (0.0, 0.0),
            procedural: Some(ProceduralWind { seed: params.seed }),
            params: params.clone(),
        };
        a.rebuild_layers();
        a.compose();
        Ok(a)
    }

    fn rebuild_layers(&mut self) {
        let (w, h) = (self.scene.width, self.scene.height);
        self.layers = self
            .scene
            .layers
            .iter()
            .zip(&self.params.layers)
            .map(|(layer, p)| {
                let spacing = w.max(h) as f32 / p.wave_grid as f32;
                let nx = (w as f32 / spacing).ceil() as usize + 1;
                let ny = (h as f32 / spacing).ceil() as usize + 1;
                LayerSim {
                    params: *p,
                    wave: Wave::new(nx, ny),
                    spacing,
                    warper: Warper::new(w, h, p.cell_x as usize, p.cell_y as usize),
                    region: layer.region(w, h, p.sway_margin_px as usize),
                }
            })
            .collect();
    }

    /// The scene being animated.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Current parameters.
    pub fn params(&self) -> &SceneParams {
        &self.params
    }

    /// Seconds simulated so far.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The wind field (for diagnostics).
    pub fn fluid(&self) -> &Fluid {
        &self.fluid
    }

    /// The latest frame (opaque RGBA, the scene's size).
    pub fn frame(&self) -> &[u8] {
        &self.frame
    }

    /// Largest corner displacement over all layers, pixels.
    pub fn max_displacement(&self) -> f32 {
        self.layers.iter().map(|l| l.warper.max_displacement()).fold(0.0, f32::max)
    }

    /// Whether injections vary procedurally (no hand drives the wind). On by default.
    pub fn set_procedural(&mut self, on: bool) {
        self.procedural = if on { Some(ProceduralWind { seed: self.params.seed }) } else { None };
    }

    /// Replaces the wind settings (validated); effective at the next step.
    pub fn set_wind(&mut self, wind: WindParams) -> Result<(), InvalidParams> {
        wind.validate()?;
        if wind.interval_s != self.params.wind.interval_s {
            self.next_injection_s = self.next_injection_s.min(self.time_s + wind.interval_s as f64);
        }
        self.params.wind = wind;
        Ok(())
    }

    /// Replaces every parameter (validated); effective at the next step. Grids whose size changes
    /// are rebuilt (their motion restarts); other changes keep the motion going.
    pub fn set_params(&mut self, mut params: SceneParams) -> Result<(), InvalidParams> {
        params.layers.resize(self.scene.layers.len().max(params.layers.len()), LayerParams::default());
        params.validate()?;
        if params.fluid.grid != self.params.fluid.grid {
            self.fluid = Fluid::new(params.fluid.grid as usize, params.fluid.viscosity);
        }
        self.fluid.set_viscosity(params.fluid.viscosity);
        let (w, h) = (self.scene.width, self.scene.height);
        for (i, sim) in self.layers.iter_mut().enumerate() {
            let p = params.layers[i];
            if p.wave_grid != sim.params.wave_grid {
                let spacing = w.max(h) as f32 / p.wave_grid as f32;
                sim.spacing = spacing;
                sim.wave = Wave::new(
                    (w as f32 / spacing).ceil() as usize + 1,
                    (h as f32 / spacing).ceil() as usize + 1,
                );
            }
            if (p.cell_x, p.cell_y) != (sim.params.cell_x, sim.params.cell_y) {
                sim.warper.set_cells(p.cell_x as usize, p.cell_y as usize);
            }
            if p.sway_margin_px != sim.params.sway_margin_px {
                sim.region = self.scene.layers[i].region(w, h, p.sway_margin_px as usize);
            }
            sim.params = p;
        }
        if params.seed != self.params.seed && self.procedural.is_some() {
            self.procedural = Some(ProceduralWind { seed: params.seed });
        }
        self.set_wind(params.wind)?;
        self.params = params;
        Ok(())
    }

    /// Advances by `dt` seconds and composes the next frame.
    pub fn step(&mut self, dt: f32) -> &[u8] {
        self.inject();
        self.fluid.step(dt);
        let (w, h) = (self.scene.width as f32, self.scene.height as f32);
        let fluid = &self.fluid;
        for sim in &mut self.layers {
            let p = sim.params;
            let wp = WaveParams { gamma: p.gamma, c: p.c, stiffness_hz: p.stiffness_hz };
            let sp = sim.spacing;
            sim.wave.step(dt, &wp, |i, j| fluid.velocity_at(i as f32 * sp / w, j as f32 * sp / h));
        }
        self.time_s += dt as f64;
        self.update_warps(dt);
        self.compose();
        &self.frame
    }

    fn update_warps(&mut self, dt: f32) {
        let scale_map = self.scene.scale_map.as_deref();
        let (w, h) = (self.scene.width, self.scene.height);
        for (sim, layer) in self.layers.iter_mut().zip(&self.scene.layers) {
            let p = sim.params;
            let (top, bottom) = (layer.top as f32, layer.bottom as f32);
            let wave = &sim.wave;
            let sp = sim.spacing;
            sim.warper.set_displacements(
                dt,
                [p.lambda_x, p.lambda_y],
                |y| rigidity_factor(p.horizon, y, top, bottom, p.rigidity),
                |x, y| match scale_map {
                    Some(m) => {
                        let xi = (x as usize).min(w - 1);
                        let yi = (y as usize).min(h - 1);
                        m[yi * w + xi]
                    }
                    None => 1.0,
                },
                |x, y| wave.sample(x / sp, y / sp),
            );
        }
    }

    fn compose(&mut self) {
        self.frame.copy_from_slice(&self.scene.background);
        for (sim, layer) in self.layers.iter().zip(&self.scene.layers) {
            sim.warper.warp_over(&layer.pixels, &sim.region, &mut self.frame);
        }
    }

    /// Adds the user's (or the hand's) force when an injection is due (seed 001, III-C: direction,
    /// strength in [0, 1], interval between injections).
    fn inject(&mut self) {
        let wind = self.params.wind;
        if wind.strength <= 0.0 {
            return;
        }
        if self.time_s >= self.next_injection_s {
            self.gust = match &self.procedural {
                Some(p) => p.gust(self.injection_k, &wind),
                None => (wind.direction_deg, wind.strength),
            };
            self.injection_k += 1;
            self.gust_until_s = self.time_s + (wind.interval_s as f64 * 0.5).min(GUST_S);
            self.next_injection_s = self.time_s + wind.interval_s as f64;
        }
        if self.time_s > self.gust_until_s && wind.interval_s > 0.0 {
            return;
        }
        let (dir_deg, strength) = if self.procedural.is_some() {
            self.gust
        } else {
            // Live settings (the hand) apply at once.
            (wind.direction_deg, wind.strength)
        };
        let (s, c) = dir_deg.to_radians().sin_cos();
        let dir = [c, s];
        let r = wind.radius;
        match wind.source {
            WindSource::Point { x, y } => self.fluid.add_force(dir, strength, |fx, fy| {
                let d2 = (fx - x).powi(2) + (fy - y).powi(2);
                (1.0 - d2 / (r * r)).max(0.0)
            }),
            WindSource::Border => self.fluid.add_force(dir, strength, |fx, fy| {
                // Distance to the domain edge going upwind.
                let tx = if dir[0] > 1e-6 {
                    fx / dir[0]
                } else if dir[0] < -1e-6 {
                    (1.0 - fx) / -dir[0]
                } else {
                    f32::INFINITY
                };
                let ty = if dir[1] > 1e-6 {
                    fy / dir[1]
                } else if dir[1] < -1e-6 {
                    (1.0 - fy) / -dir[1]
                } else {
                    f32::INFINITY
                };
                let t = tx.min(ty);
                if t <= r { 1.0 } else { 0.0 }
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layers::{LayerInput, Rgba};

    fn stripes(w: usize, h: usize) -> Rgba {
        let mut img = Rgba::filled(w, h, [0, 0, 0, 255]);
        for y in 0..h {
            for x in 0..w {
                let p = (y * w + x) * 4;
                img.data[p..p + 3].copy_from_slice(&[(x * 40 % 256) as u8, (y * 9) as u8, 90]);
            }
        }
        img
    }

    #[test]
    fn wind_moves_the_layer_and_is_deterministic() {
        let (w, h) = (64, 48);
        let mask: Vec<u8> = (0..w * h).map(|p| if p / w >= 16 { 255 } else { 0 }).collect();
        let make = || {
            let scene =
                Scene::build(stripes(w, h), vec![("g".into(), LayerInput::Mask(mask.clone()))], None, None)
                    .unwrap();
            let mut p = SceneParams::default();
            p.wind.strength = 1.0;
            p.wind.interval_s = 0.0;
            p.fluid.grid = 16;
            Animator::new(scene, p).unwrap()
        };
        let (mut a, mut b) = (make(), make());
        let still = a.frame().to_vec();
        for _ in 0..20 {
            a.step(1.0 / 30.0);
            b.step(1.0 / 30.0);
        }
        assert_eq!(a.frame(), b.frame());
        assert_ne!(a.frame(), &still[..]);
        assert!(a.max_displacement() > 0.5, "{}", a.max_displacement());
    }
}
