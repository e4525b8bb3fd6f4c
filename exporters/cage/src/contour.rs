//! The outlines of a vegetation mask: 4-connected parts, each traced along pixel edges.
//!
//! A pixel `(x, y)` covers `[x, x+1] x [y, y+1]`; an outline runs on the corner lattice with its
//! part on the right-hand side (image coordinates, y down), which makes its shoelace area
//! positive and equal to the part's pixel count when the part has no holes (holes are filled:
//! only the outer boundary is traced).

/// A binary image: `true` is vegetation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bitmap {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major, `width * height`.
    pub bits: Vec<bool>,
}

impl Bitmap {
    /// Pixels of a matte at or above `threshold` (0-255).
    pub fn from_matte(matte: &[u8], width: usize, height: usize, threshold: u8) -> Bitmap {
        Bitmap { width, height, bits: matte.iter().map(|&m| m >= threshold).collect() }
    }

    /// Whether pixel `(x, y)` is set; outside the image nothing is.
    pub fn get(&self, x: i64, y: i64) -> bool {
        x >= 0
            && y >= 0
            && (x as usize) < self.width
            && (y as usize) < self.height
            && self.bits[y as usize * self.width + x as usize]
    }

    /// Number of set pixels.
    pub fn count(&self) -> usize {
        self.bits.iter().filter(|&&b| b).count()
    }
}

/// The 4-connected parts of `map`: one label per pixel (`u32::MAX` for background) and each
/// part's pixel count, labels in raster order of their first pixel.
pub fn label_parts(map: &Bitmap) -> (Vec<u32>, Vec<usize>) {
    let (w, h) = (map.width, map.height);
    let mut labels = vec![u32::MAX; w * h];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if !map.bits[start] || labels[start] != u32::MAX {
            continue;
        }
        let label = sizes.len() as u32;
        let mut size = 0usize;
        labels[start] = label;
        stack.push(start);
        while let Some(i) = stack.pop() {
            size += 1;
            let (x, y) = (i % w, i / w);
            let mut visit = |j: usize| {
                if map.bits[j] && labels[j] == u32::MAX {
                    labels[j] = label;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        sizes.push(size);
    }
    (labels, sizes)
}

/// The outer boundary of the 4-connected part of `map` holding its first set pixel in raster
/// order, as the corners where the boundary turns; `None` for an empty map.
///
/// Crack following: standing on a corner facing a direction, the two pixels ahead decide
/// (part on the right): right one unset -> turn right; both set -> turn left; else straight.
pub fn trace_outer(map: &Bitmap) -> Option<Vec<[f64; 2]>> {
    let first = map.bits.iter().position(|&b| b)?;
    let (x0, y0) = ((first % map.width) as i64, (first / map.width) as i64);
    // Directions E, S, W, N (clockwise on screen, y down).
    const STEP: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];
    // Ahead-left and ahead-right pixels relative to the corner, per direction.
    const AHEAD: [((i64, i64), (i64, i64)); 4] =
        [((0, -1), (0, 0)), ((0, 0), (-1, 0)), ((-1, 0), (-1, -1)), ((-1, -1), (0, -1))];
    let (mut x, mut y, mut d) = (x0, y0, 0usize);
    let mut corners = vec![[x0 as f64, y0 as f64]];
    let limit = 4 * map.bits.len() + 8;
    for _ in 0..limit {
        let ((lx, ly), (rx, ry)) = AHEAD[d];
        let (left, right) = (map.get(x + lx, y + ly), map.get(x + rx, y + ry));
        let next = if !right {
            (d + 1) % 4
        } else if left {
            (d + 3) % 4
        } else {
            d
        };
        if next != d {
            // A turn: this corner is a vertex (the start is one already).
            if (x, y) != (x0, y0) {
                corners.push([x as f64, y as f64]);
            }
            d = next;
            if (x, y, d) == (x0, y0, 0) {
                return Some(corners);
            }
            continue;
        }
        x += STEP[d].0;
        y += STEP[d].1;
    }
    // Unreachable for a finite map: every corner is met at most twice per direction.
    Some(corners)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outline::signed_area2;

    fn bitmap(rows: &[&str]) -> Bitmap {
        let bits: Vec<bool> = rows.iter().flat_map(|r| r.chars().map(|c| c == '#')).collect();
        Bitmap { width: rows[0].len(), height: rows.len(), bits }
    }

    #[test]
    fn a_single_pixel_is_a_unit_square() {
        let m = bitmap(&["...", ".#.", "..."]);
        assert_eq!(trace_outer(&m).unwrap(), [[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]]);
    }

    #[test]
    fn an_ell_is_traced_corner_by_corner_with_area_equal_to_its_pixels() {
        let m = bitmap(&["#..", "#..", "###"]);
        let poly = trace_outer(&m).unwrap();
        assert_eq!(poly, [[0., 0.], [1., 0.], [1., 2.], [3., 2.], [3., 3.], [0., 3.]]);
        assert_eq!(signed_area2(&poly), 2.0 * 5.0);
    }

    #[test]
    fn holes_are_filled_and_diagonal_neighbours_are_separate_parts() {
        let ring = bitmap(&["###", "#.#", "###"]);
        assert_eq!(signed_area2(&trace_outer(&ring).unwrap()), 2.0 * 9.0);
        let diag = bitmap(&["#.", ".#"]);
        let (labels, sizes) = label_parts(&diag);
        assert_eq!((labels[0], labels[3], sizes), (0, 1, vec![1, 1]));
        assert_eq!(trace_outer(&diag).unwrap().len(), 4);
    }

    #[test]
    fn a_disc_has_the_area_of_its_pixels() {
        let (w, h) = (41, 37);
        let bits = (0..w * h).map(|i| ((i % w) as f64 - 20.0).hypot((i / w) as f64 - 18.0) < 15.0).collect();
        let m = Bitmap { width: w, height: h, bits };
        let poly = trace_outer(&m).unwrap();
        assert_eq!(signed_area2(&poly), 2.0 * m.count() as f64);
    }
}
