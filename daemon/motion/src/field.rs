//! A field of plants animated from one take (seed 000, section 6.2, Eq. 6-7) and its file,
//! `field.json`, read by the glTF baker and the warp preview.
//!
//! The ground is a grid of `rows x cols` square cells of `cell_m` metres whose rows run along the
//! force direction. Each cell is selected with probability `density` and gets one plant at a
//! uniformly random point inside it. The upwind-most plant `A` of each row (smallest position
//! along the force) starts at a random frame of the (looped) take; every other plant `B` of the
//! row plays `A`'s motion delayed by `gamma_B = ||B - A|| / V_M` (Eq. 6: `F_B(t) =
//! F_A(t - gamma_B)`, Eq. 7), with linear interpolation between frames, and every plant's bend is
//! rotated to the force direction (section 6.3 (1)(b)).
//!
//! # `field.json` (version 1)
//!
//! ```json
//! { "version": 1, "take": "sway-loop", "fps": 30.0, "frames": 1800,
//!   "rows": 4, "cols": 10, "cell_m": 0.2, "speed_m_s": 1.5, "direction_deg": 0.0,
//!   "authored_direction_deg": 0.0, "density": 1.0, "seed": 7,
//!   "plants": [ { "id": 0, "row": 0, "col": 0, "position_m": [0.13, -0.05], "source": 0,
//!                 "delay_s": 0.0, "start_frame": 412, "scale": 1.04 }, ... ] }
//! ```
//!
//! `plants` may be left out (a field of thousands of plants, whose full file would not fit in a
//! control request): readers make them from the parameters with [`make_field`].
//!
//! - `position_m` is `[x, z]` on the ground (y = 0), metres, glTF frame (Y up).
//! - `direction_deg`: the force heading, the +X axis rotated about +Y: 0 = +X, 90 = -Z.
//! - Plant `p` at time `t` seconds shows the take's (global layer's, resampled at `fps`) frame
//!   `start_frame + (t - delay_s) * fps`, linearly interpolated and clamped to the take, with
//!   every joint's bend rotated by `direction_deg - authored_direction_deg`
//!   ([`crate::controls::rotate_bend`]); `scale` is a size factor for the plant's geometry (not
//!   its angles). `source` is the id of the row's upwind plant `A` (itself for `A`).
//! - Use a looped take (`frond take loop ... --duration`) long enough for the playback.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::clip::{Clip, Joints};
use crate::controls::shape_pose;
use crate::rng::SeededRng;

/// Current `field.json` version.
pub const FIELD_VERSION: u32 = 1;
/// Plant size factors are drawn uniformly from this range.
pub const PLANT_SCALE_RANGE: (f64, f64) = (0.85, 1.15);

/// Most grid cells (`rows x cols`) of a field; `rows` and `cols` are each at least 1, so each
/// is at most this too. Every cell holds at most one plant, and a live field keeps one value
/// per row, so this bounds what a field's numbers can make anyone allocate.
pub const MAX_FIELD_CELLS: usize = 1_000_000;
/// Largest field file (JSON) read, bytes.
pub const MAX_FIELD_FILE_BYTES: u64 = 64 << 20;
/// Most plants of a field: one per cell.
pub const MAX_FIELD_PLANTS: usize = MAX_FIELD_CELLS;
/// Longest take a field may play, frames at its `fps`: one hour at 30 FPS. Start frames lie
/// below it, and a live field keeps `FIELD_HISTORY_S` plus its largest start offset of
/// history (at most about 6 MB at 30 FPS), so this bounds that history and the frames a live
/// field computes ahead.
pub const MAX_FIELD_FRAMES: usize = 108_000;
/// Highest frame rate of a field's take.
pub const MAX_FIELD_FPS: f64 = 1000.0;
/// Longest propagation delay `delay_s` of a plant, seconds (an hour: far beyond any take a
/// field may play, [`MAX_FIELD_FRAMES`]).
pub const MAX_FIELD_DELAY_S: f64 = 3600.0;

/// One plant of a field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldPlant {
    /// Index in `plants`.
    pub id: usize,
    /// Grid row (across the force).
    pub row: usize,
    /// Grid column (along the force, 0 upwind).
    pub col: usize,
    /// `[x, z]` on the ground, metres.
    pub position_m: [f32; 2],
    /// Id of the row's upwind plant `A` whose motion this one plays.
    pub source: usize,
    /// `gamma_B = ||B - A|| / V_M`, seconds (Eq. 7).
    pub delay_s: f64,
    /// The frame of the take that `A` starts at (shared by the row).
    pub start_frame: usize,
    /// Size factor of the plant's geometry.
    pub scale: f32,
}

/// A field (`field.json`, see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Field {
    /// [`FIELD_VERSION`].
    pub version: u32,
    /// Name of the take played.
    pub take: String,
    /// Frame rate the take is sampled at.
    pub fps: f64,
    /// Frames of the take at `fps`.
    pub frames: usize,
    /// Grid rows.
    pub rows: usize,
    /// Grid columns.
    pub cols: usize,
    /// Cell size, metres.
    pub cell_m: f64,
    /// Propagation speed `V_M`, m/s.
    pub speed_m_s: f64,
    /// Force heading, degrees.
    pub direction_deg: f64,
    /// Heading the take was authored towards (0: +X).
    pub authored_direction_deg: f64,
    /// Fraction of cells holding a plant.
    pub density: f64,
    /// Seed of the layout.
    pub seed: u64,
    /// The plants. A `field.json` may leave them out: its readers make them from the
    /// parameters above ([`crate::field_wire::field_from_layout`]), as a live field's
    /// subscribers do.
    #[serde(default)]
    pub plants: Vec<FieldPlant>,
}

/// Parameters of `frond take field`.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldParams {
    /// Grid rows (>= 1).
    pub rows: usize,
    /// Grid columns (>= 1).
    pub cols: usize,
    /// Cell size, metres (> 0).
    pub cell_m: f64,
    /// `V_M`, m/s (> 0).
    pub speed_m_s: f64,
    /// Force heading, degrees.
    pub direction_deg: f64,
    /// Fraction of cells selected, (0, 1].
    pub density: f64,
    /// Layout and start-frame seed.
    pub seed: u64,
}

/// Why a field could not be made or read.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FieldError {
    /// A parameter is out of range.
    #[error("{0}")]
    Invalid(String),
    /// `field.json` is malformed.
    #[error("field.json: {0}")]
    Json(String),
    /// A quantity that sizes memory or a loop is beyond its documented limit (refused before
    /// anything is allocated for it).
    #[error("field.json: {field} is {value}, outside the limit {limit}")]
    OutOfRange {
        /// The field's path in `field.json`: `rows`, `plants[3].start_frame`, ...
        field: String,
        /// The value found.
        value: String,
        /// The limit, e.g. `1..=1000000`.
        limit: String,
    },
}

fn out_of_range(field: impl Into<String>, value: impl ToString, limit: impl Into<String>) -> FieldError {
    FieldError::OutOfRange { field: field.into(), value: value.to_string(), limit: limit.into() }
}

/// Unit vector of a heading on the ground, `[x, z]`.
pub fn heading_vector(deg: f64) -> [f64; 2] {
    let (s, c) = deg.to_radians().sin_cos();
    [c, -s]
}

fn distance(a: [f32; 2], b: [f32; 2]) -> f64 {
    let (dx, dz) = (a[0] as f64 - b[0] as f64, a[1] as f64 - b[1] as f64);
    (dx * dx + dz * dz).sqrt()
}

/// Lays out a field over a take of `frames` frames at `fps` (see the module docs).
pub fn make_field(p: &FieldParams, take: &str, frames: usize, fps: f64) -> Result<Field, FieldError> {
    let bad = |m: String| Err(FieldError::Invalid(m));
    if p.rows == 0 || p.cols == 0 || p.rows.saturating_mul(p.cols) > MAX_FIELD_CELLS {
        return bad(format!(
            "--rows and --cols must be at least 1 with at most {MAX_FIELD_CELLS} cells, got {} x {}",
            p.rows, p.cols
        ));
    }
    if !(p.cell_m.is_finite() && p.cell_m > 0.0) {
        return bad(format!("--cell must be > 0 metres, got {}", p.cell_m));
    }
    if !(p.speed_m_s.is_finite() && p.speed_m_s > 0.0) {
        return bad(format!("--speed must be > 0 m/s, got {}", p.speed_m_s));
    }
    if !p.direction_deg.is_finite() {
        return bad(format!("--direction must be finite, got {}", p.direction_deg));
    }
    if !(p.density > 0.0 && p.density <= 1.0) {
        return bad(format!("--density must be in (0, 1], got {}", p.density));
    }
    if frames == 0 || !(fps.is_finite() && fps > 0.0) {
        return bad("the take has no frames".to_string());
    }
    if frames > MAX_FIELD_FRAMES || fps > MAX_FIELD_FPS {
        return bad(format!(
            "a field plays at most {MAX_FIELD_FRAMES} frames at up to {MAX_FIELD_FPS} FPS; the take has \
             {frames} frames at {fps} FPS"
        ));
    }
    let mut rng = SeededRng::new(p.seed);
    let along = heading_vector(p.direction_deg);
    let across = heading_vector(p.direction_deg + 90.0);
    let mut plants: Vec<FieldPlant> = Vec::new();
    for row in 0..p.rows {
        let first = plants.len();
        for col in 0..p.cols {
            if p.density < 1.0 && rng.unit() >= p.density {
                continue;
            }
            let u = (col as f64 + rng.unit()) * p.cell_m;
            let v = (row as f64 + rng.unit()) * p.cell_m;
            let pos = [(u * along[0] + v * across[0]) as f32, (u * along[1] + v * across[1]) as f32];
            let scale = rng.range(PLANT_SCALE_RANGE.0, PLANT_SCALE_RANGE.1) as f32;
            let id = plants.len();
            plants.push(FieldPlant {
                id,
                row,
                col,
                position_m: pos,
                source: id,
                delay_s: 0.0,
                start_frame: 0,
                scale,
            });
        }
        if plants.len() == first {
            continue;
        }
        // Columns are in order along the force, so the first plant of the row is upwind-most.
        let a = plants[first].position_m;
        let mut max_delay = 0.0f64;
        for b in &mut plants[first..] {
            b.source = first;
            b.delay_s = distance(b.position_m, a) / p.speed_m_s;
            max_delay = max_delay.max(b.delay_s);
        }
        // Start late enough that the row's most delayed plant has motion from t = 0.
        let lo = ((max_delay * fps).ceil() as usize).min(frames - 1);
        let start = lo + rng.below(frames - lo);
        for b in &mut plants[first..] {
            b.start_frame = start;
        }
    }
    let field = Field {
        version: FIELD_VERSION,
        take: take.to_string(),
        fps,
        frames,
        rows: p.rows,
        cols: p.cols,
        cell_m: p.cell_m,
        speed_m_s: p.speed_m_s,
        direction_deg: p.direction_deg,
        authored_direction_deg: 0.0,
        density: p.density,
        seed: p.seed,
        plants,
    };
    // The only limit the parameters above do not settle: a long row with a slow propagation.
    field
        .check()
        .map_err(|e| FieldError::Invalid(format!("--speed is too low for the field's size: {e}")))?;
    Ok(field)
}

impl Field {
    /// Checks every quantity that sizes memory or a loop against its limit
    /// ([`MAX_FIELD_CELLS`], [`MAX_FIELD_PLANTS`], [`MAX_FIELD_FRAMES`], [`MAX_FIELD_FPS`],
    /// [`MAX_FIELD_DELAY_S`]) and that the plants are consistent with the grid: a typed
    /// [`FieldError::OutOfRange`] names the first field out of range. Allocates nothing.
    pub fn check(&self) -> Result<(), FieldError> {
        if !(1..=MAX_FIELD_CELLS).contains(&self.rows) {
            return Err(out_of_range("rows", self.rows, format!("1..={MAX_FIELD_CELLS}")));
        }
        if !(1..=MAX_FIELD_CELLS).contains(&self.cols) {
            return Err(out_of_range("cols", self.cols, format!("1..={MAX_FIELD_CELLS}")));
        }
        if self.rows * self.cols > MAX_FIELD_CELLS {
            return Err(out_of_range(
                "rows x cols",
                format!("{} x {}", self.rows, self.cols),
                format!("at most {MAX_FIELD_CELLS} cells"),
            ));
        }
        if !(self.fps.is_finite() && self.fps > 0.0 && self.fps <= MAX_FIELD_FPS) {
            return Err(out_of_range("fps", self.fps, format!("(0, {MAX_FIELD_FPS}]")));
        }
        if !(1..=MAX_FIELD_FRAMES).contains(&self.frames) {
            return Err(out_of_range("frames", self.frames, format!("1..={MAX_FIELD_FRAMES}")));
        }
        let n = self.plants.len();
        if n > MAX_FIELD_PLANTS.min(self.rows * self.cols) {
            return Err(out_of_range(
                "plants",
                format!("{n} plants"),
                format!("one per cell, at most {}", MAX_FIELD_PLANTS.min(self.rows * self.cols)),
            ));
        }
        for (i, p) in self.plants.iter().enumerate() {
            if p.id != i || p.source >= n {
                return Err(FieldError::Json(format!("plants[{i}] is inconsistent (id or source)")));
            }
            if p.row >= self.rows {
                return Err(out_of_range(format!("plants[{i}].row"), p.row, format!("0..{}", self.rows)));
            }
            if p.col >= self.cols {
                return Err(out_of_range(format!("plants[{i}].col"), p.col, format!("0..{}", self.cols)));
            }
            if p.start_frame >= self.frames {
                return Err(out_of_range(
                    format!("plants[{i}].start_frame"),
                    p.start_frame,
                    format!("0..{} (the take's frames)", self.frames),
                ));
            }
            if !(p.delay_s.is_finite() && (0.0..=MAX_FIELD_DELAY_S).contains(&p.delay_s)) {
                return Err(out_of_range(
                    format!("plants[{i}].delay_s"),
                    p.delay_s,
                    format!("[0, {MAX_FIELD_DELAY_S}] s"),
                ));
            }
            if !p.scale.is_finite() {
                return Err(out_of_range(format!("plants[{i}].scale"), p.scale, "a finite factor"));
            }
            if !p.position_m.iter().all(|x| x.is_finite()) {
                return Err(out_of_range(
                    format!("plants[{i}].position_m"),
                    format!("{:?}", p.position_m),
                    "finite metres",
                ));
            }
        }
        Ok(())
    }

    /// Plant `id`'s pose at `t_s` from the take's clip (Eq. 6-7 with the bend rotated to the
    /// force direction): clip frame `start_frame + (t - delay_s) fps`.
    pub fn pose(&self, id: usize, clip: &Clip, t_s: f64) -> Joints {
        let p = &self.plants[id];
        let j = clip.at_index(p.start_frame as f64 + (t_s - p.delay_s) * clip.fps);
        shape_pose(&j, 1.0, self.direction_deg - self.authored_direction_deg)
    }
}

/// What the field's tests and the field player's share: a swaying clip and a layout.
#[cfg(test)]
pub(crate) mod fixtures {
    use super::*;

    /// `n` frames at 30 FPS of a plant swaying +-20 degrees.
    pub(crate) fn sway(n: usize) -> Clip {
        Clip::from_joints(
            (0..n).map(|k| {
                let s = (k as f32 * 0.3).sin() * 20.0;
                [[s, -s, 1.0], [s, 0.0, 0.0], [0.0, s, 0.0], [1.0, 2.0, 3.0]]
            }),
            30.0,
        )
    }

    /// A full `rows` x `cols` grid of 0.5 m cells, `V_M` 2 m/s towards +X.
    pub(crate) fn params(rows: usize, cols: usize) -> FieldParams {
        FieldParams { rows, cols, cell_m: 0.5, speed_m_s: 2.0, direction_deg: 0.0, density: 1.0, seed: 3 }
    }
}

#[cfg(test)]
mod tests {
    use super::fixtures::{params, sway};
    use super::*;

    #[test]
    fn eq6_7_by_hand() {
        // One row, direction 0 (+X), V_M = 2 m/s. Plants at x_A and x_B on the row: with both
        // z inside the same row, gamma_B = ||B - A|| / 2.
        let f = make_field(&params(1, 3), "t", 300, 30.0).unwrap();
        assert_eq!(f.plants.len(), 3);
        let a = f.plants[0].position_m;
        for b in &f.plants {
            assert_eq!(b.source, 0);
            let want =
                ((b.position_m[0] - a[0]).powi(2) + (b.position_m[1] - a[1]).powi(2)).sqrt() as f64 / 2.0;
            assert!((b.delay_s - want).abs() < 1e-6, "{} vs {want}", b.delay_s);
            // Cell c spans x in [0.5 c, 0.5 (c + 1)), z in [-0.5, 0) (across = heading 90 = -Z).
            assert!(b.position_m[0] >= 0.5 * b.col as f32 && b.position_m[0] < 0.5 * (b.col + 1) as f32);
            assert!(b.position_m[1] <= 0.0 && b.position_m[1] > -0.5);
        }
        // Eq. 6: F_B(t) = F_A(t - gamma_B), here at an exact frame: plant B at t = gamma_B + 1 s
        // shows what A shows at t = 1 s.
        let clip = sway(300);
        for b in &f.plants {
            let fa = f.pose(0, &clip, 1.0);
            let fb = f.pose(b.id, &clip, 1.0 + b.delay_s);
            for (x, y) in fa.iter().flatten().zip(fb.iter().flatten()) {
                assert!((x - y).abs() < 1e-4, "{fa:?} vs {fb:?}");
            }
        }
        // Hand case of the interpolation: A at start frame s; B with delay 0.05 s at t = 0.1 s
        // reads frame s + 0.05 * 30 = s + 1.5, halfway between frames s + 1 and s + 2.
        let mut g = f.clone();
        g.plants[1].delay_s = 0.05;
        let s = g.plants[0].start_frame as f64;
        let want = clip.at_index(s + 1.5);
        assert_eq!(g.pose(1, &clip, 0.1), want);
        let (a1, a2) =
            (clip.frames[s as usize + 1].joints_deg[0][0], clip.frames[s as usize + 2].joints_deg[0][0]);
        assert!((want[0][0] - (a1 + a2) / 2.0).abs() < 1e-4);
    }

    #[test]
    fn direction_rotates_rows_and_bends() {
        let mut p = params(2, 4);
        p.direction_deg = 90.0; // force towards -Z
        let f = make_field(&p, "t", 100, 30.0).unwrap();
        // Columns advance towards -Z.
        for w in f.plants.windows(2).filter(|w| w[0].row == w[1].row) {
            assert!(w[1].position_m[1] < w[0].position_m[1]);
        }
        // A pure yaw -20 (bending +X) becomes pitch -20 (bending -Z).
        let clip = Clip::from_joints([[[0.0, -20.0, 0.0]; 4]], 30.0);
        let j = f.pose(0, &clip, 0.0);
        assert!((j[0][0] + 20.0).abs() < 1e-4 && j[0][1].abs() < 1e-4, "{j:?}");
    }

    #[test]
    fn fields_are_reproducible_and_parameters_checked() {
        let f = make_field(&FieldParams { density: 0.5, ..params(3, 6) }, "t", 50, 30.0).unwrap();
        assert!(f.plants.len() < 18);
        assert_eq!(make_field(&FieldParams { density: 0.5, ..params(3, 6) }, "t", 50, 30.0).unwrap(), f);
        for (p, msg) in [
            (FieldParams { rows: 0, ..params(1, 1) }, "--rows"),
            (FieldParams { cell_m: 0.0, ..params(1, 1) }, "--cell"),
            (FieldParams { speed_m_s: -1.0, ..params(1, 1) }, "--speed"),
            (FieldParams { density: 0.0, ..params(1, 1) }, "--density"),
        ] {
            assert!(make_field(&p, "t", 10, 30.0).unwrap_err().to_string().contains(msg), "{msg}");
        }
    }
}
