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
//! Adding a live stage: one file here implementing [`LiveStage`] with a `build` function, one
//! [`StageSpec`] and one `StageKind` variant (the compiler then asks for the arm in [`build`]),
//! one `frond` subcommand; the recipe is in ARCHITECTURE.md, "Adding a live stage".

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
            field::build(take, field_json, *plants, *seed, ctx.rig, ctx)
        }
        StageSpec::FieldOfRig { take, field_json, plants, seed, rig_toml } => {
            let rig = field::field_rig(rig_toml, ctx)?;
            field::build(take, field_json, *plants, *seed, &rig, ctx)
        }
        StageSpec::Guided { spec } => guided::build(spec, ctx),
        StageSpec::Graph { sources, plants, seed } => graph::build(sources, *plants, *seed, ctx),
        StageSpec::Sim { rig_toml, wind } => sim::build(rig_toml.as_deref(), wind, ctx),
    }
}
