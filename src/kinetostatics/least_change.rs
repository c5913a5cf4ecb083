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
//! The arithmetic is nalgebra's, bit for bit (tests compare): S is summed as
//! matrixmultiply's FMA kernels sum nalgebra's product of the scaled A and its transpose
//! ([`scaled_gram_lower`], which skips the products of the zero blocks: a leg's columns
//! touch only its own rows and the platform's), factored by [`NalgebraCholesky`],
//! nalgebra's algorithm on contiguous slices. Per warm within-limits step of the 9-DoF
//! design (callgrind, three step matrices, two factorizations, three solves) the step
//! rule's algebra went from 541 k to 366 k instructions with [`NalgebraCholesky`] and
//! [`scaled_step_matrix`] on slices (2026-11-26). S by tiles instead of matrixmultiply's
//! dense product: 2.9 → 1.9 µs a product, the warm step within the limits 157–159 →
//! 147–150 µs, least-norm 147–152 → 138–141 µs (interleaved, 2026-11-26, sixth session).
//!
//! Tried and dropped (2026-11-26): S summed by columns and factored by a hand-written
//! AVX2 Cholesky of another summation order. Per factorization it took about the time
//! of nalgebra's product and Cholesky, and its round-off moved the 9-DoF sweeps' maps
//! (0.3 % of the cells, on other branches near folds).

use nalgebra::{DMatrix, DVector};

use crate::boundary::BoundaryJacobians;
use crate::linalg::{NalgebraCholesky, nalgebra_dot, scaled_gram_lower};

/// The constraint matrix of a step in scaled variables, A = W \[B_q U, B_u S\], and S:
/// rows weighted by `weights` (W), the q columns in `q_units` (U: 1 for metres, the
/// limits for q in units of its range) and each leg-unknown column scaled to unit norm
/// (S = diag(1 / ‖W B_u e_j‖), 1 for a zero column).
///
/// Written column by column on slices, every entry once (no zeroed matrix first), the
/// norm by [`nalgebra_dot`]: bitwise the values nalgebra's column views, `norm` and
/// `scale_mut` gave, at 14.3 k instead of 49.3 k instructions per call (callgrind, the
/// 9-DoF design; a warm within-limits step makes three calls).
pub(super) fn scaled_step_matrix(
    blocks: &BoundaryJacobians,
    weights: &DVector<f64>,
    q_units: &[f64],
) -> (DMatrix<f64>, Vec<f64>) {
    let (m, nq, ny) = (blocks.b_q.nrows(), q_units.len(), blocks.b_u.ncols());
    let w = weights.as_slice();
    let mut data = Vec::with_capacity(m * (nq + ny));
    for (col, unit) in blocks.b_q.as_slice().chunks_exact(m).zip(q_units) {
        data.extend(col.iter().zip(w).map(|(b, w)| w * b * unit));
    }
    let mut y_scale = Vec::with_capacity(ny);
    for col in blocks.b_u.as_slice().chunks_exact(m) {
        let start = data.len();
        data.extend(col.iter().zip(w).map(|(b, w)| w * b));
        let out = &mut data[start..];
        let norm = nalgebra_dot(out, out).sqrt();
        let scale = if norm > 0.0 { 1.0 / norm } else { 1.0 };
        out.iter_mut().for_each(|x| *x *= scale);
        y_scale.push(scale);
    }
    (DMatrix::from_vec(m, nq + ny, data), y_scale)
}

/// The factorized least-change problem of one A, P and set of fixed variables.
#[derive(Debug, Clone)]
pub(super) struct LeastChange {
    /// Cholesky factor of S = A_f P_f⁻¹ A_fᵀ.
    s: NalgebraCholesky,
    /// Whether each variable is fixed.
    fixed: Vec<bool>,
}

impl LeastChange {
    /// Factors the problem of `a` (m × n), the diagonal `p` (n values > 0) and the variables
    /// marked in `fixed` (n flags); `None` when S is not positive definite to working
    /// precision (A_f without full row rank).
    pub(super) fn factor(a: &DMatrix<f64>, p: &[f64], fixed: &[bool]) -> Option<Self> {
        let scales: Vec<f64> = fixed
            .iter()
            .zip(p)
            .map(|(&fixed, &p)| if fixed { 0.0 } else { 1.0 / p.sqrt() })
            .collect();
        let s = NalgebraCholesky::new(scaled_gram_lower(a, &scales))?;
        Some(Self {
            s,
            fixed: fixed.to_vec(),
        })
    }

    /// The least-norm step of the factored problem without fixed variables and with c = 0,
    /// into `z` (n): λ = S⁻¹ `v` (m; overwritten with λ) and z = −P⁻¹ Aᵀ λ, with `at`
    /// (n) for Aᵀ λ. Bit for bit [`LeastChange::solve`] with b = −v, in the caller's
    /// buffers (the least-norm step rule's solve allocated six vectors, now one: a warm
    /// 1 mm least-norm step of the 9-DoF design, four solves, 1 075.2 k → 1 059.8 k
    /// instructions, callgrind). `false` if a value is not finite.
    pub(super) fn least_norm_step(
        &self,
        a: &DMatrix<f64>,
        p: &[f64],
        v: &mut DVector<f64>,
        at: &mut DVector<f64>,
        z: &mut [f64],
    ) -> bool {
        debug_assert!(!self.fixed.contains(&true));
        self.s.solve_in_place(v.as_mut_slice());
        a.tr_mul_to(v, at);
        for ((z, at), p) in z.iter_mut().zip(at.iter()).zip(p) {
            *z = -(0.0 + at) / p;
        }
        z.iter().chain(v.iter()).all(|v| v.is_finite())
    }

    /// z (n) and λ (m) for `a`, `p` (as factored), linear term `c` (n), right-hand side
    /// `b` (m) and `values` (n; read at the fixed variables): stationarity of the free
    /// variables P z + c + Aᵀ λ = 0. `None` if a value is not finite.
    #[cfg(any(feature = "qp", test))]
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
                // nalgebra's `axpy(coefficient, a_j, 1)`, entry by entry: y + coefficient·x.
                let column = &a.as_slice()[j * a.nrows()..(j + 1) * a.nrows()];
                for (y, x) in rhs.iter_mut().zip(column) {
                    *y += coefficient * x;
                }
            }
        }
        self.s.solve_in_place(rhs.as_mut_slice());
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

    /// Whether two sequences of values are the same bit for bit.
    fn same_bits<'a>(
        x: impl IntoIterator<Item = &'a f64>,
        y: impl IntoIterator<Item = &'a f64>,
    ) -> bool {
        x.into_iter()
            .zip(y)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    }

    /// The former factorization, by nalgebra's own operations: the columns of `a`
    /// scaled (0 where fixed, 1/√p else), times the copied transpose, `Cholesky::new`.
    /// `None` on a CPU where nalgebra's product rounds each term apart (no bitwise
    /// reference there: [`crate::linalg::matrixmultiply_fuses`]).
    fn nalgebra_factor(
        a: &DMatrix<f64>,
        p: &[f64],
        fixed: &[bool],
    ) -> Option<nalgebra::Cholesky<f64, nalgebra::Dyn>> {
        if !crate::linalg::matrixmultiply_fuses() {
            return None;
        }
        let mut a_scaled = a.clone();
        for (j, mut col) in a_scaled.column_iter_mut().enumerate() {
            col.scale_mut(if fixed[j] { 0.0 } else { 1.0 / p[j].sqrt() });
        }
        Some(nalgebra::Cholesky::new(&a_scaled * a_scaled.transpose()).unwrap())
    }

    #[test]
    fn the_scaled_step_matrix_is_the_one_of_nalgebras_column_operations() {
        let (m, nq, ny) = (36, 9, 30);
        let mut blocks = BoundaryJacobians {
            b_x: DMatrix::zeros(m, 6),
            b_q: DMatrix::from_fn(m, nq, |i, j| ((i * 7 + j * 13) % 17) as f64 * 1e-3 - 0.008),
            b_w: DMatrix::zeros(m, 6),
            b_u: DMatrix::from_fn(m, ny, |i, j| (((i + 3) * (j + 5)) % 23) as f64 * 0.37 - 4.0),
        };
        blocks.b_u.column_mut(4).fill(0.0);
        let weights = DVector::from_fn(m, |i, _| 1.0 + (i % 5) as f64 * 0.25);
        let units: Vec<f64> = (0..nq).map(|j| 0.01 + 0.001 * j as f64).collect();
        let (a, y_scale) = scaled_step_matrix(&blocks, &weights, &units);
        // The former construction: nalgebra's column views, norm and scale.
        let mut expected = DMatrix::zeros(m, nq + ny);
        for j in 0..nq {
            for i in 0..m {
                expected[(i, j)] = weights[i] * blocks.b_q[(i, j)] * units[j];
            }
        }
        for j in 0..ny {
            let mut col = expected.column_mut(nq + j);
            for i in 0..m {
                col[i] = weights[i] * blocks.b_u[(i, j)];
            }
            let norm = col.norm();
            let s = if norm > 0.0 { 1.0 / norm } else { 1.0 };
            col.scale_mut(s);
            assert_eq!(y_scale[j].to_bits(), s.to_bits());
        }
        assert_eq!(y_scale[4], 1.0);
        assert!(same_bits(a.iter(), expected.iter()));
    }

    #[test]
    fn the_factor_is_the_one_of_the_copied_transpose_bit_for_bit() {
        let (m, n) = (36, 39);
        let a = DMatrix::from_fn(m, n, |i, j| {
            (((i + 2) * (j + 7)) % 29) as f64 * 0.11 - 1.5 + if i == j % m { 4.0 } else { 0.0 }
        });
        let p: Vec<f64> = (0..n).map(|j| if j < 9 { 1.0 } else { 1e-2 }).collect();
        let mut fixed = vec![false; n];
        fixed[3] = true;
        let factor = LeastChange::factor(&a, &p, &fixed).unwrap();
        // The former construction: a scaled copy times its copied transpose.
        let Some(expected) = nalgebra_factor(&a, &p, &fixed) else {
            return;
        };
        assert!(same_bits(factor.s.l().iter(), expected.l().iter()));
    }

    #[test]
    fn the_solution_is_the_one_of_nalgebras_operations_bit_for_bit() {
        let (m, n) = (36, 45);
        let a = DMatrix::from_fn(m, n, |i, j| {
            (((i + 5) * (j + 3)) % 37) as f64 * 0.09 - 1.6 + if i == j { 3.0 } else { 0.0 }
        });
        let p: Vec<f64> = (0..n).map(|j| if j < 9 { 1.0 } else { 1e-2 }).collect();
        let c: Vec<f64> = (0..n)
            .map(|j| if j < 9 { 0.1 * j as f64 - 0.4 } else { 0.0 })
            .collect();
        let b: Vec<f64> = (0..m).map(|i| (i as f64 * 0.37).cos() * 1e-3).collect();
        let mut fixed = vec![false; n];
        fixed[2] = true;
        let mut values = vec![0.0; n];
        values[2] = 0.25;
        let (z, lambda) = LeastChange::factor(&a, &p, &fixed)
            .unwrap()
            .solve(&a, &p, &c, &b, &values)
            .unwrap();
        // The former computation, with nalgebra's own operations throughout.
        let Some(chol) = nalgebra_factor(&a, &p, &fixed) else {
            return;
        };
        let mut rhs = DVector::from_iterator(m, b.iter().map(|v| -v));
        for j in 0..n {
            let coefficient = if fixed[j] { values[j] } else { -c[j] / p[j] };
            if coefficient != 0.0 {
                rhs.axpy(coefficient, &a.column(j), 1.0);
            }
        }
        chol.solve_mut(&mut rhs);
        let at_lambda = a.tr_mul(&rhs);
        let expected_z = DVector::from_fn(n, |j, _| {
            if fixed[j] {
                values[j]
            } else {
                -(c[j] + at_lambda[j]) / p[j]
            }
        });
        assert!(same_bits(lambda.iter(), rhs.iter()));
        assert!(same_bits(z.iter(), expected_z.iter()));
    }

    #[test]
    fn the_least_norm_step_is_the_solution_bit_for_bit() {
        let (m, n) = (36, 48);
        let a = DMatrix::from_fn(m, n, |i, j| {
            (((i + 3) * (j + 7)) % 41) as f64 * 0.07 - 1.3 + if i == j { 2.0 } else { 0.0 }
        });
        let p: Vec<f64> = (0..n).map(|j| if j < 9 { 1.0 } else { 1e-6 }).collect();
        // Residual-like entries of both signs and scales, W r of the least-norm step.
        let v: Vec<f64> = (0..m)
            .map(|i| (i as f64 * 0.61).sin() * 10f64.powi(i as i32 % 7 - 5))
            .collect();
        let f = LeastChange::factor(&a, &p, &vec![false; n]).unwrap();
        let b: Vec<f64> = v.iter().map(|v| -v).collect();
        let (z, lambda) = f.solve(&a, &p, &vec![0.0; n], &b, &vec![0.0; n]).unwrap();
        let (mut lambda_step, mut at) = (DVector::from_vec(v), DVector::zeros(n));
        let mut z_step = vec![0.0; n];
        assert!(f.least_norm_step(&a, &p, &mut lambda_step, &mut at, &mut z_step));
        assert!(same_bits(lambda.iter(), lambda_step.iter()));
        assert!(same_bits(z.iter(), z_step.iter()));
    }

    #[test]
    fn rank_deficient_free_columns_are_no_factorization() {
        let a = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 2.0, 0.0, 0.0]);
        assert!(LeastChange::factor(&a, &[1.0; 3], &[false; 3]).is_none());
    }
}
