//! A take looping on the pose stream as the plant's global element, flagged `playback` (seed 000,
//! section 5.3: the global animation plays while secondary layers are authored).

use std::sync::Arc;

use frond_formats::layers::TakeBytes;
use frond_motion::clip::Clip;
use frond_motion::layers::Take;
use frond_motion::looping::{LoopParams, Playback, PlaybackParams, Transitions, find_transitions};
use frond_motion::take::resample_plan;
use frond_protocol::control::StageKind;
use frond_protocol::{ElementId, ElementInfo, ElementKind};

use super::error::{BuildError, StageError};
use super::live::{
    BuildContext, BuiltStage, FixedReport, FrameSink, LiveStage, StageInfo, TickContext, no_input,
};
use crate::clock::NS_PER_S;

/// Frame rate takes are looped at (seed 000 records at 30 FPS).
pub const LOOP_FPS: f64 = 30.0;

/// Most frames a looped take may have at [`LOOP_FPS`]: 10 hours, the export budget of `frond
/// take export` (about 50 MB of clip). Counted before the take is resampled.
pub const MAX_LOOP_FRAMES: u64 = 1_080_000;

/// A take made ready to loop.
pub struct LoopedTake {
    /// Its global layer at [`LOOP_FPS`].
    pub clip: Clip,
    /// Its loop transitions (seed 000, Eq. 5).
    pub transitions: Transitions,
    /// What the reader skipped in a damaged take, in words; `None` when it is sound.
    pub damage: Option<String>,
    /// The joint names its header lists (the rig it was recorded with), root first.
    pub joint_names: Vec<String>,
}

/// The global layer of `take_bytes` as a 30 FPS clip with its loop transitions (seed 000, Eq. 5).
/// A damaged take loops its readable frames, saying what was skipped; one longer than
/// [`MAX_LOOP_FRAMES`] is refused before it is resampled.
pub fn looped_clip(take_bytes: &[u8]) -> Result<LoopedTake, StageError> {
    let (take, damage) = Take::from_bytes_noting_damage(take_bytes)?;
    let poses: Vec<_> = take.layer(ElementId::GLOBAL, false).iter().map(|f| f.pose).collect();
    let plan = resample_plan(&poses, LOOP_FPS);
    plan.check(LOOP_FPS, MAX_LOOP_FRAMES).map_err(StageError::TooLongToLoop)?;
    let clip = Clip::from_poses(&poses, LOOP_FPS);
    if clip.len() < 8 {
        return Err(StageError::TooShortToLoop { frames: clip.len() });
    }
    // Small takes get a smaller comparison window so Eq. 5 still finds candidates.
    let mut params = LoopParams::default();
    params.window = params.window.min((clip.len() - 2) / 4);
    let transitions = find_transitions(&clip, &params)?;
    Ok(LoopedTake { clip, transitions, damage, joint_names: take.header.joint_names.clone() })
}

/// The words a stage's report adds for a damaged take, logged once when the stage is built.
pub fn note_damage(take: &str, damage: &Option<String>) -> String {
    match damage {
        Some(d) => {
            tracing::warn!(take, damage = %d, "the take is damaged; looping its readable frames");
            format!(" (damaged: {d}; looping the readable frames)")
        }
        None => String::new(),
    }
}

/// The looping take.
pub struct PlaybackStage {
    playback: Playback,
    t0_ns: u64,
    element: ElementId,
}

impl PlaybackStage {
    /// Loops a take made ready to loop ([`looped_clip`]) from host time `t0_ns`, published as
    /// `element`.
    pub fn new(looped: LoopedTake, seed: u64, t0_ns: u64, element: ElementId) -> Self {
        let playback = Playback::new(looped.clip, &looped.transitions, seed, PlaybackParams::default(), 0);
        PlaybackStage { playback, t0_ns, element }
    }
}

impl LiveStage for PlaybackStage {
    fn tick(&mut self, ctx: &TickContext, out: &mut dyn FrameSink) {
        let t = ctx.now_ns.saturating_sub(self.t0_ns) as f64 / NS_PER_S as f64;
        out.emit(self.element, self.playback.pose_at(t));
    }

    fn every_tick(&self) -> bool {
        true
    }
}

/// Builds the playback of take `take` as the global element (id 0).
pub fn build(take: &str, seed: u64, ctx: &BuildContext) -> Result<BuiltStage, BuildError> {
    let bytes = super::live::read_take(ctx.takes_dir, take)?;
    let looped = looped_clip(&bytes).map_err(|e| BuildError::invalid(format!("take {take:?}: {e}")))?;
    let damage = note_damage(take, &looped.damage);
    let stage = PlaybackStage::new(looped, seed, ctx.now_ns, ElementId::GLOBAL);
    Ok(BuiltStage {
        stage: Box::new(stage),
        info: StageInfo {
            kind: StageKind::Playback,
            report: Arc::new(FixedReport(format!("looping take {take} as the global element{damage}"))),
            elements: vec![ElementInfo {
                id: ElementId::GLOBAL,
                name: take.to_string(),
                kind: ElementKind::Playback,
                source: ctx.name.to_string(),
                rig: ctx.rig.name.clone(),
            }],
            hand_element: None,
            accepts: no_input,
            rig: super::live::rig_info(ctx.rig),
            work: super::budget::TickWork::small("looped take frames"),
        },
    })
}
