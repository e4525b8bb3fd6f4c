//! Control requests for live stages (seed 000, sections 5.3, 6.2-6.4) and the one path by which a
//! rig, calibration and filter come into force (start-up, SIGHUP and `SetRig` alike).
//!
//! Stages are built here, off the realtime thread, from their [`StageSpec`], installed into the
//! loop with one [`StageCommand`] that also carries the new element table, and answered only once
//! the loop has applied them, so a status read right after the reply shows the new state.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Acquire};
use std::time::{Duration, Instant};

use frond_protocol::control::StageKind;
use frond_protocol::field::{FieldMessage, FieldTable};
use frond_protocol::{
    ControlErrorKind, ControlReply, ElementId, ElementTable, ServerMessage, StageInput, StageSpec,
    encode_frame,
};
use tracing::info;

use crate::clock::monotonic_ns;
use crate::control_state::{ControlContext, DaemonState, Setup, refuse};
use crate::handoff::{ELEMENTS_FRAME_MAX, LoopCommand};
use crate::stage::registry::{HandElement, Running, validate_stage_name};
use crate::stage::{self, BuildContext, BuiltStage, StageAction, StageCommand};

/// Stage name of a layer being recorded.
const LAYER_STAGE: &str = StageKind::Layer.as_str();
/// Stage name of the guided motion a rig's `[guided]` table starts.
const GUIDED_STAGE: &str = StageKind::Guided.as_str();
/// Stage name of the playback `frond record layer --over TAKE` starts under the layer.
const PLAYBACK_STAGE: &str = StageKind::Playback.as_str();
/// How long a control request waits for the loop to apply a stage change.
const APPLY_TIMEOUT: Duration = Duration::from_secs(1);

impl ControlContext {
    /// Puts `setup` in force: mapping, calibration and filter in the loop; when a rig is applied
    /// (`rig_applied`: start-up, SIGHUP, `SetRig`), the rig's own `[guided]` table replaces the
    /// guided-motion stage and the element table is announced again. The one path for start-up,
    /// SIGHUP, `SetRig`, `SetCalibration` and `SetFilter`; `state` is left unchanged when the
    /// loop refuses the first change.
    pub(crate) fn apply_setup(
        &self,
        state: &mut DaemonState,
        setup: Setup,
        rig_applied: bool,
    ) -> Result<(), ControlReply> {
        let Setup { rig, calibration, filter } = setup;
        let rig_changed = rig_applied || rig != state.rig;
        // Hands that follow the daemon's rig and drive one of its layers: the new rig must have
        // that layer (checked before anything changes), and its id may move.
        let mut moved: Vec<(usize, ElementId)> = Vec::new();
        if rig_changed {
            for (i, hand) in state.hands.iter().enumerate().filter(|(_, h)| h.own.is_none()) {
                let Some(layer) = &hand.layer else { continue };
                let id = stage::layer::layer_id(&rig, layer).map_err(|e| {
                    refuse(
                        ControlErrorKind::Invalid,
                        format!("hand {:?} drives layer {layer:?}: {e}", hand.name),
                    )
                })?;
                if id != hand.element {
                    moved.push((i, id));
                }
            }
        }
        if rig_changed {
            self.send_loop(LoopCommand::SetMapping(rig.mapping())).map_err(|r| *r)?;
        }
        if rig_changed || calibration != state.calibration {
            self.send_loop(LoopCommand::SetCalibration(calibration.params())).map_err(|r| *r)?;
        }
        if rig_changed || filter != state.filter {
            self.send_loop(LoopCommand::SetFilter(filter)).map_err(|r| *r)?;
        }
        for &(hand, element) in &moved {
            self.send_loop(LoopCommand::SetHandElement { hand, element }).map_err(|r| *r)?;
            state.hands[hand].element = element;
        }
        state.rig = rig;
        state.calibration = calibration;
        state.filter = filter;
        if rig_changed {
            let now_ns = monotonic_ns();
            let guided = {
                let free = state.stages.free_ids(0);
                let ctx = self.build_context(state, GUIDED_STAGE, &free, now_ns);
                stage::guided::from_rig(&ctx)
            };
            if guided.is_some() || state.stages.slot_of(GUIDED_STAGE).is_some() {
                self.install(state, GUIDED_STAGE, guided)?;
            } else {
                self.announce(state)?;
            }
        }
        Ok(())
    }

    fn build_context<'a>(
        &'a self,
        state: &'a DaemonState,
        name: &'a str,
        free_ids: &'a [ElementId],
        now_ns: u64,
    ) -> BuildContext<'a> {
        BuildContext {
            takes_dir: &self.takes_dir,
            rig: &state.rig,
            g3_range_deg: state.calibration.thumb_range_deg[2],
            tick_rate_hz: self.tick_rate_hz,
            now_ns,
            free_ids,
            name,
        }
    }

    /// Starts the stage `spec` under `name` (default: its kind), replacing one of that name.
    pub(crate) fn stage_start(&self, name: Option<String>, spec: StageSpec) -> ControlReply {
        let name = name.unwrap_or_else(|| spec.kind().to_string());
        if let Err(e) = validate_stage_name(&name) {
            return refuse(ControlErrorKind::BadName, e.to_string());
        }
        if name == LAYER_STAGE {
            return refuse(
                ControlErrorKind::BadName,
                "the stage name `layer` belongs to layer recording (frond record layer)",
            );
        }
        let mut state = self.lock();
        let slot = match state.stages.slot_for(&name) {
            Ok(slot) => slot,
            Err(e) => return refuse(ControlErrorKind::WrongState, e.to_string()),
        };
        let free = state.stages.free_ids(slot);
        let built = match stage::build(&spec, &self.build_context(&state, &name, &free, monotonic_ns())) {
            Ok(b) => b,
            Err(e) => return refuse(e.kind, e.message),
        };
        let kind = built.info.kind.as_str();
        match self.install(&mut state, &name, Some(built)) {
            Ok(()) => {
                info!(stage = %name, kind, "live stage started");
                ControlReply::Ok
            }
            Err(reply) => reply,
        }
    }

    /// Stops the stage `name`; nothing to do if none runs.
    pub(crate) fn stage_stop(&self, name: &str) -> ControlReply {
        if let Err(e) = validate_stage_name(name) {
            return refuse(ControlErrorKind::BadName, e.to_string());
        }
        let mut state = self.lock();
        if name == LAYER_STAGE && state.stages.slot_of(name).is_some() && state.recording.is_some() {
            return refuse(
                ControlErrorKind::WrongState,
                "a layer is being recorded: `frond record stop` ends it",
            );
        }
        match self.install(&mut state, name, None) {
            Ok(()) => ControlReply::Ok,
            Err(reply) => reply,
        }
    }

    /// Gives the stage `name` an input, answering once the loop applied it.
    pub(crate) fn stage_input(&self, name: &str, input: StageInput) -> ControlReply {
        let state = self.lock();
        let Some(slot) = state.stages.slot_of(name) else {
            let running: Vec<&str> = state.stages.iter().map(|r| r.name.as_str()).collect();
            return refuse(
                ControlErrorKind::WrongState,
                format!(
                    "no stage named {name:?} is running (running: {})",
                    if running.is_empty() { "none".to_string() } else { running.join(", ") }
                ),
            );
        };
        let running = state.stages.get(name).expect("slot_of found it");
        if let Err(why) = input.check() {
            return refuse(ControlErrorKind::BadRequest, why.to_string());
        }
        if !(running.info.accepts)(&input) {
            return refuse(
                ControlErrorKind::BadRequest,
                format!("stage {name:?} ({}) takes no input {input:?}", running.info.kind),
            );
        }
        match self.send_stage_command(slot, StageAction::Input(input), None).and_then(|a| wait_applied(&a)) {
            Ok(()) => ControlReply::Ok,
            Err(reply) => reply,
        }
    }

    /// Records a secondary layer, optionally over a looped global take.
    pub(crate) fn record_layer(
        &self,
        name: String,
        layer: String,
        global_take: Option<String>,
        seed: u64,
    ) -> ControlReply {
        let built = {
            let state = self.lock();
            if state.recording.is_some() {
                return refuse(ControlErrorKind::WrongState, "a take is already being recorded");
            }
            let primary_index = state.primary_hand();
            let primary = &state.hands[primary_index];
            let built = match stage::layer::build(primary.rig(&state.rig), &layer, &primary.name) {
                Ok(b) => b,
                Err(e) => return refuse(ControlErrorKind::Invalid, e.to_string()),
            };
            let id = built.info.hand_element.as_ref().map_or(ElementId::GLOBAL, |e| e.id);
            let mut others = state.hands.iter().enumerate().filter(|&(i, _)| i != primary_index);
            if let Some((_, other)) = others.find(|(_, h)| h.element == id) {
                return refuse(
                    ControlErrorKind::WrongState,
                    format!("hand {:?} drives layer {layer:?} already; record it from that hand", other.name),
                );
            }
            built
        };
        let started_playback = match &global_take {
            Some(take) => match self.stage_start(None, StageSpec::Playback { take: take.clone(), seed }) {
                ControlReply::Ok => true,
                reply => return reply,
            },
            None => false,
        };
        let undo_playback = |ctx: &ControlContext| {
            if started_playback {
                let _ = ctx.stage_stop(PLAYBACK_STAGE);
            }
        };
        {
            let mut state = self.lock();
            if let Err(reply) = self.install(&mut state, LAYER_STAGE, Some(built)) {
                drop(state);
                undo_playback(self);
                return reply;
            }
            state.layer_playback = started_playback;
        }
        let reply = self.record_start(name);
        if !matches!(reply, ControlReply::Recording(_)) {
            let mut state = self.lock();
            let _ = self.install(&mut state, LAYER_STAGE, None);
            state.layer_playback = false;
            drop(state);
            undo_playback(self);
        }
        reply
    }

    /// Ends a layer session with its take: the hand is the global element again, and a playback
    /// started for the layer stops.
    pub(crate) fn end_layer(&self) {
        let mut state = self.lock();
        if state.stages.slot_of(LAYER_STAGE).is_none() {
            return;
        }
        let _ = self.install(&mut state, LAYER_STAGE, None);
        if std::mem::take(&mut state.layer_playback) {
            let _ = self.install(&mut state, PLAYBACK_STAGE, None);
        }
    }

    /// Puts `built` (or nothing) in the slot of stage `name` and announces the new element table:
    /// the one path by which stages come and go.
    fn install(
        &self,
        state: &mut DaemonState,
        name: &str,
        built: Option<BuiltStage>,
    ) -> Result<(), ControlReply> {
        let slot = match (&built, state.stages.slot_of(name)) {
            (_, Some(slot)) => slot,
            (Some(_), None) => state
                .stages
                .slot_for(name)
                .map_err(|e| refuse(ControlErrorKind::WrongState, e.to_string()))?,
            (None, None) => return Ok(()),
        };
        if let Some((id, other)) = built.as_ref().and_then(|b| state.stages.collision(slot, &b.info)) {
            return Err(refuse(
                ControlErrorKind::WrongState,
                format!("stage {other:?} already publishes element {id}; stop it first"),
            ));
        }
        let (stage, running) = match built {
            Some(b) => (Some(b.stage), Some(Running::new(name, b.info))),
            None => (None, None),
        };
        let previous = state.stages.replace(slot, running);
        let (table, frame) = match self.encode_table(state) {
            Ok(t) => t,
            Err(reply) => {
                state.stages.replace(slot, previous);
                return Err(reply);
            }
        };
        let action = StageAction::Install(stage);
        let applied = match self.send_stage_command(slot, action, Some((table.version, frame))) {
            Ok(applied) => applied,
            Err(reply) => {
                state.stages.replace(slot, previous);
                return Err(reply);
            }
        };
        // Queued: even if the loop is late to apply it, it will, and the registry says so.
        state.elements = table;
        wait_applied(&applied)
    }

    /// Announces the element table again (the rig changed) without touching a stage.
    fn announce(&self, state: &mut DaemonState) -> Result<(), ControlReply> {
        let (table, frame) = self.encode_table(state)?;
        let applied = self.send_stage_command(0, StageAction::Announce, Some((table.version, frame)))?;
        state.elements = table;
        wait_applied(&applied)
    }

    /// The next element table and its frame, stored for the slow lane.
    fn encode_table(&self, state: &mut DaemonState) -> Result<(ElementTable, Vec<u8>), ControlReply> {
        let hands: Vec<HandElement> =
            state.hands.iter().map(|h| HandElement::new(&h.name, h.rig(&state.rig), h.element)).collect();
        let primary = state.primary_hand();
        let table = state.stages.next_table(&state.rig, &hands, primary);
        let mut frame = Vec::new();
        encode_frame(&ServerMessage::Elements(table.clone()), &mut frame);
        // The running fields' definitions follow the table they belong to (protocol 3), also
        // when none runs: that is how a subscriber learns a field stopped.
        let fields: Vec<_> = state.stages.iter().filter_map(|r| r.info.report.field().cloned()).collect();
        let fields = FieldTable { elements_version: table.version, fields };
        encode_frame(&ServerMessage::Field(FieldMessage::Table(fields)), &mut frame);
        if frame.len() > ELEMENTS_FRAME_MAX {
            return Err(refuse(
                ControlErrorKind::Invalid,
                format!(
                    "the element table would take {} bytes (the limit is {ELEMENTS_FRAME_MAX}); run fewer stages or plants",
                    frame.len()
                ),
            ));
        }
        self.elements_cell.store(table.version, &frame);
        Ok((table, frame))
    }

    /// Sends one stage command; returns the flag the loop raises once it applied it.
    fn send_stage_command(
        &self,
        slot: usize,
        action: StageAction,
        table: Option<(u64, Vec<u8>)>,
    ) -> Result<Arc<AtomicBool>, ControlReply> {
        let applied = Arc::new(AtomicBool::new(false));
        let (elements_version, elements_frame) = table.unzip();
        let cmd = StageCommand {
            slot,
            action,
            elements_frame,
            elements_version: elements_version.unwrap_or(0),
            applied: applied.clone(),
        };
        self.send_loop(LoopCommand::Stage(Box::new(cmd))).map_err(|r| *r)?;
        Ok(applied)
    }

    /// Live stages for status, one line each.
    pub(crate) fn modes(&self, state: &DaemonState) -> Vec<String> {
        state.stages.iter().map(|r| r.info.report.describe()).collect()
    }
}

/// Waits until the loop raised `applied`, for at most [`APPLY_TIMEOUT`].
fn wait_applied(applied: &AtomicBool) -> Result<(), ControlReply> {
    let deadline = Instant::now() + APPLY_TIMEOUT;
    while !applied.load(Acquire) {
        if Instant::now() >= deadline {
            return Err(refuse(
                ControlErrorKind::Internal,
                "the realtime loop did not apply the change within 1 s (it will when it runs again)",
            ));
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    Ok(())
}
