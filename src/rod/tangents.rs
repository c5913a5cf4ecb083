//! Tangents of the rod state in all sensitivity directions at once, stored
//! structure-of-arrays (`component[direction]`). The kernels take the number of lanes
//! `N` as a const parameter (8 for a leg with one tendon pair, 10 for two pairs), so every
//! loop over directions has a fixed trip count the compiler unrolls and vectorizes; lanes
//! beyond the directions in use stay zero.

use crate::design::MAX_TENDONS;

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
    pub fn set_initial<const N: usize>(&mut self, nt: usize) {
        for lanes in self.rows_mut(nt) {
            lanes[..N].fill(0.0);
        }
        for c in 0..3 {
            self.u[c][c] = 1.0;
            self.v[c][3 + c] = 1.0;
        }
    }

    /// Every component row: p, R, v, u, then the first `nt` tendon lengths.
    fn rows_mut(&mut self, nt: usize) -> impl Iterator<Item = &mut Lanes> {
        self.p
            .iter_mut()
            .chain(self.r.iter_mut())
            .chain(self.v.iter_mut())
            .chain(self.u.iter_mut())
            .chain(self.s[..nt].iter_mut())
    }

    /// self = y + a·k over every component (the first `N` lanes, `nt` tendon lengths).
    #[inline]
    pub fn set_sum<const N: usize>(&mut self, y: &Self, a: f64, k: &Self, nt: usize) {
        let pairs = |d: &mut [Lanes], s: &[Lanes], t: &[Lanes]| {
            for ((d, s), t) in d.iter_mut().zip(s).zip(t) {
                for j in 0..N {
                    d[j] = s[j] + a * t[j];
                }
            }
        };
        pairs(&mut self.p, &y.p, &k.p);
        pairs(&mut self.s[..nt], &y.s[..nt], &k.s[..nt]);
        self.set_stage::<N>(y, a, k);
    }

    /// self = y + a·k for the components that feed back into the right-hand side (R, v, u):
    /// an intermediate RK stage needs no p or s.
    #[inline]
    pub fn set_stage<const N: usize>(&mut self, y: &Self, a: f64, k: &Self) {
        let pairs = |d: &mut [Lanes], s: &[Lanes], t: &[Lanes]| {
            for ((d, s), t) in d.iter_mut().zip(s).zip(t) {
                for j in 0..N {
                    d[j] = s[j] + a * t[j];
                }
            }
        };
        pairs(&mut self.r, &y.r, &k.r);
        pairs(&mut self.v, &y.v, &k.v);
        pairs(&mut self.u, &y.u, &k.u);
    }

    /// self += a·k over every component (the first `N` lanes, `nt` tendon lengths).
    #[inline]
    pub fn axpy<const N: usize>(&mut self, a: f64, k: &Self, nt: usize) {
        let add = |d: &mut [Lanes], s: &[Lanes]| {
            for (d, s) in d.iter_mut().zip(s) {
                for j in 0..N {
                    d[j] += a * s[j];
                }
            }
        };
        add(&mut self.p, &k.p);
        add(&mut self.r, &k.r);
        add(&mut self.v, &k.v);
        add(&mut self.u, &k.u);
        add(&mut self.s[..nt], &k.s[..nt]);
    }
}
