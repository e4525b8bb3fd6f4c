//! USD (UsdSkel) text layers (`.usda`), the pipeline format of film studios: the plant's skinned
//! mesh, its skeleton and the take's animation, in one `SkelRoot`.
//!
//! Layout: `/RIG` (a `SkelRoot`) holds `Skeleton` (the rig's four joints `root`,
//! `root/lower`, ... and each secondary element instance's four joints under its attach joint,
//! `.../leaf0_joint0`, ...), its `Animation` (a `SkelAnimation` of the four main joints: constant
//! translations straight up the stem, rotations time-sampled at every frame, unit scales; the
//! element joints keep their rest transforms) and `Mesh` (stem and elements, triangles, vertex
//! normals, four joint influences per vertex). Y up, metres (`upAxis = "Y"`, `metersPerUnit =
//! 1`), time codes are frames at the take's rate. frond's joint rotation `R = R_yaw R_pitch
//! R_roll` relative to the parent is the joint's local rotation unchanged (USD is right-handed,
//! as frond); quaternions are written `(real, i, j, k)` as USD's text format wants; matrices row
//! by row with the translation in the last row (USD's row-vector convention). Pure: builds text.

use std::fmt::Write;

use glam::{Mat4, Quat, Vec3};

use frond_motion::mesh::{PlantModel, SkinnedMesh};
use frond_motion::sample::JOINTS;
use frond_motion::skeleton::joint_rotation;

/// What a USD layer of a take says about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct UsdTake<'a> {
    /// Prim name of the plant (the rig's name, made a valid USD identifier).
    pub name: &'a str,
    /// The rig's joint names, root first.
    pub joint_names: &'a [String; JOINTS],
    /// Frames per second of the animation (time codes per second).
    pub fps: f64,
    /// Free text recorded in the layer's `customLayerData` (take, rig, timecode, ...).
    pub info: &'a [(&'a str, String)],
}

/// A USD identifier from any name: letters, digits and `_`, not starting with a digit.
pub fn identifier(name: &str) -> String {
    let mut s: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, '_');
    }
    s
}

/// `text` as a USDA double-quoted string: `\\` and `\"` escaped, control characters as
/// `\xHH` per UTF-8 byte (the C escapes Sdf's text format reads; Rust's `{:?}` would write
/// `\u{1b}`, which it does not), everything else as it is (USDA is UTF-8). Values come from
/// take headers, which anyone may have written.
pub fn usda_string(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 2);
    out.push('"');
    for c in text.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            c if c.is_control() => {
                let mut utf8 = [0u8; 4];
                for b in c.encode_utf8(&mut utf8).bytes() {
                    let _ = write!(out, "\\x{b:02x}");
                }
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// One skeleton joint: its path, rest transform (relative to its parent) and bind transform
/// (world).
struct Joint {
    path: String,
    rest: Mat4,
    bind: Mat4,
}

fn joints(take: &UsdTake<'_>, model: &PlantModel) -> Vec<Joint> {
    let h = model.skeleton.heights_m;
    let mut out: Vec<Joint> = Vec::with_capacity(JOINTS * (1 + model.elements.len()));
    let mut path = String::new();
    let mut world = Mat4::IDENTITY;
    for j in 0..JOINTS {
        if j > 0 {
            path.push('/');
        }
        path.push_str(&identifier(&take.joint_names[j]));
        let below = if j == 0 { 0.0 } else { h[j - 1] };
        let rest = Mat4::from_translation(Vec3::new(0.0, h[j] - below, 0.0));
        world *= rest;
        out.push(Joint { path: path.clone(), rest, bind: world });
    }
    for e in &model.elements {
        let attach = &out[e.attach_joint as usize];
        let (mut path, mut world) = (attach.path.clone(), attach.bind);
        let eh = e.skeleton.heights_m;
        let prefix = identifier(&format!("{}{}", e.name, e.instance));
        for k in 0..JOINTS {
            let rest = if k == 0 {
                e.attach_matrix() * Mat4::from_translation(Vec3::new(0.0, eh[0], 0.0))
            } else {
                Mat4::from_translation(Vec3::new(0.0, eh[k] - eh[k - 1], 0.0))
            };
            path.push_str(&format!("/{prefix}_joint{k}"));
            world *= rest;
            out.push(Joint { path: path.clone(), rest, bind: world });
        }
    }
    out
}

fn push_matrix(out: &mut String, m: &Mat4) {
    // Rows of USD's matrix are glam's columns (USD multiplies row vectors on the left).
    let c = m.to_cols_array_2d();
    let _ = write!(
        out,
        "( ({}, {}, {}, {}), ({}, {}, {}, {}), ({}, {}, {}, {}), ({}, {}, {}, {}) )",
        c[0][0],
        c[0][1],
        c[0][2],
        c[0][3],
        c[1][0],
        c[1][1],
        c[1][2],
        c[1][3],
        c[2][0],
        c[2][1],
        c[2][2],
        c[2][3],
        c[3][0],
        c[3][1],
        c[3][2],
        c[3][3]
    );
}

fn push_list<T>(out: &mut String, items: impl IntoIterator<Item = T>, mut each: impl FnMut(&mut String, T)) {
    out.push('[');
    for (i, item) in items.into_iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        each(out, item);
    }
    out.push(']');
}

fn push_quat(out: &mut String, q: Quat) {
    let _ = write!(out, "({}, {}, {}, {})", q.w, q.x, q.y, q.z);
}

/// The mesh at rest in world space, with its joint influences (4 per vertex).
#[derive(Default)]
struct MeshArrays {
    points: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    indices: Vec<u32>,
    joint_indices: Vec<[u32; 4]>,
    joint_weights: Vec<[f32; 4]>,
}

impl MeshArrays {
    fn add(&mut self, mesh: &SkinnedMesh, to_world: Mat4, first_joint: u32) {
        let base = self.points.len() as u32;
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            self.points.push(to_world.transform_point3(Vec3::from(*p)).to_array());
            self.normals.push(to_world.transform_vector3(Vec3::from(*n)).normalize_or_zero().to_array());
        }
        self.indices.extend(mesh.indices.iter().map(|i| base + i));
        for w in &mesh.weights {
            self.joint_indices.push(std::array::from_fn(|k| first_joint + k as u32));
            self.joint_weights.push(*w);
        }
    }

    fn of(model: &PlantModel, joints: &[Joint]) -> MeshArrays {
        let mut m = MeshArrays::default();
        m.add(&model.stem, Mat4::IDENTITY, 0);
        for (i, e) in model.elements.iter().enumerate() {
            let first = JOINTS * (1 + i);
            // The element's geometry grows from its root (its joint 0 is `heights_m[0]` up it).
            let to_world =
                joints[first].bind * Mat4::from_translation(Vec3::new(0.0, -e.skeleton.heights_m[0], 0.0));
            m.add(&e.mesh, to_world, first as u32);
        }
        m
    }
}

/// Writes the layer: `poses[k]` is frame `k` (time code `k`) of the main joints.
pub fn write_usda(take: &UsdTake<'_>, model: &PlantModel, poses: &[[[f32; 3]; JOINTS]], out: &mut String) {
    out.clear();
    let root = identifier(take.name);
    let joints = joints(take, model);
    let end = poses.len().saturating_sub(1);
    let _ = writeln!(out, "#usda 1.0\n(");
    let _ = writeln!(out, "    defaultPrim = \"{root}\"");
    out.push_str("    customLayerData = {\n");
    for (k, v) in take.info {
        let _ = writeln!(out, "        string {} = {}", identifier(k), usda_string(v));
    }
    out.push_str("    }\n");
    let _ = writeln!(out, "    doc = \"frond {}\"", env!("CARGO_PKG_VERSION"));
    let _ = writeln!(out, "    metersPerUnit = 1\n    upAxis = \"Y\"");
    let _ = writeln!(out, "    startTimeCode = 0\n    endTimeCode = {end}");
    let _ = writeln!(out, "    timeCodesPerSecond = {}\n    framesPerSecond = {}\n)\n", take.fps, take.fps);
    let _ = writeln!(out, "def SkelRoot \"{root}\" (\n    kind = \"component\"\n)\n{{");
    // Skeleton.
    out.push_str(
        "    def Skeleton \"Skeleton\" (\n        prepend apiSchemas = [\"SkelBindingAPI\"]\n    )\n    {\n",
    );
    out.push_str("        uniform token[] joints = ");
    push_list(out, &joints, |o, j| {
        let _ = write!(o, "{:?}", j.path);
    });
    out.push_str("\n        uniform matrix4d[] bindTransforms = ");
    push_list(out, &joints, |o, j| push_matrix(o, &j.bind));
    out.push_str("\n        uniform matrix4d[] restTransforms = ");
    push_list(out, &joints, |o, j| push_matrix(o, &j.rest));
    let _ = writeln!(out, "\n        rel skel:animationSource = </{root}/Skeleton/Animation>\n");
    // Animation of the main joints.
    out.push_str("        def SkelAnimation \"Animation\"\n        {\n            uniform token[] joints = ");
    push_list(out, &joints[..JOINTS], |o, j| {
        let _ = write!(o, "{:?}", j.path);
    });
    out.push_str("\n            float3[] translations = ");
    push_list(out, &joints[..JOINTS], |o, j| {
        let t = j.rest.w_axis;
        let _ = write!(o, "({}, {}, {})", t.x, t.y, t.z);
    });
    out.push_str("\n            half3[] scales = ");
    push_list(out, 0..JOINTS, |o, _| o.push_str("(1, 1, 1)"));
    out.push_str("\n            quatf[] rotations.timeSamples = {\n");
    for (k, pose) in poses.iter().enumerate() {
        let _ = write!(out, "                {k}: ");
        push_list(out, pose.iter(), |o, a| push_quat(o, joint_rotation(*a)));
        out.push_str(",\n");
    }
    out.push_str("            }\n        }\n    }\n\n");
    // Mesh.
    let MeshArrays { points, normals, indices, joint_indices: ji, joint_weights: jw } =
        MeshArrays::of(model, &joints);
    out.push_str(
        "    def Mesh \"Mesh\" (\n        prepend apiSchemas = [\"SkelBindingAPI\"]\n    )\n    {\n",
    );
    out.push_str("        int[] faceVertexCounts = ");
    push_list(out, 0..indices.len() / 3, |o, _| o.push('3'));
    out.push_str("\n        int[] faceVertexIndices = ");
    push_list(out, &indices, |o, i| {
        let _ = write!(o, "{i}");
    });
    out.push_str("\n        point3f[] points = ");
    push_list(out, &points, |o, p| {
        let _ = write!(o, "({}, {}, {})", p[0], p[1], p[2]);
    });
    out.push_str("\n        normal3f[] normals = ");
    push_list(out, &normals, |o, n| {
        let _ = write!(o, "({}, {}, {})", n[0], n[1], n[2]);
    });
    out.push_str(" (\n            interpolation = \"vertex\"\n        )\n");
    out.push_str("        uniform token subdivisionScheme = \"none\"\n");
    out.push_str("        int[] primvars:skel:jointIndices = ");
    push_list(out, ji.iter().flatten(), |o, i| {
        let _ = write!(o, "{i}");
    });
    out.push_str(" (\n            elementSize = 4\n            interpolation = \"vertex\"\n        )\n");
    out.push_str("        float[] primvars:skel:jointWeights = ");
    push_list(out, jw.iter().flatten(), |o, w| {
        let _ = write!(o, "{w}");
    });
    out.push_str(" (\n            elementSize = 4\n            interpolation = \"vertex\"\n        )\n");
    out.push_str("        matrix4d primvars:skel:geomBindTransform = ");
    push_matrix(out, &Mat4::IDENTITY);
    let _ = writeln!(out, "\n        rel skel:skeleton = </{root}/Skeleton>\n    }}\n}}");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers_are_valid_usd_names() {
        assert_eq!(identifier("grass"), "grass");
        assert_eq!(identifier("stem low"), "stem_low");
        assert_eq!(identifier("3leaf"), "_3leaf");
        assert_eq!(identifier(""), "_");
    }

    #[test]
    fn strings_use_the_escapes_usda_reads() {
        assert_eq!(usda_string("grass"), "\"grass\"");
        assert_eq!(usda_string("a\"b\\c"), r#""a\"b\\c""#);
        assert_eq!(usda_string("a\u{1b}[31m\nz"), r#""a\x1b[31m\x0az""#);
        assert_eq!(usda_string("p\u{85}é"), r#""p\xc2\x85é""#);
    }
}
