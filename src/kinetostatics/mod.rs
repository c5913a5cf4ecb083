//! Forward and inverse kinetostatics of the parallel robot by shooting (MODEL.md §3):
//! Newton on the boundary residual b with the exact Jacobian (or the finite-difference
//! baseline), globalized by the dogleg trust region of [`crate::newton`].
//!
//! [`Solver`] holds the model and every buffer; its methods check their inputs and
//! delegate to the files of this module, one concept each:
//! - `state.rs`: [`RobotState`] (a configuration, also a warm start) and [`Solution`];
//! - `checks.rs`: the input checks of every solve;
//! - `home.rs`: the straight home guess of a cold start (MODEL.md §9, [`home_guess`]);
//! - `target.rs`: the target of one solve and which Newton takes it;
//! - `shooting.rs`: FK and square IK as a [`crate::newton::NonlinearSystem`] (unknowns,
//!   row weights, step limit at tendon kinks, rotation retraction);
//! - `predictor.rs`: the predictor of warm starts: tangent (MODEL.md §4) or extrapolated
//!   from the last solutions on a smooth path;
//! - `continuation.rs`: cold starts, ramps of actuation or pose, and the homotopy from
//!   the unloaded home;
//! - `redundant.rs`: IK of the 9-DoF design by the Gauss–Newton driver
//!   [`crate::newton::solve_with_line_search`] with a least-norm step rule
//!   ([`Redundancy`]); `within_limits.rs` its QP step rule (cargo feature `qp`);
//!   `least_change.rs` the equality-constrained least-change step both rules solve.
//!
//! A cold start uses the straight home guess of MODEL.md §9 (legs straight, strains
//! consistent with tensions from a constant-curvature estimate, γ never 0); if that fails
//! for FK, the actuation is ramped from zero in steps (continuation).
//!
//! Every solve takes its [`NewtonSettings`] from [`Solver::settings`], or per call from
//! the `*_with` variants ([`Solver::solve_fk_with`], [`Solver::solve_ik_with`],
//! [`Solver::solve_ik_newton_with`]), which leave the solver's defaults alone.

mod checks;
mod continuation;
mod home;
mod least_change;
mod predictor;
mod redundant;
mod shooting;
mod state;
mod target;
#[cfg(feature = "qp")]
mod within_limits;

use std::time::Instant;

use nalgebra::{DMatrix, DVector, Rotation3};

use crate::analysis::{
    Analysis, AnalysisSettings, Conditioning, analyze_blocks, condition_blocks_with,
};
use crate::boundary::{
    BoundaryJacobians, BoundaryScratch, FiniteDifference, boundary_derivatives,
    gamma_columns_to_linear,
};
use crate::design::Tdpcr;
use crate::error::{Error, SolveError};
use crate::input_range::{diverged_if_non_finite, parallel_robot_inputs};
use crate::model::{Model, Pose};
use crate::newton::{NewtonReport, NewtonScratch, NewtonSettings};
use crate::rod::tendon::TendonUnknown;
use crate::rod::{LegShape, ShapeDetail, Wrench};
use checks::{
    actuation_violations, analysis_violations, check_init, checked_wrench, pose_violations,
};
use predictor::LastSolve;
use target::{Target, solve_target};

pub use home::{home_guess, straight_leg_pose, straight_leg_translations};
use redundant::LastLeastNorm;
pub use redundant::{Objective, Redundancy};
pub use shooting::BEYOND_LIMITS_MARGIN;
pub use state::{RobotState, Solution};

/// The tendon variable Newton iterates on (states report γ): the piecewise-linear ζ
/// converges in a few steps where γ stalls near the taut/slack boundary.
pub(crate) const SOLVER_TENDON_UNKNOWN: TendonUnknown = TendonUnknown::Linear;

/// How the Newton Jacobian is obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JacobianMethod {
    /// Exact, from forward sensitivities.
    Exact,
    /// The paper's finite-difference baseline.
    FiniteDifference(FiniteDifference),
}

/// Solves FK and IK problems of one design; holds every buffer.
#[derive(Debug, Clone)]
pub struct Solver {
    model: Model,
    boundary: BoundaryScratch,
    blocks: BoundaryJacobians,
    newton: NewtonScratch,
    /// Default Newton settings of every solve (tolerance on ‖b‖₂ in test units, see
    /// [`NewtonSettings::tolerance`]; iteration limit); the `*_with` methods take others per call.
    pub settings: NewtonSettings,
    /// Jacobian used by Newton.
    pub jacobian: JacobianMethod,
    /// How IK of the 9-DoF design chooses among its solutions (least-norm steps by
    /// default; [`Redundancy::WithinLimits`] keeps q within its limits).
    pub redundancy: Redundancy,
    /// Whether a warm square solve (FK, or IK of the 6-DoF design, with the exact
    /// Jacobian) whose guess is this solver's last solution (a path step, as for the
    /// tangent predictor) starts from the last solve's Jacobian instead of evaluating its
    /// own (see [`NewtonScratch::reuse_jacobian_once`]): such a step then costs residual
    /// evaluations only, while that Jacobian still contracts. On by default; such steps
    /// then differ from a fresh solver's within the tolerance. Solves from any other
    /// guess, and cold ones, do not depend on earlier solves (except as
    /// [`Solver::reuse_blocks_for_ik`] asks). For the IK of the 9-DoF design see
    /// [`Solver::reuse_least_norm_factorization`].
    pub reuse_jacobian: bool,
    /// Whether a least-norm IK of the 9-DoF design ([`Redundancy::LeastNorm`]) whose
    /// guess is this solver's last least-norm solution starts with chord steps on the
    /// latest factorized least-norm step (of the last Jacobian such a run evaluated;
    /// taken while each contracts the residual
    /// tenfold, then fresh Jacobians) instead of a Jacobian at its start. Off by default:
    /// such a step costs residuals only (a 1 mm step back and forth: 4 residuals, no
    /// Jacobian; BENCHMARKS.md), but the redundant IK has a set of solutions and chord
    /// steps on an earlier Jacobian land on it elsewhere than steps from the start's:
    /// along the 30 steps of 1 mm of `tests/redundant_path.rs` q ends up to 2.3e-5 m from
    /// the Gauss–Newton reference (every solution converged, the pose held). Going back
    /// and forth between two poses, q then repeats exactly, where steps from each start's
    /// Jacobian creep by ≈ 4e-8 m per cycle. The within-limits IK always starts with a
    /// fresh Jacobian.
    pub reuse_least_norm_factorization: bool,
    /// Whether the least-norm IK of the 9-DoF design ([`Redundancy::LeastNorm`]) takes
    /// every step with the Jacobian at its iterate (Gauss–Newton, chord steps only near
    /// the solution: the default before 2026-11-28) instead of all with the Jacobian at
    /// its start. Off by default: from the start's Jacobian the solution is the one point
    /// of the solution set in the start's least-change directions, whatever the iterates,
    /// at one Jacobian a run (a warm 1 mm step: 1 Jacobian and 4 residuals instead of 2
    /// and 2, 0.75× the time); Gauss–Newton steps land elsewhere on the set, 2.9e-9 m in
    /// q after one 1 mm step and 4.2e-7 m after the 30 of `tests/redundant_path.rs`
    /// (BENCHMARKS.md). Where a chord step from the start contracts the residual less than
    /// tenfold, a default run also goes on with Gauss–Newton steps.
    pub least_norm_gauss_newton: bool,
    /// Whether the IK of the 9-DoF design takes one-sided steps across tendon kinks
    /// (MODEL.md "Least-norm steps across tendon kinks"): the default least-norm steps
    /// from the first run on, and any run (Gauss–Newton least-norm, within the limits)
    /// whose line search fails on a step across a tendon's kink once more so (a run that
    /// fails elsewhere, e.g. at the actuation limits, is not retried). On by default:
    /// warm 1 mm steps around circles of 10–50 mm radius failed where a tendon pair
    /// passes through both-slack (92 of 2 646 least-norm steps, 60 within the limits;
    /// none with it), and the least-norm steps took 5–9× fewer evaluations;
    /// within-limits and Gauss–Newton runs that converge are unchanged bit for bit. The
    /// workspace sweep keeps the retry only ([`WorkspaceSettings::one_sided_kinks`]).
    ///
    /// [`WorkspaceSettings::one_sided_kinks`]: crate::workspace::WorkspaceSettings::one_sided_kinks
    pub across_kinks: bool,
    /// Whether a Newton step of FK or square IK that takes a tendon across its kink
    /// (ζ = 0) is solved again with that tendon's column of the side it goes to (the
    /// one-sided slope the step takes, anchored at the kink; no integration): taut into
    /// slack the slack column, slack into taut the taut column kept from the exact
    /// Jacobian. After the first rejected step of such a model the run goes on
    /// two-sided (MODEL.md "One-sided columns at the kink"). Without it such a step
    /// follows the old side's slope beyond the kink, overshoots, and the trust region
    /// collapses before the pair crawls across (BENCHMARKS.md "Heavy solves").
    pub one_sided_kinks: bool,
    /// Whether a square IK (the 6-DoF designs) stops as soon as its solution is certainly
    /// beyond the actuation limits, with
    /// [`StopReason::BeyondActuationLimits`](crate::error::StopReason::BeyondActuationLimits):
    /// once an iteration reduced ‖F‖ tenfold, when some q_i plus its Newton step lies
    /// beyond its limit by more than [`BEYOND_LIMITS_MARGIN`] × the step's largest
    /// |δq_j| (the rest of the way, which shrinks tenfold or more per iteration from
    /// there) and the step takes no tendon across its kink. For callers that reject such
    /// solutions anyway (the workspace sweep ends its rays there either way); off by
    /// default.
    pub stop_beyond_limits: bool,
    /// The one-sided columns ([`Solver::one_sided_kinks`]) the last FK or square IK used.
    one_sided_columns_used: usize,
    /// The work of every Newton run of the current call, converged or not (a direct
    /// attempt before its fallback, a prediction before the guess, the steps of a
    /// continuation, halved ones included): the counts of the call's report.
    work: NewtonReport,
    /// The slack tendons' taut-side columns at the last exact Jacobian of a square solve.
    taut_columns: shooting::TautColumns,
    /// The last converged square solve whose factorized Jacobian is still in `newton`
    /// (the predictor of warm starts from it), with the solutions before it on its path.
    last: Option<LastSolve>,
    /// Which square system (FK: true, IK: false) the Jacobian in `newton` belongs to,
    /// if its last run converged on the unscaled model.
    newton_system: Option<bool>,
    /// Whether [`Solver::reuse_blocks_for_ik`] put an analysis' blocks in `newton` for
    /// the next IK solve, whatever its guess.
    seeded: bool,
    /// The last converged least-norm IK of the redundant design and its factorized step
    /// ([`Solver::reuse_least_norm_factorization`]).
    least_norm: Option<LastLeastNorm>,
    /// Whether warm starts on smooth paths may start from the extrapolated last
    /// solutions (`predictor`); off within continuations.
    extrapolate_starts: bool,
    /// Whether the redundant IK may evaluate a full step's trial point with its Jacobian
    /// ([`crate::newton::LineSearchSystem::speculate_jacobians`]); off in
    /// [`Solver::solve_ik_newton_with`] (the workspace sweep's path steps).
    speculate_trials: bool,
    /// Whether every solve's expected last residual is prepared for the analysis of its
    /// solution ([`Solver::prepare_for_analysis`]).
    prepare_for_analysis: bool,
    /// q and y_u (γ) of the last converged IK of the redundant design on the solver's
    /// own model: a run from it starts with the Jacobian its last residual prepared.
    last_redundant: Option<(Vec<f64>, Vec<f64>)>,
    /// The residual of the analyses' block evaluations (kept: an analysis allocates
    /// nothing).
    analysis_residual: DVector<f64>,
}

impl Solver {
    /// A solver for `design`, validated first.
    ///
    /// # Errors
    /// [`Error::Design`] listing every value of the design that breaks its rule
    /// ([`Tdpcr::validate`]).
    pub fn new(design: &Tdpcr) -> Result<Self, Error> {
        design.validate("design")?;
        let model = Model::new(design);
        let settings = NewtonSettings::default();
        let n = model.n_residuals();
        Ok(Self {
            boundary: BoundaryScratch::new(&model),
            blocks: BoundaryJacobians::new(&model),
            newton: NewtonScratch::new(n, settings.max_iterations),
            taut_columns: shooting::TautColumns::new(&model),
            model,
            settings,
            jacobian: JacobianMethod::Exact,
            redundancy: Redundancy::LeastNorm,
            reuse_jacobian: true,
            reuse_least_norm_factorization: false,
            least_norm_gauss_newton: false,
            across_kinks: true,
            one_sided_kinks: false,
            stop_beyond_limits: false,
            one_sided_columns_used: 0,
            work: NewtonReport::none(),
            last: None,
            newton_system: None,
            seeded: false,
            least_norm: None,
            extrapolate_starts: true,
            speculate_trials: true,
            prepare_for_analysis: false,
            last_redundant: None,
            analysis_residual: DVector::zeros(n),
        })
    }

    /// Whether each solve's last residual, where Newton expects it to be its last, is
    /// evaluated with the legs' sensitivities and knots (and what else the solver
    /// records, [`Solver::record_shape_detail`]) for the analysis of the solution that
    /// follows ([`Solver::analyze`], [`Solver::blocks_at`] recording at most that): that
    /// analysis then reuses the integration instead of repeating it.
    /// For callers that analyze every solution within the actuation limits (the
    /// workspace sweep); off by default, since a solve not followed by that analysis
    /// pays a Jacobian's integration for its last residual. Solutions, iterates and
    /// analyses are bit for bit those without; the reports count such a residual as
    /// one. (A warm IK of the redundant design from this solver's last solution always
    /// prepares its last residual for the next such solve: see [`Solver::solve_ik`].)
    pub fn prepare_for_analysis(&mut self, on: bool) {
        self.prepare_for_analysis = on;
    }

    /// The robot model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The total wrench on the platform: its weight plus `extra`.
    pub fn total_wrench(&self, extra: &Wrench) -> Wrench {
        Wrench {
            force: self.model.platform_weight + extra.force,
            moment: extra.moment,
        }
    }

    /// Forward kinetostatics: the pose and leg states for actuation `q` under the platform
    /// weight plus `extra` (world frame, at the platform centre).
    ///
    /// # Errors
    /// [`Error::Input`] for a q of the wrong length or non-finite values;
    /// [`Error::Solve`] with residual norm and iterations if Newton fails.
    pub fn solve_fk(
        &mut self,
        q: &[f64],
        extra: &Wrench,
        init: Option<&RobotState>,
    ) -> Result<Solution, Error> {
        let settings = self.settings;
        self.solve_fk_with(q, extra, init, &settings)
    }

    /// [`Solver::solve_fk`] with `settings` for this call instead of [`Solver::settings`].
    ///
    /// # Errors
    /// As [`Solver::solve_fk`]; [`Error::Input`] also for settings that break their
    /// rules ([`NewtonSettings::check`]).
    pub fn solve_fk_with(
        &mut self,
        q: &[f64],
        extra: &Wrench,
        init: Option<&RobotState>,
        settings: &NewtonSettings,
    ) -> Result<Solution, Error> {
        let v = actuation_violations(self, q);
        let wrench = checked_wrench(self, v, extra, init, settings)?;
        let start = Instant::now();
        self.work = NewtonReport::none();
        let result = match init {
            Some(s) => {
                let target = Target::Forward(q.to_vec());
                let direct = solve_target(self, None, settings, &target, &wrench, s.clone());
                // A warm start too far away: follow the straight line in q from it.
                direct.or_else(|e| {
                    continuation::ramp_actuation(self, settings, s.clone(), q, &wrench)
                        .map_err(|_| e)
                })
            }
            None => continuation::cold_fk(self, settings, q, &wrench),
        };
        finish(result, &self.work, start, extra, &self.model, Some(q))
    }

    /// Inverse kinetostatics: actuation and leg states that hold the platform at `pose`
    /// under its weight plus `extra`. The 6-DoF design solves the square system; the 9-DoF
    /// design resolves its redundancy as [`Solver::redundancy`] says: by default the
    /// least-norm change of q (every step with the start's Jacobian, or Gauss–Newton
    /// steps with [`Solver::least_norm_gauss_newton`]), or with
    /// [`Redundancy::WithinLimits`] a QP step that keeps q within its limits
    /// ([`crate::redundancy`]). A warm IK of the 9-DoF design from this solver's last
    /// solution (a path step, as a controller or `trajectory` makes; not towards a
    /// reference, nor with [`Solver::reuse_least_norm_factorization`]) evaluates the
    /// residual it expects to be its last with the legs' sensitivities, so that the next
    /// step from its solution starts without integrating its first Jacobian: the same
    /// solutions and counts, one residual's integration less per such step.
    ///
    /// # Errors
    /// As [`Solver::solve_fk`].
    pub fn solve_ik(
        &mut self,
        pose: &Pose,
        extra: &Wrench,
        init: Option<&RobotState>,
    ) -> Result<Solution, Error> {
        let settings = self.settings;
        self.solve_ik_with(pose, extra, init, &settings)
    }

    /// [`Solver::solve_ik`] with `settings` for this call instead of [`Solver::settings`].
    ///
    /// # Errors
    /// As [`Solver::solve_fk_with`].
    pub fn solve_ik_with(
        &mut self,
        pose: &Pose,
        extra: &Wrench,
        init: Option<&RobotState>,
        settings: &NewtonSettings,
    ) -> Result<Solution, Error> {
        let wrench = checked_wrench(self, pose_violations(pose), extra, init, settings)?;
        let start = Instant::now();
        self.work = NewtonReport::none();
        let guess = match init {
            Some(s) => at_pose(s, pose),
            None if self.model.pairs == 1 => {
                let result = continuation::cold_ik(self, settings, pose, &wrench);
                return finish(result, &self.work, start, extra, &self.model, None);
            }
            None => self.home_guess(pose, &straight_leg_translations(&self.model, pose), &wrench),
        };
        let direct = solve_target(
            self,
            None,
            settings,
            &Target::Inverse(*pose),
            &wrench,
            guess,
        );
        let result = match (direct, init) {
            // A warm start too far away: follow the pose path from it.
            (Err(e), Some(s)) if s.q.len() == self.model.n_actuators() => {
                continuation::ramp_pose(self, settings, s.clone(), pose, &wrench).map_err(|_| e)
            }
            (r, _) => r,
        };
        finish(result, &self.work, start, extra, &self.model, None)
    }

    /// IK by one Newton run from `guess`, without the continuation fallback of
    /// [`Solver::solve_ik`]: for path following, where a step that fails ends the path
    /// (the workspace rays of MODEL.md §6) and a fallback would only cost time. The
    /// guess's pose is replaced by `pose`; its q and y_u are the start.
    ///
    /// # Errors
    /// As [`Solver::solve_ik`].
    pub fn solve_ik_newton(
        &mut self,
        pose: &Pose,
        extra: &Wrench,
        guess: &RobotState,
    ) -> Result<Solution, Error> {
        let settings = self.settings;
        self.solve_ik_newton_with(pose, extra, guess, &settings)
    }

    /// [`Solver::solve_ik_newton`] with `settings` for this call (e.g. a
    /// [`crate::newton::ProgressCheck`] for one path step) instead of [`Solver::settings`].
    ///
    /// # Errors
    /// As [`Solver::solve_fk_with`].
    pub fn solve_ik_newton_with(
        &mut self,
        pose: &Pose,
        extra: &Wrench,
        guess: &RobotState,
        settings: &NewtonSettings,
    ) -> Result<Solution, Error> {
        let v = pose_violations(pose);
        let wrench = checked_wrench(self, v, extra, Some(guess), settings)?;
        let start = Instant::now();
        self.work = NewtonReport::none();
        let guess = at_pose(guess, pose);
        // Path steps fail or end at their trial point often enough that evaluating it with
        // its Jacobian cost the 9-DoF sweeps 8 % more Jacobians and 11 % more time.
        self.speculate_trials = false;
        let result = solve_target(
            self,
            None,
            settings,
            &Target::Inverse(*pose),
            &wrench,
            guess,
        );
        self.speculate_trials = true;
        finish(result, &self.work, start, extra, &self.model, None)
    }

    /// How many one-sided kink columns ([`Solver::one_sided_kinks`]) the system offered
    /// the Newton steps of the last FK or square IK (converged or not; counted also where
    /// the one-sided system was singular, or its step was rejected, and the run went on
    /// two-sided): 0 means the run was the same as without them.
    pub fn one_sided_columns_used(&self) -> usize {
        self.one_sided_columns_used
    }

    /// Keeps the last solution for the next warm solve's tangent prediction, but none
    /// before it for an extrapolated start.
    fn keep_last_solution_only(&mut self) {
        if let Some(last) = self.last.as_mut() {
            let older = last.path.len().saturating_sub(1);
            last.path.drain(..older);
        }
    }

    /// Forgets the last solve's Jacobian, so the next solve neither reuses it
    /// ([`Solver::reuse_jacobian`], [`Solver::reuse_blocks_for_ik`]) nor predicts from
    /// it: its result then depends only on its guess and target, bit for bit as a fresh
    /// solver's (e.g. each ray of a parallel sweep, whatever the worker solved before),
    /// and so does its work (the legs' last integration is forgotten too, see
    /// [`BoundaryScratch::forget_integration`]).
    pub fn forget_jacobian(&mut self) {
        self.boundary.forget_integration();
        self.newton_system = None;
        self.seeded = false;
        self.last = None;
        self.least_norm = None;
        self.last_redundant = None;
        self.newton.forget_jacobian();
    }

    /// Lets the next IK solve of the 6-DoF design start from the exact blocks of the last
    /// [`Solver::blocks_at`] (or [`Solver::analyze`], [`Solver::condition`]) at `state`
    /// instead of the last Newton run's Jacobian ([`Solver::reuse_jacobian`]): after an
    /// analysis of each solution on a path, the next step's chord steps use the
    /// Jacobian at the last solution. Does nothing for the redundant design (its IK is
    /// not square), with [`Solver::reuse_jacobian`] off, or where a tendon unknown of
    /// `state` is 0 (the blocks' γ columns then say nothing about the solver's ζ).
    pub fn reuse_blocks_for_ik(&mut self, state: &RobotState) {
        if !self.reuses_ik_jacobians() {
            return;
        }
        let (blocks, model) = (&self.blocks, &self.model);
        self.newton
            .set_last_jacobian(|jac| ik_jacobian(model, blocks, &state.y_u, jac));
        self.newton_system = Some(false);
        self.seeded = true;
    }

    /// The Jacobian of the IK of the 6-DoF design in the solver's unknowns, \[B_q B_u\]
    /// with ζ tendon columns, from the last [`Solver::blocks_at`] (or
    /// [`Solver::analyze`], [`Solver::condition`]) at `state`, written into `jac`
    /// (n × n, n = [`Model::n_residuals`]): what [`Solver::reuse_blocks_for_ik`] starts
    /// from, for callers that combine several (e.g. extrapolate them along a path and
    /// hand the result to [`Solver::reuse_ik_jacobian`]). False (and `jac` partly
    /// written) where a tendon unknown of `state` is 0, or for the redundant design.
    pub fn ik_jacobian_from_blocks(&self, state: &RobotState, jac: &mut DMatrix<f64>) -> bool {
        self.model.pairs == 1 && ik_jacobian(&self.model, &self.blocks, &state.y_u, jac)
    }

    /// Lets the next IK solve of the 6-DoF design start from `jac` (the IK Jacobian in
    /// the solver's unknowns, as [`Solver::ik_jacobian_from_blocks`] writes it, or an
    /// approximation of it at the next solution): its first step is a chord step with
    /// it, kept only if it contracts the residual tenfold. Conditions as
    /// [`Solver::reuse_blocks_for_ik`].
    pub fn reuse_ik_jacobian(&mut self, jac: &DMatrix<f64>) {
        if !self.reuses_ik_jacobians() {
            return;
        }
        self.newton.set_last_jacobian(|own| {
            own.copy_from(jac);
            crate::linalg::all_finite(jac.as_slice())
        });
        self.newton_system = Some(false);
        self.seeded = true;
    }

    /// Whether IK solves may start from a given Jacobian: the square IK (6-DoF design)
    /// with the exact Jacobian and [`Solver::reuse_jacobian`] on.
    fn reuses_ik_jacobians(&self) -> bool {
        self.model.pairs == 1 && self.reuse_jacobian && self.jacobian == JacobianMethod::Exact
    }

    /// Checks that a warm start (e.g. read from a file before a run of solves) fits this
    /// solver's design: its sizes and finite values.
    ///
    /// # Errors
    /// [`Error::Input`] naming `init.q`, `init.y_u` or `init`.
    pub fn check_warm_start(&self, state: &RobotState) -> Result<(), Error> {
        let mut v = crate::error::Violations::default();
        check_init(self, &mut v, Some(state));
        if v.0.is_empty() {
            Ok(())
        } else {
            Err(Error::Input(v))
        }
    }

    /// The straight home guess for platform `pose` and actuation `q`.
    pub fn home_guess(&self, pose: &Pose, q: &[f64], wrench: &Wrench) -> RobotState {
        home_guess(&self.model, pose, q, wrench)
    }

    /// ‖b‖₂ after each iteration of the last Newton run (the last continuation step when
    /// a solve needed continuation).
    pub fn residual_history(&self) -> &[f64] {
        self.newton.residual_history()
    }

    /// The residual and exact blocks at a state (for analysis and tests).
    ///
    /// # Errors
    /// [`SolveError::NonFinite`] if a leg integration blows up.
    pub fn blocks_at(
        &mut self,
        state: &RobotState,
        extra: &Wrench,
    ) -> Result<(DVector<f64>, &BoundaryJacobians), SolveError> {
        let mut r = DVector::zeros(self.model.n_residuals());
        self.blocks_into(state, extra, &mut r)?;
        Ok((r, &self.blocks))
    }

    /// [`Solver::blocks_at`] with the residual written into `r` (n_residuals long).
    fn blocks_into(
        &mut self,
        state: &RobotState,
        extra: &Wrench,
        r: &mut DVector<f64>,
    ) -> Result<(), SolveError> {
        let wrench = self.total_wrench(extra);
        let pose = state.pose();
        let p = state.boundary_point(&pose, &wrench);
        self.last = None;
        boundary_derivatives(&self.model, &mut self.boundary, &p, r, &mut self.blocks)
    }

    /// Starts (or stops) keeping every leg's frames at its disks from each exact-Jacobian
    /// evaluation ([`BoundaryScratch::record_shapes`]): after [`Solver::blocks_at`],
    /// [`Solver::analyze`] or [`Solver::condition`] of a state, [`Solver::shapes`] are
    /// that state's.
    pub fn record_shapes(&mut self, on: bool) {
        self.boundary.record_shapes(&self.model, on);
    }

    /// Starts recording `detail` of every leg's backbone in each exact-Jacobian
    /// evaluation, or stops recording (`None`): [`Solver::record_shapes`] records the
    /// disks' frames, [`ShapeDetail::Knots`] only the positions at the integration's step
    /// ends, which cost nothing more than the evaluation
    /// ([`BoundaryScratch::record`]).
    pub fn record_shape_detail(&mut self, detail: Option<ShapeDetail>) {
        self.boundary.record(&self.model, detail);
    }

    /// The legs' frames at their disks (or their knots) from the last exact-Jacobian
    /// evaluation, when recording ([`Solver::record_shape_detail`]).
    pub fn shapes(&self) -> Option<&[LegShape; 3]> {
        self.boundary.shapes()
    }

    /// The work of every Newton run of the last FK or IK call, converged or not (a
    /// converged call's report carries the same counts; a failed call's error only those
    /// of the run it reports).
    pub fn last_call_work(&self) -> &NewtonReport {
        &self.work
    }

    /// [`Solver::analyze`] of a solution under the wrench it was solved under.
    ///
    /// # Errors
    /// As [`Solver::analyze`].
    pub fn analyze_solution(
        &mut self,
        solution: &Solution,
        settings: &AnalysisSettings,
    ) -> Result<Analysis, Error> {
        let extra = solution.extra;
        self.analyze(&solution.state, &extra, settings)
    }

    /// Analyses `state` (normally a solution of [`Solver::solve_fk`] or
    /// [`Solver::solve_ik`]) under the platform weight plus `extra`: evaluates the exact
    /// blocks there (three leg integrations with sensitivities) and calls
    /// [`analyze_blocks`].
    ///
    /// # Errors
    /// [`Error::Input`] for a state or wrench of the wrong size or with non-finite
    /// values, or thresholds that are negative or not finite; [`Error::Solve`] if a leg
    /// integration blows up; [`Error::Analysis`] as [`analyze_blocks`].
    pub fn analyze(
        &mut self,
        state: &RobotState,
        extra: &Wrench,
        settings: &AnalysisSettings,
    ) -> Result<Analysis, Error> {
        self.analysis_blocks(state, extra, settings)?;
        Ok(analyze_blocks(
            &self.model,
            &self.blocks,
            &state.y_u,
            settings,
        )?)
    }

    /// The [`Conditioning`] part of [`Solver::analyze`] (the same values, bit for bit)
    /// by the leaner [`condition_blocks`](crate::analysis::condition_blocks): what the
    /// workspace sweep keeps of each point.
    ///
    /// # Errors
    /// As [`Solver::analyze`] (see
    /// [`condition_blocks`](crate::analysis::condition_blocks)).
    pub fn condition(
        &mut self,
        state: &RobotState,
        extra: &Wrench,
        settings: &AnalysisSettings,
    ) -> Result<Conditioning, Error> {
        self.condition_with(state, extra, settings, true)
    }

    /// [`Solver::condition`] (`complete`) or the workspace sweep's per-point part of it
    /// (NaN for the unit-scaled rconds of the three block matrices, which
    /// [`crate::analysis::scaled_block_rconds`] of [`Solver::last_blocks`] gives, and
    /// only the sign part of the stability; `analysis::condition_blocks_with`).
    pub(crate) fn condition_with(
        &mut self,
        state: &RobotState,
        extra: &Wrench,
        settings: &AnalysisSettings,
        complete: bool,
    ) -> Result<Conditioning, Error> {
        self.analysis_blocks(state, extra, settings)?;
        Ok(condition_blocks_with(
            &self.model,
            &self.blocks,
            &state.y_u,
            settings,
            complete,
        )?)
    }

    /// ∂b/∂τ of tendon `k` of leg `leg` (its taut column in the solver's ζ) at `state`,
    /// slack there, into `column`: from the last exact evaluation, which must be at
    /// `state` (an analysis of it) with the slack tendons' tension directions kept (as
    /// the one-sided kinks keep them); false where they were not.
    pub(crate) fn taut_column_at(
        &self,
        state: &RobotState,
        leg: usize,
        k: usize,
        column: nalgebra::DVectorViewMut<f64>,
    ) -> bool {
        if !self.boundary.keeps_slack_tension_directions() {
            return false;
        }
        let wrench = self.total_wrench(&Wrench::default());
        let pose = state.pose();
        let p = state.boundary_point(&pose, &wrench);
        crate::boundary::taut_tension_column(&self.model, &self.boundary, &p, leg, k, column);
        true
    }

    /// The exact blocks of the last [`Solver::blocks_at`] (and of every analysis).
    pub(crate) fn last_blocks(&self) -> &BoundaryJacobians {
        &self.blocks
    }

    /// The checks of [`Solver::analyze`]'s inputs, then the exact blocks at `state`.
    fn analysis_blocks(
        &mut self,
        state: &RobotState,
        extra: &Wrench,
        settings: &AnalysisSettings,
    ) -> Result<(), Error> {
        let v = analysis_violations(self, state, extra, settings);
        if !v.0.is_empty() {
            return Err(Error::Input(v));
        }
        let mut r = std::mem::take(&mut self.analysis_residual);
        let evaluated = self.blocks_into(state, extra, &mut r);
        self.analysis_residual = r;
        evaluated?;
        Ok(())
    }
}

/// \[B_q B_u\] of `blocks` (γ tendon columns, at `y_u` in γ) with the tendon columns
/// converted to the solver's ζ, into `jac`; false where some γ is 0.
fn ik_jacobian(
    model: &Model,
    blocks: &BoundaryJacobians,
    y_u: &[f64],
    jac: &mut DMatrix<f64>,
) -> bool {
    let nq = model.n_actuators();
    jac.columns_mut(0, nq).copy_from(&blocks.b_q);
    jac.columns_mut(nq, blocks.b_u.ncols())
        .copy_from(&blocks.b_u);
    gamma_columns_to_linear(model, y_u, jac, nq)
}

/// `state` moved to `pose` (its q and y_u kept): the start of an IK from a warm start.
fn at_pose(state: &RobotState, pose: &Pose) -> RobotState {
    RobotState {
        position: pose.position.into(),
        rotvec: Rotation3::from_matrix_unchecked(pose.rotation)
            .scaled_axis()
            .into(),
        ..state.clone()
    }
}

/// The solution of a solve that began at `start`, under the external wrench `extra`, its
/// report's counts those of all the call's `work`; a non-finite state as
/// [`SolveError::Diverged`], naming the actuation `q` (FK) and the load against their
/// scales in `model`. An error keeps the iterations and stop reason of the run it reports
/// (for a cold solve whose fallbacks fail too, the direct attempt).
fn finish(
    result: Result<(RobotState, NewtonReport), SolveError>,
    work: &NewtonReport,
    start: Instant,
    extra: &Wrench,
    model: &Model,
    q: Option<&[f64]>,
) -> Result<Solution, Error> {
    let (state, report) =
        result.map_err(|e| diverged_if_non_finite(e, || parallel_robot_inputs(model, q, extra)))?;
    let report = NewtonReport {
        iterations: work.iterations,
        residual_evaluations: work.residual_evaluations,
        jacobian_evaluations: work.jacobian_evaluations,
        ..report
    };
    Ok(Solution {
        state,
        report,
        solve_time_us: start.elapsed().as_secs_f64() * 1e6,
        extra: *extra,
    })
}
