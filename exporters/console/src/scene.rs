//! What the 3D view shows: the daemon's rig baked by frond-gltf (the same document `frond-gltf`
//! writes, so the page skins the mesh exactly as every other tool does), at rest, as GLB, and
//! the map from the stream's elements to the document's joint nodes.
//!
//! frond-gltf names the main joints after the rig's joints and the joints of secondary element
//! instance `i` of rig element `k` (named `leaf`, ...) `{leaf}{i}_joint{j}`; a layer element of
//! the stream (kind `layer`, named after the rig element) drives every instance of it, as a
//! layered take's bake does. The node rotations are the protocol's `joint_quat` of each pose
//! (`R = R_yaw R_pitch R_roll`), the page computes the same quaternion.

use frond_gltf::{BakeOptions, Baker, LoadedRig, TakeInput};
use frond_motion::{HandSample, JOINTS, PoseFrame, TakeFrame};
use serde_json::{Value, json};

/// The baked rig and its node map.
#[derive(Debug, Clone)]
pub struct RigScene {
    /// The GLB.
    pub glb: Vec<u8>,
    /// `{"rig", "joints": [4 names], "heights_m": [4], "elements": [{"name", "instances": [[4 node names]]}]}`.
    pub map: Value,
    /// The rig itself: its name, where it came from (`embedded rig grass`, a path); the takes
    /// panel bakes a take recorded on a rig file with `--rig`'s.
    pub loaded: LoadedRig,
}

/// A rig the console cannot show: the name or file given, and why.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// Not an embedded rig's name, or a file that cannot be read or is not a valid rig.
    #[error("rig {name:?}: {reason}")]
    Load {
        /// The rig's name or file, as given.
        name: String,
        /// What is wrong.
        reason: frond_gltf::BakeError,
    },
    /// A rig that frond-gltf cannot bake (its mesh, say).
    #[error("baking rig {name:?}: {reason}")]
    Bake {
        /// The rig's name or file, as given.
        name: String,
        /// What is wrong.
        reason: frond_gltf::BakeError,
    },
}

impl SceneError {
    /// What is wrong, without the rig's name (for a message that names it already).
    pub fn reason(&self) -> String {
        match self {
            SceneError::Load { reason, .. } => reason.to_string(),
            SceneError::Bake { reason, .. } => format!("baking it: {reason}"),
        }
    }
}

/// The scene of rig `name` (an embedded rig's name or a rig file, as `frond-gltf --rig` takes
/// it), loaded and baked at rest.
pub fn load(name: &str) -> Result<RigScene, SceneError> {
    scene_of(name, LoadedRig::resolve(name))
}

/// The scene of the rig a daemon reports by name: an embedded rig only
/// ([`LoadedRig::recorded`]). The name comes from a peer and is never opened as a path; a rig
/// the daemon loaded from a file is refused (`RigFileError::NotEmbedded`), and the operator
/// gives the console that file with `--rig FILE` ([`load`]).
pub fn load_recorded(name: &str) -> Result<RigScene, SceneError> {
    scene_of(name, LoadedRig::recorded(name))
}

/// The scene of the rig `name` loaded as (or the error why not).
fn scene_of(name: &str, rig: Result<LoadedRig, frond_gltf::BakeError>) -> Result<RigScene, SceneError> {
    let rig = rig.map_err(|reason| SceneError::Load { name: name.to_string(), reason })?;
    bake(&rig).map_err(|reason| SceneError::Bake { name: name.to_string(), reason })
}

/// Bakes `rig` at rest.
pub fn bake(rig: &LoadedRig) -> Result<RigScene, frond_gltf::BakeError> {
    let model = rig.model()?;
    let rest = TakeFrame {
        seq: 0,
        device_time_us: 0,
        host_ns: 0,
        flags: 0,
        element: frond_protocol::ElementId::GLOBAL,
        pose: PoseFrame { t: 0.0, joints_deg: [[0.0; 3]; JOINTS] },
        hand: HandSample { t: 0.0, wrist_deg: [0.0; 3], thumb_deg: [0.0; 3] },
    };
    let take = TakeInput { name: "rest".into(), frames: vec![rest], ended: true, ..Default::default() };
    let baked = Baker::new().bake_take(rig, &model, &take, &BakeOptions::default(), &mut |_, _| {})?;
    let mut glb = Vec::new();
    frond_gltf::encode_glb(&baked, &mut glb)?;
    let names: Vec<&str> = rig.rig.elements.iter().map(|e| e.name.as_str()).collect();
    let elements: Vec<Value> = names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let instances: Vec<Value> = model
                .elements
                .iter()
                .filter(|e| e.element == k)
                .map(|e| {
                    json!((0..JOINTS).map(|j| format!("{name}{}_joint{j}", e.instance)).collect::<Vec<_>>())
                })
                .collect();
            json!({ "name": name, "instances": instances })
        })
        .collect();
    let map = json!({
        "rig": rig.rig.name,
        "origin": rig.origin,
        "joints": rig.rig.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>(),
        "heights_m": model.skeleton.heights_m,
        "elements": elements,
    });
    Ok(RigScene { glb, map, loaded: rig.clone() })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The node names the map promises are the document's own (read back with the gltf crate).
    #[test]
    fn every_mapped_joint_is_a_node_of_the_glb() {
        for name in ["grass", "flower", "shrub"] {
            let rig = LoadedRig::embedded(name).unwrap().unwrap();
            let scene = bake(&rig).unwrap();
            let doc = gltf::Gltf::from_slice(&scene.glb).unwrap();
            let nodes: Vec<String> = doc.nodes().filter_map(|n| n.name().map(String::from)).collect();
            let mut want: Vec<String> = scene.map["joints"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_str().unwrap().to_string())
                .collect();
            for e in scene.map["elements"].as_array().unwrap() {
                for inst in e["instances"].as_array().unwrap() {
                    want.extend(inst.as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()));
                }
            }
            assert!(want.len() >= 4);
            for w in &want {
                assert!(nodes.contains(w), "{name}: {w} not in {nodes:?}");
            }
            assert_eq!(doc.skins().count(), 1, "{name}");
        }
    }

    #[test]
    fn the_flower_maps_its_leaf_layer_to_every_leaf_instance() {
        let rig = LoadedRig::embedded("flower").unwrap().unwrap();
        let scene = bake(&rig).unwrap();
        let els = scene.map["elements"].as_array().unwrap();
        assert!(!els.is_empty(), "the flower has secondary elements: {}", scene.map);
        assert!(els.iter().any(|e| !e["instances"].as_array().unwrap().is_empty()), "{}", scene.map);
    }

    #[test]
    fn rigs_that_cannot_be_shown_say_which_and_why() {
        assert_eq!(load("grass").unwrap().loaded.rig.name, "grass");
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.toml");
        std::fs::write(&bad, "name = [").unwrap();
        let missing = dir.path().join("missing.toml");
        for name in ["/dev/zero", "no-such-rig", bad.to_str().unwrap(), missing.to_str().unwrap()] {
            let e = load(name).unwrap_err();
            assert!(matches!(e, SceneError::Load { .. }), "{name}: {e}");
            assert!(e.to_string().starts_with(&format!("rig {name:?}: ")), "{e}");
        }
    }

    #[test]
    fn a_daemons_rig_name_is_an_embedded_rig_never_a_file() {
        assert_eq!(load_recorded("flower").unwrap().loaded.rig.name, "flower");
        // A valid rig file the name points at, and files a name must never make it read.
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("mine.toml");
        std::fs::write(&file, frond_formats::rig_files::EMBEDDED_RIGS[0].1).unwrap();
        assert!(load(file.to_str().unwrap()).is_ok(), "the file is a rig --rig would load");
        for name in [file.to_str().unwrap(), "/dev/zero", "/etc/passwd", "mine.toml"] {
            let e = load_recorded(name).unwrap_err();
            assert!(
                matches!(
                    &e,
                    SceneError::Load {
                        reason: frond_gltf::BakeError::Rig(
                            frond_formats::rig_files::RigFileError::NotEmbedded { .. }
                        ),
                        ..
                    }
                ),
                "{name}: {e}"
            );
        }
    }
}
