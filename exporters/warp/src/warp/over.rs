//! Compositing a warped straight-alpha layer over a frame ([`Warper::warp_over`]), and its fast
//! path ([`Warper::warp_over_opaque`]): a run whose pixels are all drawn and whose taps are all
//! opaque is the plain bilinear remap, exactly (with every tap's alpha 255 the alpha-weighted
//! colour `(255 S + DEN / 2) / DEN` is `(S + 2^15) >> 16`, the remap kernels' formula, and the
//! background's weight is 0), so it goes to the SIMD remap kernels. Both give the same bytes.

use super::kernels::{self, RemapKernel};
use super::{FRAC_BITS, ONE, Run, Warper, taps};

/// Side of an [`OpaqueTiles`] tile, pixels.
const TILE: usize = 4;

/// Which `4 x 4` pixel tiles of a layer are wholly opaque (alpha 255), for
/// [`Warper::warp_over_opaque`] to tell in a few lookups that a run samples only opaque pixels.
#[derive(Debug, Clone, Default)]
pub struct OpaqueTiles {
    width: usize,
    height: usize,
    cols: usize,
    tiles: Vec<bool>,
}

impl OpaqueTiles {
    /// The tiles of the RGBA `layer` (`width x height`).
    pub fn new(layer: &[u8], width: usize, height: usize) -> OpaqueTiles {
        let mut tiles = OpaqueTiles::default();
        tiles.update(layer, width, height);
        tiles
    }

    /// Recomputes the tiles for `layer` (allocates only when the size grows).
    pub fn update(&mut self, layer: &[u8], width: usize, height: usize) {
        assert!(layer.len() >= width * height * 4, "buffer size");
        let cols = width.div_ceil(TILE);
        (self.width, self.height, self.cols) = (width, height, cols);
        self.tiles.clear();
        self.tiles.resize(cols * height.div_ceil(TILE), true);
        for (y, row) in layer[..width * height * 4].chunks_exact(width * 4).enumerate() {
            let tiles = &mut self.tiles[(y / TILE) * cols..(y / TILE + 1) * cols];
            for (tile, px) in tiles.iter_mut().zip(row.chunks(TILE * 4)) {
                *tile &= px.chunks_exact(4).all(|p| p[3] == 255);
            }
        }
    }

    /// Recomputes only the tiles that meet the pixel box `[x0, y0, x1, y1)` after `layer` (the
    /// one of the last [`update`](Self::update), same size) changed inside that box.
    pub fn update_box(&mut self, layer: &[u8], [x0, y0, x1, y1]: [usize; 4]) {
        let (w, h, cols) = (self.width, self.height, self.cols);
        assert!(layer.len() >= w * h * 4 && x1 <= w && y1 <= h, "buffer size");
        if x0 >= x1 || y0 >= y1 {
            return;
        }
        // Whole tiles: from the first tile's first pixel to the last tile's last (inside the layer).
        let (tx0, tx1) = (x0 / TILE, (x1 - 1) / TILE + 1);
        let (px0, px1) = (tx0 * TILE, (tx1 * TILE).min(w));
        for ty in y0 / TILE..(y1 - 1) / TILE + 1 {
            let tiles = &mut self.tiles[ty * cols + tx0..ty * cols + tx1];
            tiles.fill(true);
            for y in ty * TILE..((ty + 1) * TILE).min(h) {
                let row = &layer[(y * w + px0) * 4..(y * w + px1) * 4];
                for (tile, px) in tiles.iter_mut().zip(row.chunks(TILE * 4)) {
                    *tile &= px.chunks_exact(4).all(|p| p[3] == 255);
                }
            }
        }
    }

    /// Whether every pixel of columns `x0..=x1` and rows `y0..=y1` (inside the layer) is opaque.
    fn covers(&self, [x0, y0, x1, y1]: [usize; 4]) -> bool {
        (y0 / TILE..=y1 / TILE).all(|ty| (x0 / TILE..=x1 / TILE).all(|tx| self.tiles[ty * self.cols + tx]))
    }
}

/// The pixels an interior run's taps read: columns `x0..=x1`, rows `y0..=y1`. The source point
/// is linear along the run and rounding is monotonic, so its first and last pixels bound it.
fn taps_box(run: &Run) -> [usize; 4] {
    let (lx, ly) = run.last();
    let px = |a: i64| (((a + 128) >> 8) >> FRAC_BITS) as usize;
    let (ax, bx, ay, by) = (px(run.sx), px(lx), px(run.sy), px(ly));
    [ax.min(bx), ay.min(by), ax.max(bx) + 1, ay.max(by) + 1]
}

impl Warper {
    /// Warps a straight-alpha RGBA layer and composites it over the opaque RGBA `frame`, only at
    /// pixels where `region` is non-zero (pixels outside the region are never written).
    ///
    /// Colours are filtered weighted by alpha (no dark fringes) and blended in one rounding, so
    /// where the displacement is zero and the frame already holds the layer's colour the frame
    /// stays the same byte for byte.
    pub fn warp_over(&self, layer: &[u8], region: &[u8], frame: &mut [u8]) {
        self.check_over_buffers(layer, region, frame);
        self.warp_over_runs::<kernels::Scalar>(layer, None, region, frame);
    }

    /// [`Warper::warp_over`], the same bytes, faster where `opaque` (the tiles of `layer`) shows
    /// a run samples only opaque pixels: those runs take the fastest remap kernel.
    pub fn warp_over_opaque(&self, layer: &[u8], opaque: &OpaqueTiles, region: &[u8], frame: &mut [u8]) {
        self.warp_over_opaque_with(RemapKernel::best(), layer, opaque, region, frame);
    }

    /// [`Warper::warp_over_opaque`] with a chosen kernel (one the CPU lacks falls back to
    /// [`RemapKernel::Scalar`]); returns how many runs the kernel wrote.
    pub fn warp_over_opaque_with(
        &self,
        kernel: RemapKernel,
        layer: &[u8],
        opaque: &OpaqueTiles,
        region: &[u8],
        frame: &mut [u8],
    ) -> usize {
        self.check_over_buffers(layer, region, frame);
        assert!((opaque.width, opaque.height) == (self.width, self.height), "tiles of another size");
        let kernel = if kernel.is_available() { kernel } else { RemapKernel::Scalar };
        kernels::warp_over(kernel, self, layer, opaque, region, frame)
    }

    fn check_over_buffers(&self, layer: &[u8], region: &[u8], frame: &[u8]) {
        let n = self.width * self.height;
        assert!(layer.len() >= n * 4 && frame.len() >= n * 4 && region.len() >= n, "buffer size");
    }

    /// The frame loop of the compositing with kernel `K` for the opaque runs (none without
    /// `opaque`), inlined into each kernel's entry point; returns how many runs `K` wrote.
    #[inline(always)]
    pub(super) fn warp_over_runs<K: kernels::Kernel>(
        &self,
        layer: &[u8],
        opaque: Option<&OpaqueTiles>,
        region: &[u8],
        frame: &mut [u8],
    ) -> usize {
        let w = self.width;
        // Weights sum to ONE^2 = 65536; alpha up to 255. Every sum below fits in u32:
        // 65536 * 255 * 255 + DEN / 2 < 2^32.
        const WSUM: u32 = (ONE * ONE) as u32;
        const DEN: u32 = WSUM * 255;
        let max_x = (self.width as i32 - 1) * ONE;
        let max_y = (self.height as i32 - 1) * ONE;
        let mut fast = 0;
        // Only the cells of each row between its first and last drawn pixel.
        let runs = region[..w * self.height].chunks_exact(w).enumerate().flat_map(|(y, drawn)| {
            let first = drawn.iter().position(|&r| r != 0);
            let last = drawn.iter().rposition(|&r| r != 0);
            let (a, b) = match (first, last) {
                (Some(a), Some(b)) => (a / self.cell_x, b / self.cell_x + 1),
                _ => (0, 0),
            };
            self.row_runs(y, a, b)
        });
        for run in runs {
            let row = run.y * w;
            let drawn = &region[row + run.x_start..row + run.x_end];
            // Runs with nothing to draw are skipped whole (the region is mostly empty).
            if drawn.iter().all(|&r| r == 0) {
                continue;
            }
            // Every pixel drawn and every tap opaque: the alpha-weighted filter is the plain
            // bilinear one and the background never shows, so the remap kernel writes the run.
            if let Some(opaque) = opaque
                && drawn.iter().all(|&r| r != 0)
                && let Some(interior) = run.interior(w, self.height)
                && opaque.covers(taps_box(&run))
            {
                K::interior(layer, w, &mut frame[(row + run.x_start) * 4..(row + run.x_end) * 4], interior);
                fast += 1;
                continue;
            }
            let (mut sxa, mut sya) = (run.sx, run.sy);
            for x in run.x_start..run.x_end {
                let (sxf, syf) = (((sxa + 128) >> 8) as i32, ((sya + 128) >> 8) as i32);
                sxa += run.dsx;
                sya += run.dsy;
                let p = row + x;
                if region[p] == 0 {
                    continue;
                }
                let (i00, i10, i01, i11, fx, fy) =
                    taps(sxf.clamp(0, max_x), syf.clamp(0, max_y), w, self.width, self.height);
                let (fx, fy, one) = (fx as u32, fy as u32, ONE as u32);
                let wts = [(one - fx) * (one - fy), fx * (one - fy), (one - fx) * fy, fx * fy];
                let idx = [i00, i10, i01, i11];
                let o = p * 4;
                if idx.iter().all(|&i| layer[i + 3] == 255) {
                    // Opaque taps: (255 S + DEN / 2) / DEN = (S + WSUM / 2) / WSUM exactly, the
                    // background does not show.
                    for c in 0..3 {
                        let s: u32 = (0..4).map(|t| wts[t] * layer[idx[t] + c] as u32).sum();
                        frame[o + c] = ((s + WSUM / 2) >> 16) as u8;
                    }
                    frame[o + 3] = 255;
                    continue;
                }
                let mut a_sum = 0u32;
                let mut c_sum = [0u32; 3];
                for t in 0..4 {
                    let wa = wts[t] * layer[idx[t] + 3] as u32;
                    a_sum += wa;
                    for c in 0..3 {
                        c_sum[c] += wa * layer[idx[t] + c] as u32;
                    }
                }
                if a_sum == 0 {
                    continue;
                }
                let keep = DEN - a_sum;
                for c in 0..3 {
                    let num = c_sum[c] + frame[o + c] as u32 * keep;
                    frame[o + c] = ((num + DEN / 2) / DEN) as u8;
                }
                frame[o + 3] = 255;
            }
        }
        fast
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Alpha compositing of the bilinear, alpha-weighted layer over the frame, written out
    /// per pixel in u64 with the formula (the definition `warp_over`'s fast paths must keep).
    fn warp_over_reference(wp: &Warper, layer: &[u8], region: &[u8], frame: &mut [u8]) {
        const DEN: u64 = 65536 * 255;
        let w = wp.width;
        wp.for_each_source(|x, y, sxf, syf| {
            let p = y * w + x;
            if region[p] == 0 {
                return;
            }
            let (i00, i10, i01, i11, fx, fy) = taps(sxf, syf, w, wp.width, wp.height);
            let (fx, fy) = (fx as u64, fy as u64);
            let wts = [(256 - fx) * (256 - fy), fx * (256 - fy), (256 - fx) * fy, fx * fy];
            let idx = [i00, i10, i01, i11];
            let a: u64 = (0..4).map(|t| wts[t] * layer[idx[t] + 3] as u64).sum();
            if a == 0 {
                return;
            }
            for c in 0..3 {
                let col: u64 =
                    (0..4).map(|t| wts[t] * layer[idx[t] + 3] as u64 * layer[idx[t] + c] as u64).sum();
                let num = col + frame[p * 4 + c] as u64 * (DEN - a);
                frame[p * 4 + c] = ((num + DEN / 2) / DEN) as u8;
            }
            frame[p * 4 + 3] = 255;
        });
    }

    /// A random field (displacements within `max_px`) on a `w x h` grid of 4 px cells, and a
    /// layer of random colours: opaque in `body` (but for alpha-128 specks every `speck`
    /// pixels), random alpha in the `rim` around it, clear outside.
    fn random_case(
        (w, h): (usize, usize),
        mut seed: u32,
        max_px: u32,
        body: [std::ops::Range<usize>; 2],
        rim: [std::ops::Range<usize>; 2],
        speck: Option<usize>,
    ) -> (Warper, Vec<u8>) {
        let mut wp = Warper::new(w, h, 4, 4);
        let (cols, rows) = wp.corners();
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed >> 8
        };
        let mut disp = || (next() % (200 * max_px)) as f32 / 100.0 - max_px as f32;
        for cy in 0..rows {
            for cx in 0..cols {
                let d = [disp(), disp()];
                wp.set_corner(cx, cy, d);
            }
        }
        let layer = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                let a = if body[0].contains(&x) && body[1].contains(&y) {
                    if speck.is_some_and(|k| i % k == 0) { 128 } else { 255 }
                } else if rim[0].contains(&x) && rim[1].contains(&y) {
                    (next() % 256) as u8
                } else {
                    0
                };
                [(next() % 256) as u8, (next() % 256) as u8, (next() % 256) as u8, a]
            })
            .collect();
        (wp, layer)
    }

    #[test]
    fn tiles_updated_in_a_box_equal_tiles_recomputed_whole() {
        // 42 x 23: partial tiles on the right and bottom edges.
        let (w, h) = (42, 23);
        let (_, mut layer) = random_case((w, h), 3, 1, [0..42, 0..23], [0..0, 0..0], Some(97));
        let mut tiles = OpaqueTiles::new(&layer, w, h);
        for (i, [x0, y0, x1, y1]) in
            [[5, 3, 17, 9], [0, 0, 42, 23], [39, 20, 42, 23], [7, 7, 8, 8], [9, 4, 9, 12]]
                .into_iter()
                .enumerate()
        {
            // Make the box clear, then opaque, then clear in one pixel (when not empty).
            for alpha in [0u8, 255] {
                for y in y0..y1 {
                    for x in x0..x1 {
                        layer[(y * w + x) * 4 + 3] =
                            if alpha == 255 && (x + y + i) % 11 == 0 { 3 } else { alpha };
                    }
                }
                tiles.update_box(&layer, [x0, y0, x1, y1]);
                let whole = OpaqueTiles::new(&layer, w, h);
                assert_eq!(tiles.tiles, whole.tiles, "box {:?} alpha {alpha}", [x0, y0, x1, y1]);
            }
        }
    }

    #[test]
    fn warp_over_equals_its_definition_for_opaque_soft_and_clear_layers() {
        let (w, h) = (41, 29);
        let (wp, layer) = random_case((w, h), 7, 5, [8..32, 6..22], [5..35, 3..25], None);
        let region: Vec<u8> =
            (0..w * h).map(|i| if (i % w) % 9 == 4 || i % 5 == 0 { 0 } else { 255 }).collect();
        let frame: Vec<u8> = (0..w * h * 4).map(|i| (i * 31 % 256) as u8).collect();
        let (mut got, mut want) = (frame.clone(), frame);
        wp.warp_over(&layer, &region, &mut got);
        warp_over_reference(&wp, &layer, &region, &mut want);
        assert_eq!(got, want);
    }

    #[test]
    fn the_opaque_fast_path_gives_the_same_bytes_with_every_kernel() {
        let (w, h) = (67, 45);
        let (wp, layer) = random_case((w, h), 11, 3, [10..57, 8..37], [6..61, 4..41], Some(97));
        // Drawn almost everywhere, with a few holes.
        let region: Vec<u8> = (0..w * h).map(|i| if i % 53 == 0 { 0 } else { 255 }).collect();
        let frame: Vec<u8> = (0..w * h * 4).map(|i| (i * 31 % 256) as u8).collect();
        let mut want = frame.clone();
        warp_over_reference(&wp, &layer, &region, &mut want);
        let opaque = OpaqueTiles::new(&layer, w, h);
        for kernel in RemapKernel::available() {
            let mut got = frame.clone();
            let fast = wp.warp_over_opaque_with(kernel, &layer, &opaque, &region, &mut got);
            assert!(fast > 20, "{}: only {fast} runs took the kernel", kernel.name());
            assert_eq!(got, want, "{}", kernel.name());
        }
        // Tiles follow the layer: a layer made clear takes no fast run and draws nothing.
        let clear = vec![0u8; w * h * 4];
        let mut got = frame.clone();
        let tiles = OpaqueTiles::new(&clear, w, h);
        let fast = wp.warp_over_opaque_with(RemapKernel::best(), &clear, &tiles, &region, &mut got);
        assert_eq!((fast, got), (0, frame));
    }
}
