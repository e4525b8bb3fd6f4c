//! The `[sim]` table of a rig: the mass-spring parameters of seed 003, section 4.2, with units in
//! the names, validated with every problem's path (`sim.mass_kg[2]`), and defaults derived from
//! the rig's geometry so that a rig without `[sim]` simulates plausibly.
//!
//! Node numbering: node 0 is joint 0 (anchored), nodes 1..3 are joints 1..3 and node 4 is the
//! plant's top (the rig's `mesh.height_m`). Arrays of the four free nodes (`mass_kg`,
//! `drag_ns_per_m`) are nodes 1..4; arrays of the four joints (`bend_*`) are joints 0..3; arrays
//! of the four segments (`stretch_*`) are segments 0..3, segment `j` from joint `j` to node `j+1`.

use serde::{Deserialize, Serialize};

use crate::problems::Problems;
use crate::rig_mesh::MeshSpec;
use crate::sample::JOINTS;

/// Free nodes of the simulated plant: joints 1..3 and the top.
pub const FREE_NODES: usize = 4;
/// All nodes: the anchored root joint and the free nodes.
pub const NODES: usize = FREE_NODES + 1;

/// Smallest and largest node mass, kg.
pub const MASS_KG_RANGE: (f64, f64) = (1e-6, 1e4);
/// Smallest and largest bend stiffness, N m / rad (a plant without one never returns to rest).
pub const BEND_STIFFNESS_RANGE: (f64, f64) = (1e-9, 1e6);
/// Largest bend damping, N m s / rad (0 is allowed).
pub const MAX_BEND_DAMPING: f64 = 1e6;
/// Smallest and largest stretch stiffness, N / m.
pub const STRETCH_STIFFNESS_RANGE: (f64, f64) = (1e-3, 1e9);
/// Largest stretch damping, N s / m (0 is allowed).
pub const MAX_STRETCH_DAMPING: f64 = 1e9;
/// Largest wind drag coefficient of a node, N s / m (0 is allowed: the node feels no wind).
pub const MAX_DRAG: f64 = 1e3;
/// Largest gravity, m/s² (0 is allowed, and the default).
pub const MAX_GRAVITY_M_S2: f64 = 100.0;
/// Smallest and largest integration time step, seconds.
pub const TIMESTEP_S_RANGE: (f64, f64) = (1e-5, 0.05);
/// Default integration time step, seconds.
pub const DEFAULT_TIMESTEP_S: f64 = 0.001;

/// Which behaviour function the angular springs use (`angular = "bending"` or `"paper"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AngularForm {
    /// The default: `C = d̂ - û` (3 components), `d̂` the joint's segment direction and `û` its
    /// parent's (the vertical for joint 0). Its energy `k (1 - cos θ)` gives the restoring torque
    /// `k sin θ ≈ k θ` for a bend `θ`, so `bend_stiffness_nm_per_rad` is the small-angle torque
    /// per radian. The torque peaks at 90 degrees: bends beyond that are restored ever more
    /// weakly.
    #[default]
    Bending,
    /// Seed 003, Eq. 2 as printed: `C = x_ij · x_kj - |x_ij| |x_kj| cos α` with the straight
    /// rest angle `α = π` of frond's rigs. Its gradient vanishes at `α = π`, so it has **no**
    /// restoring torque to first order in the bend (the torque grows as `θ³`): a plant that rests
    /// straight is floppy near rest. Its stiffness is `bend_stiffness / (L_a² L_b²)` (`L` the two
    /// segments' rest lengths), the value for which a right rest angle would give
    /// `bend_stiffness` per radian.
    Paper,
}

impl AngularForm {
    /// The name used in rig files.
    pub fn name(self) -> &'static str {
        match self {
            AngularForm::Bending => "bending",
            AngularForm::Paper => "paper",
        }
    }
}

/// The validated `[sim]` table (seed 003, section 4.2). All values SI, units in the names.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimParams {
    /// Masses of the free nodes (joints 1..3, top), kg. Default: each node is heavier than
    /// everything above it (`8, 4, 2, 1` times a unit), as section 4.2 asks; not enforced.
    pub mass_kg: [f64; FREE_NODES],
    /// Per joint 0..3: the small-angle restoring torque per radian of bend of the joint's segment
    /// relative to its parent segment (the vertical for joint 0), N m / rad (`k_s` of Eq. 3).
    pub bend_stiffness_nm_per_rad: [f64; JOINTS],
    /// Per joint 0..3: the damping torque per rad/s of bend rate (`k_d` of Eq. 3), N m s / rad.
    pub bend_damping_nms_per_rad: [f64; JOINTS],
    /// Per segment 0..3: the linear spring of Eq. 1 (`k_s` of Eq. 3), N / m.
    pub stretch_stiffness_n_per_m: [f64; JOINTS],
    /// Per segment 0..3: the linear spring's damping (`k_d` of Eq. 3), N s / m.
    pub stretch_damping_ns_per_m: [f64; JOINTS],
    /// Per free node: the wind force on it is `drag * (w - v)`, `w` the wind velocity and `v`
    /// the node's, N s / m.
    pub drag_ns_per_m: [f64; FREE_NODES],
    /// Gravity along -Y, m/s² (default 0).
    pub gravity_m_s2: f64,
    /// Implicit Euler time step, seconds (default 0.001).
    pub timestep_s: f64,
    /// The angular spring's behaviour function (default [`AngularForm::Bending`]).
    pub angular: AngularForm,
}

/// Heights of the five nodes in the rest pose (joints 0..3, top), metres: the top is the rig's
/// `mesh.height_m`, or the procedural mesh's default (the top joint plus 3/4 of the top
/// segment) when it has none (also for file meshes, whose height the rig does not know).
pub fn node_heights_m(joint_heights_m: [f32; JOINTS], mesh: &MeshSpec) -> [f64; NODES] {
    let h = joint_heights_m.map(f64::from);
    let top = match mesh {
        MeshSpec::Procedural { height_m: Some(top), .. } => f64::from(*top),
        _ => h[3] + 0.75 * (h[3] - h[2]),
    };
    [h[0], h[1], h[2], h[3], top]
}

/// Reference wind of the default stiffness, m/s.
const REFERENCE_WIND_M_S: f64 = 5.0;
/// Bend of every joint under the reference wind with the default stiffness (small angles), rad.
const REFERENCE_BEND_RAD: f64 = 0.15;
/// Damping ratio of the default bend damping.
const DEFAULT_BEND_DAMPING_RATIO: f64 = 0.2;
/// Default `stretch_stiffness * L²` over `bend_stiffness`: stretching is 100 times faster than
/// bending, so segments stay within a small fraction of a percent of their rest length.
const STRETCH_OVER_BEND: f64 = 1e4;

fn clamp(v: f64, (lo, hi): (f64, f64)) -> f64 {
    if v.is_finite() { v.clamp(lo, hi) } else { lo }
}

impl SimParams {
    /// Defaults for a plant whose nodes rest at `heights_m` (see [`node_heights_m`]). With
    /// `s = height / 0.3 m` (the size relative to a 30 cm grass blade):
    ///
    /// - `mass_kg = [8, 4, 2, 1] * 1 g * s³` (each node heavier than everything above it);
    /// - `drag_ns_per_m = 3 mN s/m * s²` per node (linearised air drag of a blade's area);
    /// - `bend_stiffness(j)`: a steady 5 m/s wind bends every joint by 0.15 rad (small-angle
    ///   statics: the drag torque above joint `j` divided by 0.15 rad);
    /// - `bend_damping(j) = 2 * 0.2 * sqrt(k_j I_j)`, `I_j` the point masses' inertia above `j`;
    /// - `stretch_stiffness(j) = 1e4 * k_j / L_j²` and critical damping for the node above;
    /// - no gravity, a 1 ms step, the bending form.
    ///
    /// Every value is clamped into its valid range, so defaults always validate.
    pub fn defaults_for(heights_m: [f64; NODES]) -> SimParams {
        let z = heights_m;
        let s = ((z[4] - z[0]) / 0.3).max(1e-9);
        let unit = 1e-3 * s * s * s;
        let mass_kg = [8.0, 4.0, 2.0, 1.0].map(|f: f64| clamp(f * unit, MASS_KG_RANGE));
        let drag_ns_per_m = [clamp(3e-3 * s * s, (0.0, MAX_DRAG)); FREE_NODES];
        let mut p = SimParams {
            mass_kg,
            bend_stiffness_nm_per_rad: [0.0; JOINTS],
            bend_damping_nms_per_rad: [0.0; JOINTS],
            stretch_stiffness_n_per_m: [0.0; JOINTS],
            stretch_damping_ns_per_m: [0.0; JOINTS],
            drag_ns_per_m,
            gravity_m_s2: 0.0,
            timestep_s: DEFAULT_TIMESTEP_S,
            angular: AngularForm::Bending,
        };
        for j in 0..JOINTS {
            let above = j + 1..NODES;
            let torque: f64 =
                above.clone().map(|n| drag_ns_per_m[n - 1] * REFERENCE_WIND_M_S * (z[n] - z[j])).sum();
            let k = clamp(torque / REFERENCE_BEND_RAD, BEND_STIFFNESS_RANGE);
            let inertia: f64 = above.map(|n| mass_kg[n - 1] * (z[n] - z[j]).powi(2)).sum();
            let length = (z[j + 1] - z[j]).max(1e-9);
            let ks = clamp(STRETCH_OVER_BEND * k / (length * length), STRETCH_STIFFNESS_RANGE);
            p.bend_stiffness_nm_per_rad[j] = k;
            p.bend_damping_nms_per_rad[j] =
                clamp(2.0 * DEFAULT_BEND_DAMPING_RATIO * (k * inertia).sqrt(), (0.0, MAX_BEND_DAMPING));
            p.stretch_stiffness_n_per_m[j] = ks;
            p.stretch_damping_ns_per_m[j] = clamp(2.0 * (ks * mass_kg[j]).sqrt(), (0.0, MAX_STRETCH_DAMPING));
        }
        p
    }

    /// Checks every value against its range, reporting each problem with its path under `sim.`.
    pub fn check(&self) -> Result<(), Problems> {
        let mut p = Problems::default();
        self.check_into(&mut p);
        if p.is_empty() { Ok(()) } else { Err(p) }
    }

    fn check_into(&self, p: &mut Problems) {
        type Checked<'a> = (&'a str, &'a [f64; 4], (f64, f64), &'a str);
        let arrays: [Checked; 6] = [
            ("mass_kg", &self.mass_kg, MASS_KG_RANGE, "a mass (kg)"),
            (
                "bend_stiffness_nm_per_rad",
                &self.bend_stiffness_nm_per_rad,
                BEND_STIFFNESS_RANGE,
                "a bend stiffness (N m/rad)",
            ),
            (
                "bend_damping_nms_per_rad",
                &self.bend_damping_nms_per_rad,
                (0.0, MAX_BEND_DAMPING),
                "a bend damping (N m s/rad)",
            ),
            (
                "stretch_stiffness_n_per_m",
                &self.stretch_stiffness_n_per_m,
                STRETCH_STIFFNESS_RANGE,
                "a stretch stiffness (N/m)",
            ),
            (
                "stretch_damping_ns_per_m",
                &self.stretch_damping_ns_per_m,
                (0.0, MAX_STRETCH_DAMPING),
                "a stretch damping (N s/m)",
            ),
            ("drag_ns_per_m", &self.drag_ns_per_m, (0.0, MAX_DRAG), "a drag (N s/m)"),
        ];
        for (key, values, range, what) in arrays {
            for (i, v) in values.iter().enumerate() {
                within(p, format!("sim.{key}[{i}]"), *v, range, what);
            }
        }
        within(p, "sim.gravity_m_s2".into(), self.gravity_m_s2, (0.0, MAX_GRAVITY_M_S2), "gravity (m/s²)");
        within(p, "sim.timestep_s".into(), self.timestep_s, TIMESTEP_S_RANGE, "the time step (s)");
    }
}

fn within(p: &mut Problems, path: String, v: f64, (lo, hi): (f64, f64), what: &str) {
    if !v.is_finite() {
        p.push(path, format!("must be a finite number, found {v}"));
    } else if !(lo..=hi).contains(&v) {
        p.push(path, format!("{what} must be between {lo} and {hi}, found {v}"));
    }
}

/// The `[sim]` table as written in a rig file; every key optional. Public for the readers in
/// frond-formats (rig files, `--sim` files); build a [`SimParams`] with [`RawSim::validate`].
#[doc(hidden)]
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSim {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mass_kg: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    bend_stiffness_nm_per_rad: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    bend_damping_nms_per_rad: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    stretch_stiffness_n_per_m: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    stretch_damping_ns_per_m: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    drag_ns_per_m: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gravity_m_s2: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    timestep_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    angular: Option<String>,
}

fn take4(p: &mut Problems, key: &str, given: &Option<Vec<f64>>, default: [f64; 4]) -> [f64; 4] {
    match given {
        None => default,
        Some(v) if v.len() == 4 => [v[0], v[1], v[2], v[3]],
        Some(v) => {
            p.push(format!("sim.{key}"), format!("expected 4 values, found {}", v.len()));
            default
        }
    }
}

impl RawSim {
    /// Validates the table; values not given take [`SimParams::defaults_for`] (damping defaults
    /// follow the stiffness and masses given).
    pub fn validate(&self, p: &mut Problems, heights_m: [f64; NODES]) -> SimParams {
        let d = SimParams::defaults_for(heights_m);
        let mut s = d;
        s.mass_kg = take4(p, "mass_kg", &self.mass_kg, d.mass_kg);
        s.bend_stiffness_nm_per_rad = take4(
            p,
            "bend_stiffness_nm_per_rad",
            &self.bend_stiffness_nm_per_rad,
            d.bend_stiffness_nm_per_rad,
        );
        s.stretch_stiffness_n_per_m = take4(
            p,
            "stretch_stiffness_n_per_m",
            &self.stretch_stiffness_n_per_m,
            d.stretch_stiffness_n_per_m,
        );
        s.drag_ns_per_m = take4(p, "drag_ns_per_m", &self.drag_ns_per_m, d.drag_ns_per_m);
        // Damping defaults from the values given, with the same ratios as `defaults_for`.
        let z = heights_m;
        let mut bend_damping = d.bend_damping_nms_per_rad;
        let mut stretch_damping = d.stretch_damping_ns_per_m;
        for j in 0..JOINTS {
            let inertia: f64 = (j + 1..NODES).map(|n| s.mass_kg[n - 1].abs() * (z[n] - z[j]).powi(2)).sum();
            let k = s.bend_stiffness_nm_per_rad[j].abs();
            bend_damping[j] =
                clamp(2.0 * DEFAULT_BEND_DAMPING_RATIO * (k * inertia).sqrt(), (0.0, MAX_BEND_DAMPING));
            let ks = s.stretch_stiffness_n_per_m[j].abs();
            stretch_damping[j] = clamp(2.0 * (ks * s.mass_kg[j].abs()).sqrt(), (0.0, MAX_STRETCH_DAMPING));
        }
        s.bend_damping_nms_per_rad =
            take4(p, "bend_damping_nms_per_rad", &self.bend_damping_nms_per_rad, bend_damping);
        s.stretch_damping_ns_per_m =
            take4(p, "stretch_damping_ns_per_m", &self.stretch_damping_ns_per_m, stretch_damping);
        s.gravity_m_s2 = self.gravity_m_s2.unwrap_or(d.gravity_m_s2);
        s.timestep_s = self.timestep_s.unwrap_or(d.timestep_s);
        s.angular = match self.angular.as_deref() {
            None | Some("bending") => AngularForm::Bending,
            Some("paper") => AngularForm::Paper,
            Some(other) => {
                p.push("sim.angular", format!("unknown form `{other}` (expected bending or paper)"));
                AngularForm::Bending
            }
        };
        s.check_into(p);
        s
    }

    /// The table that reads back as `s`: nothing when `s` is the default for the geometry,
    /// every key otherwise.
    pub(crate) fn from_params(s: &SimParams, heights_m: [f64; NODES]) -> Option<RawSim> {
        if *s == SimParams::defaults_for(heights_m) {
            return None;
        }
        Some(RawSim {
            mass_kg: Some(s.mass_kg.to_vec()),
            bend_stiffness_nm_per_rad: Some(s.bend_stiffness_nm_per_rad.to_vec()),
            bend_damping_nms_per_rad: Some(s.bend_damping_nms_per_rad.to_vec()),
            stretch_stiffness_n_per_m: Some(s.stretch_stiffness_n_per_m.to_vec()),
            stretch_damping_ns_per_m: Some(s.stretch_damping_ns_per_m.to_vec()),
            drag_ns_per_m: Some(s.drag_ns_per_m.to_vec()),
            gravity_m_s2: Some(s.gravity_m_s2),
            timestep_s: Some(s.timestep_s),
            angular: Some(s.angular.name().to_string()),
        })
    }
}
