//! The few fields of a rig file (`rig-files/plants/*.toml`) that VMC needs: joint names and rest
//! heights, and an optional `[vmc] bones = ["Hips", ...]` table naming the bones sent for the
//! joints (for receivers that only accept humanoid bone names). Parsed here rather than with
//! `frond_motion` so that the exporter depends only on the SDK and the protocol.

use std::path::Path;

use serde::Deserialize;
use thiserror::Error;

use crate::encode::VmcRig;

/// Why a rig file could not be used.
#[derive(Debug, Error)]
pub enum RigFileError {
    /// The file could not be read.
    #[error("cannot read rig file {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML or lacks the fields.
    #[error("rig file {path}: {message}")]
    Invalid {
        /// The file.
        path: String,
        /// Every problem found, `; `-separated, each naming its field.
        message: String,
    },
}

#[derive(Deserialize)]
struct RawRig {
    name: Option<String>,
    joints: Vec<RawJoint>,
    vmc: Option<RawVmc>,
}

#[derive(Deserialize)]
struct RawJoint {
    name: String,
    height_m: f64,
}

#[derive(Deserialize)]
struct RawVmc {
    bones: Vec<String>,
}

/// A rig file read for VMC.
#[derive(Debug, Clone, PartialEq)]
pub struct RigFile {
    /// The rig's `name`, if any.
    pub name: Option<String>,
    /// Joint names and heights, with bone names from `[vmc] bones` when present.
    pub vmc: VmcRig,
    /// True when the bone names came from a `[vmc] bones` table.
    pub has_vmc_bones: bool,
}

/// Reads `path`.
pub fn load(path: &Path) -> Result<RigFile, RigFileError> {
    let text = std::fs::read_to_string(path)
        .map_err(|source| RigFileError::Read { path: path.display().to_string(), source })?;
    parse(&text).map_err(|message| RigFileError::Invalid { path: path.display().to_string(), message })
}

/// Parses rig TOML; the error lists every problem with its field path.
pub fn parse(text: &str) -> Result<RigFile, String> {
    let raw: RawRig = toml::from_str(text).map_err(|e| e.message().to_string())?;
    let mut problems = Vec::new();
    if raw.joints.len() != 4 {
        problems.push(format!("joints: expected 4 joints, found {}", raw.joints.len()));
    }
    for (i, j) in raw.joints.iter().enumerate() {
        if !j.height_m.is_finite() || j.height_m < 0.0 {
            problems.push(format!("joints[{i}].height_m: {} is not a finite height >= 0", j.height_m));
        } else if i > 0 && j.height_m <= raw.joints[i - 1].height_m {
            problems.push(format!("joints[{i}].height_m: {} is not above the joint below", j.height_m));
        }
        if j.name.is_empty() || j.name.len() > 255 {
            problems.push(format!("joints[{i}].name: must be 1 to 255 bytes"));
        }
    }
    if let Some(vmc) = &raw.vmc {
        if vmc.bones.len() != 4 {
            problems.push(format!("vmc.bones: expected 4 names, found {}", vmc.bones.len()));
        }
        for (i, b) in vmc.bones.iter().enumerate() {
            if b.is_empty() || b.len() > 255 {
                problems.push(format!("vmc.bones[{i}]: must be 1 to 255 bytes"));
            }
        }
    }
    if !problems.is_empty() {
        return Err(problems.join("; "));
    }
    let names: [String; 4] = match &raw.vmc {
        Some(vmc) => std::array::from_fn(|i| vmc.bones[i].clone()),
        None => std::array::from_fn(|i| raw.joints[i].name.clone()),
    };
    Ok(RigFile {
        name: raw.name,
        vmc: VmcRig { bone_names: names, heights_m: std::array::from_fn(|i| raw.joints[i].height_m as f32) },
        has_vmc_bones: raw.vmc.is_some(),
    })
}

/// Parses `--vmc-bones`: `humanoid`, or four comma-separated names.
pub fn parse_bone_names(spec: &str) -> Result<[String; 4], String> {
    if spec == "humanoid" {
        return Ok(crate::encode::vmc_humanoid_names());
    }
    let names: Vec<&str> = spec.split(',').map(str::trim).collect();
    if names.len() != 4 || names.iter().any(|n| n.is_empty() || n.len() > 255) {
        return Err(format!(
            "--vmc-bones: expected `humanoid` or 4 non-empty comma-separated names, got `{spec}`"
        ));
    }
    Ok(std::array::from_fn(|i| names[i].to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_shipped_rigs() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/plants");
        let flower = load(&root.join("flower.toml")).unwrap();
        assert_eq!(flower.name.as_deref(), Some("flower"));
        assert_eq!(flower.vmc.bone_names, ["root", "stem_low", "stem_high", "head"].map(String::from));
        assert_eq!(flower.vmc.heights_m, [0.0, 0.12, 0.25, 0.36]);
        assert!((flower.vmc.local_offset_m(2)[1] - 0.13).abs() < 1e-6);
        assert!(!flower.has_vmc_bones);
        let grass = load(&root.join("grass.toml")).unwrap();
        assert_eq!(grass.vmc.heights_m, crate::encode::DEFAULT_HEIGHTS_M);
    }

    #[test]
    fn vmc_table_overrides_names() {
        let text = r#"
            [[joints]]
            name = "a"
            height_m = 0.0
            [[joints]]
            name = "b"
            height_m = 0.1
            [[joints]]
            name = "c"
            height_m = 0.2
            [[joints]]
            name = "d"
            height_m = 0.3
            [vmc]
            bones = ["Hips", "Spine", "Chest", "Head"]
        "#;
        let rig = parse(text).unwrap();
        assert_eq!(rig.vmc.bone_names, ["Hips", "Spine", "Chest", "Head"].map(String::from));
        assert!(rig.has_vmc_bones);
    }

    #[test]
    fn bad_rigs_name_every_problem() {
        let text = r#"
            [[joints]]
            name = "a"
            height_m = 0.2
            [[joints]]
            name = ""
            height_m = 0.1
            [vmc]
            bones = ["x"]
        "#;
        let err = parse(text).unwrap_err();
        assert!(err.contains("joints: expected 4 joints, found 2"), "{err}");
        assert!(err.contains("joints[1].height_m: 0.1 is not above the joint below"), "{err}");
        assert!(err.contains("joints[1].name"), "{err}");
        assert!(err.contains("vmc.bones: expected 4 names, found 1"), "{err}");
        assert!(
            parse("joints = 3").unwrap_err().contains("invalid type"),
            "{}",
            parse("joints = 3").unwrap_err()
        );
    }

    #[test]
    fn bone_name_specs() {
        assert_eq!(
            parse_bone_names("humanoid").unwrap(),
            ["Hips", "Spine", "Chest", "Neck"].map(String::from)
        );
        assert_eq!(parse_bone_names("a, b,c,d").unwrap(), ["a", "b", "c", "d"].map(String::from));
        assert!(parse_bone_names("a,b,c").unwrap_err().contains("expected `humanoid` or 4"));
        assert!(parse_bone_names("a,,c,d").is_err());
    }
}
