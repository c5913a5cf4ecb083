//! The rod ODE right-hand side (MODEL.md §2, eqs. 3–8) and its tangent (variational
//! equation), sharing one factorization of the 6×6 strain system.
//!
//! Body-frame strains v, u are state variables. With tendon k at offset r_k, tension τ_k,
//! path tangent w_k = v + u × r_k, ℓ_k = |w_k|, t_k = w_k / ℓ_k, the tendon matrix of eq. (5)
//! is A_k = −τ_k ŵ_k² / ℓ_k³ = c_k (I − t_k t_kᵀ) with c_k = τ_k / ℓ_k, and the strain
//! system reads, with P_k = \[I, −r̂_k\] (so P_kᵀ = \[I; r̂_k\]):
//!
//! g(state, x) = K x + Σ_k P_kᵀ A_k y_k + [u × n_b + Rᵀ f; u × m_b + v × n_b] = 0,
//!
//! x = \[v'; u'\], y_k = P_k x + u × w_k, n_b = K_se (v − e_z), m_b = K_bt u. Its matrix
//! M = K + Σ_k P_kᵀ A_k P_k is symmetric positive definite for τ ≥ 0.
//!
//! **Tangent.** Differentiating g at fixed x gives M dx = −b with
//! b = \[e; 0\] + H_v dv + H_u du + Σ_k P_kᵀ (q_k / ℓ_k) dτ_k, e = dRᵀ f, where
//! (with q_k = y_k − t_k (t_k · y_k))
//! - d(A_k y_k) = (dτ_k/ℓ_k) q_k − T_k dw_k, T_k = (c_k/ℓ_k)(q_k t_kᵀ + t_k q_kᵀ + (t_k·y_k)(I − t_k t_kᵀ)),
//! - d(A_k (u × w_k)) = A_k (û dw_k − ŵ_k du), dw_k = dv − r̂_k du,
//! - so tendon k adds P_kᵀ N_k to H_v and P_kᵀ (−N_k r̂_k − A_k ŵ_k) to H_u, N_k = A_k û − T_k;
//! - the backbone adds \[û K_se; −n̂_b + v̂ K_se\] to H_v and \[−n̂_b; −m̂_b + û K_bt\] to H_u.
//!
//! H_v, H_u (6×3 each) are built once per evaluation ([`Stage::linearize`]); every
//! sensitivity direction then costs two small matrix–vector products and one solve with
//! the stored factorization, done for all directions at once in structure-of-arrays lanes
//! ([`Stage::tangents`]).
//!
//! The primal part ([`Stage::eval`], [`Stage::linearize`]) is generic over the kernel's
//! scalar ([`Real`]): one leg (`f64`) or one leg per SIMD lane ([`F64x4`](super::lanes::F64x4));
//! the tangents of each leg then run in their own direction lanes, reading the leg's lane.

use nalgebra::{Matrix3, Vector3};

use crate::design::MAX_TENDONS;
use crate::error::SolveError;
use crate::rod::lanes::{Real, all_finite, cross, dot, fma, mat_vec, tr_mat_vec};
use crate::rod::ldlt6::Ldlt6;
use crate::rod::leg_model::LegModel;
use crate::rod::slots::TendonSlots;
/// Rows of the tangents that feed back into the right-hand side (here before 2026-11-28).
pub use crate::rod::tangents::FEEDBACK_ROWS;
use crate::rod::tangents::{K_P, K_S, K_U, K_V, MAX_DIRECTIONS, Tangents};

/// Most legs one [`Stage`] holds (the lanes of [`F64x4`](super::lanes::F64x4)).
pub const MAX_LEGS: usize = 4;

/// The rod state (or its derivative): position p \[m\], rotation R, strains v, u
/// \[–, 1/m\] and tendon path lengths s_k \[m\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RodState<T: Real = f64> {
    /// Backbone position p (world frame).
    pub p: Vector3<T>,
    /// Backbone orientation R (body to world).
    pub r: Matrix3<T>,
    /// Shear/extension strain v (body frame).
    pub v: Vector3<T>,
    /// Bending/torsion strain u (body frame).
    pub u: Vector3<T>,
    /// Tendon path lengths s_k (entries beyond n_t unused).
    pub s: [T; MAX_TENDONS],
}

/// `acc[i] += k[i] · a` for every entry, written out so that it is inlined into the
/// AVX2 copy of the kernel: nalgebra's `+=` on matrices of lanes was compiled as a call
/// out of it (generic x86-64 code, with `vzeroupper` around it), 1–5 % of a leg
/// integration (perf, 2026-11-26).
#[inline(always)]
fn add_product<T: Real>(acc: &mut [T], k: &[T], a: T) {
    for (x, y) in acc.iter_mut().zip(k) {
        *x += *y * a;
    }
}

impl<T: Real> RodState<T> {
    /// All zeros.
    #[inline(always)]
    pub fn zeros() -> Self {
        Self {
            p: Vector3::zeros(),
            r: Matrix3::zeros(),
            v: Vector3::zeros(),
            u: Vector3::zeros(),
            s: [T::zero(); MAX_TENDONS],
        }
    }

    /// self = y + Σ_j c_j k_j over R, v, u, the parts that feed back into the right-hand
    /// side (a stage input: p and s are not needed), the terms in order, a product then a
    /// sum each (no fused multiply–add). At most `MAX_STAGES` − 1 terms, dispatched on
    /// their number to an unrolled loop (as
    /// [`Tangents::set_combination`](super::tangents::Tangents::set_combination)).
    #[inline(always)]
    pub fn set_stage_input(&mut self, y: &Self, terms: &[(f64, &Self)]) {
        match terms.len() {
            0 => (self.r, self.v, self.u) = (y.r, y.v, y.u),
            1 => self.set_stage_input_terms::<1>(y, terms),
            2 => self.set_stage_input_terms::<2>(y, terms),
            3 => self.set_stage_input_terms::<3>(y, terms),
            4 => self.set_stage_input_terms::<4>(y, terms),
            5 => self.set_stage_input_terms::<5>(y, terms),
            n => unreachable!("{n} stage-input terms: more than a tableau has"),
        }
    }

    /// [`RodState::set_stage_input`] of exactly `C` terms.
    #[inline(always)]
    fn set_stage_input_terms<const C: usize>(&mut self, y: &Self, terms: &[(f64, &Self)]) {
        let terms: &[(f64, &Self); C] = terms.try_into().expect("C terms");
        // One component at a time: R, v and u together would not fit in the registers.
        macro_rules! combine {
            ($field:ident) => {{
                let mut acc = y.$field;
                for &(c, k) in terms {
                    add_product(acc.as_mut_slice(), k.$field.as_slice(), T::splat(c));
                }
                self.$field = acc;
            }};
        }
        combine!(r);
        combine!(v);
        combine!(u);
    }

    /// self = y + a·k, over the first `nt` tendon lengths (the rest copied from y): as
    /// `*self = *y` followed by [`RodState::axpy`], without the copy.
    #[inline(always)]
    pub fn set_sum(&mut self, y: &Self, a: T, k: &Self, nt: usize) {
        (self.p, self.r, self.v, self.u) = (y.p, y.r, y.v, y.u);
        add_product(self.p.as_mut_slice(), k.p.as_slice(), a);
        add_product(self.r.as_mut_slice(), k.r.as_slice(), a);
        add_product(self.v.as_mut_slice(), k.v.as_slice(), a);
        add_product(self.u.as_mut_slice(), k.u.as_slice(), a);
        for i in 0..MAX_TENDONS {
            self.s[i] = if i < nt { y.s[i] + a * k.s[i] } else { y.s[i] };
        }
    }

    /// self += a·k, over the first `nt` tendon lengths.
    #[inline(always)]
    pub fn axpy(&mut self, a: T, k: &Self, nt: usize) {
        add_product(self.p.as_mut_slice(), k.p.as_slice(), a);
        add_product(self.r.as_mut_slice(), k.r.as_slice(), a);
        add_product(self.v.as_mut_slice(), k.v.as_slice(), a);
        add_product(self.u.as_mut_slice(), k.u.as_slice(), a);
        for i in 0..nt {
            self.s[i] += a * k.s[i];
        }
    }
}

/// Skew-symmetric matrix x̂ with x̂ y = x × y.
#[inline]
pub fn hat(x: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -x.z, x.y, x.z, 0.0, -x.x, -x.y, x.x, 0.0)
}

/// M x̂ for any 3×3 M, by columns: (M x̂) e_j = M (x × e_j).
#[inline(always)]
pub fn times_hat<T: Real>(m: &Matrix3<T>, x: &Vector3<T>) -> Matrix3<T> {
    let (c0, c1, c2) = (m.column(0), m.column(1), m.column(2));
    Matrix3::from_columns(&[
        c1 * x.z - c2 * x.y,
        c2 * x.x - c0 * x.z,
        c0 * x.y - c1 * x.x,
    ])
}

/// Per-tendon quantities of one evaluation, kept for the linearization.
#[derive(Debug, Clone, Copy)]
struct TendonPoint<T: Real> {
    /// Path tangent w = v + u × r (body frame).
    w: Vector3<T>,
    /// 1/ℓ, ℓ = |w|.
    inv_len: T,
    /// t = w / ℓ.
    t: Vector3<T>,
    /// r × t: d ℓ = t · dv + (r × t) · du.
    rt: Vector3<T>,
    /// c = τ / ℓ \[N\].
    c: T,
}

/// One evaluation of the right-hand side: the point, its factorization and, after
/// [`Stage::linearize`], the linear map every tangent direction goes through.
#[derive(Debug, Clone)]
pub struct Stage<T: Real = f64> {
    r: Matrix3<T>,
    v: Vector3<T>,
    u: Vector3<T>,
    /// K_se (v − e_z): body-frame internal force \[N\].
    n_body: Vector3<T>,
    /// K_bt u: body-frame internal moment \[N·m\].
    m_body: Vector3<T>,
    /// The solution x = \[v'; u'\].
    dv: Vector3<T>,
    du: Vector3<T>,
    factor: Ldlt6<T>,
    tendons: [TendonPoint<T>; MAX_TENDONS],
    active: u32,
    /// Rows of \[H_v H_u\] (6×6).
    h: [[T; 6]; 6],
    /// Per leg and row, the tension directions' source P_kᵀ q_k / ℓ_k in lane 6 + k
    /// (zero elsewhere), contiguous over directions for the tangent products.
    inject: [[[f64; MAX_DIRECTIONS]; 6]; MAX_LEGS],
}

impl<T: Real> Stage<T> {
    /// A stage with placeholder values (overwritten by the first [`Stage::eval`]).
    pub fn new() -> Self {
        let tp = TendonPoint {
            w: Vector3::zeros(),
            inv_len: T::one(),
            t: Vector3::zeros(),
            rt: Vector3::zeros(),
            c: T::zero(),
        };
        Self {
            r: Matrix3::identity(),
            v: Vector3::zeros(),
            u: Vector3::zeros(),
            n_body: Vector3::zeros(),
            m_body: Vector3::zeros(),
            dv: Vector3::zeros(),
            du: Vector3::zeros(),
            factor: Ldlt6::identity(),
            tendons: [tp; MAX_TENDONS],
            active: 0,
            h: [[T::zero(); 6]; 6],
            inject: [[[0.0; MAX_DIRECTIONS]; 6]; MAX_LEGS],
        }
    }

    /// Evaluates y' = f(y) for the tendon slots in the bit set `active` (tendon data and
    /// tensions in `tendons`),
    /// writing the derivative of p, R, v, u and s to `out` and keeping what
    /// [`Stage::linearize`] needs if `keep` (a primal-only integration passes `false` and
    /// skips those stores: 12 % fewer instructions per primal leg integration, issue 12;
    /// the strain system's factorization is stored either way, [`Ldlt6::refactor`]).
    ///
    /// # Errors
    /// [`SolveError::NonFinite`] if the state is not finite or the strain system is not
    /// positive definite (which only a non-finite or absurd state can cause), in any lane.
    #[inline(always)]
    pub fn eval(
        &mut self,
        model: &LegModel,
        y: &RodState<T>,
        tendons: &TendonSlots<T>,
        active: u32,
        out: &mut RodState<T>,
        keep: bool,
    ) -> Result<(), SolveError> {
        let (v, u) = (y.v, y.u);
        // The running tendons' path lengths ℓ = |w| first, and their reciprocals below,
        // for all of them before any of their other terms: the square roots and the
        // divisions are long-latency operations independent of one another, which then
        // overlap with each other and with the backbone's terms (each tendon's ℓ, 1/ℓ and
        // then its terms in turn left the tendon's work waiting for them). The same
        // operations, bitwise the same results; 9-DoF residual 9.99 → 8.97 µs, its warm
        // least-norm 1 mm step 101.4–104.4 → 94.2–95.8 µs (criterion, alternating, AMD
        // EPYC; 3 % more instructions: w and ℓ go through memory), 6-DoF unchanged
        // (two tendons a leg).
        let running = |k: usize| active & (1 << k) != 0;
        for k in (0..model.n_tendons).filter(|&k| running(k)) {
            let w = v + cross(&u, &tendons.offsets[k]);
            self.tendons[k].w = w;
            out.s[k] = dot(&w, &w).sqrt();
        }
        let (k_se, k_bt) = (model.k_se.map(T::splat), model.k_bt.map(T::splat));
        let n_body = k_se.component_mul(&(v - Vector3::z()));
        let m_body = k_bt.component_mul(&u);
        // M = K + Σ_k P_kᵀ A_k P_k in 3×3 blocks [A Bᵀ; B C]: A_k, r̂A_k, r̂ A_k r̂ᵀ.
        // A and C are symmetric: only their upper triangles are formed.
        let mut blk_a = Matrix3::from_diagonal(&k_se);
        let mut blk_b = Matrix3::zeros();
        let mut blk_c = Matrix3::from_diagonal(&k_bt);
        let mut rhs_v =
            -cross(&u, &n_body) - tr_mat_vec(&y.r, &model.weight_per_length.map(T::splat));
        let mut rhs_u = -cross(&u, &m_body) - cross(&v, &n_body);
        // One division, then products: t = w/ℓ and c = τ/ℓ by four divisions took a
        // quarter of the residual's time (the divider's throughput, measured).
        for k in (0..model.n_tendons).filter(|&k| running(k)) {
            self.tendons[k].inv_len = T::one() / out.s[k];
        }
        for k in 0..model.n_tendons {
            if !running(k) {
                out.s[k] = T::zero();
                continue;
            }
            let r_k = tendons.offsets[k];
            let (w, inv_len) = (self.tendons[k].w, self.tendons[k].inv_len);
            let t = w * inv_len;
            let c = tendons.tensions[k] * inv_len;
            // A = c (I − t tᵀ); r̂A = c (r̂ − (r × t) tᵀ); r̂ A r̂ᵀ = c (r̂r̂ᵀ − (r × t)(r × t)ᵀ).
            let rt = cross(&r_k, &t);
            // A slack tendon (c = 0) adds nothing: its lanes are left as they are.
            let taut = c.nonzero();
            if T::any(taut) {
                let (hat_r, hat_sq) = (&tendons.hats[k], &tendons.hat_squares[k]);
                // Where every lane is taut (the legs' lanes agree, as at the bench's
                // configurations) the plain sums are the masked ones bit for bit, without
                // the masks' selects. A macro: the block is needed once per adder (two
                // closure types), each compiled with its adder inlined.
                macro_rules! tendon_terms {
                    ($add:expr) => {{
                        let add = $add;
                        for i in 0..3 {
                            for j in i..3 {
                                let id = T::splat(if i == j { 1.0 } else { 0.0 });
                                add(&mut blk_a[(i, j)], c * (id - t[i] * t[j]));
                                add(&mut blk_c[(i, j)], c * (hat_sq[(i, j)] - rt[i] * rt[j]));
                            }
                            for j in 0..3 {
                                add(&mut blk_b[(i, j)], c * (hat_r[(i, j)] - rt[i] * t[j]));
                            }
                        }
                        let z = cross(&u, &w);
                        let a_z = (z - t * dot(&t, &z)) * c;
                        let moment = cross(&r_k, &a_z);
                        for i in 0..3 {
                            add(&mut rhs_v[i], -a_z[i]);
                            add(&mut rhs_u[i], -moment[i]);
                        }
                    }};
                }
                if T::all(taut) {
                    tendon_terms!(|acc: &mut T, x: T| *acc += x)
                } else {
                    tendon_terms!(|acc: &mut T, x: T| *acc = T::add_where(taut, *acc, x))
                }
            }
            let point = &mut self.tendons[k];
            (point.t, point.rt, point.c) = (t, rt, c);
        }
        // The error value is built only on failure: an `ok_or` argument was built and
        // dropped at every stage (19 instructions, 1 % of a residual).
        if !self.factor.refactor(&blk_a, &blk_b, &blk_c) {
            return Err(SolveError::NonFinite {
                stage: "rod strain system (eq. 5)",
            });
        }
        let (dv, du) = self.factor.solve_blocks(&rhs_v, &rhs_u);
        if !all_finite([dv.x, dv.y, dv.z, du.x, du.y, du.z]) {
            return Err(SolveError::NonFinite {
                stage: "rod strain derivatives (eq. 5)",
            });
        }
        out.p = mat_vec(&y.r, &v);
        out.r = times_hat(&y.r, &u);
        out.v = dv;
        out.u = du;
        if keep {
            // Column by column: the whole 288-byte matrix was copied by a call to
            // `memcpy` (about 1 % of an exact Jacobian's instructions, callgrind).
            for c in 0..3 {
                self.r.set_column(c, &y.r.column(c));
            }
            self.v = v;
            self.u = u;
            self.n_body = n_body;
            self.m_body = m_body;
            self.dv = dv;
            self.du = du;
            self.active = active;
        }
        Ok(())
    }

    /// Clears the tension sources of the first `directions` lanes of the first `legs`
    /// legs (before an integration whose tension lanes may differ from the last one's;
    /// the kernel reads no other).
    pub fn clear_tension_sources(&mut self, legs: usize, directions: usize) {
        for inject in &mut self.inject[..legs] {
            for row in inject.iter_mut() {
                row[..directions].fill(0.0);
            }
        }
    }

    /// Builds H_v, H_u and the tension sources (module doc) at the last [`Stage::eval`],
    /// for the first `directions` sensitivity directions; `tension_lanes[leg][slot]` is
    /// the direction lane of the tension of the tendon in `slot` (≥ `directions` if not
    /// integrated).
    #[inline(always)]
    pub fn linearize(
        &mut self,
        model: &LegModel,
        tendons: &TendonSlots<T>,
        tension_lanes: &[[usize; MAX_TENDONS]; MAX_LEGS],
        directions: usize,
    ) {
        let (u, v, nb, mb) = (&self.u, &self.v, &self.n_body, &self.m_body);
        let (kse, kbt) = (model.k_se.map(T::splat), model.k_bt.map(T::splat));
        let zero = T::zero();
        // Backbone terms, [û K_se, −n̂_b; v̂ K_se − n̂_b, û K_bt − m̂_b], x̂ K = columns of x̂
        // scaled by the diagonal K.
        let h = &mut self.h;
        *h = [
            [zero, -u.z * kse.y, u.y * kse.z, zero, nb.z, -nb.y],
            [u.z * kse.x, zero, -u.x * kse.z, -nb.z, zero, nb.x],
            [-u.y * kse.x, u.x * kse.y, zero, nb.y, -nb.x, zero],
            [
                zero,
                -v.z * kse.y + nb.z,
                v.y * kse.z - nb.y,
                zero,
                -u.z * kbt.y + mb.z,
                u.y * kbt.z - mb.y,
            ],
            [
                v.z * kse.x - nb.z,
                zero,
                -v.x * kse.z + nb.x,
                u.z * kbt.x - mb.z,
                zero,
                -u.x * kbt.z + mb.x,
            ],
            [
                -v.y * kse.x + nb.y,
                v.x * kse.y - nb.x,
                zero,
                -u.y * kbt.x + mb.y,
                u.x * kbt.y - mb.x,
                zero,
            ],
        ];
        // Tendons that are not running here inject nothing in their tension lane.
        for k in 0..model.n_tendons {
            if self.active & (1 << k) == 0 {
                for (leg, inject) in self.inject[..T::LANES].iter_mut().enumerate() {
                    let lane = tension_lanes[leg][k];
                    if lane < directions {
                        for row in inject.iter_mut() {
                            row[lane] = 0.0;
                        }
                    }
                }
            }
        }
        for k in 0..model.n_tendons {
            if self.active & (1 << k) == 0 {
                continue;
            }
            let tp = &self.tendons[k];
            let r = tendons.offsets[k];
            let y = self.dv + cross(&self.du, &r) + cross(u, &tp.w);
            let (t, c, inv_len) = (&tp.t, tp.c, tp.inv_len);
            let ty = dot(t, &y);
            let q = y - t * ty;
            if directions > 6 {
                let src = q * inv_len;
                let moment = cross(&r, &src);
                for (leg, inject) in self.inject[..T::LANES].iter_mut().enumerate() {
                    let lane = tension_lanes[leg][k];
                    if lane < directions {
                        for i in 0..3 {
                            inject[i][lane] = src[i].lane(leg);
                            inject[3 + i][lane] = moment[i].lane(leg);
                        }
                    }
                }
            }
            // A slack tendon (c = 0) adds nothing to H: its lanes are left as they are.
            let taut = c.nonzero();
            if !T::any(taut) {
                continue;
            }
            // N = A û − T with A û = c (û + t (u × t)ᵀ) and
            // T = (c/ℓ)(q tᵀ + t qᵀ + (t·y)(I − t tᵀ)); Ñ = −N r̂ − A ŵ, A ŵ = c ŵ (t ∥ w).
            let ut = cross(u, t);
            let (ct, w) = (c * inv_len, &tp.w);
            let u_hat = [[zero, -u.z, u.y], [u.z, zero, -u.x], [-u.y, u.x, zero]];
            let mut n = [[zero; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    let id = T::splat(if i == j { 1.0 } else { 0.0 });
                    let a_u = c * (u_hat[i][j] + t[i] * ut[j]);
                    let tm = ct * (q[i] * t[j] + t[i] * q[j] + ty * (id - t[i] * t[j]));
                    n[i][j] = a_u - tm;
                }
            }
            let w_hat = [[zero, -w.z, w.y], [w.z, zero, -w.x], [-w.y, w.x, zero]];
            // Ñ = −N r̂ − c ŵ, N r̂ by columns: (N r̂) e_j = N (r × e_j).
            let mut nt = [[zero; 3]; 3];
            for i in 0..3 {
                let row = &n[i];
                let nr = [
                    row[1] * r.z - row[2] * r.y,
                    row[2] * r.x - row[0] * r.z,
                    row[0] * r.y - row[1] * r.x,
                ];
                for j in 0..3 {
                    nt[i][j] = -nr[j] - c * w_hat[i][j];
                }
            }
            // [I; r̂] applied to N (H_v columns) and Ñ (H_u columns): r̂ M by rows.
            // As in `eval`: plain sums where every lane is taut.
            macro_rules! h_terms {
                ($add:expr) => {{
                    let add = $add;
                    for (m, col) in [(&n, 0), (&nt, 3)] {
                        for j in 0..3 {
                            let (m0, m1, m2) = (m[0][j], m[1][j], m[2][j]);
                            add(&mut h[0][col + j], m0);
                            add(&mut h[1][col + j], m1);
                            add(&mut h[2][col + j], m2);
                            add(&mut h[3][col + j], r.y * m2 - r.z * m1);
                            add(&mut h[4][col + j], r.z * m0 - r.x * m2);
                            add(&mut h[5][col + j], r.x * m1 - r.y * m0);
                        }
                    }
                }};
            }
            if T::all(taut) {
                h_terms!(|acc: &mut T, x: T| *acc += x)
            } else {
                h_terms!(|acc: &mut T, x: T| *acc = T::add_where(taut, *acc, x))
            }
        }
    }

    /// Propagates the tangents of leg (lane) `leg` through this stage at the last
    /// [`Stage::linearize`]: writes the derivative k of the first `N` lanes of `d` (only
    /// its R, v, u rows are read) into `k`'s rows `0..K_S + n_t` (every component).
    #[inline(always)]
    pub fn tangents<const N: usize>(
        &self,
        leg: usize,
        model: &LegModel,
        tendons: &TendonSlots<T>,
        d: &Tangents,
        k: &mut Tangents,
    ) {
        // The leg's lanes are read in place (`*x.lane_ref(leg)`), one named scalar each:
        // copied out first (`map` over a row), each went through the stack before its
        // broadcast (callgrind: about 40 k of a 6-DoF exact Jacobian's 431 k
        // instructions); H's row as an array `map` over its indices took 505 k.
        let at = |x: &T| *x.lane_ref(leg);
        let lane = |x: &Vector3<T>| Vector3::new(at(&x.x), at(&x.y), at(&x.z));
        let f = &model.weight_per_length;
        // The input rows as copies (through references, or read element by element at
        // their use, the products were compiled as scalar code); R's rows copied where
        // they are used, not all nine up front (those went through the stack); the outputs
        // that need no strain solve first, so that b's twelve vectors are not live across
        // them. Figures in BENCHMARKS.md "The tangent kernel's live values; plain sums
        // where every lane is taut".
        let row = |i| *d.row::<N>(i);
        let dv = [row(K_V), row(K_V + 1), row(K_V + 2)];
        let du = [row(K_U), row(K_U + 1), row(K_U + 2)];
        for slot in 0..model.n_tendons {
            let mut ds = [0.0; N];
            if self.active & (1 << slot) != 0 {
                let (t, rt) = (lane(&self.tendons[slot].t), lane(&self.tendons[slot].rt));
                for j in 0..N {
                    let acc = fma(t.y, dv[1][j], t.x * dv[0][j]);
                    let acc = fma(t.z, dv[2][j], acc);
                    let acc = fma(rt.x, du[0][j], acc);
                    let acc = fma(rt.y, du[1][j], acc);
                    ds[j] = fma(rt.z, du[2][j], acc);
                }
            }
            *k.row_mut::<N>(K_S + tendons.tendon[leg][slot]) = ds;
        }
        let (v, u) = (lane(&self.v), lane(&self.u));
        let rot = &self.r;
        for i in 0..3 {
            let (r0, r1, r2) = (at(&rot[(i, 0)]), at(&rot[(i, 1)]), at(&rot[(i, 2)]));
            let (mut dp, mut c0, mut c1, mut c2) = ([0.0; N], [0.0; N], [0.0; N], [0.0; N]);
            let dr = [row(i), row(3 + i), row(6 + i)];
            for j in 0..N {
                let (a0, a1, a2) = (dr[0][j], dr[1][j], dr[2][j]);
                let (w0, w1, w2) = (du[0][j], du[1][j], du[2][j]);
                // dp' = dR v + R dv
                let acc = fma(a1, v.y, a0 * v.x);
                let acc = fma(a2, v.z, acc);
                let acc = fma(r0, dv[0][j], acc);
                let acc = fma(r1, dv[1][j], acc);
                dp[j] = fma(r2, dv[2][j], acc);
                // dR' = dR û + R dû, column by column: M x̂ e_j = M (x × e_j).
                c0[j] = fma(a1, u.z, fma(-a2, u.y, fma(r1, w2, -r2 * w1)));
                c1[j] = fma(a2, u.x, fma(-a0, u.z, fma(r2, w0, -r0 * w2)));
                c2[j] = fma(a0, u.y, fma(-a1, u.x, fma(r0, w1, -r1 * w0)));
            }
            *k.row_mut::<N>(K_P + i) = dp;
            *k.row_mut::<N>(i) = c0;
            *k.row_mut::<N>(3 + i) = c1;
            *k.row_mut::<N>(6 + i) = c2;
        }
        // b = H [dv; du] + the tension sources, column by column: each row's products are
        // summed in column order either way, but by rows the compiler spilled the twelve
        // accumulators after their first product.
        let mut b = [[0.0; N]; 6];
        for (i, b_row) in b.iter_mut().enumerate() {
            *b_row = self.inject[leg][i][..N].try_into().expect("N lanes");
        }
        for (col, x) in [&dv[0], &dv[1], &dv[2], &du[0], &du[1], &du[2]]
            .into_iter()
            .enumerate()
        {
            for (i, b_row) in b.iter_mut().enumerate() {
                let h = at(&self.h[i][col]);
                for j in 0..N {
                    b_row[j] = fma(h, x[j], b_row[j]);
                }
            }
        }
        // e = dRᵀ f (R stored column-major: entry (row, col) at 3 col + row).
        for c in 0..3 {
            let dr = [row(3 * c), row(3 * c + 1), row(3 * c + 2)];
            for j in 0..N {
                let acc = fma(dr[0][j], f.x, b[c][j]);
                let acc = fma(dr[1][j], f.y, acc);
                b[c][j] = fma(dr[2][j], f.z, acc);
            }
        }
        self.factor.solve_lanes(leg, &mut b);
        for c in 0..3 {
            for j in 0..N {
                b[c][j] = -b[c][j];
                b[3 + c][j] = -b[3 + c][j];
            }
            *k.row_mut::<N>(K_V + c) = b[c];
            *k.row_mut::<N>(K_U + c) = b[3 + c];
        }
    }
}

impl<T: Real> Default for Stage<T> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_hat_is_the_product_with_the_skew_matrix() {
        let m = Matrix3::new(1.0, 2.0, -3.0, 0.5, -1.0, 4.0, 2.0, 0.0, 1.5);
        let x = Vector3::new(0.3, -1.2, 2.0);
        assert!((times_hat(&m, &x) - m * hat(&x)).norm() < 1e-14);
    }
}
