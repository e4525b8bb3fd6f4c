//! Reading a rig's glTF/GLB mesh (`[mesh] file = "..."`), pure: the caller reads the bytes.
//!
//! Every triangle primitive of every mesh is taken, in the file's own coordinates (which must be
//! the rig's rest space: metres, Y up, ground at y = 0; node transforms are not applied). Skinning
//! weights come from the file when it has a skin and `JOINTS_0`/`WEIGHTS_0`: each skin joint is
//! matched to a rig joint by node name, or, when no skin joint name is a rig joint name, by its
//! position in the skin's joint list (the first four); weights on joints that match nothing are dropped and the rest renormalised. A
//! vertex left without weight, and files without a skin, get procedural weights by height (seed
//! 000, Appendix). Missing normals are computed. Buffers must be the GLB binary chunk or base64
//! `data:` URIs: external files are refused (this crate does no I/O).

use glam::Vec3;
use thiserror::Error;

use frond_motion::mesh::SkinnedMesh;
use frond_motion::sample::JOINTS;
use frond_motion::skeleton::Skeleton;

/// Why a glTF mesh was refused.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum GltfMeshError {
    /// Not glTF/GLB, or invalid (the gltf crate's message).
    #[error("glTF: {0}")]
    Parse(String),
    /// A buffer the mesh needs is not inside the file.
    #[error("glTF: buffer {index} {reason}")]
    Buffer {
        /// Buffer index.
        index: usize,
        /// What is wrong.
        reason: String,
    },
    /// No triangles were found.
    #[error("glTF: no triangle mesh with positions found")]
    NoTriangles,
    /// The data is malformed (index out of range, non-finite position, ...).
    #[error("glTF: {0}")]
    Invalid(String),
}

fn decode_base64(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in text.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b'\n' | b'\r' | b' ' => continue,
            _ => return None,
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Some(out)
}

/// Reads the triangles of a glTF or GLB file and skins them to `skeleton` (see module docs).
/// `joint_names` are the rig's joint names, root first.
pub fn load_gltf_mesh(
    bytes: &[u8],
    skeleton: &Skeleton,
    joint_names: &[String],
) -> Result<SkinnedMesh, GltfMeshError> {
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| GltfMeshError::Parse(e.to_string()))?;
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for b in gltf.document.buffers() {
        let err = |reason: String| GltfMeshError::Buffer { index: b.index(), reason };
        let data = match b.source() {
            gltf::buffer::Source::Bin => {
                gltf.blob.clone().ok_or_else(|| err("refers to a missing GLB binary chunk".to_string()))?
            }
            gltf::buffer::Source::Uri(uri) => {
                match uri.strip_prefix("data:").and_then(|r| r.split_once(";base64,")) {
                    Some((_, data)) => decode_base64(data)
                        .ok_or_else(|| err("has a malformed base64 data URI".to_string()))?,
                    None => return Err(err(format!("is the external file `{uri}`; embed it (use a .glb)"))),
                }
            }
        };
        if data.len() < b.length() {
            return Err(err(format!("holds {} bytes, the file declares {}", data.len(), b.length())));
        }
        buffers.push(data);
    }

    // Skin joint k -> rig joint: by node name, else by position.
    let skin_map: Vec<Option<usize>> = match gltf.document.skins().next() {
        None => Vec::new(),
        Some(skin) => {
            let by_name: Vec<Option<usize>> = skin
                .joints()
                .map(|node| node.name().and_then(|n| joint_names.iter().position(|j| j == n)))
                .collect();
            if by_name.iter().any(Option::is_some) {
                by_name
            } else {
                (0..by_name.len()).map(|k| (k < JOINTS).then_some(k)).collect()
            }
        }
    };

    let mut mesh = SkinnedMesh::default();
    let mut need_normals = false;
    for m in gltf.document.meshes() {
        for prim in m.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
            let Some(positions) = reader.read_positions() else {
                continue;
            };
            let base = mesh.positions.len() as u32;
            let positions: Vec<[f32; 3]> = positions.collect();
            if let Some(v) = positions.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
                return Err(GltfMeshError::Invalid(format!(
                    "mesh {} vertex {v} has a non-finite position",
                    m.index()
                )));
            }
            let n = positions.len();
            let normals: Option<Vec<[f32; 3]>> = reader.read_normals().map(|it| it.collect());
            need_normals |= normals.is_none();
            let joints: Option<Vec<[u16; 4]>> = reader.read_joints(0).map(|j| j.into_u16().collect());
            let weights: Option<Vec<[f32; 4]>> = reader.read_weights(0).map(|w| w.into_f32().collect());
            for (v, p) in positions.iter().enumerate() {
                let mut w = [0.0f32; JOINTS];
                if let (Some(js), Some(ws)) = (&joints, &weights)
                    && let (Some(j), Some(x)) = (js.get(v), ws.get(v))
                {
                    for (&jk, &xk) in j.iter().zip(x) {
                        if let Some(Some(i)) = skin_map.get(jk as usize)
                            && xk.is_finite()
                            && xk > 0.0
                        {
                            w[*i] += xk;
                        }
                    }
                }
                let sum: f32 = w.iter().sum();
                let w = if sum > 0.0 { w.map(|x| x / sum) } else { skeleton.weights_at(p[1]) };
                let nor = normals
                    .as_ref()
                    .and_then(|ns| ns.get(v))
                    .map_or([0.0, 1.0, 0.0], |x| Vec3::from(*x).normalize_or(Vec3::Y).to_array());
                mesh.positions.push(*p);
                mesh.normals.push(nor);
                mesh.weights.push(w);
            }
            match reader.read_indices() {
                Some(ix) => {
                    for i in ix.into_u32() {
                        if i as usize >= n {
                            return Err(GltfMeshError::Invalid(format!(
                                "mesh {} index {i} out of range for {n} vertices",
                                m.index()
                            )));
                        }
                        mesh.indices.push(base + i);
                    }
                }
                None => mesh.indices.extend((0..n as u32 - n as u32 % 3).map(|i| base + i)),
            }
            mesh.indices.truncate(mesh.indices.len() - mesh.indices.len() % 3);
        }
    }
    if mesh.indices.is_empty() {
        return Err(GltfMeshError::NoTriangles);
    }
    if need_normals {
        mesh.compute_normals();
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// A GLB with one triangle at heights 0, 0.15, 0.3, a skin whose joints are the rig's joints
    /// named in reverse order, and JOINTS_0/WEIGHTS_0 as given.
    fn glb(joints: [[u8; 4]; 3], weights: [[f32; 4]; 3], skin: bool) -> Vec<u8> {
        let mut bin = Vec::new();
        for p in [[0.0f32, 0.0, 0.0], [0.1, 0.15, 0.0], [0.0, 0.3, 0.0]] {
            for x in p {
                bin.extend_from_slice(&x.to_le_bytes());
            }
        }
        for j in joints {
            bin.extend_from_slice(&j);
        }
        for w in weights {
            for x in w {
                bin.extend_from_slice(&x.to_le_bytes());
            }
        }
        let mut attributes = json!({ "POSITION": 0 });
        if skin {
            attributes["JOINTS_0"] = json!(1);
            attributes["WEIGHTS_0"] = json!(2);
        }
        let mut doc = json!({
            "asset": { "version": "2.0" },
            "buffers": [{ "byteLength": bin.len() }],
            "bufferViews": [
                { "buffer": 0, "byteOffset": 0, "byteLength": 36 },
                { "buffer": 0, "byteOffset": 36, "byteLength": 12 },
                { "buffer": 0, "byteOffset": 48, "byteLength": 48 }
            ],
            "accessors": [
                { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                  "min": [0.0, 0.0, 0.0], "max": [0.1, 0.3, 0.0] },
                { "bufferView": 1, "componentType": 5121, "count": 3, "type": "VEC4" },
                { "bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC4" }
            ],
            "meshes": [{ "primitives": [{ "attributes": attributes }] }],
            "nodes": [
                { "name": "tip" }, { "name": "middle" }, { "name": "lower" }, { "name": "root" },
                { "mesh": 0, "skin": 0 }
            ],
            "skins": [{ "joints": [0, 1, 2, 3] }]
        });
        if !skin {
            doc["nodes"][4] = json!({ "mesh": 0 });
            doc.as_object_mut().unwrap().remove("skins");
        }
        let mut js = serde_json::to_vec(&doc).unwrap();
        while !js.len().is_multiple_of(4) {
            js.push(b' ');
        }
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&((12 + 8 + js.len() + 8 + bin.len()) as u32).to_le_bytes());
        out.extend_from_slice(&(js.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&js);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }

    fn names() -> Vec<String> {
        ["root", "lower", "middle", "tip"].map(String::from).to_vec()
    }

    const SKEL: Skeleton = Skeleton { heights_m: [0.0, 0.1, 0.2, 0.3] };

    #[test]
    fn skin_weights_are_mapped_by_joint_name() {
        // Skin joint 0 is the node "tip" (rig joint 3), 3 is "root" (rig joint 0).
        let m = load_gltf_mesh(
            &glb(
                [[3, 0, 0, 0], [2, 1, 0, 0], [0, 0, 0, 0]],
                [[1.0, 0.0, 0.0, 0.0], [0.25, 0.25, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]],
                true,
            ),
            &SKEL,
            &names(),
        )
        .unwrap();
        m.check().unwrap();
        assert_eq!(m.indices, [0, 1, 2]);
        assert_eq!(m.weights[0], [1.0, 0.0, 0.0, 0.0]);
        // 0.25 on "lower" (rig 1) and 0.25 on "middle" (rig 2), renormalised to 0.5 each.
        assert_eq!(m.weights[1], [0.0, 0.5, 0.5, 0.0]);
        assert_eq!(m.weights[2], [0.0, 0.0, 0.0, 1.0]);
        // The computed normal of a counter-clockwise triangle in the XY plane (seen from +Z).
        assert!(m.normals.iter().all(|n| n[2] > 0.999), "{:?}", m.normals);
    }

    #[test]
    fn without_a_skin_weights_are_procedural() {
        let m = load_gltf_mesh(&glb([[0; 4]; 3], [[0.0; 4]; 3], false), &SKEL, &names()).unwrap();
        let want = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.5, 0.5, 0.0], [0.0, 0.0, 0.0, 1.0]];
        for (got, want) in m.weights.iter().zip(want) {
            assert!(got.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-6), "{:?}", m.weights);
        }
    }

    #[test]
    fn bad_files_are_clear_errors() {
        let e = load_gltf_mesh(b"not a gltf", &SKEL, &names()).unwrap_err();
        assert!(matches!(e, GltfMeshError::Parse(_)), "{e}");
        let mut g = glb([[0; 4]; 3], [[0.0; 4]; 3], false);
        g.truncate(g.len() - 10);
        assert!(load_gltf_mesh(&g, &SKEL, &names()).is_err());
        let ext = br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"mesh.bin"}]}"#;
        let e = load_gltf_mesh(ext, &SKEL, &names()).unwrap_err();
        assert_eq!(e.to_string(), "glTF: buffer 0 is the external file `mesh.bin`; embed it (use a .glb)");
        let empty = br#"{"asset":{"version":"2.0"}}"#;
        assert_eq!(load_gltf_mesh(empty, &SKEL, &names()).unwrap_err(), GltfMeshError::NoTriangles);
    }

    #[test]
    fn base64_by_hand() {
        assert_eq!(decode_base64("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(decode_base64("AAEC").unwrap(), [0, 1, 2]);
        assert!(decode_base64("a*b").is_none());
    }
}
