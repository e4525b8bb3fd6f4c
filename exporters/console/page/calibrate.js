// frond console: guided calibration, frond calibrate's steps in the page, with the live hand
// against the ranges measured so far (seed 000, Eq. 3). An ES module of the console's page:
// console.js starts it with what it shares ($, the page's state, its POST helper).
export function startCalibration({ $, state, post }) {
  let calTimer = null;
  async function calPost(path, body) {
    const r = await fetch(path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body || {}) });
    const j = await r.json();
    if (!r.ok) { $('control-result').textContent = j.error; $('control-result').className = 'bad'; }
    else if (j.running !== undefined) showCal(j);
    return j;
  }
  function bar(value, lo, hi, span) {
    const [a, b] = span, pct = (x) => `${Math.max(0, Math.min(100, ((x - a) / (b - a)) * 100))}%`;
    const el = document.createElement('span'); el.className = 'bar';
    if (lo != null && hi != null) { const band = document.createElement('span'); band.className = 'band'; band.style.left = pct(lo); band.style.width = `calc(${pct(hi)} - ${pct(lo)})`; el.append(band); }
    if (value != null) { const now = document.createElement('span'); now.className = 'now'; now.style.left = pct(value); el.append(now); }
    return el;
  }
  function showCal(s) {
    state.calibration = s;
    $('cal-session').hidden = !s.running;
    if (!s.running) { clearInterval(calTimer); calTimer = null; return; }
    if (!calTimer) calTimer = setInterval(() => fetch('/api/calibrate').then((r) => r.json()).then(showCal), 200);
    const done = s.steps.filter((st) => st.samples > 0).length;
    const rec = s.recording;
    $('cal-steps').replaceChildren(...s.steps.map((st, k) => {
      const li = document.createElement('li');
      li.textContent = `${st.name}${st.samples ? ` (${st.samples} samples)` : ''}`;
      li.className = rec && rec.step === k ? 'now' : (k < done && !(rec && rec.step === k) ? 'done' : '');
      return li;
    }));
    const next = rec ? s.steps[rec.step] : s.steps[done];
    $('cal-instruction').textContent = rec ? `Recording ${next.name}: ${next.instruction} ${rec.left_s.toFixed(1)} s left`
      : next ? `Next, ${next.name}: ${next.instruction}` : 'Every step is recorded.';
    $('cal-step').disabled = !!rec || !next;
    $('cal-step').textContent = next && !rec ? `Record ${next.name}` : 'Record step';
    // The live hand against the ranges measured so far: wrist axis k in step k + 1, the thumb
    // from the neutral's mean to the thumb step's maximum (G_R of Eq. 3).
    const live = s.live;
    const rows = [];
    ['pitch', 'yaw', 'roll'].forEach((axis, k) => {
      const st = s.steps[k + 1];
      rows.push([`wrist ${axis}`, live?.wrist_deg[k], st.wrist_min?.[k], st.wrist_max?.[k], [-90, 90]]);
    });
    [1, 2, 3].forEach((g, k) => {
      const st = s.steps[4], n = s.steps[0];
      rows.push([`thumb g${g}`, live?.thumb_deg[k], n.thumb_mean?.[k], st.thumb_max?.[k], [0, 120]]);
    });
    $('cal-live').tBodies[0].replaceChildren(...rows.map(([name, now, lo, hi, span]) => {
      const tr = document.createElement('tr');
      const cells = [name, now != null ? now.toFixed(1) : '–', lo != null && hi != null ? `${lo.toFixed(1)} … ${hi.toFixed(1)}` : '–'];
      for (const c of cells) { const td = document.createElement('td'); td.textContent = c; tr.append(td); }
      const td = document.createElement('td'); td.append(bar(now, lo, hi, span)); tr.append(td);
      return tr;
    }));
    if (live && !live.fresh) $('cal-instruction').textContent += ' (the device is not connected)';
    const out = $('cal-result');
    out.replaceChildren();
    if (s.error) { const p = document.createElement('div'); p.className = 'bad'; p.textContent = s.error; out.append(p); }
    if (s.result?.error) { const p = document.createElement('div'); p.className = 'bad'; p.textContent = s.result.error; out.append(p); }
    if (s.result?.toml) {
      for (const w of s.result.warnings) { const p = document.createElement('div'); p.className = 'bad'; p.textContent = `warning: ${w}`; out.append(p); }
      const pre = document.createElement('pre'); pre.textContent = s.result.toml; out.append(pre);
    }
    $('cal-apply').hidden = !s.result?.toml;
  }
  $('cal-form').addEventListener('submit', (e) => { e.preventDefault(); calPost('/api/calibrate/start', { user: $('cal-user').value.trim(), seconds_per_step: Number($('cal-seconds').value) }); });
  $('cal-step').addEventListener('click', () => calPost('/api/calibrate/step'));
  $('cal-cancel').addEventListener('click', () => calPost('/api/calibrate/cancel'));
  $('cal-apply').addEventListener('click', () => post('/api/calibrate/apply'));
  fetch('/api/calibrate').then((r) => r.json()).then(showCal);
}
