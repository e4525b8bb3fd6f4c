//! Every shipped rig's mesh (`rig-files/plants/*.toml`) against the Appendix's height rule and
//! Eq. 1 of seed 000, both written out here in `f64` without frond's skeleton module:
//!
//! - each vertex's weights are the documented height rule at its height in the rest pose (after
//!   the vertex is placed, e.g. a leaf at its branch tip), over the main skeleton's joint heights
//!   for stem vertices and over the element's own evenly spaced skeleton for element vertices;
//! - vertices that touch at rest stay together at a strongly bent pose (no tearing), measured
//!   with a separate forward kinematics and linear blend skinning.

use std::path::{Path, PathBuf};

use frond_formats::rig_toml::RigText;
use frond_motion::Rig;
use frond_motion::mesh::{PlantModel, procedural_model};
use frond_motion::rig::MeshSpec;

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

/// A rigid transform: `p -> r p + t`.
#[derive(Clone, Copy)]
struct Rigid {
    r: M3,
    t: V3,
}

fn mul3(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn apply3(a: &M3, v: V3) -> V3 {
    std::array::from_fn(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn dist(a: V3, b: V3) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl Rigid {
    const ID: Rigid = Rigid { r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], t: [0.0; 3] };

    fn then(&self, inner: &Rigid) -> Rigid {
        Rigid { r: mul3(&self.r, &inner.r), t: add(apply3(&self.r, inner.t), self.t) }
    }

    fn apply(&self, v: V3) -> V3 {
        add(apply3(&self.r, v), self.t)
    }

    fn translation(t: V3) -> Rigid {
        Rigid { t, ..Rigid::ID }
    }
}

/// The convention in docs/mapping.md: pitch about local +X, yaw about +Z, roll about +Y,
/// `R = R_yaw R_pitch R_roll`.
fn joint_rotation([pitch, yaw, roll]: [f64; 3]) -> M3 {
    let (p, y, r) = (pitch.to_radians(), yaw.to_radians(), roll.to_radians());
    let rx = [[1.0, 0.0, 0.0], [0.0, p.cos(), -p.sin()], [0.0, p.sin(), p.cos()]];
    let rz = [[y.cos(), -y.sin(), 0.0], [y.sin(), y.cos(), 0.0], [0.0, 0.0, 1.0]];
    let ry = [[r.cos(), 0.0, r.sin()], [0.0, 1.0, 0.0], [-r.sin(), 0.0, r.cos()]];
    mul3(&rz, &mul3(&rx, &ry))
}

/// A unit quaternion `[x, y, z, w]` as a matrix.
fn quat_matrix([x, y, z, w]: [f64; 4]) -> M3 {
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// Joint world transforms: joint `i` sits `h_i - h_(i-1)` above its parent along the parent's
/// +Y and rotates by its pose; joint 0's parent is the ground frame.
fn world(heights: [f64; 4], pose: &[[f64; 3]; 4]) -> [Rigid; 4] {
    let mut out = [Rigid::ID; 4];
    let mut parent = Rigid::ID;
    let mut below = 0.0;
    for i in 0..4 {
        let local = Rigid { r: joint_rotation(pose[i]), t: [0.0, heights[i] - below, 0.0] };
        parent = parent.then(&local);
        below = heights[i];
        out[i] = parent;
    }
    out
}

/// Seed 000, Eq. 1: `v' = sum_i w_i M_i v` with `M_i = world_i * bind_i^-1`.
fn skin(heights: [f64; 4], pose: &[[f64; 3]; 4], w: [f64; 4], v: V3) -> V3 {
    let joints = world(heights, pose);
    let mut out = [0.0; 3];
    for i in 0..4 {
        let m = joints[i].then(&Rigid::translation([0.0, -heights[i], 0.0]));
        let p = m.apply(v);
        for c in 0..3 {
            out[c] += w[i] * p[c];
        }
    }
    out
}

/// The documented height rule (docs/mapping.md, "Rotation convention"; seed 000 Appendix made clean):
/// at or below joint 0 joint 0 only, between two joint heights a linear blend of those two, at
/// or above the top joint the top joint only.
fn height_rule(h: [f64; 4], y: f64) -> [f64; 4] {
    if y <= h[0] {
        return [1.0, 0.0, 0.0, 0.0];
    }
    if y >= h[3] {
        return [0.0, 0.0, 0.0, 1.0];
    }
    let mut w = [0.0; 4];
    let i = (0..3).find(|&i| y < h[i + 1]).unwrap();
    let t = (y - h[i]) / (h[i + 1] - h[i]);
    w[i] = 1.0 - t;
    w[i + 1] = t;
    w
}

fn rig_files() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rig-files/plants");
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    assert!(v.len() >= 3, "{v:?}");
    v
}

fn model(path: &Path) -> (Rig, PlantModel) {
    let rig = Rig::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    assert!(
        matches!(rig.mesh, MeshSpec::Procedural { .. }),
        "{}: a file mesh; extend this test to read it",
        path.display()
    );
    let m = procedural_model(&rig).unwrap();
    (rig, m)
}

fn f64s<const N: usize>(a: [f32; N]) -> [f64; N] {
    a.map(f64::from)
}

/// Every vertex of a plant: rest position, posed position (own Eq. 1), label for messages.
fn vertices(
    rig: &Rig,
    m: &PlantModel,
    stem_pose: &[[f64; 3]; 4],
    leaf_pose: &[[f64; 3]; 4],
) -> Vec<(V3, V3, String)> {
    let heights: [f64; 4] = std::array::from_fn(|i| rig.joints[i].height_m as f64);
    let rest_pose = [[0.0; 3]; 4];
    let mut out = Vec::new();
    for (k, (p, w)) in m.stem.positions.iter().zip(&m.stem.weights).enumerate() {
        let v = f64s(*p);
        out.push((v, skin(heights, stem_pose, f64s(*w), v), format!("stem vertex {k} at {p:?}")));
    }
    for e in &m.elements {
        let spec = &rig.elements[e.element];
        let eh: [f64; 4] = std::array::from_fn(|i| spec.length_m as f64 * i as f64 / 4.0);
        let attach = Rigid { r: quat_matrix(f64s(e.rotation)), t: f64s(e.offset_m) };
        let j = spec.attach_joint as usize;
        let rest_outer = world(heights, &rest_pose)[j].then(&attach);
        let bent_outer = world(heights, stem_pose)[j].then(&attach);
        for (k, (p, w)) in e.mesh.positions.iter().zip(&e.mesh.weights).enumerate() {
            let v = f64s(*p);
            out.push((
                rest_outer.apply(v),
                bent_outer.apply(skin(eh, leaf_pose, f64s(*w), v)),
                format!("{} {} vertex {k}", e.name, e.instance),
            ));
        }
    }
    out
}

#[test]
fn every_vertex_is_weighted_by_the_height_rule_at_its_rest_height() {
    for path in rig_files() {
        let (rig, m) = model(&path);
        let heights: [f64; 4] = std::array::from_fn(|i| rig.joints[i].height_m as f64);
        let mut above_top = 0;
        for (k, (p, w)) in m.stem.positions.iter().zip(&m.stem.weights).enumerate() {
            let want = height_rule(heights, p[1] as f64);
            let ok = (0..4).all(|i| (w[i] as f64 - want[i]).abs() < 1e-5);
            assert!(
                ok,
                "{}: stem vertex {k} at {p:?} has weights {w:?}, the height rule gives {want:?}",
                rig.name
            );
            above_top += usize::from(p[1] as f64 >= heights[3]);
        }
        assert!(above_top > 0, "{}: nothing above the top joint", rig.name);
        for e in &m.elements {
            let length = rig.elements[e.element].length_m as f64;
            let eh: [f64; 4] = std::array::from_fn(|i| length * i as f64 / 4.0);
            for (k, (p, w)) in e.mesh.positions.iter().zip(&e.mesh.weights).enumerate() {
                let want = height_rule(eh, p[1] as f64);
                let ok = (0..4).all(|i| (w[i] as f64 - want[i]).abs() < 1e-5);
                assert!(ok, "{}: {} vertex {k} at {p:?}: {w:?} vs {want:?}", rig.name, e.name);
            }
        }
    }
}

/// A strong bend in every joint, with twist.
const BENT: [[f64; 3]; 4] = [[55.0, 30.0, 0.0], [45.0, -35.0, 25.0], [50.0, 40.0, -30.0], [60.0, 25.0, 40.0]];
const LEAF_BENT: [[f64; 3]; 4] =
    [[35.0, 15.0, 0.0], [40.0, -20.0, 20.0], [30.0, 25.0, 10.0], [25.0, -30.0, 0.0]];

/// Vertices at most this far apart at rest are "touching" (a leaf's base and the branch tip
/// it hangs from are 3.75 mm apart in the shrub) ...
const TOUCH_M: f64 = 0.005;
/// ... and may move apart by at most this much at the bent pose. Linear blend skinning stretches
/// a little where weights change (2.8 mm at the shrub's fork); torn leaves moved 92 cm.
const STRETCH_M: f64 = 0.004;

#[test]
fn touching_vertices_stay_together_at_a_strongly_bent_pose() {
    for path in rig_files() {
        let (rig, m) = model(&path);
        let v = vertices(&rig, &m, &BENT, &LEAF_BENT);
        // Sanity of the independent skinning: at rest it reproduces the rest positions.
        for (rest, posed, what) in vertices(&rig, &m, &[[0.0; 3]; 4], &[[0.0; 3]; 4]) {
            assert!(dist(rest, posed) < 1e-6, "{}: {what} moves at rest", rig.name);
        }
        let mut pairs = 0usize;
        let mut worst = (0.0f64, 0.0f64, 0.0f64, String::new());
        for a in 0..v.len() {
            for b in a + 1..v.len() {
                let rest = dist(v[a].0, v[b].0);
                if rest > TOUCH_M {
                    continue;
                }
                pairs += 1;
                let bent = dist(v[a].1, v[b].1);
                if bent - rest > worst.0 {
                    worst = (bent - rest, rest, bent, format!("{} and {}", v[a].2, v[b].2));
                }
            }
        }
        assert!(pairs > 0, "{}: no touching vertices", rig.name);
        assert!(
            worst.0 <= STRETCH_M,
            "{}: {} are {:.1} mm apart at rest but {:.1} mm apart at the bent pose ({pairs} touching pairs)",
            rig.name,
            worst.3,
            worst.1 * 1e3,
            worst.2 * 1e3
        );
        // The bent pose is strong: the top of the plant moves a long way.
        let travel = v.iter().map(|(r, p, _)| dist(*r, *p)).fold(0.0, f64::max);
        assert!(travel > 0.1, "{}: the bent pose moves vertices only {travel} m", rig.name);
    }
}
