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
use crate::rod::leg_model::LegModel;
use crate::rod::rhs::{RkEmit, RodState, Stage};
pub use crate::rod::tangents::MAX_DIRECTIONS;
use crate::rod::tangents::Tangents;
use crate::spatial::Frame;

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
    y_next: RodState,
    y_stage: RodState,
    k: RodState,
    /// Tangents at the start of the step, the step's running sum, and the inputs of the
    /// current and the next RK stage (two buffers, swapped after each stage).
    dy: Box<Tangents>,
    dy_next: Box<Tangents>,
    dy_stage: Box<Tangents>,
    dy_stage_next: Box<Tangents>,
}

impl LegScratch {
    /// Allocates the buffers (the only allocation of an integration).
    pub fn new() -> Self {
        let z = RodState::zeros();
        Self {
            stage: Stage::new(),
            y: z,
            y_next: z,
            y_stage: z,
            k: z,
            dy: Box::new(Tangents::zeros()),
            dy_next: Box::new(Tangents::zeros()),
            dy_stage: Box::new(Tangents::zeros()),
            dy_stage_next: Box::new(Tangents::zeros()),
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

/// Runs the integration, with AVX2 code where the CPU has it (detected at run time; the
/// same operations in the same order, so the results are bitwise identical either way).
fn integrate(
    model: &LegModel,
    start: &LegStart,
    sc: &mut LegScratch,
    end: &mut LegEnd,
    sens: Option<&mut LegSensitivities>,
    shape: Option<&mut LegShape>,
) -> Result<(), SolveError> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        return unsafe { integrate_avx2(model, start, sc, end, sens, shape) };
    }
    integrate_dispatch(model, start, sc, end, sens, shape)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn integrate_avx2(
    model: &LegModel,
    start: &LegStart,
    sc: &mut LegScratch,
    end: &mut LegEnd,
    sens: Option<&mut LegSensitivities>,
    shape: Option<&mut LegShape>,
) -> Result<(), SolveError> {
    integrate_dispatch(model, start, sc, end, sens, shape)
}

/// Picks the lane count N ≥ the directions used (0: primal only): 8 covers a leg with
/// one tendon pair, 10 two pairs.
#[inline(always)]
fn integrate_dispatch(
    model: &LegModel,
    start: &LegStart,
    sc: &mut LegScratch,
    end: &mut LegEnd,
    sens: Option<&mut LegSensitivities>,
    shape: Option<&mut LegShape>,
) -> Result<(), SolveError> {
    match sens.as_ref().map_or(0, |s| s.directions) {
        0 => integrate_lanes::<0>(model, start, sc, end, None, shape),
        1..=8 => integrate_lanes::<8>(model, start, sc, end, sens, shape),
        9..=10 => integrate_lanes::<10>(model, start, sc, end, sens, shape),
        _ => integrate_lanes::<MAX_DIRECTIONS>(model, start, sc, end, sens, shape),
    }
}

#[inline(always)]
fn integrate_lanes<const N: usize>(
    model: &LegModel,
    start: &LegStart,
    sc: &mut LegScratch,
    end: &mut LegEnd,
    sens: Option<&mut LegSensitivities>,
    mut shape: Option<&mut LegShape>,
) -> Result<(), SolveError> {
    let nd = sens.as_ref().map_or(0, |s| s.directions);
    let nt = model.n_tendons;
    let tau = &start.tensions;
    sc.y = RodState {
        p: start.base.position,
        r: start.base.rotation,
        v: start.v0,
        u: start.u0,
        s: [0.0; MAX_TENDONS],
    };
    if N > 0 {
        sc.dy.set_initial::<N>(nt);
    }
    if let Some(shape) = shape.as_deref_mut() {
        shape.clear();
        shape.push(0.0, &sc.y);
    }
    for iv in &model.intervals {
        let h = (iv.end - iv.start) / iv.steps as f64;
        for _ in 0..iv.steps {
            rk4_step::<N>(model, sc, tau, iv.active, h, nd)?;
        }
        if iv.terminating != 0 {
            apply_tendon_ends::<N>(model, sc, tau, iv.terminating, nd);
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
            for k in 0..nt {
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

/// One classical RK4 step of size `h` for the state and the `N` tangent lanes.
/// The next state accumulates y + h Σ b_i k_i stage by stage; intermediate stages carry
/// only R, v, u (p and s do not feed back).
#[inline(always)]
fn rk4_step<const N: usize>(
    model: &LegModel,
    sc: &mut LegScratch,
    tau: &[f64; MAX_TENDONS],
    active: u32,
    h: f64,
    nd: usize,
) -> Result<(), SolveError> {
    let nt = model.n_tendons;
    // (weight b_i, offset c_(i+1) of the next stage)
    const STAGES: [(f64, f64); 4] = [(1.0, 0.5), (2.0, 0.5), (2.0, 1.0), (1.0, 0.0)];
    for (i, &(weight, next)) in STAGES.iter().enumerate() {
        let input = if i == 0 { &sc.y } else { &sc.y_stage };
        sc.stage.eval(model, input, tau, active, &mut sc.k, N > 0)?;
        let b = weight * h / 6.0;
        if i == 0 {
            sc.y_next = sc.y;
        }
        sc.y_next.axpy(b, &sc.k, nt);
        if i < 3 {
            sc.y_stage.set_stage(&sc.y, next * h, &sc.k);
        }
        if N > 0 {
            sc.stage.linearize(model, nd);
            let d_input = if i == 0 { &*sc.dy } else { &*sc.dy_stage };
            let mut emit = RkEmit {
                base: &sc.dy,
                sum: &mut sc.dy_next,
                weight: b,
                first: i == 0,
                next: (i < 3).then_some((&mut *sc.dy_stage_next, next * h)),
            };
            sc.stage.tangents::<N>(model, d_input, &mut emit);
            std::mem::swap(&mut sc.dy_stage, &mut sc.dy_stage_next);
        }
    }
    std::mem::swap(&mut sc.y, &mut sc.y_next);
    if N > 0 {
        std::mem::swap(&mut sc.dy, &mut sc.dy_next);
    }
    Ok(())
}

/// The strain jumps where tendons end (MODEL.md §2): n⁺ = n⁻ + τ R t, m⁺ = m⁻ + τ R (r × t),
/// with every t taken before the jumps; and their tangents.
#[inline(always)]
fn apply_tendon_ends<const N: usize>(
    model: &LegModel,
    sc: &mut LegScratch,
    tau: &[f64; MAX_TENDONS],
    ending: u32,
    nd: usize,
) {
    let y = sc.y;
    // Pre-jump tangents (dy_stage is free between steps).
    if N > 0 {
        sc.dy_stage.set_stage::<N>(&sc.dy, 0.0, &sc.dy);
    }
    let inv_se = model.k_se.map(|x| 1.0 / x);
    let inv_bt = model.k_bt.map(|x| 1.0 / x);
    for k in 0..model.n_tendons {
        if ending & (1 << k) == 0 {
            continue;
        }
        let r_k = &model.tendon_offsets[k];
        let w = y.v + y.u.cross(r_k);
        let len = w.norm();
        let t = w / len;
        let rt = r_k.cross(&t);
        sc.y.v += inv_se.component_mul(&t) * tau[k];
        sc.y.u += inv_bt.component_mul(&rt) * tau[k];
        let (pre, dy) = (&sc.dy_stage, &mut sc.dy);
        for j in 0..N {
            let dv = Vector3::new(pre.v[0][j], pre.v[1][j], pre.v[2][j]);
            let du = Vector3::new(pre.u[0][j], pre.u[1][j], pre.u[2][j]);
            let dw = dv + du.cross(r_k);
            let dforce = (dw - t * t.dot(&dw)) * (tau[k] / len);
            let jump_v = inv_se.component_mul(&dforce);
            let jump_u = inv_bt.component_mul(&r_k.cross(&dforce));
            for c in 0..3 {
                dy.v[c][j] += jump_v[c];
                dy.u[c][j] += jump_u[c];
            }
        }
        // The tension direction of tendon k: ∂(τ t)/∂τ = t.
        if 6 + k < nd {
            let (jump_v, jump_u) = (inv_se.component_mul(&t), inv_bt.component_mul(&rt));
            for c in 0..3 {
                dy.v[c][6 + k] += jump_v[c];
                dy.u[c][6 + k] += jump_u[c];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::{Disks, Leg, Tendon};

    fn leg() -> LegModel {
        let tendon = |angle: f64, end: f64| Tendon {
            angle,
            offset: 0.005,
            end,
        };
        let leg = Leg {
            length: 0.145,
            backbone_radius: 0.0005,
            youngs_modulus: 54e9,
            poisson_ratio: 0.3,
            backbone_mass: 0.0012,
            disks: Disks {
                count: 13,
                mass: 0.0003,
                radius: 0.006,
            },
            tendon_stiffness: 1000.0,
            tendons: vec![
                tendon(0.0, 0.145),
                tendon(std::f64::consts::PI, 0.145),
                tendon(1.0, 0.08),
            ],
            integration_steps: crate::design::DEFAULT_INTEGRATION_STEPS,
        };
        LegModel::new(&leg, Vector3::new(0.5, 0.0, -9.81))
    }

    /// The AVX2 path (where the CPU has it) and the portable path give bitwise equal tips
    /// and sensitivities: the lane count and instruction set change nothing numerically.
    #[test]
    fn every_code_path_gives_bitwise_identical_results() {
        let model = leg();
        let mut tensions = [0.0; MAX_TENDONS];
        tensions[0] = 3.2;
        tensions[2] = 0.4;
        let start = LegStart {
            base: Frame::identity(),
            u0: Vector3::new(0.3, 6.0, -0.1),
            v0: Vector3::new(1e-5, 0.0, 0.99992),
            tensions,
        };
        let run = |portable: bool, directions: usize| {
            let mut sc = LegScratch::new();
            let mut end = LegEnd::zeros();
            let mut sens = LegSensitivities::new(directions);
            if portable {
                integrate_dispatch(&model, &start, &mut sc, &mut end, Some(&mut sens), None)
            } else {
                integrate(&model, &start, &mut sc, &mut end, Some(&mut sens), None)
            }
            .unwrap();
            (end, sens.d)
        };
        let reference = run(true, 9);
        assert_eq!(run(false, 9), reference);
        // Strains only: the same tip and the same first six directions.
        let (end, d) = run(true, 6);
        assert_eq!(end, reference.0);
        assert_eq!(d[..6], reference.1[..6]);
    }
}
