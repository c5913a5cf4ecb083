//! Reciprocal condition numbers rcond(M) = σ_min(M)/σ_max(M) (MODEL.md §4), with σ_min
//! the smallest of the min(rows, cols) singular values.

use nalgebra::DMatrix;

use super::ellipsoid::ratio;

/// rcond of a dense matrix from its singular values (no singular vectors).
pub fn rcond(m: &DMatrix<f64>) -> f64 {
    if m.is_empty() || !m.iter().all(|x| x.is_finite()) {
        return 0.0;
    }
    let s = m.clone().singular_values();
    let max = s.iter().copied().fold(0.0, f64::max);
    let min = s.iter().copied().fold(f64::INFINITY, f64::min);
    ratio(min, max)
}
