//! A field playing on the pose stream (seed 000, section 6.2): plants of one looped take, each
//! delayed by its position along the propagation direction, published at [`FIELD_PUBLISH_HZ`]
//! as announced `field-plant` elements; steered live by keys and wrist swipes (section 6.3).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

use frond_formats::field_json::FieldJson;
use frond_motion::clip::Joints;
use frond_motion::controls::{ControlKey, FieldControls, SwipeDetector, SwipeParams};
use frond_motion::field::{Field, FieldPlayer};
use frond_motion::{HandSample, PoseFrame};
use frond_protocol::control::StageKind;
use frond_protocol::{ElementId, StageInput, StageKey};

use super::error::{BuildError, StageError};
use super::live::{BuildContext, BuiltStage, FrameSink, LiveStage, StageInfo, StageReport, TickContext};
use super::playback::{LoopedTake, looped_clip, note_damage};
use crate::clock::NS_PER_S;

/// Most field plants published per field frame.
pub const MAX_FIELD_PLANTS: usize = 64;
/// Field frames per second on the stream (the field itself is a 30 FPS animation).
pub const FIELD_PUBLISH_HZ: u32 = 60;

/// The live field controls, published by the loop for status. Each value is its own atomic: a
/// reader racing a change may see a mix of old and new values for one refresh, which status
/// tolerates; nothing acts on it.
#[derive(Default)]
pub struct FieldControlsCell {
    values: [AtomicU64; 7],
    set: AtomicBool,
}

impl FieldControlsCell {
    /// Publishes the controls (loop thread).
    pub fn store(&self, c: FieldControls) {
        let v = [
            c.direction_deg,
            c.speed_m_s,
            c.time_step,
            f64::from(c.scale),
            c.delays_s[0],
            c.delays_s[1],
            c.delays_s[2],
        ];
        for (cell, x) in self.values.iter().zip(v) {
            cell.store(x.to_bits(), Relaxed);
        }
        self.set.store(true, Relaxed);
    }

    /// The controls last published, if any.
    pub fn load(&self) -> Option<FieldControls> {
        if !self.set.load(Relaxed) {
            return None;
        }
        let v: [f64; 7] = std::array::from_fn(|i| f64::from_bits(self.values[i].load(Relaxed)));
        Some(FieldControls {
            direction_deg: v[0],
            speed_m_s: v[1],
            time_step: v[2],
            scale: v[3] as f32,
            delays_s: [v[4], v[5], v[6]],
        })
    }
}

/// What `frond status` says of a field.
pub struct FieldReport {
    /// The controls in force.
    pub controls: FieldControlsCell,
    take: String,
    plants: usize,
    /// What a damaged take lost, in words (empty for a sound take).
    damage: String,
}

impl FieldReport {
    /// The report of a field of take `take` with `plants` plants (no controls yet).
    pub fn new(take: &str, plants: usize) -> Self {
        FieldReport {
            controls: FieldControlsCell::default(),
            take: take.to_string(),
            plants,
            damage: String::new(),
        }
    }

    /// The same, for a damaged take: `damage` says what the reader skipped.
    pub fn damaged(take: &str, plants: usize, damage: &Option<String>) -> Self {
        FieldReport { damage: note_damage(take, damage), ..Self::new(take, plants) }
    }
}

impl StageReport for FieldReport {
    fn describe(&self) -> String {
        let controls = self.controls.load().map(|c| describe_controls(&c)).unwrap_or_default();
        format!("field of {}{}: {} plants; {controls}", self.take, self.damage, self.plants)
    }
}

/// One-line description of the controls.
pub fn describe_controls(c: &FieldControls) -> String {
    format!(
        "direction {:.0} deg, propagation {:.2} m/s, motion speed x{:.2}, scale x{:.2}, rigidity delays {:?} s",
        c.direction_deg, c.speed_m_s, c.time_step, c.scale, c.delays_s
    )
}

/// The field player in the loop.
pub struct FieldStage {
    player: FieldPlayer,
    out: Vec<Joints>,
    ids: [ElementId; MAX_FIELD_PLANTS],
    publish: usize,
    swipe: SwipeDetector,
    base_speed_m_s: f64,
    t0_ns: u64,
    next_ns: u64,
    report: Arc<FieldReport>,
}

impl FieldStage {
    /// `field` of a take made ready to loop ([`looped_clip`]), its first plants published as
    /// the element ids `ids` (one per published plant).
    pub fn new(
        looped: LoopedTake,
        field: Field,
        ids: &[ElementId],
        seed: u64,
        t0_ns: u64,
        report: Arc<FieldReport>,
    ) -> Result<Self, StageError> {
        let LoopedTake { clip, transitions, .. } = looped;
        let n = field.plants.len();
        if n == 0 {
            return Err(StageError::EmptyField);
        }
        let base_speed_m_s = field.speed_m_s.max(0.05);
        let controls = FieldControls {
            direction_deg: field.authored_direction_deg,
            speed_m_s: base_speed_m_s,
            ..FieldControls::default()
        };
        let player = FieldPlayer::try_new(field, clip, &transitions, seed, controls)?;
        report.controls.store(controls);
        let publish = ids.len().min(n).min(MAX_FIELD_PLANTS);
        let mut id_table = [ElementId::GLOBAL; MAX_FIELD_PLANTS];
        id_table[..publish].copy_from_slice(&ids[..publish]);
        Ok(FieldStage {
            player,
            // Only the published plants are computed: a field of thousands costs a tick no more
            // than its first `publish` (its budget, `budget::FIELD_PLANT_NS` each).
            out: vec![[[0.0; 3]; 4]; publish],
            ids: id_table,
            publish,
            swipe: SwipeDetector::new(SwipeParams::default()),
            base_speed_m_s,
            t0_ns,
            next_ns: t0_ns,
            report,
        })
    }

    fn set_controls(&mut self, c: FieldControls) {
        self.player.set_controls(c);
        self.report.controls.store(c);
    }
}

fn control_key(k: StageKey) -> ControlKey {
    match k {
        StageKey::Left => ControlKey::Left,
        StageKey::Right => ControlKey::Right,
        StageKey::Up => ControlKey::Up,
        StageKey::Down => ControlKey::Down,
        StageKey::Stronger => ControlKey::Stronger,
        StageKey::Weaker => ControlKey::Weaker,
    }
}

impl LiveStage for FieldStage {
    fn on_hand(&mut self, hand: &HandSample, _pose: &mut PoseFrame, _element: &mut ElementId) {
        if let Some(swipe) = self.swipe.push(hand) {
            let mut c = self.player.controls();
            c.swipe(&swipe, self.base_speed_m_s);
            self.set_controls(c);
        }
    }

    fn tick(&mut self, ctx: &TickContext, out: &mut dyn FrameSink) {
        if ctx.now_ns < self.next_ns {
            return;
        }
        let period = NS_PER_S / u64::from(FIELD_PUBLISH_HZ);
        self.next_ns = (self.next_ns + period).max(ctx.now_ns);
        let t = ctx.now_ns.saturating_sub(self.t0_ns) as f64 / NS_PER_S as f64;
        self.player.frame(t, &mut self.out);
        for (id, joints) in self.ids[..self.publish].iter().zip(&self.out) {
            out.emit(*id, *joints);
        }
    }

    fn every_tick(&self) -> bool {
        true
    }

    fn input(&mut self, input: StageInput) {
        let StageInput::Key(k) = input else { return };
        let mut c = self.player.controls();
        c.key(control_key(k));
        self.set_controls(c);
    }
}

fn takes_keys(input: &StageInput) -> bool {
    matches!(input, StageInput::Key(_))
}

/// Builds a field of the looped take `take`, publishing its first `plants` plants.
pub fn build(
    take: &str,
    field_json: &str,
    plants: u16,
    seed: u64,
    ctx: &BuildContext,
) -> Result<BuiltStage, BuildError> {
    if !(1..=MAX_FIELD_PLANTS as u16).contains(&plants) {
        return Err(BuildError::invalid(format!(
            "a field publishes 1..={MAX_FIELD_PLANTS} plants, not {plants}"
        )));
    }
    let bytes = super::live::read_take(ctx.takes_dir, take)?;
    let field = Field::from_json(field_json)
        .map_err(|e| BuildError::invalid(format!("field of take {take:?}: {e}")))?;
    let count = field.plants.len();
    let ids = super::live::element_ids(ctx, usize::from(plants).min(count))?;
    let invalid = |e: StageError| BuildError::invalid(format!("field of take {take:?}: {e}"));
    let looped = looped_clip(&bytes).map_err(invalid)?;
    let report = Arc::new(FieldReport::damaged(take, count, &looped.damage));
    let stage = FieldStage::new(looped, field, ids, seed, ctx.now_ns, report.clone()).map_err(invalid)?;
    let elements = super::live::plant_elements(ids, "plant", ctx);
    Ok(BuiltStage {
        stage: Box::new(stage),
        info: StageInfo {
            kind: StageKind::Field,
            report,
            elements,
            hand_element: None,
            accepts: takes_keys,
            rig: super::live::rig_info(ctx.rig),
            work: super::budget::TickWork {
                asked_by: format!("a field publishing {} plants", ids.len()),
                unit: "plant frames",
                units: ids.len() as u64,
                unit_ns: super::budget::FIELD_PLANT_NS,
                extra_ns: 0,
                fix: "publish fewer plants".into(),
            },
        },
    })
}
