//! The `[mesh]` table of a rig file (see `rig-files/plants/grass.toml`): a procedural shape
//! built by `crate::mesh`, or a glTF/GLB file read by `frond_formats::gltf_mesh`. Parsed into a raw form
//! with unknown fields refused, then validated into [`MeshSpec`] with every problem's path.
//! Private; the types are re-exported from `crate::rig`.

use serde::{Deserialize, Serialize};

use crate::problems::Problems;

/// Procedural plant shapes (see `crate::mesh`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshShape {
    /// A tapered grass blade.
    Blade,
    /// A stem with a head; the rig's secondary elements become leaves.
    Flower,
    /// A trunk with branches and leaf clusters.
    Shrub,
}

impl MeshShape {
    /// The name used in rig files.
    pub fn name(self) -> &'static str {
        match self {
            MeshShape::Blade => "blade",
            MeshShape::Flower => "flower",
            MeshShape::Shrub => "shrub",
        }
    }
}

/// A rig's geometry: procedural, or a glTF/GLB file whose skin weights are used.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshSpec {
    /// Built by `crate::mesh::procedural_model`.
    Procedural {
        /// The shape.
        shape: MeshShape,
        /// Base width (blade) or stem/trunk diameter, metres (> 0).
        width_m: f32,
        /// Total height, metres (> the top joint); default: the top joint plus 3/4 of the top
        /// segment.
        height_m: Option<f32>,
    },
    /// A glTF/GLB file, relative to the rig file; read with `frond_formats::gltf_mesh`.
    File {
        /// Path as written in the rig file.
        path: String,
    },
}

impl Default for MeshSpec {
    fn default() -> Self {
        MeshSpec::Procedural { shape: MeshShape::Blade, width_m: 0.012, height_m: None }
    }
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawMesh {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    shape: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    width_m: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    height_m: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    file: Option<String>,
}

impl RawMesh {
    pub(crate) fn validate(&self, p: &mut Problems, top_joint_m: f32) -> MeshSpec {
        if let Some(file) = &self.file {
            if file.trim().is_empty() {
                p.push("mesh.file", "must not be empty");
            }
            for (set, name) in [
                (self.shape.is_some(), "shape"),
                (self.width_m.is_some(), "width_m"),
                (self.height_m.is_some(), "height_m"),
            ] {
                if set {
                    p.push(format!("mesh.{name}"), "cannot be combined with mesh.file");
                }
            }
            return MeshSpec::File { path: file.clone() };
        }
        let shape = match self.shape.as_deref() {
            None | Some("blade") => MeshShape::Blade,
            Some("flower") => MeshShape::Flower,
            Some("shrub") => MeshShape::Shrub,
            Some(other) => {
                p.push("mesh.shape", format!("unknown shape `{other}` (expected blade, flower or shrub)"));
                MeshShape::Blade
            }
        };
        let width_m = self.width_m.unwrap_or(0.012);
        p.positive("mesh.width_m", width_m);
        if let Some(h) = self.height_m
            && p.finite("mesh.height_m", h)
            && h <= top_joint_m
        {
            p.push("mesh.height_m", format!("{h} must be above the top joint ({top_joint_m})"));
        }
        MeshSpec::Procedural { shape, width_m, height_m: self.height_m }
    }

    pub(crate) fn from_spec(spec: &MeshSpec) -> Self {
        match spec {
            MeshSpec::File { path } => RawMesh { file: Some(path.clone()), ..RawMesh::default() },
            MeshSpec::Procedural { shape, width_m, height_m } => RawMesh {
                shape: Some(shape.name().to_string()),
                width_m: Some(*width_m),
                height_m: *height_m,
                file: None,
            },
        }
    }
}
