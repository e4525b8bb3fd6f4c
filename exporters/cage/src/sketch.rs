//! A user's sketch (seed 004, section 5.1) and the crown outline it asks for.
//!
//! `sketch.json`: `{"version":1,"closed":true|false,"points":[[x,y],...]}` in image pixels. A
//! *closed* sketch is the crown's new outline; an *open* one oversketches part of it: the stretch
//! of the outline between the vertices nearest the stroke's ends is replaced by the stroke and the
//! joins are smoothed by Eq. 1 (Nealen et al.'s oversketching, matched by arc length).

use serde::Deserialize;
use thiserror::Error;

use crate::Point;
use crate::laplacian::LaplacianEditor;
use crate::outline::{dist, resample_closed, resample_open, signed_area2};

/// The `version` read.
pub const SKETCH_VERSION: u32 = 1;
/// Most points of a sketch.
pub const MAX_SKETCH_POINTS: usize = 65_536;
/// Vertices on each side of an oversketched stretch left free to blend the joins.
const JOIN_VERTICES: usize = 3;

/// A validated sketch.
#[derive(Debug, Clone, PartialEq)]
pub struct Sketch {
    /// A new outline (true) or a stroke over part of the outline.
    pub closed: bool,
    /// Points, image pixels (a closed sketch counter-clockwise as cages are).
    pub points: Vec<Point>,
}

/// Why a sketch was refused.
#[derive(Debug, Error)]
pub enum SketchError {
    /// Not JSON of the sketch's shape.
    #[error("not a sketch file: {0}")]
    Json(#[from] serde_json::Error),
    /// Well-formed but unusable.
    #[error("{0}")]
    Invalid(String),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSketch {
    version: u32,
    closed: bool,
    points: Vec<Point>,
}

impl Sketch {
    /// Parses and validates `sketch.json` for a `size` picture.
    pub fn from_json(text: &str, size: [u32; 2]) -> Result<Sketch, SketchError> {
        let raw: RawSketch = serde_json::from_str(text)?;
        let bad = |m: String| Err(SketchError::Invalid(m));
        if raw.version != SKETCH_VERSION {
            return bad(format!("version: {} is not {SKETCH_VERSION}", raw.version));
        }
        let min = if raw.closed { 3 } else { 2 };
        if !(min..=MAX_SKETCH_POINTS).contains(&raw.points.len()) {
            return bad(format!(
                "points: {} points; a {} sketch has {min} to {MAX_SKETCH_POINTS}",
                raw.points.len(),
                if raw.closed { "closed" } else { "open" }
            ));
        }
        let [w, h] = size.map(f64::from);
        for (k, p) in raw.points.iter().enumerate() {
            if !(p[0].is_finite() && p[1].is_finite()) || p[0] < 0.0 || p[1] < 0.0 || p[0] > w || p[1] > h {
                return bad(format!("point {k}: [{}, {}] is not a point of the {w}x{h} picture", p[0], p[1]));
            }
        }
        let mut points = raw.points;
        points.dedup();
        let length: f64 = points.windows(2).map(|p| dist(p[0], p[1])).sum();
        if length < 2.0 {
            return bad(format!("points: the stroke is {length:.1} px long; draw at least 2 px"));
        }
        if raw.closed {
            if points.len() > 1 && points.first() == points.last() {
                points.pop();
            }
            let area2 = signed_area2(&points);
            if area2.abs() < 2.0 * 16.0 {
                return bad(format!(
                    "points: the closed sketch encloses {:.1} px^2; draw a shape",
                    area2.abs() / 2.0
                ));
            }
            if area2 < 0.0 {
                points.reverse(); // either way round is fine for a sketch
            }
        }
        Ok(Sketch { closed: raw.closed, points })
    }

    /// The outline the sketch asks of `crown` (counter-clockwise, as many vertices, vertex k
    /// corresponding to the crown's vertex k).
    ///
    /// Closed: the sketch resampled by arc length to the crown's vertex count (taken as is when it
    /// already has that many points), started where the squared distances to the crown's
    /// vertices are least. Open: see the module doc.
    pub fn target_outline(&self, crown: &[Point]) -> Vec<Point> {
        let n = crown.len();
        if self.closed {
            let pts =
                if self.points.len() == n { self.points.clone() } else { resample_closed(&self.points, n) };
            // Compared about their centroids, so a moved outline keeps its correspondence.
            let (cp, cc) = (centroid(&pts), centroid(crown));
            let rel = |p: Point, c: Point| [p[0] - c[0], p[1] - c[1]];
            let cost =
                |s: usize| (0..n).map(|k| sq(rel(pts[(k + s) % n], cp), rel(crown[k], cc))).sum::<f64>();
            let best = (0..n).min_by(|&a, &b| cost(a).total_cmp(&cost(b))).unwrap_or(0);
            return (0..n).map(|k| pts[(k + best) % n]).collect();
        }
        let nearest =
            |p: Point| (0..n).min_by(|&a, &b| sq(crown[a], p).total_cmp(&sq(crown[b], p))).unwrap_or(0);
        let (first, last) = (self.points[0], *self.points.last().expect("2 points or more"));
        let (s, e) = (nearest(first), nearest(last));
        // The stretch from s to e forwards (or backwards): the one the stroke runs along.
        let forward: Vec<usize> = (0..=((e + n - s) % n)).map(|k| (s + k) % n).collect();
        let backward: Vec<usize> = (0..=((s + n - e) % n)).map(|k| (s + n - k) % n).collect();
        let fit = |idx: &[usize]| {
            let stroke = resample_open(&self.points, idx.len().max(2));
            idx.iter().zip(&stroke).map(|(&i, &p)| sq(crown[i], p)).sum::<f64>() / idx.len() as f64
        };
        let stretch = if forward.len() >= 2 && (backward.len() < 2 || fit(&forward) <= fit(&backward)) {
            forward
        } else {
            backward
        };
        if stretch.len() < 2 || stretch.len() >= n - 2 * JOIN_VERTICES {
            // The stroke spans (almost) the whole outline: it is the new outline.
            let stroke = resample_open(&self.points, n);
            let mut out = crown.to_vec();
            for (&i, p) in stretch.iter().zip(stroke) {
                out[i] = p;
            }
            return out;
        }
        let stroke = resample_open(&self.points, stretch.len());
        // Eq. 1 over the whole outline: the stretch held on the stroke, the far side held still,
        // JOIN_VERTICES on each side free to blend.
        let mut on_stroke = vec![None; n];
        for (&i, &p) in stretch.iter().zip(&stroke) {
            on_stroke[i] = Some(p);
        }
        let near_stretch = |i: usize| {
            (1..=JOIN_VERTICES)
                .any(|d| on_stroke[(i + d) % n].is_some() || on_stroke[(i + n - d) % n].is_some())
        };
        let constraints: Vec<usize> =
            (0..n).filter(|&i| on_stroke[i].is_some() || !near_stretch(i)).collect();
        let targets: Vec<Point> = constraints.iter().map(|&i| on_stroke[i].unwrap_or(crown[i])).collect();
        match LaplacianEditor::new(crown, true, &constraints, 100.0) {
            Ok(editor) => editor.solve(&targets),
            Err(_) => crown.to_vec(),
        }
    }
}

fn centroid(points: &[Point]) -> Point {
    let n = points.len().max(1) as f64;
    let s = points.iter().fold([0.0, 0.0], |s, p| [s[0] + p[0], s[1] + p[1]]);
    [s[0] / n, s[1] / n]
}

fn sq(a: Point, b: Point) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(n: usize, c: Point, r: f64) -> Vec<Point> {
        (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect()
    }

    #[test]
    fn a_closed_sketch_equal_to_the_outline_or_moved_keeps_the_correspondence() {
        let crown = circle(32, [50.0, 50.0], 20.0);
        let sketch = Sketch { closed: true, points: crown[7..].iter().chain(&crown[..7]).copied().collect() };
        assert_eq!(sketch.target_outline(&crown), crown);
        // Moved by more than a vertex spacing: vertex k still goes to vertex k moved.
        let moved: Vec<Point> = crown.iter().map(|p| [p[0] + 9.0, p[1] + 4.0]).collect();
        assert_eq!(Sketch { closed: true, points: moved.clone() }.target_outline(&crown), moved);
    }

    #[test]
    fn an_open_stroke_replaces_the_stretch_it_follows_and_leaves_the_far_side() {
        let crown = circle(64, [50.0, 50.0], 20.0);
        // A stroke pushing the right side (angles -30..30 deg) out to x = 80.
        let stroke: Vec<Point> = (0..=20).map(|k| [80.0, 40.0 + k as f64]).collect();
        let sketch = Sketch { closed: false, points: stroke };
        let out = sketch.target_outline(&crown);
        let moved: Vec<usize> = (0..64).filter(|&i| dist(out[i], crown[i]) > 0.5).collect();
        assert!(!moved.is_empty() && moved.iter().all(|&i| !(16..=48).contains(&i)), "{moved:?}");
        assert!(out.iter().any(|p| (p[0] - 80.0).abs() < 0.5), "the stroke is on the outline");
        for i in 20..=44 {
            assert!(dist(out[i], crown[i]) < 1e-3, "vertex {i} on the far side moved");
        }
    }

    #[test]
    fn bad_sketches_are_refused_by_name() {
        let e = |t: &str| Sketch::from_json(t, [100, 100]).unwrap_err().to_string();
        assert!(e(r#"{"version":1,"closed":true,"points":[[1,1],[2,2]]}"#).contains("a closed sketch has 3"));
        assert!(e(r#"{"version":1,"closed":false,"points":[[1,1],[200,2]]}"#).contains("point 1: [200, 2]"));
        assert!(e(r#"{"version":1,"closed":true,"points":[[1,1],[2,1],[2,2]]}"#).contains("encloses"));
        assert!(e(r#"{"version":3,"closed":true,"points":[]}"#).contains("version: 3"));
        assert!(e(r#"{"closed":true}"#).contains("not a sketch file"));
        let s = Sketch::from_json(
            r#"{"version":1,"closed":true,"points":[[10,10],[10,50],[50,50],[50,10],[10,10]]}"#,
            [100, 100],
        )
        .unwrap();
        assert_eq!(
            s.points,
            [[50.0, 10.0], [50.0, 50.0], [10.0, 50.0], [10.0, 10.0]],
            "closed, reversed to counter-clockwise"
        );
    }
}
