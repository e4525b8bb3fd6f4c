//! The linear system of one implicit Euler step (seed 003, section 4.2: "Each step results in a
//! linear system of equations and is solved using the conjugate gradient method"), after Baraff
//! and Witkin: a dense `DOF x DOF` symmetric positive definite matrix (12 x 12 for four free
//! nodes in 3D) and a preconditioned conjugate gradient with the diagonal (Jacobi)
//! preconditioner of Baraff and Witkin 1998, section 5.2. Fixed-size arrays: no allocation.

use glam::{DMat3, DVec3};

use super::params::FREE_NODES;

/// Degrees of freedom: three per free node.
pub const DOF: usize = 3 * FREE_NODES;
/// Most CG iterations per solve; in exact arithmetic CG ends after `DOF`, the rest absorbs
/// rounding in ill-conditioned systems.
pub const MAX_CG_ITERATIONS: usize = 8 * DOF;
/// CG stops when the residual is this small relative to the right-hand side.
pub const CG_TOLERANCE: f64 = 1e-13;

/// A dense `DOF x DOF` matrix addressed by node blocks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Matrix(pub [[f64; DOF]; DOF]);

impl Default for Matrix {
    fn default() -> Self {
        Matrix([[0.0; DOF]; DOF])
    }
}

impl Matrix {
    /// Sets every entry to 0.
    pub fn clear(&mut self) {
        self.0 = [[0.0; DOF]; DOF];
    }

    /// Adds `m` to the block of free nodes `a`, `b` (indices `0..FREE_NODES`).
    pub fn add_block(&mut self, a: usize, b: usize, m: DMat3) {
        for c in 0..3 {
            let col = m.col(c);
            for r in 0..3 {
                self.0[3 * a + r][3 * b + c] += col[r];
            }
        }
    }

    /// `y = self * x`.
    pub fn mul(&self, x: &[f64; DOF], y: &mut [f64; DOF]) {
        for (yi, row) in y.iter_mut().zip(&self.0) {
            *yi = row.iter().zip(x).map(|(a, b)| a * b).sum();
        }
    }

    /// `y = self * x` for a vector of node velocities or positions.
    pub fn mul_nodes(&self, x: &[DVec3; FREE_NODES], y: &mut [f64; DOF]) {
        let mut flat = [0.0; DOF];
        for (n, v) in x.iter().enumerate() {
            flat[3 * n..3 * n + 3].copy_from_slice(&v.to_array());
        }
        self.mul(&flat, y);
    }
}

fn dot(a: &[f64; DOF], b: &[f64; DOF]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Solves `a x = b` for a symmetric positive definite `a` by preconditioned conjugate gradient,
/// starting from `x = 0`; returns the iterations used. Stops at [`CG_TOLERANCE`] or after
/// [`MAX_CG_ITERATIONS`] (the best iterate is kept either way).
pub fn conjugate_gradient(a: &Matrix, b: &[f64; DOF], x: &mut [f64; DOF]) -> usize {
    let mut inv_diag = [0.0; DOF];
    for (i, d) in inv_diag.iter_mut().enumerate() {
        let v = a.0[i][i];
        *d = if v > 0.0 { 1.0 / v } else { 1.0 };
    }
    *x = [0.0; DOF];
    let mut r = *b;
    let mut z = [0.0; DOF];
    for i in 0..DOF {
        z[i] = inv_diag[i] * r[i];
    }
    let mut p = z;
    let mut rz = dot(&r, &z);
    let limit = CG_TOLERANCE * CG_TOLERANCE * dot(b, b);
    let mut ap = [0.0; DOF];
    for it in 0..MAX_CG_ITERATIONS {
        if dot(&r, &r) <= limit {
            return it;
        }
        a.mul(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            return it;
        }
        let alpha = rz / pap;
        for i in 0..DOF {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
            z[i] = inv_diag[i] * r[i];
        }
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..DOF {
            p[i] = z[i] + beta * p[i];
        }
    }
    MAX_CG_ITERATIONS
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sim_cg_solves_a_known_spd_system() {
        // A = L L^T + diag, with x* = (1, -2, 3, ...) and b = A x*: CG must recover x*.
        let mut a = Matrix::default();
        for i in 0..DOF {
            for j in 0..DOF {
                let l =
                    |r: usize, c: usize| if c <= r { 1.0 / (1.0 + r as f64 + 2.0 * c as f64) } else { 0.0 };
                a.0[i][j] = (0..DOF).map(|k| l(i, k) * l(j, k)).sum::<f64>();
            }
            a.0[i][i] += 1e-3 * (i + 1) as f64;
        }
        let want: [f64; DOF] =
            std::array::from_fn(|i| if i % 2 == 0 { i as f64 + 1.0 } else { -(i as f64) - 1.0 });
        let mut b = [0.0; DOF];
        a.mul(&want, &mut b);
        let mut x = [0.0; DOF];
        let it = conjugate_gradient(&a, &b, &mut x);
        assert!(it <= MAX_CG_ITERATIONS);
        for i in 0..DOF {
            assert!((x[i] - want[i]).abs() < 1e-6, "{i}: {} vs {}", x[i], want[i]);
        }
        // Zero right-hand side: zero solution, no iterations.
        assert_eq!(conjugate_gradient(&a, &[0.0; DOF], &mut x), 0);
        assert_eq!(x, [0.0; DOF]);
    }
}
