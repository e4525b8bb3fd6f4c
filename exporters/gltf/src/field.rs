//! Fields of plants (seed 000, section 6.2): `field.json` as written by `frond take field`,
//! and the delayed lookup that animates each plant (Eq. 6-7).
//!
//! The reader takes what the baker needs from each plant and ignores everything else:
//! - `position_m` (alias `position`): `[x, z]` on the ground, or `[x, y, z]`, metres;
//! - `delay_s` (alias `delay`): `gamma_B` of Eq. 7, seconds (default 0);
//! - `start_frame` (alias `start`): frame of the take where the plant's motion starts, at the
//!   field's `fps` (default 0);
//! - `scale`: uniform size (default 1);
//! - `yaw_deg` (alias `rotation_deg`): turn about +Y, which rotates the bending direction with
//!   the plant (section 6.3 (1)(b); default 0).
//!
//! Top level: `plants` (required), `fps` (frame rate of `start_frame`, default 30).

use serde::Deserialize;

use frond_motion::clip::lerp_joints;

use crate::anim::Joints;
use crate::doc::Placement;
use crate::error::BakeError;

/// Largest accepted number of plants.
pub const MAX_PLANTS: usize = 1_000_000;

/// One plant of a field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldPlant {
    /// Position `[x, y, z]`, metres (y = 0 on the ground).
    pub position_m: [f32; 3],
    /// Delay behind the take's time line, seconds (Eq. 7's `gamma_B`, plus the rigidity of
    /// the plant's row source when the field has one).
    pub delay_s: f64,
    /// Frame of the take (at [`Field::fps`]) the plant's motion starts at.
    pub start_frame: f64,
    /// Uniform scale.
    pub scale: f32,
    /// Turn about +Y, degrees.
    pub yaw_deg: f32,
}

impl FieldPlant {
    /// The plant's root node transform.
    pub fn placement(&self) -> Placement {
        let mut p = Placement::on_ground(self.position_m[0], self.position_m[2], self.yaw_deg, self.scale);
        p.translation_m[1] = self.position_m[1];
        p
    }
}

/// A validated field.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Where it came from, for messages and extras.
    pub origin: String,
    /// Frame rate of `start_frame` and of the take's clip, frames per second.
    pub fps: f64,
    /// The plants.
    pub plants: Vec<FieldPlant>,
    /// Things worth telling the user.
    pub notes: Vec<String>,
}

#[derive(Deserialize)]
struct RawField {
    #[serde(default)]
    fps: Option<f64>,
    plants: Vec<RawPlant>,
}

#[derive(Deserialize)]
struct RawPlant {
    #[serde(alias = "position")]
    position_m: Vec<f32>,
    #[serde(default, alias = "delay")]
    delay_s: Option<f64>,
    #[serde(default, alias = "start")]
    start_frame: Option<f64>,
    #[serde(default)]
    scale: Option<f32>,
    #[serde(default, alias = "rotation_deg")]
    yaw_deg: Option<f32>,
}

impl Field {
    /// Parses and validates `field.json` text, listing every problem with its path.
    pub fn from_json(text: &str, origin: &str) -> Result<Field, BakeError> {
        let err = |reason: String| BakeError::Field { origin: origin.to_string(), reason };
        let raw: RawField = serde_json::from_str(text).map_err(|e| err(e.to_string()))?;
        let mut problems: Vec<String> = Vec::new();
        let fps = raw.fps.unwrap_or(30.0);
        if !(fps.is_finite() && fps > 0.0 && fps <= crate::anim::MAX_FPS) {
            problems.push(format!("fps: must be above 0 and at most {}, got {fps}", crate::anim::MAX_FPS));
        }
        if raw.plants.is_empty() {
            problems.push("plants: the field has no plants".to_string());
        }
        if raw.plants.len() > MAX_PLANTS {
            problems.push(format!("plants: {} plants, at most {MAX_PLANTS}", raw.plants.len()));
        }
        let mut plants = Vec::with_capacity(raw.plants.len().min(MAX_PLANTS));
        for (i, p) in raw.plants.iter().enumerate().take(MAX_PLANTS) {
            let mut bad = |field: &str, why: String| problems.push(format!("plants[{i}].{field}: {why}"));
            let position_m = match p.position_m.as_slice() {
                [x, z] => [*x, 0.0, *z],
                [x, y, z] => [*x, *y, *z],
                other => {
                    bad("position_m", format!("expected [x, z] or [x, y, z], got {} numbers", other.len()));
                    [0.0; 3]
                }
            };
            if !position_m.iter().all(|c| c.is_finite()) {
                bad("position_m", format!("{position_m:?} is not finite"));
            }
            let delay_s = p.delay_s.unwrap_or(0.0);
            if !delay_s.is_finite() {
                bad("delay_s", format!("{delay_s} is not finite"));
            }
            let start_frame = p.start_frame.unwrap_or(0.0);
            if !(start_frame.is_finite() && start_frame >= 0.0) {
                bad("start_frame", format!("{start_frame} must be a frame index >= 0"));
            }
            let scale = p.scale.unwrap_or(1.0);
            if !(scale.is_finite() && scale > 0.0) {
                bad("scale", format!("{scale} must be above 0"));
            }
            let yaw_deg = p.yaw_deg.unwrap_or(0.0);
            if !yaw_deg.is_finite() {
                bad("yaw_deg", format!("{yaw_deg} is not finite"));
            }
            plants.push(FieldPlant { position_m, delay_s, start_frame, scale, yaw_deg });
        }
        if !problems.is_empty() {
            return Err(err(problems.join("; ")));
        }
        Ok(Field { origin: origin.to_string(), fps, plants, notes: Vec::new() })
    }

    /// Reads and validates a field file.
    pub fn read(path: &std::path::Path) -> Result<Field, BakeError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| BakeError::Field { origin: origin.clone(), reason: format!("cannot read: {e}") })?;
        Self::from_json(&text, &origin)
    }

    /// A plant's pose at bake time `t_s` (seed 000, Eq. 6: `F_B(t) = F_A(t - gamma_B)`): the
    /// take's clip `frames` (at [`Field::fps`]) at frame `start_frame + (t - delay_s) fps`,
    /// linearly interpolated, played as an endless loop (wrapping from the last frame to the
    /// first) so any duration and any delay have a pose.
    pub fn pose_at(&self, frames: &[Joints], plant: &FieldPlant, t_s: f64) -> Joints {
        let m = frames.len();
        if m <= 1 {
            return frames.first().copied().unwrap_or_default();
        }
        let f = (plant.start_frame + (t_s - plant.delay_s) * self.fps).rem_euclid(m as f64);
        let i = (f.floor() as usize).min(m - 1);
        lerp_joints(&frames[i], &frames[(i + 1) % m], f - i as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn j(a: f32) -> Joints {
        [[a, 0.0, 0.0]; 4]
    }

    #[test]
    fn eq6_delayed_lookup_by_hand() {
        let field = Field::from_json(r#"{"fps": 10, "plants": [{"position": [1, 2]}]}"#, "t").unwrap();
        let frames = [j(0.0), j(10.0), j(20.0), j(30.0)];
        let p = |start_frame: f64, delay_s: f64| FieldPlant { start_frame, delay_s, ..field.plants[0] };
        // No delay: frame t * fps.
        assert_eq!(field.pose_at(&frames, &p(0.0, 0.0), 0.15), j(15.0));
        // Start frame 2, delay 0.1 s = one frame behind: frame 2 + 1.5 - 1 = 2.5.
        assert_eq!(field.pose_at(&frames, &p(2.0, 0.1), 0.15), j(25.0));
        // Past the end it loops: frame 3.5 is between the last (30) and the first (0).
        assert_eq!(field.pose_at(&frames, &p(3.0, 0.0), 0.05), j(15.0));
        // A delay longer than the elapsed time reaches back across the loop: frame -1 = 3.
        assert_eq!(field.pose_at(&frames, &p(0.0, 0.1), 0.0), j(30.0));
        assert_eq!(field.pose_at(&[j(7.0)], &p(0.0, 0.0), 5.0), j(7.0));
    }

    #[test]
    fn reads_positions_and_defaults() {
        let f = Field::from_json(
            r#"{"plants": [{"position_m": [1, 2], "delay_s": 0.5, "start_frame": 3, "scale": 2, "row": 0},
                           {"position": [1, 0.5, 2], "rotation_deg": 90}], "seed": 4}"#,
            "t",
        )
        .unwrap();
        assert_eq!(f.fps, 30.0);
        assert_eq!(
            f.plants[0],
            FieldPlant {
                position_m: [1.0, 0.0, 2.0],
                delay_s: 0.5,
                start_frame: 3.0,
                scale: 2.0,
                yaw_deg: 0.0
            }
        );
        assert_eq!(f.plants[1].position_m, [1.0, 0.5, 2.0]);
        assert_eq!(f.plants[1].yaw_deg, 90.0);
    }

    #[test]
    fn lists_every_problem_with_its_path() {
        let e = Field::from_json(
            r#"{"fps": 0, "plants": [{"position": [1]}, {"position": [0, 0], "scale": -1, "start_frame": -2}]}"#,
            "f.json",
        )
        .unwrap_err()
        .to_string();
        for want in
            ["field f.json", "fps:", "plants[0].position_m", "plants[1].scale", "plants[1].start_frame"]
        {
            assert!(e.contains(want), "{want} missing from {e}");
        }
        assert!(Field::from_json(r#"{"plants": []}"#, "f").unwrap_err().to_string().contains("no plants"));
        assert!(Field::from_json("not json", "f").unwrap_err().to_string().starts_with("field f: "));
    }
}
