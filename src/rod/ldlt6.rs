//! The symmetric positive definite 6×6 strain system of eq. (5), solved by its 3×3 block
//! structure: M = \[A Bᵀ; B C\] with A the shear/extension block, C the bending/torsion
//! block. A⁻¹ and the Schur complement S = C − B A⁻¹ Bᵀ are inverted in closed form
//! (fixed-size code, no loops: this is the rod's innermost kernel). Generic over the
//! kernel's scalar ([`Real`]): one leg, or one leg per SIMD lane.

use nalgebra::{Matrix3, Vector3};

use crate::rod::lanes::{Real, fma, mat_mul, mat_vec, tr_mat_vec};

/// A factored 6×6 block matrix \[A Bᵀ; B C\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ldlt6<T: Real = f64> {
    a_inv: Matrix3<T>,
    /// X = B A⁻¹.
    x: Matrix3<T>,
    b: Matrix3<T>,
    s_inv: Matrix3<T>,
}

impl<T: Real> Ldlt6<T> {
    /// The identity (a placeholder before the first factorization).
    pub fn identity() -> Self {
        Self {
            a_inv: Matrix3::identity(),
            x: Matrix3::zeros(),
            b: Matrix3::zeros(),
            s_inv: Matrix3::identity(),
        }
    }

    /// Factors \[A Bᵀ; B C\] (A, C symmetric; only their upper triangles are read) in
    /// place of the last factorization. False unless A and the Schur complement
    /// S = C − B A⁻¹ Bᵀ are positive on the diagonal and have finite inverses (both are
    /// positive definite for τ ≥ 0), in every lane; the factorization is then not usable.
    ///
    /// In place rather than returned: the kernel's stage kept its factorization by copying
    /// a returned one (1.2 kB at four lanes: about 1 % of an exact Jacobian's
    /// instructions, callgrind, 2026-11-28). A primal integration now stores it too
    /// (residual 80.4 k → 83.6 k instructions, its time unchanged; BENCHMARKS.md "The
    /// stages' derivatives stored, each sum formed once").
    #[inline(always)]
    pub fn refactor(&mut self, a: &Matrix3<T>, b: &Matrix3<T>, c: &Matrix3<T>) -> bool {
        let Some(a_inv) = symmetric_inverse(a) else {
            return false;
        };
        let x = mat_mul(b, &a_inv);
        // S = C − X Bᵀ (symmetric: the upper triangle suffices).
        let mut s = *c;
        for i in 0..3 {
            for j in i..3 {
                s[(i, j)] -= x[(i, 0)] * b[(j, 0)] + x[(i, 1)] * b[(j, 1)] + x[(i, 2)] * b[(j, 2)];
            }
        }
        let Some(s_inv) = symmetric_inverse(&s) else {
            return false;
        };
        (self.a_inv, self.x, self.b, self.s_inv) = (a_inv, x, *b, s_inv);
        true
    }

    /// Factors \[A Bᵀ; B C\] into a new factorization ([`Ldlt6::refactor`]); `None` where
    /// that is false.
    pub fn factor_blocks(a: &Matrix3<T>, b: &Matrix3<T>, c: &Matrix3<T>) -> Option<Self> {
        let mut factor = Self::identity();
        factor.refactor(a, b, c).then_some(factor)
    }

    /// Solves M \[x1; x2\] = \[b1; b2\].
    #[inline(always)]
    pub fn solve_blocks(&self, b1: &Vector3<T>, b2: &Vector3<T>) -> (Vector3<T>, Vector3<T>) {
        let x2 = mat_vec(&self.s_inv, &(b2 - mat_vec(&self.x, b1)));
        let x1 = mat_vec(&self.a_inv, &(b1 - tr_mat_vec(&self.b, &x2)));
        (x1, x2)
    }

    /// Solves the system of lane `leg` in place for `N` right-hand sides stored by
    /// component (`b[row][rhs]`).
    #[inline(always)]
    pub fn solve_lanes<const N: usize>(&self, leg: usize, b: &mut [[f64; N]; 6]) {
        let (x, s_inv, b_mat, a_inv) = (
            Lane(&self.x, leg),
            Lane(&self.s_inv, leg),
            Lane(&self.b, leg),
            Lane(&self.a_inv, leg),
        );
        let mut t = [[0.0; N]; 3];
        for (c, t_row) in t.iter_mut().enumerate() {
            for j in 0..N {
                let acc = fma(-x[(c, 0)], b[0][j], b[3 + c][j]);
                let acc = fma(-x[(c, 1)], b[1][j], acc);
                t_row[j] = fma(-x[(c, 2)], b[2][j], acc);
            }
        }
        // x2 = S⁻¹ (b2 − X b1)
        for c in 0..3 {
            for j in 0..N {
                let acc = fma(s_inv[(c, 1)], t[1][j], s_inv[(c, 0)] * t[0][j]);
                b[3 + c][j] = fma(s_inv[(c, 2)], t[2][j], acc);
            }
        }
        // x1 = A⁻¹ (b1 − Bᵀ x2)
        for (c, t_row) in t.iter_mut().enumerate() {
            for j in 0..N {
                let acc = fma(-b_mat[(0, c)], b[3][j], b[c][j]);
                let acc = fma(-b_mat[(1, c)], b[4][j], acc);
                t_row[j] = fma(-b_mat[(2, c)], b[5][j], acc);
            }
        }
        for c in 0..3 {
            for j in 0..N {
                let acc = fma(a_inv[(c, 1)], t[1][j], a_inv[(c, 0)] * t[0][j]);
                b[c][j] = fma(a_inv[(c, 2)], t[2][j], acc);
            }
        }
    }
}

/// Lane `.1` of a matrix of the kernel's scalar, read in place.
#[derive(Clone, Copy)]
struct Lane<'a, T: Real>(&'a Matrix3<T>, usize);

impl<T: Real> std::ops::Index<(usize, usize)> for Lane<'_, T> {
    type Output = f64;

    #[inline(always)]
    fn index(&self, ij: (usize, usize)) -> &f64 {
        self.0[ij].lane_ref(self.1)
    }
}

impl Ldlt6<f64> {
    /// Solves M x = b for a 6-vector.
    #[inline]
    pub fn solve(&self, b: [f64; 6]) -> [f64; 6] {
        let (x1, x2) = self.solve_blocks(
            &Vector3::new(b[0], b[1], b[2]),
            &Vector3::new(b[3], b[4], b[5]),
        );
        [x1.x, x1.y, x1.z, x2.x, x2.y, x2.z]
    }
}

/// The inverse of a symmetric 3×3 matrix from its upper triangle, by cofactors; `None`
/// unless its first pivot and determinant are positive and the inverse is finite (in
/// every lane).
#[inline(always)]
fn symmetric_inverse<T: Real>(m: &Matrix3<T>) -> Option<Matrix3<T>> {
    let (a, b, c) = (m[(0, 0)], m[(0, 1)], m[(0, 2)]);
    let (d, e, f) = (m[(1, 1)], m[(1, 2)], m[(2, 2)]);
    let c00 = d * f - e * e;
    let c01 = c * e - b * f;
    let c02 = b * e - c * d;
    let det = a * c00 + b * c01 + c * c02;
    if !(T::all(a.positive()) && T::all(det.positive())) {
        return None;
    }
    let inv = T::one() / det;
    let (i00, i01, i02) = (c00 * inv, c01 * inv, c02 * inv);
    let i11 = (a * f - c * c) * inv;
    let i12 = (b * c - a * e) * inv;
    let i22 = (a * d - b * b) * inv;
    let out = Matrix3::new(i00, i01, i02, i01, i11, i12, i02, i12, i22);
    out.iter().all(|v| T::all(v.finite())).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix6, Vector6};

    fn spd() -> Matrix6<f64> {
        let a = Matrix6::from_fn(|i, j| ((i * 7 + j * 3) % 5) as f64 - 2.0);
        a * a.transpose() + Matrix6::identity() * 0.5
    }

    fn factor(m: &Matrix6<f64>) -> Option<Ldlt6> {
        Ldlt6::factor_blocks(
            &m.fixed_view::<3, 3>(0, 0).into_owned(),
            &m.fixed_view::<3, 3>(3, 0).into_owned(),
            &m.fixed_view::<3, 3>(3, 3).into_owned(),
        )
    }

    #[test]
    fn solves_a_symmetric_positive_definite_system() {
        let m = spd();
        let x = Vector6::new(1.0, -2.0, 0.5, 3.0, 0.0, -1.0);
        let b = m * x;
        let sol = factor(&m)
            .unwrap()
            .solve([b[0], b[1], b[2], b[3], b[4], b[5]]);
        for i in 0..6 {
            assert!((sol[i] - x[i]).abs() < 1e-10, "{sol:?}");
        }
    }

    #[test]
    fn lane_solve_matches_single_solves() {
        let f = factor(&spd()).unwrap();
        let mut lanes = [[0.0; 3]; 6];
        for i in 0..6 {
            for j in 0..3 {
                lanes[i][j] = (i as f64 + 1.0) * (j as f64 - 1.0) + 0.5;
            }
        }
        let mut solved = lanes;
        f.solve_lanes(0, &mut solved);
        for j in 0..3 {
            let single = f.solve([
                lanes[0][j],
                lanes[1][j],
                lanes[2][j],
                lanes[3][j],
                lanes[4][j],
                lanes[5][j],
            ]);
            for i in 0..6 {
                assert!((single[i] - solved[i][j]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn rejects_a_singular_matrix() {
        let mut m = Matrix6::identity();
        m[(4, 4)] = 0.0;
        assert!(factor(&m).is_none());
    }
}
