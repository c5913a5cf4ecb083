//! Manipulability and compliance ellipsoids (paper Sec. V-C, Fig. 8): the image of the
//! unit ball under a 3 × k matrix A, {A z : ‖z‖ ≤ 1}. Its semi-axes are the singular
//! values of A and its axes the left singular vectors; for a 3 × n_q Jacobian these are
//! the square roots of the eigenvalues and the eigenvectors of A Aᵀ (3 × 3).
//!
//! A is reduced to a 3 × 3 lower-triangular L with A = L Qᵀ (Gram–Schmidt on its rows,
//! twice for orthogonality) and L is decomposed by one-sided Jacobi; A Aᵀ is never
//! formed, so a thin ellipsoid keeps its small semi-axis to working precision.

use nalgebra::{Dim, Matrix, Matrix3, RawStorage, Vector3};
use serde::Serialize;

/// One ellipsoid: semi-axes in decreasing order and their unit directions (world frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Ellipsoid {
    /// Semi-axes σ₁ ≥ σ₂ ≥ σ₃ ≥ 0 (the singular values of the matrix), in its units:
    /// J_p \[m/m\], J_o \[rad/m\], C_p \[m/N\], C_o \[rad/(N·m)\].
    pub semi_axes: [f64; 3],
    /// `directions[k]` is the unit axis of `semi_axes[k]` (a left singular vector), its
    /// largest component made positive.
    pub directions: [[f64; 3]; 3],
}

impl Ellipsoid {
    /// The ellipsoid of the 3 × k matrix `a` (k ≥ 1; a `DMatrix` or a view of one).
    ///
    /// # Panics
    /// If `a` does not have 3 rows (a programmer error).
    #[track_caller]
    pub fn of<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(a: &Matrix<f64, R, C, S>) -> Self {
        assert_eq!(a.nrows(), 3, "Ellipsoid::of: expected 3 rows");
        Self::of_lower(&row_compression(a))
    }

    /// The ellipsoid of a 3 × 3 matrix.
    pub fn of_matrix3(a: &Matrix3<f64>) -> Self {
        Self::of_lower(a)
    }

    fn of_lower(l: &Matrix3<f64>) -> Self {
        if !l.iter().all(|x| x.is_finite()) {
            return Self {
                semi_axes: [f64::INFINITY; 3],
                directions: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            };
        }
        let (sigma, u) = left_svd3(l);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&i, &j| sigma[j].total_cmp(&sigma[i]));
        let mut semi_axes = [0.0; 3];
        let mut directions = [[0.0; 3]; 3];
        for (k, &i) in order.iter().enumerate() {
            semi_axes[k] = sigma[i];
            let mut d: Vector3<f64> = u.column(i).into_owned();
            let big = d.iamax();
            if d[big] < 0.0 {
                d = -d;
            }
            directions[k] = d.into();
        }
        Self {
            semi_axes,
            directions,
        }
    }

    /// Reciprocal condition number σ₃/σ₁ (0 for a zero or non-finite matrix).
    pub fn rcond(&self) -> f64 {
        ratio(self.semi_axes[2], self.semi_axes[0])
    }
}

/// [`Ellipsoid::rcond`] of [`Ellipsoid::of`]`(a)`, bit for bit, without the axes'
/// directions: the rotations of the singular vectors and the sorting are skipped (the
/// workspace sweep needs six rconds per point and no direction; perf share of the 3 × 3
/// rotations in a sweep 2.00 % → 1.84 %, BENCHMARKS.md, 2026-11-28).
pub(crate) fn rcond_of<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(a: &Matrix<f64, R, C, S>) -> f64 {
    debug_assert_eq!(a.nrows(), 3);
    rcond_of_lower(&row_compression(a))
}

/// [`rcond_of`] for a 3 × 3 matrix (as [`Ellipsoid::of_matrix3`]).
pub(crate) fn rcond_of_matrix3(a: &Matrix3<f64>) -> f64 {
    rcond_of_lower(a)
}

/// σ_min/σ_max of `l` by the rotations of [`Ellipsoid::of_lower`].
fn rcond_of_lower(l: &Matrix3<f64>) -> f64 {
    if !l.iter().all(|x| x.is_finite()) {
        return 0.0;
    }
    let sigma = jacobi3::<false>(l).0;
    let (mut min, mut max) = (sigma[0], sigma[0]);
    for &s in &sigma[1..] {
        if s.total_cmp(&max).is_gt() {
            max = s;
        }
        if s.total_cmp(&min).is_lt() {
            min = s;
        }
    }
    ratio(min, max)
}

/// Singular values and left singular vectors (columns) of a 3 × 3 matrix by one-sided
/// Jacobi (Hestenes) on its transpose: Lᵀ V = W Σ gives L = V Σ Wᵀ. Each rotation
/// orthogonalizes two columns of Lᵀ; the singular values come out with high relative
/// accuracy (nalgebra's 3 × 3 SVD goes through the eigenvectors of LᵀL, which squares
/// the condition number).
fn left_svd3(l: &Matrix3<f64>) -> ([f64; 3], Matrix3<f64>) {
    jacobi3::<true>(l)
}

/// The rotations of [`left_svd3`]; they accumulate the singular vectors only with
/// `VECTORS` (else the identity is returned), the singular values are the same either way.
#[inline(always)]
fn jacobi3<const VECTORS: bool>(l: &Matrix3<f64>) -> ([f64; 3], Matrix3<f64>) {
    let mut b = l.transpose();
    let mut v = Matrix3::identity();
    for _sweep in 0..30 {
        let mut rotated = false;
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            let alpha = b.column(p).norm_squared();
            let beta = b.column(q).norm_squared();
            let gamma = b.column(p).dot(&b.column(q));
            if gamma == 0.0 || gamma.abs() <= f64::EPSILON * (alpha * beta).sqrt() {
                continue;
            }
            rotated = true;
            let zeta = (beta - alpha) / (2.0 * gamma);
            let t = zeta.signum() / (zeta.abs() + (1.0 + zeta * zeta).sqrt());
            let c = 1.0 / (1.0 + t * t).sqrt();
            let s = c * t;
            let rotate = |m: &mut Matrix3<f64>| {
                for r in 0..3 {
                    let (x, y) = (m[(r, p)], m[(r, q)]);
                    m[(r, p)] = c * x - s * y;
                    m[(r, q)] = s * x + c * y;
                }
            };
            rotate(&mut b);
            if VECTORS {
                rotate(&mut v);
            }
        }
        if !rotated {
            break;
        }
    }
    let sigma = [0, 1, 2].map(|k| b.column(k).norm());
    (sigma, v)
}

/// σ_min/σ_max, 0 when σ_max is 0 or either is not finite.
pub(crate) fn ratio(min: f64, max: f64) -> f64 {
    if max > 0.0 && max.is_finite() && min.is_finite() {
        (min / max).max(0.0)
    } else {
        0.0
    }
}

/// Columns of the matrices [`row_compression`] works on without allocating (a design's
/// actuators, [`crate::model::MAX_ACTUATORS`]).
const STACK_COLUMNS: usize = crate::model::MAX_ACTUATORS;

/// L with a = L Qᵀ, L lower-triangular 3 × 3 and Q with orthonormal columns (modified
/// Gram–Schmidt on the rows, repeated once).
fn row_compression<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(
    a: &Matrix<f64, R, C, S>,
) -> Matrix3<f64> {
    let k = a.ncols();
    // Q's three rows, then the current row, in one buffer (these ran as six allocations
    // per call, four calls per analysis): on the stack for up to STACK_COLUMNS columns
    // (every design's J_FK), so an analysis allocates nothing.
    let mut stack = [0.0; 4 * STACK_COLUMNS];
    let mut heap = Vec::new();
    let buf = if k <= STACK_COLUMNS {
        &mut stack[..4 * k]
    } else {
        heap.resize(4 * k, 0.0);
        &mut heap[..]
    };
    let (q, r) = buf.split_at_mut(3 * k);
    let mut l = Matrix3::zeros();
    for i in 0..3 {
        for (x, c) in r.iter_mut().zip(0..k) {
            *x = a[(i, c)];
        }
        for _pass in 0..2 {
            for j in 0..i {
                let qj = &q[j * k..(j + 1) * k];
                let c: f64 = r.iter().zip(qj).map(|(x, y)| x * y).sum();
                l[(i, j)] += c;
                for (x, y) in r.iter_mut().zip(qj) {
                    *x -= c * y;
                }
            }
        }
        let norm = r.iter().map(|x| x * x).sum::<f64>().sqrt();
        l[(i, i)] = norm;
        if norm > 0.0 {
            for (x, y) in q[i * k..(i + 1) * k].iter_mut().zip(r.iter()) {
                *x = y / norm;
            }
        }
    }
    l
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    #[test]
    fn the_rcond_without_directions_is_the_ellipsoids_bit_for_bit() {
        let wave = |k: usize, a: f64| (k as f64 * a).sin() * 10f64.powi(k as i32 % 7 - 3);
        let mut cases: Vec<DMatrix<f64>> = (0..200)
            .map(|c| DMatrix::from_fn(3, 3 + c % 7, |i, j| wave(c * 31 + i * 11 + j, 0.37)))
            .collect();
        cases.push(DMatrix::zeros(3, 6));
        cases.push(DMatrix::from_row_slice(
            3,
            2,
            &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        ));
        let mut infinite = DMatrix::identity(3, 4);
        infinite[(1, 2)] = f64::INFINITY;
        cases.push(infinite);
        for (c, a) in cases.iter().enumerate() {
            let full = Ellipsoid::of(a).rcond();
            assert_eq!(rcond_of(a).to_bits(), full.to_bits(), "case {c}");
            if a.ncols() == 3 {
                let m = Matrix3::from_fn(|i, j| a[(i, j)]);
                let full = Ellipsoid::of_matrix3(&m).rcond();
                assert_eq!(rcond_of_matrix3(&m).to_bits(), full.to_bits(), "case {c}");
            }
        }
    }

    #[test]
    fn semi_axes_and_directions_of_a_known_matrix() {
        // Rows scaled 3, 2, 1 along z, x, y after a rotation of the inputs.
        let a = DMatrix::from_row_slice(
            3,
            4,
            &[0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 3.0, 0.0, 0.0, 0.0],
        );
        let e = Ellipsoid::of(&a);
        for (s, expected) in e.semi_axes.iter().zip([3.0, 2.0, 1.0]) {
            assert!((s - expected).abs() < 1e-14, "{:?}", e.semi_axes);
        }
        for (d, expected) in
            e.directions
                .iter()
                .zip([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        {
            let err: f64 = d.iter().zip(expected).map(|(a, b)| (a - b).abs()).sum();
            assert!(err < 1e-14, "{d:?} vs {expected:?}");
        }
        assert!((e.rcond() - 1.0 / 3.0).abs() < 1e-15);
    }

    #[test]
    fn matches_the_full_svd_of_a_thin_wide_matrix() {
        let a = DMatrix::from_fn(3, 9, |i, j| {
            ((i * 9 + j * j + 1) as f64).sqrt().sin() * 10f64.powi(i as i32 - 4)
        });
        let e = Ellipsoid::of(&a);
        let s = a.clone().singular_values();
        let mut s: Vec<f64> = s.iter().copied().collect();
        s.sort_by(|x, y| y.total_cmp(x));
        for k in 0..3 {
            assert!(
                (e.semi_axes[k] - s[k]).abs() <= 1e-12 * s[k],
                "{k}: {} vs {}",
                e.semi_axes[k],
                s[k]
            );
        }
        // A A^T d_k = σ_k² d_k.
        let g = &a * a.transpose();
        for k in 0..3 {
            let d = nalgebra::DVector::from_row_slice(&e.directions[k]);
            let r = &g * &d - &d * e.semi_axes[k].powi(2);
            assert!(
                r.norm() <= 1e-10 * e.semi_axes[0].powi(2),
                "{k}: {}",
                r.norm()
            );
        }
    }

    #[test]
    fn a_thin_3_by_3_keeps_its_small_axis_to_relative_precision() {
        // Singular values 1, 1e-3, 1e-7 (κ = 1e7: κ² would lose everything).
        let q1 = nalgebra::Rotation3::new(Vector3::new(0.3, -0.2, 0.5));
        let q2 = nalgebra::Rotation3::new(Vector3::new(-0.1, 0.4, 0.2));
        let a = q1.matrix() * Matrix3::from_diagonal(&Vector3::new(1.0, 1e-3, 1e-7)) * q2.matrix();
        let e = Ellipsoid::of_matrix3(&a);
        for (s, expected) in e.semi_axes.iter().zip([1.0, 1e-3, 1e-7]) {
            assert!((s - expected).abs() <= 1e-9 * expected, "{:?}", e.semi_axes);
        }
        let d = Vector3::from(e.directions[2]);
        let col = q1.matrix().column(2).into_owned();
        assert!((d.dot(&col).abs() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_rank_deficient_matrix_has_a_zero_axis_and_rcond_zero() {
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let e = Ellipsoid::of(&a);
        assert!(e.semi_axes[2].abs() < 1e-15, "{:?}", e.semi_axes);
        assert!(e.rcond() < 1e-15);
        assert!(e.semi_axes.iter().all(|x| x.is_finite()));
        let zero = Ellipsoid::of(&DMatrix::zeros(3, 6));
        assert_eq!(zero.rcond(), 0.0);
        assert_eq!(zero.semi_axes, [0.0; 3]);
    }
}
