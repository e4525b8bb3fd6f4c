// frond console: a running field drawn in the page (protocol 3; seed 000, Eq. 6-7 and section
// 6.3). The console passes on the daemon's field table and every field frame; the page evaluates
// every plant itself with field.js (globalThis.frondField, field_eval.rs ported) and draws the
// plants instanced: one instanced draw call per primitive of the rig and level of detail. Each
// plant's evaluated angles ([pitch, yaw, roll] of 4 joints) and its placement are 4 texels of a
// float DataTexture; the vertex shader chains the skeleton from them and skins (seed 000,
// Eq. 1). An instance holds a batch of plants (the mesh copied BATCH times, each copy a slot):
// software WebGL (SwiftShader) pays a fixed cost per instance, 15-40 us, which made 10,000
// single-plant instances cost 400 ms a frame whatever their size. A slot's plant is read from
// the level's slot texture, so near and far plants are chosen again without touching the mesh.
// Plants far from the camera use a ribbon of 10 vertices skinned to the same 4 joints.
import * as THREE from 'three';
import { clone as cloneSkinned } from '/vendor/three/SkeletonUtils.js';

const PER_ROW = 1024;          // plants per texture row (4 RGBA texels each), slots per slot row
const MAX_BATCH_VERTICES = 4096; // vertices of one instance (a batch of plants)
const LOD_HEIGHTS = 60;        // plants further than this many plant heights: the ribbon
const NEAR_MAX = 4096;         // and beyond the nearest this many
const REPARTITION_MS = 200;    // near / far chosen again at most this often while the camera moves

// The protocol's rotation convention, R = R_yaw(Z) R_pitch(X) R_roll(Y), degrees; the joints
// chained from the plant's root (joint k at rest offset t_k from joint k - 1, rest rotations the
// identity), then linear blend skinning (seed 000, Eq. 1) with each vertex's influences summed
// per main joint when the batch is made (meadowQ0..3: the weighted rest position in that joint's
// frame, its weight in w; meadowQr: what no main joint moves). No array is indexed per vertex:
// SwiftShader ran the indexed form at 2.7 us a vertex.
const VERTEX_PARS = `
attribute float meadowCopy;
attribute vec4 meadowQ0;
attribute vec4 meadowQ1;
attribute vec4 meadowQ2;
attribute vec4 meadowQ3;
attribute vec4 meadowQr;
uniform highp sampler2D meadowPoses;
uniform highp sampler2D meadowSlots;
uniform int meadowBatch;
uniform int meadowCount;
uniform vec3 meadowRest[4];
uniform mat4 meadowOuter;
mat3 meadowRot(vec3 pyr) {
  vec3 a = radians(pyr);
  float cp = cos(a.x), sp = sin(a.x), cy = cos(a.y), sy = sin(a.y), cr = cos(a.z), sr = sin(a.z);
  mat3 z = mat3(cy, sy, 0.0, -sy, cy, 0.0, 0.0, 0.0, 1.0);
  mat3 x = mat3(1.0, 0.0, 0.0, 0.0, cp, sp, 0.0, -sp, cp);
  mat3 y = mat3(cr, 0.0, -sr, 0.0, 1.0, 0.0, sr, 0.0, cr);
  return z * x * y;
}
`;
const VERTEX_SKIN = `
  int meadowSlot = gl_InstanceID * meadowBatch + int(meadowCopy + 0.5);
  int meadowId = int(texelFetch(meadowSlots, ivec2(meadowSlot % ${PER_ROW}, meadowSlot / ${PER_ROW}), 0).r + 0.5);
  ivec2 meadowAt = ivec2((meadowId % ${PER_ROW}) * 4, meadowId / ${PER_ROW});
  vec4 mA = texelFetch(meadowPoses, meadowAt, 0);
  vec4 mB = texelFetch(meadowPoses, meadowAt + ivec2(1, 0), 0);
  vec4 mC = texelFetch(meadowPoses, meadowAt + ivec2(2, 0), 0);
  vec4 meadowPlace = texelFetch(meadowPoses, meadowAt + ivec2(3, 0), 0); // x, z, scale
  mat3 mR0 = meadowRot(mA.xyz);
  mat3 mR1 = mR0 * meadowRot(vec3(mA.w, mB.xy));
  mat3 mR2 = mR1 * meadowRot(vec3(mB.zw, mC.x));
  mat3 mR3 = mR2 * meadowRot(mC.yzw);
  vec3 mO0 = meadowRest[0];
  vec3 mO1 = mO0 + mR0 * meadowRest[1];
  vec3 mO2 = mO1 + mR1 * meadowRest[2];
  vec3 mO3 = mO2 + mR2 * meadowRest[3];
  vec3 meadowPos = mR0 * meadowQ0.xyz + mO0 * meadowQ0.w + mR1 * meadowQ1.xyz + mO1 * meadowQ1.w
    + mR2 * meadowQ2.xyz + mO2 * meadowQ2.w + mR3 * meadowQ3.xyz + mO3 * meadowQ3.w + meadowQr.xyz;
  mat3 meadowTurn = mR0 * meadowQ0.w + mR1 * meadowQ1.w + mR2 * meadowQ2.w + mR3 * meadowQ3.w
    + mat3(1.0) * meadowQr.w;
  // Placed and sized; the last batch's empty slots collapse to a point (nothing drawn).
  float meadowSize = meadowSlot < meadowCount ? meadowPlace.z : 0.0;
  meadowPos = (meadowOuter * vec4(meadowPos, 1.0)).xyz * meadowSize + vec3(meadowPlace.x, 0.0, meadowPlace.y);
`;

// A material that skins instances from the meadow's texture.
function meadowMaterial(base, uniforms) {
  const m = base.clone();
  m.onBeforeCompile = (shader) => {
    Object.assign(shader.uniforms, uniforms);
    shader.vertexShader = shader.vertexShader
      .replace('#include <common>', `#include <common>\n${VERTEX_PARS}`)
      .replace('#include <skinbase_vertex>', VERTEX_SKIN)
      .replace('#include <skinnormal_vertex>', 'objectNormal = mat3(meadowOuter) * meadowTurn * objectNormal;')
      .replace('#include <skinning_vertex>', 'transformed = meadowPos;');
  };
  m.customProgramCacheKey = () => 'frond-meadow';
  return m;
}

// What the meadow needs of a rig: its skinned primitives (geometry, material) and the skeleton
// as uniforms, read from the console's loaded glTF scene at rest (every joint's rest rotation is
// the identity: the baked rest pose has all angles 0).
function rigOf(map, root) {
  const name = (n) => THREE.PropertyBinding.sanitizeNodeName(n);
  const skinned = [];
  root.traverse((o) => { if (o.isSkinnedMesh) skinned.push(o); });
  if (!skinned.length) throw new Error('the rig has no skinned mesh');
  const bones = skinned[0].skeleton.bones;
  const main = map.joints.map((n) => bones.findIndex((b) => b.name === name(n)));
  if (main.some((i) => i < 0)) throw new Error('the rig\'s skin lacks a main joint');
  // Rest transforms relative to the plant's root: translations only (rotations identity at rest).
  const rootInv = new THREE.Matrix4().copy(root.matrixWorld).invert();
  const restWorld = (o) => {
    const chain = [];
    for (let p = o; p && p !== root; p = p.parent) chain.unshift(p);
    const m = new THREE.Matrix4();
    for (const p of chain) m.multiply(new THREE.Matrix4().compose(p.position, new THREE.Quaternion(), p.scale));
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
  return { name: map.rig, primitives, ribbon, far, rest, bind, mainIndex, outer, top };
}

// `batch` copies of `geometry` (position, normal, uv, colour; one index) as one instanced
// geometry, each vertex with its copy's number (meadowCopy) and its skinning summed per main
// joint of `rig` (meadowQ0..3, meadowQr).
function batchOf(geometry, batch, rig) {
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

// One running field: its evaluation and its instanced meshes.
class DrawnField {
  constructor(def, layout, rig, group) {
    this.def = def;
    this.n = def.plants;
    this.rig = rig;
    this.eval = new frondField.FieldEval({
      positions: layout.positions, rows: layout.rows, startFrames: layout.startFrames,
      rowCount: def.rows, authoredDirectionDeg: def.authored_direction_deg,
      fps: def.stream_fps, historyFrames: def.history_frames,
    });
    this.positions = layout.positions;
    this.scales = layout.scales;
    const texRows = Math.max(1, Math.ceil(this.n / PER_ROW));
    // 4 texels a plant: the 12 angles, then x, z, scale (written once).
    this.angles = new Float32Array(PER_ROW * 16 * texRows);
    for (let i = 0; i < this.n; i++) {
      this.angles.set([this.positions[2 * i], this.positions[2 * i + 1], this.scales[i], 0], 16 * i + 12);
    }
    this.texture = new THREE.DataTexture(this.angles, PER_ROW * 4, texRows, THREE.RGBAFormat, THREE.FloatType);
    this.texture.needsUpdate = true;
    const shared = {
      meadowPoses: { value: this.texture },
      meadowRest: { value: rig.rest },
      meadowOuter: { value: rig.outer },
    };
    // One level of detail: the mesh copied into a batch, drawn instanced, its slots' plants in
    // a texture of its own.
    const lod = (geometry, material) => {
      const verts = geometry.getAttribute('position').count;
      const batch = Math.max(1, Math.min(256, Math.floor(MAX_BATCH_VERTICES / verts)));
      const g = batchOf(geometry, batch, rig);
      const slots = new Float32Array(PER_ROW * texRows);
      const slotTexture = new THREE.DataTexture(slots, PER_ROW, texRows, THREE.RedFormat, THREE.FloatType);
      const uniforms = { ...shared, meadowSlots: { value: slotTexture }, meadowBatch: { value: batch }, meadowCount: { value: 0 } };
      const mesh = new THREE.Mesh(g, meadowMaterial(material, uniforms));
      mesh.frustumCulled = false;
      g.instanceCount = 0;
      group.add(mesh);
      return { mesh, batch, slots, slotTexture, uniforms };
    };
    this.near = rig.primitives.map((p) => lod(p.geometry, p.material));
    this.far = [lod(rig.ribbon, rig.far)];
    this.nearCount = 0;
    this.frameSeq = null;
    this.frameAt = 0;
    this.partitionedAt = -Infinity;
    this.partitionCamera = new THREE.Vector3(Infinity, 0, 0);
  }

  // Near plants get the rig's mesh, far ones the ribbon (camera position `eye`).
  partition(eye, now) {
    if (now - this.partitionedAt < REPARTITION_MS) return;
    const reach = LOD_HEIGHTS * this.rig.top;
    if (eye.distanceTo(this.partitionCamera) < reach * 0.05) return;
    this.partitionedAt = now;
    this.partitionCamera.copy(eye);
    const d2 = new Float32Array(this.n);
    for (let i = 0; i < this.n; i++) {
      const dx = this.positions[2 * i] - eye.x, dz = this.positions[2 * i + 1] - eye.z;
      d2[i] = dx * dx + dz * dz + eye.y * eye.y;
    }
    let r2 = reach * reach;
    const within = d2.filter((x) => x <= r2);
    const nearMax = globalThis.frondMeadow?.nearMax ?? NEAR_MAX;
    if (within.length > nearMax) r2 = nearMax ? within.sort()[nearMax - 1] : -1;
    const near = [], far = [];
    for (let i = 0; i < this.n; i++) (d2[i] <= r2 && near.length < nearMax ? near : far).push(i);
    const fill = (levels, list) => {
      for (const l of levels) {
        l.slots.set(list);
        l.slotTexture.needsUpdate = true;
        l.uniforms.meadowCount.value = list.length;
        l.mesh.geometry.instanceCount = Math.ceil(list.length / l.batch);
      }
    };
    fill(this.near, near);
    fill(this.far, far);
    this.nearCount = near.length;
  }

  // The stream time to draw at: the last frame's, advanced by the motion speed since it came.
  tauNow(now) {
    const c = this.eval.controls;
    return c ? this.eval.tau + c.time_step * Math.max(0, now - this.frameAt) / 1000 : this.eval.tau;
  }

  // Every plant at stream time `tau` into the texture. A plant whose stream frames have not
  // all come (a page that joined, or lost frames) keeps its last pose, at first the rest pose.
  evaluate(tau) {
    const out = this.angles, f = this.eval, tmp = this.tmp || (this.tmp = new Float32Array(12));
    let done = 0;
    for (let i = 0; i < this.n; i++) {
      if (!f.plantPose(i, tau, tmp, 0)) continue;
      out.set(tmp, 16 * i);
      done++;
    }
    this.texture.needsUpdate = true;
    this.evaluated = done;
    return done;
  }

  dispose(group) {
    for (const l of [...this.near, ...this.far]) {
      group.remove(l.mesh);
      l.mesh.geometry.dispose();
      l.mesh.material.dispose();
      l.slotTexture.dispose();
    }
    this.texture.dispose();
  }
}

export class Meadow {
  constructor({ scene, camera, renderer, controls }) {
    this.scene = scene;
    this.camera = camera;
    this.renderer = renderer;
    this.controls = controls;
    this.group = new THREE.Group();
    this.group.name = 'meadow';
    scene.add(this.group);
    this.rig = null;
    this.defs = [];          // the console's latest table
    this.fields = new Map(); // field id -> DrawnField
    this.loading = new Map();
    this.pending = new Map(); // field id -> frames that came while its layout loaded
    this.framed = new Set();
    this.notes = [];
    this.note = (t) => { if (!this.notes.includes(t)) this.notes.push(t); this.notes.splice(0, this.notes.length - 20); };
    this.animate = true;
    globalThis.frondMeadow = this;
  }

  // The console's rig (its glTF scene and node map): the rig every field of it is drawn with.
  setRig(map, root) {
    try {
      this.rig = rigOf(map, root);
      this.rigRoot = root;
      this.rigJoints = map.joints;
    } catch (e) {
      this.rig = null;
      this.note(`the meadow cannot draw rig ${map.rig}: ${e.message}`);
    }
    for (const f of this.fields.values()) f.dispose(this.group);
    this.fields.clear();
    this.onTable({ fields: this.defs });
  }

  // Stage names of the fields drawn here (their announced plants need no clone of their own).
  drawsSource(source) {
    for (const f of this.fields.values()) if (f.def.source === source) return true;
    return false;
  }

  onMessage(m) {
    if (m.type === 'fields') this.onTable(m);
    else if (m.type === 'field-frames') this.onFrames(m.frames);
  }

  onTable(m) {
    this.defs = m.fields;
    const same = (a, b) => JSON.stringify(a) === JSON.stringify(b);
    for (const [id, f] of this.fields) {
      if (!this.defs.some((d) => same(d, f.def))) { f.dispose(this.group); this.fields.delete(id); }
    }
    for (const d of this.defs) {
      if ((this.fields.has(d.id) && same(this.fields.get(d.id).def, d)) || this.loading.has(d.id)) continue;
      if (!this.rig) continue; // drawn once the rig has loaded (setRig)
      if (d.rig !== this.rig.name) {
        this.note(`field ${d.source} of rig ${d.rig} is not drawn: the view shows rig ${this.rig.name}`);
        continue;
      }
      this.loading.set(d.id, this.load(d).catch((e) => this.note(`field ${d.source}: ${e.message}`))
        .finally(() => this.loading.delete(d.id)));
    }
  }

  async load(d) {
    const r = await fetch(d.layout);
    if (!r.ok) throw new Error(`its layout: ${r.status} ${await r.text()}`);
    const buf = await r.arrayBuffer();
    if (buf.byteLength !== 20 * d.plants) throw new Error(`its layout is ${buf.byteLength} bytes for ${d.plants} plants`);
    const n = d.plants;
    const layout = {
      positions: new Float32Array(buf, 0, 2 * n), rows: new Uint32Array(buf, 8 * n, n),
      startFrames: new Uint32Array(buf, 12 * n, n), scales: new Float32Array(buf, 16 * n, n),
    };
    // The table may have moved on while the layout came.
    if (!this.defs.some((x) => JSON.stringify(x) === JSON.stringify(d)) || !this.rig || d.rig !== this.rig.name) return;
    const f = new DrawnField(d, layout, this.rig, this.group);
    this.fields.set(d.id, f);
    this.onFrames(this.pending.get(d.id) || []);
    this.pending.delete(d.id);
    if (!this.framed.has(d.source)) { this.framed.add(d.source); this.frame(f); }
  }

  onFrames(frames) {
    const now = performance.now();
    for (const fr of frames) {
      const f = this.fields.get(fr.field);
      if (!f) {
        if (this.loading.has(fr.field)) {
          const p = this.pending.get(fr.field) || [];
          p.push(fr);
          if (p.length > 256) p.shift();
          this.pending.set(fr.field, p);
        }
        continue;
      }
      if (f.eval.applyFrame(fr)) { f.frameSeq = fr.seq; f.frameAt = now; f.frameHostNs = fr.host_monotonic_ns; f.frameShown = false; }
    }
  }

  // Puts the whole field in view, once per field (the operator may orbit away after).
  frame(f) {
    let [x0, z0, x1, z1] = [Infinity, Infinity, -Infinity, -Infinity];
    const p = f.positions;
    for (let i = 0; i < f.n; i++) {
      x0 = Math.min(x0, p[2 * i]); x1 = Math.max(x1, p[2 * i]);
      z0 = Math.min(z0, p[2 * i + 1]); z1 = Math.max(z1, p[2 * i + 1]);
    }
    const cx = (x0 + x1) / 2, cz = (z0 + z1) / 2, size = Math.max(x1 - x0, z1 - z0, f.rig.top * 4);
    this.camera.position.set(cx, size * 0.45, cz + size * 0.85);
    this.camera.far = Math.max(this.camera.far, size * 4);
    this.camera.updateProjectionMatrix();
    if (this.controls) { this.controls.target.set(cx, 0, cz); this.controls.update(); }
  }

  // Before each render: every field evaluated at the display's stream time (unless standing
  // still), near and far chosen again when the camera moved.
  update(now = performance.now()) {
    const eye = this.camera.getWorldPosition(new THREE.Vector3());
    for (const f of this.fields.values()) {
      f.partition(eye, now);
      if (this.animate) f.evaluate(f.tauNow(now));
    }
  }

  // After each render of the view: while `latency` is an array (the benchmark sets it), the
  // first render that shows a field frame waits for its pixels and records [the frame's daemon
  // publish time (CLOCK_MONOTONIC ns), the wall-clock ms it was drawn].
  rendered() {
    if (!Array.isArray(this.latency)) return;
    let gl = null;
    for (const f of this.fields.values()) {
      if (f.frameShown !== false) continue;
      if (!gl) {
        gl = this.renderer.getContext();
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
      }
      f.frameShown = true;
      if (this.latency.length < 100000) this.latency.push([f.frameHostNs, performance.timeOrigin + performance.now()]);
    }
  }

  // ---- for tests and the benchmark ----

  // Field `id`'s plants at stream time `tau` as the page evaluates them (12 angles a plant),
  // with the sequence number of the last frame it applied.
  evaluated(id, tau) {
    const f = this.fields.get(id);
    if (!f) return null;
    const done = f.evaluate(tau);
    const angles = new Array(12 * f.n);
    for (let i = 0; i < f.n; i++) for (let k = 0; k < 12; k++) angles[12 * i + k] = f.angles[16 * i + k];
    return { seq: f.frameSeq, tau: f.eval.tau, done, plants: f.n, angles };
  }

  // Plant `i` of field `id` alone in a close view, drawn by the meadow's shader (its rig mesh)
  // and by three.js's own skinning (a SkinnedMesh clone of the rig, its joints set to the same
  // angles in the protocol's convention, R = R_yaw(Z) R_pitch(X) R_roll(Y)), each into a
  // 256 x 256 target: the pixels each covers and both cover.
  silhouettes(id, i) {
    const f = this.fields.get(id);
    if (!f || !this.rigRoot || !(i >= 0 && i < f.n)) return null;
    const r = this.renderer, size = 256;
    const x = f.positions[2 * i], z = f.positions[2 * i + 1], s = f.scales[i], top = this.rig.top * s;
    const cam = new THREE.PerspectiveCamera(40, 1, top * 0.05, top * 20);
    cam.position.set(x + top * 1.2, top * 0.7, z + top * 2.2);
    cam.lookAt(x, top * 0.5, z);
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0x000000);
    scene.add(new THREE.AmbientLight(0xffffff, 3));
    const target = new THREE.WebGLRenderTarget(size, size);
    const draw = () => {
      const px = new Uint8Array(size * size * 4);
      r.setRenderTarget(target);
      r.render(scene, cam);
      r.readRenderTargetPixels(target, 0, 0, size, size, px);
      r.setRenderTarget(null);
      const mask = new Uint8Array(size * size);
      for (let k = 0; k < mask.length; k++) mask[k] = Math.max(px[4 * k], px[4 * k + 1], px[4 * k + 2]) > 8 ? 1 : 0;
      return mask;
    };
    // The meadow's: plant i in the near level's first slot, alone.
    const levels = f.near, parents = levels.map((l) => l.mesh.parent);
    for (const l of levels) {
      l.slots[0] = i;
      l.slotTexture.needsUpdate = true;
      l.uniforms.meadowCount.value = 1;
      l.mesh.geometry.instanceCount = 1;
      scene.add(l.mesh);
    }
    const a = draw();
    levels.forEach((l, k) => parents[k].add(l.mesh));
    f.partitionedAt = -Infinity;
    f.partitionCamera.set(Infinity, 0, 0); // chosen again at the next frame
    // three.js's: the rig cloned, placed and posed.
    const plant = cloneSkinned(this.rigRoot);
    plant.position.set(x, 0, z);
    plant.scale.setScalar(s);
    const d = Math.PI / 180, qa = new THREE.Quaternion(), qb = new THREE.Quaternion();
    const X = new THREE.Vector3(1, 0, 0), Y = new THREE.Vector3(0, 1, 0), Z = new THREE.Vector3(0, 0, 1);
    this.rigJoints.forEach((n, j) => {
      const b = plant.getObjectByName(THREE.PropertyBinding.sanitizeNodeName(n));
      const [p, y, rl] = f.angles.subarray(16 * i + 3 * j, 16 * i + 3 * j + 3);
      b.quaternion.setFromAxisAngle(Z, y * d).multiply(qa.setFromAxisAngle(X, p * d)).multiply(qb.setFromAxisAngle(Y, rl * d));
    });
    scene.add(plant);
    const b = draw();
    // And at rest, to show that the pose is what makes them agree.
    this.rigJoints.forEach((n) => plant.getObjectByName(THREE.PropertyBinding.sanitizeNodeName(n)).quaternion.identity());
    const c = draw();
    target.dispose();
    let both = 0, meadow = 0, skinned = 0, rest = 0, bothRest = 0;
    for (let k = 0; k < a.length; k++) {
      meadow += a[k]; skinned += b[k]; both += a[k] & b[k]; rest += c[k]; bothRest += a[k] & c[k];
    }
    return { meadow, skinned, both, rest, both_rest: bothRest, angles: Array.from(f.angles.subarray(16 * i, 16 * i + 12)) };
  }

  // Draw calls of one render of the whole scene, and of the scene without the meadow.
  drawCalls() {
    const r = this.renderer;
    r.render(this.scene, this.camera);
    const all = r.info.render.calls;
    this.group.visible = false;
    r.render(this.scene, this.camera);
    const without = r.info.render.calls;
    this.group.visible = true;
    const levels = [...this.fields.values()].flatMap((f) => [...f.near, ...f.far]);
    return {
      all, without, meadow: all - without, instanced: levels.filter((l) => l.mesh.geometry.isInstancedBufferGeometry).length,
      instances: levels.reduce((s, l) => s + l.mesh.geometry.instanceCount, 0),
      plants: levels.reduce((s, l) => s + l.uniforms.meadowCount.value, 0),
      near: [...this.fields.values()].reduce((s, f) => s + f.nearCount, 0),
    };
  }

  // The share of the view's pixels the meadow changes (rendered without it, then with it).
  coverage() {
    const r = this.renderer, gl = r.getContext();
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const read = () => { const px = new Uint8Array(w * h * 4); gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px); return px; };
    this.group.visible = false;
    r.render(this.scene, this.camera);
    const a = read();
    this.group.visible = true;
    r.render(this.scene, this.camera);
    const b = read();
    let n = 0;
    for (let i = 0; i < a.length; i += 4) {
      if (Math.max(Math.abs(a[i] - b[i]), Math.abs(a[i + 1] - b[i + 1]), Math.abs(a[i + 2] - b[i + 2])) > 24) n++;
    }
    return n / (w * h);
  }

  // `frames` frames rendered one after the other, each finished on the GPU, animating or
  // standing still: each frame's milliseconds.
  timeFrames(frames, animate) {
    const gl = this.renderer.getContext();
    const px = new Uint8Array(4);
    const out = [];
    const was = this.animate;
    this.animate = animate;
    for (let k = 0; k < frames; k++) {
      const t0 = performance.now();
      this.update(t0);
      this.renderer.render(this.scene, this.camera);
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px); // waits for the frame
      out.push(performance.now() - t0);
    }
    this.animate = was;
    return out;
  }
}
