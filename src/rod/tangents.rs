//! Tangents of the rod state in all sensitivity directions at once, stored
//! structure-of-arrays: one row per scalar component, `N` lanes (directions) a row, the
//! rows packed one after another. The kernels take the number of lanes `N` as a const
//! parameter (8 for a leg with one tendon pair, 10 for two pairs), so every loop over
//! directions has a fixed trip count the compiler unrolls and vectorizes; lanes beyond the
//! directions in use stay zero.
//!
//! Why packed rows of `N` lanes rather than rows of [`MAX_DIRECTIONS`]: a leg's stage
//! touches its tangents, the stage input and the stages' derivatives, 20 rows each; at 18
//! lanes a row (144 bytes) the 8 lanes in use of a row straddled two cache lines three
//! times in four, and the three legs' buffers did not fit in the 32 kB first-level data
//! cache (BENCHMARKS.md "The stages' derivatives stored, each sum formed once").

use crate::design::MAX_TENDONS;
use crate::rod::lanes::fma;
use crate::rod::tableau::MAX_STAGES;

/// Most sensitivity directions: u(0), v(0) and one tension per tendon.
pub const MAX_DIRECTIONS: usize = 6 + MAX_TENDONS;

/// Rows of the tangents that feed back into the right-hand side: R, v, u.
pub const FEEDBACK_ROWS: usize = 15;

/// First v row. Rows, in order: R entry 3·col + row at 0..9, then v, u, p and the tendon
/// lengths s_k.
pub const K_V: usize = 9;
/// First u row.
pub const K_U: usize = 12;
/// First p row.
pub const K_P: usize = FEEDBACK_ROWS;
/// Row of s_0 (s_k at `K_S + k`).
pub const K_S: usize = FEEDBACK_ROWS + 3;
/// Rows in all.
pub const ROWS: usize = K_S + MAX_TENDONS;

/// ∂(rod state)/∂(direction j) for every lane j, or one RK stage's derivative of it:
/// position, rotation (column-major 3×3), strains and tendon path lengths, row by row
/// (the feedback rows R, v, u first, so a stage input is rows `0..FEEDBACK_ROWS`).
///
/// Aligned to a cache line, so that a row of 8 lanes is one line (at the allocator's 16
/// bytes every row spanned two: the exact Jacobian about 7 % slower, BENCHMARKS.md "The stages'
/// derivatives stored, each sum formed once").
#[derive(Debug, Clone, PartialEq)]
#[repr(C, align(64))]
pub struct Tangents {
    /// Row `i`, lane `j` at `i·N + j` (for the `N` of the kernel that wrote it).
    data: [f64; ROWS * MAX_DIRECTIONS],
}

impl Tangents {
    /// All zeros.
    pub fn zeros() -> Self {
        Self {
            data: [0.0; ROWS * MAX_DIRECTIONS],
        }
    }

    /// Row `index` (`K_*` above) of `N` lanes.
    #[inline(always)]
    pub fn row<const N: usize>(&self, index: usize) -> &[f64; N] {
        self.data[index * N..(index + 1) * N]
            .try_into()
            .expect("N lanes")
    }

    /// Row `index` of `N` lanes, mutable.
    #[inline(always)]
    pub fn row_mut<const N: usize>(&mut self, index: usize) -> &mut [f64; N] {
        (&mut self.data[index * N..(index + 1) * N])
            .try_into()
            .expect("N lanes")
    }

    /// The initial tangents of `N` lanes (rows of the `nt` tendons only): direction
    /// j < 3 is u(0)_j, 3 ≤ j < 6 is v(0)_(j−3), the rest (tensions) start at zero.
    pub fn set_initial<const N: usize>(&mut self, nt: usize) {
        self.data[..(K_S + nt) * N].fill(0.0);
        for c in 0..3 {
            self.row_mut::<N>(K_U + c)[c] = 1.0;
            self.row_mut::<N>(K_V + c)[3 + c] = 1.0;
        }
    }

    /// Sets rows `0..rows` to base + Σ_t c_t k_t, the terms in order (fused
    /// multiply–adds from base), where base is `from`'s row, or this row itself if `from`
    /// is `None` (the step's end, formed in place). One pass per row over all of the
    /// step's terms: a stage input (base the step's start, `rows` the [`FEEDBACK_ROWS`])
    /// or the step's end (every row). At most [`MAX_STAGES`] terms, dispatched on their
    /// number to a loop unrolled at compile time: a loop over a run-time list cost a
    /// pointer load, a bounds check and a broadcast per term and row around two vector
    /// FMAs (BENCHMARKS.md "Stage inputs with the term count fixed at compile time").
    ///
    /// The stages' k are stored and combined here rather than streamed into the sum and
    /// the next input as each stage produces them: the streaming updated the sum in
    /// memory at every stage and tested, per row, whether it was the first stage, whether
    /// the weight was zero, whether a next input and a kept copy were wanted (BENCHMARKS.md
    /// "The stages' derivatives stored, each sum formed once").
    #[inline(always)]
    pub fn set_combination<const N: usize>(
        &mut self,
        from: Option<&Tangents>,
        terms: &[(f64, &Tangents)],
        rows: usize,
    ) {
        match terms.len() {
            1 => self.set_combination_terms::<N, 1>(from, terms, rows),
            2 => self.set_combination_terms::<N, 2>(from, terms, rows),
            3 => self.set_combination_terms::<N, 3>(from, terms, rows),
            4 => self.set_combination_terms::<N, 4>(from, terms, rows),
            5 => self.set_combination_terms::<N, 5>(from, terms, rows),
            6 => self.set_combination_terms::<N, 6>(from, terms, rows),
            n => unreachable!("{n} terms: none, or more than a tableau's {MAX_STAGES} stages"),
        }
    }

    /// [`Tangents::set_combination`] of exactly `C` terms.
    #[inline(always)]
    fn set_combination_terms<const N: usize, const C: usize>(
        &mut self,
        from: Option<&Tangents>,
        terms: &[(f64, &Tangents)],
        rows: usize,
    ) {
        let terms: &[(f64, &Tangents); C] = terms.try_into().expect("C terms");
        for index in 0..rows {
            let mut acc = match from {
                Some(from) => *from.row::<N>(index),
                None => *self.row::<N>(index),
            };
            for &(c, k) in terms {
                let k = k.row::<N>(index);
                for j in 0..N {
                    acc[j] = fma(c, k[j], acc[j]);
                }
            }
            *self.row_mut::<N>(index) = acc;
        }
    }

    /// Copies the R, v, u rows of `y`.
    #[inline(always)]
    pub fn copy_feedback<const N: usize>(&mut self, y: &Self) {
        self.data[..FEEDBACK_ROWS * N].copy_from_slice(&y.data[..FEEDBACK_ROWS * N]);
    }
}
