//! The multiscale cage tree (seed 004, section 5.2) and its file, `cage.json`.
//!
//! Nodes are closed outlines (cages); an edge joins a coarser cage to a finer one inside it. A
//! *leaf* cage moves content (pixels, branches); an *internal* cage only moves its children, whose
//! vertices it carries by mean value coordinates. Transformations flow only downwards.
//!
//! ```json
//! {"version": 1, "size": [w, h],
//!  "cages": [{"id": 0, "parent": null, "kind": "internal", "vertices": [[x, y], ...]},
//!            {"id": 1, "parent": 0, "kind": "leaf", "vertices": [[x, y], ...]}]}
//! ```
//!
//! Coordinates are image pixels (x right, y down, the picture spans `[0, w] x [0, h]`). Vertices
//! run counter-clockwise in those coordinates as written, i.e. the shoelace sum
//! `sum x_i y_{i+1} - x_{i+1} y_i` is positive (what `geo` and `shapely` call counter-clockwise;
//! on a y-down screen it looks clockwise). A file is validated on read and every problem is
//! reported at once, naming the cage and the vertex.

use std::collections::HashMap;

use geo::{Polygon, Validation};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::Point;
use crate::outline::{signed_area2, to_line_string};

/// The `version` this crate reads and writes.
pub const CAGE_FILE_VERSION: u32 = 1;
/// Largest image side, pixels.
pub const MAX_SIDE_PX: u32 = 16_384;
/// Most cages in a tree.
pub const MAX_CAGES: usize = 4096;
/// Most vertices of one cage.
pub const MAX_CAGE_VERTICES: usize = 1024;
/// Most vertices of all cages together.
pub const MAX_TOTAL_VERTICES: usize = 262_144;
/// How far a child's vertex may lie outside its parent, pixels.
pub const INSIDE_TOLERANCE_PX: f64 = 1.0;
/// Most problems listed before the rest are counted.
const MAX_PROBLEMS: usize = 50;

/// What a cage moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CageKind {
    /// Carries finer cages only (a crown or a lobe's outer silhouette).
    Internal,
    /// Moves content directly (an inner lobe).
    Leaf,
}

/// One cage of a validated tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Cage {
    /// Its id in the file.
    pub id: u32,
    /// Index of its parent in [`CageTree::cages`].
    pub parent: Option<usize>,
    /// Internal or leaf.
    pub kind: CageKind,
    /// Counter-clockwise outline, image pixels.
    pub vertices: Vec<Point>,
    /// Indices of its children in [`CageTree::cages`].
    pub children: Vec<usize>,
}

/// A validated multiscale cage tree.
#[derive(Debug, Clone, PartialEq)]
pub struct CageTree {
    /// Picture size, pixels.
    pub size: [u32; 2],
    /// Cages, parents before their children.
    pub cages: Vec<Cage>,
}

/// Why a cage file was refused.
#[derive(Debug, Error)]
pub enum CageError {
    /// Not JSON of the cage file's shape.
    #[error("not a cage file: {0}")]
    Json(#[from] serde_json::Error),
    /// Well-formed but wrong: every problem found.
    #[error("{} problem{} in the cage file:\n  {}", .0.len(), if .0.len() == 1 { "" } else { "s" }, .0.join("\n  "))]
    Invalid(Vec<String>),
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTree {
    version: u32,
    size: [u32; 2],
    cages: Vec<RawCage>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCage {
    id: u32,
    parent: Option<u32>,
    kind: CageKind,
    vertices: Vec<Point>,
}

impl CageTree {
    /// Parses and validates a `cage.json` text.
    pub fn from_json(text: &str) -> Result<CageTree, CageError> {
        let raw: RawTree = serde_json::from_str(text)?;
        validate(raw)
    }

    /// The `cage.json` text of this tree: one cage per line, coordinates to 1/100 px.
    pub fn to_json(&self) -> String {
        let mut out = format!(
            "{{\"version\":{CAGE_FILE_VERSION},\"size\":[{},{}],\"cages\":[\n",
            self.size[0], self.size[1]
        );
        for (i, c) in self.cages.iter().enumerate() {
            let raw = RawCage {
                id: c.id,
                parent: c.parent.map(|p| self.cages[p].id),
                kind: c.kind,
                vertices: c.vertices.iter().map(|v| v.map(|x| (x * 100.0).round() / 100.0)).collect(),
            };
            out.push_str(&serde_json::to_string(&raw).expect("a cage serialises"));
            out.push_str(if i + 1 < self.cages.len() { ",\n" } else { "\n" });
        }
        out.push_str("]}\n");
        out
    }

    /// Builds a tree from cages given as (id, parent id, kind, vertices), validating it as a
    /// file would be.
    pub fn from_parts(
        size: [u32; 2],
        cages: impl IntoIterator<Item = (u32, Option<u32>, CageKind, Vec<Point>)>,
    ) -> Result<CageTree, CageError> {
        let cages = cages
            .into_iter()
            .map(|(id, parent, kind, vertices)| RawCage { id, parent, kind, vertices })
            .collect();
        validate(RawTree { version: CAGE_FILE_VERSION, size, cages })
    }

    /// The index of the cage with file id `id`.
    pub fn index_of(&self, id: u32) -> Option<usize> {
        self.cages.iter().position(|c| c.id == id)
    }

    /// Indices of the root cages (crowns).
    pub fn roots(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.cages.len()).filter(|&i| self.cages[i].parent.is_none())
    }

    /// Depth of cage `i` (a root is 0).
    pub fn depth(&self, mut i: usize) -> usize {
        let mut d = 0;
        while let Some(p) = self.cages[i].parent {
            d += 1;
            i = p;
        }
        d
    }
}

/// The tree a file describes, or every problem with it (at most [`MAX_PROBLEMS`] listed):
/// limits first, then ids and parents, then each cage's kind and outline.
fn validate(raw: RawTree) -> Result<CageTree, CageError> {
    let mut problems = Vec::new();
    if !check_limits(&raw, &mut problems) {
        return Err(CageError::Invalid(problems));
    }
    let by_id = index_ids(&raw.cages, &mut problems);
    check_parents(&raw.cages, &by_id, &mut problems);
    let children = children_of(&raw.cages, &by_id);
    for (i, kids) in children.iter().enumerate() {
        check_cage(&raw, i, &by_id, kids, &mut problems);
    }
    if !problems.is_empty() {
        if problems.len() > MAX_PROBLEMS {
            let more = problems.len() - MAX_PROBLEMS;
            problems.truncate(MAX_PROBLEMS);
            problems.push(format!("... and {more} more"));
        }
        return Err(CageError::Invalid(problems));
    }
    Ok(in_tree_order(raw, &by_id, &children))
}

/// The version, the picture's size and the counts; `false` when the cages are too many (or
/// none) to look at one by one.
fn check_limits(raw: &RawTree, problems: &mut Vec<String>) -> bool {
    if raw.version != CAGE_FILE_VERSION {
        problems.push(format!(
            "version: {} is not {CAGE_FILE_VERSION}, the version this frond reads",
            raw.version
        ));
    }
    let [w, h] = raw.size;
    for (name, v) in [("size[0] (width)", w), ("size[1] (height)", h)] {
        if !(1..=MAX_SIDE_PX).contains(&v) {
            problems.push(format!("{name}: {v} px is outside 1..={MAX_SIDE_PX}"));
        }
    }
    if raw.cages.is_empty() || raw.cages.len() > MAX_CAGES {
        problems.push(format!("cages: {} cages; a tree has 1 to {MAX_CAGES}", raw.cages.len()));
        return false;
    }
    let total: usize = raw.cages.iter().map(|c| c.vertices.len()).sum();
    if total > MAX_TOTAL_VERTICES {
        problems.push(format!("cages: {total} vertices in all; at most {MAX_TOTAL_VERTICES}"));
        return false;
    }
    true
}

/// How a problem names cage `i`: its place in the file and its id.
fn cage_name(i: usize, c: &RawCage) -> String {
    format!("cages[{i}] (id {})", c.id)
}

/// Each id's index in the file (the first, for an id given twice, which is a problem).
fn index_ids(cages: &[RawCage], problems: &mut Vec<String>) -> HashMap<u32, usize> {
    let mut by_id = HashMap::new();
    for (i, c) in cages.iter().enumerate() {
        if let Some(first) = by_id.insert(c.id, i) {
            problems.push(format!("{}: id {} is already cages[{first}]'s", cage_name(i, c), c.id));
        }
    }
    by_id
}

/// The index of `c`'s parent, if it names an existing cage.
fn parent_index(by_id: &HashMap<u32, usize>, c: &RawCage) -> Option<usize> {
    c.parent.and_then(|p| by_id.get(&p).copied())
}

/// Parents: existing, and no cycles.
fn check_parents(cages: &[RawCage], by_id: &HashMap<u32, usize>, problems: &mut Vec<String>) {
    for (i, c) in cages.iter().enumerate() {
        match c.parent {
            Some(p) if p == c.id => {
                problems.push(format!("{}: parent: a cage cannot be its own parent", cage_name(i, c)))
            }
            Some(p) if !by_id.contains_key(&p) => {
                problems.push(format!("{}: parent: no cage has id {p}", cage_name(i, c)))
            }
            _ => {}
        }
        let (mut at, mut steps) = (i, 0);
        while let Some(p) = parent_index(by_id, &cages[at]) {
            steps += 1;
            if p == i || steps > cages.len() {
                problems.push(format!("{}: parent: the parents loop back to this cage", cage_name(i, c)));
                break;
            }
            at = p;
        }
    }
}

/// Each cage's children's indices, in file order.
fn children_of(cages: &[RawCage], by_id: &HashMap<u32, usize>) -> Vec<Vec<usize>> {
    let mut children = vec![Vec::new(); cages.len()];
    for (i, c) in cages.iter().enumerate() {
        if let Some(p) = parent_index(by_id, c)
            && p != i
        {
            children[p].push(i);
        }
    }
    children
}

/// Cage `i` on its own: its kind against its children, its vertices (count, finite, inside the
/// picture, none repeated), its winding, a simple outline, and inside its parent.
fn check_cage(
    raw: &RawTree,
    i: usize,
    by_id: &HashMap<u32, usize>,
    children: &[usize],
    problems: &mut Vec<String>,
) {
    let c = &raw.cages[i];
    let [w, h] = raw.size;
    let n = c.vertices.len();
    match (c.kind, children.is_empty()) {
        (CageKind::Leaf, false) => problems.push(format!(
            "{}: kind: a leaf cage has no children, this one has {}",
            cage_name(i, c),
            children.len()
        )),
        (CageKind::Internal, true) => problems.push(format!(
            "{}: kind: an internal cage carries children, this one has none (make it a leaf)",
            cage_name(i, c)
        )),
        _ => {}
    }
    if !(3..=MAX_CAGE_VERTICES).contains(&n) {
        problems.push(format!(
            "{}: vertices: {n} vertices; a cage has 3 to {MAX_CAGE_VERTICES}",
            cage_name(i, c)
        ));
        return;
    }
    let mut shape_ok = true;
    for (k, v) in c.vertices.iter().enumerate() {
        if !(v[0].is_finite() && v[1].is_finite()) {
            problems.push(format!(
                "{} vertex {k}: [{}, {}] is not a finite point",
                cage_name(i, c),
                v[0],
                v[1]
            ));
            shape_ok = false;
        } else if v[0] < 0.0 || v[1] < 0.0 || v[0] > f64::from(w) || v[1] > f64::from(h) {
            problems.push(format!(
                "{} vertex {k}: [{}, {}] lies outside the {w}x{h} picture",
                cage_name(i, c),
                v[0],
                v[1]
            ));
        }
        if *v == c.vertices[(k + 1) % n] {
            problems.push(format!("{} vertex {k}: repeats the next vertex", cage_name(i, c)));
            shape_ok = false;
        }
    }
    if !shape_ok {
        return;
    }
    let area2 = signed_area2(&c.vertices);
    if area2 <= 0.0 {
        problems.push(format!(
            "{}: vertices run clockwise (signed area {:.1} px^2); cages run counter-clockwise \
             in image coordinates as written: reverse them",
            cage_name(i, c),
            area2 / 2.0
        ));
    } else if !Polygon::new(to_line_string(&c.vertices, true), Vec::new()).is_valid() {
        problems.push(format!("{}: vertices: the outline crosses itself", cage_name(i, c)));
    }
    if let Some(p) = parent_index(by_id, c)
        && p != i
        && (3..=MAX_CAGE_VERTICES).contains(&raw.cages[p].vertices.len())
    {
        let parent = &raw.cages[p].vertices;
        if let Some(k) = c.vertices.iter().position(|&v| outside_by(parent, v) > INSIDE_TOLERANCE_PX) {
            problems.push(format!(
                "{} vertex {k}: [{}, {}] lies outside its parent cage id {} (by more than {INSIDE_TOLERANCE_PX} px)",
                cage_name(i, c),
                c.vertices[k][0],
                c.vertices[k][1],
                raw.cages[p].id
            ));
        }
    }
}

/// The valid tree with parents before children (breadth first from the roots), ids kept and
/// parent and child links turned into indices of the new order.
fn in_tree_order(raw: RawTree, by_id: &HashMap<u32, usize>, children: &[Vec<usize>]) -> CageTree {
    let mut order: Vec<usize> = (0..raw.cages.len()).filter(|&i| raw.cages[i].parent.is_none()).collect();
    let mut k = 0;
    while k < order.len() {
        order.extend(children[order[k]].iter().copied());
        k += 1;
    }
    let mut new_index = vec![0; raw.cages.len()];
    for (new, &old) in order.iter().enumerate() {
        new_index[old] = new;
    }
    let mut slots: Vec<Option<RawCage>> = raw.cages.into_iter().map(Some).collect();
    let cages = order
        .iter()
        .map(|&old| {
            let c = slots[old].take().expect("each cage once");
            Cage {
                id: c.id,
                parent: c.parent.map(|p| new_index[by_id[&p]]),
                kind: c.kind,
                vertices: c.vertices,
                children: children[old].iter().map(|&j| new_index[j]).collect(),
            }
        })
        .collect();
    CageTree { size: raw.size, cages }
}

/// 0 when `p` is inside the closed polygon (or on it), else its distance to the outline.
pub fn outside_by(poly: &[Point], p: Point) -> f64 {
    if contains(poly, p) {
        return 0.0;
    }
    let n = poly.len();
    (0..n).map(|i| segment_distance2(poly[i], poly[(i + 1) % n], p)).fold(f64::INFINITY, f64::min).sqrt()
}

/// Even-odd point-in-polygon test.
pub fn contains(poly: &[Point], p: Point) -> bool {
    let n = poly.len();
    let mut inside = false;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// Distance from `p` to the segment `a`-`b`.
pub fn segment_distance(a: Point, b: Point, p: Point) -> f64 {
    segment_distance2(a, b, p).sqrt()
}

/// The square of [`segment_distance`] (no square root: for comparisons in hot loops).
pub fn segment_distance2(a: Point, b: Point, p: Point) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
    let (ex, ey) = (p[0] - a[0] - t * dx, p[1] - a[1] - t * dy);
    ex * ex + ey * ey
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"{"version":1,"size":[100,80],"cages":[
        {"id":7,"parent":null,"kind":"internal","vertices":[[10,10],[90,10],[90,70],[10,70]]},
        {"id":3,"parent":7,"kind":"leaf","vertices":[[20,20],[50,20],[50,60],[20,60]]},
        {"id":4,"parent":7,"kind":"leaf","vertices":[[55,20],[85,20],[70,60]]}]}"#;

    #[test]
    fn a_good_file_reads_parents_first_and_round_trips() {
        let t = CageTree::from_json(GOOD).unwrap();
        assert_eq!(t.cages.iter().map(|c| c.id).collect::<Vec<_>>(), [7, 3, 4]);
        assert_eq!((t.cages[1].parent, t.cages[0].children.clone()), (Some(0), vec![1, 2]));
        assert_eq!(t.depth(2), 1);
        assert_eq!(CageTree::from_json(&t.to_json()).unwrap(), t);
    }

    fn problems(text: &str) -> Vec<String> {
        match CageTree::from_json(text) {
            Err(CageError::Invalid(p)) => p,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn every_problem_is_named_with_its_cage_and_vertex() {
        let bad = r#"{"version":2,"size":[100,0],"cages":[
            {"id":1,"parent":null,"kind":"internal","vertices":[[10,10],[10,70],[90,70],[90,10]]},
            {"id":2,"parent":1,"kind":"leaf","vertices":[[20,20],[95,20],[20,60]]},
            {"id":3,"parent":9,"kind":"leaf","vertices":[[0,0],[1,1]]},
            {"id":4,"parent":2,"kind":"leaf","vertices":[[0,0],[10,0],[10,10],[0,10],[6,-2]]},
            {"id":5,"parent":null,"kind":"leaf","vertices":[[0,0],[4,0],[4,0],[0,4]]}]}"#;
        let p = problems(bad);
        let want = [
            "version: 2 is not 1",
            "size[1] (height): 0 px",
            "cages[2] (id 3): parent: no cage has id 9",
            "cages[1] (id 2): kind: a leaf cage has no children, this one has 1",
            "cages[0] (id 1): vertices run clockwise",
            "cages[1] (id 2) vertex 1: [95, 20] lies outside the 100x0 picture",
            "cages[2] (id 3): vertices: 2 vertices",
            "cages[3] (id 4): vertices: the outline crosses itself",
            "cages[4] (id 5) vertex 1: repeats the next vertex",
        ];
        for w in want {
            assert!(p.iter().any(|l| l.starts_with(w)), "missing {w:?} in {p:#?}");
        }
    }

    #[test]
    fn a_child_outside_its_parent_and_a_parent_loop_are_refused() {
        let outside = GOOD.replace("[70,60]", "[70,75]");
        let p = problems(&outside);
        assert!(
            p[0].starts_with("cages[2] (id 4) vertex 2: [70, 75] lies outside its parent cage id 7"),
            "{p:?}"
        );
        let looped = r#"{"version":1,"size":[10,10],"cages":[
            {"id":1,"parent":2,"kind":"internal","vertices":[[1,1],[9,1],[9,9]]},
            {"id":2,"parent":1,"kind":"internal","vertices":[[2,2],[8,2],[8,8]]}]}"#;
        let p = problems(looped);
        assert!(p.iter().any(|l| l.contains("parents loop back")), "{p:?}");
        assert!(matches!(CageTree::from_json("{\"version\":1}"), Err(CageError::Json(_))));
        assert!(matches!(CageTree::from_json(&GOOD.replace("\"kind\"", "\"knd\"")), Err(CageError::Json(_))));
    }
}
