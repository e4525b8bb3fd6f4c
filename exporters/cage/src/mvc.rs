//! 2D mean value coordinates of a point with respect to a closed polygon (seed 004, section 5.3,
//! step 1: "the MVC of a point p_i inside a given cage C is a set of parameters w_ij satisfying
//! p_i = sum_j w_ij v_j").
//!
//! Floater's coordinates (2003) in the form Hormann and Floater (2006, "Mean value coordinates for
//! arbitrary planar polygons", Eq. 11) give for any polygon, convex or not, and any point of the
//! plane that is not on the boundary:
//!
//! ```text
//! s_i = v_i - x,  r_i = |s_i|,  A_i = det(s_i, s_{i+1}) / 2,  D_i = s_i . s_{i+1}
//! t_i = tan(alpha_i / 2) = (r_i r_{i+1} - D_i) / (2 A_i)
//! w_i = (t_{i-1} + t_i) / r_i,   lambda_i = w_i / sum_j w_j
//! ```
//!
//! On the boundary the coordinates are their limits: 1 at a vertex, linear along an edge. The
//! limits are taken explicitly (relative tolerances below) so the weights stay finite however
//! close the point comes to the boundary, instead of dividing by an area that underflows.

use crate::Point;

/// A point closer to a vertex than this fraction of the polygon's size is that vertex.
const AT_VERTEX_REL: f64 = 1e-12;
/// A point whose triangle with an edge has less than this fraction of `r_i r_{i+1}` as area,
/// and lies between the edge's ends, is on that edge.
const ON_EDGE_REL: f64 = 1e-12;

/// Writes the mean value coordinates of `x` with respect to the closed polygon `cage` (its last
/// vertex joins its first) into `weights` (cleared first; one per vertex, summing to 1).
///
/// The polygon needs at least 3 vertices and no two consecutive equal vertices (what
/// [`crate::CageTree`] validates); otherwise the weights are those of the nearest vertex.
pub fn mean_value_coordinates(cage: &[Point], x: Point, weights: &mut Vec<f64>) {
    weights.clear();
    let n = cage.len();
    weights.resize(n, 0.0);
    if n == 0 {
        return;
    }
    // One pass: r_i (kept in `weights` until replaced by w_i), the nearest vertex, the scale.
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut nearest = (f64::INFINITY, 0);
    for (i, v) in cage.iter().enumerate() {
        let (dx, dy) = (v[0] - x[0], v[1] - x[1]);
        let r = (dx * dx + dy * dy).sqrt();
        weights[i] = r;
        if r < nearest.0 {
            nearest = (r, i);
        }
        lo = [lo[0].min(v[0]), lo[1].min(v[1])];
        hi = [hi[0].max(v[0]), hi[1].max(v[1])];
    }
    let scale = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(f64::MIN_POSITIVE);
    if n < 3 || nearest.0 <= AT_VERTEX_REL * scale {
        weights.fill(0.0);
        weights[nearest.1] = 1.0;
        return;
    }
    // tan(alpha_i / 2) for the edge i -> i+1. Eq. 11 of Hormann and Floater has two forms,
    // (r r' - D) / det = det / (r r' + D); each is taken where it does not divide 0 by 0 (the
    // second for a point on the line of an edge but beyond its ends, alpha = 0). A point on an
    // edge (D < 0, det ~ 0) takes the linear interpolation of its ends.
    let edge = |i: usize, r: &[f64]| -> Result<f64, (usize, usize)> {
        let j = if i + 1 == n { 0 } else { i + 1 };
        let (si, sj) = (sub(cage[i], x), sub(cage[j], x));
        let (rr, d, a2) = (r[i] * r[j], dot(si, sj), det(si, sj));
        if d < 0.0 && a2.abs() <= ON_EDGE_REL * rr {
            return Err((i, j));
        }
        Ok(if d >= 0.0 { a2 / (rr + d) } else { (rr - d) / a2 })
    };
    let on_edge = |weights: &mut Vec<f64>, (i, j): (usize, usize)| {
        let (ri, rj) = (weights[i], weights[j]);
        weights.fill(0.0);
        weights[i] = rj / (ri + rj);
        weights[j] = ri / (ri + rj);
    };
    let t_last = match edge(n - 1, weights) {
        Ok(t) => t,
        Err(e) => return on_edge(weights, e),
    };
    let (mut t_prev, mut sum) = (t_last, 0.0);
    // w_i = (t_{i-1} + t_i) / r_i, written over r_i once r_i is no longer needed: edge i needs
    // r_i and r_{i+1}, both still there (r_0 is only needed by t_last, taken first).
    for i in 0..n {
        let t_i = if i + 1 == n {
            t_last
        } else {
            match edge(i, weights) {
                Ok(t) => t,
                Err(e) => return on_edge(weights, e),
            }
        };
        let w = (t_prev + t_i) / weights[i];
        weights[i] = w;
        sum += w;
        t_prev = t_i;
    }
    if sum.is_finite() && sum != 0.0 {
        let inv = 1.0 / sum;
        for w in weights.iter_mut() {
            *w *= inv;
        }
    } else {
        // Only reachable through cancellation far outside a degenerate polygon: the nearest vertex.
        weights.fill(0.0);
        weights[nearest.1] = 1.0;
    }
}

/// Most vertices [`map_point`] takes on its fast path (more take [`mean_value_coordinates`]).
const FAST_MAX: usize = 128;

/// `apply(target, mvc(cage, x))`: the point with `x`'s mean value coordinates in `cage` applied
/// to `target` (the same polygon elsewhere, one point per vertex), without storing the weights.
///
/// The same coordinates as [`mean_value_coordinates`]; away from the boundary (no vertex within
/// 1e-9 of the polygon's size, no edge nearly through `x`) they are computed in one pass over
/// arrays on the stack, with no stored weights and no branches per vertex; near it, and for polygons of more than 128
/// vertices, by [`mean_value_coordinates`] with its explicit limits. `scratch` serves the latter.
pub fn map_point(cage: &[Point], target: &[Point], x: Point, scratch: &mut Vec<f64>) -> Point {
    let n = cage.len();
    debug_assert_eq!(n, target.len());
    if !(3..=FAST_MAX).contains(&n) {
        mean_value_coordinates(cage, x, scratch);
        return apply(target, scratch);
    }
    map_fast(cage, target, x).unwrap_or_else(|| {
        mean_value_coordinates(cage, x, scratch);
        apply(target, scratch)
    })
}

/// The branch-free body of [`map_point`] for 3 to [`FAST_MAX`] vertices; `None` near the
/// boundary (or on cancellation), where the explicit limits take over.
#[inline]
fn map_fast(cage: &[Point], target: &[Point], x: Point) -> Option<Point> {
    let n = cage.len();
    let (mut sx, mut sy, mut r) = ([0.0f64; FAST_MAX + 1], [0.0f64; FAST_MAX + 1], [0.0f64; FAST_MAX + 1]);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (i, v) in cage.iter().enumerate() {
        sx[i] = v[0] - x[0];
        sy[i] = v[1] - x[1];
        r[i] = (sx[i] * sx[i] + sy[i] * sy[i]).sqrt();
        lo = [lo[0].min(v[0]), lo[1].min(v[1])];
        hi = [hi[0].max(v[0]), hi[1].max(v[1])];
    }
    (sx[n], sy[n], r[n]) = (sx[0], sy[0], r[0]);
    let scale = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let mut near = false;
    let mut t = [0.0f64; FAST_MAX + 1];
    for i in 0..n {
        let (rr, d, a2) =
            (r[i] * r[i + 1], sx[i] * sx[i + 1] + sy[i] * sy[i + 1], sx[i] * sy[i + 1] - sy[i] * sx[i + 1]);
        // Eq. 11 in whichever of its two forms does not divide 0 by 0 (see above).
        let pos = d >= 0.0;
        let (num, den) = if pos { (a2, rr + d) } else { (rr - d, a2) };
        t[i + 1] = num / den;
        near |= (!pos) & (a2.abs() <= 1e-9 * rr);
        near |= r[i] <= 1e-9 * scale;
    }
    t[0] = t[n];
    if near {
        return None;
    }
    // t[i + 1] is edge i's; w_i = (t_{i-1} + t_i) / r_i.
    let (mut sum, mut px, mut py) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let w = (t[i] + t[i + 1]) / r[i];
        sum += w;
        px += w * target[i][0];
        py += w * target[i][1];
    }
    (sum.is_finite() && sum != 0.0).then(|| [px / sum, py / sum])
}

/// The point with coordinates `weights` with respect to `cage`: `sum_j w_j v_j` (step 1: a finer
/// cage's vertex follows its parent's moved vertices).
pub fn apply(cage: &[Point], weights: &[f64]) -> Point {
    let mut p = [0.0, 0.0];
    for (v, w) in cage.iter().zip(weights) {
        p[0] += w * v[0];
        p[1] += w * v[1];
    }
    p
}

fn sub(a: Point, b: Point) -> Point {
    [a[0] - b[0], a[1] - b[1]]
}
fn dot(a: Point, b: Point) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}
fn det(a: Point, b: Point) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn coords(cage: &[Point], x: Point) -> Vec<f64> {
        let mut w = Vec::new();
        mean_value_coordinates(cage, x, &mut w);
        w
    }

    const SQUARE: [Point; 4] = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
    /// An L: not convex, with a reflex vertex at (1, 1).
    const ELL: [Point; 6] = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]];

    #[test]
    fn the_centre_of_a_square_weighs_each_corner_a_quarter() {
        for w in coords(&SQUARE, [1.0, 1.0]) {
            assert!((w - 0.25).abs() < 1e-15, "{w}");
        }
    }

    /// Floater's definition, evaluated from angles rather than Eq. 11:
    /// w_i = (tan(alpha_{i-1}/2) + tan(alpha_i/2)) / |v_i - x|, alpha_i the angle at x between
    /// v_i and v_{i+1} (atan2 of the two directions).
    fn floater_by_angles(cage: &[Point], x: Point) -> Vec<f64> {
        let n = cage.len();
        let angle = |i: usize| {
            let (a, b) = (cage[i], cage[(i + 1) % n]);
            let (aa, ab) = ((a[1] - x[1]).atan2(a[0] - x[0]), (b[1] - x[1]).atan2(b[0] - x[0]));
            let mut d = ab - aa;
            while d > std::f64::consts::PI {
                d -= std::f64::consts::TAU;
            }
            while d < -std::f64::consts::PI {
                d += std::f64::consts::TAU;
            }
            d
        };
        let raw: Vec<f64> = (0..n)
            .map(|i| {
                let r = (cage[i][0] - x[0]).hypot(cage[i][1] - x[1]);
                ((angle((i + n - 1) % n) / 2.0).tan() + (angle(i) / 2.0).tan()) / r
            })
            .collect();
        let sum: f64 = raw.iter().sum();
        raw.iter().map(|w| w / sum).collect()
    }

    #[test]
    fn points_inside_and_outside_match_floaters_angle_definition() {
        for (cage, x) in [
            (&SQUARE[..], [0.5, 0.5]),
            (&SQUARE[..], [1.9, 0.3]),
            (&ELL[..], [0.5, 1.5]),
            (&ELL[..], [1.5, 0.5]),
            (&ELL[..], [1.6, 1.7]), // outside, in the L's notch
            (&ELL[..], [-3.0, 5.0]),
            (&ELL[..], [0.5, 1.0]),    // inside, on the line of the edge (2,1)-(1,1)
            (&SQUARE[..], [3.0, 0.0]), // outside, on the line of the edge (0,0)-(2,0)
            (&SQUARE[..], [1.0, -4.0]),
        ] {
            let (w, want) = (coords(cage, x), floater_by_angles(cage, x));
            for (got, want) in w.iter().zip(&want) {
                assert!((got - want).abs() < 1e-12, "{x:?}: {w:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn at_a_vertex_the_weight_is_that_vertex_and_on_an_edge_linear() {
        assert_eq!(coords(&ELL, [1.0, 1.0]), [0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        let w = coords(&ELL, [1.5, 1.0]);
        assert_eq!(w, [0.0, 0.0, 0.5, 0.5, 0.0, 0.0]);
        let w = coords(&SQUARE, [0.5, 0.0]);
        assert_eq!(w, [0.75, 0.25, 0.0, 0.0]);
    }

    #[test]
    fn weights_stay_finite_and_tend_to_the_edge_as_the_point_approaches_it() {
        for k in 1..=300 {
            let eps = 10f64.powi(-k);
            let w = coords(&ELL, [0.5, eps]);
            assert!(w.iter().all(|w| w.is_finite()), "{eps}: {w:?}");
            let p = apply(&ELL, &w);
            assert!((p[0] - 0.5).abs() < 1e-9 && (p[1] - eps).abs() < 1e-9, "{eps}: {p:?}");
            if k > 8 {
                assert!((w[0] - 0.75).abs() < 1e-6 && (w[1] - 0.25).abs() < 1e-6, "{eps}: {w:?}");
            }
        }
    }

    fn star(n: usize, seed: &[f64]) -> Vec<Point> {
        // A star-shaped polygon around (0, 0) with radii from `seed`: often not convex.
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                let r = 1.0 + 2.0 * seed[i % seed.len()];
                [r * a.cos(), r * a.sin()]
            })
            .collect()
    }

    proptest! {
        /// Partition of unity and linear reproduction (p = sum w_j v_j, so every linear
        /// function is reproduced), inside and outside a non-convex polygon.
        #[test]
        fn weights_sum_to_one_and_reproduce_the_point(
            n in 3usize..40,
            seed in prop::collection::vec(0.0f64..1.0, 1..40),
            x in -4.0f64..4.0, y in -4.0f64..4.0,
        ) {
            let cage = star(n, &seed);
            let w = coords(&cage, [x, y]);
            let sum: f64 = w.iter().sum();
            prop_assert!((sum - 1.0).abs() < 1e-9, "sum {}", sum);
            let p = apply(&cage, &w);
            prop_assert!((p[0] - x).abs() < 1e-7 && (p[1] - y).abs() < 1e-7, "{:?} vs {:?}", p, (x, y));
        }

        /// Moving the cage by an affine map moves the point by the same map.
        #[test]
        fn an_affine_map_of_the_cage_maps_the_point(
            n in 3usize..24,
            seed in prop::collection::vec(0.0f64..1.0, 1..24),
            x in -0.9f64..0.9, y in -0.9f64..0.9,
            m in prop::array::uniform4(-2.0f64..2.0), t in prop::array::uniform2(-50.0f64..50.0),
        ) {
            let cage = star(n, &seed);
            let w = coords(&cage, [x, y]);
            let f = |p: Point| [m[0] * p[0] + m[1] * p[1] + t[0], m[2] * p[0] + m[3] * p[1] + t[1]];
            let moved: Vec<Point> = cage.iter().map(|&v| f(v)).collect();
            let (got, want) = (apply(&moved, &w), f([x, y]));
            prop_assert!((got[0] - want[0]).abs() < 1e-7 && (got[1] - want[1]).abs() < 1e-7);
        }

        /// The one-pass `map_point` gives the point the stored weights give, inside, outside,
        /// on vertices and on edges (where it hands over to the explicit limits).
        #[test]
        fn map_point_equals_applying_the_weights(
            n in 3usize..140,
            seed in prop::collection::vec(0.0f64..1.0, 1..24),
            x in -1.2f64..1.2, y in -1.2f64..1.2,
            on in 0usize..3, k in 0usize..1000, u in 0.0f64..1.0,
        ) {
            let cage = star(n, &seed);
            let target: Vec<Point> = cage.iter().map(|v| [3.0 * v[0] - v[1] + 7.0, v[0] * v[1] + 2.0 * v[1]]).collect();
            let (a, b) = (cage[k % n], cage[(k + 1) % n]);
            let p = match on {
                0 => [x, y],
                1 => a,
                _ => [a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1])],
            };
            let want = apply(&target, &coords(&cage, p));
            let got = map_point(&cage, &target, p, &mut Vec::new());
            prop_assert!((got[0] - want[0]).abs() < 1e-9 && (got[1] - want[1]).abs() < 1e-9, "{got:?} {want:?}");
        }
    }
}
