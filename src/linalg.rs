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
        lu_factor(&mut self.lu, &mut self.pivots)
    }

    /// Solves A x = b in place (after a successful [`DenseLu::factor`]).
    pub fn solve_in_place(&self, b: &mut DVector<f64>) {
        lu_solve(&self.lu, &self.pivots, b.as_mut_slice());
    }
}

avx2_dispatch! {
    /// Factors `lu` in place (partial pivoting, the row swaps in `pivots`), in an AVX2
    /// copy where the CPU has it: the same operations in the same order (no fused
    /// multiply–add), so the same factors bit for bit, with the column updates four
    /// rows a vector instead of two. At 36 × 36 (the 9-DoF design's square systems)
    /// 74.6 k → 58.3 k instructions per factorization (callgrind, warm FK steps).
    fn lu_factor = lu_factor_avx2 / lu_factor_inline;
        (lu: &mut DMatrix<f64>, pivots: &mut [usize]) -> Result<(), Singular>
}

avx2_dispatch! {
    /// Solves with the factors of [`lu_factor`] in place, in an AVX2 copy as
    /// [`lu_factor`]'s: 8.66 k → 5.96 k instructions per solve at 36 × 36 (the same
    /// results bit for bit).
    fn lu_solve = lu_solve_avx2 / lu_solve_inline;
        (lu: &DMatrix<f64>, pivots: &[usize], b: &mut [f64])
}

/// The orders of the designs' square systems (30 and 36: 6-DoF and 9-DoF) are fixed at
/// compile time where they match: the kernels' loops then have known bounds, with the
/// same operations (bitwise the same factors and solutions; a test compares them with
/// the general copy). The reference design's small sweep (z ∈ [−6, 0] mm, φ = 0.2):
/// the Newton runs' factorizations 147.6 M → 130.2 M instructions (callgrind,
/// 2026-11-27).
#[inline(always)]
fn lu_factor_inline(lu: &mut DMatrix<f64>, pivots: &mut [usize]) -> Result<(), Singular> {
    match lu.nrows() {
        30 => lu_factor_sized::<30>(lu, pivots),
        36 => lu_factor_sized::<36>(lu, pivots),
        _ => lu_factor_sized::<0>(lu, pivots),
    }
}

/// [`lu_factor`] for order `N` (0: any).
#[inline(always)]
fn lu_factor_sized<const N: usize>(
    lu: &mut DMatrix<f64>,
    pivots: &mut [usize],
) -> Result<(), Singular> {
    let n = if N == 0 { lu.nrows() } else { N };
    assert!(lu.shape() == (n, n), "lu_factor: square");
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
        pivots[col] = best;
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

#[inline(always)]
fn lu_solve_inline(lu: &DMatrix<f64>, pivots: &[usize], b: &mut [f64]) {
    match lu.nrows() {
        30 => lu_solve_sized::<30>(lu, pivots, b),
        36 => lu_solve_sized::<36>(lu, pivots, b),
        _ => lu_solve_sized::<0>(lu, pivots, b),
    }
}

/// [`lu_solve`] for order `N` (0: any).
#[inline(always)]
fn lu_solve_sized<const N: usize>(lu: &DMatrix<f64>, pivots: &[usize], b: &mut [f64]) {
    let n = if N == 0 { lu.nrows() } else { N };
    assert!(lu.shape() == (n, n), "lu_solve: square");
    let (pivots, b) = (&pivots[..n], &mut b[..n]);
    for (i, &p) in pivots.iter().enumerate() {
        b.swap(i, p);
    }
    let columns = || lu.as_slice().chunks_exact(n);
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

/// Cholesky factor S = L Lᵀ of a symmetric positive definite n×n matrix by nalgebra's
/// algorithm (`nalgebra::Cholesky::new`, then `solve_mut`) with the same operations in
/// the same order, so the same factor and solutions bit for bit, on contiguous column
/// slices (nalgebra walks its columns through strided views that do not vectorize), the
/// column updates eight rows at a time in AVX2 where the CPU has it. At 36 × 36 (the
/// redundant IK's least-change step) a factorization takes 30.7 k instead of 46.4 k
/// instructions (callgrind, a warm within-limits step of the 9-DoF design); a solve
/// costs about what nalgebra's did (8 k).
#[derive(Debug, Clone)]
pub struct NalgebraCholesky {
    /// L in the lower triangle (column-major); the upper triangle holds S's entries.
    l: DMatrix<f64>,
}

impl NalgebraCholesky {
    /// Factors `s` (only its lower triangle is read); `None` when a pivot is not > 0
    /// (S not positive definite to working precision, or not finite).
    ///
    /// # Panics
    /// If `s` is not square.
    pub fn new(mut s: DMatrix<f64>) -> Option<Self> {
        let n = s.nrows();
        assert_eq!(n, s.ncols(), "NalgebraCholesky::new: matrix not square");
        let a = s.as_mut_slice();
        for j in 0..n {
            let (left, right) = a.split_at_mut(j * n);
            let col_j = &mut right[j..n];
            subtract_columns(left, col_j, n, j);
            let diagonal = col_j[0];
            // nalgebra: no pivot if it is zero or `try_sqrt` fails (negative or NaN).
            if diagonal.is_nan() || diagonal <= 0.0 {
                return None;
            }
            let denom = diagonal.sqrt();
            col_j[0] = denom;
            for e in &mut col_j[1..] {
                *e /= denom;
            }
        }
        Some(Self { l: s })
    }

    /// Solves S x = b in place: L y = b by columns, then Lᵀ x = y by [`nalgebra_dot`].
    ///
    /// # Panics
    /// If `b` does not have n entries.
    pub fn solve_in_place(&self, b: &mut [f64]) {
        let n = self.l.nrows();
        assert_eq!(
            b.len(),
            n,
            "NalgebraCholesky::solve_in_place: b has the wrong length"
        );
        let columns = || self.l.as_slice().chunks_exact(n);
        for (i, column) in columns().enumerate() {
            let coeff = b[i] / column[i];
            b[i] = coeff;
            for (y, l) in b[i + 1..].iter_mut().zip(&column[i + 1..]) {
                *y += -coeff * l;
            }
        }
        for (i, column) in columns().enumerate().rev() {
            let dot = nalgebra_dot(&column[i + 1..], &b[i + 1..]);
            b[i] = (b[i] - dot) / column[i];
        }
    }

    /// L (the strict upper triangle zero).
    pub fn l(&self) -> DMatrix<f64> {
        self.l.lower_triangle()
    }
}

avx2_dispatch! {
    /// Column j of the factorization below its diagonal (`col_j`, rows j..n) minus the
    /// columns k < j of L before it (`left`, column-major, n rows each) times L_jk, as
    /// nalgebra does it (`axpy(−L_jk, L[j.., k], 1)` for k = 0, 1, …: y = y + (−L_jk)·x);
    /// each entry sees the same sequence here, eight rows at a time with the sums in
    /// registers.
    fn subtract_columns = subtract_columns_avx2 / subtract_columns_inline;
        (left: &[f64], col_j: &mut [f64], n: usize, j: usize)
}

#[inline(always)]
fn subtract_columns_inline(left: &[f64], col_j: &mut [f64], n: usize, j: usize) {
    let columns = || left.chunks_exact(n);
    let mut blocks = col_j.chunks_exact_mut(8);
    let mut i = j;
    for y in &mut blocks {
        let mut acc = [0.0; 8];
        acc.copy_from_slice(y);
        for column in columns() {
            let (f, x) = (-column[j], &column[i..i + 8]);
            for r in 0..8 {
                acc[r] += f * x[r];
            }
        }
        y.copy_from_slice(&acc);
        i += 8;
    }
    for y in blocks.into_remainder() {
        for column in columns() {
            *y += -column[j] * column[i];
        }
        i += 1;
    }
}

/// The lower triangle of S = Ã Ãᵀ (m × m) for Ã = A diag(`scales`), A m × n: each
/// column's entries scaled (x·s_j, rounded), then every entry S_ik = Σ_j Ã_ij Ã_kj summed
/// over the columns in order by fused multiply–adds from zero. That is the sum of
/// matrixmultiply's x86-64 FMA and AVX-512 kernels (one FMA per column, from zero, times
/// α = 1), so on a CPU with FMA the lower triangle of nalgebra's `Ã * Ãᵀ` bit for bit
/// (tests compare), and the same bits on every CPU (`f64::mul_add`). The strict upper
/// triangle is zero.
///
/// Products with an exactly zero factor leave a sum unchanged and are skipped by tiles:
/// S is summed in 4 × 4 tiles, each over the columns that have a nonzero entry in both
/// of its row groups of four (a column with s_j = 0 in none). This assumes a finite A:
/// an infinite entry's products with the zeros of a skipped group would have been NaN.
/// The redundant IK's step matrix is sparse in blocks (a leg's columns touch its own ten
/// rows and the six platform rows): at the 9-DoF bench configuration its S (36 × 36 from
/// 39 columns) has 31 of 45 lower tiles with any column, 339 tile-column passes instead
/// of 1 755, and takes 1.9 µs against 2.9 µs for the scaled copy and nalgebra's product
/// (AVX-512 matrixmultiply kernel).
///
/// # Panics
/// If `a` does not have `scales.len()` columns.
pub fn scaled_gram_lower(a: &DMatrix<f64>, scales: &[f64]) -> DMatrix<f64> {
    let (m, n) = a.shape();
    assert_eq!(n, scales.len(), "scaled_gram_lower: one scale per column");
    // Ã with its rows padded with zeros to a multiple of four, every entry written once
    // (a zeroed allocation first: 52.1 k → 42.1 k instructions a call at 36 × 39 by
    // callgrind, which counts calloc's fill by the iteration).
    let rows = m.next_multiple_of(4);
    let mut scaled = Vec::with_capacity(rows * n);
    for (a_j, &scale) in a.as_slice().chunks_exact(m).zip(scales) {
        if scale != 0.0 {
            scaled.extend(a_j.iter().map(|a| a * scale));
        } else {
            scaled.extend(std::iter::repeat_n(0.0, m));
        }
        scaled.extend(std::iter::repeat_n(0.0, rows - m));
    }
    let mut s = DMatrix::zeros(m, m);
    gram_tiles(&scaled, rows, s.as_mut_slice(), m);
    s
}

/// The tiles of [`scaled_gram_lower`] from the padded Ã (`rows` rows, column-major) into
/// `s` (m × m, zero), with vector FMA instructions where the CPU has them (the same
/// operations: one fused multiply–add per entry and column).
fn gram_tiles(scaled: &[f64], rows: usize, s: &mut [f64], m: usize) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA, checked just above.
        return unsafe { gram_tiles_fma(scaled, rows, s, m) };
    }
    gram_tiles_inline(scaled, rows, s, m, tile_sum);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn gram_tiles_fma(scaled: &[f64], rows: usize, s: &mut [f64], m: usize) {
    gram_tiles_inline(scaled, rows, s, m, tile_sum_fma);
}

/// The tile of row groups `gi`, `gk` (rows 4 gi.., columns 4 gk.. of S) summed over
/// `columns` of the padded Ã: `acc[c][r]` = S(4 gi + r, 4 gk + c).
type TileSum = fn(&[f64], usize, &[usize], usize, usize) -> [[f64; 4]; 4];

#[inline(always)]
fn gram_tiles_inline(scaled: &[f64], rows: usize, s: &mut [f64], m: usize, tile: TileSum) {
    let (groups, n) = (rows / 4, scaled.len() / rows);
    // Per row group, the set of columns with a nonzero entry in it (bits in words of 64
    // columns), so a tile's columns are the intersection of its two groups' sets.
    let words = n.div_ceil(64);
    let mut touching = vec![0u64; groups * words];
    for (j, column) in scaled.chunks_exact(rows).enumerate() {
        for (g, x) in column.chunks_exact(4).enumerate() {
            if x[0] != 0.0 || x[1] != 0.0 || x[2] != 0.0 || x[3] != 0.0 {
                touching[g * words + j / 64] |= 1 << (j % 64);
            }
        }
    }
    let mut columns = Vec::with_capacity(n);
    for gi in 0..groups {
        for gk in 0..=gi {
            columns.clear();
            for w in 0..words {
                let mut both = touching[gi * words + w] & touching[gk * words + w];
                while both != 0 {
                    columns.push(64 * w + both.trailing_zeros() as usize);
                    both &= both - 1;
                }
            }
            if columns.is_empty() {
                continue;
            }
            let acc = tile(scaled, rows, &columns, gi, gk);
            for (c, acc) in acc.iter().enumerate() {
                let k = 4 * gk + c;
                for (r, &value) in acc.iter().enumerate() {
                    let i = 4 * gi + r;
                    if i >= k && i < m {
                        s[k * m + i] = value;
                    }
                }
            }
        }
    }
}

/// [`TileSum`] by `f64::mul_add`.
fn tile_sum(scaled: &[f64], rows: usize, columns: &[usize], gi: usize, gk: usize) -> [[f64; 4]; 4] {
    let mut acc = [[0.0f64; 4]; 4];
    for &j in columns {
        let column = &scaled[j * rows..(j + 1) * rows];
        let (x, y) = (&column[4 * gi..4 * gi + 4], &column[4 * gk..4 * gk + 4]);
        for c in 0..4 {
            for r in 0..4 {
                acc[c][r] = x[r].mul_add(y[c], acc[c][r]);
            }
        }
    }
    acc
}

/// [`TileSum`] in AVX2 registers, one vector FMA per tile column and column of Ã (the
/// compiler left [`tile_sum`]'s sixteen FMAs scalar).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
fn tile_sum_fma(
    scaled: &[f64],
    rows: usize,
    columns: &[usize],
    gi: usize,
    gk: usize,
) -> [[f64; 4]; 4] {
    use std::arch::x86_64::{
        _mm256_fmadd_pd, _mm256_loadu_pd, _mm256_set1_pd, _mm256_setzero_pd, _mm256_storeu_pd,
    };
    let mut acc = [_mm256_setzero_pd(); 4];
    for &j in columns {
        let column = &scaled[j * rows..(j + 1) * rows];
        let (x, y) = (&column[4 * gi..4 * gi + 4], &column[4 * gk..4 * gk + 4]);
        // SAFETY: `x` holds four values.
        let x = unsafe { _mm256_loadu_pd(x.as_ptr()) };
        for c in 0..4 {
            acc[c] = _mm256_fmadd_pd(x, _mm256_set1_pd(y[c]), acc[c]);
        }
    }
    let mut out = [[0.0; 4]; 4];
    for c in 0..4 {
        // SAFETY: `out[c]` holds four values.
        unsafe { _mm256_storeu_pd(out[c].as_mut_ptr(), acc[c]) };
    }
    out
}

/// The dot product of `a` and `b` by nalgebra's summation for dynamic vectors (`dot`,
/// `dotc`, `norm`: eight partial sums over blocks of eight, combined pairwise, then the
/// remainder in order), so that it equals nalgebra's bit for bit.
///
/// # Panics
/// If `a` and `b` differ in length (as nalgebra's `dot` does).
pub fn nalgebra_dot(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "nalgebra_dot: lengths differ");
    let mut acc = [0.0f64; 8];
    let (blocks_a, blocks_b) = (a.chunks_exact(8), b.chunks_exact(8));
    let (rest_a, rest_b) = (blocks_a.remainder(), blocks_b.remainder());
    for (x, y) in blocks_a.zip(blocks_b) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut sum = 0.0;
    sum += acc[0] + acc[4];
    sum += acc[1] + acc[5];
    sum += acc[2] + acc[6];
    sum += acc[3] + acc[7];
    for (x, y) in rest_a.iter().zip(rest_b) {
        sum += x * y;
    }
    sum
}

/// Whether every entry is finite: Σ 0·x is ±0 for finite entries and NaN once one is
/// NaN or infinite (four partial sums, no branch per entry: a quarter of the
/// instructions of `iter().all(is_finite)`).
#[inline(always)]
pub(crate) fn all_finite(x: &[f64]) -> bool {
    let mut acc = [0.0; 4];
    let chunks = x.chunks_exact(4);
    let tail = chunks.remainder().iter().fold(0.0, |s, v| s + v * 0.0);
    for c in chunks {
        for i in 0..4 {
            acc[i] += c[i] * 0.0;
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail == 0.0
}

/// Whether matrixmultiply (nalgebra's dense product) sums with fused multiply–adds on
/// this CPU (its x86-64 FMA and AVX-512 kernels), so that [`scaled_gram_lower`] equals
/// nalgebra's product bit for bit: what the tests that compare the two can assume.
#[cfg(test)]
pub(crate) fn matrixmultiply_fuses() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("fma");
    #[allow(unreachable_code)]
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric positive definite n × n matrix with entries over several decades.
    fn spd(n: usize) -> DMatrix<f64> {
        let a = DMatrix::from_fn(n, n + 3, |i, j| {
            (((i + 2) * (j + 7)) % 29) as f64 * 0.11 - 1.5 + if i == j { 3.0 } else { 0.0 }
        });
        let scale = DMatrix::from_fn(n, n, |i, j| {
            if i == j {
                10f64.powi(i as i32 % 5 - 2)
            } else {
                0.0
            }
        });
        &scale * &a * a.transpose() * &scale
    }

    #[test]
    fn the_cholesky_factor_and_solutions_are_nalgebras_bit_for_bit() {
        let same = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits());
        for n in [1, 3, 8, 9, 17, 36] {
            let s = spd(n);
            let ours = NalgebraCholesky::new(s.clone()).unwrap();
            let theirs = nalgebra::Cholesky::new(s.clone()).unwrap();
            assert!(
                same(ours.l().as_slice(), theirs.l().as_slice()),
                "L, n = {n}"
            );
            for seed in 0..20 {
                let b = DVector::from_fn(n, |i, _| {
                    ((i * 7 + seed * 13) as f64 * 0.7).sin() * 10f64.powi((i + seed) as i32 % 3)
                });
                let mut x = b.clone();
                ours.solve_in_place(x.as_mut_slice());
                let mut expected = b;
                theirs.solve_mut(&mut expected);
                assert!(same(x.as_slice(), expected.as_slice()), "x, n = {n}");
            }
        }
    }

    /// The dispatched LU (AVX2 where the CPU has it, the orders 30 and 36 fixed at
    /// compile time) gives bitwise what the portable body of any order gives.
    #[test]
    fn the_dispatched_lu_equals_its_portable_body_bit_for_bit() {
        let same = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits());
        for n in [1, 5, 30, 36] {
            // Not symmetric, rows out of pivot order, entries over several decades.
            let a = DMatrix::from_fn(n, n, |i, j| {
                // A dominant entry off the diagonal in every row: pivoting reorders rows.
                let dominant = if (i + 1) % n == j { 5.0 } else { 0.0 };
                ((((i + 5) * (j + 3)) % 23) as f64 * 0.17 - 1.9 + dominant)
                    * 10f64.powi((i + 2 * j) as i32 % 4 - 1)
            });
            let mut dispatched = DenseLu::new(n);
            dispatched.factor(&a).unwrap();
            let (mut lu, mut pivots) = (a.clone(), vec![0; n]);
            lu_factor_sized::<0>(&mut lu, &mut pivots).unwrap();
            assert!(
                same(dispatched.lu.as_slice(), lu.as_slice()),
                "factors, n = {n}"
            );
            assert_eq!(dispatched.pivots, pivots, "pivots, n = {n}");
            let b = DVector::from_fn(n, |i, _| (i as f64 * 0.9).cos() * 10f64.powi(i as i32 % 3));
            let mut x = b.clone();
            dispatched.solve_in_place(&mut x);
            let mut expected = b.clone();
            lu_solve_sized::<0>(&lu, &pivots, expected.as_mut_slice());
            assert!(same(x.as_slice(), expected.as_slice()), "x, n = {n}");
            let scale = a.abs() * x.abs();
            assert!(
                (&a * &x - &b)
                    .iter()
                    .zip(&scale)
                    .all(|(r, s)| r.abs() <= 1e-12 * s),
                "residual, n = {n}"
            );
        }
        let singular =
            DMatrix::from_fn(4, 4, |i, j| if j == 2 { 0.0 } else { (i + j) as f64 + 1.0 });
        assert_eq!(
            DenseLu::new(4).factor(&singular),
            Err(Singular { column: 2 })
        );
    }

    /// A 36 × 39 matrix with the redundant IK step matrix's blocks (rows 0..6 touched by
    /// every leg-unknown column, each leg's ten rows by its own columns; q columns on
    /// two or three rows of their leg) and a few zeros inside the blocks.
    fn block_sparse() -> DMatrix<f64> {
        DMatrix::from_fn(36, 39, |i, j| {
            let value = (((i + 3) * (j + 11)) % 31) as f64 * 0.13 - 2.0;
            let leg_of_row = (i >= 6).then(|| (i - 6) / 10);
            let touches = if j < 9 {
                leg_of_row == Some(j / 3) && (i + j) % 4 != 0
            } else {
                leg_of_row.is_none() || leg_of_row == Some((j - 9) / 10)
            };
            if touches && (i * j) % 17 != 5 {
                value * 10f64.powi((i + j) as i32 % 5 - 2)
            } else {
                0.0
            }
        })
    }

    #[test]
    fn the_scaled_gram_matrix_is_nalgebras_product_bit_for_bit() {
        let same = |x: f64, y: f64| x.to_bits() == y.to_bits();
        for a in [block_sparse(), spd(12).insert_columns(12, 2, 0.5)] {
            let (m, n) = a.shape();
            let mut scales: Vec<f64> = (0..n)
                .map(|j| 1.0 / (1.0 + 0.1 * j as f64).sqrt())
                .collect();
            scales[n / 3] = 0.0;
            let s = scaled_gram_lower(&a, &scales);
            let mut scaled = a.clone();
            for (j, mut column) in scaled.column_iter_mut().enumerate() {
                column.scale_mut(scales[j]);
            }
            // Each entry summed column by column, one rounding per term.
            for i in 0..m {
                for k in 0..m {
                    let expected = if k > i {
                        0.0
                    } else {
                        (0..n).fold(0.0, |acc: f64, j| {
                            scaled[(i, j)].mul_add(scaled[(k, j)], acc)
                        })
                    };
                    assert!(same(s[(i, k)], expected), "({i}, {k}) of {m} × {n}");
                }
            }
            if matrixmultiply_fuses() {
                let product = &scaled * scaled.transpose();
                for i in 0..m {
                    for k in 0..=i {
                        assert!(same(s[(i, k)], product[(i, k)]), "({i}, {k}) of {m} × {n}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_cholesky_factor_refuses_what_nalgebras_refuses() {
        for s in [
            DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]),
            DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, 1.0]),
            DMatrix::from_row_slice(2, 2, &[f64::NAN, 0.0, 0.0, 1.0]),
        ] {
            assert!(nalgebra::Cholesky::new(s.clone()).is_none());
            assert!(NalgebraCholesky::new(s).is_none());
        }
    }

    #[test]
    fn dot_products_are_nalgebras_bit_for_bit() {
        for n in [0, 1, 7, 8, 9, 16, 23, 36, 39] {
            let a = DVector::from_fn(n, |i, _| {
                ((i * 37 % 11) as f64 - 4.7) * 10f64.powi(i as i32 % 7 - 3)
            });
            let b = DVector::from_fn(n, |i, _| {
                ((i * 5 % 13) as f64 - 6.1) * 10f64.powi(i as i32 % 4 - 2)
            });
            assert_eq!(
                nalgebra_dot(a.as_slice(), b.as_slice()).to_bits(),
                a.dot(&b).to_bits(),
                "n = {n}"
            );
            assert_eq!(
                nalgebra_dot(a.as_slice(), a.as_slice()).sqrt().to_bits(),
                a.norm().to_bits()
            );
        }
    }

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
