//! The mass-spring plant of seed 003, section 4.2, and its implicit Euler step.
//!
//! Point masses at joints 1..3 and at the plant's top; joint 0 anchored. Linear springs along the
//! four segments (Eq. 1), angular springs at the four joints (Eq. 2, or the bending form, see
//! [`AngularForm`]), forces by Eq. 3, wind drag `drag * (w - v)` and gravity. One step is an
//! implicit (backward) Euler step, `M (v₁ - v₀) = h f(x₀ + h v₁, v₁)`, solved by Newton
//! iterations whose linear systems are those of Baraff and Witkin 1998 (their Eq. 6; the first
//! iteration is exactly their single step):
//!
//! `(M + h D + h² K) δ = -r`, `r = M (v - v₀) - h f`,
//!
//! with `K = -∂f/∂x`, `D = -∂f/∂v`, solved by conjugate gradient ([`conjugate_gradient`]). For a
//! behaviour function `C` (a scalar or a 3-vector) with Jacobian `J = ∂C/∂x`, Eq. 3 is
//! `f = -Jᵀ (k_s C + k_d J v)`, so `D = k_d Jᵀ J` and `K = k_s (Jᵀ J + C ∂²C/∂x²)`. The
//! curvature term `C ∂²C/∂x²` is kept for a stretched linear spring (it is the tension's
//! sideways stiffness and positive semi-definite) and left out otherwise (a compressed spring,
//! the angular springs), as is usual: it keeps the system matrix symmetric positive definite,
//! which conjugate gradient needs. The price is that Newton converges linearly, not
//! quadratically, at large bends (up to [`MAX_NEWTON_ITERATIONS`]); a backtracking line search on
//! the step's incremental potential keeps every iteration from adding energy. The damping
//! matrix `D` is taken at the step's start (linearly implicit damping).
//!
//! Everything lives in fixed-size arrays inside [`PlantSim`]: [`PlantSim::step`] never
//! allocates.

use glam::{DMat3, DQuat, DVec3};

use super::SimError;
use super::params::{AngularForm, FREE_NODES, NODES, SimParams};
use super::solver::{DOF, Matrix, conjugate_gradient};
use super::wind::{Wind, WindSpec};
use crate::rig::Rig;
use crate::sample::{JOINTS, PoseFrame};

/// Most Newton iterations of one implicit Euler step.
pub const MAX_NEWTON_ITERATIONS: usize = 12;
/// Newton stops when the residual has shrunk by this factor.
pub const NEWTON_TOLERANCE: f64 = 1e-9;
/// Most halvings of one Newton step in its line search.
pub const MAX_LINE_SEARCH_HALVINGS: usize = 20;

/// The simulated plant: its state, parameters, wind and the preallocated step workspace.
#[derive(Debug, Clone)]
pub struct PlantSim {
    params: SimParams,
    wind: Wind,
    rest_height_m: [f64; NODES],
    rest_length_m: [f64; JOINTS],
    x: [DVec3; NODES],
    v: [DVec3; NODES],
    t_s: f64,
    force: [DVec3; FREE_NODES],
    stiffness: Matrix,
    damping: Matrix,
    damping0: Matrix,
    system: Matrix,
    rhs: [f64; DOF],
    dv: [f64; DOF],
    cg_iterations: usize,
    newton_iterations: usize,
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

fn projector(unit: DVec3) -> DMat3 {
    DMat3::IDENTITY - outer(unit, unit)
}

/// The force, `K` and `D` being assembled for one step.
struct Assembly<'a> {
    v: &'a [DVec3; NODES],
    force: &'a mut [DVec3; FREE_NODES],
    k: &'a mut Matrix,
    d: &'a mut Matrix,
}

impl Assembly<'_> {
    /// Eq. 3 for a scalar behaviour function `c` with gradients `g` per node (node 0 anchored).
    fn scalar(&mut self, g: &[(usize, DVec3)], c: f64, ks: f64, kd: f64) {
        let c_dot: f64 = g.iter().map(|&(n, gn)| gn.dot(self.v[n])).sum();
        let s = -(ks * c + kd * c_dot);
        for &(a, ga) in g.iter().filter(|(n, _)| *n > 0) {
            self.force[a - 1] += s * ga;
            for &(b, gb) in g.iter().filter(|(n, _)| *n > 0) {
                let m = outer(ga, gb);
                self.k.add_block(a - 1, b - 1, m * ks);
                self.d.add_block(a - 1, b - 1, m * kd);
            }
        }
    }

    /// Eq. 3 for a 3-vector behaviour function `c` with Jacobian blocks `j` per node.
    fn vector(&mut self, j: &[(usize, DMat3)], c: DVec3, ks: f64, kd: f64) {
        let c_dot: DVec3 = j.iter().map(|&(n, jn)| jn * self.v[n]).sum();
        let s = -(ks * c + kd * c_dot);
        for &(a, ja) in j.iter().filter(|(n, _)| *n > 0) {
            self.force[a - 1] += ja.transpose() * s;
            for &(b, jb) in j.iter().filter(|(n, _)| *n > 0) {
                let m = ja.transpose() * jb;
                self.k.add_block(a - 1, b - 1, m * ks);
                self.d.add_block(a - 1, b - 1, m * kd);
            }
        }
    }

    /// Adds a stiffness block `m` between nodes `a` and `b` as `+m` on the diagonal blocks and
    /// `-m` off them (a spring between the two).
    fn pair(&mut self, a: usize, b: usize, m: DMat3) {
        for (p, q, sign) in [(a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)] {
            if p > 0 && q > 0 {
                self.k.add_block(p - 1, q - 1, m * sign);
            }
        }
    }
}

/// A joint rotation `R_yaw R_pitch R_roll` (frond's convention, `crate::skeleton`) in f64.
fn joint_rotation(angles_deg: [f32; 3]) -> DQuat {
    let [pitch, yaw, roll] = angles_deg.map(|a| f64::from(a).to_radians());
    DQuat::from_rotation_z(yaw) * DQuat::from_rotation_x(pitch) * DQuat::from_rotation_y(roll)
}

/// Joint `j`'s segment vector `d`, its parent's `u` (the vertical for joint 0) and the bending
/// form's `C = d̂ - û`.
fn bend_vectors(x: &[DVec3; NODES], j: usize) -> (DVec3, DVec3, DVec3) {
    let d = x[j + 1] - x[j];
    let u = if j == 0 { DVec3::Y } else { x[j] - x[j - 1] };
    (d, u, d.normalize_or_zero() - u.normalize_or_zero())
}

/// Eq. 2's `x_ij` (towards the parent: the node below, or a fixed point one segment below the
/// root) and `x_kj` (towards the child) at joint `j`, and `x_ij`'s rest length.
fn paper_arms(x: &[DVec3; NODES], rest_length_m: &[f64; JOINTS], j: usize) -> (DVec3, DVec3, f64) {
    let b = x[j + 1] - x[j];
    if j == 0 {
        let l0 = rest_length_m[0];
        (DVec3::new(0.0, -l0, 0.0), b, l0)
    } else {
        (x[j - 1] - x[j], b, rest_length_m[j - 1])
    }
}

/// Seed 003, Eq. 2 at joint `j` with the straight rest angle `α = π`: the stiffness
/// `bend_stiffness / (L_a² L_b²)` and `C = x_ij · x_kj - |x_ij| |x_kj| cos α`.
fn paper_constraint(x: &[DVec3; NODES], rest_length_m: &[f64; JOINTS], k: f64, j: usize) -> (f64, f64) {
    let (a, b, la) = paper_arms(x, rest_length_m, j);
    let lb = rest_length_m[j];
    (k / (la * la * lb * lb), a.dot(b) + a.length() * b.length())
}

impl PlantSim {
    /// A plant whose nodes rest at `heights_m` (joints 0..3 and the top, strictly increasing,
    /// see [`super::node_heights_m`]), at rest, at time 0.
    pub fn new(heights_m: [f64; NODES], params: SimParams, wind: WindSpec) -> Result<PlantSim, SimError> {
        params.check().map_err(SimError::Invalid)?;
        if !heights_m.iter().all(|h| h.is_finite()) || heights_m.windows(2).any(|w| w[1] <= w[0]) {
            return Err(SimError::Heights(heights_m));
        }
        let mut sim = PlantSim {
            params,
            wind: Wind::new(wind),
            rest_height_m: heights_m,
            rest_length_m: std::array::from_fn(|j| heights_m[j + 1] - heights_m[j]),
            x: [DVec3::ZERO; NODES],
            v: [DVec3::ZERO; NODES],
            t_s: 0.0,
            force: [DVec3::ZERO; FREE_NODES],
            stiffness: Matrix::default(),
            damping: Matrix::default(),
            damping0: Matrix::default(),
            system: Matrix::default(),
            rhs: [0.0; DOF],
            dv: [0.0; DOF],
            cg_iterations: 0,
            newton_iterations: 0,
        };
        sim.set_pose(&[[0.0; 3]; JOINTS]);
        Ok(sim)
    }

    /// The plant of a rig: its `[sim]` parameters and node heights.
    pub fn from_rig(rig: &Rig, wind: WindSpec) -> Result<PlantSim, SimError> {
        PlantSim::new(rig.sim_node_heights_m(), rig.sim, wind)
    }

    /// Places the nodes where forward kinematics puts them for `joints_deg` (frond's convention,
    /// segments at their rest lengths), at rest. The time is kept.
    pub fn set_pose(&mut self, joints_deg: &[[f32; 3]; JOINTS]) {
        let mut q = DQuat::IDENTITY;
        self.x[0] = DVec3::new(0.0, self.rest_height_m[0], 0.0);
        for (i, angles) in joints_deg.iter().enumerate() {
            q *= joint_rotation(*angles);
            self.x[i + 1] = self.x[i] + q * DVec3::Y * self.rest_length_m[i];
        }
        self.v = [DVec3::ZERO; NODES];
    }

    /// Sets the velocity of free node `node` (1..=4), m/s; other indices are ignored.
    pub fn set_velocity(&mut self, node: usize, v_m_s: DVec3) {
        if (1..NODES).contains(&node) {
            self.v[node] = v_m_s;
        }
    }

    /// Node positions, metres: joints 0..3 and the top.
    pub fn positions_m(&self) -> &[DVec3; NODES] {
        &self.x
    }

    /// Node velocities, m/s (node 0's is always zero).
    pub fn velocities_m_s(&self) -> &[DVec3; NODES] {
        &self.v
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    /// Moves the simulated clock forward to `t_s` without integrating (the state is kept): what a
    /// live stage does when the steps it is behind by do not fit in its budget, so that the plant
    /// keeps real time (and the wind, a function of time, stays in step) instead of slowing down.
    /// A time not ahead of the clock (or not finite) leaves it.
    pub fn skip_to(&mut self, t_s: f64) {
        if t_s.is_finite() && t_s > self.t_s {
            self.t_s = t_s;
        }
    }

    /// The parameters.
    pub fn params(&self) -> &SimParams {
        &self.params
    }

    /// Changes the wind from the next step on (a live stage steering it; no allocation).
    pub fn set_wind(&mut self, spec: WindSpec) {
        self.wind = Wind::new(spec);
    }

    /// The wind field.
    pub fn wind(&self) -> &Wind {
        &self.wind
    }

    /// Conjugate gradient iterations of the last step (summed over its Newton iterations).
    pub fn cg_iterations(&self) -> usize {
        self.cg_iterations
    }

    /// Newton iterations (linear solves whose step was taken) of the last step.
    pub fn newton_iterations(&self) -> usize {
        self.newton_iterations
    }

    /// The largest relative stretch `| |x_ij| - L | / L` over the segments.
    pub fn max_strain(&self) -> f64 {
        (0..JOINTS)
            .map(|j| {
                ((self.x[j + 1] - self.x[j]).length() - self.rest_length_m[j]).abs() / self.rest_length_m[j]
            })
            .fold(0.0, f64::max)
    }

    /// Total mechanical energy, joules: kinetic, the springs' `½ k_s |C|²` (for the bending
    /// form `k (1 - cos θ)`) and gravity's potential.
    pub fn energy_j(&self) -> f64 {
        let kinetic: f64 =
            (1..NODES).map(|n| 0.5 * self.params.mass_kg[n - 1] * self.v[n].length_squared()).sum();
        kinetic + self.potential_j(&self.x)
    }

    /// The potential energy of the springs and gravity at the positions `x`, joules.
    fn potential_j(&self, x: &[DVec3; NODES]) -> f64 {
        let p = &self.params;
        let mut e = 0.0;
        for (m, xn) in p.mass_kg.iter().zip(&x[1..]) {
            e += m * p.gravity_m_s2 * xn.y;
        }
        for j in 0..JOINTS {
            let c = (x[j + 1] - x[j]).length() - self.rest_length_m[j];
            e += 0.5 * p.stretch_stiffness_n_per_m[j] * c * c;
            e += match p.angular {
                AngularForm::Bending => {
                    let (_, _, c) = bend_vectors(x, j);
                    0.5 * p.bend_stiffness_nm_per_rad[j] * c.length_squared()
                }
                AngularForm::Paper => {
                    let (ks, c) = paper_constraint(x, &self.rest_length_m, p.bend_stiffness_nm_per_rad[j], j);
                    0.5 * ks * c * c
                }
            };
        }
        e
    }

    /// The incremental potential of the step from `x₀`, `v₀` to the velocity `v` (Newton's
    /// merit function): `½ |v - v₀|²_M + U(x₀ + h v) + ½ h vᵀ D₀ v - h Σ c_n w · v_n`. Its
    /// gradient in `v` is the backward Euler residual `M (v - v₀) - h f`.
    fn incremental_potential(
        &self,
        x0: &[DVec3; NODES],
        v0: &[DVec3; NODES],
        v: &[DVec3; NODES],
        wind: DVec3,
    ) -> f64 {
        let h = self.params.timestep_s;
        let mut x = *x0;
        let mut flat = [DVec3::ZERO; FREE_NODES];
        let mut phi = 0.0;
        for n in 1..NODES {
            x[n] = x0[n] + h * v[n];
            flat[n - 1] = v[n];
            phi += 0.5 * self.params.mass_kg[n - 1] * (v[n] - v0[n]).length_squared()
                - h * self.params.drag_ns_per_m[n - 1] * wind.dot(v[n]);
        }
        let mut dv = [0.0; DOF];
        self.damping0.mul_nodes(&flat, &mut dv);
        let vdv: f64 = (0..DOF).map(|i| dv[i] * flat[i / 3][i % 3]).sum();
        phi + 0.5 * h * vdv + self.potential_j(&x)
    }

    /// At the positions `x`: the conservative forces (springs and gravity) into `force`,
    /// `K = -∂f/∂x` into `stiffness` and `D = -∂f/∂v` (spring damping and drag) into `damping`.
    fn assemble(&mut self, x: &[DVec3; NODES]) {
        self.force = [DVec3::ZERO; FREE_NODES];
        self.stiffness.clear();
        self.damping.clear();
        let p = self.params;
        // Zero velocities: the damping forces are applied through `D` by the step.
        let at_rest = [DVec3::ZERO; NODES];
        let mut asm =
            Assembly { v: &at_rest, force: &mut self.force, k: &mut self.stiffness, d: &mut self.damping };

        for j in 0..JOINTS {
            // Seed 003, Eq. 1 through Eq. 3: the linear spring of segment j.
            let d = x[j + 1] - x[j];
            let len = d.length();
            let dh = d.normalize_or(DVec3::Y);
            let c = len - self.rest_length_m[j];
            let ks = p.stretch_stiffness_n_per_m[j];
            asm.scalar(&[(j, -dh), (j + 1, dh)], c, ks, p.stretch_damping_ns_per_m[j]);
            if c > 0.0 && len > 0.0 {
                asm.pair(j, j + 1, projector(dh) * (ks * c / len));
            }

            // The angular spring at joint j, through Eq. 3.
            let (k, kd) = (p.bend_stiffness_nm_per_rad[j], p.bend_damping_nms_per_rad[j]);
            match p.angular {
                AngularForm::Bending => {
                    let (d, u, c) = bend_vectors(x, j);
                    let (ld, lu) = (d.length().max(1e-12), u.length().max(1e-12));
                    let jd = projector(d / ld) * (1.0 / ld);
                    if j == 0 {
                        asm.vector(&[(1, jd)], c, k, kd);
                    } else {
                        let ju = projector(u / lu) * (1.0 / lu);
                        asm.vector(&[(j - 1, ju), (j, -jd - ju), (j + 1, jd)], c, k, kd);
                    }
                }
                AngularForm::Paper => {
                    // Seed 003, Eq. 2 with cos α = -1: ∂C/∂x_kj = x_ij + |x_ij| x̂_kj and
                    // ∂C/∂x_ij = x_kj + |x_kj| x̂_ij.
                    let (ks, c) = paper_constraint(x, &self.rest_length_m, k, j);
                    let (a, b, _) = paper_arms(x, &self.rest_length_m, j);
                    let gb = a + a.length() * b.normalize_or_zero();
                    let ga = b + b.length() * a.normalize_or_zero();
                    let kd = kd * ks / k;
                    if j == 0 {
                        asm.scalar(&[(1, gb)], c, ks, kd);
                    } else {
                        asm.scalar(&[(j - 1, ga), (j, -ga - gb), (j + 1, gb)], c, ks, kd);
                    }
                }
            }
        }

        for n in 1..NODES {
            let c = p.drag_ns_per_m[n - 1];
            asm.force[n - 1] -= DVec3::Y * (p.mass_kg[n - 1] * p.gravity_m_s2);
            asm.d.add_block(n - 1, n - 1, DMat3::from_diagonal(DVec3::splat(c)));
        }
    }

    /// The total force on each free node (joints 1..3, top) in the current state, newtons: the
    /// springs (Eq. 1-3) and gravity at the current positions, the wind's drag `drag (w - v)` at
    /// the current time, and the springs' damping at the current velocities. Section 4.3 stores
    /// these with the positions and velocities of every sample. Reassembles the springs (no
    /// allocation).
    pub fn forces_n(&mut self) -> [DVec3; FREE_NODES] {
        let x = self.x;
        self.assemble(&x);
        let wind = self.wind.velocity_m_s(self.t_s);
        let mut flat = [DVec3::ZERO; FREE_NODES];
        flat.copy_from_slice(&self.v[1..]);
        let mut dv = [0.0; DOF];
        // `D` holds the drag's `-drag v` too (see `assemble`).
        self.damping.mul_nodes(&flat, &mut dv);
        std::array::from_fn(|i| {
            self.force[i] + self.params.drag_ns_per_m[i] * wind - DVec3::from_slice(&dv[3 * i..3 * i + 3])
        })
    }

    /// Advances the plant by one implicit (backward) Euler step of `timestep_s`,
    /// allocation-free: it solves `M (v₁ - v₀) = h f(x₀ + h v₁, v₁)` for `v₁` (the wind at the
    /// step's end, the damping matrix `D₀` taken at `x₀`) by Newton iterations, each the linear
    /// system `(M + h D₀ + h² K) δ = -r` of Baraff and Witkin solved by conjugate gradient.
    /// Starting from `v = 0`, the first iteration is their single linearised step; the further
    /// ones (at most [`MAX_NEWTON_ITERATIONS`]) remove its error, which with stiff springs and
    /// large steps lets a rotating segment stretch and the energy grow. Each Newton step is
    /// shortened until it lowers the step's incremental potential (a backtracking line search),
    /// so no step can add energy the springs and the wind did not put in. Then
    /// `x₁ = x₀ + h v₁`. A step whose result is not finite is not taken: the state stays as it
    /// was and [`SimError::Diverged`] says when.
    pub fn step(&mut self) -> Result<(), SimError> {
        let h = self.params.timestep_s;
        let t1 = self.t_s + h;
        let wind = self.wind.velocity_m_s(t1);
        let (x0, v0) = (self.x, self.v);
        let mut v = [DVec3::ZERO; NODES];
        let mut x = x0;
        self.assemble(&x0);
        self.damping0 = self.damping;
        let mut first = None;
        self.cg_iterations = 0;
        self.newton_iterations = 0;
        for it in 0..MAX_NEWTON_ITERATIONS {
            if it > 0 {
                for n in 1..NODES {
                    x[n] = x0[n] + h * v[n];
                }
                self.assemble(&x);
            }
            // r = M (v - v₀) - h (f + c w - D₀ v), and its size in M⁻¹ (a velocity squared).
            let mut flat = [DVec3::ZERO; FREE_NODES];
            flat.copy_from_slice(&v[1..]);
            let mut dv = [0.0; DOF];
            self.damping0.mul_nodes(&flat, &mut dv);
            let mut norm = 0.0;
            for n in 1..NODES {
                let m = self.params.mass_kg[n - 1];
                let f = self.force[n - 1] + self.params.drag_ns_per_m[n - 1] * wind
                    - DVec3::from_slice(&dv[3 * (n - 1)..3 * n]);
                let r = m * (v[n] - v0[n]) - h * f;
                self.rhs[3 * (n - 1)..3 * n].copy_from_slice(&(-r).to_array());
                norm += r.length_squared() / m;
            }
            let first = *first.get_or_insert(norm);
            if norm <= NEWTON_TOLERANCE * NEWTON_TOLERANCE * first || norm == 0.0 {
                break;
            }
            for r in 0..DOF {
                for c in 0..DOF {
                    self.system.0[r][c] = h * self.damping0.0[r][c] + h * h * self.stiffness.0[r][c];
                }
                self.system.0[r][r] += self.params.mass_kg[r / 3];
            }
            self.cg_iterations += conjugate_gradient(&self.system, &self.rhs, &mut self.dv);
            // Backtracking (Armijo) on the incremental potential along δ; rhs = -r.
            let slope: f64 = -(0..DOF).map(|i| self.rhs[i] * self.dv[i]).sum::<f64>();
            if slope.is_nan() || slope >= 0.0 {
                break;
            }
            let phi0 = self.incremental_potential(&x0, &v0, &v, wind);
            let mut alpha = 1.0;
            let mut accepted = false;
            let mut trial = v;
            for _ in 0..MAX_LINE_SEARCH_HALVINGS {
                for n in 1..NODES {
                    trial[n] = v[n] + alpha * DVec3::from_slice(&self.dv[3 * (n - 1)..3 * n]);
                }
                let phi = self.incremental_potential(&x0, &v0, &trial, wind);
                if phi <= phi0 + 1e-4 * alpha * slope {
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            if !accepted {
                break;
            }
            v = trial;
            self.newton_iterations += 1;
        }
        for n in 1..NODES {
            x[n] = x0[n] + h * v[n];
        }
        if !(x.iter().chain(&v).all(|p| p.is_finite())) {
            return Err(SimError::Diverged { t_s: self.t_s });
        }
        (self.x, self.v) = (x, v);
        self.t_s = t1;
        Ok(())
    }

    /// The joint angles read back from the node positions in frond's rotation convention
    /// (`crate::skeleton`: `[pitch, yaw, roll]` degrees relative to the parent, roll 0), so
    /// forward kinematics of the pose points every segment where the simulation's does and every
    /// exporter shows the simulation unchanged. Segment `i` runs from joint `i` to node `i + 1`;
    /// with roll 0, `R_yaw R_pitch` takes +Y to `l = (-sin yaw cos pitch, cos yaw cos pitch,
    /// sin pitch)`, `l` the segment's direction in the parent joint's frame.
    pub fn pose(&self) -> PoseFrame {
        let mut q = DQuat::IDENTITY;
        let mut joints_deg = [[0.0f32; 3]; JOINTS];
        for (i, out) in joints_deg.iter_mut().enumerate() {
            let d = (self.x[i + 1] - self.x[i]).normalize_or(q * DVec3::Y);
            let l = q.inverse() * d;
            let pitch = l.z.clamp(-1.0, 1.0).asin();
            let yaw = (-l.x).atan2(l.y);
            q = q * DQuat::from_rotation_z(yaw) * DQuat::from_rotation_x(pitch);
            *out = [pitch.to_degrees() as f32, yaw.to_degrees() as f32, 0.0];
        }
        PoseFrame { t: self.t_s, joints_deg }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The forces of Eq. 3 (assembled) are minus the gradient of the energy (written
    /// separately, `potential_j`), by central differences, for both angular forms, gravity and
    /// stretched and compressed segments.
    #[test]
    fn sim_forces_are_minus_the_energy_gradient() {
        let heights = [0.0, 0.1, 0.2, 0.3, 0.4];
        for angular in [AngularForm::Bending, AngularForm::Paper] {
            let mut p = SimParams::defaults_for(heights);
            p.angular = angular;
            p.gravity_m_s2 = 9.81;
            let mut sim = PlantSim::new(heights, p, WindSpec::CALM).unwrap();
            sim.set_pose(&[[10.0, -20.0, 0.0], [-15.0, 5.0, 0.0], [25.0, 30.0, 0.0], [-30.0, 10.0, 0.0]]);
            // At the rest lengths (bending and gravity only), then with segment 1 stretched by
            // 0.3 % and segment 3 compressed by 0.2 %.
            for stretched in [false, true] {
                let mut x = sim.x;
                if stretched {
                    let d1 = x[2] - x[1];
                    for xn in &mut x[2..] {
                        *xn += d1 * 0.003;
                    }
                    x[4] -= (x[4] - x[3]) * 0.002;
                }
                sim.assemble(&x);
                let force = sim.force;
                let eps = 1e-7;
                for n in 1..NODES {
                    for axis in 0..3 {
                        let (mut plus, mut minus) = (x, x);
                        plus[n][axis] += eps;
                        minus[n][axis] -= eps;
                        let grad = (sim.potential_j(&plus) - sim.potential_j(&minus)) / (2.0 * eps);
                        let f = force[n - 1][axis];
                        let scale = force.iter().map(|f| f.abs().max_element()).fold(0.0, f64::max);
                        assert!(
                            (f + grad).abs() < 1e-6 * scale,
                            "{angular:?} stretched {stretched} node {n} axis {axis}: force {f}, -dU/dx {}",
                            -grad
                        );
                    }
                }
                // K is symmetric and positive semi-definite (x^T K x >= 0 for a few x).
                let k = &sim.stiffness.0;
                for r in 0..DOF {
                    for c in 0..DOF {
                        assert!((k[r][c] - k[c][r]).abs() <= 1e-9 * k[r][r].abs().max(k[c][c].abs()));
                    }
                }
                for seed in 0..8 {
                    let v: [f64; DOF] = std::array::from_fn(|i| ((i * 7 + seed * 13) % 11) as f64 - 5.0);
                    let mut kv = [0.0; DOF];
                    sim.stiffness.mul(&v, &mut kv);
                    let vkv: f64 = v.iter().zip(&kv).map(|(a, b)| a * b).sum();
                    assert!(
                        vkv >= -1e-9 * k.iter().map(|r| r.iter().map(|x| x.abs()).sum::<f64>()).sum::<f64>()
                    );
                }
            }
        }
    }
}
