//! The largest and smallest singular values of an upper-triangular matrix R by the
//! Lanczos method, on RᵀR for σ_max and on (RᵀR)⁻¹ = R⁻¹R⁻ᵀ (two triangular solves per
//! step) for σ_min.
//!
//! Only two singular values are needed for rcond, and the boundary matrices' spectra
//! come in well-separated clusters (stiff shear/extension directions ~10⁴, the rest
//! ≤ ~1 in SI), so a few steps (4–12) suffice where a dense SVD reduces the whole matrix.
//! The iteration stops at the first Ritz value θ whose residual β_k |s_k| is at most
//! [`TOLERANCE`]·θ: an eigenvalue then lies within that distance of θ (and in practice
//! within its square over the gap: measured ≤ 5e-9 relative against dense SVDs). Plain
//! three-term Lanczos without reorthogonalization: orthogonality is lost only as a Ritz
//! value converges (Paige), and the iteration stops there; at k = n the Krylov space is
//! the whole space. σ_min starts from the LINPACK condition-estimator vector, σ_max from
//! a fixed pseudo-random vector or a given one, so results are reproducible.
//!
//! Cost (callgrind, all Lanczos runs of one 9-DoF `analyze_blocks` at the bench
//! configuration, before → after issue 19's work): σ_max 177 k → 102 k instructions,
//! σ_min 256 k → 206 k. What it took: the triangular kernels below (four columns per
//! pass), an AVX2 copy of both runs chosen at run time (`avx2_dispatch!`, the same
//! operations in the same order), the operator as a plain enum (closures were compiled
//! apart from the AVX2 copy), and a tighter start for the Newton iteration of
//! [`top_ritz`] (6.1 → 3.8 steps per call).
//!
//! Issue 19's second round, tried and dropped: σ_max(R_u) started from R_u's largest row
//! instead of the fixed random vector (5 → 4 steps raw, 7 → 5 scaled at the 9-DoF bench
//! configuration, 47.1 → 46.0 µs), but at 1 801 of the 178 353 points of the reference
//! design's Δ = 3 mm sweep the run stopped at a Ritz value below σ_max (the residual test
//! finds an eigenvalue, not the largest one): rcond 0.64 % off, scaled rconds up to 16 %;
//! the LINPACK start's forward pass by blocks of four columns (as in the forward
//! substitution): 655 k → 651 k instructions, but no gain in time (45.8/45.8
//! against 46.7/48.3 µs, interleaved).
//!
//! The orders of the analysis' triangles (24, 30 and 36) are fixed at compile time
//! ([`Lanczos::sigma_max`] and [`Lanczos::sigma_min`] pick a copy of the run by the
//! order; any other order takes the general one): the vector loops and the kernels'
//! blocks of four then have known trip counts and no remainder tests, with the same
//! operations in the same order (bitwise the same results; a test compares the copies).
//! Per analysis (callgrind, `analysis_cost`, 2026-11-27): σ_min 212.6 k → 183.5 k and σ_max
//! 98.1 k → 85.0 k instructions (6-DoF), σ_min 200.0 k → 182.9 k and σ_max 98.1 k → 89.0 k
//! (9-DoF). Fixing the leading dimension as well (30 or 36) was slower: 6-DoF analysis
//! 2.1 k instructions more than the order alone.
//!
//! The kernels work on R copied into a zero-padded [`Square`] of order n rounded up to
//! four (the vectors zero in the padding, which every operator keeps zero), so every
//! pass is over whole blocks of four with no remainder rows: order 30 had two scalar
//! rows per kernel, and the blocks' edges were found at run time. Per analysis
//! (callgrind, `analysis_cost`, 2026-11-27, fourteenth session): σ_min 183.4 k → 172.9 k
//! and σ_max 85.0 k → 73.1 k instructions (6-DoF), σ_min 182.9 k → 175.8 k and σ_max
//! 89.0 k → 78.4 k (9-DoF); the results move by round-off only (the dense-SVD errors of
//! `analysis_cost dump` change in their last digits). In isolation at order 30 the back
//! substitution fell from 1 690 to 716 instructions a call, R x from 1 730 to 1 044 and
//! Rᵀ x from 1 790 to 876. The forward substitution first stayed near 1 700-2 000 (over
//! the rows above each block alone the compiler split its four running sums into
//! two-lane halves; the other loop order of `block_dots` made the whole analysis 15 %
//! dearer); with y zeroed first and each block's dots run over its own rows too (exact
//! zeros added, so the same results bit for bit) it is the loop of Rᵀ x: σ_min 172.9 k →
//! 141.2 k instructions per 6-DoF analysis, 175.8 k → 147.4 k per 9-DoF one. Measured
//! before: two columns per pass cost 0.4 µs per Lanczos step at n = 30-36; four columns
//! with the 4 × 4 diagonal blocks read as arrays took the analysis from 61.2 to 56.8 µs; inverting those blocks once per run
//! gave nothing measurable (53.2 against 53.5 µs); forming R⁻¹ explicitly for σ_min cost
//! more than the solves it replaces (62.8 → 73.5 µs). Two σ_min runs of one order
//! stepped together, their solves interleaved block by block (bitwise the same values),
//! gained nothing (9-DoF analysis 54.4, 53.6 → 57.0, 52.3 µs; 555 k → 584 k
//! instructions): at 3–4 instructions a cycle the runs are bound by their instruction
//! count, not by the solves' chains (BENCHMARKS.md, 2026-11-28, twenty-sixth session).

use super::qr::Triangle;
use crate::rod::lanes::F64x4;

/// Relative Ritz residual at which an eigenvalue counts as found.
pub(crate) const TOLERANCE: f64 = 1e-5;

/// Work space of the iteration for matrices up to a size.
#[derive(Debug, Clone)]
pub(crate) struct Lanczos {
    work: Work,
    /// 1 / R_jj of the current σ_min matrix (divisions hoisted out of the solves; 1 in
    /// the padding).
    inv_diag: Vec<f64>,
    /// The current matrix as a [`Square`].
    square: Vec<f64>,
    /// The largest order taken.
    capacity: usize,
    /// The Ritz vector of the last [`Lanczos::sigma_max`] (a right singular vector).
    ritz: Vec<f64>,
    ritz_len: usize,
}

/// The iteration's vectors and tridiagonal.
#[derive(Debug, Clone)]
struct Work {
    basis: Vec<f64>,
    w: Vec<f64>,
    tmp: Vec<f64>,
    alpha: Vec<f64>,
    beta: Vec<f64>,
    steps: usize,
    /// The largest Ritz value of the last run.
    theta: f64,
}

/// Where the iteration starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Start<'a> {
    /// A fixed pseudo-random vector.
    Random,
    /// A given unit vector, padded with zeros: for R = \[R₀ X; 0 Y\], R₀'s top right
    /// singular vector ([`Lanczos::ritz`]).
    Given(&'a [f64]),
}

impl Lanczos {
    /// Work space for n × n matrices (and smaller).
    pub fn new(n: usize) -> Self {
        let np = n.next_multiple_of(4);
        Self {
            work: Work {
                // Grown as the steps need it (zeroing n² entries per analysis cost more
                // than the few steps use).
                basis: Vec::with_capacity(n * np),
                w: vec![0.0; np],
                tmp: vec![0.0; np],
                alpha: vec![0.0; n],
                beta: vec![0.0; n],
                steps: 0,
                theta: 0.0,
            },
            inv_diag: vec![0.0; np],
            square: vec![0.0; np * np],
            capacity: n,
            ritz: vec![0.0; np],
            ritz_len: 0,
        }
    }

    /// The largest order this work space takes.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Lanczos steps of the last call.
    #[cfg(test)]
    pub fn steps(&self) -> usize {
        self.work.steps
    }

    /// The right singular vector of the last [`Lanczos::sigma_max`] (unit; empty if none).
    pub fn ritz(&self) -> &[f64] {
        &self.ritz[..self.ritz_len]
    }

    /// σ_max(R) for upper-triangular R; keeps the right singular vector ([`Lanczos::ritz`]).
    pub fn sigma_max(&mut self, r: Triangle, start: Start) -> f64 {
        sigma_max(self, r, start)
    }

    /// σ_min(R) for upper-triangular R (0 if a diagonal entry is 0 or R⁻¹ overflows).
    /// Starts from the condition-estimator vector R⁻¹y, Rᵀy = e with e = ±1 chosen
    /// for growth (LINPACK), which leans towards the smallest singular vector.
    pub fn sigma_min(&mut self, r: Triangle) -> f64 {
        sigma_min(self, r)
    }

    /// [`Lanczos::sigma_max`] by the copy for R's order (the analysis' 24, 30, 36; the
    /// module docs).
    #[inline(always)]
    fn sigma_max_inline(&mut self, r: Triangle, start: Start) -> f64 {
        match r.n {
            24 => self.sigma_max_of::<24>(r, start),
            30 => self.sigma_max_of::<32>(r, start),
            36 => self.sigma_max_of::<36>(r, start),
            _ => self.sigma_max_of::<0>(r, start),
        }
    }

    /// [`Lanczos::sigma_min`] by the copy for R's order.
    #[inline(always)]
    fn sigma_min_inline(&mut self, r: Triangle) -> f64 {
        match r.n {
            24 => self.sigma_min_of::<24>(r),
            30 => self.sigma_min_of::<32>(r),
            36 => self.sigma_min_of::<36>(r),
            _ => self.sigma_min_of::<0>(r),
        }
    }

    /// [`Lanczos::sigma_max`] on R padded to order `NP` (0: n rounded up to four).
    #[inline(always)]
    fn sigma_max_of<const NP: usize>(&mut self, r: Triangle, start: Start) -> f64 {
        let (n, np) = (r.n, padded_order::<NP>(r.n));
        fill_square(r, np, 0.0, &mut self.square);
        self.work.grow(np);
        let first = &mut self.work.basis[..np];
        first.fill(0.0);
        match start {
            Start::Given(v) if !v.is_empty() && v.len() <= n => {
                first[..v.len()].copy_from_slice(v);
            }
            _ => start_vector(&mut first[..n]),
        }
        let square = Square {
            data: &self.square[..np * np],
            np,
        };
        let lambda = self
            .work
            .largest_eigenvalue::<NP>(n, np, Operator::Gram(square));
        self.ritz_len = match self.work.ritz_vector::<NP>(np, &mut self.ritz) {
            0 => 0,
            _ => n,
        };
        lambda.max(0.0).sqrt()
    }

    /// [`Lanczos::sigma_min`] on R padded to order `NP` (0: n rounded up to four).
    #[inline(always)]
    fn sigma_min_of<const NP: usize>(&mut self, r: Triangle) -> f64 {
        let (n, np) = (r.n, padded_order::<NP>(r.n));
        if r.is_singular() {
            return 0.0;
        }
        fill_square(r, np, 1.0, &mut self.square);
        for (j, d) in self.inv_diag[..np].iter_mut().enumerate() {
            *d = if j < n { 1.0 / r.column(j)[j] } else { 1.0 };
        }
        let square = Square {
            data: &self.square[..np * np],
            np,
        };
        let inv = &self.inv_diag[..np];
        let w = &mut self.work;
        w.grow(np);
        estimator_start::<NP>(square, n, inv, &mut w.tmp[..np], &mut w.basis[..np]);
        let norm = dot(&w.basis[..np], &w.basis[..np]).sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            start_vector(&mut w.basis[..n]);
            w.basis[n..np].fill(0.0);
        } else {
            w.basis[..np].iter_mut().for_each(|x| *x /= norm);
        }
        let lambda = w.largest_eigenvalue::<NP>(n, np, Operator::InverseGram(square, inv));
        if lambda.is_finite() && lambda > 0.0 {
            1.0 / lambda.sqrt()
        } else {
            0.0
        }
    }
}

avx2_dispatch! {
    fn sigma_max = sigma_max_avx2 / Lanczos::sigma_max_inline;
        (lz: &mut Lanczos, r: Triangle, start: Start) -> f64
}

avx2_dispatch! {
    fn sigma_min = sigma_min_avx2 / Lanczos::sigma_min_inline;
        (lz: &mut Lanczos, r: Triangle) -> f64
}

/// The operators whose largest eigenvalue gives σ_max² and 1/σ_min² (a plain enum, not a
/// closure: a closure would be compiled apart from the AVX2 code path that inlines the
/// rest of the iteration).
#[derive(Clone, Copy)]
enum Operator<'a> {
    /// RᵀR.
    Gram(Square<'a>),
    /// (RᵀR)⁻¹ = R⁻¹R⁻ᵀ, with 1 / R_jj.
    InverseGram(Square<'a>, &'a [f64]),
}

impl Operator<'_> {
    /// y = A x (`tmp` is scratch of the padded order).
    #[inline(always)]
    fn apply<const NP: usize>(self, x: &[f64], y: &mut [f64], tmp: &mut [f64]) {
        match self {
            Self::Gram(r) => {
                square_mul::<NP>(r, x, tmp);
                square_mul_transpose::<NP>(r, tmp, y);
            }
            Self::InverseGram(r, inv) => {
                square_solve_transpose::<NP>(r, inv, x, tmp);
                square_solve::<NP>(r, inv, tmp, y);
            }
        }
    }
}

impl Work {
    /// Makes the basis hold at least `len` entries.
    #[inline(always)]
    fn grow(&mut self, len: usize) {
        if self.basis.len() < len {
            self.basis.resize(len, 0.0);
        }
    }

    /// The largest eigenvalue of the symmetric positive semi-definite operator `op` of
    /// order `n`, padded to `np` (vectors of length `np` whose padding stays zero), from
    /// the unit start vector in the first basis slot.
    #[inline(always)]
    fn largest_eigenvalue<const NP: usize>(&mut self, n: usize, np: usize, op: Operator) -> f64 {
        let np = if NP == 0 { np } else { NP };
        assert!(self.w.len() >= np, "Lanczos: work space too small");
        self.steps = 0;
        self.theta = 0.0;
        if n == 0 {
            return 0.0;
        }
        let mut theta = 0.0;
        for k in 0..n {
            self.steps = k + 1;
            self.grow((k + 2).min(n) * np);
            let (done, current) = self.basis.split_at_mut(k * np);
            let q = &current[..np];
            op.apply::<NP>(q, &mut self.w[..np], &mut self.tmp[..np]);
            let w = &mut self.w[..np];
            if !all_finite(w) {
                return f64::INFINITY;
            }
            let a = dot(q, w);
            self.alpha[k] = a;
            axpy(-a, q, w);
            if k > 0 {
                axpy(-self.beta[k - 1], &done[(k - 1) * np..k * np], w);
            }
            let b = dot(w, w).sqrt();
            let (t, s) = top_ritz(&self.alpha[..=k], &self.beta[..k], theta);
            theta = t;
            self.theta = t;
            if k + 1 == n || b * s.abs() <= TOLERANCE * theta.abs() || b <= f64::EPSILON * theta {
                return theta;
            }
            self.beta[k] = b;
            let next = &mut self.basis[(k + 1) * np..(k + 2) * np];
            for (x, y) in next.iter_mut().zip(w.iter()) {
                *x = y / b;
            }
        }
        theta
    }

    /// Writes the Ritz vector of the last run's largest Ritz value θ into `out` (Σ y_i
    /// q_i with y the tridiagonal's eigenvector by its three-term recurrence), padded
    /// to `np` like the basis; returns its length `np` (0 if it could not be formed).
    #[inline(always)]
    fn ritz_vector<const NP: usize>(&self, np: usize, out: &mut [f64]) -> usize {
        let np = if NP == 0 { np } else { NP };
        let k = self.steps;
        if k == 0 {
            return 0;
        }
        let theta = self.theta;
        let ritz = &mut out[..np];
        ritz.fill(0.0);
        let (mut y_prev, mut y) = (0.0, 1.0);
        for i in 0..k {
            axpy(y, &self.basis[i * np..(i + 1) * np], ritz);
            if i + 1 < k {
                let b_prev = if i > 0 { self.beta[i - 1] } else { 0.0 };
                let next = ((theta - self.alpha[i]) * y - b_prev * y_prev) / self.beta[i];
                (y_prev, y) = (y, next);
            }
        }
        let norm = dot(ritz, ritz).sqrt();
        if norm > 0.0 && norm.is_finite() {
            ritz.iter_mut().for_each(|x| *x /= norm);
            np
        } else {
            0
        }
    }
}

/// x = R⁻¹ y with Rᵀ y = e, e_j = ±1 chosen so that |y_j| grows (`tmp` holds y; R of
/// order `n`, padded: y and x are zero in the padding).
#[inline(always)]
fn estimator_start<const NP: usize>(
    r: Square,
    n: usize,
    inv: &[f64],
    tmp: &mut [f64],
    x: &mut [f64],
) {
    let np = padded::<NP>(r);
    for (j, col) in r.data[..np * n].chunks_exact(np).enumerate() {
        let s = dot(&col[..j], &tmp[..j]);
        let e = if s > 0.0 { -1.0 } else { 1.0 };
        tmp[j] = (e - s) * inv[j];
    }
    tmp[n..np].fill(0.0);
    square_solve::<NP>(r, inv, tmp, x);
}

/// A fixed pseudo-random unit vector (xorshift), so no symmetry of the matrix can make
/// it orthogonal to the wanted eigenvector.
#[inline(always)]
fn start_vector(x: &mut [f64]) {
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    for v in x.iter_mut() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        *v = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
    }
    let norm = dot(x, x).sqrt();
    for v in x.iter_mut() {
        *v /= norm;
    }
}

/// The largest eigenvalue θ of the symmetric tridiagonal T (diagonal `alpha`,
/// off-diagonal `beta`) and the last component s of its unit eigenvector, by Newton's
/// method on the characteristic polynomial χ from an upper bound: the larger eigenvalue
/// of \[\[θ_prev, β_{k−1}\], \[β_{k−1}, α_k\]\] (θ_prev is the largest eigenvalue of T
/// without its last row and column). From above the largest root, Newton decreases monotonically to
/// it. s² = χ_{k−1}(θ)/χ_k′(θ).
#[inline(always)]
fn top_ritz(alpha: &[f64], beta: &[f64], theta_prev: f64) -> (f64, f64) {
    let k = alpha.len();
    if k == 1 {
        return (alpha[0], 1.0);
    }
    // The larger eigenvalue of [[θ_prev, β], [β, α_k]] bounds T's from above (for a unit
    // [x; ξ]: xᵀT_{k−1}x + 2βξ(eᵀx) + α_k ξ² ≤ (‖x‖, |ξ|) of that 2 × 2 form), and lies
    // within about β²/(θ_prev − α_k) of θ where Weyl's max(θ_prev, α_k) + β lies within β:
    // 6.1 → 3.8 Newton steps per call on average (9-DoF bench configuration).
    let (a_k, b_k) = (alpha[k - 1], beta[k - 2]);
    let half = 0.5 * (theta_prev - a_k);
    let upper = 0.5 * (theta_prev + a_k) + half.hypot(b_k);
    if !(upper > 0.0 && upper.is_finite()) {
        return (upper, 1.0);
    }
    // Work in units of the bound to keep χ of order one (divisions hoisted out of the
    // Newton loop: they sat on its dependency chain).
    let scale = upper;
    let mut a_buf = [0.0; 64];
    let mut b_buf = [0.0; 64];
    let (mut a_vec, mut b_vec) = (Vec::new(), Vec::new());
    let (a, b2) = if k <= 64 {
        (&mut a_buf[..k], &mut b_buf[..k])
    } else {
        a_vec.resize(k, 0.0);
        b_vec.resize(k, 0.0);
        (&mut a_vec[..], &mut b_vec[..])
    };
    let inv = 1.0 / scale;
    for i in 0..k {
        a[i] = alpha[i] * inv;
        b2[i] = if i > 0 {
            (beta[i - 1] * inv).powi(2)
        } else {
            0.0
        };
    }
    let mut lambda = 1.0;
    let mut chi_prev_row = 0.0;
    let mut derivative = 1.0;
    for _ in 0..200 {
        let (mut c2, mut c1) = (0.0, 1.0);
        let (mut d2, mut d1) = (0.0, 0.0);
        for i in 0..k {
            let c = (lambda - a[i]) * c1 - b2[i] * c2;
            let d = c1 + (lambda - a[i]) * d1 - b2[i] * d2;
            if i + 1 == k {
                chi_prev_row = c1;
            }
            (c2, c1) = (c1, c);
            (d2, d1) = (d1, d);
        }
        derivative = d1;
        if d1 <= 0.0 || !d1.is_finite() {
            break;
        }
        let step = c1 / d1;
        lambda -= step;
        // 1e-13 relative: far below the Lanczos tolerance, one Newton step short of ε.
        if step.abs() <= 1e-13 * lambda.abs() {
            break;
        }
    }
    let s2 = if derivative > 0.0 {
        (chi_prev_row / derivative).clamp(0.0, 1.0)
    } else {
        1.0
    };
    (lambda * scale, s2.sqrt())
}

/// a · b with four partial sums (independent chains; the compiler cannot reorder a
/// floating-point sum itself).
#[inline(always)]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

pub(crate) use crate::linalg::all_finite;

#[inline(always)]
fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
}

/// y = R x (R upper triangular of any order; the wide triangle's Lanczos start).
pub(crate) fn upper_mul(r: Triangle, x: &[f64], y: &mut [f64]) {
    y[..r.n].fill(0.0);
    for (j, &xj) in x[..r.n].iter().enumerate() {
        axpy(xj, r.column(j), &mut y[..=j]);
    }
}

/// R zero-padded to order `np` (n rounded up to four): column-major, leading dimension
/// `np`, zeros below the diagonal and in the padding (whose diagonal is 0 for RᵀR and 1
/// for its inverse), so that every kernel below works on whole blocks of four.
#[derive(Clone, Copy)]
struct Square<'a> {
    data: &'a [f64],
    np: usize,
}

/// Four consecutive entries.
type Quad = [f64; 4];

/// Entries at..at + 4 of `s`.
#[inline(always)]
fn quad(s: &[f64], at: usize) -> Quad {
    s[at..at + 4].try_into().expect("four entries")
}

/// The padded order of `s`: `NP` where the caller fixed it at compile time, else `s.np`.
#[inline(always)]
fn padded<const NP: usize>(s: Square) -> usize {
    if NP == 0 { s.np } else { NP }
}

/// The padded order for R of order `n`: `NP` where fixed (then n rounded up to four).
#[inline(always)]
fn padded_order<const NP: usize>(n: usize) -> usize {
    if NP == 0 {
        n.next_multiple_of(4)
    } else {
        debug_assert_eq!(n.next_multiple_of(4), NP, "Lanczos: padded order");
        NP
    }
}

/// Writes R into `out` as a [`Square`] of order `np`, `pad` on the padding's diagonal.
#[inline(always)]
fn fill_square(r: Triangle, np: usize, pad: f64, out: &mut Vec<f64>) {
    if out.len() < np * np {
        out.resize(np * np, 0.0);
    }
    for (j, col) in out[..np * np].chunks_exact_mut(np).enumerate() {
        if j < r.n {
            col[..=j].copy_from_slice(&r.column(j)[..=j]);
            col[j + 1..].fill(0.0);
        } else {
            col.fill(0.0);
            col[j] = pad;
        }
    }
}

/// (a₀ + a₁) + (a₂ + a₃).
#[inline(always)]
fn hsum(a: Quad) -> f64 {
    (a[0] + a[1]) + (a[2] + a[3])
}

/// Entries at..at + 4 of `s` as one vector.
#[inline(always)]
fn load(s: &[f64], at: usize) -> F64x4 {
    F64x4(quad(s, at))
}

/// [`hsum`] of a vector.
#[inline(always)]
fn hsum4(a: F64x4) -> f64 {
    hsum(a.0)
}

/// y = R x.
#[inline(always)]
fn square_mul<const NP: usize>(s: Square, x: &[f64], y: &mut [f64]) {
    let np = padded::<NP>(s);
    let data = &s.data[..np * np];
    for (c, out) in y[..np].chunks_exact_mut(4).enumerate() {
        let mut acc = F64x4([0.0; 4]);
        let cols = data[4 * c * np..].chunks_exact(np);
        for (col, &xj) in cols.zip(&x[4 * c..np]) {
            acc += load(&col[4 * c..], 0) * F64x4([xj; 4]);
        }
        out.copy_from_slice(&acc.0);
    }
}

/// Σ_c R\[4c..4c + 4, j\] ⊙ v\[4c..4c + 4\] over the blocks c of `v`, for the four columns j
/// of `block` (partial sums per lane).
#[inline(always)]
fn block_dots(block: &[f64], np: usize, v: &[f64]) -> [F64x4; 4] {
    let mut acc = [F64x4([0.0; 4]); 4];
    for (acc, col) in acc.iter_mut().zip(block.chunks_exact(np)) {
        for (cv, vv) in col[..v.len()].chunks_exact(4).zip(v.chunks_exact(4)) {
            *acc += load(cv, 0) * load(vv, 0);
        }
    }
    acc
}

/// y = Rᵀ x.
#[inline(always)]
fn square_mul_transpose<const NP: usize>(s: Square, x: &[f64], y: &mut [f64]) {
    let np = padded::<NP>(s);
    for (b, (out, block)) in y[..np]
        .chunks_exact_mut(4)
        .zip(s.data[..np * np].chunks_exact(4 * np))
        .enumerate()
    {
        let acc = block_dots(block, np, &x[..4 * b + 4]);
        for k in 0..4 {
            out[k] = hsum4(acc[k]);
        }
    }
}

/// Solves Rᵀ y = x (forward substitution); `inv` holds 1 / R_jj (1 in the padding).
#[inline(always)]
fn square_solve_transpose<const NP: usize>(s: Square, inv: &[f64], x: &[f64], y: &mut [f64]) {
    let np = padded::<NP>(s);
    // Zeros where y is not solved yet: each block's dots then run over its own rows too
    // (adding exact zeros), the same loop as in Rᵀ x, which the compiler vectorizes
    // whole; over the rows above alone it split the sums into two-lane halves.
    y[..np].fill(0.0);
    for (b, block) in s.data[..np * np].chunks_exact(4 * np).enumerate() {
        let acc = block_dots(block, np, &y[..4 * b + 4]);
        let d: [Quad; 4] = std::array::from_fn(|k| quad(block, k * np + 4 * b));
        let mut ys = [0.0; 4];
        for k in 0..4 {
            let mut t = x[4 * b + k] - hsum4(acc[k]);
            for a in 0..k {
                t -= d[k][a] * ys[a];
            }
            ys[k] = t * inv[4 * b + k];
        }
        y[4 * b..4 * b + 4].copy_from_slice(&ys);
    }
}

/// Solves R y = x (back substitution); `inv` holds 1 / R_jj (1 in the padding).
#[inline(always)]
fn square_solve<const NP: usize>(s: Square, inv: &[f64], x: &[f64], y: &mut [f64]) {
    let np = padded::<NP>(s);
    y[..np].copy_from_slice(&x[..np]);
    for (b, block) in s.data[..np * np].chunks_exact(4 * np).enumerate().rev() {
        let d: [Quad; 4] = std::array::from_fn(|k| quad(block, k * np + 4 * b));
        let mut ys = [0.0; 4];
        for k in (0..4).rev() {
            let mut t = y[4 * b + k];
            for a in k + 1..4 {
                t -= d[a][k] * ys[a];
            }
            ys[k] = t * inv[4 * b + k];
        }
        y[4 * b..4 * b + 4].copy_from_slice(&ys);
        let yb: [F64x4; 4] = std::array::from_fn(|k| F64x4([ys[k]; 4]));
        for (c, yc) in y[..4 * b].chunks_exact_mut(4).enumerate() {
            let p: [F64x4; 4] = std::array::from_fn(|k| load(block, k * np + 4 * c));
            let t = (p[0] * yb[0] + p[1] * yb[1]) + (p[2] * yb[2] + p[3] * yb[3]);
            let out = load(yc, 0) - t;
            yc.copy_from_slice(&out.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    fn tri(r: &DMatrix<f64>) -> Triangle<'_> {
        Triangle {
            data: r.as_slice(),
            n: r.nrows(),
            ld: r.nrows(),
        }
    }

    /// An upper-triangular matrix with graded, clustered singular values like the
    /// boundary blocks': R = triu(QR of a matrix with chosen singular values).
    fn graded(n: usize) -> DMatrix<f64> {
        let u = DMatrix::from_fn(n, n, |i, j| ((i * n + j) as f64 * 0.37).sin())
            .qr()
            .q();
        let v = DMatrix::from_fn(n, n, |i, j| ((i * 3 + j * 7) as f64 * 0.11).cos())
            .qr()
            .q();
        let s = DMatrix::from_fn(n, n, |i, j| {
            if i == j {
                // Three nearly equal large values, a gap, then 1e-4..1e0 decades.
                match i {
                    0 | 1 => 5.04e4,
                    2 => 4.43e4,
                    _ => 10f64.powf(-4.0 + 4.0 * (i as f64 - 3.0) / (n as f64 - 4.0)),
                }
            } else {
                0.0
            }
        });
        (u * s * v.transpose()).qr().r()
    }

    #[test]
    fn extremes_match_the_dense_svd() {
        for n in [1, 2, 6, 24, 30, 36] {
            let r = graded(n.max(5)).view((0, 0), (n, n)).into_owned();
            let r = r.upper_triangle();
            let s = r.clone().singular_values();
            let (max, min) = (s.max(), s.min());
            let mut lz = Lanczos::new(n);
            let got_max = lz.sigma_max(tri(&r), Start::Random);
            assert!(lz.steps() <= n);
            let got_min = lz.sigma_min(tri(&r));
            assert!(
                (got_max - max).abs() <= 1e-9 * max,
                "n = {n}: σ_max {got_max} vs {max}"
            );
            // The dense SVD itself is only accurate to ε·σ_max in σ_min.
            assert!(
                (got_min - min).abs() <= 1e-8 * min + 1e-15 * max,
                "n = {n}: σ_min {got_min} vs {min}"
            );
        }
    }

    /// The dispatched runs (AVX2 where the CPU has it) give bitwise what their portable
    /// bodies give.
    #[test]
    fn the_dispatched_runs_equal_their_portable_bodies_bitwise() {
        let r = graded(36).upper_triangle();
        let (mut fast, mut plain) = (Lanczos::new(36), Lanczos::new(36));
        let max = (
            fast.sigma_max(tri(&r), Start::Random),
            plain.sigma_max_inline(tri(&r), Start::Random),
        );
        assert_eq!(max.0.to_bits(), max.1.to_bits(), "σ_max");
        assert_eq!(fast.ritz(), plain.ritz(), "Ritz vector");
        let min = (fast.sigma_min(tri(&r)), plain.sigma_min_inline(tri(&r)));
        assert_eq!(min.0.to_bits(), min.1.to_bits(), "σ_min");
    }

    /// The runs with the analysis' orders fixed at compile time (24, 30, 36) give
    /// bitwise what the run of any order gives, also on a leading block (R_u in its
    /// `LegQr`: order 24, leading dimension 30).
    #[test]
    fn the_fixed_order_runs_equal_the_general_run_bitwise() {
        let r30 = graded(30).upper_triangle();
        let lead = Triangle {
            data: r30.as_slice(),
            n: 24,
            ld: 30,
        };
        let (r36, r24) = (graded(36).upper_triangle(), graded(24).upper_triangle());
        for t in [lead, tri(&r24), tri(&r30), tri(&r36)] {
            let n = t.n;
            let (mut fixed, mut general) = (Lanczos::new(n), Lanczos::new(n));
            let max = (
                fixed.sigma_max_inline(t, Start::Random),
                general.sigma_max_of::<0>(t, Start::Random),
            );
            assert_eq!(max.0.to_bits(), max.1.to_bits(), "σ_max, n = {n}");
            assert_eq!(fixed.ritz(), general.ritz(), "Ritz vector, n = {n}");
            let min = (fixed.sigma_min_inline(t), general.sigma_min_of::<0>(t));
            assert_eq!(min.0.to_bits(), min.1.to_bits(), "σ_min, n = {n}");
        }
    }

    #[test]
    fn a_warm_start_from_the_leading_block_converges_to_the_same_value() {
        let r = graded(30);
        let lead = r.view((0, 0), (24, 24)).into_owned();
        let mut lz = Lanczos::new(30);
        lz.sigma_max(tri(&lead), Start::Random);
        let v = lz.ritz().to_vec();
        assert_eq!(v.len(), 24);
        let warm = lz.sigma_max(tri(&r), Start::Given(&v));
        let cold = Lanczos::new(30).sigma_max(tri(&r), Start::Random);
        assert!((warm - cold).abs() <= 1e-9 * cold, "{warm} vs {cold}");
    }

    #[test]
    fn the_padded_kernels_match_dense_products_and_solves() {
        for n in [1, 2, 3, 4, 7, 8, 30] {
            let r = DMatrix::from_fn(n, n, |i, j| {
                if i == j {
                    2.0 + i as f64
                } else if i < j {
                    ((i * 7 + j * 3) as f64).sin()
                } else {
                    // Below the diagonal the storage holds anything; it is not read.
                    f64::NAN
                }
            });
            let np = n.next_multiple_of(4);
            let dense = r.upper_triangle();
            let mut x: Vec<f64> = (0..np).map(|i| (i as f64 + 0.5).sin()).collect();
            x[n..].fill(0.0);
            let xv = nalgebra::DVector::from_column_slice(&x[..n]);
            let (mut y, mut store) = (vec![1.0; np], Vec::new());
            let check = |y: &[f64], want: nalgebra::DVector<f64>| {
                let got = nalgebra::DVector::from_column_slice(&y[..n]);
                assert!(
                    (got - &want).norm() < 1e-12 * (1.0 + want.norm()),
                    "n = {n}"
                );
                assert!(y[n..].iter().all(|&v| v == 0.0), "n = {n}: padding");
            };
            fill_square(tri(&r), np, 0.0, &mut store);
            let sq = Square { data: &store, np };
            upper_mul(tri(&r), &x, &mut y);
            check(&y[..n], &dense * &xv);
            square_mul::<0>(sq, &x, &mut y);
            check(&y, &dense * &xv);
            square_mul_transpose::<0>(sq, &x, &mut y);
            check(&y, dense.transpose() * &xv);
            fill_square(tri(&r), np, 1.0, &mut store);
            let sq = Square { data: &store, np };
            let inv: Vec<f64> = (0..np)
                .map(|j| if j < n { 1.0 / r[(j, j)] } else { 1.0 })
                .collect();
            square_solve::<0>(sq, &inv, &x, &mut y);
            check(&y, dense.solve_upper_triangular(&xv).unwrap());
            square_solve_transpose::<0>(sq, &inv, &x, &mut y);
            check(&y, dense.transpose().solve_lower_triangular(&xv).unwrap());
        }
    }

    #[test]
    fn a_zero_diagonal_gives_sigma_min_zero_and_no_nan() {
        let mut r = graded(8);
        r[(3, 3)] = 0.0;
        let mut lz = Lanczos::new(8);
        assert_eq!(lz.sigma_min(tri(&r)), 0.0);
        assert!(lz.sigma_max(tri(&r), Start::Random).is_finite());
        let zero = DMatrix::zeros(3, 3);
        assert_eq!(Lanczos::new(3).sigma_max(tri(&zero), Start::Random), 0.0);
    }

    #[test]
    fn the_top_ritz_value_of_a_known_tridiagonal() {
        // T = tridiag(1, 2, 1) of size 4: eigenvalues 2 + 2 cos(kπ/5).
        let (theta, s) = top_ritz(&[2.0; 4], &[1.0; 3], 3.0);
        let exact = 2.0 + 2.0 * (std::f64::consts::PI / 5.0).cos();
        assert!((theta - exact).abs() < 1e-12, "{theta} vs {exact}");
        // The eigenvector is sin(jkπ/5), normalized: last component sin(4π/5)/√(5/2).
        let last = (4.0 * std::f64::consts::PI / 5.0).sin() / (2.5f64).sqrt();
        assert!((s - last).abs() < 1e-12, "{s} vs {last}");
    }
}
