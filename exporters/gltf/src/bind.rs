//! The plant model in its bind pose, as the glTF document stores it: every mesh (the stem and
//! each secondary element instance) in the plant's bind space, its vertices skinned to at most
//! four joints (the main joints `0..4`, element instance `k`'s `4 (k + 1)..`), degenerate
//! triangles dropped, and the inverse bind matrix of every skin joint. Pure: no document here;
//! [`crate::doc`] writes it.

use glam::{Mat4, Vec3};

use frond_motion::JOINTS;
use frond_motion::mesh::{PlantModel, SkinnedMesh};

/// The plant's bind-pose geometry (see the module docs), ready to be written as accessors.
pub(crate) struct BindGeometry {
    /// Vertex positions, metres.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals.
    pub normals: Vec<[f32; 3]>,
    /// Per vertex, its (up to four) skin joints.
    pub joints: Vec<[u16; 4]>,
    /// Per vertex, the weights of those joints (summing to 1).
    pub weights: Vec<[f32; 4]>,
    /// Triangles, three vertex indices each.
    pub indices: Vec<u32>,
    /// Per skin joint, its inverse bind matrix.
    pub ibm: Vec<Mat4>,
    /// The secondary element instances, in skin order.
    pub elements: Vec<ElementRig>,
}

/// `model` in its bind pose; an element instance is named after its element
/// (`element_names[e]`, else the model's name for it) and its instance number.
pub(crate) fn bind_geometry(model: &PlantModel, element_names: &[String]) -> BindGeometry {
    let heights = model.skeleton.heights_m;
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut normals: Vec<[f32; 3]> = Vec::new();
    let mut joints: Vec<[u16; 4]> = Vec::new();
    let mut weights: Vec<[f32; 4]> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    let mut ibm: Vec<Mat4> =
        heights.iter().map(|&h| Mat4::from_translation(Vec3::new(0.0, -h, 0.0))).collect();

    let mut add = |mesh: &SkinnedMesh, frame: Mat4, base: u16| {
        let first = positions.len() as u32;
        for ((p, n), w) in mesh.positions.iter().zip(&mesh.normals).zip(&mesh.weights) {
            positions.push(frame.transform_point3(Vec3::from(*p)).to_array());
            normals.push(frame.transform_vector3(Vec3::from(*n)).normalize_or(Vec3::Y).to_array());
            let (j, w) = pack_influences(w, base);
            joints.push(j);
            weights.push(w);
        }
        // Degenerate triangles (two equal corners, e.g. where a strip meets a pointed tip)
        // draw nothing; drop them.
        for t in mesh.indices.chunks_exact(3) {
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                indices.extend(t.iter().map(|i| i + first));
            }
        }
    };
    add(&model.stem, Mat4::IDENTITY, 0);
    let mut elements = Vec::with_capacity(model.elements.len());
    for (k, e) in model.elements.iter().enumerate() {
        let base = (JOINTS * (k + 1)) as u16;
        let bind =
            Mat4::from_translation(Vec3::new(0.0, heights[e.attach_joint as usize], 0.0)) * e.attach_matrix();
        add(&e.mesh, bind, base);
        for &h in &e.skeleton.heights_m {
            ibm.push((bind * Mat4::from_translation(Vec3::new(0.0, h, 0.0))).inverse());
        }
        let kind = element_names.get(e.element).cloned().unwrap_or_else(|| e.name.clone());
        elements.push(ElementRig {
            element: e.element,
            instance: e.instance,
            name: format!("{kind}{}", e.instance),
            attach_joint: e.attach_joint as usize,
            rotation: e.rotation,
            offset_m: e.offset_m,
            heights_m: e.skeleton.heights_m,
        });
    }
    BindGeometry { positions, normals, joints, weights, indices, ibm, elements }
}

/// One secondary element instance of the plant model, as the document sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct ElementRig {
    /// Index into the rig's secondary elements.
    pub element: usize,
    /// Which instance of that element.
    pub instance: u32,
    /// Node name of its attach node (`leaf0`); its joints are `leaf0_joint0`..`leaf0_joint3`.
    pub name: String,
    /// Main joint it hangs from.
    pub attach_joint: usize,
    /// Attach rotation `[x, y, z, w]`.
    pub rotation: [f32; 4],
    /// Attach offset, metres.
    pub offset_m: [f32; 3],
    /// Its own joint heights.
    pub heights_m: [f32; JOINTS],
}

/// Joint indices and weights of one vertex for glTF: the non-zero influences first, unused
/// slots joint 0 with weight 0 (the validator warns about a non-zero joint with zero weight),
/// normalised so the `f32` sum is 1 as closely as `f32` allows.
pub fn pack_influences(w: &[f32; JOINTS], base: u16) -> ([u16; 4], [f32; 4]) {
    let mut joints = [0u16; 4];
    let mut weights = [0f32; 4];
    let total: f64 = w.iter().map(|&x| f64::from(x.max(0.0))).sum();
    let mut n = 0;
    for (i, &x) in w.iter().enumerate() {
        if x > 0.0 && total > 0.0 {
            joints[n] = base + i as u16;
            weights[n] = (f64::from(x) / total) as f32;
            n += 1;
        }
    }
    if n == 0 {
        joints[0] = base;
        weights[0] = 1.0;
        return (joints, weights);
    }
    // Put the rounding residue on the largest weight.
    let sum: f32 = weights.iter().sum();
    let big = (0..n).max_by(|&a, &b| weights[a].total_cmp(&weights[b])).unwrap_or(0);
    weights[big] += 1.0 - sum;
    (joints, weights)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn influences_put_nonzero_weights_first() {
        assert_eq!(pack_influences(&[0.0, 0.25, 0.75, 0.0], 4), ([5, 6, 0, 0], [0.25, 0.75, 0.0, 0.0]));
        assert_eq!(pack_influences(&[1.0, 0.0, 0.0, 0.0], 0), ([0, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]));
        assert_eq!(pack_influences(&[0.0; 4], 8), ([8, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]));
        // Not summing to 1: renormalised.
        let (_, w) = pack_influences(&[0.2, 0.2, 0.0, 0.0], 0);
        assert_eq!(w, [0.5, 0.5, 0.0, 0.0]);
        let (_, w) = pack_influences(&[0.1, 0.7, 0.2, 0.0], 0);
        assert_eq!(w.iter().sum::<f32>(), 1.0);
    }
}
