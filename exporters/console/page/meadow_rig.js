// frond console: what the meadow (meadow.js) needs of a rig, read from its glTF scene at rest
// as frond-gltf baked it: its skinned primitives and skeleton for the meadow's vertex shader,
// the far plants' ribbon, and a primitive copied into a batch of plants with each vertex's
// skinning summed per main joint (seed 000, Eq. 1).
import * as THREE from 'three';

// What the meadow needs of a rig: its skinned primitives (geometry, material) and the skeleton
// as uniforms, read from the console's loaded glTF scene at rest (every joint's rest rotation is
// the identity: the baked rest pose has all angles 0).
export function rigOf(map, root) {
  const name = (n) => THREE.PropertyBinding.sanitizeNodeName(n);
  const skinned = [];
  root.traverse((o) => { if (o.isSkinnedMesh) skinned.push(o); });
  if (!skinned.length) throw new Error('the rig has no skinned mesh');
  const bones = skinned[0].skeleton.bones;
  const main = map.joints.map((n) => bones.findIndex((b) => b.name === name(n)));
  if (main.some((i) => i < 0)) throw new Error('the rig\'s skin lacks a main joint');
  // Rest transforms relative to the plant's root: a joint's rotation is the identity at rest
  // (the scene may be posed: the view's plant follows the stream), a node that is no joint
  // keeps its own (the flower's leaves hang from the stem turned outwards).
  const rootInv = new THREE.Matrix4().copy(root.matrixWorld).invert();
  const joints = new Set(bones);
  const restWorld = (o) => {
    const chain = [];
    for (let p = o; p && p !== root; p = p.parent) chain.unshift(p);
    const m = new THREE.Matrix4();
    for (const p of chain) {
      m.multiply(new THREE.Matrix4().compose(p.position, joints.has(p) ? new THREE.Quaternion() : p.quaternion, p.scale));
    }
    return m;
  };
  const mainWorld = main.map((i) => restWorld(bones[i]));
  const at = mainWorld.map((w) => new THREE.Vector3().setFromMatrixPosition(w));
  const rest = at.map((p, k) => (k === 0 ? p.clone() : p.clone().sub(at[k - 1])));
  const mainIndex = new Int32Array(bones.length).fill(-1);
  const bind = bones.map(() => new THREE.Matrix4());
  const mesh = skinned[0];
  bones.forEach((bone, b) => {
    // The main joint this joint hangs from (itself for a main joint; none above the root).
    let m = -1;
    for (let p = bone; p && m < 0; p = p.parent) m = main.indexOf(bones.indexOf(p));
    mainIndex[b] = m;
    const inv = m < 0 ? new THREE.Matrix4() : mainWorld[m].clone().invert();
    bind[b].copy(inv).multiply(restWorld(bone)).multiply(mesh.skeleton.boneInverses[b]).multiply(mesh.bindMatrix);
  });
  root.updateMatrixWorld(true);
  const outer = rootInv.clone().multiply(mesh.matrixWorld).multiply(mesh.bindMatrixInverse);
  const primitives = skinned.map((s) => ({ geometry: s.geometry, material: s.material }));
  // The far plants' ribbon: two vertices at the root, at each main joint and at the tip, each
  // pair skinned to its joint, as wide as a tenth of the plant.
  const box = new THREE.Box3();
  for (const s of skinned) { s.geometry.computeBoundingBox(); box.union(s.geometry.boundingBox); }
  const top = Math.max(box.max.y, at[3].y);
  const width = Math.max(top * 0.1, 1e-3);
  const levels = [at[0].y, at[1].y, at[2].y, at[3].y, top];
  const pos = [], idx = [], wt = [], nrm = [], index = [];
  levels.forEach((y, k) => {
    const j = main[Math.min(3, k)];
    const w = width * (1 - k / (levels.length));
    for (const x of [-w / 2, w / 2]) { pos.push(x, y, 0); idx.push(j, 0, 0, 0); wt.push(1, 0, 0, 0); nrm.push(0, 0, 1); }
    if (k > 0) { const a = 2 * (k - 1); index.push(a, a + 1, a + 2, a + 1, a + 3, a + 2); }
  });
  const ribbon = new THREE.BufferGeometry();
  ribbon.setAttribute('position', new THREE.Float32BufferAttribute(pos, 3));
  ribbon.setAttribute('normal', new THREE.Float32BufferAttribute(nrm, 3));
  ribbon.setAttribute('skinIndex', new THREE.Uint16BufferAttribute(idx, 4));
  ribbon.setAttribute('skinWeight', new THREE.Float32BufferAttribute(wt, 4));
  ribbon.setIndex(index);
  const color = skinned[0].material.color ? skinned[0].material.color.clone() : new THREE.Color(0x6a9a40);
  const far = new THREE.MeshStandardMaterial({ color, side: THREE.DoubleSide, roughness: 0.9 });
  const vertices = skinned.reduce((n, m) => n + m.geometry.getAttribute('position').count, 0);
  return { name: map.rig, primitives, ribbon, far, rest, bind, mainIndex, outer, top, root, joints: map.joints, vertices };
}

// `batch` copies of `geometry` (position, normal, uv, colour; one index) as one instanced
// geometry, each vertex with its copy's number (meadowCopy) and its skinning summed per main
// joint of `rig` (meadowQ0..3, meadowQr).
export function batchOf(geometry, batch, rig) {
  const src = geometry.index ? geometry : geometry.clone().setIndex([...Array(geometry.getAttribute('position').count).keys()]);
  const g = new THREE.InstancedBufferGeometry();
  const pos = src.getAttribute('position'), verts = pos.count;
  const idx = src.getAttribute('skinIndex'), wt = src.getAttribute('skinWeight');
  const q = [0, 1, 2, 3, 4].map(() => new Float32Array(4 * verts));
  const v4 = new THREE.Vector4();
  for (let v = 0; v < verts; v++) {
    for (let i = 0; i < 4; i++) {
      const w = wt.getComponent(v, i), b = idx.getComponent(v, i);
      if (!w) continue;
      const m = rig.mainIndex[b];
      v4.set(pos.getX(v), pos.getY(v), pos.getZ(v), 1).applyMatrix4(rig.bind[b]);
      const o = q[m < 0 ? 4 : m];
      o[4 * v] += w * v4.x; o[4 * v + 1] += w * v4.y; o[4 * v + 2] += w * v4.z; o[4 * v + 3] += w;
    }
  }
  const copies = (a, itemSize) => {
    const out = new Float32Array(verts * itemSize * batch);
    for (let c = 0; c < batch; c++) out.set(a, c * verts * itemSize);
    return out;
  };
  for (const name of ['position', 'normal', 'uv', 'color']) {
    const a = src.getAttribute(name);
    if (!a) continue;
    const flat = new Float32Array(a.count * a.itemSize);
    for (let v = 0; v < a.count; v++) for (let k = 0; k < a.itemSize; k++) flat[v * a.itemSize + k] = a.getComponent(v, k);
    g.setAttribute(name, new THREE.BufferAttribute(copies(flat, a.itemSize), a.itemSize));
  }
  ['meadowQ0', 'meadowQ1', 'meadowQ2', 'meadowQ3', 'meadowQr'].forEach((name, k) => g.setAttribute(name, new THREE.BufferAttribute(copies(q[k], 4), 4)));
  const copy = new Float32Array(verts * batch);
  for (let c = 0; c < batch; c++) copy.fill(c, c * verts, (c + 1) * verts);
  g.setAttribute('meadowCopy', new THREE.BufferAttribute(copy, 1));
  const index = src.index.array, out = new Uint32Array(index.length * batch);
  for (let c = 0; c < batch; c++) for (let k = 0; k < index.length; k++) out[c * index.length + k] = index[k] + c * verts;
  g.setIndex(new THREE.BufferAttribute(out, 1));
  return g;
}
