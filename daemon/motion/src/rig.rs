//! Plant rigs (seed 000, section 4): a 4-joint skeleton (joint 0 = root at the ground, 3 = top),
//! per-joint scaling factors `s_pitch(i)`, `s_yaw(i)`, `s_roll(i)` (Eq. 2-4), the number of
//! twistable joints `tau` (Eq. 4), default thumb ranges, the desired root bend range a
//! calibrated wrist is mapped onto (section 5.4), the jitter filter, and secondary elements
//! such as leaves and petals (section 5.3), each a simple short plant of its own; optionally the
//! bone names a VMC receiver is sent for the four joints (`[vmc] bones`, used by `frond-osc`).
//!
//! Rig files are TOML (see `rig-files/plants/*.toml`), read and written by
//! `frond_formats::rig_toml::RigText`. The text is parsed into the raw form [`RawRig`] (its serde
//! definition refuses unknown fields), which is validated here into [`Rig`], reporting every
//! problem with its path; [`RawRig::from_rig`] is the raw form a rig is written as.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::filter::FilterSpec;
use crate::mapping::MappingParams;
use crate::plausible::{MAX_ELEMENT_COUNT, MAX_RIG_SIZE_M};
use crate::problems::Problems;
use crate::rig_mesh::RawMesh;
pub use crate::rig_mesh::{MeshShape, MeshSpec};
use crate::sample::JOINTS;
use crate::sim::params::{NODES, RawSim, SimParams, node_heights_m};

/// Default number of twistable joints (seed 000: "In most of our experiments, we set tau = 2").
pub const DEFAULT_TAU: u8 = 2;
/// Default comfortable thumb ranges `G_R1..G_R3`, degrees, used when no calibration is given.
pub const DEFAULT_THUMB_RANGE_DEG: [f32; 3] = [60.0, 70.0, 60.0];
/// Largest `tau`: every joint above the root twists (Eq. 4 keeps `P_roll(0) = 0`).
pub const MAX_TAU: u8 = 3;
/// Most secondary elements a rig may have: their element ids are `1..=MAX_RIG_ELEMENTS`, and the
/// daemon gives the elements of its live stages ids above them.
pub const MAX_RIG_ELEMENTS: usize = frond_protocol::ElementId::RIG_LAYERS;
/// Largest `bend_range_deg`, degrees: a root bend past half a turn is not a bend.
pub const MAX_BEND_RANGE_DEG: f32 = 180.0;
/// Longest rig name, bytes (it heads status tables and take lists).
pub const MAX_RIG_NAME_BYTES: usize = 64;
/// Longest joint or element name, bytes (VMC bone names are shorter still: a rig with longer
/// joint names names its bones in a `[vmc]` table).
pub const MAX_NAME_BYTES: usize = 1024;
/// Longest VMC bone name, bytes (what `frond-osc` sends as an OSC string).
pub const MAX_VMC_BONE_NAME_BYTES: usize = 255;

/// One skeleton joint.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpec {
    /// Joint name (default `joint0`..`joint3`).
    pub name: String,
    /// Height of the joint above the ground in the rest pose, metres; strictly increasing.
    pub height_m: f32,
    /// `s_pitch(i)` (Eq. 2-3).
    pub s_pitch: f32,
    /// `s_yaw(i)` (Eq. 2-3).
    pub s_yaw: f32,
    /// `s_roll(i)` (Eq. 4).
    pub s_roll: f32,
}

/// A kind of secondary element (seed 000, section 5.3): leaves, petals. Each is a simple short
/// plant with its own 4-joint skeleton, animated by a separately authored secondary take and
/// attached to a joint of the main skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct ElementSpec {
    /// Element kind name, unique within the rig (`leaf`, `petal`).
    pub name: String,
    /// Main-skeleton joint it hangs from, 0..=3.
    pub attach_joint: u8,
    /// How many of them the plant has (>= 1); the seed assigns secondary takes to them at random.
    pub count: u32,
    /// Rest length of one element, metres (> 0).
    pub length_m: f32,
    /// Twistable joints of the element's own skeleton, 0..=3 (the seed: a leaf's root usually
    /// does not twist).
    pub tau: u8,
}

/// A validated rig.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// Rig name (`grass`).
    pub name: String,
    /// Free text.
    pub description: String,
    /// The four joints, root first.
    pub joints: [JointSpec; JOINTS],
    /// Twistable joints (Eq. 4), 0..=3.
    pub tau: u8,
    /// Default `G_R1..G_R3`, degrees, when no calibration is given.
    pub thumb_range_deg: [f32; 3],
    /// The root bend `[pitch, yaw]` (degrees, in `(0, 180]`) the plant should reach at a
    /// performer's comfortable wrist extremes (seed 000, section 5.4). With a calibration that
    /// measured the wrist (`wrist_range_deg`), it replaces `s_pitch(0)` and `s_yaw(0)` of Eq. 2
    /// by `bend / reach` on each side of the neutral; otherwise it is unused. `None`: Eq. 2 with
    /// the joint scales for every performer.
    pub bend_range_deg: Option<[f32; 2]>,
    /// Jitter filter for this rig.
    pub filter: FilterSpec,
    /// Secondary elements.
    pub elements: Vec<ElementSpec>,
    /// Where the rig's geometry comes from (`[mesh]` table; default a procedural blade).
    pub mesh: MeshSpec,
    /// Guided procedural motion applied live (seed 000, section 6.4, Eq. 8; `[guided]` table with
    /// `sigma_s` seconds and `s_g` gains per upper joint), or none.
    pub guided: Option<GuidedSpec>,
    /// Bone names sent for the joints, root first, by a VMC exporter (`[vmc] bones`, for
    /// receivers that accept only humanoid bone names); `None`: the joint names.
    pub vmc_bones: Option<[String; JOINTS]>,
    /// The simulated plant's parameters (seed 003, section 4.2; `[sim]` table, see
    /// [`crate::sim::params`]); defaults from the rig's geometry when the table is absent.
    pub sim: SimParams,
}

/// The `[guided]` table of a rig: Eq. 8's `sigma_i` (seconds) and `s_g(i)` for joints 1..3.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuidedSpec {
    /// `sigma_1..sigma_3`, seconds.
    pub sigma_s: [f64; 3],
    /// `s_g(1)..s_g(3)`.
    #[serde(default = "unit_gains")]
    pub s_g: [f64; 3],
}

fn unit_gains() -> [f64; 3] {
    [1.0; 3]
}

/// Why a rig file was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RigError {
    /// Not TOML, or a field of the wrong type or unknown (the toml message, with its line).
    #[error("rig: {0}")]
    Toml(String),
    /// Parsed, but some values are invalid; every problem is listed with its path.
    #[error("rig: {0}")]
    Invalid(Problems),
}

fn default_scale() -> f32 {
    1.0
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJoint {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    height_m: f32,
    #[serde(default = "default_scale")]
    s_pitch: f32,
    #[serde(default = "default_scale")]
    s_yaw: f32,
    #[serde(default = "default_scale")]
    s_roll: f32,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawElement {
    name: String,
    attach_joint: i64,
    #[serde(default = "default_count")]
    count: i64,
    length_m: f32,
    #[serde(default = "default_tau")]
    tau: i64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawVmc {
    bones: Vec<String>,
}

fn default_count() -> i64 {
    1
}

fn default_tau() -> i64 {
    DEFAULT_TAU as i64
}

/// A rig as written in a rig file, before validation: every key as the text gives it (integers
/// as `i64`, so that a wrong one is reported rather than wrapped), unknown keys refused. Public
/// for the reader in frond-formats (`rig_toml::RigText`); build a [`Rig`] with
/// [`RawRig::validate`], and write one from [`RawRig::from_rig`].
#[doc(hidden)]
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawRig {
    name: String,
    #[serde(default)]
    description: String,
    #[serde(default = "default_tau")]
    tau: i64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    thumb_range_deg: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    bend_range_deg: Option<[f32; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    filter: Option<String>,
    joints: Vec<RawJoint>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    elements: Vec<RawElement>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mesh: Option<RawMesh>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    guided: Option<GuidedSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    vmc: Option<RawVmc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sim: Option<RawSim>,
}

fn check_tau(p: &mut Problems, path: &str, tau: i64) -> u8 {
    if (0..=MAX_TAU as i64).contains(&tau) {
        tau as u8
    } else {
        p.push(path, format!("{tau} is out of range 0..={MAX_TAU}"));
        DEFAULT_TAU
    }
}

impl RawRig {
    /// Validates every field into a [`Rig`], collecting every problem with its path: the name,
    /// the ranges, the filter, the joints, the elements, the mesh, the guided parameters, the
    /// VMC bones and the simulation, in that order.
    pub fn validate(self) -> Result<Rig, Problems> {
        let mut p = Problems::default();
        self.check_name(&mut p);
        let tau = check_tau(&mut p, "tau", self.tau);
        let thumb_range_deg = self.thumb_range_deg.unwrap_or(DEFAULT_THUMB_RANGE_DEG);
        for (k, v) in thumb_range_deg.iter().enumerate() {
            p.thumb_range(format!("thumb_range_deg[{k}]"), *v);
        }
        self.check_bend_range(&mut p);
        let filter = match &self.filter {
            None => FilterSpec::None,
            Some(text) => text.parse().unwrap_or_else(|e| {
                p.push("filter", format!("{e}"));
                FilterSpec::None
            }),
        };
        let joints = self.validate_joints(&mut p);
        let elements = self.validate_elements(&mut p);
        let mesh = self.mesh.clone().unwrap_or_default().validate(&mut p, joints[JOINTS - 1].height_m);
        self.check_guided(&mut p);
        self.check_vmc(&mut p);

        let heights = node_heights_m(joints.each_ref().map(|j| j.height_m), &mesh);
        let sim = self.sim.clone().unwrap_or_default().validate(&mut p, heights);

        if !p.is_empty() {
            return Err(p);
        }
        let vmc_bones = self.vmc.map(|v| std::array::from_fn(|i| v.bones[i].clone()));
        Ok(Rig {
            name: self.name,
            description: self.description,
            joints,
            tau,
            thumb_range_deg,
            bend_range_deg: self.bend_range_deg,
            filter,
            elements,
            mesh,
            guided: self.guided,
            vmc_bones,
            sim,
        })
    }

    /// The rig name: a name (not blank, short, printable), and not a path: a take keeps its
    /// rig's name and exports look it up among the embedded rigs, where a '/' would make it read
    /// as a path.
    fn check_name(&self, p: &mut Problems) {
        if p.name("name", &self.name, MAX_RIG_NAME_BYTES)
            && (self.name.contains('/') || self.name.starts_with('.') || self.name.ends_with(".toml"))
        {
            p.push(
                "name",
                "contains '/', starts with '.' or ends in .toml; a rig name is a name, not a path",
            );
        }
    }

    /// `bend_range_deg`: each of pitch and yaw above 0 and at most [`MAX_BEND_RANGE_DEG`].
    fn check_bend_range(&self, p: &mut Problems) {
        for (k, v) in self.bend_range_deg.iter().flatten().enumerate() {
            if !(v.is_finite() && *v > 0.0 && *v <= MAX_BEND_RANGE_DEG) {
                p.push(
                    format!("bend_range_deg[{k}]"),
                    format!(
                        "the {} bend range must be above 0 and at most {MAX_BEND_RANGE_DEG} degrees, found {v}",
                        ["pitch", "yaw"][k]
                    ),
                );
            }
        }
    }

    /// The four joints: unique names, heights above ground and strictly increasing, scales in
    /// range. Missing joints stay at their defaults (the count is itself a problem).
    fn validate_joints(&self, p: &mut Problems) -> [JointSpec; JOINTS] {
        if self.joints.len() != JOINTS {
            p.push("joints", format!("expected {JOINTS} joints, found {}", self.joints.len()));
        }
        let mut joints: [JointSpec; JOINTS] = std::array::from_fn(|i| JointSpec {
            name: format!("joint{i}"),
            height_m: i as f32,
            s_pitch: 1.0,
            s_yaw: 1.0,
            s_roll: 1.0,
        });
        let mut prev_height: Option<f32> = None;
        for (i, raw) in self.joints.iter().enumerate().take(JOINTS) {
            let path = |f: &str| format!("joints[{i}].{f}");
            let name = raw.name.clone().unwrap_or_else(|| format!("joint{i}"));
            if p.name(path("name"), &name, MAX_NAME_BYTES)
                && let Some(j) = joints[..i].iter().position(|j| j.name == name)
            {
                p.push(path("name"), format!("`{name}` is already the name of joints[{j}]"));
            }
            if p.within(path("height_m"), raw.height_m, -MAX_RIG_SIZE_M, MAX_RIG_SIZE_M, "a height (metres)")
            {
                if i == 0 && raw.height_m < 0.0 {
                    p.push(
                        path("height_m"),
                        format!("the root must not be below ground, found {}", raw.height_m),
                    );
                }
                match prev_height {
                    Some(prev) if raw.height_m <= prev => p.push(
                        path("height_m"),
                        format!("{} must be above joints[{}].height_m ({prev})", raw.height_m, i - 1),
                    ),
                    _ => {}
                }
                prev_height = Some(raw.height_m);
            } else {
                prev_height = None;
            }
            p.joint_scale(path("s_pitch"), raw.s_pitch);
            p.joint_scale(path("s_yaw"), raw.s_yaw);
            p.joint_scale(path("s_roll"), raw.s_roll);
            joints[i] = JointSpec {
                name,
                height_m: raw.height_m,
                s_pitch: raw.s_pitch,
                s_yaw: raw.s_yaw,
                s_roll: raw.s_roll,
            };
        }
        joints
    }

    /// The secondary elements: at most [`MAX_RIG_ELEMENTS`], each with a unique name, a joint to
    /// hang from, a count, a length and its own `tau`.
    fn validate_elements(&self, p: &mut Problems) -> Vec<ElementSpec> {
        if self.elements.len() > MAX_RIG_ELEMENTS {
            p.push(
                "elements",
                format!("{} secondary elements; at most {MAX_RIG_ELEMENTS} are allowed", self.elements.len()),
            );
        }
        let mut elements = Vec::with_capacity(self.elements.len().min(MAX_RIG_ELEMENTS));
        for (e, raw) in self.elements.iter().enumerate().take(MAX_RIG_ELEMENTS) {
            let path = |f: &str| format!("elements[{e}].{f}");
            if p.name(path("name"), &raw.name, MAX_NAME_BYTES)
                && let Some(j) = self.elements[..e].iter().position(|o| o.name == raw.name)
            {
                p.push(path("name"), format!("`{}` is already the name of elements[{j}]", raw.name));
            }
            let attach_joint = if (0..JOINTS as i64).contains(&raw.attach_joint) {
                raw.attach_joint as u8
            } else {
                p.push(
                    path("attach_joint"),
                    format!("{} is out of range 0..={}", raw.attach_joint, JOINTS - 1),
                );
                0
            };
            let count = if (1..=i64::from(MAX_ELEMENT_COUNT)).contains(&raw.count) {
                raw.count as u32
            } else {
                p.push(path("count"), format!("{} must be between 1 and {MAX_ELEMENT_COUNT}", raw.count));
                1
            };
            if p.positive(path("length_m"), raw.length_m) && raw.length_m > MAX_RIG_SIZE_M {
                p.push(
                    path("length_m"),
                    format!("must be at most {MAX_RIG_SIZE_M} metres, found {}", raw.length_m),
                );
            }
            let tau = check_tau(p, &path("tau"), raw.tau);
            elements.push(ElementSpec {
                name: raw.name.clone(),
                attach_joint,
                count,
                length_m: raw.length_m,
                tau,
            });
        }
        elements
    }

    /// `[guided]`: every `sigma_s` and `s_g` between 0 and 60.
    fn check_guided(&self, p: &mut Problems) {
        if let Some(g) = &self.guided {
            for (key, values) in [("guided.sigma_s", g.sigma_s), ("guided.s_g", g.s_g)] {
                for (i, v) in values.iter().enumerate() {
                    if !(v.is_finite() && (0.0..=60.0).contains(v)) {
                        p.push(format!("{key}[{i}]"), format!("{v} must be between 0 and 60"));
                    }
                }
            }
        }
    }

    /// `[vmc] bones`: one name per joint, each 1 to [`MAX_VMC_BONE_NAME_BYTES`] printable bytes.
    fn check_vmc(&self, p: &mut Problems) {
        if let Some(vmc) = &self.vmc {
            if vmc.bones.len() != JOINTS {
                p.push("vmc.bones", format!("expected {JOINTS} names, found {}", vmc.bones.len()));
            }
            for (i, b) in vmc.bones.iter().enumerate() {
                if b.is_empty() || b.len() > MAX_VMC_BONE_NAME_BYTES {
                    p.push(
                        format!("vmc.bones[{i}]"),
                        format!("must be 1 to {MAX_VMC_BONE_NAME_BYTES} bytes"),
                    );
                } else {
                    p.name(format!("vmc.bones[{i}]"), b, MAX_VMC_BONE_NAME_BYTES);
                }
            }
        }
    }

    /// The raw form that validates back to `rig` ([`RawRig::validate`] gives it again): every
    /// key written, except what the rig does not have (`bend_range_deg`, `[guided]`, `[vmc]`)
    /// and a `[sim]` table at the defaults for its geometry.
    pub fn from_rig(rig: &Rig) -> RawRig {
        RawRig {
            name: rig.name.clone(),
            description: rig.description.clone(),
            tau: rig.tau as i64,
            thumb_range_deg: Some(rig.thumb_range_deg),
            bend_range_deg: rig.bend_range_deg,
            filter: Some(rig.filter.to_string()),
            joints: rig
                .joints
                .iter()
                .map(|j| RawJoint {
                    name: Some(j.name.clone()),
                    height_m: j.height_m,
                    s_pitch: j.s_pitch,
                    s_yaw: j.s_yaw,
                    s_roll: j.s_roll,
                })
                .collect(),
            elements: rig
                .elements
                .iter()
                .map(|e| RawElement {
                    name: e.name.clone(),
                    attach_joint: e.attach_joint as i64,
                    count: e.count as i64,
                    length_m: e.length_m,
                    tau: e.tau as i64,
                })
                .collect(),
            mesh: Some(RawMesh::from_spec(&rig.mesh)),
            guided: rig.guided,
            vmc: rig.vmc_bones.as_ref().map(|b| RawVmc { bones: b.to_vec() }),
            sim: RawSim::from_params(&rig.sim, rig.sim_node_heights_m()),
        }
    }
}

impl Rig {
    /// The mapping parameters (seed 000, Eq. 2-4): per joint `[s_pitch, s_yaw, s_roll]`, `tau`,
    /// and the desired root bend range (section 5.4).
    pub fn mapping(&self) -> MappingParams {
        MappingParams {
            scale: std::array::from_fn(|i| {
                let j = &self.joints[i];
                [j.s_pitch, j.s_yaw, j.s_roll]
            }),
            tau: self.tau,
            bend_range_deg: self.bend_range_deg,
        }
    }

    /// Rest heights of the simulated plant's nodes (joints 0..3 and the top, `mesh.height_m`),
    /// metres (see [`crate::sim::node_heights_m`]).
    pub fn sim_node_heights_m(&self) -> [f64; NODES] {
        node_heights_m(self.joints.each_ref().map(|j| j.height_m), &self.mesh)
    }

    /// The joint names, root first (for the protocol `Hello` and take headers).
    pub fn joint_names(&self) -> Vec<String> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }
}

#[cfg(test)]
impl Rig {
    /// For the unit tests, which cannot read rig text (that is frond-formats): the rig that
    /// `name = "{name}"`, four joints at `heights_m` and the `[mesh]` table of `mesh` read as,
    /// every other key at its default. Checked to be what validation gives for that raw form.
    pub(crate) fn for_tests(name: &str, heights_m: [f32; JOINTS], mesh: MeshSpec) -> Rig {
        let rig = Rig {
            name: name.to_string(),
            description: String::new(),
            joints: std::array::from_fn(|i| JointSpec {
                name: format!("joint{i}"),
                height_m: heights_m[i],
                s_pitch: 1.0,
                s_yaw: 1.0,
                s_roll: 1.0,
            }),
            tau: DEFAULT_TAU,
            thumb_range_deg: DEFAULT_THUMB_RANGE_DEG,
            bend_range_deg: None,
            filter: FilterSpec::None,
            elements: Vec::new(),
            sim: SimParams::defaults_for(node_heights_m(heights_m, &mesh)),
            mesh,
            guided: None,
            vmc_bones: None,
        };
        assert_eq!(RawRig::from_rig(&rig).validate().as_ref(), Ok(&rig), "not a valid rig");
        rig
    }
}
