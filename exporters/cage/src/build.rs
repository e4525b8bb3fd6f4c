//! A multiscale cage tree from a vegetation mask (seed 004, section 5.2, on pictures).
//!
//! The paper's tree has a crown (the group outer lobe), outer lobes and inner lobes from a 3D
//! skeleton-lobe model; a picture only has the foliage's matte, so the levels are made from it:
//!
//! 1. **crowns**: each 4-connected part of the matte (at or above `threshold`) holding at least
//!    `min_part_fraction` of the foliage is a root cage: its outline, holes filled;
//! 2. **lobes**: a cage's foliage is split into `lobes` clusters (k-means on pixel positions,
//!    seeded by farthest points, so the clusters are compact pieces of foliage, as the paper's
//!    lobes are clusters of leaves); each cluster's largest part is outlined and clipped inside its
//!    parent cage (geo's boolean intersection), the largest piece kept;
//! 3. down to `levels` levels; cages whose foliage is too small to split are leaves.
//!
//! Every outline is traced along pixel edges, simplified (Ramer-Douglas-Peucker, 0.75 px) and
//! resampled by arc length to `vertices` vertices, counter-clockwise as `cage.json` wants.

use geo::{Area, BooleanOps, Polygon, Validation};
use thiserror::Error;

use crate::Point;
use crate::contour::{Bitmap, label_parts, trace_outer};
use crate::outline::{resample_closed, signed_area2, simplify_closed, to_line_string};
use crate::tree::{CageError, CageKind, CageTree, MAX_CAGE_VERTICES, MAX_CAGES, MAX_SIDE_PX};

/// How a tree is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildOptions {
    /// Levels of cages, 1 (crowns only) to [`MAX_LEVELS`].
    pub levels: usize,
    /// Vertices per cage, 8 to 1024.
    pub vertices: usize,
    /// Lobes a cage is split into, 2 to [`MAX_LOBES`].
    pub lobes: usize,
    /// Matte level counted as vegetation.
    pub threshold: u8,
    /// Smallest part that is a crown, as a fraction of all the foliage.
    pub min_part_fraction: f64,
}

/// Most levels.
pub const MAX_LEVELS: usize = 5;
/// Most lobes per cage.
pub const MAX_LOBES: usize = 8;
/// Most crowns (the largest parts are kept).
pub const MAX_CROWNS: usize = 16;
/// A cage is split only if each lobe would have this many pixels on average.
pub const MIN_LOBE_PX: usize = 64;

impl Default for BuildOptions {
    /// Three levels (crown, outer lobes, inner lobes, as the paper's GOL / OL / IL) of 3 lobes
    /// and 64 vertices: 13 cages for one crown.
    fn default() -> Self {
        BuildOptions { levels: 3, vertices: 64, lobes: 3, threshold: 128, min_part_fraction: 0.02 }
    }
}

impl BuildOptions {
    /// Every option out of range, by flag name.
    pub fn problems(&self) -> Vec<String> {
        let mut p = Vec::new();
        if !(1..=MAX_LEVELS).contains(&self.levels) {
            p.push(format!("--levels: {} is outside 1..={MAX_LEVELS}", self.levels));
        }
        if !(8..=MAX_CAGE_VERTICES).contains(&self.vertices) {
            p.push(format!("--vertices: {} is outside 8..={MAX_CAGE_VERTICES}", self.vertices));
        }
        if !(2..=MAX_LOBES).contains(&self.lobes) {
            p.push(format!("--lobes: {} is outside 2..={MAX_LOBES}", self.lobes));
        }
        if !(self.min_part_fraction.is_finite() && (0.0..1.0).contains(&self.min_part_fraction)) {
            p.push(format!("--min-part: {} is outside [0, 1)", self.min_part_fraction));
        }
        p
    }
}

/// Why no tree was built.
#[derive(Debug, Error)]
pub enum BuildError {
    /// Options out of range.
    #[error("{}", .0.join("; "))]
    Options(Vec<String>),
    /// The matte's size does not match its data, or is too large.
    #[error("the mask is {width}x{height} but holds {len} values")]
    Size {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Values given.
        len: usize,
    },
    /// Nothing in the matte is vegetation.
    #[error(
        "the mask marks no vegetation part of at least {min_px} pixels at level {threshold} or above \
         (it has {set_px} such pixels): is it the plants' matte, white on black?"
    )]
    Empty {
        /// Smallest part counted.
        min_px: usize,
        /// The threshold.
        threshold: u8,
        /// Pixels at or above it.
        set_px: usize,
    },
    /// The built tree failed validation (a defect: reported rather than written).
    #[error("the cages built from the mask are not a valid tree: {0}")]
    Invalid(#[from] CageError),
}

/// Builds the cage tree of a matte (`width * height` values, 255 = vegetation).
pub fn build_cage_tree(
    matte: &[u8],
    width: usize,
    height: usize,
    opts: &BuildOptions,
) -> Result<CageTree, BuildError> {
    let problems = opts.problems();
    if !problems.is_empty() {
        return Err(BuildError::Options(problems));
    }
    let max = MAX_SIDE_PX as usize;
    if width == 0 || height == 0 || width > max || height > max || matte.len() != width * height {
        return Err(BuildError::Size { width, height, len: matte.len() });
    }
    let map = Bitmap::from_matte(matte, width, height, opts.threshold);
    let set_px = map.count();
    let (labels, sizes) = label_parts(&map);
    let min_px = ((opts.min_part_fraction * set_px as f64).ceil() as usize).max(16);
    let mut crowns: Vec<usize> = (0..sizes.len()).filter(|&l| sizes[l] >= min_px).collect();
    crowns.sort_by_key(|&l| std::cmp::Reverse(sizes[l]));
    crowns.truncate(MAX_CROWNS);
    if crowns.is_empty() {
        return Err(BuildError::Empty { min_px, threshold: opts.threshold, set_px });
    }
    crowns.sort_unstable(); // raster order of their first pixel: stable ids
    let mut b = Builder { width, height, opts: *opts, cages: Vec::new() };
    for &label in &crowns {
        let pixels: Vec<u32> =
            (0..labels.len() as u32).filter(|&i| labels[i as usize] == label as u32).collect();
        let outline = b.outline(&pixels, None);
        if let Some(outline) = outline {
            b.grow(None, outline, &pixels, 1);
        }
    }
    let parts = b.cages.into_iter().map(|c| (c.id, c.parent, c.kind, c.vertices));
    Ok(CageTree::from_parts([width as u32, height as u32], parts)?)
}

struct Built {
    id: u32,
    parent: Option<u32>,
    kind: CageKind,
    vertices: Vec<Point>,
}

struct Builder {
    width: usize,
    height: usize,
    opts: BuildOptions,
    cages: Vec<Built>,
}

impl Builder {
    /// Adds the cage `outline` holding `pixels` under `parent`, then its lobes down the levels.
    fn grow(&mut self, parent: Option<u32>, outline: Vec<Point>, pixels: &[u32], level: usize) {
        let id = self.cages.len() as u32;
        let me = self.cages.len();
        self.cages.push(Built { id, parent, kind: CageKind::Leaf, vertices: outline.clone() });
        let k = self.opts.lobes;
        if level >= self.opts.levels || pixels.len() < k * MIN_LOBE_PX || self.cages.len() + k > MAX_CAGES {
            return;
        }
        let mut lobes = Vec::new();
        for cluster in kmeans(pixels, self.width, k) {
            if cluster.len() < MIN_LOBE_PX / 2 {
                continue;
            }
            let part = largest_part(&cluster, self.width, self.height);
            if let Some(child) = self.outline(&part, Some(&outline)) {
                lobes.push((child, part));
            }
        }
        if lobes.len() < 2 {
            return; // one lobe would only repeat its parent
        }
        self.cages[me].kind = CageKind::Internal;
        for (child, part) in lobes {
            self.grow(Some(id), child, &part, level + 1);
        }
    }

    /// The cage of a set of pixels: traced, simplified, clipped inside `parent`, resampled.
    fn outline(&self, pixels: &[u32], parent: Option<&[Point]>) -> Option<Vec<Point>> {
        let (w, h) = (self.width, self.height);
        let mut map = Bitmap { width: w, height: h, bits: vec![false; w * h] };
        for &p in pixels {
            map.bits[p as usize] = true;
        }
        let traced = trace_outer(&map)?;
        let n = self.opts.vertices;
        // Coarser simplification if resampling a fine one crosses itself in a narrow neck.
        for eps in [0.75, 1.5, 3.0, 6.0] {
            let mut poly = simplify_closed(&traced, eps);
            if let Some(parent) = parent {
                poly = clip_inside(&poly, parent)?;
            }
            // Clipping computes in floating point: a crown on the picture's edge may come back a
            // hair outside it.
            let (w, h) = (w as f64, h as f64);
            let cage: Vec<Point> = resample_closed(&poly, n)
                .into_iter()
                .map(|p| [p[0].clamp(0.0, w), p[1].clamp(0.0, h)])
                .collect();
            if signed_area2(&cage) > 0.0 && Polygon::new(to_line_string(&cage, true), vec![]).is_valid() {
                return Some(cage);
            }
        }
        None
    }
}

/// The largest piece of `poly` inside `parent`, counter-clockwise.
fn clip_inside(poly: &[Point], parent: &[Point]) -> Option<Vec<Point>> {
    let a = Polygon::new(to_line_string(poly, true), vec![]);
    let b = Polygon::new(to_line_string(parent, true), vec![]);
    let clipped = a.intersection(&b);
    let best = clipped.0.iter().max_by(|p, q| p.unsigned_area().total_cmp(&q.unsigned_area()))?;
    let mut out: Vec<Point> = best.exterior().coords().map(|c| [c.x, c.y]).collect();
    out.pop();
    if out.len() < 3 {
        return None;
    }
    if signed_area2(&out) < 0.0 {
        out.reverse();
    }
    Some(out)
}

/// The pixels of the largest 4-connected part of `pixels`.
fn largest_part(pixels: &[u32], width: usize, height: usize) -> Vec<u32> {
    let mut map = Bitmap { width, height, bits: vec![false; width * height] };
    for &p in pixels {
        map.bits[p as usize] = true;
    }
    let (labels, sizes) = label_parts(&map);
    let Some(best) = (0..sizes.len()).max_by_key(|&l| (sizes[l], std::cmp::Reverse(l))) else {
        return Vec::new();
    };
    pixels.iter().copied().filter(|&p| labels[p as usize] == best as u32).collect()
}

/// `k` clusters of pixel positions: Lloyd's k-means from farthest-point seeds (deterministic).
fn kmeans(pixels: &[u32], width: usize, k: usize) -> Vec<Vec<u32>> {
    let pos = |p: u32| [(p as usize % width) as f64 + 0.5, (p as usize / width) as f64 + 0.5];
    let n = pixels.len() as f64;
    let mean = pixels.iter().fold([0.0, 0.0], |m, &p| {
        let q = pos(p);
        [m[0] + q[0] / n, m[1] + q[1] / n]
    });
    let d2 = |a: Point, b: Point| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2);
    let mut centres: Vec<Point> = Vec::with_capacity(k);
    let mut nearest = vec![f64::INFINITY; pixels.len()];
    let mut from = mean;
    for _ in 0..k {
        for (j, &p) in pixels.iter().enumerate() {
            nearest[j] = nearest[j].min(d2(pos(p), from));
        }
        let far = (0..pixels.len()).max_by(|&a, &b| nearest[a].total_cmp(&nearest[b])).unwrap_or(0);
        from = pos(pixels[far]);
        if centres.is_empty() {
            // The first seed is the point farthest from the mean; distances restart from it.
            nearest.fill(f64::INFINITY);
            for (j, &p) in pixels.iter().enumerate() {
                nearest[j] = d2(pos(p), from);
            }
        }
        centres.push(from);
    }
    let mut assign = vec![0usize; pixels.len()];
    for _ in 0..30 {
        let mut changed = false;
        for (j, &p) in pixels.iter().enumerate() {
            let q = pos(p);
            let best = (0..k).min_by(|&a, &b| d2(q, centres[a]).total_cmp(&d2(q, centres[b]))).unwrap_or(0);
            changed |= assign[j] != best;
            assign[j] = best;
        }
        let mut sums = vec![[0.0, 0.0, 0.0]; k];
        for (j, &p) in pixels.iter().enumerate() {
            let q = pos(p);
            let s = &mut sums[assign[j]];
            s[0] += q[0];
            s[1] += q[1];
            s[2] += 1.0;
        }
        for (c, s) in centres.iter_mut().zip(&sums) {
            if s[2] > 0.0 {
                *c = [s[0] / s[2], s[1] / s[2]];
            }
        }
        if !changed {
            break;
        }
    }
    let mut clusters = vec![Vec::new(); k];
    for (j, &p) in pixels.iter().enumerate() {
        clusters[assign[j]].push(p);
    }
    clusters
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::outside_by;

    fn disc_matte(w: usize, h: usize, discs: &[(f64, f64, f64)]) -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
                if discs.iter().any(|&(cx, cy, r)| (x - cx).hypot(y - cy) < r) { 255 } else { 0 }
            })
            .collect()
    }

    #[test]
    fn a_disc_gives_a_crown_on_its_outline_with_lobes_inside() {
        let matte = disc_matte(200, 160, &[(100.0, 80.0, 60.0)]);
        let t = build_cage_tree(&matte, 200, 160, &BuildOptions::default()).unwrap();
        assert_eq!(t.roots().count(), 1);
        let crown = &t.cages[0];
        assert_eq!((crown.kind, crown.vertices.len(), crown.children.len()), (CageKind::Internal, 64, 3));
        for v in &crown.vertices {
            let r = (v[0] - 100.0).hypot(v[1] - 80.0);
            assert!((r - 60.0).abs() < 1.5, "crown vertex {v:?} at radius {r}");
        }
        // Area within 2 % of the disc's.
        let area = signed_area2(&crown.vertices) / 2.0;
        assert!((area / (std::f64::consts::PI * 3600.0) - 1.0).abs() < 0.02, "{area}");
        // 1 + 3 + 9 cages; each child inside its parent; the lobes cover most of the crown.
        assert_eq!(t.cages.len(), 13);
        for c in &t.cages[1..] {
            let parent = &t.cages[c.parent.unwrap()].vertices;
            assert!(c.vertices.iter().all(|&v| outside_by(parent, v) <= 1.0));
        }
        let lobes: f64 = crown.children.iter().map(|&i| signed_area2(&t.cages[i].vertices) / 2.0).sum();
        assert!(lobes / area > 0.85, "lobes cover {:.2} of the crown", lobes / area);
        assert_eq!(t.cages.iter().filter(|c| c.kind == CageKind::Leaf).count(), 9);
    }

    #[test]
    fn separate_plants_are_separate_crowns_and_specks_are_ignored() {
        let matte = disc_matte(300, 100, &[(60.0, 50.0, 30.0), (220.0, 50.0, 35.0), (150.0, 90.0, 1.5)]);
        let opts = BuildOptions { levels: 1, ..BuildOptions::default() };
        let t = build_cage_tree(&matte, 300, 100, &opts).unwrap();
        assert_eq!(t.cages.len(), 2);
        assert!(t.cages.iter().all(|c| c.kind == CageKind::Leaf && c.parent.is_none()));
        // Raster order of their first pixel: the right plant reaches higher (y 15 against 20).
        assert!(t.cages[0].vertices.iter().all(|v| v[0] > 150.0), "raster order: the taller plant first");
    }

    #[test]
    fn a_mask_covering_the_whole_picture_builds_inside_it() {
        let t = build_cage_tree(&[255; 64 * 48], 64, 48, &BuildOptions::default()).unwrap();
        // Resampling to 64 vertices cuts the corners by a hair.
        assert!(signed_area2(&t.cages[0].vertices) / 2.0 > 0.99 * 64.0 * 48.0);
        assert!(t.cages.len() > 1);
    }

    #[test]
    fn an_empty_mask_and_bad_options_are_refused_by_name() {
        let err = build_cage_tree(&[0; 100], 10, 10, &BuildOptions::default()).unwrap_err();
        assert!(err.to_string().contains("marks no vegetation part"), "{err}");
        let bad = BuildOptions { levels: 0, vertices: 4, lobes: 9, ..BuildOptions::default() };
        let err = build_cage_tree(&[255; 100], 10, 10, &bad).unwrap_err().to_string();
        assert!(
            err.contains("--levels: 0") && err.contains("--vertices: 4") && err.contains("--lobes: 9"),
            "{err}"
        );
        assert!(matches!(
            build_cage_tree(&[255; 99], 10, 10, &BuildOptions::default()),
            Err(BuildError::Size { .. })
        ));
    }
}
