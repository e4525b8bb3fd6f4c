//! The console's side of running fields that the page does not get from the stream: starting
//! one (`POST /api/field/start`), the rig each field is drawn with (`GET /api/rigs/NAME.glb`,
//! `/api/rigs/NAME.json`: a meadow of grass and flowers is a field of each rig, and the page
//! draws every field with its own rig) and the field keys and stop sent to every running field
//! (the fields of one meadow are steered as one, as `frond field key` steers them).

use std::sync::Arc;

use frond_formats::field_json::FieldJson;
use frond_formats::rig_files::EMBEDDED_RIGS;
use frond_protocol::{ControlRequest, StageSpec};
use frond_web::http::{Request, Response};
use serde_json::json;

use super::{Console, NoScene, json_body};
use crate::scene::{self, RigScene};
use crate::takes;

/// The answer to a rig the console does not serve (the name is not echoed: it comes from a page).
fn no_such_rig() -> Response {
    let names: Vec<&str> = EMBEDDED_RIGS.iter().map(|(n, _)| *n).collect();
    Response::error(
        404,
        format!(
            "no such rig here: /api/rigs/NAME.glb or NAME.json, NAME an embedded rig ({}) or frond-console --rig's",
            names.join(", ")
        ),
    )
}

impl Console {
    /// Rig `name` as a field is drawn with: `--rig`'s when it has that name, else the embedded
    /// rig of that name (baked once, kept); any other name is not served.
    pub(super) fn rig_named(&self, name: &str) -> Result<Arc<RigScene>, Response> {
        if let Some(own) = &self.config.rig
            && own.loaded.rig.name == name
        {
            return Ok(Arc::clone(own));
        }
        if !EMBEDDED_RIGS.iter().any(|(n, _)| *n == name) {
            return Err(no_such_rig());
        }
        let mut cache = self.scenes.lock().unwrap_or_else(|e| e.into_inner());
        cache
            .entry(name.to_string())
            .or_insert_with(|| {
                scene::load_recorded(name).map(Arc::new).map_err(|e| NoScene::Load(Arc::new(e)))
            })
            .clone()
            .map_err(|e| Response::error(503, e.to_string()))
    }

    /// `GET /api/rigs/NAME.glb` (the rig baked at rest) and `/api/rigs/NAME.json` (its node map),
    /// as `/rig.glb` and `/api/scene` are the view's rig.
    pub(super) fn rig_file(&self, rest: &str) -> Response {
        let (name, glb) = match (rest.strip_suffix(".glb"), rest.strip_suffix(".json")) {
            (Some(n), _) => (n, true),
            (_, Some(n)) => (n, false),
            _ => return no_such_rig(),
        };
        match self.rig_named(name) {
            Ok(s) if glb => Response::new(200, "model/gltf-binary", s.glb.clone()),
            Ok(s) => Response::json(200, &s.map),
            Err(r) => r,
        }
    }

    /// `POST /api/field/start {"take", "plants"?, "rows"?, "cols"?, "cell_m"?, "rig"?, "name"?}`:
    /// builds the field ([`takes::field`]), keeps its layout for the view, and has the daemon
    /// play it, as stage `name` (default `field`), of the embedded rig `rig` (default: the
    /// daemon's rig).
    pub(super) fn field_start(&self, req: &Request) -> Response {
        let body = match json_body(req) {
            Ok(b) => b,
            Err(r) => return r,
        };
        let ask = match takes::FieldRequest::from_json(&body) {
            Ok(a) => a,
            Err(e) => return Response::error(e.status, e.message),
        };
        let field = match takes::field(&self.config.takes_dir, &ask) {
            Ok(f) => f,
            Err(e) => return Response::error(e.status, e.message),
        };
        let take = ask.take.as_str();
        let plants = ask.plants.min(field.plants.len() as u16);
        let layout = json!({
            "take": take,
            "positions_m": field.plants.iter().take(usize::from(plants)).map(|p| p.position_m).collect::<Vec<_>>(),
            "scales": field.plants.iter().take(usize::from(plants)).map(|p| p.scale).collect::<Vec<_>>(),
        });
        let (take, field_json) = (take.to_string(), field.to_json());
        // `from_json` took only an embedded rig's name.
        let rig_toml = ask.rig.as_deref().and_then(|r| EMBEDDED_RIGS.iter().find(|(n, _)| *n == r));
        let spec = match rig_toml {
            None => StageSpec::Field { take, field_json, plants, seed: 1 },
            Some((_, text)) => {
                StageSpec::FieldOfRig { take, field_json, plants, seed: 1, rig_toml: text.to_string() }
            }
        };
        let request = ControlRequest::StageStart { name: ask.name.clone(), spec };
        // Kept before the daemon is asked: its new element table can reach the page (which then
        // asks for the layout) before its answer reaches this thread.
        let before = self.field.lock().unwrap_or_else(|e| e.into_inner()).replace(layout);
        let answer = self.act(&request);
        if answer.status != 200 {
            *self.field.lock().unwrap_or_else(|e| e.into_inner()) = before;
        }
        answer
    }

    /// A field key or stop (`request`, addressed to `field`) sent to every running field, the
    /// first refusal answered; to `field` when none runs (the daemon's answer says so).
    pub(super) fn to_every_field(&self, request: ControlRequest) -> Response {
        let mut names: Vec<String> =
            self.live.lock().fields.fields.iter().map(|f| f.definition.source.clone()).collect();
        names.sort();
        names.dedup();
        if names.is_empty() {
            return self.act(&request);
        }
        let mut answer = Response::error(500, "no field");
        for name in names {
            let to = match &request {
                ControlRequest::StageInput { input, .. } => {
                    ControlRequest::StageInput { name, input: *input }
                }
                ControlRequest::StageStop { .. } => ControlRequest::StageStop { name },
                other => other.clone(),
            };
            answer = self.act(&to);
            if answer.status != 200 {
                return answer;
            }
        }
        answer
    }
}
