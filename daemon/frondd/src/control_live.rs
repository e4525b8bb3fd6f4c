//! Control requests for the live modes of the motion toolkit (seed 000, sections 5.3, 6.2-6.4):
//! looped playback, layered recording, field playback and its controls, guided motion. Takes and
//! fields are loaded and prepared here, off the realtime thread, then moved into the loop.

use frond_protocol::{ControlErrorKind, ControlReply, paths::validate_take_name};
use tracing::info;

use crate::clock::monotonic_ns;
use crate::control::{ControlContext, DaemonState, refuse};
use crate::engine::LoopCommand;
use crate::live::{LiveField, LivePlayback, guided, parse_guided, parse_key};

impl ControlContext {
    fn read_take(&self, name: &str) -> Result<Vec<u8>, ControlReply> {
        validate_take_name(name).map_err(|e| refuse(ControlErrorKind::BadName, e))?;
        let path = self.takes_dir.join(format!("{name}.take"));
        std::fs::read(&path).map_err(|e| {
            refuse(ControlErrorKind::Invalid, format!("cannot read take {name:?} at {}: {e}", path.display()))
        })
    }

    /// Loops `take` on the stream as element 0, or stops (`None`).
    pub(crate) fn play_loop(&self, take: Option<String>, seed: u64) -> ControlReply {
        let Some(name) = take else {
            if let Err(r) = self.send_loop(LoopCommand::SetPlayback(None)) {
                return *r;
            }
            self.lock().playing = None;
            return ControlReply::Ok;
        };
        match self.start_playback(&name, seed) {
            Ok(()) => ControlReply::Ok,
            Err(reply) => reply,
        }
    }

    fn start_playback(&self, name: &str, seed: u64) -> Result<(), ControlReply> {
        let bytes = self.read_take(name)?;
        let playback = LivePlayback::new(name, &bytes, seed, monotonic_ns())
            .map_err(|e| refuse(ControlErrorKind::Invalid, format!("take {name:?}: {e}")))?;
        self.send_loop(LoopCommand::SetPlayback(Some(Box::new(playback)))).map_err(|r| *r)?;
        info!(take = name, "looping take on the pose stream");
        self.lock().playing = Some(name.to_string());
        Ok(())
    }

    /// Records a secondary layer, optionally over a looped global take.
    pub(crate) fn record_layer(
        &self,
        name: String,
        layer: String,
        global_take: Option<String>,
        seed: u64,
    ) -> ControlReply {
        let id = {
            let state = self.lock();
            let names: Vec<&str> = state.rig.elements.iter().map(|e| e.name.as_str()).collect();
            match names.iter().position(|n| *n == layer) {
                Some(i) => (i + 1) as u16,
                None => {
                    return refuse(
                        ControlErrorKind::Invalid,
                        format!(
                            "rig {:?} has no secondary element {layer:?} (it has: {})",
                            state.rig.name,
                            if names.is_empty() { "none".to_string() } else { names.join(", ") }
                        ),
                    );
                }
            }
        };
        if self.lock().recording.is_some() {
            return refuse(ControlErrorKind::WrongState, "a take is already being recorded");
        }
        let started_playback = match &global_take {
            Some(global) => match self.start_playback(global, seed) {
                Ok(()) => true,
                Err(reply) => return reply,
            },
            None => false,
        };
        let reply = self.record_start(name, id);
        if matches!(reply, ControlReply::Recording(_)) {
            self.lock().layer = Some((layer, started_playback));
        } else if started_playback {
            let _ = self.send_loop(LoopCommand::SetPlayback(None));
            self.lock().playing = None;
        }
        reply
    }

    /// Starts field playback.
    pub(crate) fn field_start(&self, take: String, field_json: &str, plants: u16, seed: u64) -> ControlReply {
        let bytes = match self.read_take(&take) {
            Ok(b) => b,
            Err(reply) => return reply,
        };
        let field = match LiveField::new(&bytes, field_json, usize::from(plants), seed, monotonic_ns()) {
            Ok(f) => f,
            Err(e) => return refuse(ControlErrorKind::Invalid, format!("field of take {take:?}: {e}")),
        };
        let count = field.player.field().plants.len();
        let reply = self.field_command(LoopCommand::SetField(Some(Box::new(field))));
        if reply == ControlReply::Ok {
            info!(take, plants = count, "field playback started");
            self.lock().field = Some((take, count));
        }
        reply
    }

    /// Stops field playback.
    pub(crate) fn field_stop(&self) -> ControlReply {
        let reply = self.field_command(LoopCommand::SetField(None));
        if reply == ControlReply::Ok {
            self.lock().field = None;
        }
        reply
    }

    /// Applies a field control key.
    pub(crate) fn field_key(&self, key: &str) -> ControlReply {
        let key = match parse_key(key) {
            Ok(k) => k,
            Err(e) => return refuse(ControlErrorKind::BadRequest, e),
        };
        if self.lock().field.is_none() {
            return refuse(ControlErrorKind::WrongState, "no field is playing (frond field start ...)");
        }
        self.field_command(LoopCommand::FieldKey(key))
    }

    /// Sends a field command and answers once the loop has applied it (within a tick), so a
    /// status read right after the reply shows the new field state.
    fn field_command(&self, cmd: LoopCommand) -> ControlReply {
        let before = self.stats.field_controls.version();
        if let Err(r) = self.send_loop(cmd) {
            return *r;
        }
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(1);
        while self.stats.field_controls.version() == before && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
        ControlReply::Ok
    }

    /// Switches guided motion on (spec) or off (`None`).
    pub(crate) fn set_guided(&self, spec: Option<String>) -> ControlReply {
        let stage = match &spec {
            None => None,
            Some(text) => {
                let range = self.lock().calibration.thumb_range_deg[2];
                match parse_guided(text, range) {
                    Ok(p) => Some(Box::new(guided(p, self.tick_rate_hz))),
                    Err(e) => {
                        return refuse(ControlErrorKind::Invalid, format!("guided motion {text:?}: {e}"));
                    }
                }
            }
        };
        if let Err(r) = self.send_loop(LoopCommand::SetGuided(stage)) {
            return *r;
        }
        info!(spec = ?spec, "guided motion set");
        self.lock().guided = spec;
        ControlReply::Ok
    }

    /// Live modes for status.
    pub(crate) fn modes(&self, state: &DaemonState) -> Vec<String> {
        let mut modes = Vec::new();
        if let Some(take) = &state.playing {
            modes.push(format!("looping take {take} as the global element"));
        }
        if let Some((layer, _)) = &state.layer {
            modes.push(format!("recording layer {layer}"));
        }
        if let Some((take, plants)) = &state.field {
            let controls =
                self.stats.field_controls.load().map(|c| LiveField::describe(&c)).unwrap_or_default();
            modes.push(format!("field of {take}: {plants} plants; {controls}"));
        }
        if let Some(spec) = &state.guided {
            modes.push(format!("guided motion {spec}"));
        }
        modes
    }
}
