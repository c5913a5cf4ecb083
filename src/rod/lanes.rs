//! The scalar of the rod kernel: `f64` for one leg, or [`F64x4`] for up to four legs
//! integrated together, one leg per SIMD lane.
//!
//! Why: the primal right-hand side ([`Stage::eval`](super::rhs::Stage::eval)) is a chain
//! of small 3×3 operations, two divisions and a square root per tendon, about 300
//! scalar instructions that no single leg can spread over vector lanes. The three legs of
//! a robot share the leg model and integration grid and differ only in their data, so one
//! vector instruction can do the same operation for all three. Measured on the reference
//! design (2026-11-25; callgrind instructions per evaluation, `examples/boundary_cost`):
//! the residual of the three legs 293.6 k → 150.7 k instructions with the lanes, the
//! exact Jacobian 1 047 k → 959 k (its tangents stay per leg, in direction lanes).
//! Interleaving the three scalar integrations stage by stage instead (letting the CPU
//! overlap them) gained 7 % (criterion, residual 32.5 → 30.1 µs). A first version of the
//! selects on `[bool; 4]` masks compiled to branches: +5 % instructions but 1.8× the time
//! of the Jacobian (mispredictions); the masks are bit patterns now.
//!
//! Every lane operation is the IEEE operation of `f64` in the same order (no fused
//! multiply–add), so a leg gives bitwise the same result in any lane as alone.
//! Branches on data (a slack tendon, a failed factorization) become per-lane selects
//! ([`Real::add_where`]) or all-lane tests ([`Real::all`]). Where a tendon is taut in every
//! lane (the common case) the right-hand side adds its terms plainly, the selects' results
//! bit for bit: 1.7 % fewer instructions but 7–10 % less time for the exact Jacobian (the
//! selects lie in the sums' dependency chains, our reading without hardware counters;
//! BENCHMARKS.md "The tangent kernel's live values; plain sums where every lane is taut").

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use nalgebra::{Matrix3, Vector3};
use num_traits::{One, Zero};

/// A scalar of the rod kernel: one leg (`f64`) or several legs in lanes.
pub trait Real:
    Copy
    + Debug
    + PartialEq
    + 'static
    + Zero
    + One
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
{
    /// Number of lanes (legs) it holds.
    const LANES: usize;
    /// Per-lane truth values.
    type Mask: Copy;
    /// Every lane `x`.
    fn splat(x: f64) -> Self;
    /// Lane `i`.
    fn lane(self, i: usize) -> f64;
    /// Lane `i`, in place.
    fn lane_ref(&self, i: usize) -> &f64;
    /// Sets lane `i` to `x`.
    fn set_lane(&mut self, i: usize, x: f64);
    /// Square root of each lane.
    fn sqrt(self) -> Self;
    /// Lanes that are not zero.
    fn nonzero(self) -> Self::Mask;
    /// Lanes that are positive (false for NaN).
    fn positive(self) -> Self::Mask;
    /// Lanes that are finite.
    fn finite(self) -> Self::Mask;
    /// Whether any lane of `m` is set.
    fn any(m: Self::Mask) -> bool;
    /// Whether every lane of `m` is set (a mask from [`Real::nonzero`] and its kin: each
    /// lane all ones or all zeros, so that [`Real::add_where`] under a mask with every lane
    /// set is the plain sum).
    fn all(m: Self::Mask) -> bool;
    /// `acc + x` in the lanes of `m`, `acc` elsewhere (bitwise: a lane outside `m` is
    /// left exactly as it was, as a skipped branch would leave it).
    fn add_where(m: Self::Mask, acc: Self, x: Self) -> Self;
}

impl Real for f64 {
    const LANES: usize = 1;
    type Mask = bool;

    #[inline(always)]
    fn splat(x: f64) -> Self {
        x
    }

    #[inline(always)]
    fn lane(self, _: usize) -> f64 {
        self
    }

    #[inline(always)]
    fn lane_ref(&self, _: usize) -> &f64 {
        self
    }

    #[inline(always)]
    fn set_lane(&mut self, _: usize, x: f64) {
        *self = x;
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }

    #[inline(always)]
    fn nonzero(self) -> bool {
        self != 0.0
    }

    #[inline(always)]
    fn positive(self) -> bool {
        self > 0.0
    }

    #[inline(always)]
    fn finite(self) -> bool {
        self.is_finite()
    }

    #[inline(always)]
    fn any(m: bool) -> bool {
        m
    }

    #[inline(always)]
    fn all(m: bool) -> bool {
        m
    }

    #[inline(always)]
    fn add_where(m: bool, acc: Self, x: Self) -> Self {
        if m { acc + x } else { acc }
    }
}

/// Four `f64` lanes, one leg each (the fourth repeats the first when three are used).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(32))]
pub struct F64x4(pub [f64; 4]);

impl F64x4 {
    #[inline(always)]
    fn map2(self, o: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let (a, b) = (self.0, o.0);
        F64x4([f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]), f(a[3], b[3])])
    }
}

macro_rules! lane_ops {
    ($($op:ident $fn:ident $op_assign:ident $fn_assign:ident $sym:tt),*) => {$(
        impl $op for F64x4 {
            type Output = Self;
            #[inline(always)]
            fn $fn(self, o: Self) -> Self {
                self.map2(o, |a, b| a $sym b)
            }
        }
        impl $op_assign for F64x4 {
            #[inline(always)]
            fn $fn_assign(&mut self, o: Self) {
                *self = self.map2(o, |a, b| a $sym b);
            }
        }
    )*};
}

lane_ops!(
    Add add AddAssign add_assign +,
    Sub sub SubAssign sub_assign -,
    Mul mul MulAssign mul_assign *,
    Div div DivAssign div_assign /
);

impl Neg for F64x4 {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        let a = self.0;
        F64x4([-a[0], -a[1], -a[2], -a[3]])
    }
}

impl Zero for F64x4 {
    #[inline(always)]
    fn zero() -> Self {
        F64x4([0.0; 4])
    }

    fn is_zero(&self) -> bool {
        self.0.iter().all(|x| *x == 0.0)
    }
}

impl One for F64x4 {
    #[inline(always)]
    fn one() -> Self {
        F64x4([1.0; 4])
    }
}

/// Lane masks of [`F64x4`]: all bits set where true (so selects are bit operations, no
/// branches).
type Bits = [u64; 4];

impl F64x4 {
    #[inline(always)]
    fn mask(self, f: impl Fn(f64) -> bool) -> Bits {
        let a = self.0;
        let m = |x: f64| if f(x) { u64::MAX } else { 0 };
        [m(a[0]), m(a[1]), m(a[2]), m(a[3])]
    }
}

impl Real for F64x4 {
    const LANES: usize = 4;
    type Mask = Bits;

    #[inline(always)]
    fn splat(x: f64) -> Self {
        F64x4([x; 4])
    }

    #[inline(always)]
    fn lane(self, i: usize) -> f64 {
        self.0[i]
    }

    #[inline(always)]
    fn lane_ref(&self, i: usize) -> &f64 {
        &self.0[i]
    }

    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: f64) {
        self.0[i] = x;
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        let a = self.0;
        F64x4([a[0].sqrt(), a[1].sqrt(), a[2].sqrt(), a[3].sqrt()])
    }

    #[inline(always)]
    fn nonzero(self) -> Bits {
        self.mask(|x| x != 0.0)
    }

    #[inline(always)]
    fn positive(self) -> Bits {
        self.mask(|x| x > 0.0)
    }

    #[inline(always)]
    fn finite(self) -> Bits {
        self.mask(f64::is_finite)
    }

    #[inline(always)]
    fn any(m: Bits) -> bool {
        (m[0] | m[1] | m[2] | m[3]) != 0
    }

    #[inline(always)]
    fn all(m: Bits) -> bool {
        (m[0] & m[1] & m[2] & m[3]) != 0
    }

    #[inline(always)]
    fn add_where(m: Bits, acc: Self, x: Self) -> Self {
        let sum = acc + x;
        let pick =
            |i: usize| f64::from_bits((sum.0[i].to_bits() & m[i]) | (acc.0[i].to_bits() & !m[i]));
        F64x4([pick(0), pick(1), pick(2), pick(3)])
    }
}

/// Whether every lane of every value is finite, as one test: x − x is 0 for a finite x
/// and NaN otherwise, and a NaN survives the sum. (An iterator over the values was not
/// inlined in the kernel: 2.3 % of the workspace sweep's instructions.)
#[inline(always)]
pub fn all_finite<T: Real, const K: usize>(values: [T; K]) -> bool {
    let mut probe = T::zero();
    for x in values {
        // Deliberately x − x: the probe, not a zero.
        #[allow(clippy::eq_op)]
        let zero_if_finite = x - x;
        probe += zero_if_finite;
    }
    T::all(probe.finite())
}

/// a·b + c with one rounding (the tangent kernel's fused multiply–add: an instruction
/// where the CPU has FMA, exact software emulation elsewhere, so the same bits on every
/// CPU).
#[inline(always)]
pub fn fma(a: f64, b: f64, c: f64) -> f64 {
    a.mul_add(b, c)
}

/// a × b, in nalgebra's order of operations (so bitwise its result for `f64`), always
/// inlined: nalgebra's generic products are not inlined for [`F64x4`], and a call leaves
/// the AVX2 code of the kernel.
#[inline(always)]
pub fn cross<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

/// a · b, as nalgebra sums it: (a₀b₀ + a₁b₁) + a₂b₂.
#[inline(always)]
pub fn dot<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> T {
    a.x * b.x + a.y * b.y + a.z * b.z
}

/// M x, as nalgebra sums it (by columns: (M₀x₀ + M₁x₁) + M₂x₂).
#[inline(always)]
pub fn mat_vec<T: Real>(m: &Matrix3<T>, x: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        m[(0, 0)] * x.x + m[(0, 1)] * x.y + m[(0, 2)] * x.z,
        m[(1, 0)] * x.x + m[(1, 1)] * x.y + m[(1, 2)] * x.z,
        m[(2, 0)] * x.x + m[(2, 1)] * x.y + m[(2, 2)] * x.z,
    )
}

/// Mᵀ x, as nalgebra sums it (a dot product per column).
#[inline(always)]
pub fn tr_mat_vec<T: Real>(m: &Matrix3<T>, x: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        dot(&m.column(0).into_owned(), x),
        dot(&m.column(1).into_owned(), x),
        dot(&m.column(2).into_owned(), x),
    )
}

/// A B, as nalgebra sums it (M x for each column x of B).
#[inline(always)]
pub fn mat_mul<T: Real>(a: &Matrix3<T>, b: &Matrix3<T>) -> Matrix3<T> {
    let c0 = mat_vec(a, &Vector3::new(b[(0, 0)], b[(1, 0)], b[(2, 0)]));
    let c1 = mat_vec(a, &Vector3::new(b[(0, 1)], b[(1, 1)], b[(2, 1)]));
    let c2 = mat_vec(a, &Vector3::new(b[(0, 2)], b[(1, 2)], b[(2, 2)]));
    Matrix3::new(c0.x, c1.x, c2.x, c0.y, c1.y, c2.y, c0.z, c1.z, c2.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_are_the_scalar_operations() {
        let a = F64x4([1.5, -2.0, 0.0, 3.0]);
        let b = F64x4([0.25, 4.0, -1.0, 0.0]);
        for i in 0..4 {
            let (x, y) = (a.0[i], b.0[i]);
            assert_eq!((a + b).lane(i), x + y);
            assert_eq!((a - b).lane(i), x - y);
            assert_eq!((a * b).lane(i), x * y);
            assert_eq!((a / b).lane(i).to_bits(), (x / y).to_bits());
            assert_eq!((-a).lane(i).to_bits(), (-x).to_bits());
            assert_eq!(a.sqrt().lane(i).to_bits(), x.sqrt().to_bits());
        }
        let m = b.nonzero();
        assert_eq!(m, [u64::MAX, u64::MAX, u64::MAX, 0]);
        let acc = F64x4::splat(-0.0);
        assert_eq!(
            F64x4::add_where(m, acc, a).0[3].to_bits(),
            (-0.0f64).to_bits()
        );
        assert!(F64x4::any(m) && !F64x4::all(m));
        assert!(!F64x4::all((a / b).finite()));
    }

    /// The helpers give nalgebra's results bitwise (the kernel's results must not move).
    #[test]
    fn products_are_nalgebras_bitwise() {
        let m = Matrix3::new(0.3, -1.7, 2.2, 1e-3, 4.5, -0.6, 7.1, 0.25, -3.3);
        let n = Matrix3::new(1.1, 0.4, -2.9, 3.3, -0.05, 0.8, -1.2, 6.0, 0.7);
        let (x, y) = (Vector3::new(0.7, -1.9, 1e-2), Vector3::new(-2.5, 0.33, 4.1));
        assert_eq!(cross(&x, &y), x.cross(&y));
        assert_eq!(dot(&x, &y).to_bits(), x.dot(&y).to_bits());
        assert_eq!(mat_vec(&m, &x), m * x);
        assert_eq!(tr_mat_vec(&m, &x), m.tr_mul(&x));
        assert_eq!(mat_mul(&m, &n), m * n);
    }
}
