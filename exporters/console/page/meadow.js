// frond console: a running field drawn in the page (protocol 3; seed 000, Eq. 6-7 and section
// 6.3). The console passes on the daemon's field table and every field frame; the page evaluates
// every plant itself with field.js (globalThis.frondField, field_eval.rs ported) and draws the
// plants instanced: one instanced draw call per primitive of the field's rig and level of detail
// (each field is drawn with its own rig: a meadow of grass and flowers is a field of each). Each
// plant's evaluated angles ([pitch, yaw, roll] of 4 joints) and its placement are 4 texels of a
// float DataTexture; the vertex shader chains the skeleton from them and skins (seed 000,
// Eq. 1). An instance holds a batch of plants (the mesh copied BATCH times, each copy a slot):
// software WebGL (SwiftShader) pays a fixed cost per instance, 15-40 us, which made 10,000
// single-plant instances cost 400 ms a frame whatever their size. A slot's plant is read from
// the level's slot texture, so near and far plants are chosen again without touching the mesh.
// Plants far from the camera use a ribbon of 10 vertices skinned to the same 4 joints.
import * as THREE from 'three';
import { GLTFLoader } from '/vendor/three/GLTFLoader.js';
import { clone as cloneSkinned } from '/vendor/three/SkeletonUtils.js';
import { rigOf, batchOf } from '/meadow_rig.js';

const PER_ROW = 1024;          // plants per texture row (4 RGBA texels each), slots per slot row
const MAX_BATCH_VERTICES = 4096; // vertices of one instance (a batch of plants)
const LOD_HEIGHTS = 60;        // plants further than this many plant heights: the ribbon
const NEAR_VERTICES = 4096 * 42; // and beyond the nearest whose meshes have this many vertices
                                 // (4,096 grass blades; a flower has 164, a shrub 690)
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
  }

  // Every plant's squared distance from the camera at `eye` (the meadow partitions on them).
  distances(eye) {
    const d2 = this.d2 || (this.d2 = new Float32Array(this.n));
    for (let i = 0; i < this.n; i++) {
      const dx = this.positions[2 * i] - eye.x, dz = this.positions[2 * i + 1] - eye.z;
      d2[i] = dx * dx + dz * dz + eye.y * eye.y;
    }
    return d2;
  }

  // The plants at most `r2` away (squared, from `distances`), `budget` of them at most, get the
  // rig's mesh, the others the ribbon; how many got the mesh.
  fill(r2, budget) {
    const near = [], far = [];
    for (let i = 0; i < this.n; i++) (this.d2[i] <= r2 && near.length < budget ? near : far).push(i);
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
    return near.length;
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
    this.rig = null;         // the view's rig
    this.rigs = new Map();   // rig name -> promise of what the meadow needs of it (rigOf)
    this.defs = [];          // the console's latest table
    this.fields = new Map(); // field id -> DrawnField
    this.loading = new Map();
    this.pending = new Map(); // field id -> frames that came while its layout loaded
    this.framed = new Set();
    this.notes = [];
    this.note = (t) => { if (!this.notes.includes(t)) this.notes.push(t); this.notes.splice(0, this.notes.length - 20); };
    this.animate = true;
    this.partitionedAt = -Infinity;
    this.partitionCamera = new THREE.Vector3(Infinity, 0, 0);
    globalThis.frondMeadow = this;
  }

  // The view's rig (the console's glTF scene and node map), which fields of it are drawn with;
  // fields of other rigs load theirs from the console (rigNamed).
  setRig(map, root) {
    try {
      this.rig = rigOf(map, root);
      this.rigs.set(this.rig.name, Promise.resolve(this.rig));
    } catch (e) {
      this.rig = null;
      this.note(`the meadow cannot draw rig ${map.rig}: ${e.message}`);
    }
    for (const f of this.fields.values()) f.dispose(this.group);
    this.fields.clear();
    this.onTable({ fields: this.defs });
  }

  // Rig `name` as the meadow draws it: the view's, or the console's /api/rigs/NAME (baked by
  // frond-gltf as the view's is), loaded once.
  rigNamed(name) {
    if (!this.rigs.has(name)) {
      const at = `/api/rigs/${encodeURIComponent(name)}`;
      const p = (async () => {
        const r = await fetch(`${at}.json`);
        if (!r.ok) throw new Error(`rig ${name}: ${r.status} ${await r.text()}`);
        const map = await r.json();
        const gltf = await new GLTFLoader().loadAsync(`${at}.glb`);
        gltf.scene.updateMatrixWorld(true);
        return rigOf(map, gltf.scene);
      })();
      p.catch(() => this.rigs.delete(name)); // asked again with the next table
      this.rigs.set(name, p);
    }
    return this.rigs.get(name);
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
      if (!this.defs.some((d) => same(d, f.def))) { f.dispose(this.group); this.fields.delete(id); this.repartition(); }
    }
    for (const d of this.defs) {
      if ((this.fields.has(d.id) && same(this.fields.get(d.id).def, d)) || this.loading.has(d.id)) continue;
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
    const rig = await this.rigNamed(d.rig);
    // The table may have moved on while the layout and the rig came.
    if (!this.defs.some((x) => JSON.stringify(x) === JSON.stringify(d))) return;
    const old = this.fields.get(d.id);
    if (old) old.dispose(this.group);
    const f = new DrawnField(d, layout, rig, this.group);
    this.fields.set(d.id, f);
    this.repartition();
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
    this.partition(eye, now);
    if (this.animate) for (const f of this.fields.values()) f.evaluate(f.tauNow(now));
  }

  // Near and far chosen again at the next frame.
  repartition() {
    this.partitionedAt = -Infinity;
    this.partitionCamera.set(Infinity, 0, 0);
  }

  // Near plants get their rig's mesh, far ones the ribbon (camera position `eye`): a plant is
  // near within LOD_HEIGHTS of its rig's height, nearest first over the whole meadow, until
  // their meshes hold NEAR_VERTICES (software WebGL pays per vertex: a meadow of grass and
  // flowers costs what the grass alone does). Chosen again at most every REPARTITION_MS when
  // the camera moved, and at the next frame when the fields changed (repartition).
  partition(eye, now) {
    const fields = [...this.fields.values()];
    const reach = (f) => LOD_HEIGHTS * f.rig.top;
    const moved = eye.distanceTo(this.partitionCamera) >= Math.max(0, ...fields.map(reach)) * 0.05;
    if (now - this.partitionedAt < REPARTITION_MS || !moved) return;
    this.partitionedAt = now;
    this.partitionCamera.copy(eye);
    // Each field's plants within reach, nearest first, merged over the fields.
    const sorted = fields.map((f) => {
      const r2 = reach(f) ** 2;
      return f.distances(eye).filter((x) => x <= r2).sort();
    });
    const at = fields.map(() => 0), near = fields.map(() => 0);
    let left = this.nearVertices ?? NEAR_VERTICES;
    for (;;) {
      let k = -1;
      sorted.forEach((d, j) => { if (at[j] < d.length && (k < 0 || d[at[j]] < sorted[k][at[k]])) k = j; });
      if (k < 0 || fields[k].rig.vertices > left) break;
      left -= fields[k].rig.vertices;
      at[k]++;
      near[k]++;
    }
    fields.forEach((f, j) => f.fill(near[j] ? sorted[j][near[j] - 1] : -1, near[j]));
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
    if (!f || !(i >= 0 && i < f.n)) return null;
    const r = this.renderer, size = 256;
    const x = f.positions[2 * i], z = f.positions[2 * i + 1], s = f.scales[i], top = f.rig.top * s;
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
    this.repartition();
    // three.js's: the rig cloned, placed and posed.
    const plant = cloneSkinned(f.rig.root);
    plant.position.set(x, 0, z);
    plant.scale.setScalar(s);
    const d = Math.PI / 180, qa = new THREE.Quaternion(), qb = new THREE.Quaternion();
    const X = new THREE.Vector3(1, 0, 0), Y = new THREE.Vector3(0, 1, 0), Z = new THREE.Vector3(0, 0, 1);
    f.rig.joints.forEach((n, j) => {
      const b = plant.getObjectByName(THREE.PropertyBinding.sanitizeNodeName(n));
      const [p, y, rl] = f.angles.subarray(16 * i + 3 * j, 16 * i + 3 * j + 3);
      b.quaternion.setFromAxisAngle(Z, y * d).multiply(qa.setFromAxisAngle(X, p * d)).multiply(qb.setFromAxisAngle(Y, rl * d));
    });
    scene.add(plant);
    const b = draw();
    // And at rest, to show that the pose is what makes them agree.
    f.rig.joints.forEach((n) => plant.getObjectByName(THREE.PropertyBinding.sanitizeNodeName(n)).quaternion.identity());
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
    // Per rig: its levels (instanced meshes: one draw call each when it has plants), the
    // instances and plants they draw.
    const rigs = {};
    for (const f of this.fields.values()) {
      const r = rigs[f.rig.name] || (rigs[f.rig.name] = { fields: 0, levels: 0, drawn: 0, instances: 0, plants: 0 });
      r.fields++;
      for (const l of [...f.near, ...f.far]) {
        r.levels++;
        r.drawn += l.mesh.geometry.instanceCount > 0 ? 1 : 0;
        r.instances += l.mesh.geometry.instanceCount;
        r.plants += l.uniforms.meadowCount.value;
      }
    }
    return {
      rigs,
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
