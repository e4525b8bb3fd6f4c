//! Live stages: anything that produces poses in the realtime loop besides the plain hand mapping.
//!
//! A stage may transform the hand's pose and the element it is published as ([`LiveStage::on_hand`]:
//! guided motion, seed 000 Eq. 8; layer recording, section 5.3) or publish elements of its own
//! every tick ([`LiveStage::tick`]: a looped take, the plants of a field). It takes typed inputs
//! while it runs ([`LiveStage::input`]: field keys) and reports what it is doing through a
//! lock-free cell of its own ([`StageReport`]), which `frond status` reads.
//!
//! Stages are built off the realtime thread by [`build`] from a protocol [`StageSpec`] (they may
//! allocate and read files there), moved into one of the loop's [`MAX_STAGES`] preallocated
//! slots with one [`StageCommand`], and handed back to housekeeping to be dropped. In the loop
//! they only call allocation-free, lock-free, non-blocking methods.
//!
//! Adding a motion source: one file here implementing [`LiveStage`] with a `build` function,
//! one [`StageSpec`] variant (and its arm in [`build`]), one `frond` subcommand.

pub mod budget;
pub mod error;
pub mod field;
pub mod graph;
pub mod guided;
pub mod layer;
pub mod live;
pub mod playback;
pub mod registry;
pub mod sim;

use frond_protocol::StageSpec;

pub use error::{BuildError, MAX_STAGE_NAME, MAX_STAGES};
pub use live::{
    BuildContext, BuiltStage, FixedReport, FrameSink, LiveStage, MAX_STAGE_TAKE_BYTES, StageAction,
    StageCommand, StageInfo, StageReport, TickContext, element_ids, no_input, plant_elements, read_take,
    rig_info,
};

/// Builds the stage `spec` describes (off the realtime thread).
/// Every stage's declared work per tick ([`StageInfo::work`]) must fit in its share of the tick
/// ([`budget::TickWork::check`]): a stage asking for more is refused with the reason.
pub fn build(spec: &StageSpec, ctx: &BuildContext) -> Result<BuiltStage, BuildError> {
    let built = build_any(spec, ctx)?;
    built.info.work.check(ctx.tick_rate_hz)?;
    Ok(built)
}

fn build_any(spec: &StageSpec, ctx: &BuildContext) -> Result<BuiltStage, BuildError> {
    match spec {
        StageSpec::Playback { take, seed } => playback::build(take, *seed, ctx),
        StageSpec::Field { take, field_json, plants, seed } => {
            field::build(take, field_json, *plants, *seed, ctx)
        }
        StageSpec::Guided { spec } => guided::build(spec, ctx),
        StageSpec::Graph { sources, plants, seed } => graph::build(sources, *plants, *seed, ctx),
        StageSpec::Sim { rig_toml, wind } => sim::build(rig_toml.as_deref(), wind, ctx),
    }
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
