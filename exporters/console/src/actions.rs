//! The page's control actions (`POST /api/...` with a JSON body), each checked here and turned
//! into the one [`ControlRequest`] that `frond` would send for it, so the daemon sees the same
//! requests from the console as from the command line.
//!
//! | path | body | as |
//! |---|---|---|
//! | `/api/record/start` | `{"name"}` | `frond record start NAME` |
//! | `/api/record/stop` | | `frond record stop` |
//! | `/api/mark` | `{"label"}` | `frond mark LABEL` |
//! | `/api/playback` | `{"take"}` | `frond play TAKE` (the daemon loops it) |
//! | `/api/playback/stop` | | stops it |
//! | `/api/rig` | `{"rig"}`: an embedded rig's name | `frond rig set NAME` |
//! | `/api/filter` | `{"spec"}` | `frond filter SPEC` |
//! | `/api/calibration` | `{"toml"}`: a calibration file's text | `frond calibration apply FILE` |
//! | `/api/field/key` | `{"key"}`: left, right, up, down, stronger, weaker | `frond field key KEY` |
//! | `/api/field/stop` | | stops the field |
//! | `/api/guided` | `{"spec"}`, or `"off"` | `frond guided SPEC` |
//! | `/api/triggers` | `{"mode"}`: follow or pause | `frond triggers MODE` |
//!
//! A rig is taken by embedded name only: a browser does not name files on the daemon's machine.

use frond_formats::rig_toml::CalibrationText;
use frond_motion::{Calibration, FilterSpec};
use frond_protocol::{ControlRequest, StageInput, StageKey, StageSpec, paths};
use serde_json::Value;

/// Every action path, for the router.
pub const PATHS: [&str; 12] = [
    "/api/record/start",
    "/api/record/stop",
    "/api/mark",
    "/api/playback",
    "/api/playback/stop",
    "/api/rig",
    "/api/filter",
    "/api/calibration",
    "/api/field/key",
    "/api/field/stop",
    "/api/guided",
    "/api/triggers",
];

/// Longest marker label, bytes (the daemon's limit).
pub const MAX_LABEL_BYTES: usize = 256;

/// What is wrong with a page's action ([`request`]); the page shows the message.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ActionError {
    /// The body lacks a string field the action needs.
    #[error("{path} needs {{\"{key}\": \"...\"}}")]
    Missing {
        /// The action's path.
        path: String,
        /// The field.
        key: &'static str,
    },
    /// A take name (`name` or `take`) that is not one.
    #[error("{key}: {why}")]
    TakeName {
        /// The field.
        key: &'static str,
        /// Why.
        why: frond_protocol::paths::TakeNameError,
    },
    /// A marker label that is empty or longer than [`MAX_LABEL_BYTES`].
    #[error("a marker label is 1-{MAX_LABEL_BYTES} bytes, not {len}")]
    LabelLength {
        /// The label's length in bytes.
        len: usize,
    },
    /// No embedded rig has this name.
    #[error("no embedded rig {name:?}; the console offers {known}")]
    UnknownRig {
        /// The name asked for.
        name: String,
        /// The embedded rigs' names, comma-separated.
        known: String,
    },
    /// An embedded rig failed to load: the loader's message, kept as text because its error
    /// holds an `io::Error` (not comparable) and embedded rigs are checked by their own tests.
    #[error("{0}")]
    BrokenRig(String),
    /// A filter specification that does not parse.
    #[error("filter {spec:?}: {why}")]
    Filter {
        /// The specification as posted.
        spec: String,
        /// Why.
        why: frond_motion::FilterSpecError,
    },
    /// A calibration file's text that is not a calibration.
    #[error("calibration: {0}")]
    Calibration(frond_motion::CalibrationError),
    /// A field key that is none of the stage's.
    #[error(transparent)]
    FieldKey(#[from] frond_protocol::control::UnknownStageKey),
    /// A trigger mode that is neither `follow` nor `pause` (not quoted back: the page sent it).
    #[error("/api/triggers needs {{\"mode\": \"follow\"}} or {{\"mode\": \"pause\"}}")]
    TriggerMode,
    /// No action has this path.
    #[error("no action {0}")]
    NoAction(String),
}

/// The request for action `path` with `body` (the JSON object the page posted), or what is
/// wrong with it.
pub fn request(path: &str, body: &Value) -> Result<ControlRequest, ActionError> {
    let text = |key: &'static str| -> Result<String, ActionError> {
        body.get(key)
            .and_then(Value::as_str)
            .map(str::to_string)
            .ok_or_else(|| ActionError::Missing { path: path.to_string(), key })
    };
    let take_name = |key: &'static str| -> Result<String, ActionError> {
        let name = text(key)?;
        paths::validate_take_name(&name).map_err(|why| ActionError::TakeName { key, why })?;
        Ok(name)
    };
    Ok(match path {
        "/api/record/start" => ControlRequest::RecordStart { name: take_name("name")? },
        "/api/record/stop" => ControlRequest::RecordStop,
        "/api/mark" => {
            let label = text("label")?;
            if label.is_empty() || label.len() > MAX_LABEL_BYTES {
                return Err(ActionError::LabelLength { len: label.len() });
            }
            ControlRequest::Mark { label }
        }
        "/api/playback" => ControlRequest::StageStart {
            name: None,
            spec: StageSpec::Playback { take: take_name("take")?, seed: 0 },
        },
        "/api/playback/stop" => ControlRequest::StageStop { name: "playback".into() },
        "/api/rig" => {
            let name = text("rig")?;
            let Some(loaded) = frond_formats::rig_files::embedded_rig(&name) else {
                let known: Vec<&str> =
                    frond_formats::rig_files::EMBEDDED_RIGS.iter().map(|(n, _)| *n).collect();
                return Err(ActionError::UnknownRig { name, known: known.join(", ") });
            };
            let loaded = loaded.map_err(|e| ActionError::BrokenRig(e.to_string()))?;
            ControlRequest::SetRig { name: loaded.rig.name.clone(), toml: loaded.text }
        }
        "/api/filter" => {
            let spec = text("spec")?;
            let filter: FilterSpec = match spec.trim().parse() {
                Ok(filter) => filter,
                Err(why) => return Err(ActionError::Filter { spec, why }),
            };
            ControlRequest::SetFilter { spec: filter.to_string() }
        }
        "/api/calibration" => {
            let toml = text("toml")?;
            let cal = Calibration::from_toml_str(&toml).map_err(ActionError::Calibration)?;
            ControlRequest::SetCalibration { id: cal.id.clone(), toml }
        }
        "/api/field/key" => {
            let key: StageKey = text("key")?.parse()?;
            ControlRequest::StageInput { name: "field".into(), input: StageInput::Key(key) }
        }
        "/api/field/stop" => ControlRequest::StageStop { name: "field".into() },
        "/api/guided" => match text("spec")?.trim() {
            "off" => ControlRequest::StageStop { name: "guided".into() },
            spec => {
                ControlRequest::StageStart { name: None, spec: StageSpec::Guided { spec: spec.to_string() } }
            }
        },
        "/api/triggers" => match text("mode")?.as_str() {
            "follow" => ControlRequest::SetTriggers { follow: true },
            "pause" => ControlRequest::SetTriggers { follow: false },
            _ => return Err(ActionError::TriggerMode),
        },
        other => return Err(ActionError::NoAction(other.to_string())),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn actions_become_the_requests_frond_sends() {
        assert_eq!(
            request("/api/record/start", &json!({"name": "t1"})),
            Ok(ControlRequest::RecordStart { name: "t1".into() })
        );
        assert_eq!(
            request("/api/field/key", &json!({"key": "left"})),
            Ok(ControlRequest::StageInput { name: "field".into(), input: StageInput::Key(StageKey::Left) })
        );
        assert_eq!(
            request("/api/triggers", &json!({"mode": "pause"})),
            Ok(ControlRequest::SetTriggers { follow: false })
        );
        assert_eq!(
            request("/api/triggers", &json!({"mode": "follow"})),
            Ok(ControlRequest::SetTriggers { follow: true })
        );
        assert_eq!(
            request("/api/guided", &json!({"spec": "off"})),
            Ok(ControlRequest::StageStop { name: "guided".into() })
        );
        let Ok(ControlRequest::SetRig { name, toml }) = request("/api/rig", &json!({"rig": "flower"})) else {
            panic!("the flower is embedded")
        };
        assert_eq!(name, "flower");
        assert!(toml.contains("[[elements]]"));
        let Ok(ControlRequest::SetFilter { spec }) = request("/api/filter", &json!({"spec": "lowpass"}))
        else {
            panic!("a bare kind takes its defaults")
        };
        assert!(spec.starts_with("lowpass"), "{spec}");
    }

    #[test]
    fn bad_actions_say_what_is_wrong() {
        for (path, body, want) in [
            ("/api/record/start", json!({}), "needs {\"name\""),
            ("/api/record/start", json!({"name": "../x"}), "name: take name"),
            ("/api/playback", json!({"take": ".x"}), "take: take name"),
            ("/api/mark", json!({"label": ""}), "1-256 bytes"),
            ("/api/rig", json!({"rig": "/etc/passwd"}), "no embedded rig"),
            ("/api/filter", json!({"spec": "median"}), "filter \"median\""),
            ("/api/calibration", json!({"toml": "not = [toml"}), "calibration"),
            ("/api/field/key", json!({"key": "sideways"}), "unknown field key"),
            ("/api/triggers", json!({"mode": "<b>on</b>"}), "needs {\"mode\": \"follow\"} or"),
            ("/api/triggers", json!({}), "needs {\"mode\""),
            ("/api/nothing", json!({}), "no action"),
        ] {
            let e = request(path, &body).unwrap_err().to_string();
            assert!(e.contains(want), "{path} {body}: {e}");
        }
    }
}
