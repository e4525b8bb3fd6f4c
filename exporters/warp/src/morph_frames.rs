//! The in-betweens of a cage morph (seed 004, section 5), frame by frame, for `frond-warp morph`
//! ([`crate::morph`]), the cage mode of `serve` and `render --mode cage`: the plan's cages at `t`,
//! every grid corner's source point by the leaf cage holding it (mapped exactly where an outline
//! passes, interpolated inside one cage's smooth blocks), the layer with pruned lobes faded, the
//! region it may draw in (the deformed crowns grown by the layer's own slack), and section 6.2's
//! outline distance of a frame to the reference in-between.

use frond_cage::contour::{Bitmap, label_parts, trace_outer};
use frond_cage::morph::{MorphPlan, Placed};
use frond_cage::outline::{frechet_closed, resample_closed, start_nearest};
use frond_cage::raster::fill_polygon;
use frond_cage::tree::outside_by;
use frond_cage::{CageTree, Point};

use crate::Scene;
use crate::warp::{OpaqueTiles, Warper};

/// Grid cell of the cage warp, pixels (the field is smooth inside a leaf cage).
pub const CAGE_CELL_PX: usize = 4;
/// Cells per side of a block whose corners are interpolated when the block lies inside one cage,
/// clear of every outline (the map is smooth there): 16 px blocks.
const BLOCK_CELLS: usize = 4;
/// Most slack a layer may have beyond its rest crowns, pixels.
const MAX_SLACK_PX: usize = 16;

/// The in-betweens of one morph, frame by frame: the cage field, the fading of pruned lobes and
/// the region the layer may draw in, with their buffers kept between frames.
pub struct MorphFrames<'a> {
    scene: &'a Scene,
    plan: &'a MorphPlan,
    roots: Vec<usize>,
    slack: usize,
    /// Pixels of pruned cages at rest (non-zero), which fade with `t`, and their box
    /// `[x0, y0, x1, y1)` (`None` when nothing is pruned).
    pruned_px: Vec<u8>,
    pruned_box: Option<[usize; 4]>,
    warper: Warper,
    layer_t: Vec<u8>,
    /// Which tiles of `layer_t` are opaque (the compositing's fast path).
    opaque: OpaqueTiles,
    region: Vec<u8>,
    /// The deformed crowns before growing, and the horizontal pass of the growing.
    filled: Vec<u8>,
    tmp: Vec<u8>,
    counts: Vec<u16>,
    /// Grid cells holding a pixel of the region (the corners the warp reads).
    needed: Vec<bool>,
    /// Grid cells an outline may cross.
    crossed: Vec<bool>,
    /// Per grid corner: the frame stamp when it was last mapped exactly, and the cage that
    /// mapped it.
    mapped: Vec<(u32, u32)>,
    stamp: u32,
    weights: Vec<f64>,
    now: Vec<Vec<Point>>,
}

impl<'a> MorphFrames<'a> {
    /// Prepares the morph of `scene`'s first layer by `plan`.
    pub fn new(scene: &'a Scene, plan: &'a MorphPlan) -> MorphFrames<'a> {
        let (w, h) = (scene.width, scene.height);
        let layer = &scene.layers[0];
        let tree = plan.tree();
        let roots: Vec<usize> = tree.roots().collect();
        let slack = layer_slack(&layer.pixels, w, tree, &roots);
        // Pixels of pruned cages at rest: they fade with t.
        let mut pruned_px = vec![0u8; w * h];
        for (i, c) in tree.cages.iter().enumerate() {
            if plan.pruned()[i] {
                fill_polygon(&c.vertices, w, h, &mut pruned_px);
            }
        }
        MorphFrames {
            scene,
            plan,
            roots,
            slack,
            pruned_box: set_box(&pruned_px, w, h),
            pruned_px,
            warper: Warper::new(w, h, CAGE_CELL_PX, CAGE_CELL_PX),
            layer_t: layer.pixels.clone(),
            opaque: OpaqueTiles::new(&layer.pixels, w, h),
            region: vec![0; w * h],
            filled: vec![0; w * h],
            tmp: vec![0; w * h],
            counts: Vec::with_capacity(w),
            needed: Vec::new(),
            crossed: Vec::new(),
            mapped: Vec::new(),
            stamp: 0,
            weights: Vec::new(),
            now: Vec::new(),
        }
    }

    /// The cages at `t` (seed 004, sections 5.3-5.4).
    pub fn update_cages(&mut self, t: f64) {
        self.now = self.plan.cages_at(t);
    }

    /// The cages with the plan's crown at `crown` (the skeleton-driven mode).
    pub fn set_crown(&mut self, crown: &[Point]) {
        self.now = self.plan.cages_for_crown(crown);
    }

    /// Sets every grid corner that a drawn pixel uses (a corner of a cell holding a pixel of the
    /// region, from [`MorphFrames::update_layer`], which must come first) to the cage map's
    /// displacement; the others are never read and are left as they are.
    ///
    /// The map is smooth inside a cage, so a block (16 px, then its 8 px quarters) whose four
    /// corners are mapped by the same cage and which no deformed outline crosses takes its inner
    /// corners by bilinear interpolation; other corners are mapped one by one, each once.
    pub fn update_field(&mut self) {
        let (cols, rows) = self.warper.corners();
        let cells_x = cols - 1;
        self.mark_needed_cells(cells_x, rows - 1);
        self.mark_crossed_cells(cells_x, rows - 1);
        let needed = &self.needed;
        // A corner is read by the (up to) four cells around it.
        let used = |cx: usize, cy: usize| {
            let (x0, x1) = (cx.saturating_sub(1), cx.min(cells_x - 1));
            let (y0, y1) = (cy.saturating_sub(1), cy.min(rows - 2));
            (y0..=y1).any(|y| (x0..=x1).any(|x| needed[y * cells_x + x]))
        };
        let corner_at =
            |cx: usize, cy: usize| [(cx * CAGE_CELL_PX) as f64 + 0.5, (cy * CAGE_CELL_PX) as f64 + 0.5];
        let (plan, now) = (self.plan, &self.now);
        let placed = Placed::new(plan, now);
        let weights = &mut self.weights;
        let mut map_corner = |cx: usize, cy: usize| -> ([f32; 2], usize) {
            if !used(cx, cy) {
                return ([0.0, 0.0], usize::MAX);
            }
            let p = corner_at(cx, cy);
            let (src, cage) = plan.inverse_map_placed(&placed, p, weights);
            ([(src[0] - p[0]) as f32, (src[1] - p[1]) as f32], cage)
        };
        // Blocks share their corners and edges: each corner is mapped once per frame, and a
        // mapped corner keeps its value against a neighbour's interpolation.
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 || self.mapped.len() != cols * rows {
            self.mapped.clear();
            self.mapped.resize(cols * rows, (0, 0));
            self.stamp = 1;
        }
        let (stamp, memo, warper, crossed) = (self.stamp, &mut self.mapped, &mut self.warper, &self.crossed);
        let mut exact = |memo: &mut [(u32, u32)], warper: &mut Warper, cx: usize, cy: usize| {
            let m = &mut memo[cy * cols + cx];
            if m.0 == stamp {
                return (warper.corner(cx, cy), m.1 as usize);
            }
            let (d, cage) = map_corner(cx, cy);
            *m = (stamp, cage as u32);
            warper.set_corner(cx, cy, d);
            (d, cage)
        };
        let b = BLOCK_CELLS;
        // Blocks to fill, as corner ranges [x0, y0, x1, y1]: a block and its quarters (depth 2).
        let mut todo: Vec<[usize; 4]> = Vec::with_capacity(8);
        for by in (0..rows - 1).step_by(b) {
            for bx in (0..cols - 1).step_by(b) {
                let (x1, y1) = ((bx + b).min(cols - 1), (by + b).min(rows - 1));
                // No drawn pixel reads any corner of this block.
                let (cx0, cy0) = (bx.saturating_sub(1), by.saturating_sub(1));
                let (cx1, cy1) = (x1.min(cells_x - 1), y1.min(rows - 2));
                if !(cy0..=cy1).any(|y| (cx0..=cx1).any(|x| needed[y * cells_x + x])) {
                    continue;
                }
                todo.push([bx, by, x1, y1]);
                while let Some([x0, y0, x1, y1]) = todo.pop() {
                    let corners = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)];
                    let mapped = corners.map(|(cx, cy)| exact(memo, warper, cx, cy));
                    if x1 - x0 <= 1 && y1 - y0 <= 1 {
                        continue;
                    }
                    // No outline crosses the block: every point of it lies in the same cages,
                    // so one cage maps it all, smoothly.
                    let smooth = mapped[0].1 != usize::MAX
                        && mapped.iter().all(|m| m.1 == mapped[0].1)
                        && !(y0..y1).any(|y| crossed[y * cells_x + x0..y * cells_x + x1].contains(&true));
                    if smooth {
                        let corners = mapped.map(|m| m.0);
                        fill_block(warper, memo, stamp, cols, [x0, y0, x1, y1], corners);
                    } else {
                        push_quarters(&mut todo, [x0, y0, x1, y1]);
                    }
                }
            }
        }
    }

    /// `crossed[cy * cells_x + cx]`: whether an outline of the current cages may cross cell
    /// `(cx, cy)` (each edge marks every cell, grown by a pixel, that it passes through).
    fn mark_crossed_cells(&mut self, cells_x: usize, cells_y: usize) {
        let span = CAGE_CELL_PX as f64;
        self.crossed.clear();
        self.crossed.resize(cells_x * cells_y, false);
        // Cell k spans corner pixels k * span + 0.5 to (k + 1) * span + 0.5.
        let cell = |v: f64, n: usize| (((v - 0.5) / span).floor().max(0.0) as usize).min(n - 1);
        for c in &self.now {
            for (i, &a) in c.iter().enumerate() {
                let z = c[(i + 1) % c.len()];
                let (kx0, kx1) = (cell(a[0].min(z[0]) - 1.0, cells_x), cell(a[0].max(z[0]) + 1.0, cells_x));
                let (ky0, ky1) = (cell(a[1].min(z[1]) - 1.0, cells_y), cell(a[1].max(z[1]) + 1.0, cells_y));
                // The cells of the box whose square, grown by a pixel, the edge's line passes
                // through (the square's corners are not all on one side of it).
                let (dx, dy) = (z[0] - a[0], z[1] - a[1]);
                let side = |x: f64, y: f64| dx * (y - a[1]) - dy * (x - a[0]);
                for ky in ky0..=ky1 {
                    let (y0, y1) = (ky as f64 * span - 0.5, (ky + 1) as f64 * span + 1.5);
                    for kx in kx0..=kx1 {
                        let (x0, x1) = (kx as f64 * span - 0.5, (kx + 1) as f64 * span + 1.5);
                        let s = [side(x0, y0), side(x1, y0), side(x0, y1), side(x1, y1)];
                        if !(s.iter().all(|&v| v > 0.0) || s.iter().all(|&v| v < 0.0)) {
                            self.crossed[ky * cells_x + kx] = true;
                        }
                    }
                }
            }
        }
    }

    /// `needed[cy * cells_x + cx]`: whether cell `(cx, cy)` of the grid holds a pixel of the
    /// region.
    fn mark_needed_cells(&mut self, cells_x: usize, cells_y: usize) {
        let (w, h) = (self.scene.width, self.scene.height);
        self.needed.clear();
        self.needed.resize(cells_x * cells_y, false);
        for y in 0..h {
            let cy = (y / CAGE_CELL_PX).min(cells_y - 1);
            let row = &self.region[y * w..(y + 1) * w];
            for (cx, cell) in row.chunks(CAGE_CELL_PX).enumerate() {
                if cell.iter().any(|&r| r != 0) {
                    self.needed[cy * cells_x + cx.min(cells_x - 1)] = true;
                }
            }
        }
    }

    /// The layer's colours with pruned lobes faded to `1 - t`, and the region it may draw in:
    /// the deformed crowns grown by the slack.
    pub fn update_layer(&mut self, t: f64) {
        let (w, h) = (self.scene.width, self.scene.height);
        let layer = &self.scene.layers[0];
        if let Some([x0, y0, x1, y1]) = self.pruned_box {
            // Only the pruned pixels' box changes; the rest stays as the layer is.
            let keep = 1.0 - t;
            for y in y0..y1 {
                let (a, b) = (y * w + x0, y * w + x1);
                let rows = layer.pixels[a * 4..b * 4]
                    .chunks_exact(4)
                    .zip(self.layer_t[a * 4..b * 4].chunks_exact_mut(4));
                for ((px, out), &pr) in rows.zip(&self.pruned_px[a..b]) {
                    out[3] = if pr != 0 { (px[3] as f64 * keep).round() as u8 } else { px[3] };
                }
            }
            self.opaque.update_box(&self.layer_t, [x0, y0, x1, y1]);
        }
        // Only the crowns' box (grown by the slack) can be set: the rest stays 0.
        let s = self.slack as f64;
        let crowns: Vec<Point> = self.roots.iter().flat_map(|&r| self.now[r].iter().copied()).collect();
        let b = bounds(&crowns, s + 1.0);
        let clamp = |v: f64, hi: usize| (v.max(0.0) as usize).min(hi);
        let (x0, y0, x1, y1) = (clamp(b[0], w), clamp(b[1], h), clamp(b[2].ceil(), w), clamp(b[3].ceil(), h));
        self.region.fill(0);
        self.filled.fill(0);
        for &r in &self.roots {
            fill_polygon(&self.now[r], w, h, &mut self.filled);
        }
        dilate_box(
            &self.filled,
            &mut self.tmp,
            &mut self.region,
            &mut self.counts,
            w,
            self.slack,
            [x0, y0, x1, y1],
        );
    }

    /// The whole in-between at `t`, composed over the background into `frame`.
    pub fn frame_at(&mut self, t: f64, frame: &mut Vec<u8>) {
        self.update_cages(t);
        self.compose(t, frame);
    }

    /// The frame of the current cages, pruned lobes faded to `1 - t`, over the background.
    pub fn compose(&mut self, t: f64, frame: &mut Vec<u8>) {
        self.update_layer(t);
        self.update_field();
        frame.clear();
        frame.extend_from_slice(&self.scene.background);
        self.warp_over(frame);
    }

    /// Warps the layer as last drawn over `frame` in the last frame's region.
    pub fn warp_over(&self, frame: &mut [u8]) {
        self.warper.warp_over_opaque(&self.layer_t, &self.opaque, &self.region, frame);
    }

    /// The cages of the last frame (one vertex list per cage of the plan's tree).
    pub fn cages(&self) -> &[Vec<Point>] {
        &self.now
    }

    /// Section 6.2's quality of the last frame (composed at `t`): the Frechet distance of the
    /// warped layer's outline to the reference in-between, pixels. `warped` is scratch.
    pub fn outline_distance(&self, t: f64, warped: &mut Vec<u8>) -> f64 {
        let (w, h) = (self.scene.width, self.scene.height);
        warped.resize(w * h * 4, 0);
        self.warper.remap(&self.layer_t, warped);
        let n = self.plan.tree().cages[self.plan.crown()].vertices.len();
        outline_distance(warped, &self.region, w, h, &self.plan.crown_at(t), n)
    }

    /// The warper of the last frame.
    pub fn warper(&self) -> &Warper {
        &self.warper
    }

    /// The layer as last drawn (pruned lobes faded).
    pub fn layer(&self) -> &[u8] {
        &self.layer_t
    }

    /// The region of the last frame.
    pub fn region(&self) -> &[u8] {
        &self.region
    }
}

/// The box `[x0, y0, x1, y1)` of the non-zero pixels of `map` (`w x h`), `None` if there are none.
fn set_box(map: &[u8], w: usize, h: usize) -> Option<[usize; 4]> {
    let mut b: Option<[usize; 4]> = None;
    for (y, row) in map[..w * h].chunks_exact(w).enumerate() {
        let Some(first) = row.iter().position(|&v| v != 0) else { continue };
        let last = row.iter().rposition(|&v| v != 0).unwrap_or(first);
        let [x0, _, x1, y1] = b.get_or_insert([first, y, first, y]);
        (*x0, *x1, *y1) = ((*x0).min(first), (*x1).max(last + 1), y + 1);
    }
    b
}

/// Square dilation of the binary `map` (0 or not) by `r` into `out` (255 or 0) inside
/// `[x0, y0, x1, y1)`: a pixel is set when any pixel of `map` within `r` in x and y (inside the
/// box) is. Separable, O(1) per pixel: rows grow each run of set pixels by `r` into `tmp`, then
/// columns keep a running count of the set `tmp` pixels in their window (straight loops over
/// rows the compiler vectorises; `map` is a filled polygon, a few runs a row). `map` is 0
/// outside the box, and there `tmp` and `out` are left. `counts` is scratch, one per column.
fn dilate_box(
    map: &[u8],
    tmp: &mut [u8],
    out: &mut [u8],
    counts: &mut Vec<u16>,
    w: usize,
    r: usize,
    [x0, y0, x1, y1]: [usize; 4],
) {
    if x0 >= x1 || y0 >= y1 {
        return;
    }
    let n = x1 - x0;
    for y in y0..y1 {
        let (m, t) = (&map[y * w + x0..y * w + x1], &mut tmp[y * w + x0..y * w + x1]);
        t.fill(0);
        let mut x = 0;
        while let Some(start) = m[x..].iter().position(|&v| v != 0) {
            let start = x + start;
            let end = m[start..].iter().position(|&v| v == 0).map_or(n, |k| start + k);
            t[start.saturating_sub(r)..(end + r).min(n)].fill(255);
            x = end;
        }
    }
    // The window of row y is rows y - r ..= y + r inside the box: at most 2r + 1 <= u16::MAX.
    assert!(r < u16::MAX as usize / 2, "dilation radius {r}");
    counts.clear();
    counts.resize(n, 0);
    let row = |y: usize| y * w + x0..y * w + x1;
    for y in y0..(y0 + r).min(y1) {
        counts.iter_mut().zip(&tmp[row(y)]).for_each(|(c, &t)| *c += u16::from(t != 0));
    }
    for y in y0..y1 {
        if y + r < y1 {
            counts.iter_mut().zip(&tmp[row(y + r)]).for_each(|(c, &t)| *c += u16::from(t != 0));
        }
        if y > y0 + r {
            counts.iter_mut().zip(&tmp[row(y - r - 1)]).for_each(|(c, &t)| *c -= u16::from(t != 0));
        }
        out[row(y)].iter_mut().zip(counts.iter()).for_each(|(o, &c)| *o = if c > 0 { 255 } else { 0 });
    }
}

/// `[x0, y0, x1, y1]` of `poly` grown by `margin`.
fn bounds(poly: &[Point], margin: f64) -> [f64; 4] {
    let b = frond_cage::outline::bounds(poly);
    [b[0] - margin, b[1] - margin, b[2] + margin, b[3] + margin]
}

/// How far the layer's vegetation reaches outside its rest crowns (whole pixels, at least 1).
fn layer_slack(pixels: &[u8], w: usize, tree: &CageTree, roots: &[usize]) -> usize {
    let mut worst = 0.0f64;
    for (i, px) in pixels.chunks_exact(4).enumerate() {
        if px[3] == 0 {
            continue;
        }
        let p = [(i % w) as f64 + 0.5, (i / w) as f64 + 0.5];
        let d = roots.iter().map(|&r| outside_by(&tree.cages[r].vertices, p)).fold(f64::INFINITY, f64::min);
        worst = worst.max(d);
    }
    (worst.ceil() as usize + 1).min(MAX_SLACK_PX)
}

/// Frechet distance between the outline of the warped layer's largest part (alpha >= 128 inside
/// the region) and `reference`, both resampled to `n` vertices from the points nearest each other.
fn outline_distance(warped: &[u8], region: &[u8], w: usize, h: usize, reference: &[Point], n: usize) -> f64 {
    let bits: Vec<bool> = warped.chunks_exact(4).zip(region).map(|(p, &r)| r != 0 && p[3] >= 128).collect();
    let map = Bitmap { width: w, height: h, bits };
    let (labels, sizes) = label_parts(&map);
    let Some(best) = (0..sizes.len()).max_by_key(|&l| sizes[l]) else {
        return f64::INFINITY;
    };
    let part = Bitmap { width: w, height: h, bits: labels.iter().map(|&l| l == best as u32).collect() };
    let Some(traced) = trace_outer(&part) else {
        return f64::INFINITY;
    };
    let reference = resample_closed(reference, n);
    let outline = resample_closed(&start_nearest(&traced, reference[0]), n);
    frechet_closed(&outline, &reference)
}

/// Sets every corner of block `[x0, y0, x1, y1]` not mapped this frame (`memo[i].0 != stamp`,
/// `cols` corners a row) by bilinear interpolation of the displacements at its four corners
/// (`[top left, top right, bottom left, bottom right]`): a block one cage maps smoothly.
fn fill_block(
    warper: &mut Warper,
    memo: &[(u32, u32)],
    stamp: u32,
    cols: usize,
    [x0, y0, x1, y1]: [usize; 4],
    corners: [[f32; 2]; 4],
) {
    let lerp = |a: [f32; 2], b: [f32; 2], t: f32| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
    for cy in y0..=y1 {
        for cx in x0..=x1 {
            if memo[cy * cols + cx].0 != stamp {
                let u = (cx - x0) as f32 / (x1 - x0) as f32;
                let v = (cy - y0) as f32 / (y1 - y0) as f32;
                let d = lerp(lerp(corners[0], corners[1], u), lerp(corners[2], corners[3], u), v);
                warper.set_corner(cx, cy, d);
            }
        }
    }
}

/// Pushes the (up to four, non-empty) quarters of block `[x0, y0, x1, y1]` onto `todo`.
fn push_quarters(todo: &mut Vec<[usize; 4]>, [x0, y0, x1, y1]: [usize; 4]) {
    let (mx, my) = ((x0 + x1).div_ceil(2), (y0 + y1).div_ceil(2));
    for (qx0, qx1) in [(x0, mx), (mx, x1)] {
        for (qy0, qy1) in [(y0, my), (my, y1)] {
            if qx0 < qx1 && qy0 < qy1 {
                todo.push([qx0, qy0, qx1, qy1]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition, pixel by pixel: the window's maximum inside the box.
    fn dilate_naive(map: &[u8], w: usize, r: usize, [x0, y0, x1, y1]: [usize; 4]) -> Vec<u8> {
        let mut out = vec![0u8; map.len()];
        for y in y0..y1 {
            for x in x0..x1 {
                let any = (y.saturating_sub(r).max(y0)..=(y + r).min(y1 - 1)).any(|yy| {
                    (x.saturating_sub(r).max(x0)..=(x + r).min(x1 - 1)).any(|xx| map[yy * w + xx] != 0)
                });
                out[y * w + x] = if any { 255 } else { 0 };
            }
        }
        out
    }

    #[test]
    fn the_running_dilation_equals_the_windowed_maximum() {
        let (w, h) = (37, 23);
        let mut seed = 12345u32;
        for case in 0..40 {
            let bx = [case % 5, case % 3, w - case % 4, h - case % 6];
            let mut map = vec![0u8; w * h];
            for y in bx[1]..bx[3] {
                for x in bx[0]..bx[2] {
                    seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
                    // Sparse (about 1 pixel in 40) or dense (1 in 2: runs of all lengths).
                    if (seed >> 16).is_multiple_of(if case < 20 { 40 } else { 2 }) {
                        map[y * w + x] = 255;
                    }
                }
            }
            let r = case % 7;
            let (mut tmp, mut out, mut counts) = (vec![0u8; w * h], vec![0u8; w * h], Vec::new());
            dilate_box(&map, &mut tmp, &mut out, &mut counts, w, r, bx);
            assert_eq!(out, dilate_naive(&map, w, r, bx), "case {case}, r {r}, box {bx:?}");
        }
    }
}
