//! The equality-constrained least-change step of the redundant IK: minimize
//! ½ zᵀ P z + cᵀ z subject to A z = b and z_j = v_j for the fixed j, with P diagonal
//! positive (the least-norm step, and every trial of the QP step's active-set search in
//! `within_limits.rs`).
//!
//! Solved through the Schur complement of the free variables f: with z_f = −P_f⁻¹ (c_f +
//! A_fᵀ λ), the multipliers λ (m) solve S λ = −(b − A_F v_F) − A_f P_f⁻¹ c_f,
//! S = A_f P_f⁻¹ A_fᵀ (m × m, symmetric positive definite when A_f has full row rank), by
//! Cholesky. For the 9-DoF IK (n = 48 unknowns, m = 36 rows) that is a 36 × 36 Cholesky
//! where the full KKT system is an 84 × 84 LU. The factor is kept: a chord step with a
//! new b ([`LeastChange::solve`]) costs two triangular solves, and [`FactorCache`] keeps
//! the last one for a QP that repeats.
//!
//! Tried and dropped (2026-11-26): S summed by columns and factored by a hand-written
//! AVX2 Cholesky. Per factorization it took about the time of nalgebra's product and
//! Cholesky, and its round-off moved the 9-DoF sweeps' maps (0.3 % of the cells, on
//! other branches near folds); nalgebra's factorization is kept bit for bit.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

use crate::boundary::BoundaryJacobians;

/// The constraint matrix of a step in scaled variables, A = W \[B_q U, B_u S\], and S:
/// rows weighted by `weights` (W), the q columns in `q_units` (U: 1 for metres, the
/// limits for q in units of its range) and each leg-unknown column scaled to unit norm
/// (S = diag(1 / ‖W B_u e_j‖), 1 for a zero column).
pub(super) fn scaled_step_matrix(
    blocks: &BoundaryJacobians,
    weights: &DVector<f64>,
    q_units: &[f64],
) -> (DMatrix<f64>, Vec<f64>) {
    let (m, nq, ny) = (blocks.b_q.nrows(), q_units.len(), blocks.b_u.ncols());
    let mut a = DMatrix::zeros(m, nq + ny);
    // Column by column through slices (column-major storage; indexing checked every
    // entry), the same operations in the same order.
    let w = weights.as_slice();
    let b_q = blocks.b_q.as_slice();
    for (j, out) in a.as_mut_slice()[..m * nq].chunks_exact_mut(m).enumerate() {
        for ((o, w), b) in out.iter_mut().zip(w).zip(&b_q[j * m..(j + 1) * m]) {
            *o = w * b * q_units[j];
        }
    }
    let mut y_scale = vec![1.0; ny];
    let b_u = blocks.b_u.as_slice();
    for j in 0..ny {
        let mut col = a.column_mut(nq + j);
        for ((o, w), b) in col.iter_mut().zip(w).zip(&b_u[j * m..(j + 1) * m]) {
            *o = w * b;
        }
        let norm = col.norm();
        y_scale[j] = if norm > 0.0 { 1.0 / norm } else { 1.0 };
        col.scale_mut(y_scale[j]);
    }
    (a, y_scale)
}

/// The factorized least-change problem of one A, P and set of fixed variables.
#[derive(Debug, Clone)]
pub(super) struct LeastChange {
    /// Cholesky factor of S = A_f P_f⁻¹ A_fᵀ.
    s: Cholesky<f64, Dyn>,
    /// Whether each variable is fixed.
    fixed: Vec<bool>,
}

impl LeastChange {
    /// Factors the problem of `a` (m × n), the diagonal `p` (n values > 0) and the variables
    /// marked in `fixed` (n flags); `None` when S is not positive definite to working
    /// precision (A_f without full row rank).
    pub(super) fn factor(a: &DMatrix<f64>, p: &[f64], fixed: &[bool]) -> Option<Self> {
        let mut a_scaled = a.clone();
        for (j, mut col) in a_scaled.column_iter_mut().enumerate() {
            let s = if fixed[j] { 0.0 } else { 1.0 / p[j].sqrt() };
            col.scale_mut(s);
        }
        let s = Cholesky::new(&a_scaled * a_scaled.transpose())?;
        Some(Self {
            s,
            fixed: fixed.to_vec(),
        })
    }

    /// z (n) and λ (m) for `a`, `p` (as factored), linear term `c` (n), right-hand side
    /// `b` (m) and `values` (n; read at the fixed variables): stationarity of the free
    /// variables P z + c + Aᵀ λ = 0. `None` if a value is not finite.
    pub(super) fn solve(
        &self,
        a: &DMatrix<f64>,
        p: &[f64],
        c: &[f64],
        b: &[f64],
        values: &[f64],
    ) -> Option<(DVector<f64>, DVector<f64>)> {
        let n = a.ncols();
        // rhs = −(b − A_F v_F) − A_f P_f⁻¹ c_f.
        let mut rhs = DVector::from_iterator(b.len(), b.iter().map(|v| -v));
        for j in 0..n {
            let coefficient = if self.fixed[j] {
                values[j]
            } else {
                -c[j] / p[j]
            };
            if coefficient != 0.0 {
                rhs.axpy(coefficient, &a.column(j), 1.0);
            }
        }
        self.s.solve_mut(&mut rhs);
        let lambda = rhs;
        let at_lambda = a.tr_mul(&lambda);
        let z = DVector::from_fn(n, |j, _| {
            if self.fixed[j] {
                values[j]
            } else {
                -(c[j] + at_lambda[j]) / p[j]
            }
        });
        let finite = z.iter().chain(lambda.iter()).all(|v| v.is_finite());
        finite.then_some((z, lambda))
    }
}

/// The last [`LeastChange`] factorization with its inputs, reused while they repeat: the
/// chord step of the within-limits IK solves the QP of the same Jacobian again, and its
/// active-set search usually tries the same limits (a factorization is about 4–6 µs of a
/// warm 1 mm step; BENCHMARKS.md "The redundant IK's linear algebra").
#[cfg(feature = "qp")]
#[derive(Debug, Clone, Default)]
pub(super) struct FactorCache {
    /// A, the diagonal P and the fixed variables of `factor`.
    key: Option<(DMatrix<f64>, Vec<f64>, Vec<bool>)>,
    factor: Option<LeastChange>,
}

#[cfg(feature = "qp")]
impl FactorCache {
    /// [`LeastChange::factor`] of `a`, `p`, `fixed`, from the cache if it holds them.
    pub(super) fn factor(
        &mut self,
        a: &DMatrix<f64>,
        p: &[f64],
        fixed: &[bool],
    ) -> Option<&LeastChange> {
        // Compared and copied as slices (nalgebra's `==` and `copy_from` walk the matrix
        // element by element).
        let hit = matches!(&self.key, Some((ka, kp, kf))
            if ka.shape() == a.shape() && ka.as_slice() == a.as_slice() && kp == p && kf == fixed);
        if !hit {
            self.factor = LeastChange::factor(a, p, fixed);
            match &mut self.key {
                Some((ka, kp, kf)) if ka.shape() == a.shape() && kp.len() == p.len() => {
                    ka.as_mut_slice().copy_from_slice(a.as_slice());
                    kp.copy_from_slice(p);
                    kf.copy_from_slice(fixed);
                }
                key => *key = Some((a.clone(), p.to_vec(), fixed.to_vec())),
            }
        }
        self.factor.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::DenseLu;

    /// The same problem through the full KKT system [P Aᵀ Eᵀ; A 0 0; E 0 0] by LU.
    fn by_kkt(
        a: &DMatrix<f64>,
        p: &[f64],
        c: &[f64],
        b: &[f64],
        fixed: &[(usize, f64)],
    ) -> DVector<f64> {
        let (m, n) = a.shape();
        let k = n + m + fixed.len();
        let mut kkt = DMatrix::zeros(k, k);
        let mut rhs = DVector::zeros(k);
        for j in 0..n {
            kkt[(j, j)] = p[j];
            rhs[j] = -c[j];
        }
        kkt.view_mut((n, 0), (m, n)).copy_from(a);
        kkt.view_mut((0, n), (n, m)).copy_from(&a.transpose());
        for i in 0..m {
            rhs[n + i] = b[i];
        }
        for (r, &(j, v)) in fixed.iter().enumerate() {
            kkt[(n + m + r, j)] = 1.0;
            kkt[(j, n + m + r)] = 1.0;
            rhs[n + m + r] = v;
        }
        let mut lu = DenseLu::new(k);
        lu.factor(&kkt).unwrap();
        lu.solve_in_place(&mut rhs);
        rhs
    }

    #[test]
    fn the_schur_solution_is_the_kkt_solution() {
        let (m, n) = (4, 7);
        let a = DMatrix::from_fn(m, n, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 - 5.0 + 0.1 * j as f64
        });
        let p = [1.0, 1.0, 0.5, 1e-2, 1e-2, 1e-2, 1e-2];
        let c = [0.3, -0.2, 0.0, 0.0, 0.1, 0.0, 0.0];
        let b = [1.0, -2.0, 0.5, 0.25];
        let fixed = [(1, 0.7), (4, -0.2)];
        let mut flags = vec![false; n];
        let mut values = vec![0.0; n];
        for &(j, v) in &fixed {
            flags[j] = true;
            values[j] = v;
        }
        let f = LeastChange::factor(&a, &p, &flags).unwrap();
        let (z, lambda) = f.solve(&a, &p, &c, &b, &values).unwrap();
        let reference = by_kkt(&a, &p, &c, &b, &fixed);
        for j in 0..n {
            assert!(
                (z[j] - reference[j]).abs() < 1e-12,
                "z[{j}] {} vs {}",
                z[j],
                reference[j]
            );
        }
        for i in 0..m {
            assert!((lambda[i] - reference[n + i]).abs() < 1e-10, "λ[{i}]");
        }
        // A z = b, and the fixed values held.
        let residual = &a * &z - DVector::from_column_slice(&b);
        assert!(residual.amax() < 1e-12, "{residual}");
        assert_eq!((z[1], z[4]), (0.7, -0.2));
    }

    #[cfg(feature = "qp")]
    #[test]
    fn the_cache_returns_the_factorization_of_its_inputs() {
        let a = DMatrix::from_fn(3, 5, |i, j| ((i * 5 + j * 2) % 7) as f64 - 3.0);
        let p = [1.0, 0.5, 1e-2, 1e-2, 1e-2];
        let (free, one_fixed) = ([false; 5], [true, false, false, false, false]);
        let b = [1.0, -1.0, 0.5];
        let solve =
            |a: &DMatrix<f64>, f: &LeastChange| f.solve(a, &p, &[0.0; 5], &b, &[0.2; 5]).unwrap().0;
        let mut other = a.clone();
        other[(2, 4)] += 1.0;
        let mut cache = FactorCache::default();
        for (a, fixed) in [(&a, free), (&a, free), (&a, one_fixed), (&other, one_fixed)] {
            let fresh = solve(a, &LeastChange::factor(a, &p, &fixed).unwrap());
            assert_eq!(solve(a, cache.factor(a, &p, &fixed).unwrap()), fresh);
        }
    }

    #[test]
    fn rank_deficient_free_columns_are_no_factorization() {
        let a = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 2.0, 0.0, 0.0]);
        assert!(LeastChange::factor(&a, &[1.0; 3], &[false; 3]).is_none());
    }
}
