// frond: a field's plants evaluated in the page (seed 000, Eq. 6-7 and section 6.3).
//
// A line-for-line port of daemon/motion/src/field_eval.rs, the one evaluation the daemon's field
// and frond_sdk run, so that the page draws every plant of a field itself from what the daemon
// publishes (protocol 3: the field's definition and frames of its driving stream) instead of
// receiving a pose per plant. Same arithmetic: angles are f32 (Float32Array, Math.fround where
// Rust casts to f32), everything else f64. A classic script: it defines globalThis.frondField.
//
// Plant B of row r at stream time tau shows, for joint i, the stream at
//   tau + start_r / fps - K (gamma_B + delta_i),   gamma_B = ((B - A_r) . d) / V_M
// interpolated linearly between frames and clamped to the history held, then scaled and its
// bend (pitch, yaw) turned by direction - authored_direction.
(function () {
  'use strict';

  const MAX_HISTORY = 1 << 18; // frond_protocol::field::MAX_FIELD_HISTORY_FRAMES
  const F = Math.fround;

  // The last `capacity` frames of a driving stream (12 angles each), indexed by stream index.
  class StreamHistory {
    constructor(capacity) {
      this.cap = Math.min(Math.max(capacity | 0, 2), MAX_HISTORY);
      this.frames = new Float32Array(this.cap * 12);
      this.held = new Float64Array(this.cap); // index + 1 of the frame in each slot, 0 empty
      this.produced = 0;
    }
    oldest() { return Math.max(0, this.produced - this.cap); }
    // Records frame `index` (12 angles); older than the window: ignored.
    insert(index, joints) {
      if (!(index >= this.oldest()) || !Number.isSafeInteger(index)) return;
      this.produced = Math.max(this.produced, index + 1);
      const slot = index % this.cap;
      for (let k = 0; k < 12; k++) this.frames[slot * 12 + k] = joints[k];
      this.held[slot] = index + 1;
    }
    // Offset of frame `index` in `frames`, or -1 when not held.
    slotOf(index) {
      const slot = index % this.cap;
      return this.held[slot] === index + 1 ? slot * 12 : -1;
    }
    isComplete() {
      for (let k = this.oldest(); k < this.produced; k++) if (this.slotOf(k) < 0) return false;
      return true;
    }
    // The stream at fractional index f into out[o..o+12]; false when a frame it needs is missing.
    atIndex(f, out, o) {
      if (this.produced === 0) return false;
      const lo = this.oldest(), hi = this.produced - 1;
      const x = Number.isNaN(f) ? lo : Math.min(Math.max(f, lo), hi);
      const k = Math.floor(x);
      const a = this.slotOf(k);
      if (a < 0) return false;
      const u = x - k;
      if (u === 0) {
        for (let c = 0; c < 12; c++) out[o + c] = this.frames[a + c];
        return true;
      }
      const b = this.slotOf(k + 1);
      if (b < 0) return false;
      const fr = this.frames;
      for (let c = 0; c < 12; c++) out[o + c] = F(fr[a + c] + u * (fr[b + c] - fr[a + c]));
      return true;
    }
  }

  function heading(deg) {
    const r = deg * (Math.PI / 180);
    return [Math.cos(r), -Math.sin(r)];
  }

  // A field being evaluated. `layout`: { positions: Float32Array [x0, z0, x1, z1, ...] (metres),
  // rows: Uint32Array, startFrames: Uint32Array, rowCount, authoredDirectionDeg, fps,
  // historyFrames }.
  class FieldEval {
    constructor(layout) {
      this.positions = layout.positions;
      this.rows = layout.rows;
      this.startFrames = layout.startFrames;
      this.n = layout.rows.length;
      this.authored = layout.authoredDirectionDeg;
      this.fps = layout.fps;
      this.history = new StreamHistory(layout.historyFrames);
      this.delays = new Float64Array(this.n);
      this.rowUpwind = new Float64Array(layout.rowCount);
      this.controls = null;
      this.tau = 0;
      this.tmp = new Float32Array(12);
    }

    // Eq. 7 for every plant under `c` (direction_deg, speed_m_s, time_step, scale, delays_s).
    setControls(c) {
      this.controls = c;
      const d = heading(c.direction_deg);
      const p = this.positions;
      this.rowUpwind.fill(Infinity);
      for (let i = 0; i < this.n; i++) {
        const proj = p[2 * i] * d[0] + p[2 * i + 1] * d[1];
        const r = this.rows[i];
        if (proj < this.rowUpwind[r]) this.rowUpwind[r] = proj;
      }
      const v = Math.max(c.speed_m_s, 1e-6);
      for (let i = 0; i < this.n; i++) {
        const proj = p[2 * i] * d[0] + p[2 * i + 1] * d[1];
        this.delays[i] = (proj - this.rowUpwind[this.rows[i]]) / v;
      }
    }

    // One field frame as the daemon sends it ({ tau_s, controls, produced, entries: [{ index,
    // joints_deg: [[p, y, r] x 4] }] }); false when ignored (values not finite).
    applyFrame(f) {
      const c = f.controls;
      const vals = [c.direction_deg, c.speed_m_s, c.time_step, c.scale, ...c.delays_s, f.tau_s];
      if (!vals.every(Number.isFinite)) return false;
      for (const e of f.entries) {
        if (e.index < f.produced) this.history.insert(e.index, e.joints_deg.flat());
      }
      const cur = this.controls;
      const same = cur && cur.direction_deg === c.direction_deg && cur.speed_m_s === c.speed_m_s
        && cur.time_step === c.time_step && cur.scale === F(c.scale) && c.delays_s.every((x, i) => cur.delays_s[i] === x);
      if (!same) this.setControls({ ...c, scale: F(c.scale), delays_s: c.delays_s.slice() });
      this.tau = f.tau_s;
      return true;
    }

    // Plant i's pose at stream time tau into out[o..o+12] ([pitch, yaw, roll] per joint, root
    // first, degrees); false for an unknown plant or while the history lacks a frame.
    plantPose(i, tau, out, o) {
      if (!(i >= 0 && i < this.n) || !this.controls) return false;
      const c = this.controls, fps = this.fps, h = this.history, tmp = this.tmp;
      const base = tau + this.startFrames[i] / fps - c.time_step * this.delays[i];
      for (let j = 0; j < 4; j++) {
        const delta = j === 0 ? 0 : c.delays_s[j - 1];
        const at = base - c.time_step * delta;
        if (!h.atIndex(at * fps, tmp, 0)) return false;
        out[o + 3 * j] = tmp[3 * j];
        out[o + 3 * j + 1] = tmp[3 * j + 1];
        out[o + 3 * j + 2] = tmp[3 * j + 2];
      }
      // shape_pose: scale every angle (f32), then turn the bend.
      const rot = c.direction_deg - this.authored;
      let s = 0, co = 1;
      if (rot !== 0) { const r = rot * (Math.PI / 180); s = Math.sin(r); co = Math.cos(r); }
      for (let j = 0; j < 4; j++) {
        const p = F(out[o + 3 * j] * c.scale), y = F(out[o + 3 * j + 1] * c.scale), r = F(out[o + 3 * j + 2] * c.scale);
        if (rot === 0) { out[o + 3 * j] = p; out[o + 3 * j + 1] = y; out[o + 3 * j + 2] = r; continue; }
        out[o + 3 * j] = F(p * co + y * s);
        out[o + 3 * j + 1] = F(y * co - p * s);
        out[o + 3 * j + 2] = r;
      }
      return true;
    }

    // Every plant at stream time tau into out (Float32Array of 12 n); plants that cannot be
    // evaluated yet get NaN. Returns how many were evaluated.
    evalAll(tau, out) {
      let done = 0;
      for (let i = 0; i < this.n; i++) {
        if (this.plantPose(i, tau, out, 12 * i)) done++;
        else out.fill(NaN, 12 * i, 12 * i + 12);
      }
      return done;
    }
  }

  globalThis.frondField = { StreamHistory, FieldEval };
})();
