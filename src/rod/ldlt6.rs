//! LDLᵀ factorization of the symmetric positive definite 6×6 strain matrix of eq. (5),
//! on plain arrays so the fixed-size loops unroll (the rod's innermost kernel).

/// A factored symmetric 6×6 matrix: M = L D Lᵀ, L unit lower triangular.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ldlt6 {
    /// Strictly lower part of L (row-major; upper part unused).
    l: [[f64; 6]; 6],
    /// 1 / D.
    inv_d: [f64; 6],
}

impl Ldlt6 {
    /// The identity (a placeholder before the first factorization).
    pub fn identity() -> Self {
        Self {
            l: [[0.0; 6]; 6],
            inv_d: [1.0; 6],
        }
    }

    /// Factors the matrix whose lower triangle is in `m` (the upper part is not read).
    /// `None` if a pivot is not positive and finite (the matrix is not positive definite).
    #[inline]
    pub fn factor(m: &[[f64; 6]; 6]) -> Option<Self> {
        let mut l = [[0.0; 6]; 6];
        let mut d = [0.0; 6];
        let mut inv_d = [0.0; 6];
        for j in 0..6 {
            let mut dj = m[j][j];
            for k in 0..j {
                dj -= l[j][k] * l[j][k] * d[k];
            }
            if !(dj > 0.0 && dj.is_finite()) {
                return None;
            }
            d[j] = dj;
            inv_d[j] = 1.0 / dj;
            for i in j + 1..6 {
                let mut s = m[i][j];
                for k in 0..j {
                    s -= l[i][k] * l[j][k] * d[k];
                }
                l[i][j] = s * inv_d[j];
            }
        }
        Some(Self { l, inv_d })
    }

    /// Solves M x = b.
    #[inline]
    pub fn solve(&self, mut b: [f64; 6]) -> [f64; 6] {
        for i in 1..6 {
            for k in 0..i {
                b[i] -= self.l[i][k] * b[k];
            }
        }
        for i in 0..6 {
            b[i] *= self.inv_d[i];
        }
        for i in (0..5).rev() {
            for k in i + 1..6 {
                b[i] -= self.l[k][i] * b[k];
            }
        }
        b
    }
}

impl Ldlt6 {
    /// Solves M x = b for `n` right-hand sides stored by component (`b[row][rhs]`).
    #[inline]
    pub fn solve_lanes<const N: usize>(&self, b: &mut [[f64; N]; 6], n: usize) {
        for i in 1..6 {
            for k in 0..i {
                let l = self.l[i][k];
                let (head, tail) = b.split_at_mut(i);
                for j in 0..n {
                    tail[0][j] -= l * head[k][j];
                }
            }
        }
        for i in 0..6 {
            let d = self.inv_d[i];
            for x in b[i][..n].iter_mut() {
                *x *= d;
            }
        }
        for i in (0..5).rev() {
            for k in i + 1..6 {
                let l = self.l[k][i];
                let (head, tail) = b.split_at_mut(k);
                for j in 0..n {
                    head[i][j] -= l * tail[0][j];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix6, Vector6};

    #[test]
    fn solves_a_symmetric_positive_definite_system() {
        let a = Matrix6::from_fn(|i, j| ((i * 7 + j * 3) % 5) as f64 - 2.0);
        let spd = a * a.transpose() + Matrix6::identity() * 0.5;
        let mut m = [[0.0; 6]; 6];
        for i in 0..6 {
            for j in 0..6 {
                m[i][j] = spd[(i, j)];
            }
        }
        let x = Vector6::new(1.0, -2.0, 0.5, 3.0, 0.0, -1.0);
        let b = spd * x;
        let sol = Ldlt6::factor(&m)
            .unwrap()
            .solve([b[0], b[1], b[2], b[3], b[4], b[5]]);
        for i in 0..6 {
            assert!((sol[i] - x[i]).abs() < 1e-10, "{sol:?}");
        }
    }

    #[test]
    fn lane_solve_matches_single_solves() {
        let a = Matrix6::from_fn(|i, j| ((i * 5 + j * 2) % 7) as f64 - 3.0);
        let spd = a * a.transpose() + Matrix6::identity();
        let mut m = [[0.0; 6]; 6];
        for i in 0..6 {
            for j in 0..6 {
                m[i][j] = spd[(i, j)];
            }
        }
        let f = Ldlt6::factor(&m).unwrap();
        let mut lanes = [[0.0; 3]; 6];
        for i in 0..6 {
            for j in 0..3 {
                lanes[i][j] = (i as f64 + 1.0) * (j as f64 - 1.0) + 0.5;
            }
        }
        let mut solved = lanes;
        f.solve_lanes(&mut solved, 3);
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
    fn rejects_an_indefinite_matrix() {
        let mut m = [[0.0; 6]; 6];
        for (i, row) in m.iter_mut().enumerate() {
            row[i] = if i == 3 { -1.0 } else { 1.0 };
        }
        assert!(Ldlt6::factor(&m).is_none());
    }
}
