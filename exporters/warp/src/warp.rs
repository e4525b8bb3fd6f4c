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

    /// Eq. 8 for every pixel: calls `f(x, y, src_x, src_y)` with the source point in fixed point
    /// (1/256 pixel), clamped to the layer.
    #[inline(always)]
    fn for_each_source(&self, mut f: impl FnMut(usize, usize, i32, i32)) {
        let (w, h) = (self.width, self.height);
        let max_x = (w as i32 - 1) * ONE;
        let max_y = (h as i32 - 1) * ONE;
        let inv_sx = 1.0 / self.cell_x as f32;
        let inv_sy = 1.0 / self.cell_y as f32;
        for y in 0..h {
            let cy = y / self.cell_y;
            let v = (y - cy * self.cell_y) as f32 * inv_sy;
            let row0 = &self.disp[cy * self.cols..(cy + 1) * self.cols];
            let row1 = &self.disp[(cy + 1) * self.cols..(cy + 2) * self.cols];
            let mut x = 0;
            for cx in 0..self.cols - 1 {
                if x >= w {
                    break;
                }
                // Left and right cell edges interpolated in v.
                let l = lerp2(row0[cx], row1[cx], v);
                let r = lerp2(row0[cx + 1], row1[cx + 1], v);
                let end = ((cx + 1) * self.cell_x).min(w);
                let x_start = cx * self.cell_x;
                // The source point is linear in x inside a cell row: step it in 1/65536 pixel.
                const SUB: f32 = 65536.0;
                let sx0 = ((x_start as f32 + l[0]) * SUB).round() as i64;
                let sy0 = ((y as f32 + l[1]) * SUB).round() as i64;
                let dsx = ((1.0 + (r[0] - l[0]) * inv_sx) * SUB).round() as i64;
                let dsy = ((r[1] - l[1]) * inv_sx * SUB).round() as i64;
                let (mut sxa, mut sya) = (sx0 + (x - x_start) as i64 * dsx, sy0 + (x - x_start) as i64 * dsy);
                while x < end {
                    // Round 1/65536 to 1/256 pixel.
                    let sxf = (((sxa + 128) >> 8) as i32).clamp(0, max_x);
                    let syf = (((sya + 128) >> 8) as i32).clamp(0, max_y);
                    f(x, y, sxf, syf);
                    sxa += dsx;
                    sya += dsy;
                    x += 1;
                }
            }
        }
    }

    /// Warps an RGBA image (4 bytes per pixel, `width x height`) into `dst`: each channel is
    /// bilinearly sampled at the mapped source point (the operation `cv2.remap` with
    /// `INTER_LINEAR` and `BORDER_REPLICATE` performs for the same field).
    pub fn remap(&self, src: &[u8], dst: &mut [u8]) {
        let w = self.width;
        assert!(src.len() >= w * self.height * 4 && dst.len() >= w * self.height * 4, "buffer size");
        self.for_each_source(|x, y, sxf, syf| {
            let (i00, i10, i01, i11, fx, fy) = taps(sxf, syf, w, self.width, self.height);
            let o = (y * w + x) * 4;
            let (p00, p10, p01, p11) = (px(src, i00), px(src, i10), px(src, i01), px(src, i11));
            let (fx, fy) = (fx as u32, fy as u32);
            let (gx, gy) = (ONE as u32 - fx, ONE as u32 - fy);
            let out: &mut [u8; 4] = (&mut dst[o..o + 4]).try_into().expect("4 bytes");
            for c in 0..4 {
                let top = p00[c] as u32 * gx + p10[c] as u32 * fx;
                let bot = p01[c] as u32 * gx + p11[c] as u32 * fx;
                out[c] = ((top * gy + bot * fy + (1 << (2 * FRAC_BITS - 1))) >> (2 * FRAC_BITS)) as u8;
            }
        });
    }

    /// Warps a straight-alpha RGBA layer and composites it over the opaque RGBA `frame`, only at
    /// pixels where `region` is non-zero (pixels outside the region are never written).
    ///
    /// Colours are filtered weighted by alpha (no dark fringes) and blended in one rounding, so
    /// where the displacement is zero and the frame already holds the layer's colour the frame
    /// stays the same byte for byte.
    pub fn warp_over(&self, layer: &[u8], region: &[u8], frame: &mut [u8]) {
        let w = self.width;
        let n = w * self.height;
        assert!(layer.len() >= n * 4 && frame.len() >= n * 4 && region.len() >= n, "buffer size");
        // Weights sum to ONE^2 = 65536; alpha up to 255.
        const WSUM: u64 = (ONE * ONE) as u64;
        const DEN: u64 = WSUM * 255;
        self.for_each_source(|x, y, sxf, syf| {
            let p = y * w + x;
            if region[p] == 0 {
                return;
            }
            let (i00, i10, i01, i11, fx, fy) = taps(sxf, syf, w, self.width, self.height);
            let (fx, fy) = (fx as u64, fy as u64);
            let one = ONE as u64;
            let wts = [(one - fx) * (one - fy), fx * (one - fy), (one - fx) * fy, fx * fy];
            let idx = [i00, i10, i01, i11];
            let mut a_sum = 0u64;
            let mut c_sum = [0u64; 3];
            for t in 0..4 {
                let wa = wts[t] * layer[idx[t] + 3] as u64;
                a_sum += wa;
                for c in 0..3 {
                    c_sum[c] += wa * layer[idx[t] + c] as u64;
                }
            }
            if a_sum == 0 {
                return;
            }
            let o = p * 4;
            let keep = DEN - a_sum;
            for c in 0..3 {
                let num = c_sum[c] + frame[o + c] as u64 * keep;
                frame[o + c] = ((num + DEN / 2) / DEN) as u8;
            }
            frame[o + 3] = 255;
        });
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
    fn remap_with_zero_field_is_identity() {
        let w = Warper::new(13, 7, 4, 3);
        let src: Vec<u8> = (0..13 * 7 * 4).map(|i| (i * 37 % 256) as u8).collect();
        let mut dst = vec![0; src.len()];
        w.remap(&src, &mut dst);
        assert_eq!(src, dst);
    }
}
