//! Tangents of the rod state in all sensitivity directions at once, stored
//! structure-of-arrays (`component[direction]`) so each operation is a loop over
//! directions that the compiler vectorizes.

use crate::design::MAX_TENDONS;

/// Most sensitivity directions: u(0), v(0) and one tension per tendon.
pub const MAX_DIRECTIONS: usize = 6 + MAX_TENDONS;

/// One scalar component across directions.
pub type Lanes = [f64; MAX_DIRECTIONS];

/// ∂(rod state)/∂(direction j) for j < `n`: position, rotation (column-major 3×3),
/// strains and tendon path lengths.
#[derive(Debug, Clone, PartialEq)]
pub struct Tangents {
    /// Number of directions in use.
    pub n: usize,
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
    /// Zero tangents for `n` directions.
    pub fn zeros(n: usize) -> Self {
        let z = [0.0; MAX_DIRECTIONS];
        Self {
            n,
            p: [z; 3],
            r: [z; 9],
            v: [z; 3],
            u: [z; 3],
            s: [z; MAX_TENDONS],
        }
    }

    /// The initial tangents: direction j < 3 is u(0)_j, 3 ≤ j < 6 is v(0)_(j−3), the rest
    /// (tensions) start at zero.
    pub fn set_initial(&mut self, n: usize) {
        *self = Self::zeros(n);
        for c in 0..3 {
            self.u[c][c] = 1.0;
            self.v[c][3 + c] = 1.0;
        }
    }

    /// Applies `f(dst, src)` to every lane array pair of the state part and the first `nt`
    /// tendon lengths.
    #[inline]
    fn zip_with(&mut self, other: &Self, nt: usize, mut f: impl FnMut(&mut Lanes, &Lanes)) {
        for c in 0..3 {
            f(&mut self.p[c], &other.p[c]);
            f(&mut self.v[c], &other.v[c]);
            f(&mut self.u[c], &other.u[c]);
        }
        for c in 0..9 {
            f(&mut self.r[c], &other.r[c]);
        }
        for k in 0..nt {
            f(&mut self.s[k], &other.s[k]);
        }
    }

    /// self += a·k.
    #[inline]
    pub fn axpy(&mut self, a: f64, k: &Self, nt: usize) {
        let n = self.n;
        self.zip_with(k, nt, |d, s| {
            for (x, y) in d[..n].iter_mut().zip(&s[..n]) {
                *x += a * y;
            }
        });
    }

    /// self = y + a·k.
    #[inline]
    pub fn set_axpy(&mut self, y: &Self, a: f64, k: &Self, nt: usize) {
        let n = y.n;
        self.n = n;
        let pairs = |d: &mut [Lanes], s: &[Lanes], t: &[Lanes]| {
            for ((d, s), t) in d.iter_mut().zip(s).zip(t) {
                for ((x, y), z) in d[..n].iter_mut().zip(&s[..n]).zip(&t[..n]) {
                    *x = y + a * z;
                }
            }
        };
        pairs(&mut self.p, &y.p, &k.p);
        pairs(&mut self.r, &y.r, &k.r);
        pairs(&mut self.v, &y.v, &k.v);
        pairs(&mut self.u, &y.u, &k.u);
        pairs(&mut self.s[..nt], &y.s[..nt], &k.s[..nt]);
    }

    /// self = k (the first `nt` tendon lengths).
    #[inline]
    pub fn assign(&mut self, k: &Self, nt: usize) {
        let n = k.n;
        self.n = n;
        self.zip_with(k, nt, |d, s| d[..n].copy_from_slice(&s[..n]));
    }
}
