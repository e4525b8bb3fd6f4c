//! What VMC needs from a rig: joint rest heights and the bone names sent for the joints (the
//! rig's `[vmc] bones` table when it has one, for receivers that only accept humanoid bone names;
//! else its joint names). The rig itself comes from the one rig loader,
//! [`frond_formats::rig_files::load_rig`]: an embedded rig by name or a rig file, validated as the
//! daemon validates it.

use frond_formats::rig_files::{LoadedRig, load_rig};
use frond_motion::Rig;
use frond_motion::rig::MAX_VMC_BONE_NAME_BYTES;
use thiserror::Error;

use crate::encode::VmcRig;

/// Why a rig cannot be used for VMC.
#[derive(Debug, Error)]
pub enum RigFileError {
    /// The rig could not be loaded (not found, unreadable, or invalid: every problem named).
    #[error(transparent)]
    Load(#[from] frond_formats::rig_files::RigFileError),
    /// A joint name to be sent as a bone name is longer than an OSC bone name may be.
    #[error(
        "{origin}: joints[{joint}].name is {bytes} bytes; VMC bone names are 1 to {MAX_VMC_BONE_NAME_BYTES} bytes (give the rig a [vmc] bones table)"
    )]
    LongJointName {
        /// `embedded rig grass` or the file path.
        origin: String,
        /// The joint.
        joint: usize,
        /// Its name's length.
        bytes: usize,
    },
}

/// A rig read for VMC.
#[derive(Debug, Clone, PartialEq)]
pub struct RigFile {
    /// The rig's name.
    pub name: String,
    /// Joint names and heights, with bone names from `[vmc] bones` when present.
    pub vmc: VmcRig,
    /// True when the bone names came from a `[vmc] bones` table.
    pub has_vmc_bones: bool,
}

/// Loads `--rig SPEC` (an embedded rig name, or a path) with [`load_rig`].
pub fn load(spec: &str) -> Result<RigFile, RigFileError> {
    from_loaded(&load_rig(spec)?)
}

/// What VMC needs from a loaded rig.
pub fn from_loaded(loaded: &LoadedRig) -> Result<RigFile, RigFileError> {
    let rig: &Rig = &loaded.rig;
    let names = match &rig.vmc_bones {
        Some(bones) => bones.clone(),
        None => {
            let names: [String; 4] = std::array::from_fn(|i| rig.joints[i].name.clone());
            if let Some((joint, n)) =
                names.iter().enumerate().find(|(_, n)| n.len() > MAX_VMC_BONE_NAME_BYTES)
            {
                return Err(RigFileError::LongJointName {
                    origin: loaded.origin.clone(),
                    joint,
                    bytes: n.len(),
                });
            }
            names
        }
    };
    Ok(RigFile {
        name: rig.name.clone(),
        vmc: VmcRig { bone_names: names, heights_m: std::array::from_fn(|i| rig.joints[i].height_m) },
        has_vmc_bones: rig.vmc_bones.is_some(),
    })
}

/// A `--vmc-bones` value that is neither `humanoid` nor four names.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--vmc-bones: expected `humanoid`, `joints` or 4 non-empty comma-separated names, got `{0}`")]
pub struct BadBoneNames(pub String);

/// Parses `--vmc-bones`: `humanoid`, or four comma-separated names.
pub fn parse_bone_names(spec: &str) -> Result<[String; 4], BadBoneNames> {
    if spec == "humanoid" {
        return Ok(crate::encode::vmc_humanoid_names());
    }
    let names: Vec<&str> = spec.split(',').map(str::trim).collect();
    if names.len() != 4 || names.iter().any(|n| n.is_empty() || n.len() > 255) {
        return Err(BadBoneNames(spec.to_string()));
    }
    Ok(std::array::from_fn(|i| names[i].to_string()))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn parse(text: &str) -> Result<RigFile, RigFileError> {
        let loaded =
            frond_formats::rig_files::rig_from_text(text.to_string(), "test rig".into(), "test", None)?;
        from_loaded(&loaded)
    }

    #[test]
    fn reads_the_shipped_rigs() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/plants");
        let flower = load(&root.join("flower.toml").to_string_lossy()).unwrap();
        assert_eq!(flower.name, "flower");
        assert_eq!(flower.vmc.bone_names, ["root", "stem_low", "stem_high", "head"].map(String::from));
        assert_eq!(flower.vmc.heights_m, [0.0, 0.12, 0.25, 0.36]);
        assert!((flower.vmc.local_offset_m(2)[1] - 0.13).abs() < 1e-6);
        assert!(!flower.has_vmc_bones);
        let grass = load(&root.join("grass.toml").to_string_lossy()).unwrap();
        assert_eq!(grass.vmc.heights_m, crate::encode::DEFAULT_HEIGHTS_M);
        // The embedded rigs by name are the files' rigs.
        assert_eq!(load("flower").unwrap().vmc, flower.vmc);
        assert_eq!(load("grass").unwrap().vmc, grass.vmc);
    }

    #[test]
    fn vmc_table_overrides_names() {
        let text = r#"
            name = "v"
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
        let long = text.replace("name = \"d\"", &format!("name = \"{}\"", "d".repeat(256)));
        assert_eq!(parse(&long).unwrap().vmc.bone_names[0], "Hips", "a [vmc] table names the bones");
        let long =
            long.replace("[vmc]\n", "").replace("bones = [\"Hips\", \"Spine\", \"Chest\", \"Head\"]", "");
        let err = parse(&long).unwrap_err().to_string();
        assert!(err.contains("test rig: joints[3].name is 256 bytes"), "{err}");
    }

    #[test]
    fn bad_rigs_name_every_problem() {
        let text = r#"
            name = "bad"
            [[joints]]
            name = "a"
            height_m = 0.2
            [[joints]]
            name = ""
            height_m = 0.1
            [vmc]
            bones = ["x"]
        "#;
        let err = parse(text).unwrap_err().to_string();
        assert!(err.starts_with("test rig: "), "{err}");
        assert!(err.contains("joints: expected 4 joints, found 2"), "{err}");
        assert!(err.contains("joints[1].height_m: 0.1 must be above joints[0].height_m (0.2)"), "{err}");
        assert!(err.contains("joints[1].name"), "{err}");
        assert!(err.contains("vmc.bones: expected 4 names, found 1"), "{err}");
        let err = parse("joints = 3").unwrap_err().to_string();
        assert!(err.contains("invalid type"), "{err}");
        let err = load("no-such-rig").unwrap_err().to_string();
        assert!(err.contains("rig `no-such-rig` not found"), "{err}");
    }

    #[test]
    fn bone_name_specs() {
        assert_eq!(
            parse_bone_names("humanoid").unwrap(),
            ["Hips", "Spine", "Chest", "Neck"].map(String::from)
        );
        assert_eq!(parse_bone_names("a, b,c,d").unwrap(), ["a", "b", "c", "d"].map(String::from));
        assert!(
            parse_bone_names("a,b,c").unwrap_err().to_string().contains("expected `humanoid`, `joints` or 4")
        );
        assert!(parse_bone_names("a,,c,d").is_err());
    }
}
