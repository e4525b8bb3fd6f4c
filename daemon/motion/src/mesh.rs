//! Skinned plant geometry as plain data (positions, normals, triangle indices, per-joint weights),
//! so the glTF baker and the previews have something to draw without external assets.
//!
//! [`procedural_model`] builds the shape a rig names in its `[mesh]` table (seed 000, Figure 3):
//! a tapered two-sided grass blade, a flower (stem tube, star-shaped head, and one leaf per
//! secondary element instance on its own 4-joint skeleton, section 5.3), or a shrub (trunk,
//! fanned branches, leaf clusters). The stem geometry is given in the rest (bind) pose, Y up,
//! ground at y = 0, and skinned to the rig's four joints with [`procedural_weights`]
//! (seed 000, Appendix) at each vertex's rest height once it is placed (a shrub's leaf clusters
//! take the weights of the branch tips they sit on, not of their own length); vertices start a little below the ground, which the weights give to
//! joint 0. Weights are stored per rig joint (`weights[v][i]` for joint `i`), so a glTF writer
//! uses `JOINTS_0 = [0, 1, 2, 3]` for every vertex.

use glam::{Mat4, Quat, Vec3};
use thiserror::Error;

use crate::rig::Rig;
use crate::rig_mesh::{MeshShape, MeshSpec};
use crate::sample::JOINTS;
use crate::skeleton::{Skeleton, procedural_weights, skin_normal, skin_point};

/// How far below the ground procedural stems start, metres (planted, not floating).
pub const BELOW_GROUND_M: f32 = 0.01;

/// Triangle geometry skinned to one 4-joint skeleton.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SkinnedMesh {
    /// Rest-pose positions, metres.
    pub positions: Vec<[f32; 3]>,
    /// Unit normals, one per position.
    pub normals: Vec<[f32; 3]>,
    /// Triangles, counter-clockwise seen from the front, three indices each.
    pub indices: Vec<u32>,
    /// Per vertex, the weight of each skeleton joint (non-negative, sum 1).
    pub weights: Vec<[f32; JOINTS]>,
}

impl SkinnedMesh {
    fn vertex(&mut self, p: Vec3, w: [f32; JOINTS]) -> u32 {
        self.positions.push(p.to_array());
        self.normals.push([0.0; 3]);
        self.weights.push(w);
        (self.positions.len() - 1) as u32
    }

    fn tri(&mut self, a: u32, b: u32, c: u32) {
        self.indices.extend_from_slice(&[a, b, c]);
    }

    /// Recomputes every normal as the area-weighted mean of its triangles' normals.
    pub fn compute_normals(&mut self) {
        let mut acc = vec![Vec3::ZERO; self.positions.len()];
        for t in self.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| Vec3::from(self.positions[i as usize]));
            let n = (b - a).cross(c - a);
            for &i in t {
                acc[i as usize] += n;
            }
        }
        for (n, a) in self.normals.iter_mut().zip(acc) {
            *n = a.normalize_or(Vec3::Y).to_array();
        }
    }

    /// The mesh posed by a skeleton: positions and normals after linear blend skinning (seed
    /// 000, Eq. 1).
    pub fn posed(&self, skeleton: &Skeleton, joints_deg: &[[f32; 3]; JOINTS]) -> (Vec<Vec3>, Vec<Vec3>) {
        self.posed_by(&skeleton.skinning_matrices(joints_deg), Mat4::IDENTITY)
    }

    fn posed_by(&self, m: &[Mat4; JOINTS], outer: Mat4) -> (Vec<Vec3>, Vec<Vec3>) {
        let mut p = Vec::with_capacity(self.positions.len());
        let mut n = Vec::with_capacity(self.positions.len());
        for ((pos, nor), w) in self.positions.iter().zip(&self.normals).zip(&self.weights) {
            p.push(outer.transform_point3(skin_point(m, w, Vec3::from(*pos))));
            n.push(outer.transform_vector3(skin_normal(m, w, Vec3::from(*nor))).normalize_or_zero());
        }
        (p, n)
    }

    /// Checks the invariants every consumer relies on; returns the first that does not hold.
    pub fn check(&self) -> Result<(), MeshCheckError> {
        let n = self.positions.len();
        if self.normals.len() != n || self.weights.len() != n {
            return Err(MeshCheckError::Lengths {
                positions: n,
                normals: self.normals.len(),
                weights: self.weights.len(),
            });
        }
        if !self.indices.len().is_multiple_of(3) {
            return Err(MeshCheckError::PartialTriangle(self.indices.len()));
        }
        if let Some(&index) = self.indices.iter().find(|&&i| i as usize >= n) {
            return Err(MeshCheckError::IndexOutOfRange { index, vertices: n });
        }
        for (v, ((p, nor), w)) in self.positions.iter().zip(&self.normals).zip(&self.weights).enumerate() {
            if !p.iter().chain(nor).chain(w).all(|x| x.is_finite()) {
                return Err(MeshCheckError::NonFinite(v));
            }
            if (Vec3::from(*nor).length() - 1.0).abs() > 1e-3 {
                return Err(MeshCheckError::NormalNotUnit { vertex: v, normal: *nor });
            }
            if w.iter().any(|&x| x < 0.0) || (w.iter().sum::<f32>() - 1.0).abs() > 1e-4 {
                return Err(MeshCheckError::Weights { vertex: v, weights: *w });
            }
        }
        Ok(())
    }
}

/// An invariant of [`SkinnedMesh`] that does not hold ([`SkinnedMesh::check`]).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MeshCheckError {
    /// Positions, normals and weights differ in number.
    #[error("{positions} positions but {normals} normals and {weights} weights")]
    Lengths {
        /// Number of positions.
        positions: usize,
        /// Number of normals.
        normals: usize,
        /// Number of weight rows.
        weights: usize,
    },
    /// The index count is not a multiple of 3.
    #[error("{0} indices is not a whole number of triangles")]
    PartialTriangle(usize),
    /// A triangle index names no vertex.
    #[error("index {index} out of range for {vertices} vertices")]
    IndexOutOfRange {
        /// The index.
        index: u32,
        /// Number of vertices.
        vertices: usize,
    },
    /// A position, normal or weight of this vertex is NaN or infinite.
    #[error("vertex {0} has a non-finite value")]
    NonFinite(usize),
    /// This vertex's normal is not of unit length.
    #[error("vertex {vertex} normal {normal:?} is not unit length")]
    NormalNotUnit {
        /// The vertex.
        vertex: usize,
        /// Its normal.
        normal: [f32; 3],
    },
    /// This vertex's weights are negative or do not sum to 1.
    #[error("vertex {vertex} weights {weights:?} are not non-negative with sum 1")]
    Weights {
        /// The vertex.
        vertex: usize,
        /// Its weights, one per joint.
        weights: [f32; JOINTS],
    },
}

/// One secondary element (leaf, petal) of a plant: its own skeleton and mesh, hung from a joint
/// of the main skeleton (seed 000, section 5.3: "secondary elements are treated as simple short
/// plants").
#[derive(Debug, Clone, PartialEq)]
pub struct ElementInstance {
    /// Index into `Rig::elements`; the element's take layer id is `element + 1`.
    pub element: usize,
    /// Element kind name (`leaf`).
    pub name: String,
    /// Which of the `count` instances this is.
    pub instance: u32,
    /// Main-skeleton joint it hangs from.
    pub attach_joint: u8,
    /// The element root's frame relative to the attach joint's frame, as a rotation (quaternion
    /// `[x, y, z, w]`) applied after a translation `offset_m`.
    pub rotation: [f32; 4],
    /// Translation from the attach joint, metres, in the joint's frame.
    pub offset_m: [f32; 3],
    /// The element's own skeleton (evenly spaced joints along its length).
    pub skeleton: Skeleton,
    /// Geometry in the element's own frame (root at the origin, growing along +Y).
    pub mesh: SkinnedMesh,
}

impl ElementInstance {
    /// The element root frame relative to its attach joint: `T(offset) * R(rotation)`.
    pub fn attach_matrix(&self) -> Mat4 {
        Mat4::from_rotation_translation(Quat::from_array(self.rotation), Vec3::from(self.offset_m))
    }
}

/// A whole plant: the main (stem) mesh and its secondary element instances.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantModel {
    /// The rig's skeleton.
    pub skeleton: Skeleton,
    /// Geometry skinned to the main skeleton.
    pub stem: SkinnedMesh,
    /// Secondary element instances.
    pub elements: Vec<ElementInstance>,
}

impl PlantModel {
    /// Every vertex posed: the stem by `stem_pose`, each element by `element_pose(instance)` on
    /// top of its attach joint's world matrix. Stem vertices first, then elements in order.
    pub fn posed_positions(
        &self,
        stem_pose: &[[f32; 3]; JOINTS],
        mut element_pose: impl FnMut(&ElementInstance) -> [[f32; 3]; JOINTS],
    ) -> Vec<Vec3> {
        let (mut out, _) = self.stem.posed(&self.skeleton, stem_pose);
        let world = self.skeleton.joint_matrices(stem_pose);
        for e in &self.elements {
            let outer = world[e.attach_joint as usize] * e.attach_matrix();
            let m = e.skeleton.skinning_matrices(&element_pose(e));
            out.extend(e.mesh.posed_by(&m, outer).0);
        }
        out
    }
}

/// Why a model could not be built.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MeshError {
    /// The rig points at a file: load it with `frond_formats::gltf_mesh::load_gltf_mesh`.
    #[error("rig `{rig}` uses the mesh file `{path}`; load it with the glTF reader")]
    FileMesh {
        /// Rig name.
        rig: String,
        /// The file path from the rig.
        path: String,
    },
}

/// A two-sided strip from profile rows `(height, half width)` in the strip's own frame, placed by
/// `frame` (the strip's frame in the skeleton's rest space). Each vertex is weighted by its
/// height after placement (seed 000, Appendix: the weights follow the vertex's height in the
/// rest pose), not by its height along the strip: a leaf hung at a branch tip gets the weights
/// of the branch tip, so it moves with it.
fn two_sided_strip(mesh: &mut SkinnedMesh, skel: &Skeleton, rows: &[(f32, f32)], frame: Mat4) {
    let placed = |mesh: &mut SkinnedMesh, x: f32, y: f32| {
        let p = frame.transform_point3(Vec3::new(x, y, 0.0));
        mesh.vertex(p, skel.weights_at(p.y))
    };
    for side in [1.0f32, -1.0] {
        let mut prev: Option<(u32, u32)> = None;
        for &(y, half) in rows {
            let l = placed(mesh, -half, y);
            let r = if half > 0.0 { placed(mesh, half, y) } else { l };
            if let Some((pl, pr)) = prev {
                // Front (+Z) faces counter-clockwise; the back side reverses the winding.
                let mut quad = |a, b, c| if side > 0.0 { mesh.tri(a, b, c) } else { mesh.tri(a, c, b) };
                // A row of zero width (a leaf's base or tip) is one vertex: no triangle may
                // repeat it, or importers find degenerate faces (Blender's USD importer did).
                if pl != pr {
                    quad(pl, pr, r);
                }
                if l != r {
                    quad(pl, r, l);
                }
            }
            prev = Some((l, r));
        }
    }
}

/// A tube from `a` to `b` with radii `ra`, `rb`, `rows` rings of `sides` vertices, skinned by the
/// height of each vertex; closed at the top with a cone tip when `cap` is set.
#[allow(clippy::too_many_arguments)]
fn tube(
    mesh: &mut SkinnedMesh,
    skel: &Skeleton,
    a: Vec3,
    b: Vec3,
    ra: f32,
    rb: f32,
    rows: usize,
    sides: usize,
    cap: bool,
) {
    let axis = (b - a).normalize_or(Vec3::Y);
    let side = if axis.x.abs() < 0.9 { Vec3::X } else { Vec3::Z };
    let u = axis.cross(side).normalize();
    let v = axis.cross(u);
    let start = mesh.positions.len() as u32;
    for k in 0..=rows {
        let s = k as f32 / rows as f32;
        let c = a.lerp(b, s);
        let r = ra + (rb - ra) * s;
        for j in 0..sides {
            let ang = std::f32::consts::TAU * j as f32 / sides as f32;
            let p = c + (u * ang.cos() + v * ang.sin()) * r;
            mesh.vertex(p, skel.weights_at(p.y));
        }
    }
    let sides32 = sides as u32;
    for k in 0..rows as u32 {
        for j in 0..sides32 {
            let i0 = start + k * sides32 + j;
            let i1 = start + k * sides32 + (j + 1) % sides32;
            // Outward-facing: (u, v, axis) is right-handed, rings go counter-clockwise about axis.
            mesh.tri(i0, i1, i1 + sides32);
            mesh.tri(i0, i1 + sides32, i0 + sides32);
        }
    }
    if cap {
        let tip = b + axis * rb;
        let t = mesh.vertex(tip, skel.weights_at(tip.y));
        let top = start + rows as u32 * sides32;
        for j in 0..sides32 {
            mesh.tri(top + j, top + (j + 1) % sides32, t);
        }
    }
}

fn leaf_profile(length_m: f32, width_m: f32) -> Vec<(f32, f32)> {
    // A lens: zero width at both ends, widest at 40 % of the length.
    (0..=8)
        .map(|k| {
            let s = k as f32 / 8.0;
            let half = 0.5 * width_m * (std::f32::consts::PI * s.powf(0.8)).sin().max(0.0);
            (s * length_m, if k == 8 { 0.0 } else { half })
        })
        .collect()
}

/// Builds the procedural model a rig names (`[mesh] shape = ...`).
pub fn procedural_model(rig: &Rig) -> Result<PlantModel, MeshError> {
    let (shape, width_m, height_m) = match &rig.mesh {
        MeshSpec::Procedural { shape, width_m, height_m } => (*shape, *width_m, *height_m),
        MeshSpec::File { path } => {
            return Err(MeshError::FileMesh { rig: rig.name.clone(), path: path.clone() });
        }
    };
    let skeleton = Skeleton::from_rig(rig);
    let h = skeleton.heights_m;
    let top = height_m.unwrap_or(h[3] + 0.75 * (h[3] - h[2]));
    let mut stem = SkinnedMesh::default();
    let mut elements = Vec::new();
    match shape {
        MeshShape::Blade => {
            let rows: Vec<(f32, f32)> = (0..=10)
                .map(|k| {
                    let s = k as f32 / 10.0;
                    let y = -BELOW_GROUND_M + s * (top + BELOW_GROUND_M);
                    (y, if k == 10 { 0.0 } else { 0.5 * width_m * (1.0 - s).powf(0.7) })
                })
                .collect();
            two_sided_strip(&mut stem, &skeleton, &rows, Mat4::IDENTITY);
        }
        MeshShape::Flower => {
            let r = 0.5 * width_m;
            tube(
                &mut stem,
                &skeleton,
                Vec3::new(0.0, -BELOW_GROUND_M, 0.0),
                Vec3::new(0.0, top, 0.0),
                r,
                r * 0.8,
                12,
                6,
                false,
            );
            // Head: a two-sided five-pointed star around the stem top.
            let centre = Vec3::new(0.0, top + r, 0.0);
            for side in [1.0f32, -1.0] {
                let c = stem.vertex(centre, procedural_weights(h, centre.y));
                let ring: Vec<u32> = (0..10)
                    .map(|j| {
                        let ang = std::f32::consts::TAU * j as f32 / 10.0;
                        let rad = if j % 2 == 0 { 6.0 * width_m } else { 2.5 * width_m };
                        let p = Vec3::new(rad * ang.cos(), top, -rad * ang.sin());
                        stem.vertex(p, procedural_weights(h, p.y))
                    })
                    .collect();
                for j in 0..10 {
                    let (a, b) = (ring[j], ring[(j + 1) % 10]);
                    if side > 0.0 { stem.tri(c, a, b) } else { stem.tri(c, b, a) }
                }
            }
            for (e, spec) in rig.elements.iter().enumerate() {
                for k in 0..spec.count {
                    let spin = std::f32::consts::TAU * (k as f32 + 0.25) / spec.count as f32;
                    let rotation = Quat::from_rotation_y(spin) * Quat::from_rotation_x(55f32.to_radians());
                    let mut mesh = SkinnedMesh::default();
                    let leaf_skel = Skeleton::even(spec.length_m);
                    two_sided_strip(
                        &mut mesh,
                        &leaf_skel,
                        &leaf_profile(spec.length_m, spec.length_m * 0.35),
                        Mat4::IDENTITY,
                    );
                    mesh.compute_normals();
                    elements.push(ElementInstance {
                        element: e,
                        name: spec.name.clone(),
                        instance: k,
                        attach_joint: spec.attach_joint,
                        rotation: rotation.to_array(),
                        offset_m: [0.0; 3],
                        skeleton: leaf_skel,
                        mesh,
                    });
                }
            }
        }
        MeshShape::Shrub => {
            let r = 0.5 * width_m;
            let fork = Vec3::new(0.0, h[1], 0.0);
            tube(&mut stem, &skeleton, Vec3::new(0.0, -BELOW_GROUND_M, 0.0), fork, r, r * 0.8, 4, 6, false);
            for b in 0..5 {
                let ang = std::f32::consts::TAU * b as f32 / 5.0;
                let spread = 0.35 * top;
                let tip = Vec3::new(spread * ang.cos(), top, -spread * ang.sin());
                tube(&mut stem, &skeleton, fork, tip, r * 0.6, r * 0.25, 6, 5, true);
                // Leaf cluster: three crossed two-sided leaves at the branch tip.
                for l in 0..3 {
                    let frame = Mat4::from_rotation_translation(
                        Quat::from_rotation_y(ang + l as f32 * 1.05) * Quat::from_rotation_x(0.6),
                        tip,
                    );
                    let len = 0.15 * top;
                    two_sided_strip(&mut stem, &skeleton, &leaf_profile(len, len * 0.5), frame);
                }
            }
        }
    }
    stem.compute_normals();
    Ok(PlantModel { skeleton, stem, elements })
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::rig::{ElementSpec, MeshShape, MeshSpec};

    /// Joints at 0, 0.1, 0.2 and 0.3 m and a `shape` 2 cm wide of the default height, with
    /// `leaves` three leaves 8 cm long on joint 1 or no elements.
    fn rig(shape: MeshShape, leaves: bool) -> Rig {
        let mesh = MeshSpec::Procedural { shape, width_m: 0.02, height_m: None };
        let mut rig = Rig::for_tests("t", [0.0, 0.1, 0.2, 0.3], mesh);
        if leaves {
            let leaf = ElementSpec { name: "leaf".into(), attach_joint: 1, count: 3, length_m: 0.08, tau: 2 };
            rig.elements.push(leaf);
        }
        rig
    }

    #[test]
    fn every_shape_is_well_formed() {
        for shape in [MeshShape::Blade, MeshShape::Flower, MeshShape::Shrub] {
            let m = procedural_model(&rig(shape, true)).unwrap();
            m.stem.check().unwrap_or_else(|e| panic!("{shape:?}: {e}"));
            assert!(m.stem.indices.len() >= 3 * 10, "{shape:?}");
            for e in &m.elements {
                e.mesh.check().unwrap();
            }
            // No triangle repeats a vertex (importers report such faces as invalid).
            for mesh in std::iter::once(&m.stem).chain(m.elements.iter().map(|e| &e.mesh)) {
                for t in mesh.indices.chunks_exact(3) {
                    assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2], "{shape:?}: degenerate {t:?}");
                }
            }
            // Planted: something below ground, all of it weighted to joint 0.
            let below: Vec<_> =
                m.stem.positions.iter().zip(&m.stem.weights).filter(|(p, _)| p[1] < 0.0).collect();
            assert!(!below.is_empty(), "{shape:?}");
            assert!(below.iter().all(|(_, w)| **w == [1.0, 0.0, 0.0, 0.0]));
        }
    }

    #[test]
    fn check_names_the_broken_invariant() {
        let ok = SkinnedMesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            indices: vec![0, 1, 2],
            weights: vec![[1.0, 0.0, 0.0, 0.0]; 3],
        };
        assert_eq!(ok.check(), Ok(()));
        let broken = |f: fn(&mut SkinnedMesh)| {
            let mut m = ok.clone();
            f(&mut m);
            m.check().unwrap_err()
        };
        let e = broken(|m| {
            m.normals.pop();
        });
        assert_eq!(e, MeshCheckError::Lengths { positions: 3, normals: 2, weights: 3 });
        assert_eq!(e.to_string(), "3 positions but 2 normals and 3 weights");
        assert_eq!(broken(|m| m.indices.push(0)), MeshCheckError::PartialTriangle(4));
        let e = broken(|m| m.indices[2] = 3);
        assert_eq!(e.to_string(), "index 3 out of range for 3 vertices");
        assert_eq!(broken(|m| m.positions[1][0] = f32::NAN), MeshCheckError::NonFinite(1));
        let e = broken(|m| m.normals[2] = [0.0, 0.0, 2.0]);
        assert_eq!(e, MeshCheckError::NormalNotUnit { vertex: 2, normal: [0.0, 0.0, 2.0] });
        let e = broken(|m| m.weights[0] = [0.5, 0.0, 0.0, 0.0]);
        assert_eq!(e.to_string(), "vertex 0 weights [0.5, 0.0, 0.0, 0.0] are not non-negative with sum 1");
    }

    #[test]
    fn blade_tapers_to_a_tip_at_the_default_height() {
        let m = procedural_model(&rig(MeshShape::Blade, false)).unwrap();
        // Default height: top joint + 3/4 of the top segment = 0.3 + 0.075.
        let max_y = m.stem.positions.iter().map(|p| p[1]).fold(f32::MIN, f32::max);
        assert!((max_y - 0.375).abs() < 1e-6, "{max_y}");
        let tip: Vec<_> = m.stem.positions.iter().filter(|p| p[1] == max_y).collect();
        assert!(tip.iter().all(|p| p[0] == 0.0));
        // A flat blade: front normals +Z, back normals -Z.
        assert!(m.stem.normals.iter().all(|n| n[2].abs() > 0.999));
        assert!(m.elements.is_empty());
    }

    #[test]
    fn flower_gets_one_leaf_per_element_instance_and_outward_stem_normals() {
        let m = procedural_model(&rig(MeshShape::Flower, true)).unwrap();
        assert_eq!(m.elements.len(), 3);
        assert_eq!(m.elements.iter().map(|e| e.instance).collect::<Vec<_>>(), [0, 1, 2]);
        // Stem tube vertices (radius 0.01 ring below the head) have outward normals.
        for (p, n) in m.stem.positions.iter().zip(&m.stem.normals).take(12 * 6) {
            let radial = Vec3::new(p[0], 0.0, p[2]).normalize();
            assert!(Vec3::from(*n).dot(radial) > 0.8, "{p:?} {n:?}");
        }
    }

    #[test]
    fn bending_the_root_tips_the_whole_plant() {
        let m = procedural_model(&rig(MeshShape::Flower, true)).unwrap();
        let rest = m.posed_positions(&[[0.0; 3]; 4], |_| [[0.0; 3]; 4]);
        let bent = m.posed_positions(&[[90.0, 0.0, 0.0], [0.0; 3], [0.0; 3], [0.0; 3]], |_| [[0.0; 3]; 4]);
        assert_eq!(rest.len(), bent.len());
        // Root pitch 90 about the ground origin: (x, y, z) -> (x, -z, y) for every vertex.
        for (a, b) in rest.iter().zip(&bent) {
            assert!((*b - Vec3::new(a.x, -a.z, a.y)).length() < 1e-5, "{a:?} -> {b:?}");
        }
    }

    #[test]
    fn file_meshes_are_not_procedural() {
        let r = Rig::for_tests("g", [0.0, 0.1, 0.2, 0.3], MeshSpec::File { path: "g.glb".into() });
        assert_eq!(
            procedural_model(&r).unwrap_err().to_string(),
            "rig `g` uses the mesh file `g.glb`; load it with the glTF reader"
        );
    }
}
