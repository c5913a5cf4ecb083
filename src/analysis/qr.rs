//! Householder QR of the boundary blocks that follows their leg structure.
//!
//! Leg i's unknowns (columns of B_u) appear only in the 6 platform rows and in leg i's
//! own 6 + n_t rows (MODEL.md §3 order). The rows are held as \[leg 1, platform, leg 2,
//! leg 3\]; after leg 1's columns are reduced the platform rows move down past leg 2's,
//! and so on, so each reflector acts on one contiguous run of at most 6 + n_t + 6 rows,
//! and rows of legs not yet reached stay zero. The result is Qᵀ B_u = \[R_u; 0\] with R_u
//! square upper-triangular (rows \[leg 1, leg 2, leg 3\], then the 6 platform rows), for a
//! fraction of a dense QR. The same reflectors applied to extra columns (B_x, B_q, B_w)
//! leave a 6-row remainder below R_u; a 6 × 6 QR of the remainder of the pose (or
//! actuation) columns then makes \[B_u B_x\] (or \[B_u B_q\]) triangular. Orthogonal
//! transforms keep singular values: σ(\[B_x B_u\]) = σ(R_x), and R_x solves the Jacobian
//! systems.
//!
//! Cost (callgrind, one 9-DoF `analyze_blocks` at the bench configuration, raw and
//! scaled factorization together, before → after issue 19's work): [`LegQr::new`] 309 k →
//! 141 k instructions (plus 9.5 k for [`LegQr::finish`], counted inside it before),
//! [`wide_triangle`] 165 k → 106 k, [`back_substitute_rows`] 65 k → 51 k. What it took:
//! an AVX2 copy of each kernel chosen at run time (`avx2_dispatch!`; the same operations
//! in the same order as the baseline copy), reflectors applied on the shortest window of
//! 4, 8, 12 or 16 rows that holds them (always 16 before), the blocks loaded in three
//! contiguous runs into a fresh `Vec` (no zeroing first). Applying two reflectors per
//! pass (H₂H₁x = x − s₁v₁ − s₂v₂, s₂ = τ₂(v₂·x − s₁ v₂·v₁)) was tried and dropped: more
//! instructions (797 k → 877 k per analysis) and J_FK 1e-12 away from the sequential
//! application where the windows hold graded columns.
//!
//! [`back_substitute_rows`] takes four rows per block (the diagonal block by
//! substitution, then one pass over the rows above with four columns of R, as the
//! Lanczos kernels do): 9-DoF analysis 669 k → 655 k instructions, 6-DoF 555 k → 544 k;
//! criterion 47.0 → 46.0 µs (9-DoF, interleaved), 6-DoF unchanged within noise; J_FK
//! and C move by round-off (≤ 3e-16 of their largest entry, Λ ≤ 5e-14).
//!
//! The designs' sizes are fixed at compile time where they match (n_u = 8 or 10 leg
//! unknowns for [`LegQr::new`], order and rows 30 or 36 for [`back_substitute_rows`],
//! 36 × 9 for [`wide_triangle`]; any other size takes the general copy): the same
//! operations with known loop bounds (bitwise the same results; a test compares the
//! copies). Per analysis (callgrind, `analysis_cost`, 2026-11-27): [`LegQr::new`] 91.5 k →
//! 78.2 k instructions (6-DoF) and 141.9 k → 119.9 k (9-DoF), [`back_substitute_rows`]
//! 38.0 k → 23.5 k and 36.7 k → 28.3 k (with 1 / R_jj on the stack instead of a fresh
//! `Vec`), [`wide_triangle`] 91.0 k → 84.3 k. [`LegQr::finish`] with fixed sizes gained
//! nothing (0.2 k) and stays general.

use std::ops::Range;

use nalgebra::DMatrix;

/// Platform rows (force and moment balance).
const PLATFORM: usize = 6;

/// The transformed blocks: rows \[leg rows (n_y), platform rows (6)\], columns
/// \[B_u (n_y) | extra blocks in the order given\].
#[derive(Debug, Clone)]
pub(crate) struct LegQr {
    /// Qᵀ Π \[B_u | extra\]: R_u in the top-left n_y × n_y, zeros below it.
    pub w: DMatrix<f64>,
    /// Leg unknowns (columns of B_u) n_y = 3 n_u.
    pub ny: usize,
}

/// An upper-triangular n × n matrix stored column-major with leading dimension `ld` (a
/// view into a [`LegQr`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Triangle<'a> {
    /// Column-major entries; column j starts at j·ld.
    pub data: &'a [f64],
    /// Order.
    pub n: usize,
    /// Leading dimension (≥ n).
    pub ld: usize,
}

impl Triangle<'_> {
    /// Column j's entries on and above the diagonal.
    #[inline(always)]
    pub fn column(&self, j: usize) -> &[f64] {
        &self.data[j * self.ld..j * self.ld + j + 1]
    }

    /// Whether a diagonal entry is zero or not finite.
    #[inline(always)]
    pub fn is_singular(&self) -> bool {
        (0..self.n).any(|j| {
            let d = self.data[j * self.ld + j];
            d == 0.0 || !d.is_finite()
        })
    }
}

impl LegQr {
    /// Factors `blocks[0]` = B_u (rows × 3 n_u, MODEL.md §3 row order) and applies the
    /// reflectors to the other blocks (same rows). Entry (i, j) of block b is loaded as
    /// `row_scale[i] · value · col_scales[b][j]` when scales are given.
    ///
    /// The entries are written into `storage` (cleared first; no allocation where its
    /// capacity suffices: the analysis hands back the storage of an earlier factorization,
    /// [`LegQr::into_storage`]).
    ///
    /// # Panics
    /// If the sizes do not agree (a programmer error; callers check the model).
    #[track_caller]
    pub fn new(
        blocks: &[&DMatrix<f64>],
        nu: usize,
        scales: Option<Scales>,
        storage: Vec<f64>,
    ) -> Self {
        leg_qr(blocks, nu, scales, storage)
    }

    /// A copy of `self` in `storage` (cleared first).
    pub fn copy_into(&self, mut storage: Vec<f64>) -> Self {
        storage.clear();
        storage.extend_from_slice(self.w.as_slice());
        Self {
            w: DMatrix::from_vec(self.w.nrows(), self.w.ncols(), storage),
            ny: self.ny,
        }
    }

    /// The entries' storage, for the next [`LegQr::new`] or [`LegQr::copy_into`].
    pub fn into_storage(self) -> Vec<f64> {
        self.w.data.into()
    }

    #[inline(always)]
    fn new_inline(
        blocks: &[&DMatrix<f64>],
        nu: usize,
        scales: Option<Scales>,
        storage: Vec<f64>,
    ) -> Self {
        // The leg unknowns of the designs (one and two tendon pairs), fixed at compile
        // time.
        match nu {
            8 => Self::new_sized::<8>(blocks, nu, scales, storage),
            10 => Self::new_sized::<10>(blocks, nu, scales, storage),
            _ => Self::new_sized::<0>(blocks, nu, scales, storage),
        }
    }

    /// [`LegQr::new`] for `NU` leg unknowns (0: any number).
    #[inline(always)]
    fn new_sized<const NU: usize>(
        blocks: &[&DMatrix<f64>],
        nu: usize,
        scales: Option<Scales>,
        storage: Vec<f64>,
    ) -> Self {
        let nu = if NU == 0 { nu } else { NU };
        let ny = blocks[0].ncols();
        let m = blocks[0].nrows();
        assert!(ny == 3 * nu && m == ny + PLATFORM, "LegQr: block sizes");
        let (ny, m) = (3 * nu, 3 * nu + PLATFORM);
        let ncols: usize = blocks.iter().map(|b| b.ncols()).sum();
        // Load order: leg 1 (original rows 6..6 + nu), platform (0..6), legs 2 and 3.
        let segments = [
            (0..nu, PLATFORM),
            (nu..nu + PLATFORM, 0),
            (nu + PLATFORM..m, nu + PLATFORM),
        ];
        // Filled column by column (no zeroing first).
        let mut data = storage;
        data.clear();
        data.reserve(m * ncols);
        for (b, block) in blocks.iter().enumerate() {
            assert_eq!(block.nrows(), m, "LegQr: block rows");
            for c in 0..block.ncols() {
                let src = block.column(c);
                let src = src.as_slice();
                for (rows, from) in segments.clone() {
                    let src = &src[from..from + rows.len()];
                    match &scales {
                        None => data.extend_from_slice(src),
                        Some(s) => {
                            let cs = s.cols[b][c];
                            let rs = &s.rows[from..from + rows.len()];
                            data.extend(src.iter().zip(rs).map(|(v, r)| r * v * cs));
                        }
                    }
                }
            }
        }
        let w = DMatrix::from_vec(m, ncols, data);
        let mut qr = Self { w, ny };
        for leg in 0..3 {
            for j in leg * nu..(leg + 1) * nu {
                qr.reflect_at::<NU>(j, j, (leg + 1) * nu + PLATFORM, j + 1..ncols, 0..0);
            }
            if leg < 2 {
                // Move the platform rows below the next leg's rows.
                let run = (leg + 1) * nu..(leg + 2) * nu + PLATFORM;
                for column in qr.w.as_mut_slice().chunks_exact_mut(m) {
                    column[run.clone()].rotate_left(PLATFORM);
                }
            }
        }
        qr
    }

    /// Triangularizes the 6-row remainder of the columns `cols` (one reflector per
    /// column over the platform rows), applying the reflectors to the columns `also`.
    pub fn finish(&mut self, cols: Range<usize>, also: Range<usize>) {
        finish(self, cols, also);
    }

    #[inline(always)]
    fn finish_inline(&mut self, cols: Range<usize>, also: Range<usize>) {
        let m = self.w.nrows();
        for (k, c) in cols.clone().enumerate().take(m - self.ny) {
            self.reflect_at::<0>(c, self.ny + k, m, c + 1..cols.end, also.clone());
        }
    }

    /// Swaps two column ranges of equal length.
    #[inline(always)]
    pub fn swap_columns(&mut self, a: Range<usize>, b: Range<usize>) {
        for (i, j) in a.zip(b) {
            self.w.swap_columns(i, j);
        }
    }

    /// The leading `n` × `n` triangle (R_u for n = n_y; R_x or R_q for n = n_y + 6 after
    /// [`LegQr::finish`] on the columns right after B_u).
    pub fn triangle(&self, n: usize) -> Triangle<'_> {
        Triangle {
            data: self.w.as_slice(),
            n,
            ld: self.w.nrows(),
        }
    }

    /// Householder reflector H = I − τ v vᵀ that zeroes column `col` over rows
    /// `diag + 1..end` into row `diag`, applied to the column ranges `a` and `b`; `NU`
    /// (if not 0) the leg unknowns, fixing the row count at compile time.
    #[inline(always)]
    fn reflect_at<const NU: usize>(
        &mut self,
        col: usize,
        diag: usize,
        end: usize,
        a: Range<usize>,
        b: Range<usize>,
    ) {
        let m = if NU == 0 {
            self.w.nrows()
        } else {
            3 * NU + PLATFORM
        };
        let data = self.w.as_mut_slice();
        let mut v = [0.0; 2 * (6 + crate::design::MAX_TENDONS) + PLATFORM];
        let len = end - diag;
        let v = &mut v[..len];
        v.copy_from_slice(&data[col * m + diag..col * m + end]);
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 || !norm.is_finite() {
            return;
        }
        let alpha = if v[0] > 0.0 { -norm } else { norm };
        v[0] -= alpha;
        let tau = 2.0 / v.iter().map(|x| x * x).sum::<f64>();
        let cols = a.chain(b);
        // The shortest fixed-length kernel that holds the reflector (rows of the window
        // outside diag..end see a zero multiple of v).
        match len {
            ..=4 if 4 <= m => apply_window::<4>(data, m, diag, v, tau, cols),
            ..=8 if 8 <= m => apply_window::<8>(data, m, diag, v, tau, cols),
            ..=12 if 12 <= m => apply_window::<12>(data, m, diag, v, tau, cols),
            ..=16 if 16 <= m => apply_window::<16>(data, m, diag, v, tau, cols),
            _ => {
                for c in cols {
                    let x = &mut data[c * m + diag..c * m + end];
                    let s = tau * super::lanczos::dot(x, v);
                    if s != 0.0 {
                        for (p, q) in x.iter_mut().zip(v.iter()) {
                            *p -= s * q;
                        }
                    }
                }
            }
        }
        let x = &mut data[col * m + diag..col * m + end];
        x.fill(0.0);
        x[0] = alpha;
    }
}

avx2_dispatch! {
    fn leg_qr = leg_qr_avx2 / LegQr::new_inline;
        (blocks: &[&DMatrix<f64>], nu: usize, scales: Option<Scales>, storage: Vec<f64>) -> LegQr
}

avx2_dispatch! {
    fn finish = finish_avx2 / LegQr::finish_inline;
        (qr: &mut LegQr, cols: Range<usize>, also: Range<usize>)
}

/// Applies the reflector I − τ v vᵀ (v over rows diag..diag + v.len(), at most L) to the
/// columns `cols` of the column-major `data` (m rows), on a window of L rows that holds
/// diag..diag + v.len().
#[inline(always)]
fn apply_window<const L: usize>(
    data: &mut [f64],
    m: usize,
    diag: usize,
    v: &[f64],
    tau: f64,
    cols: impl Iterator<Item = usize>,
) {
    let start = diag.min(m - L);
    let mut vp = [0.0; L];
    vp[diag - start..diag - start + v.len()].copy_from_slice(v);
    for c in cols {
        let x: &mut [f64; L] = (&mut data[c * m + start..c * m + start + L])
            .try_into()
            .expect("L rows");
        apply_block(&vp, tau, x);
    }
}

/// x ← (I − τ v vᵀ) x for one column of L rows (L a multiple of 4).
#[inline(always)]
fn apply_block<const L: usize>(v: &[f64; L], tau: f64, x: &mut [f64; L]) {
    let mut acc = [0.0; 4];
    for i in 0..L / 4 {
        for l in 0..4 {
            acc[l] += v[4 * i + l] * x[4 * i + l];
        }
    }
    let s = tau * ((acc[0] + acc[1]) + (acc[2] + acc[3]));
    for (p, q) in x.iter_mut().zip(v) {
        *p -= s * q;
    }
}

/// Row and column scalings applied while loading the blocks.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Scales<'a> {
    /// Factor of each original row.
    pub rows: &'a [f64],
    /// Factor of each column, per block.
    pub cols: &'a [&'a [f64]],
}

/// Solves R X = B in place for the triangle R and the columns `b` of `w` (back
/// substitution), where R is the leading n × n block of `w`. Returns false if a diagonal
/// entry of R is zero.
pub(crate) fn back_substitute(qr: &mut LegQr, n: usize, b: Range<usize>) -> bool {
    back_substitute_rows(qr, n, b, 0)
}

avx2_dispatch! {
    /// [`back_substitute`] for rows `from..n` of the solution only (a column-oriented back
    /// substitution finishes the bottom rows first, so these rows equal those of the full
    /// solve bit for bit); rows above `from` are left partly reduced.
    pub(crate) fn back_substitute_rows = back_substitute_rows_avx2 / back_substitute_rows_inline;
        (qr: &mut LegQr, n: usize, b: Range<usize>, from: usize) -> bool
}

/// The body of [`back_substitute_rows`].
#[inline(always)]
fn back_substitute_rows_inline(qr: &mut LegQr, n: usize, b: Range<usize>, from: usize) -> bool {
    // The orders and row counts of R_x and R_q of the designs, fixed at compile time.
    match (n, qr.w.nrows()) {
        (30, 30) => back_substitute_sized::<30, 30>(qr, n, b, from),
        (36, 36) => back_substitute_sized::<36, 36>(qr, n, b, from),
        _ => back_substitute_sized::<0, 0>(qr, n, b, from),
    }
}

/// [`back_substitute_rows`] for a triangle of order `N` (= `n`) in a [`LegQr`] of `M`
/// rows (0, 0: any).
#[inline(always)]
fn back_substitute_sized<const N: usize, const M: usize>(
    qr: &mut LegQr,
    n: usize,
    b: Range<usize>,
    from: usize,
) -> bool {
    let n = if N == 0 { n } else { N };
    if qr.triangle(n).is_singular() {
        return false;
    }
    let m = if M == 0 { qr.w.nrows() } else { M };
    let (left, right) = qr.w.as_mut_slice().split_at_mut(b.start * m);
    let mut inv = [0.0; 3 * (6 + crate::design::MAX_TENDONS) + PLATFORM];
    let inv = &mut inv[..n];
    for (j, d) in inv.iter_mut().enumerate() {
        *d = 1.0 / left[j * m + j];
    }
    let col = |j: usize| &left[j * m..j * m + j];
    for x in right[..b.len() * m].chunks_exact_mut(m) {
        // The bottom n mod 4 rows one by one, then blocks of four rows: their diagonal
        // block by substitution, then one update of the rows above with four columns
        // of R per pass (a block straddling `from` is done whole: rows from `from` on
        // get the same operations either way).
        let mut j = n;
        while j % 4 != 0 && j > from {
            j -= 1;
            let xj = x[j] * inv[j];
            x[j] = xj;
            if xj != 0.0 {
                for (xi, rij) in x[..j].iter_mut().zip(col(j)) {
                    *xi -= rij * xj;
                }
            }
        }
        while j >= 4 && j > from {
            j -= 4;
            let mut xs = [0.0; 4];
            for b in (0..4).rev() {
                let mut t = x[j + b];
                for (a, xa) in xs.iter().enumerate().skip(b + 1) {
                    t -= left[(j + a) * m + j + b] * xa;
                }
                xs[b] = t * inv[j + b];
            }
            x[j..j + 4].copy_from_slice(&xs);
            let cols = col(j).iter().zip(&col(j + 1)[..j]);
            let cols = cols.zip(col(j + 2)[..j].iter().zip(&col(j + 3)[..j]));
            for (xi, ((a, b), (c, d))) in x[..j].iter_mut().zip(cols) {
                *xi -= (xs[0] * a + xs[1] * b) + (xs[2] * c + xs[3] * d);
            }
        }
    }
    true
}

/// Buffers of [`wide_triangle`], kept between calls (sized on first use).
#[derive(Debug, Clone, Default)]
pub(crate) struct WideBuffers {
    /// The reflectors' rows (row-major, n each): unused, then Cᵀ's n_q rows (row 6 takes
    /// the staircase rows once spent).
    rows: Vec<f64>,
    /// Column-major n × n; only the upper triangle is written (and read).
    r: Vec<f64>,
    /// One entry per row of `rows`.
    v: Vec<f64>,
    /// Column sums of the current reflector's rows.
    sums: Vec<f64>,
}

/// An upper triangle R (n × n, column-major) with RᵀR = P M Mᵀ P (P reverses the order of
/// the n rows of M), so σ(R) = σ(M), for the
/// wide M = Qᵀ\[B_u B_q\] = \[\[R_u; 0\] C\] (n × (n_y + n_q), n_y = n − 6, n_q > 6) of
/// the 9-DoF design, taken from `qr.w` (R_u) and its columns `c` (C). Only the upper
/// triangle of the result is written (a [`Triangle`] reads nothing else).
///
/// Householder QR of Mᵀ with its rows and columns reversed: R_uᵀ then becomes a staircase
/// that is upper triangular from column 6 on, so only the n_q dense rows of Cᵀ need
/// eliminating: reflectors over n_q − k of them for the first 6 columns, and over one
/// staircase row plus the n_q − 6 remaining dense rows after that (a dense QR of Mᵀ costs
/// about five times as much).
///
/// The reflector's rows are a contiguous run (the dense rows not yet used as pivots) and,
/// from column 6 on, the staircase row; the buffers live in `buf`. Before (an index list
/// per column, a fresh `DMatrix` and four vectors per call): 82.5 k instructions per call
/// (callgrind, 9-DoF bench configuration); after (with the AVX2 copy): 52.8 k.
#[inline(always)]
fn wide_triangle_inline(qr: &LegQr, c: Range<usize>, buf: &mut WideBuffers) {
    // The 9-DoF design's sizes, fixed at compile time.
    match (qr.w.nrows(), c.len()) {
        (36, 9) => wide_triangle_sized::<36, 9>(qr, c, buf),
        _ => wide_triangle_sized::<0, 0>(qr, c, buf),
    }
}

/// [`wide_triangle`] for M of `N` rows and C of `NQ` columns (0, 0: any).
#[inline(always)]
fn wide_triangle_sized<const N: usize, const NQ: usize>(
    qr: &LegQr,
    c: Range<usize>,
    buf: &mut WideBuffers,
) {
    let (n, nq) = if N == 0 {
        (qr.w.nrows(), c.len())
    } else {
        assert!(qr.w.nrows() == N && c.len() == NQ, "wide_triangle: sizes");
        (N, NQ)
    };
    let ny = n - PLATFORM;
    debug_assert!(nq > PLATFORM && ny == qr.ny);
    let w = qr.w.as_slice();
    for (b, len) in [
        (&mut buf.rows, (1 + nq) * n),
        (&mut buf.r, n * n),
        (&mut buf.v, 1 + nq),
        (&mut buf.sums, n),
    ] {
        b.resize(len, 0.0);
    }
    let (rows, r, v, sums) = (
        &mut buf.rows[..],
        &mut buf.r[..],
        &mut buf.v[..],
        &mut buf.sums[..],
    );
    // Reversed column j' of Mᵀ is row n − 1 − j' of M.
    for t in 0..nq {
        let col = &w[(c.start + t) * n..(c.start + t + 1) * n];
        for (e, x) in rows[(1 + t) * n..(2 + t) * n]
            .iter_mut()
            .zip(col.iter().rev())
        {
            *e = *x;
        }
    }
    for k in 0..n {
        // The reflector's rows first..=n_q: the dense rows not yet used as pivots
        // (1 + k..=n_q), and from k = 6 on the staircase row in the place of row 6 (the
        // pivot of k = 5, spent), then the dense rows 7..=n_q.
        let first = (1 + k).min(PLATFORM);
        if k >= PLATFORM {
            // Row i' = k − 6 of the reversed R_uᵀ: column j' ≥ k holds R_u[n − 1 − j', i]
            // with i = n_y − 1 − i'.
            let i = ny - 1 - (k - PLATFORM);
            let col = &w[i * n..i * n + n - k];
            for (e, x) in rows[PLATFORM * n + k..(PLATFORM + 1) * n]
                .iter_mut()
                .zip(col.iter().rev())
            {
                *e = *x;
            }
        }
        let active = first..1 + nq;
        let v = &mut v[active.clone()];
        for (x, row) in v.iter_mut().zip(active.clone()) {
            *x = rows[row * n + k];
        }
        let norm = v.iter().fold(0.0, |s, x| s + x * x).sqrt();
        if norm > 0.0 {
            let alpha = if v[0] > 0.0 { -norm } else { norm };
            v[0] -= alpha;
            let beta = 2.0 / v.iter().fold(0.0, |s, x| s + x * x);
            let sums = &mut sums[k..n];
            let rows = &mut rows[first * n..(1 + nq) * n];
            sums.fill(0.0);
            for (vr, row) in v.iter().zip(rows.chunks_exact(n)) {
                for (s, x) in sums.iter_mut().zip(&row[k..]) {
                    *s += vr * x;
                }
            }
            for (vr, row) in v.iter().zip(rows.chunks_exact_mut(n)) {
                let f = beta * vr;
                for (x, s) in row[k..].iter_mut().zip(sums.iter()) {
                    *x -= f * s;
                }
            }
        }
        // The pivot row becomes row k of R.
        for (x, e) in rows[first * n + k..(first + 1) * n]
            .iter()
            .zip(r[k * n + k..].iter_mut().step_by(n))
        {
            *e = *x;
        }
    }
}

avx2_dispatch! {
    /// Forms the wide triangle in `buf` (see [`wide_triangle_inline`]; read it with
    /// [`WideBuffers::triangle`]).
    pub(crate) fn wide_triangle = wide_triangle_avx2 / wide_triangle_inline;
        (qr: &LegQr, c: Range<usize>, buf: &mut WideBuffers)
}

impl WideBuffers {
    /// The n × n triangle of the last [`wide_triangle`].
    pub fn triangle(&self, n: usize) -> Triangle<'_> {
        Triangle {
            data: &self.r[..n * n],
            n,
            ld: n,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random entries in [−1, 1).
    fn noise(i: usize, j: usize, seed: u64) -> f64 {
        let mut z = (i as u64 * 0x9E37_79B9 + j as u64 * 0x85EB_CA6B) ^ seed;
        z = (z ^ (z >> 15)).wrapping_mul(0x2C1B_3C6D);
        z = (z ^ (z >> 12)).wrapping_mul(0x297A_2D39);
        ((z ^ (z >> 15)) % 2_000_000) as f64 / 1e6 - 1.0
    }

    /// A random matrix with the boundary blocks' sparsity: leg i's columns only in the
    /// platform rows and its own rows.
    fn structured(nu: usize) -> DMatrix<f64> {
        let ny = 3 * nu;
        DMatrix::from_fn(ny + PLATFORM, ny, |i, j| {
            let own = i >= PLATFORM && (i - PLATFORM) / nu == j / nu;
            if i < PLATFORM || own {
                ((i * 31 + j * 17) as f64 * 0.618).sin()
                    + if own && i - PLATFORM == j { 2.0 } else { 0.0 }
            } else {
                0.0
            }
        })
    }

    #[test]
    fn r_u_and_the_transformed_columns_reproduce_the_dense_qr() {
        for nu in [8, 10] {
            let b_u = structured(nu);
            let n = b_u.nrows();
            let x = DMatrix::from_fn(n, 6, |i, j| noise(i, j, 2));
            let mut qr = LegQr::new(&[&b_u, &x], nu, None, Vec::new());
            qr.finish(3 * nu..3 * nu + 6, 0..0);
            let r = qr.triangle(n);
            // RᵀR = MᵀM for M = [B_u x] (Q orthogonal).
            let mut full = DMatrix::zeros(n, n);
            full.columns_mut(0, 3 * nu).copy_from(&b_u);
            full.columns_mut(3 * nu, 6).copy_from(&x);
            let dense =
                DMatrix::from_fn(n, n, |i, j| if i <= j { r.data[j * r.ld + i] } else { 0.0 });
            let err = (dense.transpose() * &dense - full.transpose() * &full)
                .abs()
                .max();
            assert!(err < 1e-12, "nu = {nu}: |RᵀR − MᵀM| = {err:.2e}");
            // Strictly lower part is zero.
            assert!((0..n).all(|j| (j + 1..n).all(|i| qr.w[(i, j)] == 0.0)));
        }
    }

    /// A factorization in the storage of an earlier one (longer, other values) and a copy
    /// into such storage are bitwise what fresh storage gives.
    #[test]
    fn reused_storage_gives_the_fresh_factors() {
        let nu = 8;
        let b_u = structured(nu);
        let c = DMatrix::from_fn(b_u.nrows(), 6, |i, j| noise(i, j, 3));
        let bits = |m: &DMatrix<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let fresh = LegQr::new(&[&b_u, &c], nu, None, Vec::new());
        let used = vec![f64::NAN; 3 * fresh.w.len()];
        let reused = LegQr::new(&[&b_u, &c], nu, None, used);
        assert_eq!(bits(&reused.w), bits(&fresh.w));
        let copy = fresh.copy_into(reused.into_storage());
        assert_eq!(bits(&copy.w), bits(&fresh.w));
        assert_eq!((copy.w.shape(), copy.ny), (fresh.w.shape(), fresh.ny));
    }

    /// The dispatched kernels (AVX2 where the CPU has it) give bitwise what their
    /// portable bodies give.
    #[test]
    fn the_dispatched_kernels_equal_their_portable_bodies_bitwise() {
        let nu = 10;
        let b_u = structured(nu);
        let n = b_u.nrows();
        let (ny, nc) = (3 * nu, 9);
        let c = DMatrix::from_fn(n, nc, |i, j| noise(i, j, 7));
        let bits = |m: &DMatrix<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (mut fast, mut plain) = (
            LegQr::new(&[&b_u, &c], nu, None, Vec::new()),
            LegQr::new_inline(&[&b_u, &c], nu, None, Vec::new()),
        );
        assert_eq!(bits(&fast.w), bits(&plain.w), "LegQr::new");
        let (mut wide_fast, mut wide_plain) = (WideBuffers::default(), WideBuffers::default());
        wide_triangle(&fast, ny..ny + nc, &mut wide_fast);
        wide_triangle_inline(&plain, ny..ny + nc, &mut wide_plain);
        let upper = |b: &WideBuffers| {
            let t = b.triangle(n);
            (0..n)
                .flat_map(|j| {
                    t.column(j)[..=j]
                        .iter()
                        .map(|x| x.to_bits())
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(upper(&wide_fast), upper(&wide_plain), "wide_triangle");
        fast.finish(ny..n, n..ny + nc);
        plain.finish_inline(ny..n, n..ny + nc);
        assert_eq!(bits(&fast.w), bits(&plain.w), "finish");
        let ok = (
            back_substitute_rows(&mut fast, n, n..ny + nc, 0),
            back_substitute_rows_inline(&mut plain, n, n..ny + nc, 0),
        );
        assert!(ok.0 && ok.1);
        assert_eq!(bits(&fast.w), bits(&plain.w), "back_substitute_rows");
    }

    /// The kernels with the designs' sizes fixed at compile time (n_u = 8, 10) give
    /// bitwise what the kernels of any size give.
    #[test]
    fn the_fixed_size_kernels_equal_the_general_ones_bitwise() {
        let bits = |m: &DMatrix<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for nu in [8, 10] {
            let b_u = structured(nu);
            let n = b_u.nrows();
            let (ny, nc) = (3 * nu, 9);
            let c = DMatrix::from_fn(n, nc, |i, j| noise(i, j, 11));
            let (mut fixed, mut general) = (
                LegQr::new_inline(&[&b_u, &c], nu, None, Vec::new()),
                LegQr::new_sized::<0>(&[&b_u, &c], nu, None, Vec::new()),
            );
            assert_eq!(bits(&fixed.w), bits(&general.w), "LegQr::new, nu = {nu}");
            if nu == 10 {
                let (mut wide_fixed, mut wide_general) =
                    (WideBuffers::default(), WideBuffers::default());
                wide_triangle_inline(&fixed, ny..ny + nc, &mut wide_fixed);
                wide_triangle_sized::<0, 0>(&general, ny..ny + nc, &mut wide_general);
                let wide_bits =
                    |b: &WideBuffers| b.r.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    wide_bits(&wide_fixed),
                    wide_bits(&wide_general),
                    "wide_triangle"
                );
            }
            fixed.finish(ny..n, n..ny + nc);
            general.finish(ny..n, n..ny + nc);
            let ok = (
                back_substitute_rows_inline(&mut fixed, n, n..ny + nc, 0),
                back_substitute_sized::<0, 0>(&mut general, n, n..ny + nc, 0),
            );
            assert!(ok.0 && ok.1);
            assert_eq!(
                bits(&fixed.w),
                bits(&general.w),
                "back substitution, nu = {nu}"
            );
        }
    }

    #[test]
    fn the_wide_triangle_reproduces_m_m_transpose() {
        // The 9-DoF shape: n_u = 10, n_q = 9 columns of C.
        let nu = 10;
        let b_u = structured(nu);
        let n = b_u.nrows();
        let c = DMatrix::from_fn(n, 9, |i, j| noise(i, j, 5));
        let qr = LegQr::new(&[&b_u, &c], nu, None, Vec::new());
        let ny = 3 * nu;
        // Garbage in the buffers must not matter (only the upper triangle is read).
        let mut buf = WideBuffers {
            r: vec![f64::NAN; n * n],
            ..WideBuffers::default()
        };
        wide_triangle(&qr, ny..ny + 9, &mut buf);
        let t = buf.triangle(n);
        let r = DMatrix::from_fn(n, n, |i, j| if i <= j { t.column(j)[i] } else { 0.0 });
        // RᵀR = P M Mᵀ P for M = Qᵀ[B_u C] (n × (n_y + 9)), P the reversal; R upper
        // triangular.
        let m = DMatrix::from_fn(n, ny + 9, |i, j| qr.w[(n - 1 - i, j)]);
        let err = (r.transpose() * &r - &m * m.transpose()).abs().max();
        assert!(err < 1e-12, "|RᵀR − P M Mᵀ P| = {err:.2e}");
        // Same singular values as [B_u C] itself.
        let mut full = DMatrix::zeros(n, ny + 9);
        full.columns_mut(0, ny).copy_from(&b_u);
        full.columns_mut(ny, 9).copy_from(&c);
        let (mut a, mut b) = (
            r.singular_values().as_slice().to_vec(),
            full.singular_values().as_slice().to_vec(),
        );
        a.sort_by(f64::total_cmp);
        b.sort_by(f64::total_cmp);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-12 * b[b.len() - 1], "{x} vs {y}");
        }
    }

    #[test]
    fn back_substitution_solves_the_original_system() {
        let nu = 8;
        let b_u = structured(nu);
        let n = b_u.nrows();
        let x = DMatrix::from_fn(n, 6, |i, j| noise(i, j, 3));
        let rhs = DMatrix::from_fn(n, 2, |i, j| (i + j) as f64);
        let mut qr = LegQr::new(&[&b_u, &x, &rhs], nu, None, Vec::new());
        qr.finish(n - 6..n, n..n + 2);
        assert!(back_substitute(&mut qr, n, n..n + 2));
        let z = qr.w.columns(n, 2).into_owned();
        let mut full = DMatrix::zeros(n, n);
        full.columns_mut(0, n - 6).copy_from(&b_u);
        full.columns_mut(n - 6, 6).copy_from(&x);
        let err = (&full * &z - &rhs).abs().max();
        assert!(err < 1e-11, "residual {err:.2e}");
    }
}
