//! Live (and benchmark) playback of a field (seed 000, section 6.2-6.3): the driving stream
//! made by an endless loop player over the take, and the plants evaluated from it by
//! [`crate::field_eval`].

use crate::clip::{Clip, Joints};
use crate::controls::FieldControls;
use crate::field::{Field, FieldError, FieldParams, MAX_FIELD_FPS, make_field};
pub use crate::field_eval::FIELD_HISTORY_S;
use crate::field_eval::FieldState;
use crate::looping::{LoopPlayer, PlaybackParams, Transitions};
use crate::sample::JOINTS;

/// Live playback of a field: one endless loop stream of the take feeds the history of a
/// [`FieldState`], and each plant reads it at `tau + start_r / fps - K (gamma_B + delta_i)` where
/// `tau` is the stream time (advanced by the motion speed `K`), `start_r` its row's start frame,
/// `gamma_B` its propagation delay (Eq. 6-7) and `delta_i` the rigidity delay of joint `i`
/// (section 6.3 (3)); see [`crate::field_eval`]. Controls change live
/// ([`FieldPlayer::set_controls`]); delays are then recomputed for the new direction and speed.
/// Allocation-free after [`FieldPlayer::new`].
#[derive(Debug, Clone)]
pub struct FieldPlayer {
    state: FieldState,
    clip: Clip,
    player: LoopPlayer,
    last_t: Option<f64>,
    max_offset_s: f64,
}

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
            return Err(FieldError::OutOfRange {
                field: "the take's fps".into(),
                value: clip.fps.to_string(),
                limit: format!("(0, {MAX_FIELD_FPS}]"),
            });
        }
        Ok(Self::new(field, clip, transitions, seed, controls))
    }

    /// [`FieldPlayer::try_new`] for a field made in code ([`make_field`], the bench fixture);
    /// fields from outside go through [`FieldPlayer::try_new`].
    pub fn new(
        field: Field,
        clip: Clip,
        transitions: &Transitions,
        seed: u64,
        controls: FieldControls,
    ) -> Self {
        let max_offset_s = FieldState::max_offset_s(&field, clip.fps);
        let cap = FieldState::history_frames_for(&field, clip.fps);
        let player = LoopPlayer::new(clip.len(), transitions, seed, PlaybackParams::default(), 0);
        let state = FieldState::new(field, clip.fps, controls, cap);
        FieldPlayer { state, clip, player, last_t: None, max_offset_s }
    }

    /// The field.
    pub fn field(&self) -> &Field {
        self.state.field()
    }

    /// The evaluation state: stream history, controls, delays and stream time.
    pub fn state(&self) -> &FieldState {
        &self.state
    }

    /// Frames of stream history this player keeps (sized once, in the constructor).
    pub fn history_capacity(&self) -> usize {
        self.state.history().capacity()
    }

    /// The controls in force.
    pub fn controls(&self) -> FieldControls {
        self.state.controls()
    }

    /// Replaces the controls (constant work, no allocation: the plants' delays are recomputed
    /// when [`FieldPlayer::frame`] next evaluates them).
    pub fn set_controls(&mut self, c: FieldControls) {
        self.state.set_controls_deferred(c);
    }

    /// Advances to wall time `t_s` (seconds, non-decreasing): the stream time grows by the motion
    /// speed times the wall time elapsed, and the loop player produces the stream up to what the
    /// most advanced row reads. Evaluates no plant: the daemon publishes the stream, and each
    /// subscriber evaluates the plants it draws.
    pub fn advance(&mut self, t_s: f64) {
        let c = self.state.controls();
        let mut tau = self.state.tau_s();
        if let Some(last) = self.last_t
            && t_s > last
        {
            tau += c.time_step * (t_s - last);
        }
        self.state.set_tau_s(tau);
        self.last_t = Some(self.last_t.map_or(t_s, |l| l.max(t_s)));
        if self.clip.is_empty() {
            return;
        }
        let fps = self.clip.fps;
        let need = tau + self.max_offset_s + 1.0 / fps;
        while (self.state.history().produced() as f64) / fps <= need {
            let j = self.player.next_step(&self.clip).joints(&self.clip);
            self.state.history_mut().push(j);
        }
    }

    /// [`FieldPlayer::advance`], then every plant's pose into `out[id]` (one entry per plant, or
    /// fewer for the first plants).
    pub fn frame(&mut self, t_s: f64, out: &mut [Joints]) {
        self.advance(t_s);
        if self.clip.is_empty() {
            out.iter_mut().for_each(|o| *o = [[0.0; 3]; JOINTS]);
            return;
        }
        self.state.refresh_delays();
        self.state.plants(out);
    }
}

/// A fixture for `frond bench`: a 10 s synthetic sway at 30 FPS (two sines on the root, the
/// upper joints following) and its loop transitions.
pub fn bench_sway() -> (Clip, Transitions) {
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
    (clip, transitions)
}

/// A fixture for `frond bench`: a 1000-plant field (20 rows x 50 columns) over [`bench_sway`],
/// and an output buffer. Time [`FieldPlayer::frame`] on it for the per-frame cost.
pub fn bench_field_1000() -> (FieldPlayer, Vec<Joints>) {
    let (clip, transitions) = bench_sway();
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
    use crate::field::fixtures::{params, sway};
    use crate::looping::{LoopParams, find_transitions, loop_clip};

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
        for p in &f.plants {
            let want = (p.position_m[0] - f.plants[0].position_m[0]) as f64 / 2.0;
            assert!((live.state().delay_s(p.id).unwrap() - want).abs() < 1e-6);
        }
        // Reverse the force: the last plant is now upwind (delay 0), the first the most delayed.
        // The daemon's loop changes them in constant time; the delays follow at the next
        // evaluation.
        live.set_controls(FieldControls { direction_deg: 180.0, speed_m_s: 2.0, ..Default::default() });
        let mut out = vec![[[0.0; 3]; 4]; 4];
        live.frame(0.0, &mut out);
        let d = |i| live.state().delay_s(i).unwrap();
        assert!(d(3).abs() < 1e-9);
        assert!(d(0) > d(1));
        live.frame(10.0, &mut out);
        assert!(out.iter().flatten().flatten().all(|x| x.is_finite()));
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
