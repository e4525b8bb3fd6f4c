//! A field playing on the pose stream (seed 000, section 6.2): plants of one looped take, each
//! delayed by its position along the propagation direction; steered live by keys and wrist
//! swipes (section 6.3).
//!
//! The loop evaluates no plant. It publishes what defines the field (protocol 3,
//! [`frond_protocol::field`]): the definition once, with the element table ([`FieldReport`]
//! carries it to the control side), and at [`FIELD_PUBLISH_HZ`] one [`FieldFrame`] with the
//! stream time, the controls and frames of the driving stream, whose size does not depend on the
//! number of plants. Subscribers evaluate the plants with `frond_motion::field_eval`; the SDK
//! delivers the first plants (announced as `field-plant` elements, at most
//! [`MAX_ANNOUNCED_PLANTS`]) as poses, as version 2 published them.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

use frond_formats::field_json::FieldJson;
use frond_motion::controls::{ControlKey, FieldControls, SwipeDetector, SwipeParams};
use frond_motion::field::Field;
use frond_motion::field_eval::FieldState;
use frond_motion::field_player::FieldPlayer;
use frond_motion::field_wire::{FrameFiller, field_is_generated, layout_of};
use frond_motion::{HandSample, JOINTS, PoseFrame, Rig};
use frond_protocol::control::StageKind;
use frond_protocol::field::{FieldDefinition, FieldFrame, MAX_ANNOUNCED_PLANTS};
use frond_protocol::{ElementId, StageInput, StageKey};

use super::error::{BuildError, StageError};
use super::live::{BuildContext, BuiltStage, FrameSink, LiveStage, StageInfo, StageReport, TickContext};
use super::playback::{LoopedTake, looped_clip, note_damage};
use crate::clock::NS_PER_S;

/// Most field plants announced as `field-plant` elements (whose poses the SDK delivers).
pub const MAX_FIELD_PLANTS: usize = MAX_ANNOUNCED_PLANTS;
/// Most plants of a live field. The loop's work does not depend on it (it evaluates no plant);
/// it bounds the daemon's memory for the layout (about 70 bytes a plant) and what every
/// subscriber makes of the definition.
pub const MAX_LIVE_FIELD_PLANTS: usize = 100_000;
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

/// What `frond status` says of a field, and its definition for the element table.
pub struct FieldReport {
    /// The controls in force.
    pub controls: FieldControlsCell,
    take: String,
    plants: usize,
    /// What a damaged take lost, in words (empty for a sound take).
    damage: String,
    /// The plants' rig when it is not the active rig.
    rig: Option<String>,
    /// What subscribers evaluate the plants from.
    definition: Option<FieldDefinition>,
}

impl FieldReport {
    /// The report of a field of take `take` with `plants` plants (no controls yet).
    pub fn new(take: &str, plants: usize) -> Self {
        FieldReport {
            controls: FieldControlsCell::default(),
            take: take.to_string(),
            plants,
            damage: String::new(),
            rig: None,
            definition: None,
        }
    }

    /// The same, for a damaged take: `damage` says what the reader skipped.
    pub fn damaged(take: &str, plants: usize, damage: &Option<String>) -> Self {
        FieldReport { damage: note_damage(take, damage), ..Self::new(take, plants) }
    }

    /// The same, of plants of rig `rig` when it is not the active rig (status names it).
    pub fn of_rig(self, rig: Option<String>) -> Self {
        FieldReport { rig, ..self }
    }

    /// The same, publishing `definition` with the element table.
    pub fn with_definition(self, definition: FieldDefinition) -> Self {
        FieldReport { definition: Some(definition), ..self }
    }
}

impl StageReport for FieldReport {
    fn describe(&self) -> String {
        let controls = self.controls.load().map(|c| describe_controls(&c)).unwrap_or_default();
        let rig = self.rig.as_ref().map(|r| format!(" (rig {r})")).unwrap_or_default();
        format!("field of {}{}: {} plants{rig}; {controls}", self.take, self.damage, self.plants)
    }

    fn field(&self) -> Option<&FieldDefinition> {
        self.definition.as_ref()
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
    filler: FrameFiller,
    frame: FieldFrame,
    swipe: SwipeDetector,
    base_speed_m_s: f64,
    t0_ns: u64,
    next_ns: u64,
    report: Arc<FieldReport>,
}

impl FieldStage {
    /// `field` of a take made ready to loop ([`looped_clip`]), its frames published as field
    /// `id` ([`FieldDefinition::id`]) with `announced` plants announced as elements (at most
    /// [`MAX_FIELD_PLANTS`]: their poses' sequence numbers are each frame's).
    pub fn new(
        looped: LoopedTake,
        field: Field,
        id: ElementId,
        announced: usize,
        seed: u64,
        t0_ns: u64,
        report: Arc<FieldReport>,
    ) -> Result<Self, StageError> {
        let LoopedTake { clip, transitions, .. } = looped;
        if field.plants.is_empty() {
            return Err(StageError::EmptyField);
        }
        let controls = initial_controls(&field);
        let player = FieldPlayer::try_new(field, clip, &transitions, seed, controls)?;
        report.controls.store(controls);
        Ok(FieldStage {
            player,
            filler: FrameFiller::default(),
            frame: FieldFrame {
                field: id,
                poses: announced.min(MAX_FIELD_PLANTS) as u8,
                ..FieldFrame::default()
            },
            swipe: SwipeDetector::new(SwipeParams::default()),
            base_speed_m_s: controls.speed_m_s,
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

/// The controls a field starts with: its layout's heading as authored, its propagation speed.
pub fn initial_controls(field: &Field) -> FieldControls {
    FieldControls {
        direction_deg: field.authored_direction_deg,
        speed_m_s: field.speed_m_s.max(0.05),
        ..FieldControls::default()
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
        self.player.advance(t);
        self.filler.fill(self.player.state(), &mut self.frame);
        out.emit_field(&mut self.frame);
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

/// The rig of `rig_toml` (a rig file's text, at most [`frond_protocol::MAX_STAGE_RIG_BYTES`]) as a field's
/// plants ([`StageSpec::FieldOfRig`](frond_protocol::StageSpec::FieldOfRig)): valid, named
/// plainly, and, when it has the active rig's name, the active rig itself (the element table
/// and every subscriber know rigs by name).
pub fn field_rig(text: &str, ctx: &BuildContext) -> Result<Rig, BuildError> {
    let rig = super::live::rig_from_request(text, "the field's")?;
    if !super::registry::is_plain_name(&rig.name) {
        return Err(BuildError::invalid(format!(
            "the field's rig is named {:?}: a field's rig needs a name of 1 to 32 letters, digits, '-' or '_' \
             (subscribers draw it by name)",
            rig.name.chars().take(40).collect::<String>()
        )));
    }
    if rig.name == ctx.rig.name && rig.joint_names() != ctx.rig.joint_names() {
        return Err(BuildError::invalid(format!(
            "the field's rig {:?} differs from the active rig of that name: rename it (subscribers know rigs \
             by name)",
            rig.name
        )));
    }
    Ok(rig)
}

/// Builds a field of the looped take `take` (its layout from `field_json`, at most
/// [`MAX_LIVE_FIELD_PLANTS`] plants, made by its own parameters) whose plants are `rig`
/// ([`field_rig`]), announcing its first `plants` plants as `field-plant` elements.
pub fn build(
    take: &str,
    field_json: &str,
    plants: u16,
    seed: u64,
    rig: &Rig,
    ctx: &BuildContext,
) -> Result<BuiltStage, BuildError> {
    if !(1..=MAX_FIELD_PLANTS as u16).contains(&plants) {
        return Err(BuildError::invalid(format!(
            "a field announces 1..={MAX_FIELD_PLANTS} plants as elements, not {plants}"
        )));
    }
    let bytes = super::live::read_take(ctx.takes_dir, take)?;
    let field = Field::from_json(field_json)
        .map_err(|e| BuildError::invalid(format!("field of take {take:?}: {e}")))?;
    let count = field.plants.len();
    if count == 0 || count > MAX_LIVE_FIELD_PLANTS {
        return Err(BuildError::invalid(format!(
            "field of take {take:?}: a live field has 1..={MAX_LIVE_FIELD_PLANTS} plants, this one {count}"
        )));
    }
    // Subscribers make the plants from the layout's parameters: a layout they would not make
    // alike (a hand-edited field.json) cannot be published as one.
    if !field_is_generated(&field) {
        return Err(BuildError::invalid(format!(
            "field of take {take:?}: its plants are not what its rows, cols, cell_m, speed_m_s, direction_deg, \
             density and seed make (edited by hand?); make it again with `frond take field`"
        )));
    }
    let ids = super::live::element_ids(ctx, usize::from(plants).min(count))?;
    let invalid = |e: StageError| BuildError::invalid(format!("field of take {take:?}: {e}"));
    let looped = looped_clip(&bytes).map_err(invalid)?;
    // Every rig has JOINTS joints, the take's frames too: a header listing another number is
    // not a take of any rig this field can play (one made offline may list none).
    let joints = looped.joint_names.len();
    if joints != 0 && joints != JOINTS {
        return Err(BuildError::invalid(format!(
            "take {take:?} names {joints} joints ({}); rig {:?} has {JOINTS} ({})",
            looped.joint_names.join(", "),
            rig.name,
            rig.joint_names().join(", ")
        )));
    }
    let fps = looped.clip.fps;
    let definition = FieldDefinition {
        id: ids[0],
        source: ctx.name.to_string(),
        rig: rig.name.clone(),
        layout: layout_of(&field),
        plants: count as u32,
        stream_fps: fps,
        history_frames: FieldState::history_frames_for(&field, fps) as u32,
        publish_hz: FIELD_PUBLISH_HZ,
        plant_elements: ids.to_vec(),
    };
    definition.check().map_err(|e| BuildError::invalid(format!("field of take {take:?}: {e}")))?;
    let report = Arc::new(
        FieldReport::damaged(take, count, &looped.damage)
            .of_rig((rig.name != ctx.rig.name).then(|| rig.name.clone()))
            .with_definition(definition),
    );
    let stage = FieldStage::new(looped, field, ids[0], ids.len(), seed, ctx.now_ns, report.clone())
        .map_err(invalid)?;
    let elements = super::live::plant_elements(ids, "plant", &rig.name, ctx);
    Ok(BuiltStage {
        stage: Box::new(stage),
        info: StageInfo {
            kind: StageKind::Field,
            report,
            elements,
            hand_element: None,
            accepts: takes_keys,
            rig: super::live::rig_info(rig),
            work: super::budget::TickWork {
                asked_by: format!("a field of {count} plants"),
                unit: "field frames",
                units: 1,
                unit_ns: super::budget::SMALL_NS,
                extra_ns: 0,
                fix: "run fewer stages".into(),
            },
        },
    })
}

#[cfg(test)]
mod tests {
    use frond_formats::rig_toml::RigText;
    use frond_motion::clip::{Clip, Joints};
    use frond_motion::field::{FieldParams, make_field};
    use frond_motion::field_eval::FieldState;
    use frond_motion::field_wire::apply_frame;
    use frond_motion::looping::{LoopParams, find_transitions};
    use frond_protocol::MAX_STAGE_RIG_BYTES;

    use super::*;

    /// Keeps the field frames a stage emits; a stage's poses would be a failure here.
    #[derive(Default)]
    struct Frames(Vec<FieldFrame>);

    impl FrameSink for Frames {
        fn emit(&mut self, element: ElementId, _joints_deg: Joints) {
            panic!("a field publishes no pose per plant (got one for element {element})");
        }
        fn emit_field(&mut self, frame: &mut FieldFrame) {
            self.0.push(*frame);
        }
    }

    #[test]
    fn the_stage_publishes_frames_a_subscriber_evaluates_as_the_stage_does() {
        let clip = Clip::from_joints(
            (0..90).map(|k| {
                let s = (k as f32 * 0.2).sin() * 15.0;
                [[s, -s, 0.0], [s, 0.5 * s, 1.0], [0.0, s, 0.0], [2.0, s, -s]]
            }),
            30.0,
        );
        let transitions = find_transitions(&clip, &LoopParams::default()).unwrap();
        let p = FieldParams {
            rows: 6,
            cols: 7,
            cell_m: 0.3,
            speed_m_s: 1.0,
            direction_deg: 0.0,
            density: 1.0,
            seed: 2,
        };
        let field = make_field(&p, "t", 90, 30.0).unwrap();
        let report = Arc::new(FieldReport::new("t", field.plants.len()));
        let looped = LoopedTake { clip, transitions, damage: None, joint_names: Vec::new() };
        let id = ElementId::new(40);
        let mut stage = FieldStage::new(looped, field.clone(), id, 3, 4, 0, report.clone()).unwrap();
        let history = FieldState::history_frames_for(&field, 30.0);
        let mut sub = FieldState::new(field, 30.0, FieldControls::default(), history);
        let mut sink = Frames::default();
        // 1 kHz ticks for 3 s, a key after 1 s: 60 field frames a second, whatever the plants.
        for ms in 0..3000u64 {
            if ms == 1000 {
                stage.input(StageInput::Key(StageKey::Left));
            }
            let ctx = TickContext {
                now_ns: ms * 1_000_000,
                device_time_us: ms * 1000,
                hand: HandSample::default(),
            };
            stage.tick(&ctx, &mut sink);
        }
        assert!((179..=181).contains(&sink.0.len()), "{} field frames in 3 s", sink.0.len());
        assert!(sink.0.iter().all(|f| f.field == id && f.poses == 3));
        assert_eq!(sink.0.last().unwrap().controls.direction_deg, 180.0, "the key reached the frames");
        for f in &sink.0 {
            assert!(apply_frame(&mut sub, f));
        }
        // The subscriber, fed only the frames, evaluates every plant as the stage's own player.
        let mut own = stage.player.state().clone();
        own.refresh_delays();
        let mut want = vec![[[0.0f32; 3]; 4]; sub.field().plants.len()];
        own.plants(&mut want);
        assert_eq!(own.tau_s(), sub.tau_s());
        assert!(sub.history().is_complete());
        for (i, w) in want.iter().enumerate() {
            let got = sub.plant(i).expect("every frame it needs arrived");
            for (g, w) in got.iter().flatten().zip(w.iter().flatten()) {
                assert!((g - w).abs() < 1e-4, "plant {i}: {got:?} vs {w:?}");
            }
        }
    }

    const GRASS: &str = include_str!("../../../../rig-files/plants/grass.toml");
    const FLOWER: &str = include_str!("../../../../rig-files/plants/flower.toml");

    /// A take `name` in `dir` of 3 s of swaying at 30 FPS, its header listing `joints`.
    fn write_take(dir: &std::path::Path, name: &str, joints: &[&str]) {
        use frond_formats::layers::TakeBytes;
        use frond_motion::layers::Take;
        use frond_motion::take::{TakeFrame, TakeHeader};
        let header = TakeHeader {
            name: name.into(),
            rig_name: "grass".into(),
            calibration_id: "none".into(),
            filter: "none".into(),
            tick_rate_hz: 30,
            created_unix_s: 0,
            daemon_version: "test".into(),
            joint_names: joints.iter().map(|j| j.to_string()).collect(),
            clock: None,
            stage: None,
            stage_clock: None,
        };
        let mut take = Take::new(header);
        for k in 0..90u64 {
            let s = (k as f32 * 0.2).sin() * 15.0;
            take.frames.push(TakeFrame {
                seq: k,
                device_time_us: k * 33_333,
                host_ns: k * 33_333_333,
                flags: 0,
                element: ElementId::GLOBAL,
                pose: PoseFrame {
                    t: k as f64 / 30.0,
                    joints_deg: [[s, -s, 0.0], [s, 0.5 * s, 1.0], [0.0, s, 0.0], [2.0, s, -s]],
                },
                hand: HandSample::default(),
            });
        }
        std::fs::write(dir.join(format!("{name}.take")), take.to_bytes()).unwrap();
    }

    fn field_json() -> String {
        let p = FieldParams {
            rows: 3,
            cols: 4,
            cell_m: 0.3,
            speed_m_s: 1.0,
            direction_deg: 0.0,
            density: 1.0,
            seed: 2,
        };
        make_field(&p, "t", 90, 30.0).unwrap().to_json()
    }

    /// Builds `spec` with the grass as the active rig and takes from `dir`.
    fn build_in(dir: &std::path::Path, spec: &frond_protocol::StageSpec) -> Result<BuiltStage, BuildError> {
        let rig = Rig::from_toml_str(GRASS).unwrap();
        let ids: Vec<ElementId> = (33..40).map(ElementId::new).collect();
        let ctx = BuildContext {
            takes_dir: dir,
            rig: &rig,
            g3_range_deg: 60.0,
            tick_rate_hz: 1000,
            now_ns: 0,
            free_ids: &ids,
            name: "flowers",
        };
        super::super::build(spec, &ctx)
    }

    fn of_rig(take: &str, rig_toml: &str) -> frond_protocol::StageSpec {
        frond_protocol::StageSpec::FieldOfRig {
            take: take.into(),
            field_json: field_json(),
            plants: 2,
            seed: 1,
            rig_toml: rig_toml.into(),
        }
    }

    #[test]
    fn a_field_of_another_rig_names_that_rig_everywhere_a_subscriber_looks() {
        let dir = tempfile::tempdir().unwrap();
        write_take(dir.path(), "t", &["root", "lower", "middle", "top"]);
        let built = build_in(dir.path(), &of_rig("t", FLOWER)).unwrap();
        let def = built.info.report.field().unwrap();
        assert_eq!((def.rig.as_str(), def.source.as_str(), def.plants), ("flower", "flowers", 12));
        assert_eq!(built.info.rig.name, "flower", "the element table lists the flower");
        assert_eq!(built.info.rig.joint_names.len(), 4);
        assert!(built.info.elements.iter().all(|e| e.rig == "flower"), "{:?}", built.info.elements);
        assert!(built.info.report.describe().contains("(rig flower)"), "{}", built.info.report.describe());
        // Without a rig: the active one, as before.
        let spec = frond_protocol::StageSpec::Field {
            take: "t".into(),
            field_json: field_json(),
            plants: 2,
            seed: 1,
        };
        let built = build_in(dir.path(), &spec).unwrap();
        assert_eq!(built.info.report.field().unwrap().rig, "grass");
        assert!(built.info.elements.iter().all(|e| e.rig == "grass"));
    }

    #[test]
    fn a_rig_a_field_cannot_play_is_refused_saying_why() {
        let dir = tempfile::tempdir().unwrap();
        write_take(dir.path(), "t", &["root", "lower", "middle", "top"]);
        write_take(dir.path(), "three", &["root", "middle", "top"]);
        let unnamed = FLOWER.replacen("name = \"flower\"", "name = \"a flower\"", 1);
        assert!(unnamed.contains("name = \"a flower\""));
        let renamed_grass = FLOWER.replacen("name = \"flower\"", "name = \"grass\"", 1);
        assert!(renamed_grass.contains("name = \"grass\""));
        let huge = format!("{FLOWER}\n# {}\n", "x".repeat(MAX_STAGE_RIG_BYTES));
        for (take, rig, want) in [
            ("three", FLOWER, "take \"three\" names 3 joints (root, middle, top); rig \"flower\" has 4"),
            ("t", "name = [", "the field's rig: TOML parse error"),
            (
                "t",
                unnamed.as_str(),
                "the field's rig is named \"a flower\": a field's rig needs a name of 1 to 32",
            ),
            ("t", renamed_grass.as_str(), "differs from the active rig of that name"),
            ("t", huge.as_str(), "bytes of text; a rig file is at most 65536"),
        ] {
            let e = build_in(dir.path(), &of_rig(take, rig)).err().unwrap_or_else(|| panic!("{want}: built"));
            assert_eq!(e.kind, frond_protocol::ControlErrorKind::Invalid, "{want}");
            assert!(e.message.contains(want), "{want}: {}", e.message);
        }
        // The active rig's own text is the active rig: played. A take made offline names no
        // joints: played on any rig.
        assert!(build_in(dir.path(), &of_rig("t", GRASS)).is_ok());
        write_take(dir.path(), "offline", &[]);
        assert!(build_in(dir.path(), &of_rig("offline", FLOWER)).is_ok());
    }
}
