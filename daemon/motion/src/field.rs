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

use crate::clip::{Clip, DelayLine, Joints};
use crate::controls::{FieldControls, shape_pose};
use crate::looping::{LoopPlayer, PlaybackParams, Transitions};
use crate::rng::SeededRng;
use crate::sample::{JOINTS, PoseFrame};

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
    /// The plants.
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

/// Live (and benchmark) playback of a field: one endless loop stream of the take feeds a
/// history ring, and each plant reads it at `tau + start_r / fps - K (gamma_B + delta_i)` where
/// `tau` is the stream time (advanced by the motion speed `K`), `start_r` its row's start frame,
/// `gamma_B` its propagation delay (Eq. 6-7) and `delta_i` the rigidity delay of joint `i`
/// (section 6.3 (3)). Controls change live ([`FieldPlayer::set_controls`]); delays are then
/// recomputed for the new direction and speed: `gamma_B = (B - A_row) . dir / V_M`, where `A_row`
/// is the row's plant furthest upwind along the new direction (so with the layout direction this
/// is Eq. 7's `||B - A||` for plants on the row's axis). Allocation-free after
/// [`FieldPlayer::new`].
#[derive(Debug, Clone)]
pub struct FieldPlayer {
    field: Field,
    clip: Clip,
    player: LoopPlayer,
    line: DelayLine,
    controls: FieldControls,
    delays: Vec<f64>,
    row_upwind: Vec<f64>,
    /// Stream time, seconds.
    tau: f64,
    last_t: Option<f64>,
    /// Stream frames produced.
    produced: u64,
    max_offset_s: f64,
}

/// Seconds of stream history a [`FieldPlayer`] keeps (the longest delay it can show).
pub const FIELD_HISTORY_S: f64 = 60.0;

impl FieldPlayer {
    /// A player for `field` looping `clip` (the take at `field.fps`) over `transitions`, after
    /// [`Field::check`]: a field out of its limits is refused before anything is allocated for
    /// it. The one constructor for fields from outside.
    pub fn try_new(
        field: Field,
        clip: Clip,
        transitions: &Transitions,
        seed: u64,
        controls: FieldControls,
    ) -> Result<Self, FieldError> {
        field.check()?;
        if !(clip.fps.is_finite() && clip.fps > 0.0 && clip.fps <= MAX_FIELD_FPS) {
            return Err(out_of_range("the take's fps", clip.fps, format!("(0, {MAX_FIELD_FPS}]")));
        }
        Ok(Self::new(field, clip, transitions, seed, controls))
    }

    /// [`FieldPlayer::try_new`] for a field made in code ([`make_field`], the bench fixture).
    ///
    /// # Panics
    /// If `field` breaks [`Field::check`]'s limits (a plant's row beyond `rows`); fields from
    /// outside go through [`FieldPlayer::try_new`].
    pub fn new(
        field: Field,
        clip: Clip,
        transitions: &Transitions,
        seed: u64,
        controls: FieldControls,
    ) -> Self {
        let max_offset_s = field.plants.iter().map(|p| p.start_frame).max().unwrap_or(0) as f64 / clip.fps;
        let cap = DelayLine::capacity_for(FIELD_HISTORY_S + max_offset_s + 1.0, clip.fps);
        let player = LoopPlayer::new(clip.len(), transitions, seed, PlaybackParams::default(), 0);
        let n = field.plants.len();
        let rows = field.rows;
        let mut fp = FieldPlayer {
            field,
            clip,
            player,
            line: DelayLine::new(cap),
            controls,
            delays: vec![0.0; n],
            row_upwind: vec![0.0; rows],
            tau: 0.0,
            last_t: None,
            produced: 0,
            max_offset_s,
        };
        fp.set_controls(controls);
        fp
    }

    /// The field.
    pub fn field(&self) -> &Field {
        &self.field
    }

    /// Frames of stream history this player keeps (sized once, in the constructor).
    pub fn history_capacity(&self) -> usize {
        self.line.capacity()
    }

    /// The controls in force.
    pub fn controls(&self) -> FieldControls {
        self.controls
    }

    /// Replaces the controls and recomputes every plant's delay (no allocation).
    pub fn set_controls(&mut self, c: FieldControls) {
        self.controls = c;
        let dir = heading_vector(c.direction_deg);
        let proj = |p: &FieldPlant| p.position_m[0] as f64 * dir[0] + p.position_m[1] as f64 * dir[1];
        self.row_upwind.iter_mut().for_each(|x| *x = f64::INFINITY);
        for p in &self.field.plants {
            let r = &mut self.row_upwind[p.row];
            *r = r.min(proj(p));
        }
        let v = c.speed_m_s.max(1e-6);
        for (d, p) in self.delays.iter_mut().zip(&self.field.plants) {
            *d = (proj(p) - self.row_upwind[p.row]) / v;
        }
    }

    /// Fills `out[id]` with every plant's pose at wall time `t_s` (seconds, non-decreasing).
    /// `out` must have one entry per plant.
    pub fn frame(&mut self, t_s: f64, out: &mut [Joints]) {
        let c = self.controls;
        if let Some(last) = self.last_t
            && t_s > last
        {
            self.tau += c.time_step * (t_s - last);
        }
        self.last_t = Some(self.last_t.map_or(t_s, |l| l.max(t_s)));
        if self.clip.is_empty() {
            out.iter_mut().for_each(|o| *o = [[0.0; 3]; JOINTS]);
            return;
        }
        let fps = self.clip.fps;
        let need = self.tau + self.max_offset_s + 1.0 / fps;
        while (self.produced as f64) / fps <= need {
            let j = self.player.next_step(&self.clip).joints(&self.clip);
            self.line.push(PoseFrame { t: self.produced as f64 / fps, joints_deg: j });
            self.produced += 1;
        }
        let rotate = c.direction_deg - self.field.authored_direction_deg;
        for ((o, p), gamma) in out.iter_mut().zip(&self.field.plants).zip(&self.delays) {
            let base = self.tau + p.start_frame as f64 / fps - c.time_step * gamma;
            let mut j = [[0.0; 3]; JOINTS];
            for (i, ji) in j.iter_mut().enumerate() {
                let delta = if i == 0 { 0.0 } else { c.delays_s[i - 1] };
                let at = base - c.time_step * delta;
                *ji = self.line.at_time(at).map_or([0.0; 3], |x| x[i]);
            }
            *o = shape_pose(&j, c.scale, rotate);
        }
    }
}

/// A fixture for `frond bench`: a 1000-plant field (20 rows x 50 columns) over a 10 s synthetic
/// sway at 30 FPS, and an output buffer. Time [`FieldPlayer::frame`] on it for the per-frame cost.
pub fn bench_field_1000() -> (FieldPlayer, Vec<Joints>) {
    let clip = Clip::from_joints(
        (0..300).map(|k| {
            let t = k as f32 / 30.0;
            let s = (t * 2.1).sin() * 20.0 + (t * 5.3).sin() * 4.0;
            [
                [s, -s * 0.5, 0.0],
                [s * 0.5, -s * 0.25, 0.0],
                [s * 0.5, -s * 0.25, 3.0],
                [s * 0.3, -s * 0.1, 3.0],
            ]
        }),
        30.0,
    );
    let transitions = crate::looping::find_transitions(&clip, &crate::looping::LoopParams::default())
        .unwrap_or(Transitions { pivot: 297, transitions: vec![297] });
    let params = FieldParams {
        rows: 20,
        cols: 50,
        cell_m: 0.2,
        speed_m_s: 1.5,
        direction_deg: 30.0,
        density: 1.0,
        seed: 1,
    };
    let field = make_field(&params, "bench", clip.len(), clip.fps).expect("fixed, valid bench parameters");
    let out = vec![[[0.0; 3]; JOINTS]; field.plants.len()];
    (FieldPlayer::new(field, clip, &transitions, 1, FieldControls::default()), out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::looping::{LoopParams, find_transitions, loop_clip};

    fn sway(n: usize) -> Clip {
        Clip::from_joints(
            (0..n).map(|k| {
                let s = (k as f32 * 0.3).sin() * 20.0;
                [[s, -s, 1.0], [s, 0.0, 0.0], [0.0, s, 0.0], [1.0, 2.0, 3.0]]
            }),
            30.0,
        )
    }

    fn params(rows: usize, cols: usize) -> FieldParams {
        FieldParams { rows, cols, cell_m: 0.5, speed_m_s: 2.0, direction_deg: 0.0, density: 1.0, seed: 3 }
    }

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
    fn one_plant_per_row_equals_the_looped_take() {
        let clip = sway(120);
        let t = find_transitions(&clip, &LoopParams::default()).unwrap();
        let (looped, _) = loop_clip(&clip, &t, 11, PlaybackParams::default(), 0, 1200);
        // Start frames within the first 900, so 200 frames of playback stay inside the take.
        let f = make_field(&params(5, 1), "loop", 900, looped.fps).unwrap();
        assert_eq!(f.plants.len(), 5);
        for p in &f.plants {
            assert_eq!((p.source, p.delay_s), (p.id, 0.0));
            for k in 0..100 {
                let t = k as f64 / 30.0;
                let want = looped.frames[(p.start_frame + k).min(looped.len() - 1)].joints_deg;
                assert_eq!(f.pose(p.id, &looped, t), want, "plant {} frame {k}", p.id);
            }
        }
        // Live: the endless stream with the same seed is the same looped take.
        let mut live = FieldPlayer::new(f.clone(), clip, &t, 11, FieldControls::default());
        let mut out = vec![[[0.0; 3]; 4]; 5];
        for k in 0..200 {
            live.frame(k as f64 / 30.0, &mut out);
            for p in &f.plants {
                let want = looped.frames[p.start_frame + k].joints_deg;
                for (x, y) in out[p.id].iter().flatten().zip(want.iter().flatten()) {
                    assert!((x - y).abs() < 1e-4, "plant {} frame {k}", p.id);
                }
            }
        }
    }

    #[test]
    fn live_field_delays_follow_eq7_and_controls() {
        let clip = sway(200);
        let t = find_transitions(&clip, &LoopParams::default()).unwrap();
        let f = make_field(&params(1, 4), "t", 200, 30.0).unwrap();
        let mut live = FieldPlayer::new(
            f.clone(),
            clip.clone(),
            &t,
            2,
            FieldControls { speed_m_s: 2.0, ..Default::default() },
        );
        // Same layout direction: delay = x distance / V_M (projection along +X).
        for (p, d) in f.plants.iter().zip(&live.delays) {
            let want = (p.position_m[0] - f.plants[0].position_m[0]) as f64 / 2.0;
            assert!((d - want).abs() < 1e-6);
        }
        // Reverse the force: the last plant is now upwind (delay 0), the first the most delayed.
        live.set_controls(FieldControls { direction_deg: 180.0, speed_m_s: 2.0, ..Default::default() });
        assert!(live.delays[3].abs() < 1e-9);
        assert!(live.delays[0] > live.delays[1]);
        let mut out = vec![[[0.0; 3]; 4]; 4];
        live.frame(0.0, &mut out);
        live.frame(10.0, &mut out);
        assert!(out.iter().flatten().flatten().all(|x| x.is_finite()));
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

    #[test]
    fn bench_fixture_has_1000_plants() {
        let (mut player, mut out) = bench_field_1000();
        assert_eq!(out.len(), 1000);
        player.frame(0.0, &mut out);
        player.frame(1.0 / 30.0, &mut out);
        assert!(out.iter().flatten().flatten().any(|x| *x != 0.0));
    }
}
