//! The boundary residual b of the parallel robot (MODEL.md §3, eq. 16) and its Jacobian
//! blocks B_x, B_q, B_w, B_u (§4): exact from the legs' forward sensitivities (§5), or by
//! the paper's finite-difference baseline (perturb one unknown, re-integrate only the leg
//! it affects).
//!
//! Row order (30 rows for the 6-DoF design, 36 for the 9-DoF design):
//! 0..3 platform force balance Σ F_i − f_ext \[N\]; 3..6 platform moment balance
//! Σ (R_ee ᵇp_ci) × F_i − l_ext \[N·m\]; then per leg i, at 6 + i (6 + n_t):
//! coupling position p_ee + R_ee ᵇp_ci − p_i(L) − R_i(L) L_c e_z (3, m), zero joint moment
//! m_i⁺(L) + c_i × F_i (3, N·m), tendon lengths (n_t, m). F_i = n_i⁺(L) is the force the
//! leg transmits beyond its tip.
//!
//! Column order: x_ee = (δp, δθ) with R_ee ← exp(δθ^) R_ee; q per leg \[q_b per pair, q_t\];
//! w = (f_ext, l_ext); y_u per leg [γ (n_t), u(0) (3), v(0) (3)].

use nalgebra::{DMatrix, DVector, Vector3};

use crate::design::MAX_TENDONS;
use crate::error::SolveError;
use crate::model::{Model, Pose};
use crate::rod::rhs::hat;
use crate::rod::tendon::TendonUnknown;
use crate::rod::{
    LegEnd, LegScratch, LegSensitivities, LegShape, LegStart, LegsScratch, ShapeDetail, Wrench,
    integrate_leg, integrate_legs,
};

/// Where the residual is evaluated: platform pose, actuation, external wrench (world
/// frame, at the platform centre, including the platform weight) and leg unknowns.
#[derive(Debug, Clone, Copy)]
pub struct BoundaryPoint<'a> {
    /// Platform pose x_ee.
    pub pose: &'a Pose,
    /// Actuation q (6 or 9 values) \[m\].
    pub q: &'a [f64],
    /// Total external wrench w on the platform.
    pub wrench: &'a Wrench,
    /// Leg unknowns y_u (3 (6 + n_t) values).
    pub y_u: &'a [f64],
    /// What the tendon entries of y_u are (γ of the paper, or the solver's linear ζ).
    pub tendon_unknown: TendonUnknown,
}

/// The Jacobian blocks of b (MODEL.md eq. 17).
#[derive(Debug, Clone, PartialEq)]
pub struct BoundaryJacobians {
    /// ∂b/∂x_ee (rows × 6).
    pub b_x: DMatrix<f64>,
    /// ∂b/∂q (rows × 6 or 9).
    pub b_q: DMatrix<f64>,
    /// ∂b/∂w (rows × 6), constant.
    pub b_w: DMatrix<f64>,
    /// ∂b/∂y_u (rows × 3 (6 + n_t)).
    pub b_u: DMatrix<f64>,
}

impl BoundaryJacobians {
    /// Zero blocks sized for `model`.
    pub fn new(model: &Model) -> Self {
        let m = model.n_residuals();
        Self {
            b_x: DMatrix::zeros(m, 6),
            b_q: DMatrix::zeros(m, model.n_actuators()),
            b_w: DMatrix::zeros(m, 6),
            b_u: DMatrix::zeros(m, 3 * model.n_leg_unknowns()),
        }
    }
}

/// How the finite-difference baseline differentiates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FiniteDifference {
    /// (b(x + h) − b(x)) / h: one re-integration per leg unknown.
    Forward,
    /// (b(x + h) − b(x − h)) / 2h: two re-integrations per leg unknown.
    Central,
}

/// Buffers for residual and Jacobian evaluations of one model.
#[derive(Debug, Clone)]
pub struct BoundaryScratch {
    /// The three legs together (residual and exact Jacobian).
    group: Box<LegsScratch>,
    /// One leg at a time (the finite-difference baseline re-integrates one leg).
    legs: Box<[LegScratch; 3]>,
    sens: Box<[LegSensitivities; 3]>,
    ends: [LegEnd; 3],
    starts: [LegStart; 3],
    trial: DVector<f64>,
    base: DVector<f64>,
    /// Every leg's frames at its disks (or only its knots) from the last exact
    /// evaluation, when recording.
    shapes: Option<Box<[LegShape; 3]>>,
    /// What exact evaluations record into `shapes`, if anything (the buffers are kept
    /// allocated while paused).
    recording: Option<ShapeDetail>,
    /// Evaluations so far: [`boundary_residual`] calls, [`boundary_derivatives`] calls
    /// (the tests' independent count of a solve's work).
    evaluations: [usize; 2],
    /// Whether [`boundary_derivatives`] integrates the tension directions of slack
    /// tendons too ([`BoundaryScratch::keep_slack_tension_directions`]).
    slack_tension_directions: bool,
    /// What the buffers' last integration with sensitivities was computed at, while
    /// `ends`, `sens` (and `shapes`, if it recorded them) still hold it.
    integrated: Option<ExactIntegration>,
    /// Integrations of the three legs so far (with or without sensitivities).
    integrations: usize,
}

/// The inputs of an integration of the legs with sensitivities: an evaluation with the
/// same ones reuses it ([`boundary_derivatives`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct ExactIntegration {
    starts: [LegStart; 3],
    /// The tension directions of each leg (bit k: tendon k) and the directions in all.
    tensions: [u32; 3],
    directions: usize,
    /// What it recorded of the legs' shapes, if anything.
    shapes: Option<ShapeDetail>,
}

impl ExactIntegration {
    /// Whether an evaluation that needs `wanted` can reuse this integration.
    fn serves(&self, wanted: &Self) -> bool {
        self.starts == wanted.starts
            && self.tensions == wanted.tensions
            && self.directions == wanted.directions
            && self.shapes >= wanted.shapes
    }
}

impl BoundaryScratch {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let nd = 6 + model.n_tendons();
        Self {
            group: Box::new(LegsScratch::new()),
            legs: Box::new([LegScratch::new(), LegScratch::new(), LegScratch::new()]),
            sens: Box::new([
                LegSensitivities::new(nd),
                LegSensitivities::new(nd),
                LegSensitivities::new(nd),
            ]),
            ends: [LegEnd::zeros(); 3],
            starts: [leg_start(
                model,
                0,
                &vec![0.0; model.n_actuators()],
                &vec![0.0; 3 * model.n_leg_unknowns()],
                TendonUnknown::Gamma,
            ); 3],
            trial: DVector::zeros(model.n_residuals()),
            base: DVector::zeros(model.n_residuals()),
            shapes: None,
            recording: None,
            evaluations: [0; 2],
            slack_tension_directions: false,
            integrated: None,
            integrations: 0,
        }
    }

    /// Forgets the last integration with sensitivities: the next evaluation integrates
    /// the legs whatever its point (a benchmark of one evaluation at a fixed point, or
    /// the work of fresh buffers).
    pub fn forget_integration(&mut self) {
        self.integrated = None;
    }

    /// How many times these buffers integrated the three legs, with or without
    /// sensitivities ([`boundary_residual`], [`boundary_derivatives`] and
    /// [`boundary_residual_with_derivatives`] integrate at most once per call; an
    /// evaluation at the leg starts of the last integration with sensitivities reuses it).
    pub fn integrations(&self) -> usize {
        self.integrations
    }

    /// Whether exact evaluations ([`boundary_derivatives`]) also integrate the tension
    /// direction of every slack tendon (off by default). A slack tendon's column of B_u
    /// does not use it (dτ/dζ = 0 there: only its length row, dΘ/dζ, is not zero), so by
    /// default it is skipped; the one-sided Newton step of a slack tendon that the step
    /// makes taut needs it
    /// ([`Solver::one_sided_kinks`](crate::kinetostatics::Solver::one_sided_kinks)).
    /// Measured (criterion, the 9-DoF design, two of each leg's four tendons slack): the
    /// exact Jacobian 72 → 57 µs (10 → 8 lanes of tangents).
    pub fn keep_slack_tension_directions(&mut self, on: bool) {
        self.slack_tension_directions = on;
    }

    /// Whether [`BoundaryScratch::keep_slack_tension_directions`] is on.
    pub(crate) fn keeps_slack_tension_directions(&self) -> bool {
        self.slack_tension_directions
    }

    /// How many residuals ([`boundary_residual`]) and exact Jacobians
    /// ([`boundary_derivatives`]) these buffers have evaluated (read by the tests that
    /// check the solvers' reports).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn evaluations(&self) -> [usize; 2] {
        self.evaluations
    }

    /// Adds the evaluations of `other` (buffers a solve used beside these, e.g. for a
    /// check that must leave these buffers' last integration as it was) to these
    /// buffers' tally ([`BoundaryScratch::evaluations`]).
    pub(crate) fn count_evaluations_of(&mut self, other: &BoundaryScratch) {
        self.evaluations[0] += other.evaluations[0];
        self.evaluations[1] += other.evaluations[1];
    }

    /// Starts (or stops) recording every leg's frames at its disks in each exact
    /// evaluation ([`boundary_derivatives`]), at the cost of a partial step (primal only)
    /// to each disk inside an integration step, about one residual evaluation for the
    /// bundled 13-disk legs (the workspace sweep records only the knots: see
    /// [`CollisionChecker::clear_by_knots`](crate::workspace::collision::CollisionChecker::clear_by_knots)).
    /// Turning it off keeps the buffers, so switching it on and off around single
    /// evaluations allocates nothing.
    pub fn record_shapes(&mut self, model: &Model, on: bool) {
        self.record(model, on.then_some(ShapeDetail::Disks));
    }

    /// Starts recording `detail` of every leg's backbone in each exact evaluation
    /// ([`BoundaryScratch::record_shapes`] with [`ShapeDetail::Disks`]; the knots alone
    /// cost nothing more than the evaluation), or stops recording (`None`).
    pub fn record(&mut self, model: &Model, detail: Option<ShapeDetail>) {
        if detail.is_some() {
            self.allocate_shapes(model);
        }
        self.recording = detail;
    }

    /// Allocates the shapes' buffers, once.
    fn allocate_shapes(&mut self, model: &Model) {
        if self.shapes.is_none() {
            let shape = || LegShape::new(&model.leg);
            self.shapes = Some(Box::new([shape(), shape(), shape()]));
        }
    }

    /// The legs' frames at their disks (or only their knots, as recorded) from the last
    /// [`boundary_derivatives`], when recording ([`BoundaryScratch::record`]).
    pub fn shapes(&self) -> Option<&[LegShape; 3]> {
        self.shapes.as_deref().filter(|_| self.recording.is_some())
    }

    /// The leg tips of the last evaluation.
    pub fn leg_ends(&self) -> &[LegEnd; 3] {
        &self.ends
    }
}

/// First row of leg i's block.
fn leg_row(model: &Model, leg: usize) -> usize {
    6 + leg * model.n_leg_unknowns()
}

/// Integration start of leg i at q and its unknowns.
pub fn leg_start(
    model: &Model,
    leg: usize,
    q: &[f64],
    y_u: &[f64],
    tendon: TendonUnknown,
) -> LegStart {
    let nt = model.n_tendons();
    let y = &y_u[leg * model.n_leg_unknowns()..];
    let mut tensions = [0.0; MAX_TENDONS];
    for k in 0..nt {
        tensions[k] = tendon.tension(y[k]);
    }
    LegStart {
        base: model.base_frame(leg, model.translation(leg, q)),
        u0: Vector3::new(y[nt], y[nt + 1], y[nt + 2]),
        v0: Vector3::new(y[nt + 3], y[nt + 4], y[nt + 5]),
        tensions,
    }
}

/// Converts the tendon entries of y_u between two tendon variables, in place.
pub fn convert_tendon_unknowns(
    model: &Model,
    y_u: &mut [f64],
    from: TendonUnknown,
    to: TendonUnknown,
) {
    for i in model.tendon_unknown_indices() {
        y_u[i] = to.from_gamma(from.to_gamma(y_u[i]));
    }
}

/// Converts the tendon columns of ∂b/∂y_u from γ (the paper's, at the leg unknowns
/// `y_u` in γ) to the solver's piecewise-linear ζ = γ|γ| (the taut or slack side of
/// each tendon as at `y_u`): ∂b/∂ζ = ∂b/∂γ / (2|γ|). The columns of y_u start at column
/// `first` of `jac`. Returns false where some γ is 0 or not finite (∂b/∂γ = 0 there
/// says nothing about ∂b/∂ζ); `jac` is then partly converted.
pub fn gamma_columns_to_linear(
    model: &Model,
    y_u: &[f64],
    jac: &mut DMatrix<f64>,
    first: usize,
) -> bool {
    for i in model.tendon_unknown_indices() {
        let dzeta_dgamma = 2.0 * y_u[i].abs();
        if !(dzeta_dgamma > 0.0 && dzeta_dgamma.is_finite()) {
            return false;
        }
        jac.column_mut(first + i).unscale_mut(dzeta_dgamma);
    }
    true
}

/// b from the three leg tips.
fn assemble_residual(model: &Model, p: &BoundaryPoint, ends: &[LegEnd; 3], r: &mut DVector<f64>) {
    let nt = model.n_tendons();
    let lc = model.coupling_offset;
    let mut force = -p.wrench.force;
    let mut moment = -p.wrench.moment;
    for (i, end) in ends.iter().enumerate() {
        let a = p.pose.rotation * model.coupling_points[i];
        force += end.n;
        moment += a.cross(&end.n);
        let tip_axis = end.r.column(2).into_owned();
        let coupling = p.pose.position + a - end.p - tip_axis * lc;
        let joint_moment = end.m - (tip_axis * lc).cross(&end.n);
        let row = leg_row(model, i);
        for c in 0..3 {
            r[row + c] = coupling[c];
            r[row + 3 + c] = joint_moment[c];
        }
        let y = &p.y_u[i * model.n_leg_unknowns()..];
        let displacement = model.tendon_displacements(i, p.q);
        for k in 0..nt {
            let g = y[k];
            let t = p.tendon_unknown;
            r[row + 6 + k] = end.lengths[k] + t.slack(g)
                - (1.0 + t.tension(g) / model.leg.tendon_stiffness) * model.leg.tendon_ends[k]
                - displacement[k];
        }
    }
    for c in 0..3 {
        r[c] = force[c];
        r[3 + c] = moment[c];
    }
}

/// Evaluates b at `p` (three primal leg integrations).
///
/// # Errors
/// [`SolveError::NonFinite`] if a leg integration blows up.
pub fn boundary_residual(
    model: &Model,
    sc: &mut BoundaryScratch,
    p: &BoundaryPoint,
    r: &mut DVector<f64>,
) -> Result<(), SolveError> {
    sc.evaluations[0] += 1;
    for i in 0..3 {
        sc.starts[i] = leg_start(model, i, p.q, p.y_u, p.tendon_unknown);
    }
    // The tips of an integration with sensitivities from the same starts are these (the
    // primal part is the same arithmetic, bit for bit).
    if !sc.integrated.is_some_and(|last| last.starts == sc.starts) {
        sc.integrated = None;
        sc.integrations += 1;
        integrate_legs(
            &model.leg,
            &sc.starts,
            &mut sc.group,
            &mut sc.ends,
            None,
            None,
        )?;
    }
    assemble_residual(model, p, &sc.ends, r);
    Ok(())
}

/// Evaluates b at `p` as [`boundary_residual`] does, but integrates the legs with their
/// sensitivities (and what the buffers record of the shapes, at least the knots if
/// `knots`), so that a
/// [`boundary_derivatives`] at the same leg starts next needs no integration: for a
/// point where the Jacobian is likely asked next (a solve's last iterate before the
/// analysis of its solution, or the start of the next solve from it). Counted as a
/// residual evaluation; it costs an exact one.
///
/// # Errors
/// As [`boundary_residual`].
pub fn boundary_residual_with_derivatives(
    model: &Model,
    sc: &mut BoundaryScratch,
    p: &BoundaryPoint,
    knots: bool,
    r: &mut DVector<f64>,
) -> Result<(), SolveError> {
    sc.evaluations[0] += 1;
    if knots {
        sc.allocate_shapes(model);
    }
    integrate_with_derivatives(model, sc, p, knots)?;
    assemble_residual(model, p, &sc.ends, r);
    Ok(())
}

/// Integrates the legs at `p` with sensitivities into `sc` (the directions
/// [`select_tension_directions`] picks; what the buffers record of the shapes, at least
/// the knots if `knots`), unless the buffers hold such an integration from the same
/// starts already.
fn integrate_with_derivatives(
    model: &Model,
    sc: &mut BoundaryScratch,
    p: &BoundaryPoint,
    knots: bool,
) -> Result<(), SolveError> {
    for i in 0..3 {
        sc.starts[i] = leg_start(model, i, p.q, p.y_u, p.tendon_unknown);
    }
    let (tensions, directions) = select_tension_directions(model, p, sc.slack_tension_directions);
    let recording = sc
        .recording
        .max(knots.then_some(ShapeDetail::Knots))
        .filter(|_| sc.shapes.is_some());
    let wanted = ExactIntegration {
        starts: sc.starts,
        tensions,
        directions,
        shapes: recording,
    };
    if sc.integrated.is_some_and(|last| last.serves(&wanted)) {
        return Ok(());
    }
    sc.integrated = None;
    sc.integrations += 1;
    for (sens, bits) in sc.sens.iter_mut().zip(tensions) {
        sens.select_tensions(bits, directions);
    }
    let shapes = match (&mut sc.shapes, recording) {
        (Some(s), Some(detail)) => {
            for shape in s.iter_mut() {
                shape.detail = detail;
            }
            Some(&mut s[..])
        }
        _ => None,
    };
    integrate_legs(
        &model.leg,
        &sc.starts,
        &mut sc.group,
        &mut sc.ends,
        Some(&mut sc.sens[..]),
        shapes,
    )?;
    sc.integrated = Some(wanted);
    Ok(())
}

/// Evaluates b and its exact Jacobian blocks at `p` (three leg integrations with
/// 6 + n_t sensitivity directions each).
///
/// # Errors
/// As [`boundary_residual`].
pub fn boundary_derivatives(
    model: &Model,
    sc: &mut BoundaryScratch,
    p: &BoundaryPoint,
    r: &mut DVector<f64>,
    jac: &mut BoundaryJacobians,
) -> Result<(), SolveError> {
    sc.evaluations[1] += 1;
    let nt = model.n_tendons();
    let nu = model.n_leg_unknowns();
    integrate_with_derivatives(model, sc, p, false)?;
    assemble_residual(model, p, &sc.ends, r);
    // Through slices: nalgebra's `fill` walks a matrix with its strided iterator, element
    // by element (60 % of this function's own time, perf 2026-11-26).
    jac.b_x.as_mut_slice().fill(0.0);
    jac.b_q.as_mut_slice().fill(0.0);
    jac.b_u.as_mut_slice().fill(0.0);
    fill_b_w(&mut jac.b_w);
    for i in 0..3 {
        let end = &sc.ends[i];
        let row = leg_row(model, i);
        let a = p.pose.rotation * model.coupling_points[i];
        // B_x: δp moves every coupling point; δθ rotates a = R_ee ᵇp_c (δa = δθ × a).
        for c in 0..3 {
            jac.b_x[(row + c, c)] = 1.0;
        }
        let moment_block = hat(&end.n) * hat(&a);
        let coupling_block = -hat(&a);
        for (rr, cc) in (0..3).flat_map(|rr| (0..3).map(move |cc| (rr, cc))) {
            jac.b_x[(3 + rr, 3 + cc)] += moment_block[(rr, cc)];
            jac.b_x[(row + rr, 3 + cc)] = coupling_block[(rr, cc)];
        }
        // B_q: bending pairs shift the tendon length rows; translation moves the leg rigidly.
        let qa = i * (model.pairs + 1);
        for j in 0..model.pairs {
            jac.b_q[(row + 6 + 2 * j, qa + j)] = 1.0;
            jac.b_q[(row + 6 + 2 * j + 1, qa + j)] = -1.0;
        }
        for c in 0..3 {
            jac.b_q[(row + c, qa + model.pairs)] = -model.tangents[i][c];
        }
        // B_u: leg i's unknowns, from its sensitivities.
        let y = &p.y_u[i * nu..];
        for j in 0..nu {
            // (scale, slack slope): γ_k → τ_k direction · dτ/dγ, and dΘ/dγ.
            let (scale, slack) = if j < nt {
                (
                    p.tendon_unknown.tension_derivative(y[j]),
                    p.tendon_unknown.slack_derivative(y[j]),
                )
            } else {
                (1.0, 0.0)
            };
            let column = jac.b_u.column_mut(i * nu + j);
            leg_unknown_column(model, sc, p, i, j, scale, slack, column);
        }
    }
    Ok(())
}

/// The tension directions each leg integrates (bit k: tendon k): those of the tendons
/// whose tension moves with their unknown (dτ/dx ≠ 0), or all with `slack`; and the
/// directions in all, which every leg gets (the legs are integrated together): 6 + the
/// largest count.
fn select_tension_directions(model: &Model, p: &BoundaryPoint, slack: bool) -> ([u32; 3], usize) {
    let (nt, nu) = (model.n_tendons(), model.n_leg_unknowns());
    let selected: [u32; 3] = std::array::from_fn(|i| {
        let y = &p.y_u[i * nu..i * nu + nt];
        (0..nt)
            .filter(|&k| slack || p.tendon_unknown.tension_derivative(y[k]) != 0.0)
            .fold(0, |bits, k| bits | 1 << k)
    });
    let directions = 6 + selected.iter().map(|b| b.count_ones()).max().unwrap_or(0) as usize;
    (selected, directions)
}

/// Writes the nonzero entries of leg `leg`'s unknown `j` column of B_u into `column`
/// from the sensitivities and leg ends of the last [`boundary_derivatives`] evaluation:
/// the sensitivity direction times `scale` (a tendon's dτ/dx, 1 for a strain) and, for a
/// tendon, `slack` (dΘ/dx) in its length row.
#[allow(clippy::too_many_arguments)]
fn leg_unknown_column<S: nalgebra::storage::StorageMut<f64, nalgebra::Dyn>>(
    model: &Model,
    sc: &BoundaryScratch,
    p: &BoundaryPoint,
    leg: usize,
    j: usize,
    scale: f64,
    slack: f64,
    mut column: nalgebra::Matrix<f64, nalgebra::Dyn, nalgebra::U1, S>,
) {
    let nt = model.n_tendons();
    let lc = model.coupling_offset;
    let end = &sc.ends[leg];
    let row = leg_row(model, leg);
    let a = p.pose.rotation * model.coupling_points[leg];
    let tip_axis = end.r.column(2).into_owned();
    let sens = &sc.sens[leg];
    let d = if j < nt {
        match sens.tension(j) {
            Some(d) => d,
            None => {
                // Not integrated: dτ/dx = 0 (checked), only the slack slope remains.
                assert_eq!(
                    scale, 0.0,
                    "tension direction {j} of leg {leg} not integrated"
                );
                column[row + 6 + j] += slack;
                return;
            }
        }
    } else {
        &sens.d[j - nt]
    };
    let dn = d.n * scale;
    let daxis = d.r.column(2) * scale;
    let d_joint = d.m * scale - (daxis * lc).cross(&end.n) - (tip_axis * lc).cross(&dn);
    let d_coupling = -(d.p * scale) - daxis * lc;
    let d_moment = a.cross(&dn);
    for c in 0..3 {
        column[c] = dn[c];
        column[3 + c] = d_moment[c];
        column[row + c] = d_coupling[c];
        column[row + 3 + c] = d_joint[c];
    }
    for k in 0..nt {
        column[row + 6 + k] = d.lengths[k] * scale;
    }
    if j < nt {
        column[row + 6 + j] +=
            slack - model.leg.tendon_ends[j] / model.leg.tendon_stiffness * scale;
    }
}

/// The taut side's column of tendon `k` of leg `leg` (∂b/∂τ_k: the column of a tendon
/// unknown with dτ/dx = 1, dΘ/dx = 0) into `column` (n values, zero elsewhere), from the
/// last [`boundary_derivatives`] evaluation (which integrates every tension direction,
/// slack tendons' too); `p` must be that evaluation's point. The one-sided Newton step of
/// a slack tendon that the step makes taut takes it (MODEL.md "One-sided columns at the
/// kink").
pub(crate) fn taut_tension_column(
    model: &Model,
    sc: &BoundaryScratch,
    p: &BoundaryPoint,
    leg: usize,
    k: usize,
    mut column: nalgebra::DVectorViewMut<f64>,
) {
    column.fill(0.0);
    leg_unknown_column(model, sc, p, leg, k, 1.0, 0.0, column);
}

/// The slack side's column ∂b/∂ζ of tendon `k` of leg `leg` (ζ < 0, the solver's
/// unknown): dΘ/dζ = −1 in its length row, zero elsewhere (a slack tendon's tension, and
/// with it the rod, does not depend on ζ), into `column` (n_residuals long).
pub(crate) fn slack_side_column(model: &Model, leg: usize, k: usize, column: &mut DVector<f64>) {
    column.fill(0.0);
    column[leg_row(model, leg) + 6 + k] = -1.0;
}

/// B_w: the force rows see −f_ext, the moment rows −l_ext.
fn fill_b_w(b_w: &mut DMatrix<f64>) {
    b_w.as_mut_slice().fill(0.0);
    for c in 0..6 {
        b_w[(c, c)] = -1.0;
    }
}

/// Finite-difference steps of the baseline, per kind of unknown: (forward, central).
/// Chosen for the reference design's scales: strains v are ~1e4 times stiffer than u.
pub mod fd_steps {
    /// Platform position \[m\].
    pub const POSITION: (f64, f64) = (1e-8, 1e-6);
    /// Platform rotation \[rad\].
    pub const ROTATION: (f64, f64) = (1e-8, 1e-6);
    /// Actuation \[m\].
    pub const ACTUATION: (f64, f64) = (1e-8, 1e-6);
    /// Wrench \[N, N·m\].
    pub const WRENCH: (f64, f64) = (1e-6, 1e-4);
    /// γ \[√N\], relative to max(1, |γ|).
    pub const GAMMA: (f64, f64) = (1e-7, 1e-5);
    /// u(0) \[1/m\], relative to max(1, |u|).
    pub const BENDING_STRAIN: (f64, f64) = (1e-7, 1e-4);
    /// v(0) \[–\].
    pub const SHEAR_STRAIN: (f64, f64) = (1e-10, 1e-8);
}

/// A copy of a [`BoundaryPoint`]'s inputs that the baseline perturbs.
#[derive(Clone, Copy)]
struct Perturbed {
    pose: Pose,
    q: [f64; 9],
    wrench: Wrench,
    y_u: [f64; 3 * (6 + MAX_TENDONS)],
    nq: usize,
    ny: usize,
    tendon_unknown: TendonUnknown,
}

impl Perturbed {
    fn new(p: &BoundaryPoint) -> Self {
        let mut q = [0.0; 9];
        q[..p.q.len()].copy_from_slice(p.q);
        let mut y_u = [0.0; 3 * (6 + MAX_TENDONS)];
        y_u[..p.y_u.len()].copy_from_slice(p.y_u);
        Self {
            pose: *p.pose,
            q,
            wrench: *p.wrench,
            y_u,
            nq: p.q.len(),
            ny: p.y_u.len(),
            tendon_unknown: p.tendon_unknown,
        }
    }

    fn point(&self) -> BoundaryPoint<'_> {
        BoundaryPoint {
            pose: &self.pose,
            q: &self.q[..self.nq],
            wrench: &self.wrench,
            y_u: &self.y_u[..self.ny],
            tendon_unknown: self.tendon_unknown,
        }
    }
}

/// b at a perturbed point into `sc.trial`, re-integrating only the legs whose start
/// differs from the baseline's.
fn perturbed_residual(
    model: &Model,
    sc: &mut BoundaryScratch,
    pert: &Perturbed,
) -> Result<(), SolveError> {
    let point = pert.point();
    let mut ends = sc.ends;
    for i in 0..3 {
        let start = leg_start(model, i, point.q, point.y_u, point.tendon_unknown);
        if start != sc.starts[i] {
            integrate_leg(&model.leg, &start, &mut sc.legs[i], &mut ends[i], None)?;
        }
    }
    assemble_residual(model, &point, &ends, &mut sc.trial);
    Ok(())
}

/// One finite-difference column: `perturb(copy, h)` shifts one input by h.
fn fd_column(
    model: &Model,
    sc: &mut BoundaryScratch,
    base: &Perturbed,
    method: FiniteDifference,
    h: f64,
    (block, col): (&mut DMatrix<f64>, usize),
    perturb: impl Fn(&mut Perturbed, f64),
) -> Result<(), SolveError> {
    let mut pert = *base;
    perturb(&mut pert, h);
    perturbed_residual(model, sc, &pert)?;
    match method {
        FiniteDifference::Forward => {
            for i in 0..sc.trial.len() {
                block[(i, col)] = (sc.trial[i] - sc.base[i]) / h;
            }
        }
        FiniteDifference::Central => {
            for i in 0..sc.trial.len() {
                block[(i, col)] = sc.trial[i];
            }
            let mut pert = *base;
            perturb(&mut pert, -h);
            perturbed_residual(model, sc, &pert)?;
            for i in 0..sc.trial.len() {
                block[(i, col)] = (block[(i, col)] - sc.trial[i]) / (2.0 * h);
            }
        }
    }
    Ok(())
}

/// The paper's finite-difference Jacobian: one column at a time, re-integrating only the
/// leg the unknown belongs to (pose, bending and wrench columns need no integration).
/// Steps: [`fd_steps`].
///
/// # Errors
/// As [`boundary_residual`].
pub fn boundary_derivatives_fd(
    model: &Model,
    sc: &mut BoundaryScratch,
    p: &BoundaryPoint,
    method: FiniteDifference,
    r: &mut DVector<f64>,
    jac: &mut BoundaryJacobians,
) -> Result<(), SolveError> {
    // The baseline integrates everything itself.
    sc.forget_integration();
    boundary_residual(model, sc, p, r)?;
    sc.base.copy_from(r);
    let pick = |s: (f64, f64)| match method {
        FiniteDifference::Forward => s.0,
        FiniteDifference::Central => s.1,
    };
    let base = Perturbed::new(p);
    for c in 0..3 {
        fd_column(
            model,
            sc,
            &base,
            method,
            pick(fd_steps::POSITION),
            (&mut jac.b_x, c),
            |x, d| x.pose.position[c] += d,
        )?;
        fd_column(
            model,
            sc,
            &base,
            method,
            pick(fd_steps::ROTATION),
            (&mut jac.b_x, 3 + c),
            |x, d| {
                let mut axis = Vector3::zeros();
                axis[c] = d;
                x.pose.rotation = nalgebra::Rotation3::new(axis).matrix() * x.pose.rotation;
            },
        )?;
    }
    for c in 0..p.q.len() {
        fd_column(
            model,
            sc,
            &base,
            method,
            pick(fd_steps::ACTUATION),
            (&mut jac.b_q, c),
            |x, d| x.q[c] += d,
        )?;
    }
    for c in 0..6 {
        fd_column(
            model,
            sc,
            &base,
            method,
            pick(fd_steps::WRENCH),
            (&mut jac.b_w, c),
            |x, d| {
                if c < 3 {
                    x.wrench.force[c] += d;
                } else {
                    x.wrench.moment[c - 3] += d;
                }
            },
        )?;
    }
    let nt = model.n_tendons();
    let nu = model.n_leg_unknowns();
    for c in 0..p.y_u.len() {
        let j = c % nu;
        let scale = p.y_u[c].abs().max(1.0);
        let h = if j < nt {
            pick(fd_steps::GAMMA) * scale
        } else if j < nt + 3 {
            pick(fd_steps::BENDING_STRAIN) * scale
        } else {
            pick(fd_steps::SHEAR_STRAIN)
        };
        fd_column(model, sc, &base, method, h, (&mut jac.b_u, c), |x, d| {
            x.y_u[c] += d
        })?;
    }
    Ok(())
}
