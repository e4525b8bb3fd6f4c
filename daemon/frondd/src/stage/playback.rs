//! A take looping on the pose stream as the plant's global element, flagged `playback` (seed 000,
//! section 5.3: the global animation plays while secondary layers are authored).

use std::sync::Arc;

use frond_motion::clip::Clip;
use frond_motion::layers::Take;
use frond_motion::looping::{LoopParams, Playback, PlaybackParams, Transitions, find_transitions};
use frond_protocol::{ElementInfo, ElementKind};

use super::error::StageError;
use super::{
    BuildContext, BuildError, BuiltStage, FixedReport, FrameSink, LiveStage, StageInfo, TickContext, no_input,
};
use crate::clock::NS_PER_S;

/// Frame rate takes are looped at (seed 000 records at 30 FPS).
pub const LOOP_FPS: f64 = 30.0;

/// The global layer of `take_bytes` as a 30 FPS clip with its loop transitions (seed 000, Eq. 5).
pub fn looped_clip(take_bytes: &[u8]) -> Result<(Clip, Transitions), StageError> {
    let take = Take::from_bytes(take_bytes)?;
    let clip = take.clip(0, LOOP_FPS);
    if clip.len() < 8 {
        return Err(StageError::TooShortToLoop { frames: clip.len() });
    }
    // Small takes get a smaller comparison window so Eq. 5 still finds candidates.
    let mut params = LoopParams::default();
    params.window = params.window.min((clip.len() - 2) / 4);
    let transitions = find_transitions(&clip, &params)?;
    Ok((clip, transitions))
}

/// The looping take.
pub struct PlaybackStage {
    playback: Playback,
    t0_ns: u64,
    element: u16,
}

impl PlaybackStage {
    /// Loops the global layer of `take_bytes` from host time `t0_ns`, published as `element`.
    pub fn new(take_bytes: &[u8], seed: u64, t0_ns: u64, element: u16) -> Result<Self, StageError> {
        let (clip, transitions) = looped_clip(take_bytes)?;
        let playback = Playback::new(clip, &transitions, seed, PlaybackParams::default(), 0);
        Ok(PlaybackStage { playback, t0_ns, element })
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
    let bytes = super::read_take(ctx.takes_dir, take)?;
    let stage = PlaybackStage::new(&bytes, seed, ctx.now_ns, 0)
        .map_err(|e| BuildError::invalid(format!("take {take:?}: {e}")))?;
    Ok(BuiltStage {
        stage: Box::new(stage),
        info: StageInfo {
            kind: "playback",
            report: Arc::new(FixedReport(format!("looping take {take} as the global element"))),
            elements: vec![ElementInfo {
                id: 0,
                name: take.to_string(),
                kind: ElementKind::Playback,
                source: ctx.name.to_string(),
                rig: ctx.rig.name.clone(),
            }],
            hand_element: None,
            accepts: no_input,
            rig: super::rig_info(ctx.rig),
        },
    })
}
