//! Bake throughput for `frond bench`: a long take on one plant and a large field, baked and
//! encoded as GLB in memory (no disk I/O), on synthetic input made here.

use std::time::{Duration, Instant};

use frond_formats::field_json::FieldJson;
use frond_motion::{JOINTS, PoseFrame, TakeFrame, TakeHeader};

use crate::bake::{BakeOptions, Baker};
use crate::error::BakeError;
use crate::field::Field;
use crate::input::{LoadedRig, TakeInput};
use crate::output::encode_glb;
use frond_motion::field::{FieldParams, make_field};

/// One measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchResult {
    /// What was baked.
    pub name: String,
    /// Take frames read.
    pub frames_in: usize,
    /// Plants baked.
    pub plants: usize,
    /// Keys per channel.
    pub keys: usize,
    /// Rotation channels.
    pub channels: usize,
    /// GLB size, bytes.
    pub bytes: usize,
    /// Wall time of bake + GLB encoding.
    pub elapsed: Duration,
}

impl BenchResult {
    /// Rotation keys written per second.
    pub fn keys_per_s(&self) -> f64 {
        (self.keys * self.channels) as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }
}

impl std::fmt::Display for BenchResult {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {:.3} s ({} frames in, {} plants, {} channels x {} keys, {:.2} M keys/s, {:.1} MB GLB)",
            self.name,
            self.elapsed.as_secs_f64(),
            self.frames_in,
            self.plants,
            self.channels,
            self.keys,
            self.keys_per_s() / 1e6,
            self.bytes as f64 / 1e6
        )
    }
}

/// A synthetic take: `seconds` of a swaying plant captured at `rate_hz` (main layer only).
pub fn synthetic_take(seconds: f64, rate_hz: f64) -> TakeInput {
    let n = (seconds * rate_hz).round().max(1.0) as usize;
    let frames = (0..n)
        .map(|k| {
            let t = k as f64 / rate_hz;
            let s = (t * 1.3).sin() as f32;
            let c = (t * 0.7).cos() as f32;
            let joints_deg: [[f32; 3]; JOINTS] = std::array::from_fn(|i| {
                [25.0 * s * (i as f32 + 1.0) / 2.0, 15.0 * c, if i >= 2 { 10.0 * s } else { 0.0 }]
            });
            TakeFrame { seq: k as u64, pose: PoseFrame { t, joints_deg }, ..TakeFrame::default() }
        })
        .collect();
    TakeInput {
        name: "bench".to_string(),
        header: Some(TakeHeader::offline("bench", "grass", rate_hz as u32)),
        frames,
        ..TakeInput::default()
    }
}

/// A field of `plants` plants (a `rows x cols` grid, every cell used) laid out by `frond_motion::field::make_field` (rows along +X,
/// 0.25 m cells, wind at 1.5 m/s) over a take of `frames` frames at 30 FPS.
pub fn grid_field(plants: usize, frames: usize) -> Result<Field, BakeError> {
    // rows x cols == plants exactly: the largest divisor not above the square root.
    let plants = plants.max(1);
    let rows = (1..=plants)
        .take_while(|r| r * r <= plants)
        .filter(|r| plants.is_multiple_of(*r))
        .last()
        .unwrap_or(1);
    let cols = plants / rows;
    let params =
        FieldParams { rows, cols, cell_m: 0.25, speed_m_s: 1.5, direction_deg: 0.0, density: 1.0, seed: 7 };
    let f = make_field(&params, "bench", frames, 30.0)
        .map_err(|e| BakeError::Field { origin: "bench".to_string(), reason: e.to_string() })?;
    Field::from_json(&f.to_json(), "bench")
}

fn grass() -> Result<LoadedRig, BakeError> {
    LoadedRig::embedded("grass").unwrap_or_else(|| Err(BakeError::Json("no embedded grass rig".to_string())))
}

/// Bakes a `minutes`-long take captured at `rate_hz` (the daemon default is 1000) on the grass
/// rig at 30 FPS, and encodes it as GLB.
pub fn take_bake(minutes: f64, rate_hz: f64) -> Result<BenchResult, BakeError> {
    let rig = grass()?;
    let model = rig.model()?;
    let take = synthetic_take(minutes * 60.0, rate_hz);
    let mut baker = Baker::new();
    let mut glb = Vec::new();
    let start = Instant::now();
    let baked = baker.bake_take(&rig, &model, &take, &BakeOptions::default(), &mut |_, _| {})?;
    encode_glb(&baked, &mut glb)?;
    let elapsed = start.elapsed();
    Ok(BenchResult {
        name: format!("gltf bake: {minutes} min take at {rate_hz} Hz"),
        frames_in: take.frames.len(),
        plants: 1,
        keys: baked.stats.keys,
        channels: baked.stats.channels,
        bytes: glb.len(),
        elapsed,
    })
}

/// Bakes a field of `plants` grass plants for `seconds` at 30 FPS from a 20-second take, and
/// encodes it as GLB.
pub fn field_bake(plants: usize, seconds: f64) -> Result<BenchResult, BakeError> {
    let rig = grass()?;
    let model = rig.model()?;
    let take = synthetic_take(20.0, 1000.0);
    let field = grid_field(plants, 600)?;
    let mut baker = Baker::new();
    let mut glb = Vec::new();
    let start = Instant::now();
    let baked =
        baker.bake_field(&rig, &model, &take, &field, seconds, &BakeOptions::default(), &mut |_, _| {})?;
    encode_glb(&baked, &mut glb)?;
    let elapsed = start.elapsed();
    Ok(BenchResult {
        name: format!("gltf bake: {plants}-plant field, {seconds} s"),
        frames_in: take.frames.len(),
        plants: baked.stats.plants,
        keys: baked.stats.keys,
        channels: baked.stats.channels,
        bytes: glb.len(),
        elapsed,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_benches_run() {
        let r = take_bake(0.05, 100.0).unwrap();
        assert_eq!((r.plants, r.channels, r.keys), (1, 4, 90));
        let r = field_bake(9, 1.0).unwrap();
        assert_eq!((r.plants, r.channels, r.keys), (9, 36, 31));
        assert!(r.to_string().contains("9-plant field"));
    }
}
