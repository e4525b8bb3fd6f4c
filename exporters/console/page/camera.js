// frond console: the camera panel (issue 47). For a `webcam` hand source: which camera, its
// frame rate and latency, the picture the landmark helper keeps (the frame with the detected
// hand's bones in green and landmarks in magenta), and the wrist and thumb angles the daemon
// derives from those landmarks (the primary hand's raw sample, before calibration). The
// picture is fetched a few times a second while the page is visible and drawn on a canvas; it
// is served to this page only (same origin). Everything from the daemon is set as text.

const $ = (id) => document.getElementById(id);
const PERIOD_MS = 250;
const IDLE_MS = 2000;
// `shown`: the hand whose camera the panel shows; `last`: the last /api/camera answer.
const state = { cameras: [], raw: null, pictures: 0, picture: null, error: null, shown: null, last: null };

const fmt = (v) => (v == null || !Number.isFinite(v) ? '–' : `${v.toFixed(1)}°`);

let chosen = null;    // the hand whose camera the panel shows (null: the primary hand's)
let pickerFor = '';  // the hands the picker's buttons are for

// One button per hand of a camera when there are several, rebuilt only when they change (a
// button replaced under the pointer would lose its click).
function showPicker(cameras, cam) {
  const picker = $('camera-pick');
  const key = cameras.map((c) => c.hand).join('\n');
  if (key !== pickerFor) {
    pickerFor = key;
    picker.replaceChildren(...cameras.map((c) => {
      const b = document.createElement('button');
      b.type = 'button'; b.textContent = c.hand; b.title = c.path;
      b.addEventListener('click', () => { chosen = c.hand; showInfo(state.last); });
      return b;
    }));
  }
  picker.hidden = cameras.length < 2;
  [...picker.children].forEach((b) => { b.className = b.textContent === cam.hand ? 'now' : ''; });
}

function showInfo(m) {
  const panel = $('camera');
  panel.hidden = !m.cameras.length;
  if (!m.cameras.length) return null;
  const cam = m.cameras.find((c) => c.hand === chosen) || m.cameras.find((c) => c.hand === m.primary) || m.cameras[0];
  state.shown = cam.hand;
  showPicker(m.cameras, cam);
  const c = cam.camera;
  $('camera-source').textContent = `${cam.hand}: ${cam.path} — ${cam.connected ? 'hand in view' : 'NO HAND in view'}`;
  $('camera-source').className = cam.connected ? 'ok' : 'bad';
  $('camera-rate').textContent = `${c.fps.toFixed(1)} fps, ${c.latency_ms.toFixed(1)} ms frame to sample (model ${c.model_ms.toFixed(1)} ms), ` +
    `${c.empty_frames} of ${c.frames} frames without a hand${c.helper_starts > 1 ? `, helper started ${c.helper_starts} times` : ''}`;
  // The daemon gives the primary hand's raw sample only (the one frond calibrate measures).
  const own = cam.hand === m.primary;
  const r = own ? m.raw : null;
  const angles = r ? [...r.wrist_deg, ...r.thumb_deg] : [];
  ['pitch', 'yaw', 'roll', 'g1', 'g2', 'g3'].forEach((name, k) => { $(`camera-${name}`).textContent = fmt(angles[k]); });
  $('camera-angles').className = r && r.fresh ? '' : 'bad';
  $('camera-angles-note').textContent = own
    ? 'the angles frond derives from the landmarks, before calibration'
    : `the angles are shown for the primary hand (${m.primary}) only`;
  return cam.image;
}

async function showPicture(url) {
  if (!url) {
    $('camera-view').style.opacity = '0.3';
    $('camera-note').textContent = 'the daemon keeps no picture of this camera';
    return;
  }
  const r = await fetch(url, { cache: 'no-store' });
  if (!r.ok) {
    // The last picture stays, dimmed: it is not what the camera sees now.
    $('camera-view').style.opacity = '0.3';
    $('camera-note').textContent = (await r.json().catch(() => ({}))).error || `picture: HTTP ${r.status}`;
    return;
  }
  const bitmap = await createImageBitmap(await r.blob());
  const c = $('camera-view');
  if (c.width !== bitmap.width || c.height !== bitmap.height) { c.width = bitmap.width; c.height = bitmap.height; }
  c.getContext('2d').drawImage(bitmap, 0, 0);
  c.style.opacity = '1';
  state.picture = { url, width: bitmap.width, height: bitmap.height };
  state.pictures++;
  $('camera-note').textContent = '';
}

async function poll() {
  try {
    const m = await (await fetch('/api/camera')).json();
    state.cameras = m.cameras; state.raw = m.raw; state.error = m.error || null; state.last = m;
    const url = showInfo(m);
    if (m.cameras.length && document.visibilityState === 'visible') await showPicture(url);
  } catch (e) {
    state.error = String(e.message || e);
  }
  // Without a camera, a slow look now and then: one may come with a daemon started anew.
  setTimeout(poll, state.cameras.length ? PERIOD_MS : IDLE_MS);
}
poll();

// For tests and scripts: the panel's state, and the colours of the shown picture at points
// [u, v], fractions of its width and height.
window.frondCamera = {
  state,
  rgbAt(points) {
    const c = $('camera-view'), g = c.getContext('2d');
    return points.map(([u, v]) => {
      const x = Math.min(c.width - 1, Math.round(u * c.width)), y = Math.min(c.height - 1, Math.round(v * c.height));
      return [...g.getImageData(x, y, 1, 1).data.slice(0, 3)];
    });
  },
  text() {
    return ['camera-source', 'camera-rate', 'camera-pitch', 'camera-yaw', 'camera-roll', 'camera-g1', 'camera-g2', 'camera-g3']
      .map((id) => $(id).textContent);
  },
};
