//! Tangents of the rod state in all sensitivity directions at once, stored
//! structure-of-arrays (`component[direction]`). The kernels take the number of lanes
//! `N` as a const parameter (8 for a leg with one tendon pair, 10 for two pairs), so every
//! loop over directions has a fixed trip count the compiler unrolls and vectorizes; lanes
//! beyond the directions in use stay zero.

use crate::design::MAX_TENDONS;
use crate::rod::lanes::fma;
use crate::rod::rhs::FEEDBACK_ROWS;

/// Most sensitivity directions: u(0), v(0) and one tension per tendon.
pub const MAX_DIRECTIONS: usize = 6 + MAX_TENDONS;

/// One scalar component across directions.
pub type Lanes = [f64; MAX_DIRECTIONS];

/// ∂(rod state)/∂(direction j) for every lane j: position, rotation (column-major 3×3),
/// strains and tendon path lengths.
#[derive(Debug, Clone, PartialEq)]
pub struct Tangents {
    /// `dp[c][j]`.
    pub p: [Lanes; 3],
    /// `dR[3·col + row][j]`.
    pub r: [Lanes; 9],
    /// `dv[c][j]`.
    pub v: [Lanes; 3],
    /// `du[c][j]`.
    pub u: [Lanes; 3],
    /// `ds_k[j]`.
    pub s: [Lanes; MAX_TENDONS],
}

impl Tangents {
    /// All zeros.
    pub fn zeros() -> Self {
        let z = [0.0; MAX_DIRECTIONS];
        Self {
            p: [z; 3],
            r: [z; 9],
            v: [z; 3],
            u: [z; 3],
            s: [z; MAX_TENDONS],
        }
    }

    /// The initial tangents of the first `N` lanes: direction j < 3 is u(0)_j, 3 ≤ j < 6
    /// is v(0)_(j−3), the rest (tensions) start at zero.
    ///
    /// Each row group is cleared by its own loop: one iterator chained over the groups
    /// was compiled as a jump table per row (6-DoF exact Jacobian 390.3 k → 389.4 k
    /// instructions without it; callgrind, 2026-11-27, fourteenth session).
    pub fn set_initial<const N: usize>(&mut self, nt: usize) {
        let clear = |rows: &mut [Lanes]| rows.iter_mut().for_each(|l| l[..N].fill(0.0));
        clear(&mut self.p);
        clear(&mut self.r);
        clear(&mut self.v);
        clear(&mut self.u);
        clear(&mut self.s[..nt]);
        for c in 0..3 {
            self.u[c][c] = 1.0;
            self.v[c][3 + c] = 1.0;
        }
    }

    /// Adds Σ_j c_j k_j to the first `N` lanes of the R, v, u rows (the terms in order,
    /// fused multiply–adds): the earlier stages' terms of a stage input. Each k_j is given
    /// by its [`FEEDBACK_ROWS`] rows of `N` lanes, row after row (as
    /// [`RkEmit`](crate::rod::rhs::RkEmit) keeps them). At most `MAX_STAGES` − 1 terms.
    ///
    /// Dispatched on the number of terms to a loop unrolled at compile time: the loop
    /// over a run-time list cost a pointer load, a bounds check and a broadcast per term
    /// and row around two vector FMAs (the exact Jacobian −8 % instructions without it,
    /// BENCHMARKS.md "Stage inputs with the term count fixed at compile time").
    #[inline(always)]
    pub fn add_kept<const N: usize>(&mut self, terms: &[(f64, &[f64])]) {
        match terms.len() {
            0 => {}
            1 => self.add_kept_terms::<N, 1>(terms),
            2 => self.add_kept_terms::<N, 2>(terms),
            3 => self.add_kept_terms::<N, 3>(terms),
            4 => self.add_kept_terms::<N, 4>(terms),
            5 => self.add_kept_terms::<N, 5>(terms),
            n => unreachable!("{n} stage-input terms: more than a tableau has"),
        }
    }

    /// [`Tangents::add_kept`] of exactly `T` terms.
    #[inline(always)]
    fn add_kept_terms<const N: usize, const T: usize>(&mut self, terms: &[(f64, &[f64])]) {
        let terms: &[(f64, &[f64]); T] = terms.try_into().expect("T terms");
        for index in 0..FEEDBACK_ROWS {
            let out = match index {
                0..9 => &mut self.r[index],
                9..12 => &mut self.v[index - 9],
                _ => &mut self.u[index - 12],
            };
            let mut acc = [0.0; N];
            acc.copy_from_slice(&out[..N]);
            for &(c, k) in terms {
                let k: &[f64; N] = k[index * N..(index + 1) * N].try_into().expect("N lanes");
                for j in 0..N {
                    acc[j] = fma(c, k[j], acc[j]);
                }
            }
            out[..N].copy_from_slice(&acc);
        }
    }

    /// Copies the first `N` lanes of the R, v, u rows of `y`.
    #[inline(always)]
    pub fn copy_feedback<const N: usize>(&mut self, y: &Self) {
        for (out, y) in self
            .r
            .iter_mut()
            .chain(&mut self.v)
            .chain(&mut self.u)
            .zip(y.r.iter().chain(&y.v).chain(&y.u))
        {
            out[..N].copy_from_slice(&y[..N]);
        }
    }
}
