//! Closed outlines (cages, silhouettes, sketches) as vertex lists.

use geo::line_measures::FrechetDistance;
use geo::{Coord, Euclidean, LineString, Simplify};

use crate::Point;

/// Twice the signed area (shoelace, `sum x_i y_{i+1} - x_{i+1} y_i`) of the closed polygon:
/// positive when its vertices turn counter-clockwise in the (x, y) coordinates as written.
pub fn signed_area2(poly: &[Point]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum()
}

/// The bounding box `[x0, y0, x1, y1]` of the points (inverted, infinite, for none).
pub fn bounds(points: &[Point]) -> [f64; 4] {
    points.iter().fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, p| {
        [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])]
    })
}

/// Perimeter of the closed polygon.
pub fn perimeter(poly: &[Point]) -> f64 {
    let n = poly.len();
    (0..n).map(|i| dist(poly[i], poly[(i + 1) % n])).sum()
}

/// `n` points spaced evenly by arc length along the closed polygon, the first at its first
/// vertex (Nealen et al.'s arc-length parameterisation, used to match outlines and sketches).
pub fn resample_closed(poly: &[Point], n: usize) -> Vec<Point> {
    resample(poly, n, true)
}

/// `n` points spaced evenly by arc length along the open polyline, from its first vertex to its
/// last.
pub fn resample_open(line: &[Point], n: usize) -> Vec<Point> {
    resample(line, n, false)
}

fn resample(poly: &[Point], n: usize, closed: bool) -> Vec<Point> {
    if poly.is_empty() || n == 0 {
        return Vec::new();
    }
    let segments = if closed { poly.len() } else { poly.len() - 1 };
    let seg = |i: usize| (poly[i], poly[(i + 1) % poly.len()]);
    let total: f64 = (0..segments).map(|i| dist(seg(i).0, seg(i).1)).sum();
    if total <= 0.0 || segments == 0 {
        return vec![poly[0]; n];
    }
    let step = if closed { total / n as f64 } else { total / (n.max(2) - 1) as f64 };
    let mut out = Vec::with_capacity(n);
    let (mut i, mut walked) = (0usize, 0.0f64);
    for k in 0..n {
        let target = (k as f64 * step).min(total);
        while i + 1 < segments && walked + dist(seg(i).0, seg(i).1) < target {
            walked += dist(seg(i).0, seg(i).1);
            i += 1;
        }
        let (a, b) = seg(i);
        let len = dist(a, b);
        let t = if len > 0.0 { ((target - walked) / len).clamp(0.0, 1.0) } else { 0.0 };
        out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
    }
    out
}

/// Ramer-Douglas-Peucker simplification of the closed polygon within `epsilon_px` (geo's).
pub fn simplify_closed(poly: &[Point], epsilon_px: f64) -> Vec<Point> {
    let mut ring = to_line_string(poly, true);
    ring = ring.simplify(epsilon_px);
    let mut out: Vec<Point> = ring.coords().map(|c| [c.x, c.y]).collect();
    out.pop(); // the closing repeat of the first vertex
    if out.len() < 3 { poly.to_vec() } else { out }
}

/// The discrete Frechet distance (Eiter and Mannila 1994) between two closed outlines, each
/// walked from its first vertex back to it (geo's implementation of the coupling recurrence).
pub fn frechet_closed(a: &[Point], b: &[Point]) -> f64 {
    Euclidean.frechet_distance(&to_line_string(a, true), &to_line_string(b, true))
}

/// The same between open polylines.
pub fn frechet_open(a: &[Point], b: &[Point]) -> f64 {
    Euclidean.frechet_distance(&to_line_string(a, false), &to_line_string(b, false))
}

pub(crate) fn to_line_string(poly: &[Point], closed: bool) -> LineString<f64> {
    let mut coords: Vec<Coord<f64>> = poly.iter().map(|p| Coord { x: p[0], y: p[1] }).collect();
    if closed && let Some(&first) = coords.first() {
        coords.push(first);
    }
    LineString::new(coords)
}

/// The closed polygon rotated to start at its vertex nearest `p`.
pub fn start_nearest(poly: &[Point], p: Point) -> Vec<Point> {
    let start = (0..poly.len()).min_by(|&i, &j| dist(poly[i], p).total_cmp(&dist(poly[j], p))).unwrap_or(0);
    poly[start..].iter().chain(&poly[..start]).copied().collect()
}

pub(crate) fn dist(a: Point, b: Point) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [Point; 4] = [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]];

    #[test]
    fn area_and_resampling_of_a_square() {
        assert_eq!(signed_area2(&SQUARE), 32.0);
        let rev: Vec<Point> = SQUARE.iter().rev().copied().collect();
        assert_eq!(signed_area2(&rev), -32.0);
        assert_eq!(perimeter(&SQUARE), 16.0);
        let r = resample_closed(&SQUARE, 8);
        let want = [[0., 0.], [2., 0.], [4., 0.], [4., 2.], [4., 4.], [2., 4.], [0., 4.], [0., 2.]];
        assert_eq!(r, want);
        let open = resample_open(&[[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]], 3);
        assert_eq!(open, [[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]]);
    }

    /// Worked by hand: two parallel segments of 3 points, 1 apart, the second shifted by 2
    /// along them: a = (0,0),(2,0),(4,0); b = (2,1),(4,1),(6,1). The coupling
    /// (a0,b0),(a1,b0)?.. the best walks a_i with b_i: each pair sqrt(2^2+1) = sqrt 5.
    /// Stalling cannot help: a0 must pair with b0 (sqrt 5) and a2 with b2 (sqrt 5).
    #[test]
    fn frechet_of_shifted_segments_is_worked_by_hand() {
        let a = [[0.0, 0.0], [2.0, 0.0], [4.0, 0.0]];
        let b = [[2.0, 1.0], [4.0, 1.0], [6.0, 1.0]];
        assert!((frechet_open(&a, &b) - 5f64.sqrt()).abs() < 1e-12);
        // The same outline started elsewhere is far in Frechet's sense: the walk order matters.
        assert_eq!(frechet_closed(&SQUARE, &SQUARE), 0.0);
        assert!(frechet_closed(&SQUARE, &start_nearest(&SQUARE, [4.0, 4.0])) > 4.0);
    }

    /// A second implementation: Eiter and Mannila's recurrence, written out.
    fn eiter_mannila(a: &[Point], b: &[Point]) -> f64 {
        let mut ca = vec![vec![0.0f64; b.len()]; a.len()];
        for i in 0..a.len() {
            for j in 0..b.len() {
                let d = dist(a[i], b[j]);
                ca[i][j] = match (i, j) {
                    (0, 0) => d,
                    (0, _) => ca[0][j - 1].max(d),
                    (_, 0) => ca[i - 1][0].max(d),
                    _ => ca[i - 1][j].min(ca[i - 1][j - 1]).min(ca[i][j - 1]).max(d),
                };
            }
        }
        ca[a.len() - 1][b.len() - 1]
    }

    #[test]
    fn frechet_matches_the_recurrence_written_out() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 100.0
        };
        for n in [2usize, 3, 7, 20] {
            for m in [2usize, 5, 13] {
                let a: Vec<Point> = (0..n).map(|_| [next(), next()]).collect();
                let b: Vec<Point> = (0..m).map(|_| [next(), next()]).collect();
                let (got, want) = (frechet_open(&a, &b), eiter_mannila(&a, &b));
                assert!((got - want).abs() < 1e-9, "{n}x{m}: {got} vs {want}");
                let closed = |p: &[Point]| p.iter().chain(p.first()).copied().collect::<Vec<_>>();
                assert!((frechet_closed(&a, &b) - eiter_mannila(&closed(&a), &closed(&b))).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn simplifying_drops_collinear_vertices() {
        let poly = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
        assert_eq!(simplify_closed(&poly, 0.1), [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]);
    }
}
