// frond console page: the daemon's rig (as frond-gltf bakes it) driven by the live poses over
// a WebSocket, the stage's health from /api/status, and the recording controls.
import * as THREE from 'three';
import { GLTFLoader } from '/vendor/three/GLTFLoader.js';
import { OrbitControls } from '/vendor/three/OrbitControls.js';
import { clone as cloneSkinned } from '/vendor/three/SkeletonUtils.js';
import { Meadow } from '/meadow.js';
import { startCalibration } from '/calibrate.js';

const $ = (id) => document.getElementById(id);

// State read by people and by the headless-browser test (window.frondConsole).
const state = {
  hello: null,       // the stream's hello message
  map: null,         // /api/scene: joint node names of the baked rig
  received: {},      // element id -> the latest pose message received
  applied: {},       // element id -> seq of the pose the scene shows
  messages: 0,
  webgl: false,
};

// ---- the protocol's rotation convention: R = R_yaw(Z) * R_pitch(X) * R_roll(Y), degrees ----
const X = new THREE.Vector3(1, 0, 0), Y = new THREE.Vector3(0, 1, 0), Z = new THREE.Vector3(0, 0, 1);
const qa = new THREE.Quaternion(), qb = new THREE.Quaternion();
function jointQuat([pitch, yaw, roll], out) {
  const d = Math.PI / 180;
  out.setFromAxisAngle(Z, yaw * d);
  out.multiply(qa.setFromAxisAngle(X, pitch * d));
  out.multiply(qb.setFromAxisAngle(Y, roll * d));
  return out;
}

// ---- 3D view ----
const canvas = $('three');
let renderer = null;
try {
  renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  state.webgl = true;
} catch (e) {
  $('view-note').hidden = false;
  $('view-note').textContent = `The 3D view needs WebGL, which this browser does not give (${e.message}). Health and controls still work.`;
}
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x14171a);
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
camera.position.set(1.2, 0.9, 1.6);
scene.add(new THREE.HemisphereLight(0xdde8ff, 0x404030, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 2.0);
sun.position.set(2, 4, 3);
scene.add(sun);
let grid = new THREE.GridHelper(4, 40, 0x556070, 0x2a3038);
scene.add(grid);
const controls = renderer ? new OrbitControls(camera, canvas) : null;
if (controls) { controls.target.set(0, 0.4, 0); controls.update(); }
// A running field's plants, every one evaluated and drawn in the page (meadow.js).
const meadow = renderer ? new Meadow({ scene, camera, renderer, controls }) : null;

let plant = null;           // gltf.scene
let mainBones = [];         // the rig's 4 joints
let layerBones = {};        // rig element name -> [[4 joints] per instance]
let axes = [];

function resize() {
  const r = canvas.parentElement.getBoundingClientRect();
  camera.aspect = Math.max(r.width, 1) / Math.max(r.height, 1);
  camera.updateProjectionMatrix();
  if (renderer) renderer.setSize(r.width, r.height, false);
}
window.addEventListener('resize', resize);

async function loadRig() {
  const map = await (await fetch('/api/scene')).json();
  if (map.error) throw new Error(map.error);
  const gltf = await new GLTFLoader().loadAsync('/rig.glb');
  if (plant) scene.remove(plant);
  plant = gltf.scene;
  scene.add(plant);
  const byName = (n) => {
    const o = plant.getObjectByName(THREE.PropertyBinding.sanitizeNodeName(n));
    if (!o) throw new Error(`the GLB has no node ${n}`);
    return o;
  };
  mainBones = map.joints.map(byName);
  layerBones = {};
  for (const e of map.elements) layerBones[e.name] = e.instances.map((inst) => inst.map(byName));
  state.map = map;
  meadow?.setRig(map, plant);
  state.applied = {};
  for (const f of Object.values(fieldPlants)) f.root.removeFromParent();
  fieldPlants = {};
  const top = map.heights_m[map.heights_m.length - 1];
  // A ground grid of the plant's scale: 8 heights across, a line every half height.
  const visible = grid.visible;
  scene.remove(grid);
  grid = new THREE.GridHelper(top * 8, 16, 0x556070, 0x2a3038);
  grid.visible = visible;
  scene.add(grid);
  if (controls) { controls.target.set(0, top * 0.5, 0); camera.position.set(top * 1.8, top * 1.3, top * 3.2); controls.update(); }
  setAxes($('axes').checked);
  $('rig').textContent = `rig ${map.rig}`;
  await syncField();
  for (const p of Object.values(state.received)) apply(p);
}

// ---- field plants (seed 000, section 6.2) and graph walks: one instance of the plant each ----
let fieldPlants = {}; // element id -> {root, bones, index, position, scale}
let syncing = null;
function syncField() {
  syncing = (syncing || Promise.resolve()).then(syncFieldNow).catch(() => {});
  return syncing;
}
async function syncFieldNow() {
  const els = (state.hello?.hello?.elements || []).filter((e) => e.kind === 'field-plant' && e.rig === state.map?.rig);
  for (const id of Object.keys(fieldPlants)) {
    if (!els.some((e) => e.id === Number(id))) { fieldPlants[id].root.removeFromParent(); delete fieldPlants[id]; }
  }
  if (!els.length || !plant) return;
  // The layout of a field this console started; any other field's plants stand on a grid.
  const layout = await (await fetch('/api/field')).json();
  for (const e of els) {
    if (fieldPlants[e.id]) continue;
    const i = Number((e.name.match(/(\d+)$/) || [0, '0'])[1]);
    const spacing = state.map.heights_m[3] * 1.5;
    const position = layout?.positions_m?.[i] ?? [(i % 8) * spacing, Math.floor(i / 8) * spacing];
    const scale = layout?.scales?.[i] ?? 1;
    const root = cloneSkinned(plant);
    root.position.set(position[0], 0, position[1]);
    root.scale.setScalar(scale);
    scene.add(root);
    const bones = state.map.joints.map((n) => root.getObjectByName(THREE.PropertyBinding.sanitizeNodeName(n)));
    fieldPlants[e.id] = { root, bones, index: i, position, scale, source: e.source };
  }
  // The hand's own plant stays where it is; the field stands around it.
}

function setAxes(on) {
  for (const a of axes) a.removeFromParent();
  axes = [];
  if (!on || !state.map) return;
  const size = state.map.heights_m[3] * 0.15;
  for (const b of [...mainBones, ...Object.values(layerBones).flat(2)]) {
    const a = new THREE.AxesHelper(size);
    b.add(a);
    axes.push(a);
  }
}
$('axes').addEventListener('change', (e) => setAxes(e.target.checked));
$('grid').addEventListener('change', (e) => { grid.visible = e.target.checked; });

// The bones an element drives: the main skeleton for the hand / playback element of the
// daemon's rig, every instance of a rig element for its layer.
function bonesOf(id) {
  const info = state.hello?.hello?.elements?.find((e) => e.id === id);
  if (!info) return id === 0 ? [mainBones] : [];
  if (info.kind === 'layer') return layerBones[info.name] || [];
  if (info.kind === 'hand' || info.kind === 'playback') return info.rig === state.map?.rig ? [mainBones] : [];
  if (info.kind === 'field-plant' && fieldPlants[id]) return [fieldPlants[id].bones];
  return [];
}

function apply(p) {
  // While a take plays in the view, the main skeleton shows the take, not the live hand.
  if (player && p.e === 0) return;
  const sets = bonesOf(p.e);
  for (const bones of sets) {
    bones.forEach((b, i) => jointQuat(p.j[i], b.quaternion));
  }
  if (sets.length) state.applied[p.e] = p.seq;
}

function frame() {
  if (player) showTakeFrame();
  if (renderer) {
    resize();
    // A field the meadow draws needs no clone of its announced plants.
    for (const f of Object.values(fieldPlants)) f.root.visible = !meadow?.drawsSource(f.source);
    meadow?.update();
    renderer.render(scene, camera);
    meadow?.rendered();
  }
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);

// ---- the pose stream ----
let rigShown = null;
// Messages taken on the socket, said to the console as each is handled: it keeps a page at most
// a few messages behind, so one slower than the stream (a large meadow drawn in software) gets
// the latest when it is free rather than a queue.
const flow = { ws: null, taken: 0 };
function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  Object.assign(flow, { ws, taken: 0 });
  ws.onmessage = (ev) => {
    flow.taken++;
    // Taken as soon as it is handled, not once the next frame is drawn: while the page draws,
    // the console goes on sending (up to its window), and the frame after draws the newest.
    ws.send(`{"ack":${flow.taken}}`);
    const m = JSON.parse(ev.data);
    state.messages++;
    if (m.type === 'hello') {
      state.hello = m;
      const link = $('link');
      link.textContent = m.connected ? `daemon ${m.hello?.daemon_version ?? ''}` : `daemon not connected: ${m.why}`;
      link.className = m.connected ? 'ok' : 'bad';
      const rig = m.hello?.rig;
      if (m.connected && rig && rig !== rigShown) {
        rigShown = rig;
        loadRig().catch((e) => { $('view-note').hidden = false; $('view-note').textContent = String(e.message || e); });
      } else if (state.map) {
        syncField();
      }
    } else if (m.type === 'fields' || m.type === 'field-frames') {
      meadow?.onMessage(m);
    } else if (m.type === 'poses') {
      for (const p of m.poses) {
        state.received[p.e] = p;
        if (state.map) apply(p);
      }
    }
  };
  ws.onclose = () => setTimeout(connect, 500);
}
connect();

// ---- health ----
const history = [];
function fmtUs(v) { return v >= 1000 ? `${(v / 1000).toFixed(2)} ms` : `${v.toFixed(0)} µs`; }
function drawLateness() {
  const c = $('lateness-plot'), g = c.getContext('2d');
  g.clearRect(0, 0, c.width, c.height);
  if (history.length < 2) return;
  const top = Math.max(50, ...history.map((h) => h.max_us));
  const y = (v) => c.height - 2 - (v / top) * (c.height - 12);
  for (const [key, color] of [['max_us', '#e5534b'], ['p99_us', '#d4a72c'], ['p50_us', '#5fbf77']]) {
    g.strokeStyle = color; g.beginPath();
    history.forEach((h, i) => { const x = (i / 119) * c.width; i ? g.lineTo(x, y(h[key])) : g.moveTo(x, y(h[key])); });
    g.stroke();
  }
  g.fillStyle = '#8b949e'; g.fillText(fmtUs(top), 2, 10);
}
function drawHistogram(buckets, id = 'latency-hist') {
  const c = $(id), g = c.getContext('2d');
  g.clearRect(0, 0, c.width, c.height);
  const top = Math.max(1, ...buckets.map((b) => b.count)), w = c.width / buckets.length;
  g.fillStyle = '#5f8fbf';
  buckets.forEach((b, i) => { const h = (b.count / top) * (c.height - 12); g.fillRect(i * w + 1, c.height - 12 - h, w - 2, h); });
  g.fillStyle = '#8b949e';
  for (const [i, b] of buckets.entries()) if (i % 4 === 0 && b.le_us) g.fillText(fmtUs(b.le_us), i * w, c.height - 1);
}
// The mocap stage (issue 46): capture triggers followed or led, and the stage's timecode (LTC),
// in the words of `frond status`. Names come from the stage network: set as text, never HTML.
function showStageSync(d) {
  const lines = [];
  const t = d.triggers;
  if (t) {
    const parts = [];
    const from = t.allow.length ? ` from ${t.allow.join(', ')}` : ' from any host';
    if (t.listen) parts.push(t.paused
      ? `PAUSED: capture triggers on ${t.listen}${from} are heard, not followed (${t.paused_starts} starts missed)`
      : `following capture triggers on ${t.listen}${from}`);
    if (t.lead) parts.push(`leading to ${t.lead}`);
    if (t.scheduled) parts.push(`take ${t.scheduled} waits for its delay`);
    if (t.last) parts.push(`last ${t.last.kind}${t.last.name ? ` ${t.last.name}` : ''} from ${t.last.from}, ${t.last.age_s.toFixed(0)} s ago`);
    const refused = t.foreign + t.malformed + t.oversized;
    if (refused) parts.push(`${refused} refused (${t.foreign} foreign, ${t.malformed} malformed, ${t.oversized} oversized)`);
    lines.push(`triggers: ${parts.join('; ')}`);
  }
  const l = d.ltc;
  if (l) {
    const last = l.last_timecode ? `, last ${l.last_timecode}` : '';
    const overruns = l.overruns ? `, ${l.overruns} ALSA overruns` : '';
    lines.push(`timecode (LTC): ${l.state}${l.fps ? ` at ${l.fps} fps` : ''} from ${l.input}${last}${overruns}`);
  }
  const toggle = $('triggers-toggle');
  toggle.hidden = !(t && t.listen);
  if (t && t.listen) {
    toggle.textContent = t.paused ? 'follow triggers' : 'pause triggers';
    toggle.dataset.mode = t.paused ? 'follow' : 'pause';
  }
  const el = $('stage-sync');
  el.replaceChildren(...lines.map((text) => { const div = document.createElement('div'); div.textContent = text; return div; }));
  el.hidden = !lines.length;
  el.className = (l && l.state !== 'locked') || (t && t.paused) ? 'bad' : '';
}
$('triggers-toggle').addEventListener('click', (e) => post('/api/triggers', { mode: e.target.dataset.mode }).then(pollStatus));
async function pollStatus() {
  try {
    const s = await (await fetch('/api/status')).json();
    state.status = s;
    const d = s.daemon;
    const probs = $('problems');
    probs.replaceChildren();
    // What is wrong, in words, with the fix (the same words as `frond doctor`).
    for (const p of s.health || []) {
      const li = document.createElement('li');
      const what = document.createElement('b'); what.textContent = p.what;
      const fix = document.createElement('div'); fix.className = 'fix'; fix.textContent = `fix: ${p.fix}`;
      li.append(what, fix);
      probs.append(li);
    }
    if (d) {
      $('source').textContent = `${d.source.kind} ${d.source.path} — ${d.source.connected ? 'connected' : 'NOT CONNECTED'}, ${d.source.reports} reports`;
      $('source').className = d.source.connected ? 'ok' : 'bad';
      $('achieved').textContent = `${d.achieved_rate_hz.toFixed(1)} Hz of ${d.tick_rate_hz} Hz, ${d.publish_drops} publish drops`;
      const l = d.lateness;
      $('lateness').textContent = `p50 ${fmtUs(l.p50_us)}, p99 ${fmtUs(l.p99_us)}, max ${fmtUs(l.max_us)}`;
      history.push(l); if (history.length > 120) history.shift();
      drawLateness();
      if (d.lateness_histogram?.length) drawHistogram(d.lateness_histogram, 'lateness-hist');
      const tb = $('subscribers').tBodies[0];
      tb.replaceChildren(...d.subscribers.map((sub) => {
        const tr = document.createElement('tr');
        for (const v of [sub.id, `${sub.connected_s.toFixed(0)} s`, sub.sent, sub.dropped]) {
          const td = document.createElement('td'); td.textContent = v; tr.append(td);
        }
        if (sub.dropped > 0) tr.className = 'bad';
        return tr;
      }));
      $('device-events').replaceChildren(...d.device_events.slice(-6).map((t) => { const li = document.createElement('li'); li.textContent = t; return li; }));
      const r = d.recording;
      $('recording').textContent = r && r.active ? `RECORDING ${r.name}: ${r.frames} frames${r.dropped ? `, ${r.dropped} dropped` : ''}` : 'not recording';
      $('recording').className = r && r.active ? 'bad' : '';
      showStageSync(d);
      $('rate').textContent = `${d.achieved_rate_hz.toFixed(0)} Hz`;
      $('stages').textContent = [`rig ${d.rig_name}`, `filter ${d.filter}`, `calibration ${d.calibration_id}`, ...(d.modes || [])].join(' · ');
      if (document.activeElement !== $('rig-select') && rigShown) $('rig-select').value = rigShown;
    }
    const c = s.console;
    const gl = c.glove_latency;
    $('glove-latency').textContent = gl && gl.samples
      ? `glove → console p50 ${fmtUs(gl.p50_us)}, p99 ${fmtUs(gl.p99_us)}, max ${fmtUs(gl.max_us)}`
      : c.glove_clock_foreign ? 'the glove keeps its own clock: glove → console cannot be measured (delivery below)' : '–';
    const lat = c.latency;
    if (lat && lat.samples) {
      $('delivery').textContent = `daemon → console p50 ${fmtUs(lat.p50_us)}, p99 ${fmtUs(lat.p99_us)}, max ${fmtUs(lat.max_us)}`;
      drawHistogram(lat.histogram);
    }
    $('stream').textContent = `${c.frames} poses in, ${c.gaps} gaps (${c.missing} missing), ${c.dropped} page messages dropped`;
  } catch (e) {
    $('source').textContent = `console unreachable: ${e.message}`;
  }
  setTimeout(pollStatus, 250);
}
pollStatus();

// ---- controls ----
async function post(path, body) {
  const out = $('control-result');
  try {
    const r = await fetch(path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body || {}) });
    const j = await r.json();
    out.textContent = r.ok ? (j.recording ? `${j.recording.active ? 'recording' : 'stopped'} ${j.recording.name}: ${j.recording.frames} frames` : 'done') : j.error;
    out.className = r.ok ? 'ok' : 'bad';
    return j;
  } catch (e) {
    out.textContent = e.message; out.className = 'bad';
    return null;
  }
}
$('record-form').addEventListener('submit', (e) => { e.preventDefault(); post('/api/record/start', { name: $('take-name').value.trim() }); });
$('record-stop').addEventListener('click', () => post('/api/record/stop').then(listTakes));
$('mark-form').addEventListener('submit', (e) => { e.preventDefault(); post('/api/mark', { label: $('mark-label').value }); });

// ---- takes: list, play in the view with a scrubber, downloads, loop on the daemon ----
let player = null; // {name, fps, frames, t0, paused, k}
function showTakeFrame() {
  const n = player.frames.length;
  if (!player.paused) player.k = Math.floor(((performance.now() - player.t0) / 1000) * player.fps) % n;
  $('scrubber').value = player.k;
  mainBones.forEach((b, i) => jointQuat(player.frames[player.k][i], b.quaternion));
}
async function play(name) {
  const r = await fetch(`/api/takes/${encodeURIComponent(name)}/play`);
  const j = await r.json();
  if (!r.ok) { $('control-result').textContent = j.error; $('control-result').className = 'bad'; return; }
  player = { name, fps: j.fps, frames: j.frames, t0: performance.now(), paused: false, k: 0 };
  $('player').hidden = false;
  $('player-title').textContent = `playing ${name} (${(j.frames.length / j.fps).toFixed(1)} s)`;
  $('scrubber').max = j.frames.length - 1;
  $('player-pause').textContent = 'Pause';
}
$('scrubber').addEventListener('input', (e) => {
  if (!player) return;
  player.paused = true; player.k = Number(e.target.value);
  $('player-pause').textContent = 'Play';
});
$('player-pause').addEventListener('click', () => {
  if (!player) return;
  player.paused = !player.paused;
  if (!player.paused) player.t0 = performance.now() - (player.k / player.fps) * 1000;
  $('player-pause').textContent = player.paused ? 'Play' : 'Pause';
});
$('player-live').addEventListener('click', () => {
  player = null; $('player').hidden = true;
  if (state.received[0]) apply(state.received[0]);
});
async function listTakes() {
  const j = await (await fetch('/api/takes')).json();
  $('takes-dir').textContent = j.error || `in ${j.dir}${j.left_out ? ` (${j.left_out} more not listed)` : ''}`;
  const tb = $('take-list').tBodies[0];
  tb.replaceChildren(...j.takes.map((t) => {
    const tr = document.createElement('tr');
    tr.dataset.take = t.name;
    const cells = [t.name, t.frames ?? '', t.duration_s != null ? `${t.duration_s.toFixed(1)} s` : '', t.state];
    for (const c of cells) { const td = document.createElement('td'); td.textContent = c; tr.append(td); }
    if (t.damage || t.error) tr.title = t.damage || t.error;
    const td = document.createElement('td');
    const btn = (label, title, fn) => { const b = document.createElement('button'); b.type = 'button'; b.textContent = label; b.title = title; b.className = `take-${label.toLowerCase()}`; b.onclick = fn; td.append(b); };
    const link = (label, href) => { const a = document.createElement('a'); a.textContent = label; a.href = href; a.download = ''; td.append(a); };
    btn('Play', 'play in the view', () => play(t.name));
    btn('Loop', 'loop on the daemon (every subscriber sees it)', () => post('/api/playback', { take: t.name }));
    btn('Field', 'play a 4 x 4 field of it on the daemon (section 6.2 of Interactive authoring of bending and twisting motions of short plants using hand gestures), of the rig chosen above', () => {
      const rig = $('field-rig').value;
      post('/api/field/start', rig ? { take: t.name, rig, name: `field-${rig}` } : { take: t.name });
    });
    if (t.state === 'torn' || t.state === 'damaged' || t.state === 'open') {
      btn('Repair', 'keep the readable records and close the take, as frond take repair', async () => {
        const j = await post('/api/takes/repair', { take: t.name });
        if (j && j.message) $('control-result').textContent = j.message;
        listTakes();
      });
    }
    link('GLB', `/api/takes/${encodeURIComponent(t.name)}.glb`);
    link('JSONL', `/api/takes/${encodeURIComponent(t.name)}.jsonl`);
    tr.append(td);
    return tr;
  }));
}
$('takes-refresh').addEventListener('click', listTakes);
listTakes();

// ---- the seed-001 warp preview: JPEG frames over a binary WebSocket ----
const warp = { ws: null, frames: 0, bytes: 0, since: performance.now(), state: null };
state.warp = warp;
function warpConnect() {
  if (!$('warp-on').checked || warp.ws) return;
  const ws = new WebSocket(`ws://${location.host}/ws/warp`);
  ws.binaryType = 'blob';
  warp.ws = ws;
  ws.onmessage = async (ev) => {
    if (typeof ev.data === 'string') {
      const m = JSON.parse(ev.data);
      warp.state = m.state;
      const w = m.state.wind;
      const secs = (performance.now() - warp.since) / 1000;
      $('warp-state').textContent = `wind from the ${m.state.source === 'hand' ? 'hand' : 'procedural gusts (no hand moves)'}: ` +
        `${w.direction_deg.toFixed(0)}°, strength ${w.strength.toFixed(2)}, every ${w.interval_s.toFixed(2)} s · ` +
        `${m.state.fps.toFixed(0)} FPS, ${(warp.bytes / 1024 / Math.max(secs, 0.001)).toFixed(0)} KB/s`;
      return;
    }
    warp.frames++; warp.bytes += ev.data.size;
    const bmp = await createImageBitmap(ev.data);
    $('warp-view').getContext('2d').drawImage(bmp, 0, 0);
    bmp.close();
  };
  ws.onclose = () => { warp.ws = null; setTimeout(warpConnect, 1000); };
}
$('warp-on').addEventListener('change', (e) => {
  $('warp-view').hidden = !e.target.checked;
  if (e.target.checked) warpConnect(); else if (warp.ws) { const ws = warp.ws; warp.ws = null; ws.onclose = null; ws.close(); }
});
warpConnect();

// ---- stage controls: rig, filter, calibration, guided motion, field keys ----
async function listRigs() {
  const rigs = await (await fetch('/api/rigs')).json();
  $('rig-select').replaceChildren(...rigs.map((r) => { const o = document.createElement('option'); o.value = o.textContent = r; return o; }));
  if (rigShown) $('rig-select').value = rigShown;
  const fieldRig = $('field-rig'), chosen = fieldRig.value;
  fieldRig.replaceChildren(fieldRig.options[0], ...rigs.map((r) => { const o = document.createElement('option'); o.value = o.textContent = r; return o; }));
  fieldRig.value = chosen;
}
listRigs();
$('rig-form').addEventListener('submit', (e) => { e.preventDefault(); post('/api/rig', { rig: $('rig-select').value }); });
$('filter-form').addEventListener('submit', (e) => { e.preventDefault(); post('/api/filter', { spec: $('filter-spec').value }); });
$('guided-form').addEventListener('submit', (e) => { e.preventDefault(); post('/api/guided', { spec: $('guided-spec').value.trim() || 'off' }); });
$('calibration-form').addEventListener('submit', async (e) => {
  e.preventDefault();
  const f = $('calibration-file').files[0];
  if (!f) { $('control-result').textContent = 'choose a calibration file first'; $('control-result').className = 'bad'; return; }
  if (f.size > 60000) { $('control-result').textContent = `${f.name} is ${f.size} bytes: not a calibration`; $('control-result').className = 'bad'; return; }
  post('/api/calibration', { toml: await f.text() });
});
for (const b of document.querySelectorAll('#field-keys [data-key]')) b.addEventListener('click', () => post('/api/field/key', { key: b.dataset.key }));
$('field-stop').addEventListener('click', () => post('/api/field/stop'));
$('playback-stop').addEventListener('click', () => post('/api/playback/stop'));
const KEYS = { ArrowLeft: 'left', ArrowRight: 'right', ArrowUp: 'up', ArrowDown: 'down', '+': 'stronger', '=': 'stronger', '-': 'weaker' };
window.addEventListener('keydown', (e) => {
  if (e.target.closest('input, select, textarea') || !KEYS[e.key]) return;
  e.preventDefault();
  post('/api/field/key', { key: KEYS[e.key] });
});

// ---- guided calibration (calibrate.js) ----
startCalibration({ $, state, post });

// ---- for tests and scripts ----
const v = new THREE.Vector3();
let grabbed = null;
let warpGrabbed = null;
function canvasPixels() {
  const c = document.createElement('canvas');
  c.width = canvas.width; c.height = canvas.height;
  const g = c.getContext('2d');
  g.drawImage(canvas, 0, 0);
  return g.getImageData(0, 0, c.width, c.height).data;
}
// The plant's box on screen, canvas pixels: its bones projected, grown by a fifth of its size.
function screenBox() {
  camera.updateMatrixWorld();
  const pts = [...mainBones, ...Object.values(layerBones).flat(2)].map((b) => b.getWorldPosition(new THREE.Vector3()).project(camera));
  const xs = pts.map((p) => (p.x + 1) / 2 * canvas.width), ys = pts.map((p) => (1 - p.y) / 2 * canvas.height);
  const [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
  const m = 0.2 * Math.max(x1 - x0, y1 - y0, 20);
  return [x0 - m, y0 - m, x1 + m, y1 + m].map(Math.round);
}
window.frondConsole = {
  state,
  // The latest applied pose of `element` and the world position of each of its bones, read
  // from the scene graph in one go.
  snapshot(element = 0) {
    if (player && element === 0) {
      showTakeFrame();
      const p = { e: 0, j: player.frames[player.k], k: player.k, take: player.name };
      plant.updateMatrixWorld(true);
      return { pose: p, main: p, bones: [mainBones.map((b) => b.getWorldPosition(v).toArray())] };
    }
    const p = state.received[element];
    const sets = bonesOf(element);
    if (!p || state.applied[element] !== p.seq || !sets.length) return null;
    plant.updateMatrixWorld(true);
    // The main skeleton's pose too: an element's bones hang from it; a field plant's placement.
    const f = fieldPlants[element];
    for (const r of Object.values(fieldPlants)) r.root.updateMatrixWorld(true);
    return {
      pose: p, main: state.received[0] ?? null,
      placement: f ? { index: f.index, position: f.position, scale: f.scale } : null,
      bones: sets.map((bones) => bones.map((b) => b.getWorldPosition(v).toArray())),
    };
  },
  // Keeps the warp panel's pixels now, for warpDiff.
  warpGrab() { const c = $('warp-view'); warpGrabbed = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; return warp.frames; },
  // Pixels of the warp panel changed by more than 30 levels (any channel) since warpGrab().
  warpDiff() {
    const c = $('warp-view'), now = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    for (let i = 0; i < now.length; i += 4) {
      if (Math.max(Math.abs(now[i] - warpGrabbed[i]), Math.abs(now[i + 1] - warpGrabbed[i + 1]), Math.abs(now[i + 2] - warpGrabbed[i + 2])) > 30) n++;
    }
    return { changed: n, pixels: now.length / 4, frames: warp.frames, bytes: warp.bytes };
  },
  // Keeps the canvas's pixels now, for diffSinceGrab.
  grab() { grabbed = canvasPixels(); return grabbed.length; },
  // Pixels changed (any channel by more than 24) since grab(), inside and outside the plant's
  // screen box.
  diffSinceGrab() {
    const now = canvasPixels(), w = canvas.width;
    const [x0, y0, x1, y1] = screenBox();
    let inside = 0, outside = 0;
    for (let i = 0; i < now.length; i += 4) {
      const d = Math.max(Math.abs(now[i] - grabbed[i]), Math.abs(now[i + 1] - grabbed[i + 1]), Math.abs(now[i + 2] - grabbed[i + 2]));
      if (d <= 24) continue;
      const x = (i / 4) % w, y = Math.floor(i / 4 / w);
      if (x >= x0 && x <= x1 && y >= y0 && y <= y1) inside++; else outside++;
    }
    return { inside, outside, box: [x0, y0, x1, y1], size: [w, canvas.height] };
  },
};
