//! Fields of plants (seed 000, section 6.2): `field.json` as written by `frond take field`, read
//! and played with `frond_motion::field` (the one implementation of Eq. 6-7 and the bend
//! rotation of section 6.3 (1)(b)), and where each plant stands in the glTF scene.

use std::path::Path;

use frond_formats::field_json::FieldJson;
use frond_motion::clip::Clip;
use frond_motion::field::Field as MotionField;

use crate::anim::Joints;
use crate::doc::Placement;
use crate::error::BakeError;

pub use frond_motion::field::FieldPlant;

/// A validated `field.json` and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// The file (for messages and extras).
    pub origin: String,
    /// The field.
    pub field: MotionField,
}

impl Field {
    /// Parses and checks `field.json` text (no I/O); `origin` names it in errors.
    pub fn from_json(text: &str, origin: &str) -> Result<Field, BakeError> {
        let err = |reason: String| BakeError::Field { origin: origin.to_string(), reason };
        let field = MotionField::from_json(text).map_err(|e| err(e.to_string()))?;
        if field.plants.is_empty() {
            return Err(err("the field has no plants".to_string()));
        }
        if !(field.fps.is_finite() && field.fps > 0.0 && field.fps <= crate::anim::MAX_FPS) {
            return Err(err(format!(
                "fps must be above 0 and at most {}, got {}",
                crate::anim::MAX_FPS,
                field.fps
            )));
        }
        if let Some((i, p)) =
            field.plants.iter().enumerate().find(|(_, p)| !(p.scale.is_finite() && p.scale > 0.0))
        {
            return Err(err(format!("plants[{i}].scale must be above 0, got {}", p.scale)));
        }
        if let Some((i, _)) =
            field.plants.iter().enumerate().find(|(_, p)| !p.position_m.iter().all(|c| c.is_finite()))
        {
            return Err(err(format!("plants[{i}].position_m is not finite")));
        }
        Ok(Field { origin: origin.to_string(), field })
    }

    /// Reads and checks a field file.
    pub fn read(path: &Path) -> Result<Field, BakeError> {
        let origin = path.display().to_string();
        let text = frond_formats::rig_files::read_small_text(path, frond_motion::field::MAX_FIELD_FILE_BYTES)
            .map_err(|e| BakeError::Field {
                origin: origin.clone(),
                reason: format!("cannot read: {}", e.reason()),
            })?;
        Self::from_json(&text, &origin)
    }

    /// Frame rate of the field's take clip.
    pub fn fps(&self) -> f64 {
        self.field.fps
    }

    /// The plants.
    pub fn plants(&self) -> &[FieldPlant] {
        &self.field.plants
    }

    /// Plant `id`'s root node: at `[x, 0, z]`, scaled by its size factor (the bend direction is
    /// in its poses, see [`Field::pose_at`]).
    pub fn placement(&self, id: usize) -> Placement {
        Placement::of_field_plant(&self.field.plants[id])
    }

    /// Plant `id`'s pose at `t_s` from one layer's clip (at [`Field::fps`]): seed 000, Eq. 6-7,
    /// `F_B(t) = F_A(t - gamma_B)`, by `frond_motion::field::Field::pose`.
    pub fn pose_at(&self, id: usize, clip: &Clip, t_s: f64) -> Joints {
        self.field.pose(id, clip, t_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE: &str = r#"{"version": 1, "take": "t", "fps": 10.0, "frames": 4, "rows": 1, "cols": 2,
        "cell_m": 0.2, "speed_m_s": 1.0, "direction_deg": 90.0, "authored_direction_deg": 0.0,
        "density": 1.0, "seed": 1, "plants": [
        {"id": 0, "row": 0, "col": 0, "position_m": [1.0, 2.0], "source": 0, "delay_s": 0.0, "start_frame": 0, "scale": 1.0},
        {"id": 1, "row": 0, "col": 1, "position_m": [1.5, 2.0], "source": 0, "delay_s": 0.1, "start_frame": 0, "scale": 1.2}]}"#;

    #[test]
    fn eq6_delayed_lookup_with_the_bend_turned_to_the_force() {
        let f = Field::from_json(ONE, "f.json").unwrap();
        let clip = Clip::from_joints((0..4).map(|k| [[10.0 * k as f32, 1.0, 5.0]; 4]), 10.0);
        // Plant 0 at 0.15 s: frame 1.5 -> pitch 15, yaw 1; turned 90 degrees: (p, y) -> (y, -p).
        assert_eq!(f.pose_at(0, &clip, 0.15)[0], [1.0, -15.0, 5.0]);
        // Plant 1 is 0.1 s (one frame) behind.
        assert_eq!(f.pose_at(1, &clip, 0.15)[0], [1.0, -5.0, 5.0]);
        let p = f.placement(1);
        assert_eq!((p.translation_m, p.scale), ([1.5, 0.0, 2.0], 1.2));
    }

    #[test]
    fn refuses_bad_fields_naming_the_file() {
        let e = Field::from_json("not json", "f.json").unwrap_err().to_string();
        assert!(e.starts_with("field f.json: field.json: "), "{e}");
        let bad = ONE.replace("\"scale\": 1.2", "\"scale\": 0.0");
        assert!(
            Field::from_json(&bad, "f").unwrap_err().to_string().contains("plants[1].scale must be above 0")
        );
        let bad = ONE.replace("\"version\": 1", "\"version\": 9");
        assert!(Field::from_json(&bad, "f").unwrap_err().to_string().contains("version 9 is not supported"));
    }
}
