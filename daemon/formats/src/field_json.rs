//! The JSON a field and a loop analysis are written as: `field.json` (`frond take field`, read by
//! the daemon's field stage, `frond take bvh --field` and `frond-gltf`), and the transition frames
//! `frond take loop --explain` prints. The values and their checks are `frond_motion`'s
//! ([`Field::check`], [`Transitions`]); this module only turns them into text and back.

use frond_motion::field::{FIELD_VERSION, Field, FieldError};
use frond_motion::looping::Transitions;

/// `field.json` for a [`Field`]: `use frond_formats::field_json::FieldJson;` and call
/// `Field::from_json(text)` / `field.to_json()`.
pub trait FieldJson: Sized {
    /// Writes `field.json` (pretty, with a trailing newline).
    fn to_json(&self) -> String;
    /// Reads and checks `field.json` ([`Field::check`]); a file of another version is refused.
    fn from_json(text: &str) -> Result<Self, FieldError>;
}

impl FieldJson for Field {
    fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).unwrap_or_default();
        s.push('\n');
        s
    }

    fn from_json(text: &str) -> Result<Field, FieldError> {
        let f: Field = serde_json::from_str(text).map_err(|e| FieldError::Json(e.to_string()))?;
        if f.version != FIELD_VERSION {
            return Err(FieldError::Json(format!(
                "version {} is not supported (expected {FIELD_VERSION})",
                f.version
            )));
        }
        f.check()?;
        // A field.json without its plants (a large live field's, which must fit in a control
        // request) is made again from its parameters, as subscribers make it.
        if f.plants.is_empty() {
            return frond_motion::field_wire::field_from_layout(&frond_motion::field_wire::layout_of(&f));
        }
        Ok(f)
    }
}

/// The JSON of a loop analysis (`frond take loop --explain`).
pub trait TransitionsJson {
    /// `{"pivot":N,"transitions":[...]}`.
    fn explain_json(&self) -> String;
}

impl TransitionsJson for Transitions {
    fn explain_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }
}
