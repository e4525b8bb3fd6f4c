//! What every live stage is and what the loop and the control side know of one: the
//! [`LiveStage`] trait the loop calls, the [`StageInfo`] the control side keeps, what building
//! one may look at ([`BuildContext`]) and the [`StageCommand`] that installs it; with the helpers
//! every stage's `build` shares (its elements, its rig, its take file). Each stage's file and
//! the registry use this module, and `stage::build` uses them.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use frond_formats::rig_toml::RigText;
use frond_motion::clip::Joints;
use frond_motion::{HandSample, PoseFrame, Rig};
use frond_protocol::control::StageKind;
use frond_protocol::{ControlErrorKind, ElementId, ElementInfo, RigInfo, StageInput};

use super::budget;
use super::error::BuildError;

/// What a stage sees at each tick.
#[derive(Debug, Clone, Copy)]
pub struct TickContext {
    /// Host monotonic time of the tick, nanoseconds.
    pub now_ns: u64,
    /// Device time of the latest hand report, microseconds.
    pub device_time_us: u64,
    /// The latest calibrated hand sample.
    pub hand: HandSample,
}

/// Where a stage puts the frames it publishes.
pub trait FrameSink {
    /// Publishes `joints_deg` as element `element` (flagged `playback`).
    fn emit(&mut self, element: ElementId, joints_deg: Joints);
    /// Publishes a field frame (protocol 3): the sink numbers and stamps it. A sink that only
    /// counts poses (a test's) ignores it.
    fn emit_field(&mut self, _frame: &mut frond_protocol::field::FieldFrame) {}
}

/// Anything that produces poses in the realtime loop. Every method runs on the loop thread and
/// must not allocate, lock, log or block.
pub trait LiveStage: Send {
    /// Called for every hand report after mapping, in slot order: may change the hand's pose and
    /// the element it is published and recorded as.
    fn on_hand(&mut self, _hand: &HandSample, _pose: &mut PoseFrame, _element: &mut ElementId) {}
    /// The element the hand is published as while this stage runs, if it changes it (a layer):
    /// also what the loop stamps on held frames.
    fn hand_element(&self) -> Option<ElementId> {
        None
    }
    /// Called once per tick, before the device is read: publishes the stage's own elements.
    fn tick(&mut self, _ctx: &TickContext, _out: &mut dyn FrameSink) {}
    /// Whether [`LiveStage::tick`] has work at every tick (the loop then never skips one).
    fn every_tick(&self) -> bool {
        false
    }
    /// A typed input while it runs. Inputs a stage does not take are ignored (the control side
    /// refuses them before they get here).
    fn input(&mut self, _input: StageInput) {}
}

/// A stage's status, read by `frond status` from any thread while the loop writes it.
pub trait StageReport: Send + Sync {
    /// One line: what the stage is doing.
    fn describe(&self) -> String;
    /// Work dropped to stay within its budget since it started ([`budget`]): 0 while it keeps up.
    fn dropped_work(&self) -> u64 {
        0
    }
    /// The definition of the field the stage plays, if it plays one: the control side publishes
    /// it with the element table (protocol 3, [`frond_protocol::field`]).
    fn field(&self) -> Option<&frond_protocol::field::FieldDefinition> {
        None
    }
}

/// A report that never changes.
pub struct FixedReport(pub String);

impl StageReport for FixedReport {
    fn describe(&self) -> String {
        self.0.clone()
    }
}

/// A stage ready to go into the loop, with what the control side keeps of it.
pub struct BuiltStage {
    /// The stage itself, for the loop.
    pub stage: Box<dyn LiveStage>,
    /// What the control side keeps.
    pub info: StageInfo,
}

/// What the control side knows of a stage: its kind, status cell, elements and inputs.
#[derive(Clone)]
pub struct StageInfo {
    /// Its kind.
    pub kind: StageKind,
    /// Its status cell.
    pub report: Arc<dyn StageReport>,
    /// Elements it publishes itself.
    pub elements: Vec<ElementInfo>,
    /// The element the hand is published as while it runs (a layer), if it changes it.
    pub hand_element: Option<ElementInfo>,
    /// Which [`StageInput`]s it takes, for the control side to refuse the others by name.
    pub accepts: fn(&StageInput) -> bool,
    /// The skeleton its elements use (the rig in force when it was built, or the rig it plays:
    /// a field of another rig's plants, the simulated plant of its own rig).
    pub rig: RigInfo,
    /// The most work it does in one tick ([`budget`]: checked by `stage::build` against its share).
    pub work: budget::TickWork,
}

impl StageInfo {
    /// Every element id it publishes or puts the hand on.
    pub fn element_ids(&self) -> impl Iterator<Item = ElementId> + '_ {
        self.elements.iter().chain(&self.hand_element).map(|e| e.id)
    }
}

/// A rig a stage request carries as a rig file's text (`whose` names it in errors: "the
/// field's"): at most [`frond_protocol::MAX_STAGE_RIG_BYTES`], measured before it is parsed,
/// and a valid rig.
pub fn rig_from_request(text: &str, whose: &str) -> Result<Rig, BuildError> {
    let max = frond_protocol::MAX_STAGE_RIG_BYTES;
    if text.len() > max {
        return Err(BuildError::invalid(format!(
            "{whose} rig is {} bytes of text; a rig file is at most {max}",
            text.len()
        )));
    }
    // The rig's errors start with "rig: ".
    Rig::from_toml_str(text).map_err(|e| BuildError::invalid(format!("{whose} {e}")))
}

/// A rig as the element table describes it.
pub fn rig_info(rig: &Rig) -> RigInfo {
    RigInfo { name: rig.name.clone(), joint_names: rig.joints.iter().map(|j| j.name.clone()).collect() }
}

/// The first `count` element ids no running stage uses, or a refusal saying how many are free.
pub fn element_ids<'a>(ctx: &BuildContext<'a>, count: usize) -> Result<&'a [ElementId], BuildError> {
    ctx.free_ids.get(..count).ok_or_else(|| {
        BuildError::invalid(format!("no room for {count} more elements ({} free)", ctx.free_ids.len()))
    })
}

/// The announced `field-plant` elements `PREFIX0`, `PREFIX1`, ... of a group of plants of `rig`
/// (a field's, a graph walk's), one per id.
pub fn plant_elements(ids: &[ElementId], prefix: &str, rig: &str, ctx: &BuildContext) -> Vec<ElementInfo> {
    ids.iter()
        .enumerate()
        .map(|(i, &id)| ElementInfo {
            id,
            name: format!("{prefix}{i}"),
            kind: frond_protocol::ElementKind::FieldPlant,
            source: ctx.name.to_string(),
            rig: rig.to_string(),
        })
        .collect()
}

/// Takes no input.
pub fn no_input(_: &StageInput) -> bool {
    false
}

/// What building a stage may look at.
pub struct BuildContext<'a> {
    /// Where takes are.
    pub takes_dir: &'a Path,
    /// The active rig.
    pub rig: &'a Rig,
    /// The active calibration's `G_R3` (guided motion normalises `G_3` by it).
    pub g3_range_deg: f32,
    /// The loop's rate.
    pub tick_rate_hz: u32,
    /// Host time now (the stage's start).
    pub now_ns: u64,
    /// Element ids no running stage uses (other than the one being replaced), lowest first.
    pub free_ids: &'a [ElementId],
    /// The stage's name.
    pub name: &'a str,
}

/// What a [`StageCommand`] does to its slot.
pub enum StageAction {
    /// Put this stage in the slot (`None` empties it). After the loop applied it, holds the
    /// stage that was there, to be dropped off the loop.
    Install(Option<Box<dyn LiveStage>>),
    /// Give the slot's stage an input.
    Input(StageInput),
    /// Only announce a new element table.
    Announce,
}

/// One change to the loop's stages, applied between two frames.
pub struct StageCommand {
    /// The slot (`< MAX_STAGES`).
    pub slot: usize,
    /// What to do.
    pub action: StageAction,
    /// A new element table, encoded as a frame, to send to every subscriber before the next
    /// frame. The loop keeps it for new subscribers whose Hello carries an older one, and
    /// returns the one it replaces here.
    pub elements_frame: Option<Vec<u8>>,
    /// The version of that table.
    pub elements_version: u64,
    /// Set by the loop once applied (the control side answers only then).
    pub applied: Arc<AtomicBool>,
}

/// Largest take file a live stage reads, bytes (about 4 million frames; the clip it loops is
/// bounded further by `playback::MAX_LOOP_FRAMES`).
pub const MAX_STAGE_TAKE_BYTES: u64 = 512 << 20;

/// Reads a take file from the takes directory (its name validated first): a regular file of at
/// most [`MAX_STAGE_TAKE_BYTES`], so a FIFO or a device put there cannot block or exhaust the
/// control thread.
pub fn read_take(takes_dir: &Path, name: &str) -> Result<Vec<u8>, BuildError> {
    frond_protocol::paths::validate_take_name(name)
        .map_err(|e| BuildError { kind: ControlErrorKind::BadName, message: e.to_string() })?;
    let path = takes_dir.join(format!("{name}.take"));
    frond_formats::rig_files::read_small_file(&path, MAX_STAGE_TAKE_BYTES).map_err(|e| {
        BuildError::invalid(format!("cannot read take {name:?} at {}: {}", path.display(), e.reason()))
    })
}
