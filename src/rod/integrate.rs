//! Fixed-step RK4 integration of one leg from base to tip, optionally with forward
//! sensitivities propagated through the same discrete steps (MODEL.md §5), so they are
//! the exact derivatives of the discrete map.
//!
//! Sensitivity directions, in this order: u(0) (3), v(0) (3), then the tension τ_k of
//! each tendon (n_t). Tendon ends apply the force/moment jumps of MODEL.md §2; the tip
//! outputs n, m are taken after the jumps of the tendons ending at L, i.e. they are the
//! wrench the rod transmits beyond its tip (n(L) − Σ f_t,k, m(L) − Σ l_t,k).

use nalgebra::{Matrix3, Vector3};

use crate::design::MAX_TENDONS;
use crate::error::SolveError;
use crate::rod::model::{Frame, LegModel};
use crate::rod::rhs::{RodState, Stage};
pub use crate::rod::tangents::MAX_DIRECTIONS;
use crate::rod::tangents::Tangents;

/// The state at the tip of a leg (world frame, SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegEnd {
    /// Tip position p(L) \[m\].
    pub p: Vector3<f64>,
    /// Tip orientation R(L).
    pub r: Matrix3<f64>,
    /// Force transmitted beyond the tip, n(L) − Σ f_t,k \[N\].
    pub n: Vector3<f64>,
    /// Moment transmitted beyond the tip, m(L) − Σ l_t,k \[N·m\].
    pub m: Vector3<f64>,
    /// Path length of each tendon from the base to its end, s_k(end_k) \[m\].
    pub lengths: [f64; MAX_TENDONS],
}

impl LegEnd {
    /// All zeros.
    pub fn zeros() -> Self {
        Self {
            p: Vector3::zeros(),
            r: Matrix3::zeros(),
            n: Vector3::zeros(),
            m: Vector3::zeros(),
            lengths: [0.0; MAX_TENDONS],
        }
    }
}

/// Derivatives of [`LegEnd`] with respect to the sensitivity directions.
#[derive(Debug, Clone)]
pub struct LegSensitivities {
    directions: usize,
    /// `d[j]` = ∂(tip state)/∂(direction j).
    pub d: [LegEnd; MAX_DIRECTIONS],
}

impl LegSensitivities {
    /// Room for the first `directions` directions: 6 (strains only) up to 6 + n_t.
    ///
    /// # Panics
    /// If `directions` exceeds [`MAX_DIRECTIONS`] (a programming error).
    #[track_caller]
    pub fn new(directions: usize) -> Self {
        assert!(
            directions <= MAX_DIRECTIONS,
            "at most {MAX_DIRECTIONS} directions"
        );
        Self {
            directions,
            d: [LegEnd::zeros(); MAX_DIRECTIONS],
        }
    }

    /// Number of directions computed.
    pub fn directions(&self) -> usize {
        self.directions
    }
}

/// Backbone frames at the base and at every disk, for plots and collision checks.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LegShape {
    /// Arc lengths \[m\]: 0, then each disk.
    pub arcs: Vec<f64>,
    /// Backbone positions \[m\].
    pub positions: Vec<Vector3<f64>>,
    /// Backbone orientations.
    pub rotations: Vec<Matrix3<f64>>,
}

impl LegShape {
    /// Empty shape with room for `n_disks + 1` frames.
    pub fn with_capacity(n_disks: usize) -> Self {
        Self {
            arcs: Vec::with_capacity(n_disks + 1),
            positions: Vec::with_capacity(n_disks + 1),
            rotations: Vec::with_capacity(n_disks + 1),
        }
    }

    fn push(&mut self, s: f64, y: &RodState) {
        self.arcs.push(s);
        self.positions.push(y.p);
        self.rotations.push(y.r);
    }

    fn clear(&mut self) {
        self.arcs.clear();
        self.positions.clear();
        self.rotations.clear();
    }
}

/// Buffers for one leg integration; build once, reuse for every call.
#[derive(Debug, Clone)]
pub struct LegScratch {
    stage: Stage,
    y: RodState,
    y_stage: RodState,
    acc: RodState,
    k: RodState,
    dk: Box<Tangents>,
    dy: Box<Tangents>,
    dy_stage: Box<Tangents>,
    dacc: Box<Tangents>,
}

impl LegScratch {
    /// Allocates the buffers (the only allocation of an integration).
    pub fn new() -> Self {
        let z = RodState::zeros();
        Self {
            stage: Stage::new(),
            y: z,
            y_stage: z,
            acc: z,
            k: z,
            dk: Box::new(Tangents::zeros(0)),
            dy: Box::new(Tangents::zeros(0)),
            dy_stage: Box::new(Tangents::zeros(0)),
            dacc: Box::new(Tangents::zeros(0)),
        }
    }
}

impl Default for LegScratch {
    fn default() -> Self {
        Self::new()
    }
}

/// Initial conditions of one leg integration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegStart {
    /// Base frame (p(0), R(0)).
    pub base: Frame,
    /// Bending/torsion strain at the base u(0) \[1/m\].
    pub u0: Vector3<f64>,
    /// Shear/extension strain at the base v(0) \[–\].
    pub v0: Vector3<f64>,
    /// Tendon tensions τ_k \[N\] (≥ 0; entries beyond n_t ignored).
    pub tensions: [f64; MAX_TENDONS],
}

/// Integrates the leg from base to tip (no sensitivities); writes the tip to `end` and,
/// if given, the frames at the disks to `shape`.
///
/// # Errors
/// [`SolveError::NonFinite`] if the state blows up (absurd initial strains).
pub fn integrate_leg(
    model: &LegModel,
    start: &LegStart,
    scratch: &mut LegScratch,
    end: &mut LegEnd,
    shape: Option<&mut LegShape>,
) -> Result<(), SolveError> {
    integrate(model, start, scratch, end, None, shape)
}

/// As [`integrate_leg`], and also the exact derivatives of the tip state with respect
/// to the first `sens.directions()` directions (u(0), v(0), τ_1..τ_nt).
///
/// # Panics
/// If `sens.directions()` exceeds 6 + n_t (a programming error).
#[track_caller]
pub fn integrate_leg_with_sensitivities(
    model: &LegModel,
    start: &LegStart,
    scratch: &mut LegScratch,
    end: &mut LegEnd,
    sens: &mut LegSensitivities,
    shape: Option<&mut LegShape>,
) -> Result<(), SolveError> {
    assert!(
        sens.directions <= 6 + model.n_tendons,
        "{} sensitivity directions requested, the leg has {}",
        sens.directions,
        6 + model.n_tendons
    );
    integrate(model, start, scratch, end, Some(sens), shape)
}

fn integrate(
    model: &LegModel,
    start: &LegStart,
    sc: &mut LegScratch,
    end: &mut LegEnd,
    sens: Option<&mut LegSensitivities>,
    mut shape: Option<&mut LegShape>,
) -> Result<(), SolveError> {
    let nd = sens.as_ref().map_or(0, |s| s.directions);
    let tau = &start.tensions;
    sc.y = RodState {
        p: start.base.position,
        r: start.base.rotation,
        v: start.v0,
        u: start.u0,
        s: [0.0; MAX_TENDONS],
    };
    sc.dy.set_initial(nd);
    if let Some(shape) = shape.as_deref_mut() {
        shape.clear();
        shape.push(0.0, &sc.y);
    }
    for iv in &model.intervals {
        let h = (iv.end - iv.start) / iv.steps as f64;
        for _ in 0..iv.steps {
            rk4_step(model, sc, tau, iv.active, h, nd)?;
        }
        if iv.terminating != 0 {
            apply_tendon_ends(model, sc, tau, iv.terminating, nd);
        }
        if let (Some(shape), Some(_)) = (shape.as_deref_mut(), iv.disk) {
            shape.push(iv.end, &sc.y);
        }
    }
    let y = &sc.y;
    let n_body = model.k_se.component_mul(&(y.v - Vector3::z()));
    let m_body = model.k_bt.component_mul(&y.u);
    *end = LegEnd {
        p: y.p,
        r: y.r,
        n: y.r * n_body,
        m: y.r * m_body,
        lengths: y.s,
    };
    if !end
        .p
        .iter()
        .chain(end.n.iter())
        .chain(end.m.iter())
        .all(|x| x.is_finite())
    {
        return Err(SolveError::NonFinite {
            stage: "leg tip state",
        });
    }
    if let Some(sens) = sens {
        let dy = &sc.dy;
        for (j, d) in sens.d[..nd].iter_mut().enumerate() {
            let dr = Matrix3::from_fn(|row, col| dy.r[3 * col + row][j]);
            let dv = Vector3::new(dy.v[0][j], dy.v[1][j], dy.v[2][j]);
            let du = Vector3::new(dy.u[0][j], dy.u[1][j], dy.u[2][j]);
            let mut lengths = [0.0; MAX_TENDONS];
            for k in 0..model.n_tendons {
                lengths[k] = dy.s[k][j];
            }
            *d = LegEnd {
                p: Vector3::new(dy.p[0][j], dy.p[1][j], dy.p[2][j]),
                r: dr,
                n: dr * n_body + y.r * model.k_se.component_mul(&dv),
                m: dr * m_body + y.r * model.k_bt.component_mul(&du),
                lengths,
            };
        }
    }
    Ok(())
}

/// One classical RK4 step of size `h` for the state and all `nd` tangents.
fn rk4_step(
    model: &LegModel,
    sc: &mut LegScratch,
    tau: &[f64; MAX_TENDONS],
    active: u32,
    h: f64,
    nd: usize,
) -> Result<(), SolveError> {
    let nt = model.n_tendons;
    // (weight in the sum, offset of the next stage)
    const STAGES: [(f64, f64); 4] = [(1.0, 0.5), (2.0, 0.5), (2.0, 1.0), (1.0, 0.0)];
    sc.y_stage = sc.y;
    if nd > 0 {
        sc.dy_stage.assign(&sc.dy, nt);
    }
    for (i, &(weight, next)) in STAGES.iter().enumerate() {
        sc.stage.eval(model, &sc.y_stage, tau, active, &mut sc.k)?;
        if i == 0 {
            sc.acc = sc.k;
        } else {
            sc.acc.axpy(weight, &sc.k, nt);
        }
        if i < 3 {
            sc.y_stage.set_axpy(&sc.y, next * h, &sc.k, nt);
        }
        if nd > 0 {
            sc.stage.tangents(model, &sc.dy_stage, &mut sc.dk);
            if i == 0 {
                sc.dacc.assign(&sc.dk, nt);
            } else {
                sc.dacc.axpy(weight, &sc.dk, nt);
            }
            if i < 3 {
                sc.dy_stage.set_axpy(&sc.dy, next * h, &sc.dk, nt);
            }
        }
    }
    sc.y.axpy(h / 6.0, &sc.acc, nt);
    if nd > 0 {
        sc.dy.axpy(h / 6.0, &sc.dacc, nt);
    }
    Ok(())
}

/// The strain jumps where tendons end (MODEL.md §2): n⁺ = n⁻ + τ R t, m⁺ = m⁻ + τ R (r × t),
/// with every t taken before the jumps; and their tangents.
fn apply_tendon_ends(
    model: &LegModel,
    sc: &mut LegScratch,
    tau: &[f64; MAX_TENDONS],
    ending: u32,
    nd: usize,
) {
    let y = sc.y;
    let nt = model.n_tendons;
    // Pre-jump tangents (dy_stage is free between steps).
    if nd > 0 {
        sc.dy_stage.assign(&sc.dy, nt);
    }
    let inv_se = model.k_se.map(|x| 1.0 / x);
    let inv_bt = model.k_bt.map(|x| 1.0 / x);
    for k in 0..nt {
        if ending & (1 << k) == 0 {
            continue;
        }
        let r_k = &model.tendon_offsets[k];
        let w = y.v + y.u.cross(r_k);
        let len = w.norm();
        let t = w / len;
        sc.y.v += inv_se.component_mul(&t) * tau[k];
        sc.y.u += inv_bt.component_mul(&r_k.cross(&t)) * tau[k];
        let pre = &sc.dy_stage;
        for j in 0..nd {
            let dv = Vector3::new(pre.v[0][j], pre.v[1][j], pre.v[2][j]);
            let du = Vector3::new(pre.u[0][j], pre.u[1][j], pre.u[2][j]);
            let dw = dv + du.cross(r_k);
            let dt = (dw - t * t.dot(&dw)) / len;
            let dtau = if j == 6 + k { 1.0 } else { 0.0 };
            let dforce = t * dtau + dt * tau[k];
            let jump_v = inv_se.component_mul(&dforce);
            let jump_u = inv_bt.component_mul(&r_k.cross(&dforce));
            for c in 0..3 {
                sc.dy.v[c][j] += jump_v[c];
                sc.dy.u[c][j] += jump_u[c];
            }
        }
    }
}
