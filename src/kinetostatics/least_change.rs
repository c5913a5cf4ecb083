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
//! new b ([`LeastChange::solve`]) costs two triangular solves.
//!
//! S's lower triangle is summed column by column of A (contiguous inner loops) and
//! factored in place by a plain column Cholesky: nalgebra's product (through
//! matrixmultiply, with packing) and its generic Cholesky took 15 µs of the 36 × 36
//! factorizations of a warm 1 mm within-limits step of the 9-DoF design, about 9 % of it
//! (perf, 2026-11-26; BENCHMARKS.md "The redundant IK's linear algebra").

use nalgebra::{DMatrix, DVector};

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
    // Column by column through slices (column-major storage).
    let weights = weights.as_slice();
    let (q_part, y_part) = a.as_mut_slice().split_at_mut(m * nq);
    let b_q = blocks.b_q.as_slice();
    for (j, out) in q_part.chunks_exact_mut(m).enumerate() {
        for ((o, w), b) in out.iter_mut().zip(weights).zip(&b_q[j * m..(j + 1) * m]) {
            *o = w * b * q_units[j];
        }
    }
    let mut y_scale = vec![1.0; ny];
    let b_u = blocks.b_u.as_slice();
    for (j, out) in y_part.chunks_exact_mut(m).enumerate() {
        for ((o, w), b) in out.iter_mut().zip(weights).zip(&b_u[j * m..(j + 1) * m]) {
            *o = w * b;
        }
        let norm = out.iter().map(|x| x * x).sum::<f64>().sqrt();
        y_scale[j] = if norm > 0.0 { 1.0 / norm } else { 1.0 };
        for o in out.iter_mut() {
            *o *= y_scale[j];
        }
    }
    (a, y_scale)
}

/// The factorized least-change problem of one A, P and set of fixed variables.
#[derive(Debug, Clone)]
pub(super) struct LeastChange {
    /// The Cholesky factor L of S = A_f P_f⁻¹ A_fᵀ = L Lᵀ in the lower triangle (the
    /// upper one holds nothing of use).
    l: DMatrix<f64>,
    /// Whether each variable is fixed.
    fixed: Vec<bool>,
}

impl LeastChange {
    /// Factors the problem of `a` (m × n), the diagonal `p` (n values > 0) and the variables
    /// marked in `fixed` (n flags); `None` when S is not positive definite to working
    /// precision (A_f without full row rank).
    pub(super) fn factor(a: &DMatrix<f64>, p: &[f64], fixed: &[bool]) -> Option<Self> {
        let mut l = DMatrix::<f64>::zeros(a.nrows(), a.nrows());
        schur_cholesky(a, p, fixed, &mut l).then(|| Self {
            l,
            fixed: fixed.to_vec(),
        })
    }

    /// x = S⁻¹ x in place: L y = x forward, then Lᵀ x = y backward.
    fn solve_s(&self, x: &mut [f64]) {
        solve_cholesky(&self.l, x);
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
        self.solve_s(rhs.as_mut_slice());
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
/// active-set search usually tries the same limits (a factorization is about 4 µs of a
/// warm 1 mm step's 159 µs; BENCHMARKS.md "The redundant IK's linear algebra").
#[derive(Debug, Clone, Default)]
pub(super) struct FactorCache {
    /// A, the diagonal P and the fixed variables of `factor`.
    key: Option<(DMatrix<f64>, Vec<f64>, Vec<bool>)>,
    factor: Option<LeastChange>,
}

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

avx2_dispatch! {
    fn schur_cholesky = schur_cholesky_avx2 / schur_cholesky_inline;
        (a: &DMatrix<f64>, p: &[f64], fixed: &[bool], l: &mut DMatrix<f64>) -> bool
}

avx2_dispatch! {
    fn solve_cholesky = solve_cholesky_avx2 / solve_cholesky_inline;
        (l: &DMatrix<f64>, x: &mut [f64])
}

/// The lower triangle of `l` (m × m, zero on entry) becomes the Cholesky factor of
/// S = A_f P_f⁻¹ A_fᵀ; false where S is not positive definite to working precision.
#[inline(always)]
fn schur_cholesky_inline(
    a: &DMatrix<f64>,
    p: &[f64],
    fixed: &[bool],
    l: &mut DMatrix<f64>,
) -> bool {
    let m = a.nrows();
    // S (lower triangle) = Σ_j a_j a_jᵀ / p_j over the free columns a_j.
    for (j, column) in a.column_iter().enumerate() {
        if fixed[j] {
            continue;
        }
        let column = column.as_slice();
        let inv_p = 1.0 / p[j];
        for k in 0..m {
            let f = column[k] * inv_p;
            if f != 0.0 {
                let target = &mut l.as_mut_slice()[k * m + k..(k + 1) * m];
                for (t, x) in target.iter_mut().zip(&column[k..]) {
                    *t += x * f;
                }
            }
        }
    }
    // L Lᵀ = S in place, column by column (right-looking).
    for k in 0..m {
        let d = l[(k, k)];
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        let inv_d = 1.0 / d;
        let data = l.as_mut_slice();
        data[k * m + k] = d;
        for x in &mut data[k * m + k + 1..(k + 1) * m] {
            *x *= inv_d;
        }
        let (done, rest) = data.split_at_mut((k + 1) * m);
        let pivot = &done[k * m..(k + 1) * m];
        for j in k + 1..m {
            let f = pivot[j];
            if f != 0.0 {
                let target = &mut rest[(j - k - 1) * m + j..(j - k) * m];
                for (t, x) in target.iter_mut().zip(&pivot[j..]) {
                    *t -= x * f;
                }
            }
        }
    }
    true
}

/// x = S⁻¹ x in place for S = L Lᵀ (`l`'s lower triangle): L y = x forward, then
/// Lᵀ x = y backward.
#[inline(always)]
fn solve_cholesky_inline(l: &DMatrix<f64>, x: &mut [f64]) {
    let m = x.len();
    let data = l.as_slice();
    for k in 0..m {
        let column = &data[k * m..(k + 1) * m];
        let v = x[k] / column[k];
        x[k] = v;
        for (t, l) in x[k + 1..].iter_mut().zip(&column[k + 1..]) {
            *t -= l * v;
        }
    }
    for k in (0..m).rev() {
        let column = &data[k * m..(k + 1) * m];
        let dot: f64 = column[k + 1..]
            .iter()
            .zip(&x[k + 1..])
            .map(|(l, v)| l * v)
            .sum();
        x[k] = (x[k] - dot) / column[k];
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
