//! The glTF document under construction: a `gltf_json::Root` and its one binary buffer, with
//! helpers that write typed data and the accessors over it (min/max always set, from the exact
//! values written), the plant assets (one mesh, material and inverse-bind-matrix accessor shared
//! by every plant of a document) and plant instances (a node hierarchy and a skin each).

use glam::{Mat4, Quat};
use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use json::{Index, accessor, buffer, mesh};
use serde_json::Value;

use frond_motion::JOINTS;
use frond_motion::mesh::PlantModel;

use crate::bind::{BindGeometry, bind_geometry};
pub use crate::bind::{ElementRig, pack_influences};

/// A document being built: JSON plus the binary buffer (buffer 0).
pub struct DocBuilder {
    /// The JSON side.
    pub root: json::Root,
    /// The binary buffer; every view starts 4-byte aligned.
    pub bin: Vec<u8>,
    /// Nodes of the default scene.
    pub scene_nodes: Vec<Index<json::Node>>,
}

fn floats(v: &[f32]) -> Value {
    Value::Array(v.iter().map(|&x| Value::from(f64::from(x))).collect())
}

fn ints(v: &[u32]) -> Value {
    Value::Array(v.iter().map(|&x| Value::from(x)).collect())
}

/// Running per-component minimum and maximum of `N`-component float data.
struct Bounds<const N: usize> {
    min: [f32; N],
    max: [f32; N],
}

impl<const N: usize> Bounds<N> {
    fn new() -> Self {
        Bounds { min: [f32::INFINITY; N], max: [f32::NEG_INFINITY; N] }
    }
    fn add(&mut self, v: &[f32; N]) {
        for (c, &x) in v.iter().enumerate() {
            self.min[c] = self.min[c].min(x);
            self.max[c] = self.max[c].max(x);
        }
    }
}

impl DocBuilder {
    /// An empty document writing into `bin` (cleared; its capacity is reused).
    pub fn new(mut bin: Vec<u8>) -> Self {
        bin.clear();
        let root = json::Root {
            asset: json::Asset {
                generator: Some(crate::GENERATOR.to_string()),
                version: "2.0".to_string(),
                copyright: None,
                extensions: None,
                extras: None,
                min_version: None,
            },
            ..Default::default()
        };
        DocBuilder { root, bin, scene_nodes: Vec::new() }
    }

    fn align4(&mut self) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
    }

    fn put_f32s(&mut self, v: &[f32]) {
        for x in v {
            self.bin.extend_from_slice(&x.to_le_bytes());
        }
    }

    /// A view over `bin[start..]`.
    fn view(&mut self, start: usize, target: Option<buffer::Target>) -> Index<buffer::View> {
        let len = self.bin.len() - start;
        self.root.push(buffer::View {
            buffer: Index::new(0),
            byte_length: USize64(len as u64),
            byte_offset: Some(USize64(start as u64)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: None,
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn accessor(
        &mut self,
        view: Index<buffer::View>,
        byte_offset: usize,
        count: usize,
        component: accessor::ComponentType,
        type_: accessor::Type,
        min: Value,
        max: Value,
        name: Option<String>,
    ) -> Index<json::Accessor> {
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: (byte_offset > 0).then_some(USize64(byte_offset as u64)),
            count: USize64(count as u64),
            component_type: Valid(accessor::GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Valid(type_),
            min: Some(min),
            max: Some(max),
            name,
            normalized: false,
            sparse: None,
        })
    }

    /// A float accessor of `N`-component elements in its own view.
    fn float_attr<const N: usize>(
        &mut self,
        data: &[[f32; N]],
        type_: accessor::Type,
        target: Option<buffer::Target>,
        name: &str,
    ) -> Index<json::Accessor> {
        self.align4();
        let start = self.bin.len();
        let mut b = Bounds::<N>::new();
        for v in data {
            self.put_f32s(v);
            b.add(v);
        }
        let view = self.view(start, target);
        self.accessor(
            view,
            0,
            data.len(),
            accessor::ComponentType::F32,
            type_,
            floats(&b.min),
            floats(&b.max),
            Some(name.to_string()),
        )
    }

    /// Animation key times (a SCALAR float accessor in its own view).
    pub fn times(&mut self, times_s: &[f64]) -> Index<json::Accessor> {
        let t: Vec<[f32; 1]> = times_s.iter().map(|&t| [t as f32]).collect();
        self.float_attr(&t, accessor::Type::Scalar, None, "time")
    }

    /// The plant's mesh, material and inverse bind matrices (see [`PlantAssets`]).
    pub fn plant_assets(
        &mut self,
        model: &PlantModel,
        joint_names: &[String; JOINTS],
        element_names: &[String],
    ) -> PlantAssets {
        let BindGeometry { positions, normals, joints, weights, indices, ibm, elements } =
            bind_geometry(model, element_names);
        let joint_count = ibm.len();

        let pos =
            self.float_attr(&positions, accessor::Type::Vec3, Some(buffer::Target::ArrayBuffer), "position");
        let nor =
            self.float_attr(&normals, accessor::Type::Vec3, Some(buffer::Target::ArrayBuffer), "normal");
        let wgt =
            self.float_attr(&weights, accessor::Type::Vec4, Some(buffer::Target::ArrayBuffer), "weights");
        let jnt = self.joints_attr(&joints, joint_count);
        let idx = self.indices(&indices, positions.len());

        let ibm = self.inverse_bind_matrices(&ibm);

        let mesh = self.plant_mesh([pos, nor, jnt, wgt], idx);
        PlantAssets {
            mesh,
            ibm,
            heights_m: model.skeleton.heights_m,
            joint_names: joint_names.clone(),
            elements,
            vertices: positions.len(),
        }
    }

    /// The inverse bind matrices as a `MAT4` accessor: column-major, the bottom row forced to
    /// exactly (0, 0, 0, 1) (an affine inverse can leave -0.0 or rounding noise there).
    fn inverse_bind_matrices(&mut self, ibm: &[Mat4]) -> Index<json::Accessor> {
        let mats: Vec<[f32; 16]> = ibm
            .iter()
            .map(|m| {
                let mut a = m.to_cols_array();
                a[3] = 0.0;
                a[7] = 0.0;
                a[11] = 0.0;
                a[15] = 1.0;
                a.map(|x| if x == 0.0 { 0.0 } else { x })
            })
            .collect();
        self.float_attr(&mats, accessor::Type::Mat4, None, "inverse_bind_matrices")
    }

    /// The plant's material and its one skinned mesh over the accessors `[positions, normals,
    /// joints, weights]` and `indices`.
    fn plant_mesh(
        &mut self,
        [pos, nor, jnt, wgt]: [Index<json::Accessor>; 4],
        idx: Index<json::Accessor>,
    ) -> Index<json::Mesh> {
        let material = self.root.push(json::Material {
            name: Some("plant".to_string()),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([0.30, 0.55, 0.20, 1.0]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.85),
                ..Default::default()
            },
            ..Default::default()
        });
        let mut attributes = std::collections::BTreeMap::new();
        attributes.insert(Valid(mesh::Semantic::Positions), pos);
        attributes.insert(Valid(mesh::Semantic::Normals), nor);
        attributes.insert(Valid(mesh::Semantic::Joints(0)), jnt);
        attributes.insert(Valid(mesh::Semantic::Weights(0)), wgt);
        self.root.push(json::Mesh {
            extensions: None,
            extras: None,
            name: Some("plant".to_string()),
            primitives: vec![mesh::Primitive {
                attributes,
                extensions: None,
                extras: None,
                indices: Some(idx),
                material: Some(material),
                mode: Valid(mesh::Mode::Triangles),
                targets: None,
            }],
            weights: None,
        })
    }

    fn joints_attr(&mut self, joints: &[[u16; 4]], joint_count: usize) -> Index<json::Accessor> {
        self.align4();
        let start = self.bin.len();
        let mut min = [u32::MAX; 4];
        let mut max = [0u32; 4];
        let small = joint_count <= 256;
        for j in joints {
            for c in 0..4 {
                if small {
                    self.bin.push(j[c] as u8);
                } else {
                    self.bin.extend_from_slice(&j[c].to_le_bytes());
                }
                min[c] = min[c].min(u32::from(j[c]));
                max[c] = max[c].max(u32::from(j[c]));
            }
        }
        let view = self.view(start, Some(buffer::Target::ArrayBuffer));
        let ct = if small { accessor::ComponentType::U8 } else { accessor::ComponentType::U16 };
        self.accessor(
            view,
            0,
            joints.len(),
            ct,
            accessor::Type::Vec4,
            ints(&min),
            ints(&max),
            Some("joints".to_string()),
        )
    }

    fn indices(&mut self, indices: &[u32], vertices: usize) -> Index<json::Accessor> {
        self.align4();
        let start = self.bin.len();
        let small = vertices <= usize::from(u16::MAX);
        for &i in indices {
            if small {
                self.bin.extend_from_slice(&(i as u16).to_le_bytes());
            } else {
                self.bin.extend_from_slice(&i.to_le_bytes());
            }
        }
        let view = self.view(start, Some(buffer::Target::ElementArrayBuffer));
        let min = indices.iter().copied().min().unwrap_or(0);
        let max = indices.iter().copied().max().unwrap_or(0);
        let ct = if small { accessor::ComponentType::U16 } else { accessor::ComponentType::U32 };
        self.accessor(
            view,
            0,
            indices.len(),
            ct,
            accessor::Type::Scalar,
            ints(&[min]),
            ints(&[max]),
            Some("indices".to_string()),
        )
    }

    fn node(
        &mut self,
        name: String,
        translation: [f32; 3],
        rotation: [f32; 4],
        scale: f32,
    ) -> Index<json::Node> {
        self.root.push(json::Node {
            name: Some(name),
            translation: (translation != [0.0; 3]).then_some(translation),
            rotation: (rotation != [0.0, 0.0, 0.0, 1.0]).then_some(json::scene::UnitQuaternion(rotation)),
            scale: (scale != 1.0).then_some([scale; 3]),
            ..Default::default()
        })
    }

    fn add_child(&mut self, parent: Index<json::Node>, child: Index<json::Node>) {
        self.root.nodes[parent.value()].children.get_or_insert_with(Vec::new).push(child);
    }

    /// `n` plants, plant `i` at `placement(i)` and named `<rig>_<i>` with `i` zero-padded to
    /// `n`'s digits (`grass_03`): the names by which the Blender add-on finds a field's or a
    /// grove's plants.
    pub fn plants(
        &mut self,
        assets: &PlantAssets,
        rig_name: &str,
        n: usize,
        placement: impl Fn(usize) -> Placement,
    ) -> Vec<PlantNodes> {
        let digits = n.max(1).to_string().len();
        (0..n).map(|i| self.plant(assets, &format!("{rig_name}_{i:0digits$}"), &placement(i))).collect()
    }

    /// One plant: a root node placed in the scene, the rig's joints under it (named after the
    /// rig's joints), each secondary element instance's skeleton under its attach joint, a skin
    /// over all of them, and a root-level node with the shared mesh and that skin.
    pub fn plant(&mut self, assets: &PlantAssets, name: &str, placement: &Placement) -> PlantNodes {
        let root = self.node(name.to_string(), placement.translation_m, placement.rotation, placement.scale);
        let h = assets.heights_m;
        let mut main = [root; JOINTS];
        let mut parent = root;
        for i in 0..JOINTS {
            let below = if i == 0 { 0.0 } else { h[i - 1] };
            main[i] =
                self.node(assets.joint_names[i].clone(), [0.0, h[i] - below, 0.0], [0.0, 0.0, 0.0, 1.0], 1.0);
            self.add_child(parent, main[i]);
            parent = main[i];
        }
        let mut elements = Vec::with_capacity(assets.elements.len());
        for e in &assets.elements {
            let attach = self.node(e.name.clone(), e.offset_m, e.rotation, 1.0);
            self.add_child(main[e.attach_joint], attach);
            let mut joints = [attach; JOINTS];
            let mut parent = attach;
            let mut below = 0.0;
            for (k, (joint, &h)) in joints.iter_mut().zip(&e.heights_m).enumerate() {
                *joint = self.node(
                    format!("{}_joint{k}", e.name),
                    [0.0, h - below, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                    1.0,
                );
                self.add_child(parent, *joint);
                parent = *joint;
                below = h;
            }
            elements.push(joints);
        }
        let mut skin_joints: Vec<Index<json::Node>> = main.to_vec();
        skin_joints.extend(elements.iter().flat_map(|j| j.iter().copied()));
        let skin = self.root.push(json::Skin {
            extensions: None,
            extras: None,
            inverse_bind_matrices: Some(assets.ibm),
            joints: skin_joints,
            name: Some(name.to_string()),
            skeleton: Some(root),
        });
        let mesh_node = self.root.push(json::Node {
            name: Some(format!("{name}_mesh")),
            mesh: Some(assets.mesh),
            skin: Some(skin),
            ..Default::default()
        });
        self.scene_nodes.push(root);
        self.scene_nodes.push(mesh_node);
        PlantNodes { root, main, elements }
    }

    /// Starts the data of one animation: every output accessor goes into one view.
    pub fn begin_animation(&mut self, input: Index<json::Accessor>) -> AnimationBuilder {
        self.align4();
        let start = self.bin.len();
        let view = self.view(start, None);
        AnimationBuilder { input, view, start, channels: Vec::new(), samplers: Vec::new() }
    }

    /// A LINEAR rotation channel for `node` with unit quaternions `[x, y, z, w]`, one per key.
    pub fn rotation_channel(
        &mut self,
        anim: &mut AnimationBuilder,
        node: Index<json::Node>,
        quats: &[[f32; 4]],
    ) {
        let offset = self.bin.len() - anim.start;
        let mut b = Bounds::<4>::new();
        for q in quats {
            self.put_f32s(q);
            b.add(q);
        }
        let output = self.accessor(
            anim.view,
            offset,
            quats.len(),
            accessor::ComponentType::F32,
            accessor::Type::Vec4,
            floats(&b.min),
            floats(&b.max),
            None,
        );
        let sampler = Index::new(anim.samplers.len() as u32);
        anim.samplers.push(json::animation::Sampler {
            extensions: None,
            extras: None,
            input: anim.input,
            interpolation: Valid(json::animation::Interpolation::Linear),
            output,
        });
        anim.channels.push(json::animation::Channel {
            sampler,
            target: json::animation::Target {
                extensions: None,
                extras: None,
                node,
                path: Valid(json::animation::Property::Rotation),
            },
            extensions: None,
            extras: None,
        });
    }

    /// Finishes an animation.
    pub fn end_animation(
        &mut self,
        anim: AnimationBuilder,
        name: &str,
        extras: Option<Box<json::extras::RawValue>>,
    ) {
        let len = self.bin.len() - anim.start;
        self.root.buffer_views[anim.view.value()].byte_length = USize64(len as u64);
        if anim.channels.is_empty() {
            return;
        }
        self.root.push(json::Animation {
            extensions: None,
            extras,
            channels: anim.channels,
            name: Some(name.to_string()),
            samplers: anim.samplers,
        });
    }

    /// Closes the document: the buffer (padded to 4 bytes), the scene, the asset extras.
    pub fn finish(mut self, extras: Option<Box<json::extras::RawValue>>) -> (json::Root, Vec<u8>) {
        self.align4();
        self.root.push(json::Buffer {
            byte_length: USize64(self.bin.len() as u64),
            name: None,
            uri: None,
            extensions: None,
            extras: None,
        });
        let scene = self.root.push(json::Scene {
            extensions: None,
            extras: None,
            name: Some("frond".to_string()),
            nodes: std::mem::take(&mut self.scene_nodes),
        });
        self.root.scene = Some(scene);
        self.root.asset.extras = extras;
        (self.root, self.bin)
    }
}

/// Where a plant stands: its root node's transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Translation, metres.
    pub translation_m: [f32; 3],
    /// Rotation, unit quaternion `[x, y, z, w]`.
    pub rotation: [f32; 4],
    /// Uniform scale.
    pub scale: f32,
}

impl Default for Placement {
    fn default() -> Self {
        Placement { translation_m: [0.0; 3], rotation: [0.0, 0.0, 0.0, 1.0], scale: 1.0 }
    }
}

impl Placement {
    /// Where a field's plant stands: at its place on the ground, unturned (its bend is turned to
    /// the force by its pose), at its size.
    pub fn of_field_plant(p: &frond_motion::field::FieldPlant) -> Self {
        Placement::on_ground(p.position_m[0], p.position_m[1], 0.0, p.scale)
    }

    /// At `(x, 0, z)`, turned `yaw_deg` about +Y, scaled.
    pub fn on_ground(x_m: f32, z_m: f32, yaw_deg: f32, scale: f32) -> Self {
        Placement {
            translation_m: [x_m, 0.0, z_m],
            rotation: Quat::from_rotation_y(yaw_deg.to_radians()).to_array(),
            scale,
        }
    }
}

/// What every plant of a document shares: one mesh (all geometry in the plant's bind space,
/// skinned to the main joints `0..4` and element instance `k`'s joints `4 (k + 1)..`), one
/// material, one inverse-bind-matrix accessor (the bind pose does not depend on where a plant
/// stands, so every skin uses the same one).
#[derive(Debug, Clone)]
pub struct PlantAssets {
    /// The mesh.
    pub mesh: Index<json::Mesh>,
    /// Inverse bind matrices, one per skin joint.
    pub ibm: Index<json::Accessor>,
    /// Main joint heights.
    pub heights_m: [f32; JOINTS],
    /// Main joint names.
    pub joint_names: [String; JOINTS],
    /// Secondary element instances, in skin order.
    pub elements: Vec<ElementRig>,
    /// Vertex count.
    pub vertices: usize,
}

/// The nodes of one plant.
#[derive(Debug, Clone)]
pub struct PlantNodes {
    /// The plant's root node.
    pub root: Index<json::Node>,
    /// Main joints, root first.
    pub main: [Index<json::Node>; JOINTS],
    /// Per element instance (in [`PlantAssets::elements`] order), its joints.
    pub elements: Vec<[Index<json::Node>; JOINTS]>,
}

/// An animation being written (see [`DocBuilder::begin_animation`]).
pub struct AnimationBuilder {
    input: Index<json::Accessor>,
    view: Index<buffer::View>,
    start: usize,
    channels: Vec<json::animation::Channel>,
    samplers: Vec<json::animation::Sampler>,
}
