//! The one evaluation of a field's plants (seed 000, Eq. 6-7 and section 6.3), shared by the
//! daemon's live field ([`crate::field_player::FieldPlayer`]), the SDK (`frond_sdk::field`) and, ported
//! line for line, the console page (`exporters/console/page/field.js`).
//!
//! A field plays one driving stream (the looped take; stream frame `k` at stream time
//! `k / fps`). At stream time `tau`, plant `B` of row `r` shows, for joint `i`,
//!
//! ```text
//! P_i = stream(tau + start_r / fps - K (gamma_B + delta_i))       (Eq. 6, section 6.3 (3))
//! gamma_B = ((B - A_r) . d) / V_M                                  (Eq. 7)
//! pose_B = rotate(scale * P, direction - authored_direction)       (section 6.3 (1)(b), (2)(e))
//! ```
//!
//! where `d` is the unit force heading, `A_r` the row's plant furthest upwind along `d`, `K` the
//! motion speed, `delta_0 = 0` and `delta_1..3` the rigidity delays. `stream(s)` interpolates
//! linearly between frames `floor(s fps)` and the next, clamped to the history held: from
//! `max(0, produced - capacity)` to `produced - 1` ([`StreamHistory::at_index`]).

use crate::clip::{Joints, lerp_joints};
use crate::controls::{FieldControls, shape_pose};
use crate::field::{Field, FieldPlant, heading_vector};
use crate::sample::JOINTS;

/// Seconds of stream history a live field keeps besides its rows' start offsets (the longest
/// delay it can show).
pub const FIELD_HISTORY_S: f64 = 60.0;

/// Most frames a [`StreamHistory`] holds (the protocol's `MAX_FIELD_HISTORY_FRAMES`).
pub const MAX_STREAM_HISTORY: usize = frond_protocol::field::MAX_FIELD_HISTORY_FRAMES as usize;

/// The last `capacity` frames of a driving stream, indexed by their stream index. The daemon
/// pushes every frame in order ([`StreamHistory::push`]); a subscriber inserts what its field
/// frames carry, in any order and with holes ([`StreamHistory::insert`]). Allocation-free after
/// [`StreamHistory::new`].
#[derive(Debug, Clone)]
pub struct StreamHistory {
    frames: Vec<Joints>,
    /// `index + 1` of the frame in each slot, 0 when empty.
    held: Vec<u64>,
    produced: u64,
}

impl StreamHistory {
    /// A history of `capacity` frames, clamped to `2..=`[`MAX_STREAM_HISTORY`].
    pub fn new(capacity: usize) -> Self {
        let cap = capacity.clamp(2, MAX_STREAM_HISTORY);
        StreamHistory { frames: vec![[[0.0; 3]; JOINTS]; cap], held: vec![0; cap], produced: 0 }
    }

    /// Frames it holds at most.
    pub fn capacity(&self) -> usize {
        self.frames.len()
    }

    /// Frames of the stream known to exist: the newest index seen plus one.
    pub fn produced(&self) -> u64 {
        self.produced
    }

    /// The oldest index the window covers: `max(0, produced - capacity)`.
    pub fn oldest(&self) -> u64 {
        self.produced.saturating_sub(self.frames.len() as u64)
    }

    /// Appends the next frame of the stream (index [`StreamHistory::produced`]).
    pub fn push(&mut self, joints: Joints) {
        self.insert(self.produced, joints);
    }

    /// Records frame `index`; one older than the window is ignored, a newer one moves the window.
    pub fn insert(&mut self, index: u64, joints: Joints) {
        if index == u64::MAX || index < self.oldest() {
            return;
        }
        self.produced = self.produced.max(index + 1);
        let slot = (index % self.frames.len() as u64) as usize;
        self.frames[slot] = joints;
        self.held[slot] = index + 1;
    }

    /// Frame `index`, if held.
    pub fn get(&self, index: u64) -> Option<&Joints> {
        let slot = (index % self.frames.len() as u64) as usize;
        (index != u64::MAX && self.held[slot] == index + 1).then(|| &self.frames[slot])
    }

    /// Forgets every frame (a new stream starts at index 0).
    pub fn clear(&mut self) {
        self.held.iter_mut().for_each(|h| *h = 0);
        self.produced = 0;
    }

    /// Whether every frame of the window is held (a subscriber's history is complete).
    pub fn is_complete(&self) -> bool {
        (self.oldest()..self.produced).all(|k| self.get(k).is_some())
    }

    /// The stream at fractional index `f`, clamped to the window and linearly interpolated
    /// between frames `floor(f)` and `floor(f) + 1` ([`lerp_joints`]). `None` while nothing was
    /// produced, or when a frame it needs is not held (a subscriber still filling its history).
    pub fn at_index(&self, f: f64) -> Option<Joints> {
        if self.produced == 0 {
            return None;
        }
        let (lo, hi) = (self.oldest() as f64, (self.produced - 1) as f64);
        let f = if f.is_nan() { lo } else { f.clamp(lo, hi) };
        let k = f.floor();
        let a = self.get(k as u64)?;
        let u = f - k;
        if u == 0.0 {
            return Some(*a);
        }
        let b = self.get(k as u64 + 1)?;
        Some(lerp_joints(a, b, u))
    }
}

/// Eq. 7 for every plant under the controls' heading and propagation speed: `out[id] =
/// ((B - A_row) . d) / V_M`, with `A_row` the row's plant furthest upwind along `d` (its
/// smallest projection; `row_upwind` is scratch, one per row). With the layout's own heading this
/// is `||B - A|| / V_M` for plants on the row's axis. No allocation.
pub fn plant_delays(field: &Field, c: &FieldControls, row_upwind: &mut [f64], out: &mut [f64]) {
    let dir = heading_vector(c.direction_deg);
    let proj = |p: &FieldPlant| p.position_m[0] as f64 * dir[0] + p.position_m[1] as f64 * dir[1];
    row_upwind.iter_mut().for_each(|x| *x = f64::INFINITY);
    for p in &field.plants {
        if let Some(r) = row_upwind.get_mut(p.row) {
            *r = r.min(proj(p));
        }
    }
    let v = c.speed_m_s.max(1e-6);
    for (d, p) in out.iter_mut().zip(&field.plants) {
        *d = (proj(p) - row_upwind.get(p.row).copied().unwrap_or(0.0)) / v;
    }
}

/// One plant's pose at stream time `tau_s` (the module's equations): `start_frame` its row's
/// start, `gamma_s` its Eq. 7 delay, `rotate_deg` the bend rotation (`direction -
/// authored_direction`). `None` when the history lacks a frame it needs.
pub fn plant_pose(
    history: &StreamHistory,
    fps: f64,
    tau_s: f64,
    start_frame: usize,
    gamma_s: f64,
    c: &FieldControls,
    rotate_deg: f64,
) -> Option<Joints> {
    let base = tau_s + start_frame as f64 / fps - c.time_step * gamma_s;
    let mut j = [[0.0; 3]; JOINTS];
    for (i, ji) in j.iter_mut().enumerate() {
        let delta = if i == 0 { 0.0 } else { c.delays_s[i - 1] };
        let at = base - c.time_step * delta;
        *ji = history.at_index(at * fps)?[i];
    }
    Some(shape_pose(&j, c.scale, rotate_deg))
}

/// A field being evaluated: its plants, the driving stream's history, the controls in force,
/// each plant's delay under them and the stream time. The daemon's [`crate::field_player::FieldPlayer`]
/// fills the history from its loop player; a subscriber from field frames
/// ([`crate::field_wire`]). Allocation-free after [`FieldState::new`].
#[derive(Debug, Clone)]
pub struct FieldState {
    field: Field,
    fps: f64,
    history: StreamHistory,
    controls: FieldControls,
    delays: Vec<f64>,
    row_upwind: Vec<f64>,
    /// Whether `delays` are those of `controls` (see [`FieldState::set_controls_deferred`]).
    delays_current: bool,
    tau_s: f64,
}

impl FieldState {
    /// `field` played from a stream at `fps` (> 0), keeping `history_frames` frames of it
    /// ([`FieldState::history_frames_for`] is what the daemon keeps). The caller has checked the
    /// field ([`Field::check`]).
    pub fn new(field: Field, fps: f64, controls: FieldControls, history_frames: usize) -> Self {
        let n = field.plants.len();
        let rows = field.rows;
        let mut s = FieldState {
            field,
            fps,
            history: StreamHistory::new(history_frames),
            controls,
            delays: vec![0.0; n],
            row_upwind: vec![0.0; rows],
            delays_current: false,
            tau_s: 0.0,
        };
        s.set_controls(controls);
        s
    }

    /// The stream history the daemon keeps for `field` at `fps`: [`FIELD_HISTORY_S`]
    /// of delays, plus the largest row start, plus a second.
    pub fn history_frames_for(field: &Field, fps: f64) -> usize {
        crate::clip::DelayLine::capacity_for(FIELD_HISTORY_S + Self::max_offset_s(field, fps) + 1.0, fps)
            .min(MAX_STREAM_HISTORY)
    }

    /// The largest row start, seconds of stream.
    pub fn max_offset_s(field: &Field, fps: f64) -> f64 {
        field.plants.iter().map(|p| p.start_frame).max().unwrap_or(0) as f64 / fps
    }

    /// The field.
    pub fn field(&self) -> &Field {
        &self.field
    }

    /// Stream frames per second.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// The controls in force.
    pub fn controls(&self) -> FieldControls {
        self.controls
    }

    /// Replaces the controls and recomputes every plant's delay (no allocation; work in
    /// proportion to the plants).
    pub fn set_controls(&mut self, c: FieldControls) {
        self.controls = c;
        plant_delays(&self.field, &c, &mut self.row_upwind, &mut self.delays);
        self.delays_current = true;
    }

    /// Replaces the controls without recomputing the delays (constant work: the daemon's loop,
    /// which evaluates no plant); [`FieldState::refresh_delays`] brings them up to date before
    /// plants are evaluated.
    pub fn set_controls_deferred(&mut self, c: FieldControls) {
        self.delays_current = self.delays_current && c == self.controls;
        self.controls = c;
    }

    /// Recomputes the delays if the controls changed since they were computed.
    pub fn refresh_delays(&mut self) {
        if !self.delays_current {
            self.set_controls(self.controls);
        }
    }

    /// Plant `id`'s Eq. 7 delay under the controls of the last [`FieldState::set_controls`] or
    /// [`FieldState::refresh_delays`], seconds.
    pub fn delay_s(&self, id: usize) -> Option<f64> {
        self.delays.get(id).copied()
    }

    /// The stream time, seconds.
    pub fn tau_s(&self) -> f64 {
        self.tau_s
    }

    /// Sets the stream time.
    pub fn set_tau_s(&mut self, tau_s: f64) {
        self.tau_s = tau_s;
    }

    /// The driving stream's history.
    pub fn history(&self) -> &StreamHistory {
        &self.history
    }

    /// The driving stream's history, to fill.
    pub fn history_mut(&mut self) -> &mut StreamHistory {
        &mut self.history
    }

    /// Plant `id`'s pose at stream time `tau_s` ([`plant_pose`]); `None` for an unknown plant or
    /// while the history lacks a frame it needs. Delays are those last computed (see
    /// [`FieldState::set_controls_deferred`]).
    pub fn plant_at(&self, id: usize, tau_s: f64) -> Option<Joints> {
        let p = self.field.plants.get(id)?;
        let rotate = self.controls.direction_deg - self.field.authored_direction_deg;
        plant_pose(&self.history, self.fps, tau_s, p.start_frame, self.delays[id], &self.controls, rotate)
    }

    /// Plant `id`'s pose now (at [`FieldState::tau_s`]).
    pub fn plant(&self, id: usize) -> Option<Joints> {
        self.plant_at(id, self.tau_s)
    }

    /// Every plant's pose now into `out[id]` (zeros where the history lacks a frame); `out`
    /// shorter than the field gets its first plants.
    pub fn plants(&self, out: &mut [Joints]) {
        for (id, o) in out.iter_mut().enumerate() {
            *o = self.plant(id).unwrap_or([[0.0; 3]; JOINTS]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(x: f32) -> Joints {
        [[x, -x, 1.0], [x, 0.0, 0.0], [0.0, x, 0.0], [1.0, 2.0, x]]
    }

    #[test]
    fn history_holds_its_window_and_interpolates() {
        let mut h = StreamHistory::new(4);
        assert_eq!(h.at_index(0.0), None);
        for k in 0..6 {
            h.push(pose(k as f32 * 10.0));
        }
        // Frames 2..=5 held; clamped at both ends, halfway between 3 and 4 is 35.
        assert_eq!((h.oldest(), h.produced()), (2, 6));
        assert_eq!(h.at_index(0.0), Some(pose(20.0)));
        assert_eq!(h.at_index(99.0), Some(pose(50.0)));
        assert_eq!(h.at_index(3.5).unwrap()[0][0], 35.0);
        assert!(h.get(1).is_none() && h.is_complete());
        // A subscriber's history with a hole: lookups that need it say so.
        let mut s = StreamHistory::new(4);
        s.insert(5, pose(5.0));
        s.insert(7, pose(7.0));
        assert!(!s.is_complete());
        assert_eq!(s.at_index(5.0), Some(pose(5.0)));
        assert_eq!(s.at_index(6.5), None);
        s.insert(6, pose(6.0));
        assert_eq!(s.at_index(6.5).unwrap()[0][0], 6.5);
        // Too old for the window, or absurd indices: ignored, no panic.
        s.insert(u64::MAX, pose(1.0));
        s.insert(0, pose(1.0));
        assert!(s.get(0).is_none() && s.get(u64::MAX).is_none());
    }
}
