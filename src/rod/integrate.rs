//! Fixed-step Runge–Kutta integration (the leg's
//! [`Tableau`](super::tableau::Tableau)) of one leg from base to tip, optionally with
//! forward sensitivities propagated through the same discrete steps (MODEL.md §5), so
//! they are the exact derivatives of the discrete map.
//!
//! Sensitivity directions, in this order: u(0) (3), v(0) (3), then the tension τ_k of
//! each tendon (n_t), or of the selected tendons only
//! ([`LegSensitivities::select_tensions`]). Tendon ends apply the force/moment jumps of
//! MODEL.md §2; the tip outputs n, m are taken after the jumps of the tendons ending at L,
//! i.e. they are the wrench the rod transmits beyond its tip (n(L) − Σ f_t,k,
//! m(L) − Σ l_t,k).

use nalgebra::{Matrix3, Vector3};

use crate::design::MAX_TENDONS;
use crate::error::SolveError;
use crate::rod::lanes::{F64x4, Real, cross, dot, mat_vec};
use crate::rod::leg_model::LegModel;
pub use crate::rod::rhs::MAX_LEGS;
use crate::rod::rhs::{RodState, Stage};
use crate::rod::slots::TendonSlots;
use crate::rod::tableau::MAX_STAGES;
pub use crate::rod::tangents::MAX_DIRECTIONS;
use crate::rod::tangents::{FEEDBACK_ROWS, K_P, K_S, K_U, K_V, Tangents};
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
///
/// Direction (lane) j < 6 is u(0)_j, then v(0); the lanes from 6 hold the tensions of the
/// selected tendons ([`LegSensitivities::select_tensions`]; by default every tendon k
/// in lane 6 + k).
#[derive(Debug, Clone)]
pub struct LegSensitivities {
    directions: usize,
    /// Lane of tendon k's tension direction, or [`NO_LANE`].
    tension_lanes: [usize; MAX_TENDONS],
    /// `d[j]` = ∂(tip state)/∂(direction j).
    pub d: [LegEnd; MAX_DIRECTIONS],
}

/// The lane of a tension direction that is not integrated.
const NO_LANE: usize = usize::MAX;

impl LegSensitivities {
    /// Room for the first `directions` directions: 6 (strains only) up to 6 + n_t, tendon
    /// k's tension in lane 6 + k.
    ///
    /// # Panics
    /// If `directions` exceeds [`MAX_DIRECTIONS`] (a programming error).
    #[track_caller]
    pub fn new(directions: usize) -> Self {
        assert!(
            directions <= MAX_DIRECTIONS,
            "at most {MAX_DIRECTIONS} directions"
        );
        let mut sens = Self {
            directions,
            tension_lanes: [NO_LANE; MAX_TENDONS],
            d: [LegEnd::zeros(); MAX_DIRECTIONS],
        };
        for (k, lane) in sens.tension_lanes.iter_mut().enumerate() {
            if 6 + k < directions {
                *lane = 6 + k;
            }
        }
        sens
    }

    /// Integrates the tension directions of the tendons in the bit set `tendons` only
    /// (bit k: tendon k), in lanes 6, 7, … in tendon order, and `directions` lanes in
    /// all (the lanes beyond the selected tendons stay zero: the legs of one
    /// [`integrate_legs`] call need equal counts). A slack tendon's tension direction is
    /// zero in every column that uses it (dτ/dζ = 0), and skipping it saves a vector of
    /// lanes where two of four tendons are slack.
    ///
    /// # Panics
    /// If `directions` is below 6 + the selected count or above [`MAX_DIRECTIONS`] (a
    /// programming error).
    #[track_caller]
    pub fn select_tensions(&mut self, tendons: u32, directions: usize) {
        let selected = tendons.count_ones() as usize;
        assert!(
            (6 + selected..=MAX_DIRECTIONS).contains(&directions),
            "{directions} directions for {selected} tensions"
        );
        self.directions = directions;
        let mut next = 6;
        for (k, lane) in self.tension_lanes.iter_mut().enumerate() {
            *lane = if tendons & (1 << k) != 0 {
                next += 1;
                next - 1
            } else {
                NO_LANE
            };
        }
    }

    /// Number of directions computed.
    pub fn directions(&self) -> usize {
        self.directions
    }

    /// ∂(tip state)/∂τ_k, if that direction was integrated.
    pub fn tension(&self, k: usize) -> Option<&LegEnd> {
        let lane = *self.tension_lanes.get(k)?;
        (lane < self.directions).then(|| &self.d[lane])
    }
}

/// How much of a leg's backbone an integration records into its [`LegShape`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
pub enum ShapeDetail {
    /// The positions at the base and at every integration step's end (the knots,
    /// [`LegModel::knot_arcs`]): copies of states the integration computes anyway.
    Knots,
    /// The knots and the frames at the base and at every disk: a partial step (primal
    /// only) to each disk inside a step, about one residual evaluation for the bundled
    /// 13-disk legs.
    #[default]
    Disks,
}

/// Backbone frames at the base and at every disk, for plots and collision checks, and
/// the positions at the integration's knots.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LegShape {
    /// What the next integration into this shape records ([`ShapeDetail::Disks`] unless
    /// set otherwise); with [`ShapeDetail::Knots`] `arcs`, `positions` and `rotations`
    /// are left empty.
    pub detail: ShapeDetail,
    /// Arc lengths \[m\]: 0, then each disk.
    pub arcs: Vec<f64>,
    /// Backbone positions \[m\].
    pub positions: Vec<Vector3<f64>>,
    /// Backbone orientations.
    pub rotations: Vec<Matrix3<f64>>,
    /// Backbone positions \[m\] at the arcs of [`LegModel::knot_arcs`]: the base, then
    /// every integration step's end.
    pub knots: Vec<Vector3<f64>>,
}

impl LegShape {
    /// Empty shape for legs of `model`, recording the disks, with room for all of its
    /// frames and knots (no integration into it allocates).
    pub fn new(model: &LegModel) -> Self {
        let mut shape = Self::with_capacity(model.n_disks);
        shape.knots.reserve_exact(model.knot_arcs().count());
        shape
    }

    /// Empty shape with room for `n_disks + 1` frames, recording the disks (the knots'
    /// buffer grows in the first integration; [`LegShape::new`] reserves it too).
    pub fn with_capacity(n_disks: usize) -> Self {
        Self {
            detail: ShapeDetail::Disks,
            arcs: Vec::with_capacity(n_disks + 1),
            positions: Vec::with_capacity(n_disks + 1),
            rotations: Vec::with_capacity(n_disks + 1),
            knots: Vec::new(),
        }
    }

    /// Appends the frame of lane `leg`.
    fn push<T: Real>(&mut self, s: f64, y: &RodState<T>, leg: usize) {
        self.arcs.push(s);
        self.positions.push(y.p.map(|e| e.lane(leg)));
        self.rotations.push(y.r.map(|e| e.lane(leg)));
    }

    /// Appends the position of lane `leg` as the next knot.
    fn push_knot<T: Real>(&mut self, y: &RodState<T>, leg: usize) {
        self.knots.push(y.p.map(|e| e.lane(leg)));
    }

    fn clear(&mut self) {
        self.arcs.clear();
        self.positions.clear();
        self.rotations.clear();
        self.knots.clear();
    }
}

/// The tangent buffers of one leg: at the start of the step (then its end, formed in
/// place), the input of the current RK stage (overwritten by the next one's once the
/// stage's k is known), and each stage's derivative k_i.
#[derive(Debug, Clone)]
struct LegTangents {
    dy: Box<Tangents>,
    dy_stage: Box<Tangents>,
    ks: Box<[Tangents; MAX_STAGES]>,
}

impl LegTangents {
    fn new() -> Self {
        Self {
            dy: Box::new(Tangents::zeros()),
            dy_stage: Box::new(Tangents::zeros()),
            ks: Box::new(std::array::from_fn(|_| Tangents::zeros())),
        }
    }
}

/// Buffers of one integration of up to `T::LANES` legs, one per lane.
#[derive(Debug, Clone)]
struct Buffers<T: Real> {
    stage: Stage<T>,
    y: RodState<T>,
    y_next: RodState<T>,
    y_stage: RodState<T>,
    /// Each stage's derivative k_i (boxed: 5.8 kB for four lanes, kept off the stack).
    ks: Box<[RodState<T>; MAX_STAGES]>,
    /// The tendons of each lane in slot order, with their tensions.
    tendons: TendonSlots<T>,
    /// Tangents of each lane's leg.
    tangents: Vec<LegTangents>,
    /// `tension_lanes[lane][slot]`: the direction lane of the tension of the tendon in
    /// `slot` (from [`LegSensitivities::select_tensions`]; [`NO_LANE`] if not integrated).
    tension_lanes: [[usize; MAX_TENDONS]; MAX_LEGS],
}

impl<T: Real> Buffers<T> {
    fn new() -> Self {
        let z = RodState::zeros();
        Self {
            stage: Stage::new(),
            y: z,
            y_next: z,
            y_stage: z,
            ks: Box::new([z; MAX_STAGES]),
            tendons: TendonSlots::new(),
            tangents: (0..T::LANES).map(|_| LegTangents::new()).collect(),
            tension_lanes: [[NO_LANE; MAX_TENDONS]; MAX_LEGS],
        }
    }
}

/// Buffers for one leg integration; build once, reuse for every call.
#[derive(Debug, Clone)]
pub struct LegScratch(Buffers<f64>);

impl LegScratch {
    /// Allocates the buffers (the only allocation of an integration).
    pub fn new() -> Self {
        Self(Buffers::new())
    }
}

impl Default for LegScratch {
    fn default() -> Self {
        Self::new()
    }
}

/// Buffers for integrating up to [`MAX_LEGS`] legs of one model together
/// ([`integrate_legs`]); build once, reuse for every call.
#[derive(Debug, Clone)]
pub struct LegsScratch(Buffers<F64x4>);

impl LegsScratch {
    /// Allocates the buffers (the only allocation of an integration).
    pub fn new() -> Self {
        Self(Buffers::new())
    }
}

impl Default for LegsScratch {
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
    let (starts, ends) = (std::slice::from_ref(start), std::slice::from_mut(end));
    let shapes = shape.map(std::slice::from_mut);
    integrate(model, starts, &mut scratch.0, ends, None, shapes)
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
    check_directions(model, std::slice::from_ref(sens));
    let (starts, ends) = (std::slice::from_ref(start), std::slice::from_mut(end));
    let sens = Some(std::slice::from_mut(sens));
    let shapes = shape.map(std::slice::from_mut);
    integrate(model, starts, &mut scratch.0, ends, sens, shapes)
}

/// Integrates several legs of one model (up to [`MAX_LEGS`], e.g. the three legs of a
/// robot) together, one per SIMD lane: the same tips and sensitivities, bitwise, as
/// [`integrate_leg`] / [`integrate_leg_with_sensitivities`] leg by leg, in about the time
/// of one leg's primal kernel (module [`lanes`](super::lanes)). With `sens`, every leg
/// gets the same number of directions; with `shapes`, every leg's frames at the disks.
///
/// # Errors
/// [`SolveError::NonFinite`] if any leg's state blows up.
///
/// # Panics
/// If `starts`, `ends` (and `sens`, `shapes`) differ in length or hold more than [`MAX_LEGS`]
/// legs, or the legs' direction counts differ or exceed 6 + n_t (programming errors).
#[track_caller]
pub fn integrate_legs(
    model: &LegModel,
    starts: &[LegStart],
    scratch: &mut LegsScratch,
    ends: &mut [LegEnd],
    sens: Option<&mut [LegSensitivities]>,
    shapes: Option<&mut [LegShape]>,
) -> Result<(), SolveError> {
    assert!(
        (1..=MAX_LEGS).contains(&starts.len()) && ends.len() == starts.len(),
        "integrate_legs: {} starts, {} ends (1 to {MAX_LEGS} legs)",
        starts.len(),
        ends.len()
    );
    if let Some(sens) = sens.as_deref() {
        assert_eq!(
            sens.len(),
            starts.len(),
            "integrate_legs: one sensitivity per leg"
        );
        check_directions(model, sens);
    }
    if let Some(shapes) = shapes.as_deref() {
        assert_eq!(
            shapes.len(),
            starts.len(),
            "integrate_legs: one shape per leg"
        );
    }
    integrate(model, starts, &mut scratch.0, ends, sens, shapes)
}

#[track_caller]
fn check_directions(model: &LegModel, sens: &[LegSensitivities]) {
    let nd = sens[0].directions;
    assert!(
        nd <= 6 + model.n_tendons && sens.iter().all(|s| s.directions == nd),
        "{nd} sensitivity directions requested, the leg has {}",
        6 + model.n_tendons
    );
}

/// Runs the integration, with AVX2 code where the CPU has it (detected at run time; the
/// same operations in the same order, so the results are bitwise identical either way).
fn integrate<T: Real>(
    model: &LegModel,
    starts: &[LegStart],
    buf: &mut Buffers<T>,
    ends: &mut [LegEnd],
    sens: Option<&mut [LegSensitivities]>,
    shapes: Option<&mut [LegShape]>,
) -> Result<(), SolveError> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA, checked just above.
        return unsafe { integrate_avx2(model, starts, buf, ends, sens, shapes) };
    }
    integrate_dispatch(model, starts, buf, ends, sens, shapes)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn integrate_avx2<T: Real>(
    model: &LegModel,
    starts: &[LegStart],
    buf: &mut Buffers<T>,
    ends: &mut [LegEnd],
    sens: Option<&mut [LegSensitivities]>,
    shapes: Option<&mut [LegShape]>,
) -> Result<(), SolveError> {
    integrate_dispatch(model, starts, buf, ends, sens, shapes)
}

/// Picks the lane count N ≥ the directions used (0: primal only): 8 covers a leg with
/// one tendon pair, 10 two pairs.
#[inline(always)]
fn integrate_dispatch<T: Real>(
    model: &LegModel,
    starts: &[LegStart],
    buf: &mut Buffers<T>,
    ends: &mut [LegEnd],
    sens: Option<&mut [LegSensitivities]>,
    shapes: Option<&mut [LegShape]>,
) -> Result<(), SolveError> {
    match sens.as_ref().map_or(0, |s| s[0].directions) {
        0 => integrate_lanes::<0, T>(model, starts, buf, ends, None, shapes),
        1..=8 => integrate_lanes::<8, T>(model, starts, buf, ends, sens, shapes),
        9..=10 => integrate_lanes::<10, T>(model, starts, buf, ends, sens, shapes),
        _ => integrate_lanes::<MAX_DIRECTIONS, T>(model, starts, buf, ends, sens, shapes),
    }
}

/// Lane `i` of a vector.
#[inline(always)]
fn lane3<T: Real>(x: &Vector3<T>, i: usize) -> Vector3<f64> {
    x.map(|e| e.lane(i))
}

// Inlined (into the AVX2 copy) in optimized builds only (`build.rs` sets
// `tdpcr_unoptimized` at opt-level 0): an unoptimized build keeps every temporary of every
// inlined call in its own stack slot, and the four direction counts inlined into one
// function took a frame of 1 MB, which with a solver's call stack overflowed the 2 MB
// stacks of rayon's workers.
#[cfg_attr(not(tdpcr_unoptimized), inline(always))]
#[cfg_attr(tdpcr_unoptimized, inline(never))]
fn integrate_lanes<const N: usize, T: Real>(
    model: &LegModel,
    starts: &[LegStart],
    buf: &mut Buffers<T>,
    ends: &mut [LegEnd],
    sens: Option<&mut [LegSensitivities]>,
    mut shapes: Option<&mut [LegShape]>,
) -> Result<(), SolveError> {
    let legs = starts.len();
    let nd = sens.as_ref().map_or(0, |s| s[0].directions);
    let nt = model.n_tendons;
    // Leg l in lane l; lanes beyond the legs repeat leg 0 (valid data, never read).
    let mut y = RodState::<T>::zeros();
    for lane in 0..T::LANES {
        let start = &starts[if lane < legs { lane } else { 0 }];
        let frame = &start.base;
        for i in 0..3 {
            y.p[i].set_lane(lane, frame.position[i]);
            y.v[i].set_lane(lane, start.v0[i]);
            y.u[i].set_lane(lane, start.u0[i]);
        }
        for (e, x) in y.r.iter_mut().zip(frame.rotation.iter()) {
            e.set_lane(lane, *x);
        }
        buf.tendons.set_lane(lane, model, &start.tensions);
    }
    buf.y = y;
    if let Some(sens) = sens.as_deref() {
        buf.tension_lanes = [[NO_LANE; MAX_TENDONS]; MAX_LEGS];
        for (leg, sens) in sens.iter().enumerate() {
            for (slot, &k) in buf.tendons.tendon[leg][..nt].iter().enumerate() {
                buf.tension_lanes[leg][slot] = sens.tension_lanes[k];
            }
        }
        buf.stage.clear_tension_sources(legs, N);
        for tg in &mut buf.tangents[..legs] {
            tg.dy.set_initial::<N>(nt);
        }
    }
    // The disks' frames only where a shape asks for them (each shape gets its detail).
    let disks = shapes
        .as_deref()
        .is_some_and(|s| s.iter().any(|s| s.detail == ShapeDetail::Disks));
    if let Some(shapes) = shapes.as_deref_mut() {
        for (leg, shape) in shapes.iter_mut().enumerate() {
            shape.clear();
            shape.push_knot(&buf.y, leg);
            if shape.detail == ShapeDetail::Disks {
                shape.push(0.0, &buf.y, leg);
            }
        }
    }
    // Disks are not step boundaries: a disk inside a step gets the state of a partial step
    // of the same method from the step's start; one at a step's end that step's state
    // (after the jumps of tendons ending there).
    let tol = 1e-12 * model.length;
    let mut disk = if disks { 1 } else { model.n_disks + 1 };
    for iv in &model.intervals {
        let h = (iv.end - iv.start) / iv.steps as f64;
        for step in 0..iv.steps {
            let last = step + 1 == iv.steps;
            let (from, to) = (
                iv.start + step as f64 * h,
                if last {
                    iv.end
                } else {
                    iv.start + (step + 1) as f64 * h
                },
            );
            if let Some(shapes) = shapes.as_deref_mut() {
                while disk <= model.n_disks && model.disk_arc(disk) < to - tol {
                    let arc = model.disk_arc(disk);
                    // The partial step leaves its state in y and the step's start in
                    // y_next; swapped back after recording.
                    rk_step::<0, T>(model, buf, iv.active, arc - from, 0, legs)?;
                    for (leg, shape) in shapes.iter_mut().enumerate() {
                        if shape.detail == ShapeDetail::Disks {
                            shape.push(arc, &buf.y, leg);
                        }
                    }
                    std::mem::swap(&mut buf.y, &mut buf.y_next);
                    disk += 1;
                }
            }
            rk_step::<N, T>(model, buf, iv.active, h, nd, legs)?;
            if last && iv.terminating != 0 {
                apply_tendon_ends::<N, T>(model, buf, iv.terminating, nd, legs);
            }
            if let Some(shapes) = shapes.as_deref_mut() {
                for (leg, shape) in shapes.iter_mut().enumerate() {
                    shape.push_knot(&buf.y, leg);
                }
                while disk <= model.n_disks && model.disk_arc(disk) <= to + tol {
                    for (leg, shape) in shapes.iter_mut().enumerate() {
                        if shape.detail == ShapeDetail::Disks {
                            shape.push(model.disk_arc(disk), &buf.y, leg);
                        }
                    }
                    disk += 1;
                }
            }
        }
    }
    let y = &buf.y;
    let (k_se, k_bt) = (model.k_se.map(T::splat), model.k_bt.map(T::splat));
    let n_body = k_se.component_mul(&(y.v - Vector3::z()));
    let m_body = k_bt.component_mul(&y.u);
    let (n_world, m_world) = (mat_vec(&y.r, &n_body), mat_vec(&y.r, &m_body));
    for (leg, end) in ends.iter_mut().enumerate() {
        *end = LegEnd {
            p: lane3(&y.p, leg),
            r: y.r.map(|e| e.lane(leg)),
            n: lane3(&n_world, leg),
            m: lane3(&m_world, leg),
            lengths: [0.0; MAX_TENDONS],
        };
        for (slot, &k) in buf.tendons.tendon[leg][..nt].iter().enumerate() {
            end.lengths[k] = y.s[slot].lane(leg);
        }
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
    }
    if let Some(sens) = sens {
        for (leg, sens) in sens.iter_mut().enumerate() {
            let dy = &buf.tangents[leg].dy;
            let rot = y.r.map(|e| e.lane(leg));
            let (n_body, m_body) = (lane3(&n_body, leg), lane3(&m_body, leg));
            for (j, d) in sens.d[..nd].iter_mut().enumerate() {
                let at = |row: usize| dy.row::<N>(row)[j];
                let dr = Matrix3::from_fn(|row, col| at(3 * col + row));
                let dv = Vector3::new(at(K_V), at(K_V + 1), at(K_V + 2));
                let du = Vector3::new(at(K_U), at(K_U + 1), at(K_U + 2));
                let mut lengths = [0.0; MAX_TENDONS];
                for k in 0..nt {
                    lengths[k] = at(K_S + k);
                }
                *d = LegEnd {
                    p: Vector3::new(at(K_P), at(K_P + 1), at(K_P + 2)),
                    r: dr,
                    n: dr * n_body + rot * model.k_se.component_mul(&dv),
                    m: dr * m_body + rot * model.k_bt.component_mul(&du),
                    lengths,
                };
            }
        }
    }
    Ok(())
}

/// One step of size `h` of the leg's Runge–Kutta method ([`LegModel::tableau`]) for the
/// state and, for each of the first `legs` lanes, its `N` tangent lanes (the same method
/// applied to the variational equation with each stage's linearization, so the tangents
/// are the exact derivatives of the discrete step). The ODE is autonomous within an
/// interval, so the stages need no c. The step y + h Σ_i b_i k_i accumulates stage by
/// stage; a stage input y + h Σ_j a_ij k_j carries only R, v, u (p and s do not feed
/// back). The tangents' k_i are stored whole; each stage input is formed from them in one
/// pass, the step's end in one pass after the last stage
/// ([`Tangents::set_combination`]).
#[inline(always)]
fn rk_step<const N: usize, T: Real>(
    model: &LegModel,
    buf: &mut Buffers<T>,
    active: u32,
    h: f64,
    nd: usize,
    legs: usize,
) -> Result<(), SolveError> {
    let nt = model.n_tendons;
    let tab = model.tableau;
    let Buffers {
        stage,
        y,
        y_next,
        y_stage,
        ks,
        tendons,
        tangents,
        tension_lanes,
    } = buf;
    for i in 0..tab.stages {
        let input = if i == 0 { &*y } else { &*y_stage };
        stage.eval(model, input, tendons, active, &mut ks[i], N > 0)?;
        // The state: into the sum, and the next stage's input from the kept k_j.
        let b = h * tab.b[i];
        if i == 0 {
            y_next.set_sum(y, T::splat(b), &ks[0], nt);
        } else if b != 0.0 {
            y_next.axpy(T::splat(b), &ks[i], nt);
        }
        // The next stage's input: its terms, and the coefficient of this stage's k in it.
        let next = (i + 1 < tab.stages).then(|| (&tab.inputs[i + 1], h * tab.a[i + 1][i]));
        // Plain loops build the term lists: `std::array::from_fn` was compiled as a call
        // out of the AVX2 code (with `vzeroupper` and a stalled reload of its result): 12 %
        // of the exact Jacobian's samples (perf, 2026-11-26).
        if let Some((input, _)) = next {
            let mut terms = [(0.0, &ks[0]); MAX_STAGES];
            for (t, term) in terms[..input.n].iter_mut().enumerate() {
                *term = (h * input.coefficient[t], &ks[input.stage[t]]);
            }
            y_stage.set_stage_input(y, &terms[..input.n]);
        }
        if N > 0 {
            stage.linearize(model, tendons, tension_lanes, nd);
            for (leg, tg) in tangents[..legs].iter_mut().enumerate() {
                let LegTangents { dy, dy_stage, ks } = tg;
                let d = if i == 0 { &**dy } else { &**dy_stage };
                stage.tangents::<N>(leg, model, tendons, d, &mut ks[i]);
                // The next stage's input in one pass: this stage's term first, then the
                // earlier stages' in order (RK4 has none).
                if i + 1 < tab.stages {
                    let earlier = &tab.earlier[i + 1];
                    let mut terms = [(0.0, &ks[0]); MAX_STAGES];
                    terms[0] = (h * tab.a[i + 1][i], &ks[i]);
                    for t in 0..earlier.n {
                        terms[1 + t] = (h * earlier.coefficient[t], &ks[earlier.stage[t]]);
                    }
                    dy_stage.set_combination::<N>(Some(dy), &terms[..1 + earlier.n], FEEDBACK_ROWS);
                }
            }
        }
    }
    std::mem::swap(y, y_next);
    if N > 0 {
        // The step's end: the first stage's term, then every other stage with a weight.
        let mut n = 1;
        let mut weights = [(h * tab.b[0], 0); MAX_STAGES];
        for i in 1..tab.stages {
            let w = h * tab.b[i];
            if w != 0.0 {
                weights[n] = (w, i);
                n += 1;
            }
        }
        for tg in &mut tangents[..legs] {
            let mut terms = [(0.0, &tg.ks[0]); MAX_STAGES];
            for (term, &(w, i)) in terms.iter_mut().zip(&weights[..n]) {
                *term = (w, &tg.ks[i]);
            }
            tg.dy.set_combination::<N>(None, &terms[..n], K_S + nt);
        }
    }
    Ok(())
}

/// The strain jumps where tendons end (MODEL.md §2): n⁺ = n⁻ + τ R t, m⁺ = m⁻ + τ R (r × t),
/// with every t taken before the jumps; and their tangents.
#[inline(always)]
fn apply_tendon_ends<const N: usize, T: Real>(
    model: &LegModel,
    buf: &mut Buffers<T>,
    ending: u32,
    nd: usize,
    legs: usize,
) {
    let y = buf.y;
    // Pre-jump tangents (dy_stage is free between steps).
    if N > 0 {
        for tg in &mut buf.tangents[..legs] {
            tg.dy_stage.copy_feedback::<N>(&tg.dy);
        }
    }
    let inv_se = model.k_se.map(|x| 1.0 / x);
    let inv_bt = model.k_bt.map(|x| 1.0 / x);
    for k in 0..model.n_tendons {
        if ending & (1 << k) == 0 {
            continue;
        }
        let r_lanes = buf.tendons.offsets[k];
        let w = y.v + cross(&y.u, &r_lanes);
        let len = dot(&w, &w).sqrt();
        let t = w / len;
        let rt = cross(&r_lanes, &t);
        let tau = buf.tendons.tensions[k];
        buf.y.v += inv_se.map(T::splat).component_mul(&t) * tau;
        buf.y.u += inv_bt.map(T::splat).component_mul(&rt) * tau;
        for (leg, tg) in buf.tangents[..legs].iter_mut().enumerate() {
            let (t, rt, r_k) = (lane3(&t, leg), lane3(&rt, leg), lane3(&r_lanes, leg));
            let tension_lane = buf.tension_lanes[leg][k];
            let (len, tau) = (len.lane(leg), tau.lane(leg));
            let (pre, dy) = (&tg.dy_stage, &mut tg.dy);
            for j in 0..N {
                let at = |row: usize| pre.row::<N>(row)[j];
                let dv = Vector3::new(at(K_V), at(K_V + 1), at(K_V + 2));
                let du = Vector3::new(at(K_U), at(K_U + 1), at(K_U + 2));
                let dw = dv + du.cross(&r_k);
                let dforce = (dw - t * t.dot(&dw)) * (tau / len);
                let jump_v = inv_se.component_mul(&dforce);
                let jump_u = inv_bt.component_mul(&r_k.cross(&dforce));
                for c in 0..3 {
                    dy.row_mut::<N>(K_V + c)[j] += jump_v[c];
                    dy.row_mut::<N>(K_U + c)[j] += jump_u[c];
                }
            }
            // The tension direction of the slot's tendon: ∂(τ t)/∂τ = t.
            if tension_lane < nd {
                let (jump_v, jump_u) = (inv_se.component_mul(&t), inv_bt.component_mul(&rt));
                for c in 0..3 {
                    dy.row_mut::<N>(K_V + c)[tension_lane] += jump_v[c];
                    dy.row_mut::<N>(K_U + c)[tension_lane] += jump_u[c];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leg() -> LegModel {
        let tendons = [(0.0, 0.145), (std::f64::consts::PI, 0.145), (1.0, 0.08)];
        let leg = crate::design::test_leg(&tendons);
        LegModel::new(&leg, Vector3::new(0.5, 0.0, -9.81))
    }

    /// A start that bends the leg strongly, two of its tendons taut.
    fn bent_start() -> LegStart {
        let mut tensions = [0.0; MAX_TENDONS];
        tensions[0] = 3.2;
        tensions[2] = 0.4;
        LegStart {
            base: Frame::identity(),
            u0: Vector3::new(0.3, 6.0, -0.1),
            v0: Vector3::new(1e-5, 0.0, 0.99992),
            tensions,
        }
    }

    /// The AVX2 path (where the CPU has it) and the portable path give bitwise equal tips
    /// and sensitivities: the lane count and instruction set change nothing numerically.
    #[test]
    fn every_code_path_gives_bitwise_identical_results() {
        let (model, start) = (leg(), bent_start());
        let run = |portable: bool, directions: usize| {
            let mut sc = LegScratch::new();
            let mut end = LegEnd::zeros();
            let mut sens = LegSensitivities::new(directions);
            let (starts, ends) = (std::slice::from_ref(&start), std::slice::from_mut(&mut end));
            let sens_slice = Some(std::slice::from_mut(&mut sens));
            if portable {
                integrate_dispatch(&model, starts, &mut sc.0, ends, sens_slice, None)
            } else {
                integrate(&model, starts, &mut sc.0, ends, sens_slice, None)
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

    /// Three different legs, leg i pulled by tendon i (one taut, the others slack).
    fn three_starts() -> [LegStart; 3] {
        let start = |i: usize| {
            let mut tensions = [0.0; MAX_TENDONS];
            tensions[i % 3] = 1.5 + i as f64;
            let angle = 2.0 * i as f64;
            LegStart {
                base: Frame {
                    position: Vector3::new(0.01 * i as f64, -0.02, 0.003),
                    rotation: *nalgebra::Rotation3::from_euler_angles(0.1, -0.2 * i as f64, angle)
                        .matrix(),
                },
                u0: Vector3::new(0.3 - i as f64, 6.0 * i as f64 - 4.0, -0.1),
                v0: Vector3::new(1e-5 * i as f64, 0.0, 0.99992),
                tensions,
            }
        };
        [start(0), start(1), start(2)]
    }

    /// Three different legs integrated together, one per SIMD lane, give bitwise the tips
    /// and sensitivities of three separate integrations, with and without AVX2; a
    /// slack tendon in one lane and a taut one in another exercise the per-lane selects.
    #[test]
    fn legs_in_lanes_are_bitwise_the_single_legs() {
        let model = leg();
        let starts = three_starts();
        for directions in [0, 6, 9] {
            let single = |i: usize| {
                let (mut end, mut sens) = (LegEnd::zeros(), LegSensitivities::new(directions));
                let mut sc = LegScratch::new();
                if directions == 0 {
                    integrate_leg(&model, &starts[i], &mut sc, &mut end, None).unwrap();
                } else {
                    integrate_leg_with_sensitivities(
                        &model, &starts[i], &mut sc, &mut end, &mut sens, None,
                    )
                    .unwrap();
                }
                (end, sens.d)
            };
            for portable in [false, true] {
                let mut sc = LegsScratch::new();
                let mut ends = [LegEnd::zeros(); 3];
                let mut sens: Vec<_> = (0..3).map(|_| LegSensitivities::new(directions)).collect();
                let sens_slice = (directions > 0).then_some(&mut sens[..]);
                if portable {
                    integrate_dispatch(&model, &starts, &mut sc.0, &mut ends, sens_slice, None)
                } else {
                    integrate_legs(&model, &starts, &mut sc, &mut ends, sens_slice, None)
                }
                .unwrap();
                for i in 0..3 {
                    let (end, d) = single(i);
                    assert_eq!(ends[i], end, "leg {i}, {directions} directions");
                    assert_eq!(sens[i].d, d, "leg {i}, {directions} directions");
                }
            }
        }
    }

    /// Selected tension directions (the boundary skips slack tendons') are bitwise the
    /// full set's, each in its own lane; a lane beyond a leg's selection stays zero even
    /// after an integration on the same buffers that used it.
    #[test]
    fn selected_tension_directions_are_bitwise_those_of_the_full_set() {
        let (model, starts) = (leg(), three_starts());
        let mut sc = LegsScratch::new();
        let mut ends = [LegEnd::zeros(); 3];
        let mut full: Vec<_> = (0..3).map(|_| LegSensitivities::new(9)).collect();
        integrate_legs(&model, &starts, &mut sc, &mut ends, Some(&mut full), None).unwrap();
        let mut sens = full.clone();
        let selections = [0b100, 0b011, 0b000];
        for (s, bits) in sens.iter_mut().zip(selections) {
            s.select_tensions(bits, 8);
        }
        let mut selected_ends = [LegEnd::zeros(); 3];
        integrate_legs(
            &model,
            &starts,
            &mut sc,
            &mut selected_ends,
            Some(&mut sens),
            None,
        )
        .unwrap();
        assert_eq!(selected_ends, ends);
        for (leg, bits) in selections.into_iter().enumerate() {
            let (s, f) = (&sens[leg], &full[leg]);
            assert_eq!(s.d[..6], f.d[..6], "leg {leg}: strain directions");
            for k in 0..3 {
                let expected = (bits & (1 << k) != 0).then_some(&f.d[6 + k]);
                assert_eq!(s.tension(k), expected, "leg {leg}, tendon {k}");
            }
            let used = 6 + bits.count_ones() as usize;
            for (lane, d) in s.d[used..8].iter().enumerate() {
                assert_eq!(
                    *d,
                    LegEnd::zeros(),
                    "leg {leg}, lane {} not zero",
                    used + lane
                );
            }
        }
    }

    /// The frames at the disks come from partial steps of the same method: the shape has
    /// a frame at the base and at each disk, the last one is the tip itself, the tip and
    /// its sensitivities do not depend on whether a shape is recorded, and every disk is
    /// within 1e-7 L of a 16× finer integration's (a tendon ends at 0.08 m, an interval
    /// end, and the disks at 11.15 mm spacing fall between the steps of 13.0–13.3 mm).
    #[test]
    fn disk_frames_come_from_partial_steps_as_accurate_as_the_steps() {
        let (model, start) = (leg(), bent_start());
        let run = |model: &LegModel, shape: bool| {
            let mut sc = LegScratch::new();
            let mut end = LegEnd::zeros();
            let mut sens = LegSensitivities::new(9);
            let mut s = LegShape::with_capacity(model.n_disks);
            let shape = shape.then_some(&mut s);
            integrate_leg_with_sensitivities(model, &start, &mut sc, &mut end, &mut sens, shape)
                .unwrap();
            (end, sens.d, s)
        };
        let (end, d, shape) = run(&model, true);
        let (bare_end, bare_d, _) = run(&model, false);
        assert_eq!((end, d), (bare_end, bare_d));
        let arcs: Vec<f64> = (0..=model.n_disks)
            .map(|j| if j == 0 { 0.0 } else { model.disk_arc(j) })
            .collect();
        assert_eq!(shape.arcs, arcs);
        assert_eq!(shape.positions.last(), Some(&end.p));
        assert_eq!(shape.rotations.last(), Some(&end.r));
        let mut fine = model.clone();
        for iv in &mut fine.intervals {
            iv.steps *= 16;
        }
        let (_, _, reference) = run(&fine, true);
        for (j, (p, q)) in shape.positions.iter().zip(&reference.positions).enumerate() {
            let error = (p - q).norm();
            assert!(
                error < 1e-7 * model.length,
                "disk {j}: {error:.2e} m from the fine integration"
            );
        }
    }

    /// A shape recording only the knots gets the same knots as one recording the disks
    /// (one per step end after the base, at [`LegModel::knot_arcs`], the last the tip),
    /// no frames, and the same tip and sensitivities, bit for bit.
    #[test]
    fn knots_are_the_step_ends_whatever_else_is_recorded() {
        let (model, start) = (leg(), bent_start());
        let run = |detail: ShapeDetail| {
            let mut sc = LegScratch::new();
            let mut end = LegEnd::zeros();
            let mut sens = LegSensitivities::new(9);
            let mut s = LegShape::new(&model);
            s.detail = detail;
            integrate_leg_with_sensitivities(
                &model,
                &start,
                &mut sc,
                &mut end,
                &mut sens,
                Some(&mut s),
            )
            .unwrap();
            (end, sens.d, s)
        };
        let (end, d, disks) = run(ShapeDetail::Disks);
        let (knots_end, knots_d, knots) = run(ShapeDetail::Knots);
        assert_eq!((end, d), (knots_end, knots_d));
        assert_eq!(knots.knots, disks.knots);
        assert!(knots.positions.is_empty() && knots.arcs.is_empty() && knots.rotations.is_empty());
        let steps: usize = model.intervals.iter().map(|iv| iv.steps).sum();
        assert_eq!(knots.knots.len(), steps + 1);
        assert_eq!(model.knot_arcs().count(), steps + 1);
        assert_eq!(knots.knots.last(), Some(&end.p));
        assert_eq!(knots.knots[0], start.base.position);
        // A knot at a disk's arc is that disk's position.
        for (k, arc) in model.knot_arcs().enumerate() {
            if let Some(j) = disks.arcs.iter().position(|&a| (a - arc).abs() < 1e-12) {
                assert_eq!(knots.knots[k], disks.positions[j], "knot {k} at {arc} m");
            }
        }
    }
}
