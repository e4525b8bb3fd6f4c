//! Laplacian editing of a polyline with constraint vertices: seed 004, Eq. 1,
//!
//! ```text
//! min  sum_i |L(v'_i) - sigma_i|^2  +  mu sum_{j in C} |v'_j - c_j|^2
//! ```
//!
//! where `sigma_i = L(v_i)` are the Laplacian coordinates of the shape before the edit and `c_j`
//! the constraint vertices' new positions. On a curve the cotangent weights of a surface reduce
//! to the 1D Laplace-Beltrami weights, inversely proportional to the two edge lengths at a vertex:
//! `L(v_i) = v_i - (a_i v_{i-1} + b_i v_{i+1})`, `a_i = l_next / (l_prev + l_next)`, `b_i = 1 - a_i`
//! (the weights of the rest shape, so evenly spaced vertices get the uniform 1/2, 1/2).
//!
//! The normal equations `(L^T L + mu S) x = L^T sigma + mu S c` (S selects the constraints) are
//! one symmetric positive definite matrix for both coordinates: [`LaplacianEditor`] factors it
//! once (Cholesky) for a shape and a constraint set, and each edit is then two triangular solves.

use nalgebra::{DMatrix, DVector};
use thiserror::Error;

use crate::Point;
use crate::outline::dist;

/// Largest polyline edited (the dense factor is n^2 doubles: 8 MiB at this size).
pub const MAX_EDIT_VERTICES: usize = 1024;

/// Why an edit cannot be set up.
#[derive(Debug, Error, PartialEq)]
pub enum LaplacianError {
    /// Too few or too many vertices.
    #[error("a polyline to edit needs {min} to {MAX_EDIT_VERTICES} vertices, not {got}")]
    Size {
        /// At least this many.
        min: usize,
        /// Given.
        got: usize,
    },
    /// No constraint: the shape could float anywhere.
    #[error("a Laplacian edit needs at least one constraint vertex")]
    NoConstraint,
    /// A constraint names a vertex the polyline lacks.
    #[error("constraint vertex {index} is beyond the polyline's {len} vertices")]
    ConstraintIndex {
        /// Named vertex.
        index: usize,
        /// Vertex count.
        len: usize,
    },
    /// The weight is not positive and finite, or the shape has non-finite coordinates.
    #[error("{0}")]
    Invalid(&'static str),
}

/// Eq. 1 factored for one rest shape and one set of constraint vertices.
#[derive(Debug, Clone)]
pub struct LaplacianEditor {
    closed: bool,
    /// Constraint vertex indices.
    constraints: Vec<usize>,
    mu: f64,
    /// `L` (rows without a Laplacian, the ends of an open polyline, are zero).
    lap: DMatrix<f64>,
    /// `L^T sigma`, per coordinate.
    rhs_rest: [DVector<f64>; 2],
    factor: nalgebra::Cholesky<f64, nalgebra::Dyn>,
}

impl LaplacianEditor {
    /// Factors Eq. 1 for `rest` (closed: the last vertex joins the first) with the vertices
    /// `constraints` held with weight `mu`.
    pub fn new(rest: &[Point], closed: bool, constraints: &[usize], mu: f64) -> Result<Self, LaplacianError> {
        let n = rest.len();
        let min = if closed { 3 } else { 2 };
        if !(min..=MAX_EDIT_VERTICES).contains(&n) {
            return Err(LaplacianError::Size { min, got: n });
        }
        if constraints.is_empty() {
            return Err(LaplacianError::NoConstraint);
        }
        if let Some(&index) = constraints.iter().find(|&&c| c >= n) {
            return Err(LaplacianError::ConstraintIndex { index, len: n });
        }
        if !(mu.is_finite() && mu > 0.0) {
            return Err(LaplacianError::Invalid("the constraint weight must be positive and finite"));
        }
        if rest.iter().flatten().any(|c| !c.is_finite()) {
            return Err(LaplacianError::Invalid("the polyline has a non-finite coordinate"));
        }
        let mut constraints = constraints.to_vec();
        constraints.sort_unstable();
        constraints.dedup();
        let mut lap = DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            let (prev, next) = match (closed, i) {
                (true, _) => ((i + n - 1) % n, (i + 1) % n),
                (false, 0) => continue,
                (false, _) if i == n - 1 => continue,
                (false, _) => (i - 1, i + 1),
            };
            let (lp, ln) = (dist(rest[prev], rest[i]), dist(rest[i], rest[next]));
            let a = if lp + ln > 0.0 { ln / (lp + ln) } else { 0.5 };
            lap[(i, i)] = 1.0;
            lap[(i, prev)] -= a;
            lap[(i, next)] -= 1.0 - a;
        }
        let mut normal = lap.transpose() * &lap;
        for &c in &constraints {
            normal[(c, c)] += mu;
        }
        let factor = normal.cholesky().ok_or(LaplacianError::Invalid(
            "the edit's normal equations are singular (repeated vertices?)",
        ))?;
        let rhs_rest = [0, 1].map(|k| {
            let v = DVector::from_iterator(n, rest.iter().map(|p| p[k]));
            let sigma = &lap * v;
            lap.transpose() * sigma
        });
        Ok(LaplacianEditor { closed, constraints, mu, lap, rhs_rest, factor })
    }

    /// Whether the polyline is closed.
    pub fn closed(&self) -> bool {
        self.closed
    }

    /// The minimiser of Eq. 1 with the constraint vertices pulled to `targets` (one per
    /// constraint, in the order of the sorted, deduplicated constraint indices).
    pub fn solve(&self, targets: &[Point]) -> Vec<Point> {
        let n = self.lap.nrows();
        let coords = [0, 1].map(|k| {
            let mut rhs = self.rhs_rest[k].clone();
            for (&c, t) in self.constraints.iter().zip(targets) {
                rhs[c] += self.mu * t[k];
            }
            self.factor.solve(&rhs)
        });
        (0..n).map(|i| [coords[0][i], coords[1][i]]).collect()
    }

    /// The constraint vertex indices, sorted.
    pub fn constraints(&self) -> &[usize] {
        &self.constraints
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Worked by hand (the module doc's Eq. 1 with mu = 1): the open polyline (0,0),(1,0),(2,0),
    /// all three constrained, to (0,0),(1,1),(2,0). x is consistent (0,1,2). For y with
    /// y0 = y2 = a by symmetry: (y1 - a)^2 + 2 a^2 + (y1 - 1)^2; zero derivatives give
    /// y1 = (a + 1)/2 and y1 = 3a, so a = 1/5, y1 = 3/5.
    #[test]
    fn a_three_point_edit_matches_the_minimum_worked_by_hand() {
        let rest = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
        let ed = LaplacianEditor::new(&rest, false, &[0, 1, 2], 1.0).unwrap();
        let got = ed.solve(&[[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]]);
        let want = [[0.0, 0.2], [1.0, 0.6], [2.0, 0.2]];
        for (g, w) in got.iter().zip(want) {
            assert!((g[0] - w[0]).abs() < 1e-12 && (g[1] - w[1]).abs() < 1e-12, "{got:?}");
        }
    }

    #[test]
    fn a_translated_constraint_set_translates_the_shape_exactly() {
        let rest: Vec<Point> = (0..32)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 32.0;
                [10.0 * a.cos() + 3.0 * (3.0 * a).sin(), 7.0 * a.sin()]
            })
            .collect();
        let ed = LaplacianEditor::new(&rest, true, &[0, 9, 20], 1.0).unwrap();
        let got = ed.solve(&[0, 9, 20].map(|i| [rest[i][0] + 5.0, rest[i][1] - 2.0]));
        for (g, r) in got.iter().zip(&rest) {
            assert!((g[0] - r[0] - 5.0).abs() < 1e-9 && (g[1] - r[1] + 2.0).abs() < 1e-9);
        }
    }

    /// A second implementation: the objective minimised by plain gradient descent must not go
    /// below the factored solution, and the solution's gradient is zero.
    #[test]
    fn the_solution_is_the_objectives_minimum() {
        let rest: Vec<Point> = (0..12).map(|i| [i as f64, ((i * 7) % 5) as f64 * 0.3]).collect();
        let cons = [0usize, 5, 11];
        let targets = [[0.0, 1.0], [5.0, 3.0], [11.0, -1.0]];
        let mu = 2.5;
        let ed = LaplacianEditor::new(&rest, false, &cons, mu).unwrap();
        let sol = ed.solve(&targets);
        let lap_of = |v: &[Point], i: usize| {
            let (lp, ln) = (dist(rest[i - 1], rest[i]), dist(rest[i], rest[i + 1]));
            let a = ln / (lp + ln);
            [0, 1].map(|k| v[i][k] - a * v[i - 1][k] - (1.0 - a) * v[i + 1][k])
        };
        let objective = |v: &[Point]| {
            let mut e = 0.0;
            for i in 1..v.len() - 1 {
                let (l, s) = (lap_of(v, i), lap_of(&rest, i));
                e += (l[0] - s[0]).powi(2) + (l[1] - s[1]).powi(2);
            }
            for (&c, t) in cons.iter().zip(&targets) {
                e += mu * ((v[c][0] - t[0]).powi(2) + (v[c][1] - t[1]).powi(2));
            }
            e
        };
        let best = objective(&sol);
        // Numerical gradient at the solution is ~0; nudging any coordinate raises the energy.
        for i in 0..sol.len() {
            for k in 0..2 {
                for h in [1e-4, -1e-4] {
                    let mut v = sol.clone();
                    v[i][k] += h;
                    assert!(objective(&v) >= best - 1e-12, "vertex {i} coord {k}");
                }
            }
        }
        let mut v = rest.clone();
        for _ in 0..20_000 {
            let e0 = objective(&v);
            let mut g = vec![[0.0; 2]; v.len()];
            for i in 0..v.len() {
                for k in 0..2 {
                    let mut w = v.clone();
                    w[i][k] += 1e-6;
                    g[i][k] = (objective(&w) - e0) / 1e-6;
                }
            }
            for i in 0..v.len() {
                for k in 0..2 {
                    v[i][k] -= 0.05 * g[i][k];
                }
            }
        }
        assert!(objective(&v) >= best - 1e-9 && objective(&v) - best < 1e-3, "{} vs {best}", objective(&v));
    }

    #[test]
    fn bad_setups_are_refused_by_name() {
        let rest = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
        assert_eq!(LaplacianEditor::new(&rest, false, &[], 1.0).unwrap_err(), LaplacianError::NoConstraint);
        assert_eq!(
            LaplacianEditor::new(&rest, false, &[3], 1.0).unwrap_err(),
            LaplacianError::ConstraintIndex { index: 3, len: 3 }
        );
        assert!(matches!(
            LaplacianEditor::new(&rest[..2], true, &[0], 1.0),
            Err(LaplacianError::Size { .. })
        ));
        assert!(LaplacianEditor::new(&rest, false, &[0], f64::NAN).is_err());
    }
}
