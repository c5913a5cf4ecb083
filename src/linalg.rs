//! Small dense linear algebra on preallocated storage (no allocation after `new`).

use nalgebra::{DMatrix, DVector};

/// LU factorization with partial pivoting of an n×n matrix, stored in place.
#[derive(Debug, Clone)]
pub struct DenseLu {
    lu: DMatrix<f64>,
    pivots: Vec<usize>,
}

/// The matrix is singular to working precision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Singular {
    /// Column where no usable pivot was found.
    pub column: usize,
}

impl DenseLu {
    /// Storage for n×n matrices.
    pub fn new(n: usize) -> Self {
        Self {
            lu: DMatrix::zeros(n, n),
            pivots: vec![0; n],
        }
    }

    /// Factors a copy of `a`.
    ///
    /// # Errors
    /// [`Singular`] when a pivot is zero or not finite.
    ///
    /// # Panics
    /// If `a` is not of the size given to [`DenseLu::new`].
    #[track_caller]
    pub fn factor(&mut self, a: &DMatrix<f64>) -> Result<(), Singular> {
        assert_eq!(
            a.shape(),
            self.lu.shape(),
            "DenseLu::factor: matrix size mismatch"
        );
        self.lu.copy_from(a);
        let n = a.nrows();
        let lu = &mut self.lu;
        for col in 0..n {
            let mut best = col;
            let mut best_abs = lu[(col, col)].abs();
            for row in col + 1..n {
                let v = lu[(row, col)].abs();
                if v > best_abs {
                    best = row;
                    best_abs = v;
                }
            }
            if best_abs == 0.0 || !best_abs.is_finite() {
                return Err(Singular { column: col });
            }
            self.pivots[col] = best;
            if best != col {
                lu.swap_rows(best, col);
            }
            // Column-major storage: column `col` (the multipliers) and the columns right
            // of it as slices (the same operations, element by element, as indexing).
            let (left, right) = lu.as_mut_slice().split_at_mut((col + 1) * n);
            let multipliers = &mut left[col * n + col..];
            let pivot = multipliers[0];
            let multipliers = &mut multipliers[1..];
            for l in multipliers.iter_mut() {
                *l /= pivot;
            }
            for column in right.chunks_exact_mut(n) {
                let factor = column[col];
                if factor != 0.0 {
                    for (x, l) in column[col + 1..].iter_mut().zip(multipliers.iter()) {
                        *x -= l * factor;
                    }
                }
            }
        }
        Ok(())
    }

    /// Solves A x = b in place (after a successful [`DenseLu::factor`]).
    pub fn solve_in_place(&self, b: &mut DVector<f64>) {
        let n = self.lu.nrows();
        for i in 0..n {
            b.swap_rows(i, self.pivots[i]);
        }
        let b = b.as_mut_slice();
        let columns = || self.lu.as_slice().chunks_exact(n);
        for (c, column) in columns().enumerate() {
            let bc = b[c];
            if bc != 0.0 {
                for (x, l) in b[c + 1..].iter_mut().zip(&column[c + 1..]) {
                    *x -= l * bc;
                }
            }
        }
        for (c, column) in columns().enumerate().rev() {
            b[c] /= column[c];
            let bc = b[c];
            for (x, u) in b[..c].iter_mut().zip(&column[..c]) {
                *x -= u * bc;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_pivoting_system() {
        let a = DMatrix::from_row_slice(3, 3, &[0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0]);
        let x = DVector::from_vec(vec![1.0, -2.0, 0.5]);
        let mut b = &a * &x;
        let mut lu = DenseLu::new(3);
        lu.factor(&a).unwrap();
        lu.solve_in_place(&mut b);
        assert!((b - x).norm() < 1e-14);
    }

    #[test]
    fn reports_singular_matrices() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        assert_eq!(DenseLu::new(2).factor(&a), Err(Singular { column: 1 }));
    }
}
