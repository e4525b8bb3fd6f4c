//! Grid-based inverse warping of a vegetation layer (seed 001, section III-E, Eq. 5-8).
//!
//! A uniform grid of cells `s_x x s_y` pixels covers the layer; corner `(cx, cy)` sits at pixel
//! `(cx s_x, cy s_y)`. Each frame the corners are displaced against the vegetation's velocity
//! ([`Warper::set_displacements`], Eq. 5-7):
//!
//! `n = lambda R V_p dt` (Eq. 5), `R = (l / h)^r` (Eq. 6), `(x', y') = (x, y) - (n_x s_x, n_y s_y)`
//! (Eq. 7),
//!
//! and every output pixel `(i, j)` is mapped to the source point given by the bilinear
//! interpolation of its cell's four displaced corners at its cell coordinates `(u, v)` (Eq. 8),
//! where the layer is sampled with bilinear colour filtering. Since Eq. 8 interpolates corners that
//! are the undisplaced lattice plus a displacement, the source point is the pixel plus the
//! bilinearly interpolated displacement; with no displacement it is the pixel itself, exactly.
//!
//! Source positions are rounded to 1/256 pixel and filtered in fixed point, so a zero field
//! reproduces the input byte for byte. Buffers are sized when the grid changes; warping a frame
//! allocates nothing.

use crate::params::Horizon;

mod kernels;
mod over;

pub use kernels::RemapKernel;
pub use over::OpaqueTiles;

/// Fraction bits of the fixed-point source coordinates.
const FRAC_BITS: u32 = 8;
const ONE: i32 = 1 << FRAC_BITS;

/// Rigidity factor `R` of seed 001, Eq. 6 for a point at row `y` of a layer that spans rows
/// `top..=bottom`: `(l / h)^r` with `l` the distance to the horizon (bottom or top of the layer)
/// and `h` the layer height; `1` when every part can move.
pub fn rigidity_factor(horizon: Horizon, y: f32, top: f32, bottom: f32, r: f32) -> f32 {
    let h = (bottom - top).max(1.0);
    let l = match horizon {
        Horizon::None => return 1.0,
        Horizon::Bottom => bottom - y,
        Horizon::Top => y - top,
    };
    (l / h).clamp(0.0, 1.0).powf(r)
}

/// Corner displacements of one layer and the per-pixel mapping they define.
#[derive(Debug, Clone)]
pub struct Warper {
    width: usize,
    height: usize,
    cell_x: usize,
    cell_y: usize,
    cols: usize,
    rows: usize,
    /// Displacement `(x' - x, y' - y)` of each corner in pixels, row-major `cy * cols + cx`.
    disp: Vec<[f32; 2]>,
}

impl Warper {
    /// A still grid over a `width x height` layer with cells of `cell_x x cell_y` pixels.
    pub fn new(width: usize, height: usize, cell_x: usize, cell_y: usize) -> Warper {
        let mut w = Warper { width, height, cell_x: 1, cell_y: 1, cols: 0, rows: 0, disp: Vec::new() };
        w.set_cells(cell_x, cell_y);
        w
    }

    /// Changes the cell size (reallocates the corner array only when it grows).
    pub fn set_cells(&mut self, cell_x: usize, cell_y: usize) {
        self.cell_x = cell_x.max(1);
        self.cell_y = cell_y.max(1);
        // Enough corners that the last pixel lies inside a cell.
        self.cols = self.width.saturating_sub(1) / self.cell_x + 2;
        self.rows = self.height.saturating_sub(1) / self.cell_y + 2;
        self.disp.clear();
        self.disp.resize(self.cols * self.rows, [0.0, 0.0]);
    }

    /// Layer size `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Cell size `(s_x, s_y)`.
    pub fn cells(&self) -> (usize, usize) {
        (self.cell_x, self.cell_y)
    }

    /// Corner counts `(cols, rows)`.
    pub fn corners(&self) -> (usize, usize) {
        (self.cols, self.rows)
    }

    /// Displacement of corner `(cx, cy)` in pixels.
    pub fn corner(&self, cx: usize, cy: usize) -> [f32; 2] {
        self.disp[cy * self.cols + cx]
    }

    /// Sets the displacement of corner `(cx, cy)` in pixels directly.
    pub fn set_corner(&mut self, cx: usize, cy: usize, d: [f32; 2]) {
        self.disp[cy * self.cols + cx] = d;
    }

    /// Zero displacement everywhere.
    pub fn reset(&mut self) {
        self.disp.fill([0.0, 0.0]);
    }

    /// Eq. 5-7: displaces every corner against the vegetation velocity.
    ///
    /// For the corner at pixel `(x, y)`: `n = lambda * scale(x, y) * r_factor(y) * vp(x, y) * dt`
    /// and the displacement is `(-n_x s_x, -n_y s_y)` pixels. `scale` is the scale map (|lambda|
    /// per pixel, 1 without one), `r_factor` is Eq. 6 and `vp` the vegetation velocity there.
    pub fn set_displacements(
        &mut self,
        dt: f32,
        lambda: [f32; 2],
        mut r_factor: impl FnMut(f32) -> f32,
        mut scale: impl FnMut(f32, f32) -> f32,
        mut vp: impl FnMut(f32, f32) -> [f32; 2],
    ) {
        let (sx, sy) = (self.cell_x as f32, self.cell_y as f32);
        for cy in 0..self.rows {
            let y = cy as f32 * sy;
            let r = r_factor(y);
            for cx in 0..self.cols {
                let x = cx as f32 * sx;
                let k = scale(x, y) * r * dt;
                let v = vp(x, y);
                let n = [lambda[0] * k * v[0], lambda[1] * k * v[1]];
                self.disp[cy * self.cols + cx] = [-n[0] * sx, -n[1] * sy];
            }
        }
    }

    /// Largest corner displacement magnitude in pixels.
    pub fn max_displacement(&self) -> f32 {
        self.disp.iter().fold(0.0f32, |m, d| m.max((d[0] * d[0] + d[1] * d[1]).sqrt()))
    }

    /// Eq. 8 run by run: the source point is linear in `x` inside one cell row, so each run of
    /// pixels that share a cell row comes with its first source point and per-pixel step in
    /// 1/65536 pixel (unclamped). An iterator rather than a callback so that the SIMD kernels,
    /// compiled with their own target features, inline into the loop over it.
    #[inline(always)]
    fn runs(&self) -> Runs<'_> {
        Runs { warper: self, y: 0, cx: usize::MAX, cx_end: usize::MAX, v: 0.0, left: [0.0; 2] }
    }

    /// The runs of row `y` in cell columns `cx_start..cx_end` only.
    #[inline(always)]
    fn row_runs(&self, y: usize, cx_start: usize, cx_end: usize) -> Runs<'_> {
        let cx_end = cx_end.min(self.cols);
        let mut runs = Runs { warper: self, y, cx: cx_start, cx_end, v: 0.0, left: [0.0; 2] };
        let cy = y / self.cell_y;
        runs.v = (y - cy * self.cell_y) as f32 * (1.0 / self.cell_y as f32);
        if cx_start + 1 < self.cols {
            runs.left = runs.edge(cx_start);
        }
        runs
    }

    /// Eq. 8 for every pixel: calls `f(x, y, src_x, src_y)` with the source point in fixed point
    /// (1/256 pixel), clamped to the layer.
    #[inline(always)]
    fn for_each_source(&self, mut f: impl FnMut(usize, usize, i32, i32)) {
        let max_x = (self.width as i32 - 1) * ONE;
        let max_y = (self.height as i32 - 1) * ONE;
        for run in self.runs() {
            let (mut sxa, mut sya) = (run.sx, run.sy);
            for x in run.x_start..run.x_end {
                // Round 1/65536 to 1/256 pixel.
                let sxf = (((sxa + 128) >> 8) as i32).clamp(0, max_x);
                let syf = (((sya + 128) >> 8) as i32).clamp(0, max_y);
                f(x, run.y, sxf, syf);
                sxa += run.dsx;
                sya += run.dsy;
            }
        }
    }

    /// Warps an RGBA image (4 bytes per pixel, `width x height`) into `dst`: each channel is
    /// bilinearly sampled at the mapped source point (the operation `cv2.remap` with
    /// `INTER_LINEAR` and `BORDER_REPLICATE` performs for the same field).
    ///
    /// Uses the fastest [`RemapKernel`] this CPU supports; every kernel gives the same bytes.
    pub fn remap(&self, src: &[u8], dst: &mut [u8]) {
        self.remap_with(RemapKernel::best(), src, dst);
    }

    /// [`Warper::remap`] with a chosen kernel (for tests and benchmarks); a kernel the CPU lacks
    /// falls back to [`RemapKernel::Scalar`].
    ///
    /// Runs whose taps all lie inside the image go to the kernel; runs that are an exact
    /// whole-pixel shift are copied; the rest (near the border) take the clamped scalar path.
    pub fn remap_with(&self, kernel: RemapKernel, src: &[u8], dst: &mut [u8]) {
        let (w, h) = (self.width, self.height);
        assert!(src.len() >= w * h * 4 && dst.len() >= w * h * 4, "buffer size");
        let kernel = if kernel.is_available() { kernel } else { RemapKernel::Scalar };
        kernels::remap(kernel, self, src, dst);
    }

    /// The frame loop of [`Warper::remap_with`] with kernel `K`, inlined into each kernel's
    /// entry point (which carries its target features).
    #[inline(always)]
    fn remap_runs<K: kernels::Kernel>(&self, src: &[u8], dst: &mut [u8]) {
        let (w, h) = (self.width, self.height);
        let max_x = (w as i32 - 1) * ONE;
        let max_y = (h as i32 - 1) * ONE;
        for run in self.runs() {
            let out = &mut dst[(run.y * w + run.x_start) * 4..(run.y * w + run.x_end) * 4];
            if let Some(shift) = run.whole_pixel_shift(w, h) {
                out.copy_from_slice(&src[shift..shift + out.len()]);
            } else if let Some(interior) = run.interior(w, h) {
                K::interior(src, w, out, interior);
            } else {
                let (mut sxa, mut sya) = (run.sx, run.sy);
                for o in out.chunks_exact_mut(4) {
                    let sxf = (((sxa + 128) >> 8) as i32).clamp(0, max_x);
                    let syf = (((sya + 128) >> 8) as i32).clamp(0, max_y);
                    let (i00, i10, i01, i11, fx, fy) = taps(sxf, syf, w, w, h);
                    let p = [px(src, i00), px(src, i10), px(src, i01), px(src, i11)];
                    let o: &mut [u8; 4] = o.try_into().expect("4 bytes");
                    *o = kernels::bilinear(p, fx as u32, fy as u32);
                    sxa += run.dsx;
                    sya += run.dsy;
                }
            }
        }
    }

    /// The per-pixel source map `(map_x, map_y)` in pixels, as `cv2.remap` takes it (row-major
    /// float32 arrays). Allocates: for benchmarks and export, not for the frame loop.
    pub fn source_maps(&self) -> (Vec<f32>, Vec<f32>) {
        let n = self.width * self.height;
        let mut mx = vec![0.0; n];
        let mut my = vec![0.0; n];
        self.for_each_source(|x, y, sxf, syf| {
            mx[y * self.width + x] = sxf as f32 / ONE as f32;
            my[y * self.width + x] = syf as f32 / ONE as f32;
        });
        (mx, my)
    }
}

#[inline(always)]
fn px(buf: &[u8], i: usize) -> [u8; 4] {
    buf[i..i + 4].try_into().expect("4 bytes")
}

#[inline(always)]
fn lerp2(a: [f32; 2], b: [f32; 2], t: f32) -> [f32; 2] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

/// `x.round() as i64` without a library call (the baseline x86_64 target has no rounding
/// instruction): rounds half away from zero, saturates, and maps NaN to 0, exactly as the cast of
/// `f32::round` does.
#[inline(always)]
fn round_i64(x: f32) -> i64 {
    let t = x as i64; // truncates toward zero (saturating, NaN -> 0)
    // For |x| < 2^23 both `t as f32` and the difference are exact; beyond, x is an integer.
    let frac = x - t as f32;
    // Branch-free: `frac` is effectively random, so branches would mispredict once per run.
    t.saturating_add((frac >= 0.5) as i64).saturating_sub((frac <= -0.5) as i64)
}

/// [`round_i64`] of four values; when all lie within i32 (always, for sane fields) it rounds in
/// 32 bits without saturation logic, four at a time.
#[inline(always)]
fn round4_i64(x: [f32; 4]) -> [i64; 4] {
    // The largest f32 below 2^31.
    const I32_SAFE: f32 = 2_147_483_520.0;
    if x.iter().all(|v| v.abs() <= I32_SAFE) {
        // Exact as in `round_i64`: for |v| >= 2^23, v is an integer and `t as f32 == v`.
        x.map(|v| {
            let t = v as i32;
            let frac = v - t as f32;
            (t + (frac >= 0.5) as i32 - (frac <= -0.5) as i32) as i64
        })
    } else {
        x.map(round_i64)
    }
}

/// One cell row's run of output pixels `x_start..x_end` of row `y`: the source point of
/// `x_start` is `(sx, sy)` and each further pixel adds `(dsx, dsy)`, all in 1/65536 pixel.
#[derive(Debug, Clone, Copy)]
struct Run {
    y: usize,
    x_start: usize,
    x_end: usize,
    sx: i64,
    sy: i64,
    dsx: i64,
    dsy: i64,
}

/// Iterator over the runs of a frame, row by row (see [`Warper::runs`]).
struct Runs<'a> {
    warper: &'a Warper,
    y: usize,
    /// Cell column of the next run; `usize::MAX` before the first row.
    cx: usize,
    /// Cell column where row `y`'s runs end, for one row only ([`Warper::row_runs`]);
    /// `usize::MAX` for every row, each to its end.
    cx_end: usize,
    /// Cell coordinate of row `y` inside its cell row.
    v: f32,
    /// Displacement of the next run's left cell edge at row `y`.
    left: [f32; 2],
}

impl Runs<'_> {
    /// Corner displacements of cell column edge `cx` interpolated at row `y` (Eq. 8 in `v`).
    #[inline(always)]
    fn edge(&self, cx: usize) -> [f32; 2] {
        let wp = self.warper;
        let cy = self.y / wp.cell_y;
        lerp2(wp.disp[cy * wp.cols + cx], wp.disp[(cy + 1) * wp.cols + cx], self.v)
    }
}

impl Iterator for Runs<'_> {
    type Item = Run;

    #[inline(always)]
    fn next(&mut self) -> Option<Run> {
        const SUB: f32 = 65536.0;
        let wp = self.warper;
        while self.cx == usize::MAX
            || self.cx >= self.cx_end
            || self.cx + 1 >= wp.cols
            || self.cx * wp.cell_x >= wp.width
        {
            if self.cx_end != usize::MAX {
                return None;
            }
            // Next row.
            self.y = if self.cx == usize::MAX { 0 } else { self.y + 1 };
            self.cx = 0;
            if self.y >= wp.height {
                // Stays here: the iterator is fused.
                self.y = wp.height;
                self.cx = wp.cols;
                return None;
            }
            let cy = self.y / wp.cell_y;
            self.v = (self.y - cy * wp.cell_y) as f32 * (1.0 / wp.cell_y as f32);
            self.left = self.edge(0);
        }
        let x_start = self.cx * wp.cell_x;
        let (cx, y) = (self.cx, self.y);
        let inv_sx = 1.0 / wp.cell_x as f32;
        // Left and right cell edges interpolated in v.
        let (l, r) = (self.left, self.edge(cx + 1));
        self.left = r;
        self.cx += 1;
        let [sx, sy, dsx, dsy] = round4_i64([
            (x_start as f32 + l[0]) * SUB,
            (y as f32 + l[1]) * SUB,
            (1.0 + (r[0] - l[0]) * inv_sx) * SUB,
            (r[1] - l[1]) * inv_sx * SUB,
        ]);
        Some(Run { y, x_start, x_end: ((cx + 1) * wp.cell_x).min(wp.width), sx, sy, dsx, dsy })
    }
}

impl Run {
    /// Source point of the last pixel, 1/65536 pixel.
    fn last(&self) -> (i64, i64) {
        let k = (self.x_end - self.x_start) as i64 - 1;
        (self.sx + k * self.dsx, self.sy + k * self.dsy)
    }

    /// When every pixel of the run samples exactly one source pixel (a whole-pixel shift, e.g.
    /// where the corners do not move), the byte offset of the first one's source.
    fn whole_pixel_shift(&self, w: usize, h: usize) -> Option<usize> {
        if self.dsx != 1 << 16 || self.dsy != 0 {
            return None;
        }
        let (fx, fy) = ((self.sx + 128) >> 8, (self.sy + 128) >> 8);
        if fx & (ONE as i64 - 1) != 0 || fy & (ONE as i64 - 1) != 0 {
            return None;
        }
        let (x0, y0) = (fx >> FRAC_BITS, fy >> FRAC_BITS);
        let n = (self.x_end - self.x_start) as i64;
        let inside = x0 >= 0 && x0 + n <= w as i64 && y0 >= 0 && y0 < h as i64;
        inside.then(|| (y0 as usize * w + x0 as usize) * 4)
    }

    /// The run in 32-bit form when no tap of any of its pixels needs clamping: every source point
    /// (rounded to 1/256 pixel) lies in `[0, w - 1) x [0, h - 1)`, so its right and lower
    /// neighbours exist. The source point is linear in `x` and rounding is monotonic, so the
    /// first and last pixels bound the run.
    fn interior(&self, w: usize, h: usize) -> Option<kernels::Interior> {
        // Keeps every 1/65536-pixel value of the run, and a few steps past its end, within i32.
        let small_step = |d: i64| d.abs() < 1 << 24;
        if w >= 1 << 15 || h >= 1 << 15 || !small_step(self.dsx) || !small_step(self.dsy) {
            return None;
        }
        let (lx, ly) = self.last();
        let ok = |a: i64, b: i64, size: usize| {
            let (fa, fb) = ((a + 128) >> 8, (b + 128) >> 8);
            fa.min(fb) >= 0 && fa.max(fb) < (size as i64 - 1) * ONE as i64
        };
        (ok(self.sx, lx, w) && ok(self.sy, ly, h)).then_some(kernels::Interior {
            sx: self.sx as i32,
            sy: self.sy as i32,
            dsx: self.dsx as i32,
            dsy: self.dsy as i32,
        })
    }
}

/// Byte offsets of the four bilinear taps and the fractions, clamped to the edge.
#[inline(always)]
fn taps(sxf: i32, syf: i32, stride: usize, w: usize, h: usize) -> (usize, usize, usize, usize, i32, i32) {
    let x0 = (sxf >> FRAC_BITS) as usize;
    let y0 = (syf >> FRAC_BITS) as usize;
    let fx = sxf & (ONE - 1);
    let fy = syf & (ONE - 1);
    let x1 = (x0 + 1).min(w - 1);
    let y1 = (y0 + 1).min(h - 1);
    ((y0 * stride + x0) * 4, (y0 * stride + x1) * 4, (y1 * stride + x0) * 4, (y1 * stride + x1) * 4, fx, fy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigidity_factor_follows_eq6() {
        // Layer rows 10..=110 (h = 100), horizon at the bottom, r = 2: at y = 60, l = 50.
        assert!((rigidity_factor(Horizon::Bottom, 60.0, 10.0, 110.0, 2.0) - 0.25).abs() < 1e-6);
        assert_eq!(rigidity_factor(Horizon::Bottom, 110.0, 10.0, 110.0, 2.0), 0.0);
        assert_eq!(rigidity_factor(Horizon::Bottom, 10.0, 10.0, 110.0, 2.0), 1.0);
        // Seen from above: the top is fixed; at y = 35, l = 25 -> (0.25)^1.
        assert!((rigidity_factor(Horizon::Top, 35.0, 10.0, 110.0, 1.0) - 0.25).abs() < 1e-6);
        assert_eq!(rigidity_factor(Horizon::None, 35.0, 10.0, 110.0, 7.0), 1.0);
        // r = 0: every part moves fully.
        assert_eq!(rigidity_factor(Horizon::Bottom, 60.0, 10.0, 110.0, 0.0), 1.0);
    }

    #[test]
    fn eq5_to_7_corner_displacement_is_hand_computed() {
        let mut w = Warper::new(40, 30, 8, 6);
        // lambda = (3, 2), V_p = (0.5, -0.25), dt = 0.1, R = 1, scale 1:
        // n = (3 * 0.5 * 0.1, 2 * -0.25 * 0.1) = (0.15, -0.05);
        // displacement = (-0.15 * 8, 0.05 * 6) = (-1.2, 0.3) pixels.
        w.set_displacements(0.1, [3.0, 2.0], |_| 1.0, |_, _| 1.0, |_, _| [0.5, -0.25]);
        let d = w.corner(2, 3);
        assert!((d[0] + 1.2).abs() < 1e-6 && (d[1] - 0.3).abs() < 1e-6, "{d:?}");
    }

    #[test]
    fn eq8_interpolates_corner_displacements_inside_a_cell() {
        let mut w = Warper::new(9, 9, 8, 8);
        // Only the bottom-right corner of the first cell moves, by (8, 0).
        w.set_corner(1, 1, [8.0, 0.0]);
        let (mx, my) = w.source_maps();
        // Pixel (4, 4): u = v = 0.5, weight of that corner 0.25 -> source x = 4 + 2.
        assert_eq!(mx[4 * 9 + 4], 6.0);
        assert_eq!(my[4 * 9 + 4], 4.0);
        // Pixel (2, 6): u = 0.25, v = 0.75 -> weight 0.1875 -> 2 + 1.5.
        assert_eq!(mx[6 * 9 + 2], 3.5);
        // Top-left pixel is its own source.
        assert_eq!(mx[0], 0.0);
    }

    #[test]
    fn rounding_matches_f32_round_cast() {
        let mut vals = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            0.49999997,
            -0.49999997,
            0.50000006,
            8388607.5,
            -8388607.5,
            8388608.0,
            16777217.0,
            2_147_483_520.0,
            -2_147_483_520.0,
            2_147_483_648.0,
            -2_147_483_648.0,
            9.3e18,
            -9.3e18,
            1e30,
            -1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            123456.49,
            -123456.51,
        ];
        // A spread of values with .0 and .5 fractions up to 3e8 (beyond 2^24 the halves vanish).
        vals.extend((-300_000i64..300_000).map(|i| i as f32 * 1000.5 + 0.5));
        for &v in &vals {
            let want = v.round() as i64;
            assert_eq!(round_i64(v), want, "round_i64({v:e})");
            assert_eq!(round4_i64([v, 0.5, -1.5, v])[0], want, "round4_i64({v:e})");
            assert_eq!(round4_i64([1.0, 2.0, 3.0, v])[3], want, "round4_i64 lane 3 ({v:e})");
        }
    }

    #[test]
    fn remap_with_zero_field_is_identity() {
        let w = Warper::new(13, 7, 4, 3);
        let src: Vec<u8> = (0..13 * 7 * 4).map(|i| (i * 37 % 256) as u8).collect();
        let mut dst = vec![0; src.len()];
        w.remap(&src, &mut dst);
        assert_eq!(src, dst);
    }
}
