//! A field on the wire (protocol 3, [`frond_protocol::field`]) and back: the layout a field is
//! made from, the controls, and the field frames that carry the driving stream. The daemon
//! fills field frames with [`FrameFiller`]; a subscriber makes the field from its definition
//! with [`field_from_definition`] and feeds each frame to [`apply_frame`], then evaluates plants
//! with [`FieldState::plant_at`], the same code the daemon's own field runs.

use frond_protocol::field::{
    FIELD_FRAME_NEW, FIELD_FRAME_TRICKLE, FieldControlsWire, FieldDefinition, FieldFrame, FieldLayout,
    StreamFrame,
};

use crate::controls::FieldControls;
use crate::field::{FIELD_VERSION, Field, FieldError, FieldParams, make_field};
use crate::field_eval::FieldState;

/// The controls as they travel.
pub fn controls_to_wire(c: &FieldControls) -> FieldControlsWire {
    FieldControlsWire {
        direction_deg: c.direction_deg,
        speed_m_s: c.speed_m_s,
        time_step: c.time_step,
        scale: c.scale,
        delays_s: c.delays_s,
    }
}

/// The controls a peer sent, or `None` when a value is not finite (such a frame is ignored).
pub fn controls_from_wire(w: &FieldControlsWire) -> Option<FieldControls> {
    let finite = [w.direction_deg, w.speed_m_s, w.time_step, f64::from(w.scale)]
        .iter()
        .chain(&w.delays_s)
        .all(|x| x.is_finite());
    finite.then_some(FieldControls {
        direction_deg: w.direction_deg,
        speed_m_s: w.speed_m_s,
        time_step: w.time_step,
        scale: w.scale,
        delays_s: w.delays_s,
    })
}

/// The parameters `field` was made from (its `field.json` header).
pub fn layout_of(field: &Field) -> FieldLayout {
    FieldLayout {
        version: field.version,
        take: field.take.clone(),
        fps: field.fps,
        frames: field.frames as u64,
        rows: field.rows.try_into().unwrap_or(u32::MAX),
        cols: field.cols.try_into().unwrap_or(u32::MAX),
        cell_m: field.cell_m,
        speed_m_s: field.speed_m_s,
        direction_deg: field.direction_deg,
        authored_direction_deg: field.authored_direction_deg,
        density: field.density,
        seed: field.seed,
    }
}

/// The field a layout makes ([`make_field`], limits checked before anything is allocated).
pub fn field_from_layout(l: &FieldLayout) -> Result<Field, FieldError> {
    if l.version != FIELD_VERSION {
        return Err(FieldError::Invalid(format!(
            "a field layout of version {} (this build makes version {FIELD_VERSION})",
            l.version
        )));
    }
    let params = FieldParams {
        rows: l.rows as usize,
        cols: l.cols as usize,
        cell_m: l.cell_m,
        speed_m_s: l.speed_m_s,
        direction_deg: l.direction_deg,
        density: l.density,
        seed: l.seed,
    };
    let frames = usize::try_from(l.frames).unwrap_or(usize::MAX);
    let mut field = make_field(&params, &l.take, frames, l.fps)?;
    field.authored_direction_deg = l.authored_direction_deg;
    Ok(field)
}

/// Whether `field` is exactly what its own parameters make, so that its definition on the wire
/// (the parameters) gives every subscriber the same plants. A hand-edited `field.json` is not.
pub fn field_is_generated(field: &Field) -> bool {
    field_from_layout(&layout_of(field)).is_ok_and(|made| made == *field)
}

/// A subscriber's field from its definition: the plants made from the layout (their count
/// checked against the definition's), an empty history of the definition's length.
pub fn field_from_definition(d: &FieldDefinition) -> Result<FieldState, FieldError> {
    d.check().map_err(|e| FieldError::Invalid(e.to_string()))?;
    let field = field_from_layout(&d.layout)?;
    if field.plants.len() != d.plants as usize {
        return Err(FieldError::Invalid(format!(
            "field {}: its layout makes {} plants, its definition says {}",
            d.id,
            field.plants.len(),
            d.plants
        )));
    }
    Ok(FieldState::new(field, d.stream_fps, FieldControls::default(), d.history_frames as usize))
}

/// Feeds one field frame to a subscriber's field: its stream frames into the history, its stream
/// time and controls (delays recomputed only when the controls changed). `false` when the frame
/// was ignored (controls or stream time not finite). Allocation-free.
pub fn apply_frame(state: &mut FieldState, f: &FieldFrame) -> bool {
    let Some(c) = controls_from_wire(&f.controls) else { return false };
    if !f.tau_s.is_finite() {
        return false;
    }
    for e in f.entries.as_slice().iter().filter(|e| e.index < f.produced) {
        state.history_mut().insert(e.index, e.joints_deg);
    }
    if c != state.controls() {
        state.set_controls(c);
    }
    state.set_tau_s(f.tau_s);
    true
}

/// Fills the daemon's field frames: the newest [`FIELD_FRAME_NEW`] stream frames and
/// [`FIELD_FRAME_TRICKLE`] older ones, a cursor walking the history back from the newest to the
/// oldest frame and round again, so a subscriber that joins (or missed frames) holds the recent
/// frames most plants read within a few frames and the whole window after `capacity /
/// FIELD_FRAME_TRICKLE` frames. `Copy`, allocation-free.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameFiller {
    cursor: u64,
}

impl FrameFiller {
    /// Sets `out`'s stream time, controls, `produced` and entries from `state` (its sequence
    /// number, times and field id are the caller's).
    pub fn fill(&mut self, state: &FieldState, out: &mut FieldFrame) {
        let h = state.history();
        out.tau_s = state.tau_s();
        out.controls = controls_to_wire(&state.controls());
        out.produced = h.produced();
        out.entries.clear();
        let newest_from = h.produced().saturating_sub(FIELD_FRAME_NEW as u64).max(h.oldest());
        for k in newest_from..h.produced() {
            if let Some(j) = h.get(k) {
                out.entries.push(StreamFrame { index: k, joints_deg: *j });
            }
        }
        // Backwards from just below the newest: most rows read the recent part of the window
        // (the part beyond their start offsets is there for long delays), so a subscriber that
        // joins can evaluate most plants long before the whole window has arrived.
        for _ in 0..FIELD_FRAME_TRICKLE {
            if newest_from <= h.oldest() {
                break;
            }
            if self.cursor < h.oldest() || self.cursor >= newest_from {
                self.cursor = newest_from - 1;
            }
            if let Some(j) = h.get(self.cursor) {
                out.entries.push(StreamFrame { index: self.cursor, joints_deg: *j });
            }
            // Past the oldest, start again below the newest (next time round).
            self.cursor = if self.cursor == h.oldest() { newest_from } else { self.cursor - 1 };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{FieldParams, make_field};
    use frond_protocol::ElementId;

    #[test]
    fn a_layout_makes_the_same_field_and_a_hand_edited_one_is_told_apart() {
        let p = FieldParams {
            rows: 3,
            cols: 5,
            cell_m: 0.3,
            speed_m_s: 1.2,
            direction_deg: 20.0,
            density: 0.7,
            seed: 9,
        };
        let f = make_field(&p, "t", 200, 30.0).unwrap();
        assert_eq!(field_from_layout(&layout_of(&f)).unwrap(), f);
        assert!(field_is_generated(&f));
        let mut edited = f.clone();
        edited.plants[0].position_m[0] += 0.01;
        assert!(!field_is_generated(&edited));
        let bad = FieldLayout { version: 2, ..layout_of(&f) };
        assert!(field_from_layout(&bad).unwrap_err().to_string().contains("version 2"));
    }

    #[test]
    fn frames_refill_a_late_subscribers_history() {
        let f = make_field(
            &FieldParams {
                rows: 1,
                cols: 2,
                cell_m: 0.5,
                speed_m_s: 1.0,
                direction_deg: 0.0,
                density: 1.0,
                seed: 1,
            },
            "t",
            100,
            30.0,
        )
        .unwrap();
        let mut daemon = FieldState::new(f.clone(), 30.0, FieldControls::default(), 64);
        for k in 0..100 {
            daemon.history_mut().push([[k as f32; 3]; 4]);
        }
        let def = FieldDefinition {
            id: ElementId::new(40),
            source: "field".into(),
            rig: "grass".into(),
            layout: layout_of(&f),
            plants: 2,
            stream_fps: 30.0,
            history_frames: 64,
            publish_hz: 60,
            plant_elements: vec![],
        };
        let mut sub = field_from_definition(&def).unwrap();
        let (mut filler, mut frame) = (FrameFiller::default(), FieldFrame::default());
        // The first frame brings the newest 4 and the 8 just below them: the recent frames come
        // first.
        filler.fill(&daemon, &mut frame);
        assert!(apply_frame(&mut sub, &frame));
        assert!((88..100).all(|k| sub.history().get(k).is_some()) && sub.history().get(87).is_none());
        let mut frames = 1;
        while !sub.history().is_complete() || sub.history().produced() < 100 {
            filler.fill(&daemon, &mut frame);
            assert!(apply_frame(&mut sub, &frame));
            frames += 1;
            assert!(frames <= 64 / FIELD_FRAME_TRICKLE + 1, "{frames} frames and still incomplete");
        }
        for k in 36..100 {
            assert_eq!(sub.history().get(k), daemon.history().get(k), "frame {k}");
        }
        // A frame whose controls are not finite changes nothing.
        frame.controls.speed_m_s = f64::NAN;
        assert!(!apply_frame(&mut sub, &frame));
        assert!(field_from_definition(&FieldDefinition { plants: 3, ..def }).is_err());
    }
}
