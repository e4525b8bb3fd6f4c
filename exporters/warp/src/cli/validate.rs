//! [`SimArgs`] validated into [`SceneParams`]: every bad parameter reported at once, by name,
//! with its allowed range, and `--layer-set N:key=value,...` applied to its layer.

use super::SimArgs;
use crate::params::{Checker, Horizon, InvalidParams, LayerParams, SceneParams, WindSource};

impl SimArgs {
    /// Validates into scene parameters for `layers` layers; every problem is reported.
    pub fn to_params(&self, layers: usize) -> Result<SceneParams, InvalidParams> {
        let mut ck = Checker::new();
        let mut p = SceneParams { seed: self.seed, ..SceneParams::default() };
        p.wind.direction_deg = self.direction;
        p.wind.strength = self.strength;
        p.wind.interval_s = self.interval;
        p.wind.radius = self.radius;
        p.wind.source = match self.source.as_str() {
            "border" => WindSource::Border,
            s => match s.split_once(',').map(|(a, b)| (a.trim().parse::<f32>(), b.trim().parse::<f32>())) {
                Some((Ok(x), Ok(y))) => WindSource::Point { x, y },
                _ => {
                    ck.push("source", s, "`border` or a point `X,Y` with X, Y in [0, 1]");
                    WindSource::Border
                }
            },
        };
        p.fluid.grid = to_u32(&mut ck, "fluid-grid", self.fluid_grid);
        p.fluid.viscosity = self.viscosity;
        let horizon = self.horizon.parse::<Horizon>().unwrap_or_else(|_| {
            ck.push("horizon", &self.horizon, "bottom, top or none");
            Horizon::Bottom
        });
        let cell = to_u32(&mut ck, "cell", self.cell);
        let base = LayerParams {
            gamma: self.gamma,
            c: self.c,
            stiffness_hz: self.stiffness,
            rigidity: self.rigidity,
            horizon,
            cell_x: cell,
            cell_y: cell,
            lambda_x: self.lambda_x,
            lambda_y: self.lambda_y,
            wave_grid: to_u32(&mut ck, "wave-grid", self.wave_grid),
            sway_margin_px: to_u32(&mut ck, "sway-margin", self.sway_margin),
        };
        p.layers = vec![base; layers];
        for spec in &self.layer_set {
            apply_layer_set(&mut ck, &mut p.layers, spec);
        }
        // Range checks, with the command line's flag names for the shared values.
        let mut ranges = Checker::new();
        let mut shared = p.wind.check();
        shared.extend_prefixed("", p.fluid.check());
        ranges.extend_renamed(shared, |name| {
            let flag = match name {
                "direction_deg" => "direction",
                "interval_s" => "interval",
                "grid" => "fluid-grid",
                "source.x" | "source.y" => "source",
                other => other,
            };
            format!("--{flag}")
        });
        let mut layer_ck = Checker::new();
        if layers == 0 {
            layer_ck.extend_prefixed("", base.check());
        }
        for (i, l) in p.layers.iter().enumerate() {
            layer_ck.extend_prefixed(&format!("layer[{i}]."), l.check());
        }
        ck.extend_prefixed("", ranges);
        ck.extend_prefixed("", layer_ck);
        ck.finish()?;
        Ok(p)
    }
}

/// An integer flag that must fit `u32` (negative values are reported, not wrapped).
fn to_u32(ck: &mut Checker, name: &str, v: i64) -> u32 {
    if v < 0 || v > u32::MAX as i64 {
        ck.push(name, v, "a non-negative integer");
        0
    } else {
        v as u32
    }
}

fn apply_layer_set(ck: &mut Checker, layers: &mut [LayerParams], spec: &str) {
    let Some((idx, rest)) = spec.split_once(':') else {
        ck.push("layer-set", spec, "N:key=value[,key=value]");
        return;
    };
    let Some(l) = idx.trim().parse::<usize>().ok().and_then(|i| layers.get_mut(i)) else {
        ck.push("layer-set", spec, format!("a layer index from 0 to {}", layers.len() as i64 - 1));
        return;
    };
    for kv in rest.split(',') {
        let Some((k, v)) = kv.split_once('=') else {
            ck.push("layer-set", kv, "key=value");
            continue;
        };
        let (k, v) = (k.trim(), v.trim());
        let num = v.parse::<f64>();
        let name = format!("layer-set {idx}:{k}");
        match (k, num) {
            ("horizon", _) => match v.parse::<Horizon>() {
                Ok(h) => l.horizon = h,
                Err(_) => ck.push(&name, v, "bottom, top or none"),
            },
            ("gamma", Ok(x)) => l.gamma = x as f32,
            ("c", Ok(x)) => l.c = x as f32,
            ("stiffness", Ok(x)) => l.stiffness_hz = x as f32,
            ("rigidity", Ok(x)) => l.rigidity = x as f32,
            ("lambda_x", Ok(x)) => l.lambda_x = x as f32,
            ("lambda_y", Ok(x)) => l.lambda_y = x as f32,
            ("cell", Ok(x)) => {
                let c = to_u32(ck, &name, x as i64);
                l.cell_x = c;
                l.cell_y = c;
            }
            ("wave_grid", Ok(x)) => l.wave_grid = to_u32(ck, &name, x as i64),
            ("sway_margin", Ok(x)) => l.sway_margin_px = to_u32(ck, &name, x as i64),
            (
                "gamma" | "c" | "stiffness" | "rigidity" | "lambda_x" | "lambda_y" | "cell" | "wave_grid"
                | "sway_margin",
                Err(_),
            ) => ck.push(&name, v, "a number"),
            _ => ck.push(&name, k, "one of gamma, c, stiffness, rigidity, horizon, cell, lambda_x, lambda_y, wave_grid, sway_margin"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    fn sim(args: &[&str]) -> SimArgs {
        #[derive(Parser)]
        struct T {
            #[command(flatten)]
            sim: SimArgs,
        }
        let mut v = vec!["t"];
        v.extend_from_slice(args);
        T::try_parse_from(v).unwrap().sim
    }

    #[test]
    fn defaults_validate() {
        let p = sim(&[]).to_params(2).unwrap();
        assert_eq!(p.layers.len(), 2);
        assert_eq!(p.fluid.grid, 64);
    }

    #[test]
    fn all_bad_values_reported_with_names_and_ranges() {
        let err = sim(&[
            "--cell",
            "-4",
            "--gamma",
            "2",
            "--strength",
            "-0.5",
            "--horizon",
            "left",
            "--source",
            "3",
            "--interval",
            "99",
            "--direction",
            "999",
            "--fluid-grid",
            "2",
        ])
        .to_params(1)
        .unwrap_err()
        .to_string();
        for needle in [
            "cell = -4",
            "horizon = left",
            "source = 3",
            "--strength = -0.5 is out of range (allowed: 0 to 1)",
            "layer[0].gamma = 2 is out of range (allowed: 0.01 to 1)",
            // Named as the flags are spelt, not as the library's fields.
            "--interval = 99 is out of range (allowed: 0 to 10)",
            "--direction = 999 is out of range (allowed: -360 to 360)",
            "--fluid-grid = 2 is out of range (allowed: 8 to 256)",
        ] {
            assert!(err.contains(needle), "missing `{needle}` in:\n{err}");
        }
    }

    #[test]
    fn layer_set_overrides_one_layer() {
        let p = sim(&["--layer-set", "1:gamma=0.5,horizon=top,cell=8"]).to_params(2).unwrap();
        assert_eq!(p.layers[0].gamma, 0.05);
        assert_eq!((p.layers[1].gamma, p.layers[1].horizon, p.layers[1].cell_x), (0.5, Horizon::Top, 8));
        let err = sim(&["--layer-set", "5:gamma=0.5"]).to_params(2).unwrap_err().to_string();
        assert!(err.contains("layer index from 0 to 1"), "{err}");
    }
}
