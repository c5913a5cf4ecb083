//! The rod ODE right-hand side (MODEL.md §2, eqs. 3–8) and its tangent (variational
//! equation), sharing one Cholesky factorization of the 6×6 strain system.
//!
//! Body-frame strains v, u are state variables. With tendon k at offset r_k, tension τ_k,
//! path tangent w_k = v + u × r_k, ℓ_k = |w_k|, t_k = w_k / ℓ_k, the tendon matrix of eq. (5)
//! is A_k = −τ_k ŵ_k² / ℓ_k³ = c_k (I − t_k t_kᵀ) with c_k = τ_k / ℓ_k, and the strain
//! system reads, with P_k = \[I, −r̂_k\]:
//!
//! (K + Σ_k P_kᵀ A_k P_k) \[v'; u'\] = [−u × K_se(v − e_z) − Rᵀ f − Σ a_k;
//!                                    −u × K_bt u − v × K_se(v − e_z) − Σ r_k × a_k],
//!
//! a_k = A_k (u × w_k). The matrix is symmetric positive definite for τ ≥ 0, so it is
//! factored by Cholesky. Writing the system as g(state, x) = 0 with x = \[v'; u'\], the
//! tangent is dx = −M⁻¹ ∂g/∂state · dstate, where every tendon enters through
//! F_k = A_k y_k, y_k = v' + u' × r_k + u × w_k.

use nalgebra::{Matrix3, Vector3};

use crate::design::MAX_TENDONS;
use crate::error::SolveError;
use crate::rod::ldlt6::Ldlt6;
use crate::rod::model::LegModel;
use crate::rod::tangents::{MAX_DIRECTIONS, Tangents};

/// The rod state (or its derivative, or a tangent): position p \[m\], rotation R, strains
/// v, u \[–, 1/m\] and tendon path lengths s_k \[m\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RodState {
    /// Backbone position p (world frame).
    pub p: Vector3<f64>,
    /// Backbone orientation R (body to world).
    pub r: Matrix3<f64>,
    /// Shear/extension strain v (body frame).
    pub v: Vector3<f64>,
    /// Bending/torsion strain u (body frame).
    pub u: Vector3<f64>,
    /// Tendon path lengths s_k (entries beyond n_t unused).
    pub s: [f64; MAX_TENDONS],
}

impl RodState {
    /// All zeros.
    pub fn zeros() -> Self {
        Self {
            p: Vector3::zeros(),
            r: Matrix3::zeros(),
            v: Vector3::zeros(),
            u: Vector3::zeros(),
            s: [0.0; MAX_TENDONS],
        }
    }

    /// self = y + a·k, over the first `nt` tendon lengths.
    #[inline]
    pub fn set_axpy(&mut self, y: &Self, a: f64, k: &Self, nt: usize) {
        self.p = y.p + k.p * a;
        self.r = y.r + k.r * a;
        self.v = y.v + k.v * a;
        self.u = y.u + k.u * a;
        for i in 0..nt {
            self.s[i] = y.s[i] + a * k.s[i];
        }
    }

    /// self += a·k, over the first `nt` tendon lengths.
    #[inline]
    pub fn axpy(&mut self, a: f64, k: &Self, nt: usize) {
        self.p += k.p * a;
        self.r += k.r * a;
        self.v += k.v * a;
        self.u += k.u * a;
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
#[inline]
pub fn times_hat(m: &Matrix3<f64>, x: &Vector3<f64>) -> Matrix3<f64> {
    let (c0, c1, c2) = (m.column(0), m.column(1), m.column(2));
    Matrix3::from_columns(&[
        c1 * x.z - c2 * x.y,
        c2 * x.x - c0 * x.z,
        c0 * x.y - c1 * x.x,
    ])
}

/// Per-tendon quantities of one evaluation, kept for the tangent.
#[derive(Debug, Clone, Copy)]
struct TendonPoint {
    w: Vector3<f64>,
    len: f64,
    t: Vector3<f64>,
    /// c = τ / ℓ \[N/m\].
    c: f64,
    /// y = v' + u' × r + u × w.
    y: Vector3<f64>,
    /// t · y.
    ty: f64,
    /// y − t (t · y), so that A y = c q.
    q: Vector3<f64>,
}

/// One evaluation of the right-hand side: the point, its factorization and what the
/// tangent reuses.
#[derive(Debug, Clone)]
pub struct Stage {
    r: Matrix3<f64>,
    v: Vector3<f64>,
    u: Vector3<f64>,
    /// K_se (v − e_z): body-frame internal force \[N\].
    n_body: Vector3<f64>,
    /// K_bt u: body-frame internal moment \[N·m\].
    m_body: Vector3<f64>,
    factor: Ldlt6,
    tendons: [TendonPoint; MAX_TENDONS],
    active: u32,
}

impl Stage {
    /// A stage with placeholder values (overwritten by the first [`Stage::eval`]).
    pub fn new() -> Self {
        let tp = TendonPoint {
            w: Vector3::zeros(),
            len: 1.0,
            t: Vector3::zeros(),
            c: 0.0,
            y: Vector3::zeros(),
            ty: 0.0,
            q: Vector3::zeros(),
        };
        Self {
            r: Matrix3::identity(),
            v: Vector3::zeros(),
            u: Vector3::zeros(),
            n_body: Vector3::zeros(),
            m_body: Vector3::zeros(),
            factor: Ldlt6::identity(),
            tendons: [tp; MAX_TENDONS],
            active: 0,
        }
    }

    /// Evaluates y' = f(y) for the tendons in the bit set `active` with tensions `tau` \[N\],
    /// writing the derivative to `out` and keeping what [`Stage::tangents`] needs.
    ///
    /// # Errors
    /// [`SolveError::NonFinite`] if the state is not finite or the strain system is not
    /// positive definite (which only a non-finite or absurd state can cause).
    pub fn eval(
        &mut self,
        model: &LegModel,
        y: &RodState,
        tau: &[f64; MAX_TENDONS],
        active: u32,
        out: &mut RodState,
    ) -> Result<(), SolveError> {
        let (v, u) = (y.v, y.u);
        let n_body = model.k_se.component_mul(&(v - Vector3::z()));
        let m_body = model.k_bt.component_mul(&u);
        // M = K + Σ_k P_kᵀ A_k P_k in 3×3 blocks [A Bᵀ; B C]: A_k, r̂A_k, r̂ A_k r̂ᵀ.
        let mut blk_a = Matrix3::from_diagonal(&model.k_se);
        let mut blk_b = Matrix3::zeros();
        let mut blk_c = Matrix3::from_diagonal(&model.k_bt);
        let mut rhs_v = -u.cross(&n_body) - y.r.tr_mul(&model.weight_per_length);
        let mut rhs_u = -u.cross(&m_body) - v.cross(&n_body);
        for k in 0..model.n_tendons {
            if active & (1 << k) == 0 {
                continue;
            }
            let r_k = &model.tendon_offsets[k];
            let w = v + u.cross(r_k);
            let len = w.norm();
            let t = w / len;
            let c = tau[k] / len;
            // A = c (I − t tᵀ); r̂A = c (r̂ − s tᵀ); r̂ A r̂ᵀ = c (r̂r̂ᵀ − s sᵀ), s = r × t.
            let sv = r_k.cross(&t);
            blk_a += (Matrix3::identity() - t * t.transpose()) * c;
            blk_b += (model.tendon_hats[k] - sv * t.transpose()) * c;
            blk_c += (model.tendon_hat_squares[k] - sv * sv.transpose()) * c;
            let z = u.cross(&w);
            let a_z = (z - t * t.dot(&z)) * c;
            rhs_v -= a_z;
            rhs_u -= r_k.cross(&a_z);
            // y and q need x; store z in y for now.
            self.tendons[k] = TendonPoint {
                w,
                len,
                t,
                c,
                y: z,
                ty: 0.0,
                q: Vector3::zeros(),
            };
        }
        let factor = Ldlt6::factor_blocks(&blk_a, &blk_b, &blk_c).ok_or(SolveError::NonFinite {
            stage: "rod strain system (eq. 5)",
        })?;
        let (dv, du) = factor.solve_blocks(&rhs_v, &rhs_u);
        if !(dv.iter().chain(du.iter()).all(|e| e.is_finite())) {
            return Err(SolveError::NonFinite {
                stage: "rod strain derivatives (eq. 5)",
            });
        }
        for k in 0..model.n_tendons {
            if active & (1 << k) == 0 {
                out.s[k] = 0.0;
                continue;
            }
            let tp = &mut self.tendons[k];
            tp.y += dv + du.cross(&model.tendon_offsets[k]);
            tp.ty = tp.t.dot(&tp.y);
            tp.q = tp.y - tp.t * tp.ty;
            out.s[k] = tp.len;
        }
        out.p = y.r * v;
        out.r = times_hat(&y.r, &u);
        out.v = dv;
        out.u = du;
        self.r = y.r;
        self.v = v;
        self.u = u;
        self.n_body = n_body;
        self.m_body = m_body;
        self.factor = factor;
        self.active = active;
        Ok(())
    }

    /// The tangents of the last [`Stage::eval`] in all directions of `dy` at once:
    /// direction j ≥ 6 also carries dτ_(j−6) = 1 (the tension directions).
    pub fn tangents(&self, model: &LegModel, dy: &Tangents, out: &mut Tangents) {
        let n = dy.n;
        out.n = n;
        let (v, u, rot) = (&self.v, &self.u, &self.r);
        let f = &model.weight_per_length;
        let (k_se, k_bt) = (&model.k_se, &model.k_bt);
        let (nb, mb) = (&self.n_body, &self.m_body);
        let mut g = [[0.0; MAX_DIRECTIONS]; 6];
        for j in 0..n {
            let dv = Vector3::new(dy.v[0][j], dy.v[1][j], dy.v[2][j]);
            let du = Vector3::new(dy.u[0][j], dy.u[1][j], dy.u[2][j]);
            let dr = Matrix3::from_column_slice(&[
                dy.r[0][j], dy.r[1][j], dy.r[2][j], dy.r[3][j], dy.r[4][j], dy.r[5][j], dy.r[6][j],
                dy.r[7][j], dy.r[8][j],
            ]);
            let k_se_dv = k_se.component_mul(&dv);
            let k_bt_du = k_bt.component_mul(&du);
            let g_v = dr.tr_mul(f) + du.cross(nb) + u.cross(&k_se_dv);
            let g_u = du.cross(mb) + u.cross(&k_bt_du) + dv.cross(nb) + v.cross(&k_se_dv);
            for c in 0..3 {
                g[c][j] = g_v[c];
                g[3 + c][j] = g_u[c];
            }
            let dp = dr * v + rot * dv;
            let d_rot = times_hat(&dr, u) + times_hat(rot, &du);
            for c in 0..3 {
                out.p[c][j] = dp[c];
            }
            for c in 0..9 {
                out.r[c][j] = d_rot[c];
            }
        }
        for k in 0..model.n_tendons {
            if self.active & (1 << k) == 0 {
                out.s[k][..n].fill(0.0);
                continue;
            }
            let tp = &self.tendons[k];
            let r_k = &model.tendon_offsets[k];
            if tp.c == 0.0 {
                // A slack tendon loads the rod only through its own tension direction.
                for j in 0..n {
                    let dv = Vector3::new(dy.v[0][j], dy.v[1][j], dy.v[2][j]);
                    let du = Vector3::new(dy.u[0][j], dy.u[1][j], dy.u[2][j]);
                    out.s[k][j] = tp.t.dot(&(dv + du.cross(r_k)));
                }
                let own = 6 + k;
                if own < n {
                    let df = tp.q / tp.len;
                    let rdf = r_k.cross(&df);
                    for c in 0..3 {
                        g[c][own] += df[c];
                        g[3 + c][own] += rdf[c];
                    }
                }
                continue;
            }
            for j in 0..n {
                let dv = Vector3::new(dy.v[0][j], dy.v[1][j], dy.v[2][j]);
                let du = Vector3::new(dy.u[0][j], dy.u[1][j], dy.u[2][j]);
                let dw = dv + du.cross(r_k);
                let dlen = tp.t.dot(&dw);
                out.s[k][j] = dlen;
                let dt = (dw - tp.t * dlen) / tp.len;
                let dyk = du.cross(&tp.w) + u.cross(&dw);
                let dtau = if j == 6 + k { 1.0 } else { 0.0 };
                let dc = (dtau - tp.c * dlen) / tp.len;
                let df =
                    tp.q * dc + (dyk - dt * tp.ty - tp.t * (dt.dot(&tp.y) + tp.t.dot(&dyk))) * tp.c;
                let rdf = r_k.cross(&df);
                for c in 0..3 {
                    g[c][j] += df[c];
                    g[3 + c][j] += rdf[c];
                }
            }
        }
        for row in g.iter_mut() {
            for x in row[..n].iter_mut() {
                *x = -*x;
            }
        }
        self.factor.solve_lanes(&mut g, n);
        for c in 0..3 {
            out.v[c][..n].copy_from_slice(&g[c][..n]);
            out.u[c][..n].copy_from_slice(&g[3 + c][..n]);
        }
    }
}

impl Default for Stage {
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
