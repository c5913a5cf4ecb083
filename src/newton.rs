//! Newton's method with an exact Jacobian, globalized by Powell's dogleg trust region in
//! scaled variables (as MINPACK's `hybrj`).
//!
//! - Residual rows are weighted by the problem ([`NonlinearSystem::row_weights`]) so that
//!   forces, moments and lengths are comparable in the merit function ½‖W F‖².
//! - Unknowns are scaled by D_j = max over iterations of the weighted Jacobian's column
//!   norms; the trust region is ‖D δ‖ ≤ Δ.
//! - Inside the region the full Newton step J δ = −F is taken, so convergence near the
//!   solution is quadratic. Far from it the step bends towards steepest descent.
//!
//! Stopping: converged when the Euclidean norm of the residual in test units
//! ([`NonlinearSystem::row_scales`], [`test_unit`]: each SI row divided by min(1, its
//! characteristic size)) is at most [`NewtonSettings::tolerance`]; failure when the iteration limit is reached or the trust
//! region shrinks below 1e-14 of ‖D x‖ (no further progress possible in double precision),
//! except that a collapsed trust region with ‖F‖₂ within [`FLOOR_FACTOR`] of the residual's
//! round-off floor ([`round_off_floor`]) is converged too
//! ([`NewtonReport::converged_at_floor`]; MODEL.md "Convergence at the round-off floor").

use nalgebra::{DMatrix, DVector};

use crate::error::{SolveError, StopReason, Violations};
use crate::linalg::DenseLu;

/// A square system of nonlinear equations F(x) = 0 with its exact Jacobian.
pub trait NonlinearSystem {
    /// Number of unknowns (= number of equations).
    fn dim(&self) -> usize;

    /// r = F(x) in SI units.
    ///
    /// # Errors
    /// [`SolveError::NonFinite`] when x leads to a non-finite state; the solver treats it
    /// as a rejected step.
    fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError>;

    /// r = F(x) and jac = ∂F/∂x.
    ///
    /// # Errors
    /// As [`NonlinearSystem::residual`].
    fn residual_and_jacobian(
        &mut self,
        x: &DVector<f64>,
        r: &mut DVector<f64>,
        jac: &mut DMatrix<f64>,
    ) -> Result<(), SolveError>;

    /// Weight of each row in the merit function (about 1 / its typical size).
    fn row_weights(&self, w: &mut DVector<f64>);

    /// The characteristic size c_i of each row relative to [`SI_TEST_SIZES`]
    /// ([`RowScales::relative_to_si_test`]); the convergence test divides row i by
    /// [`test_unit`]`(c_i)`. Default 1: the plain SI test.
    fn row_scales(&self, c: &mut DVector<f64>) {
        c.fill(1.0);
    }

    /// Whether the run may stop at `x` because the solution its iterates converge to is
    /// certainly one the caller would reject: asked once the last iteration reduced ‖F‖
    /// at least tenfold, with `step` the full Newton step from `x` (the rest of the way
    /// to the solution, to first order). Default: never.
    fn beyond_reach(&self, _x: &DVector<f64>, _step: &DVector<f64>) -> bool {
        false
    }

    /// The largest fraction α ∈ (0, 1] of `step` to take from `x` (default 1): a system
    /// with kinks (piecewise-linear unknowns) stops a step where it would cross one.
    fn step_limit(&self, x: &DVector<f64>, step: &DVector<f64>) -> f64 {
        let _ = (x, step);
        1.0
    }

    /// The point reached from `x` by the step `step` expressed in the Jacobian's local
    /// coordinates (default: `x + step`; a rotation unknown overrides this to compose
    /// rotations).
    fn retract(&self, x: &DVector<f64>, step: &DVector<f64>, out: &mut DVector<f64>) {
        out.copy_from(x);
        *out += step;
    }

    /// Whether the driver evaluates a trial it expects to end the run by
    /// [`NonlinearSystem::final_residual`] (default: no).
    fn prepares_final_residual(&self) -> bool {
        false
    }

    /// r = F at a trial `x` that the driver expects to end the run ([`ends_the_run`]):
    /// at `x` or at a point within round-off of it, with what the system's caller asks
    /// for next prepared there (the leg sensitivities of the Jacobian at the solution).
    /// If the run goes on after all, the driver evaluates
    /// [`NonlinearSystem::residual`] at `x` again, so its iterates are those of a run
    /// without. Default: the residual.
    ///
    /// # Errors
    /// As [`NonlinearSystem::residual`].
    fn final_residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
        self.residual(x, r)
    }

    /// For a system with kinks: whether the Newton step `step` from `x` leaves the kink
    /// of unknown `j` (near `x`) for the side whose slope the Jacobian at `x` does not
    /// hold; if so, the raw column ∂F/∂x_j of that side is written into `column` (n
    /// values) and the distance x_j − k_j of `x` from the kink k_j is returned, and
    /// [`solve`] solves the step again with that column, anchored at the kink (the
    /// element of the generalized Jacobian that agrees with the step, as in semismooth
    /// Newton). Default: never.
    fn one_sided_column(
        &self,
        x: &DVector<f64>,
        step: &DVector<f64>,
        j: usize,
        column: &mut DVector<f64>,
    ) -> Option<f64> {
        let _ = (x, step, j, column);
        None
    }
}

/// A run whose trust region collapses is converged when ‖F‖₂ ≤ `FLOOR_FACTOR` × its
/// round-off floor ([`round_off_floor`]): no step representable in double precision can
/// reduce it further, and it is as small as the arithmetic allows.
pub const FLOOR_FACTOR: f64 = 10.0;

/// The round-off floor relaxes the tolerance by at most this factor: a floor above
/// `MAX_FLOOR_RELAXATION × tolerance` (a design whose Jacobian spans hundreds of orders of
/// magnitude, e.g. a tendon stiffness of 1e-250 N found by the fuzz corpus) is no
/// evidence of convergence, and such a solve fails as before.
pub const MAX_FLOOR_RELAXATION: f64 = 1e4;

/// The round-off floor of ‖F‖₂ at `x` (SI): ε ‖(Σ_j |J_ij| |x_j|)_i‖₂ with J = ∂F/∂x. Row i
/// sums terms of about that size (for a rod, the internal force EA·(v − 1) cancels a
/// tension or a load: its round-off is ε·EA), and x itself is known only to ε|x_j|, so F
/// cannot be made reliably smaller.
pub fn round_off_floor(jac: &DMatrix<f64>, x: &DVector<f64>) -> f64 {
    floor_of_rows((0..jac.nrows()).map(|i| {
        (0..jac.ncols())
            .map(|j| jac[(i, j)].abs() * x[j].abs())
            .sum()
    }))
}

/// ε ‖(s_i)_i‖₂ of the row sums s_i = Σ_j |J_ij| |x_j| (already in test units).
fn floor_of_rows(sums: impl Iterator<Item = f64>) -> f64 {
    sums.map(|s| (f64::EPSILON * s).powi(2)).sum::<f64>().sqrt()
}

/// Characteristic sizes of the residual rows of a rod problem (SI), from which the
/// convergence test's units follow ([`test_unit`]): a position or length row is compared
/// with the rod's length L \[m\], a moment row with M* = EI / r_g = √(EI·EA) \[N·m\] (the
/// bending moment at which the backbone's strain at its radius of gyration r_g = √(I/A) is
/// one) and a force row with F* = M*/L \[N\]. All three scale like the robot (L like λ,
/// F* like λ², M* like λ³ when every length is scaled by λ), so a residual in these units
/// means the same relative accuracy at every size; and F*, M* are far above the residual's
/// round-off floor ε·EA (its relative floor is ε·2L/r, 1.3e-13 for the reference leg).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowScales {
    /// L \[m\].
    pub length: f64,
    /// F* = √(EI·EA)/L \[N\].
    pub force: f64,
    /// M* = √(EI·EA) \[N·m\].
    pub moment: f64,
}

/// The row sizes from which on the convergence test is the plain SI one: a leg of 0.1 m,
/// forces of 1 N, moments of 1 N·m. The reference robot (L = 0.145 m, F* = 73 N, M* =
/// 10.6 N·m) is of this size class, so its test is the SI one; a smaller robot is tested
/// in units of its own sizes relative to these (a 1 mm leg: positions 100× stricter).
/// (With 1 m for lengths, the reference design's position rows became 6.9× stricter than
/// the SI test and its Δ = 3 mm map lost 0.3 % of its cells to rays ending at the
/// tightened test: −101 of 35 906 cells on z = −30…0 mm.)
pub const SI_TEST_SIZES: RowScales = RowScales {
    length: 0.1,
    force: 1.0,
    moment: 1.0,
};

impl RowScales {
    /// These sizes divided by [`SI_TEST_SIZES`] (dimensionless): what
    /// [`NonlinearSystem::row_scales`] reports.
    pub fn relative_to_si_test(&self) -> Self {
        Self {
            length: self.length / SI_TEST_SIZES.length,
            force: self.force / SI_TEST_SIZES.force,
            moment: self.moment / SI_TEST_SIZES.moment,
        }
    }

    /// The scales of a rod of `length` L \[m\], bending stiffness EI \[N·m²\] and axial
    /// stiffness EA \[N\].
    pub fn of_rod(length: f64, bending_stiffness: f64, axial_stiffness: f64) -> Self {
        let moment = (bending_stiffness * axial_stiffness).sqrt();
        Self {
            length,
            force: moment / length,
            moment,
        }
    }
}

/// The unit a residual row of relative size `c` (its size divided by [`SI_TEST_SIZES`])
/// is measured in by the convergence test: min(c, 1) (1 where c is not a finite positive
/// number). A row of a robot smaller than 0.1 m, 1 N or 1 N·m is measured relative to its
/// size, so a tolerance means the same relative accuracy at every size below; a larger
/// robot keeps the SI test, never looser, and reaches it up to its round-off floor
/// ([`FLOOR_FACTOR`]).
pub fn test_unit(c: f64) -> f64 {
    if c.is_finite() && c > 0.0 {
        c.min(1.0)
    } else {
        1.0
    }
}

/// Whether a run that can reduce its residual norm `norm` no further is converged at its
/// round-off `floor` (both in test units): `norm` ≤ [`FLOOR_FACTOR`] × floor. A floor far
/// above the `tolerance` means an ill-scaled problem, not round-off: it does not relax the
/// test (nor a NaN or infinite one).
fn floor_accepts(norm: f64, floor: f64, tolerance: f64) -> bool {
    norm.is_finite() && floor <= MAX_FLOOR_RELAXATION * tolerance && norm <= FLOOR_FACTOR * floor
}

/// ‖(r_i / u_i)_i‖₂ for residual `r` and test units `u`.
fn test_norm(r: &DVector<f64>, u: &DVector<f64>) -> f64 {
    r.as_slice()
        .iter()
        .zip(u.as_slice())
        .map(|(a, b)| (a / b) * (a / b))
        .sum::<f64>()
        .sqrt()
}

/// The test units of `system`'s rows, into `u`.
fn fill_test_units(u: &mut DVector<f64>, scales: impl FnOnce(&mut DVector<f64>)) {
    scales(u);
    u.apply(|c| *c = test_unit(*c));
}

/// Stopping and globalization settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonSettings {
    /// Converged when ‖F(x)‖₂ in test units ≤ tolerance: each SI row divided by
    /// min(1, its characteristic size relative to [`SI_TEST_SIZES`]) ([`test_unit`],
    /// [`RowScales`]: the rod's length, M* = √(EI·EA), F* = M*/L), so the SI residual for a
    /// robot of the reference robot's size class (legs ≥ 0.1 m, F*, M* ≥ 1) and the same
    /// relative residual for a smaller one (MODEL.md §9b). A run that can
    /// reduce it no further ([`solve`]: its trust region collapses; [`solve_with_line_search`]:
    /// its line search fails) is also converged when that norm ≤ [`FLOOR_FACTOR`] × its
    /// round-off floor ([`round_off_floor`]), for robots whose floor is above the tolerance
    /// (reported as [`NewtonReport::converged_at_floor`]).
    pub tolerance: f64,
    /// Most Jacobian evaluations (Newton iterations).
    pub max_iterations: usize,
    /// Initial trust radius Δ₀ = factor · ‖D x₀‖ (MINPACK's `factor`).
    pub initial_radius_factor: f64,
    /// Chord steps (the factorized Jacobian reused) are taken while each full step
    /// reduces the weighted residual norm by at least this factor; 0 re-evaluates the
    /// Jacobian at every iterate (plain Newton).
    pub chord_contraction: f64,
    /// An early exit for runs that make no headway (e.g. a path step beyond a fold, where
    /// no solution exists); `None` runs to [`NewtonSettings::max_iterations`].
    pub progress_check: Option<ProgressCheck>,
}

impl NewtonSettings {
    /// Adds every value that breaks its rule to `v`, each field named `{prefix}.{field}`:
    /// tolerance finite and > 0, at least one iteration, a finite positive trust-radius
    /// factor, a chord contraction in [0, 1), and a progress check of at least one
    /// iteration and a finite factor ≥ 1. Every solve of [`crate::kinetostatics::Solver`]
    /// checks its settings so.
    pub fn check(&self, prefix: &str, v: &mut Violations) {
        let field = |name: &str| format!("{prefix}.{name}");
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            v.push(field("tolerance"), self.tolerance, "finite and > 0");
        }
        if self.max_iterations == 0 {
            v.push(field("max_iterations"), 0, ">= 1");
        }
        if !(self.initial_radius_factor.is_finite() && self.initial_radius_factor > 0.0) {
            v.push(
                field("initial_radius_factor"),
                self.initial_radius_factor,
                "finite and > 0",
            );
        }
        if !(0.0..1.0).contains(&self.chord_contraction) {
            v.push(
                field("chord_contraction"),
                self.chord_contraction,
                "in [0, 1)",
            );
        }
        if let Some(p) = self.progress_check {
            if p.iterations == 0 {
                v.push(field("progress_check.iterations"), 0, ">= 1");
            }
            if !(p.factor.is_finite() && p.factor >= 1.0) {
                v.push(field("progress_check.factor"), p.factor, "finite and >= 1");
            }
        }
    }

    /// Whether a run that is not converged must stop before iteration `iterations + 1`:
    /// the reason (iteration limit, or a failed [`ProgressCheck`] given the first residual
    /// norm `first` and the current `norm`), or `None` to go on. Every solver loop that
    /// takes these settings asks this.
    pub fn stop_reason(&self, iterations: usize, first: f64, norm: f64) -> Option<StopReason> {
        if iterations >= self.max_iterations {
            return Some(StopReason::IterationLimit);
        }
        match self.progress_check {
            Some(check) if iterations == check.iterations && first < check.factor * norm => {
                Some(StopReason::TooLittleProgress)
            }
            _ => None,
        }
    }
}

impl NewtonSettings {
    /// How a run ends at the current iterate (work so far in `report`, first residual
    /// norm `first`): converged (‖F‖₂ ≤ tolerance), stopped (see
    /// [`NewtonSettings::stop_reason`]) or `None` to go on. The one stopping rule of
    /// [`solve`] and [`solve_with_line_search`].
    ///
    /// # Errors
    /// The [`SolveError::NotConverged`] the run ends with.
    pub fn outcome(
        &self,
        report: &NewtonReport,
        first: f64,
    ) -> Option<Result<NewtonReport, SolveError>> {
        if report.residual_norm <= self.tolerance {
            return Some(Ok(*report));
        }
        let reason = self.stop_reason(report.iterations, first, report.residual_norm)?;
        Some(Err(self.not_converged(report, reason)))
    }

    /// The error of a run that stops for `reason` after the work in `report`.
    pub fn not_converged(&self, report: &NewtonReport, reason: StopReason) -> SolveError {
        SolveError::NotConverged {
            iterations: report.iterations,
            residual_norm: report.residual_norm,
            tolerance: self.tolerance,
            reason,
        }
    }
}

/// Fail a Newton run after `iterations` iterations unless ‖F‖₂ has fallen by at least
/// `factor` from the start. The run then ends exactly as one limited to `iterations`
/// would; one that passes goes on without repeating them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgressCheck {
    /// Iterations after which the progress is checked.
    pub iterations: usize,
    /// Required reduction ‖F(x₀)‖ / ‖F(x_k)‖ (> 1).
    pub factor: f64,
}

impl Default for NewtonSettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_iterations: 60,
            initial_radius_factor: 100.0,
            chord_contraction: 0.1,
            progress_check: None,
        }
    }
}

/// Work done by one solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonReport {
    /// Newton iterations: accepted steps (a chord step reuses the last Jacobian, so there
    /// can be fewer Jacobian evaluations than iterations).
    pub iterations: usize,
    /// Residual evaluations, including those of rejected trial steps (each Jacobian
    /// evaluation also evaluates the residual and is counted here).
    pub residual_evaluations: usize,
    /// Of those, the evaluations that also computed the Jacobian.
    pub jacobian_evaluations: usize,
    /// Final ‖F(x)‖₂ in the units of the convergence test (SI rows divided by
    /// [`test_unit`]; the SI norm for a robot of metre and newton scale).
    pub residual_norm: f64,
    /// Converged at the round-off floor: the trust region collapsed with ‖F‖₂ above the
    /// tolerance but within [`FLOOR_FACTOR`] of [`round_off_floor`].
    pub converged_at_floor: bool,
}

impl NewtonReport {
    /// No work done yet; the residual norm is NaN until the first evaluation.
    pub(crate) fn none() -> Self {
        Self {
            iterations: 0,
            residual_evaluations: 0,
            jacobian_evaluations: 0,
            residual_norm: f64::NAN,
            converged_at_floor: false,
        }
    }

    /// Adds the counts of `other` (a run that preceded or continued this one); the
    /// residual norm stays this report's.
    pub(crate) fn add_work(&mut self, other: &NewtonReport) {
        self.iterations += other.iterations;
        self.residual_evaluations += other.residual_evaluations;
        self.jacobian_evaluations += other.jacobian_evaluations;
    }

    /// Counts one evaluation of the system: the residual, with the Jacobian if
    /// `with_jacobian` (a system's own tally of the work a run asked of it).
    pub(crate) fn count_evaluation(&mut self, with_jacobian: bool) {
        self.residual_evaluations += 1;
        self.jacobian_evaluations += usize::from(with_jacobian);
    }

    /// The work of a run that ended in `error`: its iterations (from the error) and the
    /// evaluations in `evaluated` (the system's tally of that run); the residual norm
    /// is the error's, NaN if it has none.
    pub(crate) fn of_failed_run(error: &SolveError, evaluated: &NewtonReport) -> Self {
        let (iterations, residual_norm) = match error {
            SolveError::NotConverged {
                iterations,
                residual_norm,
                ..
            } => (*iterations, *residual_norm),
            _ => (0, f64::NAN),
        };
        Self {
            iterations,
            residual_evaluations: evaluated.residual_evaluations,
            jacobian_evaluations: evaluated.jacobian_evaluations,
            residual_norm,
            converged_at_floor: false,
        }
    }
}

/// Buffers for [`solve`] on systems of one size.
#[derive(Debug, Clone)]
pub struct NewtonScratch {
    r: DVector<f64>,
    r_trial: DVector<f64>,
    x_trial: DVector<f64>,
    weights: DVector<f64>,
    /// The unit of each row in the convergence test ([`test_unit`]).
    units: DVector<f64>,
    /// The Jacobian: raw after an evaluation, row-weighted once factored.
    jac: DMatrix<f64>,
    jac_trial: DMatrix<f64>,
    /// The (weighted) two-sided Jacobian while `jac` holds one-sided kink columns.
    jac_two_sided: DMatrix<f64>,
    /// W (J₁ − J) d: the one-sided model's offset from anchoring its columns at their
    /// kinks; non-zero only while `jac` holds one-sided columns built at the current
    /// iterate (cleared at the start of each run and of each iteration).
    kink_shift: DVector<f64>,
    lu: DenseLu,
    /// Whether `jac` is weighted and factored (its LU in `lu`).
    factored: bool,
    /// Whether that factorization succeeded.
    newton_ok: bool,
    /// Whether `jac` (raw, or weighted and factored in `lu` when `factored`) is an exact
    /// Jacobian of the last run's system, at a point of that run, and the run converged.
    reusable: bool,
    /// Whether the next run may start from that Jacobian
    /// ([`NewtonScratch::reuse_jacobian_once`]).
    reuse_next: bool,
    /// The window of the next run's nonmonotone acceptance
    /// ([`NewtonScratch::nonmonotone_once`]; 0: monotone).
    nonmonotone_next: usize,
    /// ‖W F‖² after each accepted iterate of the current run (the nonmonotone test's
    /// reference values).
    merits: Vec<f64>,
    diag: DVector<f64>,
    newton_step: DVector<f64>,
    gradient: DVector<f64>,
    step: DVector<f64>,
    work: DVector<f64>,
    /// Row sums of a Jacobian product (the Cauchy step's J s, the model's W r + W J s).
    rows: DVector<f64>,
    history: Vec<f64>,
    /// ‖F₁‖/‖F₀‖ (test units) of the chord step that started the last run from the
    /// Jacobian of the run before ([`NewtonScratch::reuse_jacobian_once`]), if the last
    /// run started so: the next such step is expected to contract alike
    /// ([`start_from_last_jacobian`]).
    first_chord_ratio: Option<f64>,
}

impl NewtonScratch {
    /// Buffers for n unknowns and up to `max_iterations` iterations of history.
    pub fn new(n: usize, max_iterations: usize) -> Self {
        let v = || DVector::zeros(n);
        Self {
            r: v(),
            r_trial: v(),
            x_trial: v(),
            weights: v(),
            units: v(),
            jac: DMatrix::zeros(n, n),
            jac_trial: DMatrix::zeros(n, n),
            jac_two_sided: DMatrix::zeros(n, n),
            kink_shift: v(),
            lu: DenseLu::new(n),
            factored: false,
            newton_ok: false,
            reusable: false,
            reuse_next: false,
            nonmonotone_next: 0,
            merits: Vec::with_capacity(max_iterations + 1),
            diag: v(),
            newton_step: v(),
            gradient: v(),
            step: v(),
            work: v(),
            rows: v(),
            history: Vec::with_capacity(max_iterations + 1),
            first_chord_ratio: None,
        }
    }

    /// ‖F‖₂ in test units after each accepted iterate of the last solve (the first is the
    /// start).
    pub fn residual_history(&self) -> &[f64] {
        &self.history
    }

    /// The residual F at the final iterate of the last solve (SI).
    pub fn residual(&self) -> &DVector<f64> {
        &self.r
    }

    /// Solves J δ = b with the last factorized Jacobian J of the last solve (the exact
    /// Jacobian at the last point where it was evaluated, near the solution, with the
    /// one-sided kink columns its last Newton step took, if any:
    /// [`NonlinearSystem::one_sided_column`]), in place; `None` if there is none or it was
    /// singular.
    pub fn solve_with_last_jacobian(&self, b: &mut DVector<f64>) -> Option<()> {
        if !(self.factored && self.newton_ok) {
            return None;
        }
        // The factorization is of W J: (W J) δ = W b.
        b.component_mul_assign(&self.weights);
        self.lu.solve_in_place(b);
        b.iter().all(|v| v.is_finite()).then_some(())
    }

    /// Lets the next [`solve`] start from the Jacobian of the last converged run instead
    /// of evaluating one: its first step is a chord step with that Jacobian, taken whole
    /// if it contracts ‖W F‖ by [`NewtonSettings::chord_contraction`] (the run then goes on
    /// with chord steps until one contracts less, as after any Newton step); otherwise
    /// the run starts as it would have (the trial costs one residual evaluation, the
    /// start's residual is evaluated again with the Jacobian). The caller promises that
    /// the next system is the last one with at most its target moved (the same unknowns,
    /// rows and weights). One run only: [`solve`] clears the request.
    pub fn reuse_jacobian_once(&mut self) {
        self.reuse_next = true;
    }

    /// Lets the next [`solve`] accept a trial step by its merit against the largest
    /// ‖W F‖² of the last `window` iterates (the current one included) instead of the
    /// current one alone: a nonmonotone trust region (Deng, Xiao and Zhou 1993; Toint
    /// 1997). A step the monotone test would take is taken and updates the region as
    /// there, so a run without such steps is the monotone run bit for bit; a step only the
    /// window takes updates the radius by its ratio of actual to predicted reduction
    /// measured from the window's reference. Far from a solution a full Newton step that
    /// raises the merit for an iterate or two is then taken instead of shrinking the
    /// region until the model is trusted: the cold FK of the 9-DoF design from straight
    /// legs converges in a median of 17 iterations instead of 27 (BENCHMARKS.md).
    /// `window` ≤ 1 is the monotone test. One run only: [`solve`] clears the request.
    pub fn nonmonotone_once(&mut self, window: usize) {
        self.nonmonotone_next = window;
    }

    /// Replaces the last run's Jacobian by the one `fill` writes into the given n × n
    /// matrix (raw: unweighted, in the system's unknowns; e.g. exact blocks evaluated at
    /// the last solution), for [`NewtonScratch::reuse_jacobian_once`]. If `fill` returns
    /// false there is no Jacobian to reuse.
    pub fn set_last_jacobian(&mut self, fill: impl FnOnce(&mut DMatrix<f64>) -> bool) {
        self.factored = false;
        self.reusable = fill(&mut self.jac);
    }

    /// Forgets the last run's Jacobian, so the next [`solve`] evaluates its own whatever
    /// is requested: a run then depends only on its start.
    pub fn forget_jacobian(&mut self) {
        self.reusable = false;
        self.first_chord_ratio = None;
    }

    /// Size the buffers were made for.
    pub fn dim(&self) -> usize {
        self.r.len()
    }
}

/// ‖D x‖₂ without a temporary.
fn scaled_norm(x: &DVector<f64>, d: &DVector<f64>) -> f64 {
    x.as_slice()
        .iter()
        .zip(d.as_slice())
        .map(|(a, b)| (a * b) * (a * b))
        .sum::<f64>()
        .sqrt()
}

fn weighted_norm_sq(r: &DVector<f64>, w: &DVector<f64>) -> f64 {
    r.as_slice()
        .iter()
        .zip(w.as_slice())
        .map(|(a, b)| (a * b) * (a * b))
        .sum()
}

/// Solves F(x) = 0 from the start in `x` (overwritten with the solution).
///
/// Newton with the exact Jacobian, reused (Shamanskii's chord steps) while it still
/// contracts the residual by [`NewtonSettings::chord_contraction`] per step: near a solution a chord step
/// costs one residual evaluation instead of one Jacobian evaluation and keeps the
/// convergence superlinear. A trial point is evaluated together with its Jacobian when the
/// last step contracted poorly (a fresh Jacobian will be needed there anyway), unless a
/// trial of the same iteration was already rejected or the last iteration's first trial
/// was ([`SKIP_AFTER_REJECTION`]), or the run is stalling ([`STALL_RATIO`]; the Jacobian
/// then follows at the trial once it is accepted), or the trial is a full Newton step
/// from a Jacobian at the iterate that is expected to converge
/// ([`FRESH_STEP_PREDICTION`]; it is then evaluated as a chord trial that ends the run).
/// A chord trial that [`ends_the_run`] predicts to converge is evaluated by
/// [`NonlinearSystem::final_residual`] if the system [prepares
/// one](NonlinearSystem::prepares_final_residual). A run stops early where the system
/// says its solution is [beyond reach](NonlinearSystem::beyond_reach).
///
/// # Errors
/// [`SolveError::NotConverged`] with the residual norm and iteration count (and
/// [`StopReason::BeyondActuationLimits`] for a run stopped beyond reach), or
/// [`SolveError::NonFinite`] if F cannot be evaluated at the start.
///
/// # Panics
/// If `scratch` or `x` do not match `system.dim()` (a programming error).
#[track_caller]
pub fn solve<S: NonlinearSystem>(
    system: &mut S,
    x: &mut DVector<f64>,
    settings: &NewtonSettings,
    sc: &mut NewtonScratch,
) -> Result<NewtonReport, SolveError> {
    let rules = Rules {
        skip_after_rejection: SKIP_AFTER_REJECTION,
        fresh_step_prediction: FRESH_STEP_PREDICTION,
        stall_ratio: STALL_RATIO,
    };
    solve_with_rule(system, x, settings, sc, rules)
}

/// Whether [`solve`] evaluates the first trial of an iteration without its Jacobian when
/// the last iteration's first trial was rejected (the Jacobian is then evaluated at the
/// trial once it is accepted: the same iterates, one residual more). Runs far from a
/// solution reject trials in streaks, each first trial's Jacobian then wasted: over the
/// 30 draws of the cold-FK set, 5 603 → 5 001 Jacobians (9-DoF design) and 2 968 → 2 634
/// (6-DoF), the same solutions and iterations (BENCHMARKS.md).
pub const SKIP_AFTER_REJECTION: bool = true;

/// A full Newton step from a Jacobian evaluated at the iterate x is expected to end the
/// run where ‖F(x)‖² ≤ this × the tolerance (test units): quadratic convergence,
/// ‖F_next‖ ≈ K ‖F‖², with K ≤ 1 / this. Where the run would evaluate that step's trial
/// with its Jacobian (the last step contracted poorly), it evaluates the trial as the
/// run's expected last residual instead ([`NonlinearSystem::final_residual`], or the
/// plain residual where the system prepares none), and the Jacobian at the trial only
/// once it is accepted without converging: the same iterates. (The boundary blocks that
/// the run leaves for the next warm start's predictor are then those of the last
/// iterate's Jacobian, not the solution's: a trajectory's next steps land elsewhere within
/// the tolerance, by at most 1.2e-11 m in q on the peer-style path.)
///
/// Measured (2026-11-27) over the trials so evaluated with their Jacobians: on the
/// reference design's Δ = 3 mm sweep (z ∈ [−30, 0] mm, tolerance 1e-10) those from
/// ‖F‖ ≤ 1e-6 converged in 357 of 370 cases, those from 1e-6 to 1e-5 in 235 of 618; on
/// the design search's coarse sweep of the reference (Δ = 12 mm, tolerance 1e-8) those from
/// ‖F‖ ≤ 1e-5 in 173 of 173, from 1e-5 to 3e-5 in 58 of 72, from 3e-5 to 1e-4 in 27 of 103.
/// A converged trial's Jacobian was wasted (the run ends; the sweep's analysis integrates
/// its own sensitivities); a mispredicted trial costs its prepared residual (about a
/// Jacobian's integration) and a plain one.
pub const FRESH_STEP_PREDICTION: f64 = 0.01;

/// The first trial of an iteration goes without its Jacobian (evaluated at the trial
/// once it is accepted: the same iterates, one residual more) when each of the last two
/// iterations left more than this fraction of ‖F‖ (test units): a run stalling at a
/// positive minimum of its merit, as steps beyond a fold of the IK do until their
/// progress check or iteration limit ends them, rejects many of its trials, and each
/// rejected trial's Jacobian was wasted.
///
/// Measured (2026-11-27, sixteenth session) over the trials so evaluated with their
/// Jacobians in the design search's evaluations of the reference and two drawn candidates
/// (`candidate_cost 2`): after two such iterations 1 363 of 3 182 were accepted (43 %;
/// a deferred Jacobian costs one residual more where accepted and saves the tangents,
/// about four residuals more, where rejected), after one 1 340 of 1 590 and after none
/// 1 793 of 1 853; on the reference's Δ = 3 mm sweep (z ∈ [−30, 0] mm) 76 of 3 422 trials
/// came after two such iterations.
pub const STALL_RATIO: f64 = 0.5;

/// Whether the last iteration of `history` (‖F‖ at the accepted iterates, the start
/// first) reduced ‖F‖ at least tenfold: the run is then converging, and its Newton step
/// is the rest of the way to the solution to first order
/// ([`NonlinearSystem::beyond_reach`]).
fn contracted_tenfold(history: &[f64]) -> bool {
    matches!(history, [.., a, b] if *b <= 0.1 * *a)
}

/// Whether the last two iterations of `history` (‖F‖ at the accepted iterates, the start
/// first) each left more than `ratio` of ‖F‖ ([`STALL_RATIO`]).
fn stalling(history: &[f64], ratio: f64) -> bool {
    match history {
        [.., a, b, c] => *b > ratio * *a && *c > ratio * *b,
        _ => false,
    }
}

/// Whether a full Newton step from a Jacobian at the iterate, whose residual norm is
/// `norm` (test units), is expected to converge ([`FRESH_STEP_PREDICTION`]).
fn fresh_step_ends_the_run(norm: f64, tolerance: f64, prediction: f64) -> bool {
    norm * norm <= prediction * tolerance
}

/// The evaluation rules of a [`solve`] run (tests compare each with its alternative).
#[derive(Debug, Clone, Copy)]
struct Rules {
    /// [`SKIP_AFTER_REJECTION`].
    skip_after_rejection: bool,
    /// [`FRESH_STEP_PREDICTION`] (0: no fresh step's trial is expected to converge).
    fresh_step_prediction: f64,
    /// [`STALL_RATIO`] (∞: no trial's Jacobian is deferred for stalling).
    stall_ratio: f64,
}

/// [`solve`] with its evaluation rules given.
#[track_caller]
fn solve_with_rule<S: NonlinearSystem>(
    system: &mut S,
    x: &mut DVector<f64>,
    settings: &NewtonSettings,
    sc: &mut NewtonScratch,
    rules: Rules,
) -> Result<NewtonReport, SolveError> {
    let n = system.dim();
    assert!(
        sc.dim() == n && x.len() == n,
        "newton::solve: size mismatch"
    );
    system.row_weights(&mut sc.weights);
    fill_test_units(&mut sc.units, |c| system.row_scales(c));
    sc.history.clear();
    // A one-sided model's anchor belongs to the iterate it was built at (a run that
    // converged right after such a step leaves it).
    sc.kink_shift.fill(0.0);
    let warm = std::mem::take(&mut sc.reuse_next) && sc.reusable;
    let expected_ratio = sc.first_chord_ratio.take();
    let window = std::mem::take(&mut sc.nonmonotone_next);
    sc.reusable = false;
    let mut evaluations = 0;
    let mut jacobians = 0;
    let mut iterations = 0;
    let mut radius = 0.0;
    if warm {
        match start_from_last_jacobian(system, x, settings, sc, expected_ratio) {
            LastJacobianStart::Converged(report) => {
                sc.reusable = true;
                return Ok(report);
            }
            LastJacobianStart::Stepped { evaluations: e } => {
                evaluations = e;
                iterations = 1;
                let dx = scaled_norm(x, &sc.diag);
                radius = settings.initial_radius_factor * if dx > 0.0 { dx } else { 1.0 };
            }
            LastJacobianStart::Declined { evaluations: e } => evaluations = e,
        }
    }
    if iterations == 0 {
        sc.history.clear();
        sc.factored = false;
        // Residual and Jacobian together: a start is rarely converged already (trajectory
        // steps never are), and a separate residual would cost a primal integration per
        // solve.
        system.residual_and_jacobian(x, &mut sc.r, &mut sc.jac)?;
        // A start whose residual (or its norm) or Jacobian is NaN or infinite (an input
        // far outside the design's range, e.g. a base translation of 1e308 m) cannot be
        // improved on: say so.
        if !(sc.r.norm().is_finite() && sc.jac.as_slice().iter().all(|v| v.is_finite())) {
            return Err(SolveError::NonFinite {
                stage: "the residual or Jacobian at the start",
            });
        }
        evaluations += 1;
        jacobians += 1;
        sc.history.push(test_norm(&sc.r, &sc.units));
    }
    let mut norm = sc.history[sc.history.len() - 1];
    let mut merit = weighted_norm_sq(&sc.r, &sc.weights);
    sc.merits.clear();
    sc.merits.push(merit);
    let mut successes = 0usize;
    // Whether one-sided kink columns may still be tried: not after one mispredicted.
    let mut one_sided_allowed = true;
    // Whether the next trial is expected to contract well (then its Jacobian is not needed).
    let mut contracting = true;
    // Whether the last iteration's first trial was rejected.
    let mut first_rejected = false;
    loop {
        let report = NewtonReport {
            iterations,
            residual_evaluations: evaluations,
            jacobian_evaluations: jacobians,
            residual_norm: norm,
            converged_at_floor: false,
        };
        if let Some(end) = settings.outcome(&report, sc.history[0]) {
            sc.reusable = end.is_ok();
            return end;
        }
        let fresh = !sc.factored;
        if fresh {
            // A fresh Jacobian: weight its rows, update the column scaling, factor it.
            weight_rows(&mut sc.jac, &sc.weights);
            for j in 0..n {
                let c = sc.jac.column(j).norm();
                let c = if c > 0.0 { c } else { 1.0 };
                sc.diag[j] = if iterations == 0 {
                    c
                } else {
                    sc.diag[j].max(c)
                };
            }
            sc.newton_ok = sc.lu.factor(&sc.jac).is_ok();
            sc.factored = true;
        }
        if iterations == 0 {
            let dx = scaled_norm(x, &sc.diag);
            radius = settings.initial_radius_factor * if dx > 0.0 { dx } else { 1.0 };
        }
        sc.kink_shift.fill(0.0);
        let mut newton_ok = newton_step(sc);
        if newton_ok && contracted_tenfold(&sc.history) && system.beyond_reach(x, &sc.newton_step) {
            return Err(settings.not_converged(&report, StopReason::BeyondActuationLimits));
        }
        // Whether the factored Jacobian holds one-sided columns (the two-sided one is then
        // in `sc.jac_two_sided`).
        let mut one_sided = false;
        if fresh && newton_ok && one_sided_allowed && one_sided_columns(system, x, sc) {
            sc.newton_ok = sc.lu.factor(&sc.jac).is_ok();
            newton_ok = newton_step(sc);
            one_sided = newton_ok;
            if !newton_ok {
                // Singular with the one-sided columns (a pair switching sides: the tendon
                // going slack gets its slack column while its mate, slack too, is about to
                // turn taut): back to the two-sided Jacobian and its step.
                newton_ok = back_to_two_sided(sc);
            }
        }
        let mut dogleg = Dogleg::at(sc, newton_ok);
        // Inner loop: shrink the region until a step is accepted.
        let mut rejected = false;
        // Whether this iteration's first trial went without the Jacobian it would have had.
        let mut deferred = false;
        let (trial_jacobian, full_newton) = loop {
            let mut full_newton = false;
            let Dogleg {
                newton_ok,
                newton_len,
                cauchy_t,
                s_len,
            } = dogleg;
            if newton_ok && newton_len <= radius {
                sc.step.copy_from(&sc.newton_step);
                full_newton = true;
            } else if cauchy_t * s_len >= radius || !newton_ok {
                let scale = if s_len > 0.0 {
                    radius.min(cauchy_t * s_len) / s_len
                } else {
                    0.0
                };
                for j in 0..n {
                    sc.step[j] = -scale * sc.gradient[j] / (sc.diag[j] * sc.diag[j]);
                }
            } else {
                // Dogleg: c + β (N − c) with ‖D(c + β(N − c))‖ = Δ.
                let mut a = 0.0;
                let mut b = 0.0;
                let mut c0 = 0.0;
                for j in 0..n {
                    let cj = -cauchy_t * sc.gradient[j] / (sc.diag[j] * sc.diag[j]);
                    let dj = sc.newton_step[j] - cj;
                    sc.work[j] = cj;
                    a += (sc.diag[j] * dj).powi(2);
                    b += sc.diag[j] * sc.diag[j] * cj * dj;
                    c0 += (sc.diag[j] * cj).powi(2);
                }
                let disc = (b * b - a * (c0 - radius * radius)).max(0.0);
                let beta = ((-b + disc.sqrt()) / a).clamp(0.0, 1.0);
                for j in 0..n {
                    sc.step[j] = sc.work[j] + beta * (sc.newton_step[j] - sc.work[j]);
                }
            }
            let alpha = system.step_limit(x, &sc.step);
            if alpha < 1.0 {
                sc.step.scale_mut(alpha);
                full_newton = false;
            }
            let step_len = scaled_norm(&sc.step, &sc.diag);
            // Predicted reduction of the weighted merit from the linear model.
            // W r + W J step, each row's sum in the order of j (column by column).
            sc.rows.copy_from(&sc.r);
            sc.rows.component_mul_assign(&sc.weights);
            sc.rows += &sc.kink_shift;
            for (j, column) in sc.jac.as_slice().chunks_exact(n).enumerate() {
                let step = sc.step[j];
                for (acc, a) in sc.rows.as_mut_slice().iter_mut().zip(column) {
                    *acc += a * step;
                }
            }
            let predicted_sq: f64 = sc.rows.iter().map(|acc| acc * acc).sum();
            let predicted = merit - predicted_sq;
            system.retract(x, &sc.step, &mut sc.x_trial);
            evaluations += 1;
            // A Jacobian at the trial only where one will be needed and the trial is likely
            // to be accepted (not after a rejection in this iteration, nor, with
            // `skip_after_rejection`, after one at the last iteration's first trial).
            let wanted = !contracting && !rejected;
            // A full Newton step from a Jacobian at x, expected to converge: its Jacobian
            // would be wasted.
            let converging = wanted
                && fresh
                && full_newton
                && fresh_step_ends_the_run(norm, settings.tolerance, rules.fresh_step_prediction);
            // The Jacobian waits for the trial's acceptance after a rejection, where the
            // run is stalling, and is not needed where the trial is expected to converge.
            let waits = (rules.skip_after_rejection && first_rejected)
                || stalling(&sc.history, rules.stall_ratio);
            let with_jacobian = wanted && !waits && !converging;
            if !rejected {
                deferred = wanted && !with_jacobian;
            }
            let last = system.prepares_final_residual()
                && (converging
                    || (!wanted
                        && sc.history.len() >= 2
                        && ends_the_run(
                            norm,
                            sc.history[sc.history.len() - 2],
                            settings.tolerance,
                        )));
            let evaluated = if with_jacobian {
                jacobians += 1;
                system.residual_and_jacobian(&sc.x_trial, &mut sc.r_trial, &mut sc.jac_trial)
            } else if last {
                let (e, count) = expected_last_residual(system, sc, settings.tolerance);
                evaluations += count - 1;
                e
            } else {
                system.residual(&sc.x_trial, &mut sc.r_trial)
            };
            let actual = match evaluated {
                Ok(()) if sc.r_trial.as_slice().iter().all(|v| v.is_finite()) => {
                    merit - weighted_norm_sq(&sc.r_trial, &sc.weights)
                }
                _ => f64::NEG_INFINITY,
            };
            let ratio = if predicted > 0.0 {
                actual / predicted
            } else {
                -1.0
            };
            // The acceptance test's reduction, measured from the largest merit of the
            // window (the current one if monotone).
            let reference = sc
                .merits
                .iter()
                .rev()
                .take(window)
                .fold(merit, |a, &b| a.max(b));
            let accepted_reduction = actual + (reference - merit);
            let acceptance_ratio = if predicted > 0.0 {
                accepted_reduction / predicted
            } else {
                -1.0
            };
            // A step the monotone test takes updates the region as there; one only the
            // window takes, by its own ratio.
            let ratio = if ratio > 1e-4 && actual > 0.0 {
                ratio
            } else {
                acceptance_ratio
            };
            // MINPACK's update: halve on a poor step; expand to twice the step after a
            // good one or after two acceptable ones in a row, and (ours) to four times
            // after a run of very good ones: the region then recovers in half the
            // iterations after a collapse (a tendon pair switching sides: 16 -> 12).
            if ratio < 0.1 {
                successes = 0;
                radius = 0.5 * radius.min(step_len);
            } else {
                successes += 1;
                if ratio >= 0.5 || successes > 1 {
                    let grow = if ratio > 0.9 && successes > 1 {
                        4.0
                    } else {
                        2.0
                    };
                    radius = radius.max(grow * step_len);
                }
            }
            if acceptance_ratio > 1e-4 && accepted_reduction > 0.0 {
                x.copy_from(&sc.x_trial);
                break (with_jacobian, full_newton);
            }
            // A rejected step whose residual is already within tolerance still counts.
            if actual.is_finite() && test_norm(&sc.r_trial, &sc.units) <= settings.tolerance {
                x.copy_from(&sc.x_trial);
                break (with_jacobian, full_newton);
            }
            rejected = true;
            if one_sided {
                // The one-sided model mispredicted (a shorter step may not reach the kink
                // any more): on with the two-sided Jacobian and the shrunk region.
                let ok = back_to_two_sided(sc);
                dogleg = Dogleg::at(sc, ok);
                one_sided = false;
                one_sided_allowed = false;
            }
            if radius <= 1e-14 * scaled_norm(x, &sc.diag).max(1e-300) {
                // The factored Jacobian is row-weighted: unweight it for the floor, in the
                // test's units.
                for i in 0..n {
                    let w = sc.weights[i] * sc.units[i];
                    for j in 0..n {
                        sc.jac_trial[(i, j)] = sc.jac[(i, j)] / w;
                    }
                }
                let floor = round_off_floor(&sc.jac_trial, x);
                if floor_accepts(norm, floor, settings.tolerance) {
                    sc.reusable = true;
                    return Ok(NewtonReport {
                        converged_at_floor: true,
                        ..report
                    });
                }
                return Err(settings.not_converged(&report, StopReason::TrustRegionCollapsed));
            }
        };
        iterations += 1;
        first_rejected = rejected;
        sc.r.copy_from(&sc.r_trial);
        norm = test_norm(&sc.r, &sc.units);
        sc.history.push(norm);
        let new_merit = weighted_norm_sq(&sc.r, &sc.weights);
        contracting = full_newton && new_merit <= settings.chord_contraction.powi(2) * merit;
        // The first trial, accepted without the Jacobian it would have had: evaluated
        // below, as it would have been with it (not a chord step).
        let deferred_accepted = deferred && !rejected;
        merit = new_merit;
        sc.merits.push(merit);
        if norm <= settings.tolerance {
            continue; // converged: reported at the top of the loop, no Jacobian needed
        }
        if trial_jacobian {
            std::mem::swap(&mut sc.jac, &mut sc.jac_trial);
            sc.factored = false;
        } else if !contracting || deferred_accepted {
            evaluations += 1;
            jacobians += 1;
            system.residual_and_jacobian(x, &mut sc.r, &mut sc.jac)?;
            sc.factored = false;
        }
        // Otherwise a chord step: the factorized Jacobian is kept.
    }
}

/// The pieces of the dogleg step at the current iterate for the factored Jacobian; the
/// gradient g = (W J)ᵀ W r goes into `sc.gradient`.
#[derive(Debug, Clone, Copy)]
struct Dogleg {
    /// Whether there is a Newton step (in `sc.newton_step`).
    newton_ok: bool,
    /// Its scaled length ‖D s_N‖ (∞ without one).
    newton_len: f64,
    /// The Cauchy point's step length along s = −D⁻² g, in units of ‖D s‖.
    cauchy_t: f64,
    /// ‖D s‖ = ‖D⁻¹ g‖.
    s_len: f64,
}

impl Dogleg {
    /// The pieces for `sc`'s factored Jacobian, residual and Newton step (`newton_ok`:
    /// whether there is one).
    fn at(sc: &mut NewtonScratch, newton_ok: bool) -> Self {
        dogleg_at(sc, newton_ok)
    }
}

avx2_dispatch! {
    /// [`Dogleg::at`], in an AVX2 copy where the CPU has it: the same operations in the
    /// same order (the same pieces bit for bit), the products with the Jacobian four
    /// rows a vector: 14.6 k → 10.6 k instructions per call at 36 unknowns
    /// (callgrind, a warm FK step of the 9-DoF design).
    fn dogleg_at = dogleg_at_avx2 / dogleg_at_inline;
        (sc: &mut NewtonScratch, newton_ok: bool) -> Dogleg
}

#[inline(always)]
fn dogleg_at_inline(sc: &mut NewtonScratch, newton_ok: bool) -> Dogleg {
    let n = sc.r.len();
    for i in 0..n {
        sc.work[i] = sc.r[i] * sc.weights[i];
    }
    sc.jac.tr_mul_to(&sc.work, &mut sc.gradient);
    let newton_len = if newton_ok {
        scaled_norm(&sc.newton_step, &sc.diag)
    } else {
        f64::INFINITY
    };
    // Cauchy point along s = −D⁻² g.
    let g_scaled_sq: f64 = sc
        .gradient
        .as_slice()
        .iter()
        .zip(sc.diag.as_slice())
        .map(|(g, d)| (g / d).powi(2))
        .sum();
    // (J s)_i with s = −D⁻² g, each row's sum in the order of j (column by column).
    sc.rows.fill(0.0);
    for (j, column) in sc.jac.as_slice().chunks_exact(n).enumerate() {
        let (g, dd) = (sc.gradient[j], sc.diag[j] * sc.diag[j]);
        for (acc, a) in sc.rows.as_mut_slice().iter_mut().zip(column) {
            *acc -= a * g / dd;
        }
    }
    let js_sq: f64 = sc.rows.iter().map(|acc| acc * acc).sum();
    let cauchy_t = if js_sq > 0.0 {
        g_scaled_sq / js_sq
    } else {
        0.0
    };
    Dogleg {
        newton_ok,
        newton_len,
        cauchy_t,
        s_len: g_scaled_sq.sqrt(),
    }
}

/// The Newton step −(W J)⁻¹ (W r + s) of the factored Jacobian into `sc.newton_step`,
/// with s the one-sided model's anchor `sc.kink_shift` (zero for a two-sided Jacobian); whether
/// there is one (the factorization succeeded and the step is finite).
fn newton_step(sc: &mut NewtonScratch) -> bool {
    if !sc.newton_ok {
        return false;
    }
    for i in 0..sc.r.len() {
        sc.newton_step[i] = -(sc.r[i] * sc.weights[i] + sc.kink_shift[i]);
    }
    sc.lu.solve_in_place(&mut sc.newton_step);
    sc.newton_step.as_slice().iter().all(|v| v.is_finite())
}

/// Replaces (row-weighted) each column of `sc.jac` whose unknown the Newton step in
/// `sc.newton_step` takes across a kink by the system's one-sided column
/// ([`NonlinearSystem::one_sided_column`]); whether any was replaced (the caller then
/// factors and solves again). The Jacobian before is kept in `sc.jac_two_sided` if any
/// was.
fn one_sided_columns<S: NonlinearSystem>(
    system: &S,
    x: &DVector<f64>,
    sc: &mut NewtonScratch,
) -> bool {
    let mut replaced = false;
    for j in 0..x.len() {
        if let Some(d) = system.one_sided_column(x, &sc.newton_step, j, &mut sc.rows) {
            if !replaced {
                sc.jac_two_sided.copy_from(&sc.jac);
            }
            for (i, w) in sc.weights.iter().enumerate() {
                let new = w * sc.rows[i];
                // Anchored at the kink: F(x + s) = F(x) + (J_new − J_old)_j d + J₁ s.
                sc.kink_shift[i] += (new - sc.jac[(i, j)]) * d;
                sc.jac[(i, j)] = new;
            }
            replaced = true;
        }
    }
    replaced
}

/// Puts the two-sided Jacobian kept by [`one_sided_columns`] back (without an anchor),
/// factors it and computes its Newton step; whether there is one.
fn back_to_two_sided(sc: &mut NewtonScratch) -> bool {
    std::mem::swap(&mut sc.jac, &mut sc.jac_two_sided);
    sc.kink_shift.fill(0.0);
    sc.newton_ok = sc.lu.factor(&sc.jac).is_ok();
    newton_step(sc)
}

/// Multiplies each row i of `jac` by `w[i]`.
fn weight_rows(jac: &mut DMatrix<f64>, w: &DVector<f64>) {
    for column in jac.as_mut_slice().chunks_exact_mut(w.len()) {
        for (a, w) in column.iter_mut().zip(w.as_slice()) {
            *a *= w;
        }
    }
}

/// How a run requested by [`NewtonScratch::reuse_jacobian_once`] started.
enum LastJacobianStart {
    /// The start is converged: the run's report (no iteration, no Jacobian).
    Converged(NewtonReport),
    /// One chord step with the last Jacobian was taken: `x`, `sc.r` and the history are
    /// at the new iterate (after `evaluations` residual evaluations: two, three where a
    /// trial expected to converge did not).
    Stepped { evaluations: usize },
    /// `x` is unchanged; the run starts afresh after `evaluations` residual evaluations.
    Declined { evaluations: usize },
}

/// The residual at `x` and one chord step with the last run's Jacobian (factored now if
/// it was not), taken whole if it is a full step within the system's step limit and
/// contracts ‖W F‖ by [`NewtonSettings::chord_contraction`].
///
/// Where the system [prepares a final residual](NonlinearSystem::prepares_final_residual)
/// and the last run started alike with the ratio ‖F₁‖/‖F₀‖ = `expected_ratio`, the trial
/// is evaluated by [`NonlinearSystem::final_residual`] if ‖F₀‖ × that ratio is within
/// [`FIRST_STEP_PREDICTION`] × the tolerance (a trial that does not converge is then
/// evaluated again as a plain residual: the same iterates).
fn start_from_last_jacobian<S: NonlinearSystem>(
    system: &mut S,
    x: &mut DVector<f64>,
    settings: &NewtonSettings,
    sc: &mut NewtonScratch,
    expected_ratio: Option<f64>,
) -> LastJacobianStart {
    let finite = |v: &DVector<f64>| v.as_slice().iter().all(|a| a.is_finite());
    if system.residual(x, &mut sc.r).is_err() || !finite(&sc.r) {
        return LastJacobianStart::Declined { evaluations: 1 };
    }
    let norm = test_norm(&sc.r, &sc.units);
    if norm <= settings.tolerance {
        sc.history.push(norm);
        return LastJacobianStart::Converged(NewtonReport {
            iterations: 0,
            residual_evaluations: 1,
            jacobian_evaluations: 0,
            residual_norm: norm,
            converged_at_floor: false,
        });
    }
    if !sc.factored {
        weight_rows(&mut sc.jac, &sc.weights);
        sc.newton_ok = sc.lu.factor(&sc.jac).is_ok();
        sc.factored = true;
        // The column scaling of a run that starts with this Jacobian.
        for (j, d) in sc.diag.iter_mut().enumerate() {
            let c = sc.jac.column(j).norm();
            *d = if c > 0.0 { c } else { 1.0 };
        }
    }
    if !newton_step(sc) || system.step_limit(x, &sc.newton_step) < 1.0 {
        return LastJacobianStart::Declined { evaluations: 1 };
    }
    system.retract(x, &sc.newton_step, &mut sc.x_trial);
    let mut evaluations = 2;
    let expected_to_converge = system.prepares_final_residual()
        && expected_ratio.is_some_and(|c| norm * c <= FIRST_STEP_PREDICTION * settings.tolerance);
    let evaluated = if expected_to_converge {
        let (e, count) = expected_last_residual(system, sc, settings.tolerance);
        evaluations += count - 1;
        e
    } else {
        system.residual(&sc.x_trial, &mut sc.r_trial)
    };
    let merit = weighted_norm_sq(&sc.r, &sc.weights);
    let contracted = evaluated.is_ok()
        && finite(&sc.r_trial)
        && weighted_norm_sq(&sc.r_trial, &sc.weights) <= settings.chord_contraction.powi(2) * merit;
    if !contracted {
        return LastJacobianStart::Declined { evaluations };
    }
    x.copy_from(&sc.x_trial);
    sc.r.copy_from(&sc.r_trial);
    let trial_norm = test_norm(&sc.r, &sc.units);
    sc.first_chord_ratio = Some(trial_norm / norm);
    sc.history.push(norm);
    sc.history.push(trial_norm);
    LastJacobianStart::Stepped { evaluations }
}

/// `sc.r_trial` = F at the trial `sc.x_trial` that the driver expects to end the run, by
/// [`NonlinearSystem::final_residual`]; where it does not converge after all
/// (mispredicted), by [`NonlinearSystem::residual`] at the trial again, so the run goes
/// on from the residual at the trial itself. Returns the result and the residual
/// evaluations taken (one, or two when mispredicted).
fn expected_last_residual<S: NonlinearSystem>(
    system: &mut S,
    sc: &mut NewtonScratch,
    tolerance: f64,
) -> (Result<(), SolveError>, usize) {
    let e = system.final_residual(&sc.x_trial, &mut sc.r_trial);
    let converged =
        sc.r_trial.iter().all(|v| v.is_finite()) && test_norm(&sc.r_trial, &sc.units) <= tolerance;
    if e.is_ok() && !converged {
        (system.residual(&sc.x_trial, &mut sc.r_trial), 2)
    } else {
        (e, 1)
    }
}

/// A warm start's first chord step ([`NewtonScratch::reuse_jacobian_once`]) is evaluated
/// as the run's expected last residual ([`NonlinearSystem::final_residual`]) when the
/// last run's first step, applied to this ‖F₀‖, predicts at most this multiple of the
/// tolerance. Measured on the workspace sweep of the reference design (z ∈ [−6, 0] mm,
/// φ = 0.2, one thread, the predictor's quartic): without the prediction 8 320 residual
/// integrations and 3 678 with sensitivities; with 0.3, 7 212 and 3 680; with 0.9, 6 528
/// and 3 706 (26 trials mispredicted, each a Jacobian's tangents in vain); 1.0 is as
/// good.
pub const FIRST_STEP_PREDICTION: f64 = 1.0;

/// A system of m nonlinear equations F(x) = 0 in n ≥ m unknowns (an underdetermined
/// one: the redundant IK), solved by [`solve_with_line_search`]. The Jacobian stays
/// with the system, where the [`StepRule`] reads it.
pub trait LineSearchSystem {
    /// Number of equations m.
    fn dim(&self) -> usize;

    /// r = F(x) in SI units, and the Jacobian at x kept for the step rule.
    ///
    /// # Errors
    /// [`SolveError::NonFinite`] when x leads to a non-finite state (ends the run).
    fn residual_and_jacobian(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError>;

    /// r = F(x) at a trial point.
    ///
    /// # Errors
    /// [`SolveError::NonFinite`] as above (rejects the trial point).
    fn residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError>;

    /// Weight of each row in the merit function ‖W F‖² (about 1 / its typical size).
    fn row_weights(&self, w: &mut DVector<f64>);

    /// The characteristic size of each row in SI, as [`NonlinearSystem::row_scales`]
    /// (default 1: the plain SI test).
    fn row_scales(&self, c: &mut DVector<f64>) {
        c.fill(1.0);
    }

    /// Σ_j |J_ij| |x_j| of each row i (SI) with the Jacobian J of the last
    /// [`LineSearchSystem::residual_and_jacobian`] at `x`: the size of the terms each row
    /// sums, for the round-off floor ([`round_off_floor`]).
    fn jacobian_row_sums(&self, x: &[f64], sums: &mut DVector<f64>);

    /// Whether the driver evaluates a trial it expects to end the run by
    /// [`LineSearchSystem::final_residual`] (default: no).
    fn prepares_final_residual(&self) -> bool {
        false
    }

    /// r = F at a trial `x` that the driver expects to end the run, as
    /// [`NonlinearSystem::final_residual`]. Default: the residual.
    ///
    /// # Errors
    /// As [`LineSearchSystem::residual`].
    fn final_residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
        self.residual(x, r)
    }

    /// The factor of [`ends_the_run`]'s prediction for this system's chord trials: a
    /// trial is evaluated by [`LineSearchSystem::final_residual`] where the last
    /// contraction repeated would bring ‖F‖ within this multiple of the tolerance
    /// (default [`FINAL_PREDICTION`]).
    fn final_prediction(&self) -> f64 {
        FINAL_PREDICTION
    }

    /// Whether [`solve_with_line_search`] may evaluate a full step's trial point with its
    /// Jacobian where the next iterate will need one, and end a run at a chord trial
    /// within the tolerance that contracted less than a chord step must (default: no).
    /// The workspace sweep's path steps do neither: there the first cost 8 % more
    /// Jacobians, and the second saved no time and moved 0.05–0.08 % of the 9-DoF maps'
    /// cells onto other branches near folds (BENCHMARKS.md).
    fn speculate_jacobians(&self) -> bool {
        false
    }
}

/// How each iteration of [`solve_with_line_search`] computes its step from the residual
/// and the Jacobian its system holds (the least-norm KKT step, the QP step within
/// limits, ...).
pub trait StepRule<S> {
    /// The step δx (n values) from `x` with residual `r` and row weights `weights` in
    /// iteration `iteration` (0-based), or why there is none.
    ///
    /// # Errors
    /// The [`StopReason`] the run ends with.
    fn step(
        &mut self,
        system: &S,
        x: &[f64],
        r: &DVector<f64>,
        weights: &DVector<f64>,
        iteration: usize,
    ) -> Result<Vec<f64>, StopReason>;

    /// A chord step: as [`StepRule::step`] at a new `x` and `r`, with the Jacobian (and
    /// any factorization) of the last [`StepRule::step`] reused, or `None` when the rule
    /// has none (default; the driver then evaluates the Jacobian at `x`).
    fn chord_step(
        &mut self,
        system: &S,
        x: &[f64],
        r: &DVector<f64>,
        weights: &DVector<f64>,
        iteration: usize,
    ) -> Option<Vec<f64>> {
        let _ = (system, x, r, weights, iteration);
        None
    }

    /// Whether the run starts with chord steps on the factorization the rule already
    /// holds (from an earlier run that ended near this start: a path step), instead of a
    /// Jacobian at the start. `false` by default.
    fn starts_with_chord(&self) -> bool {
        false
    }

    /// Whether the run takes chord steps on the first Jacobian from its first iterate on
    /// (while each contracts ‖W F‖ by [`NewtonSettings::chord_contraction`]), not only in
    /// the [`CHORD_TAIL`], and never evaluates a trial point's Jacobian ahead
    /// ([`LineSearchSystem::speculate_jacobians`]): for a rule whose solution is defined
    /// by the Jacobian at the start (the least-norm IK's steps along the start's
    /// least-change directions). A run that needed a second Jacobian goes on as any
    /// other. `false` by default.
    fn chord_from_start(&self) -> bool {
        false
    }
}

/// Whether a chord trial from an iterate with residual norm `norm` (test units), after
/// one with `previous`, is expected to end the run: the last contraction repeated,
/// norm · (norm / previous), within [`FINAL_PREDICTION`] × `tolerance`.
///
/// Measured on the reference design's Δ = 3 mm sweep (z ∈ [−20, 0] mm, 2026-11-26): of
/// the chord trials so predicted 35 794 converged and 51 did not; the trials not so
/// predicted converged in 6 606 of 27 886 cases (with the factor 1 instead of 0.1:
/// 41 455 and 4 620 — a mispredicted trial costs its sensitivities, about six
/// residuals).
pub fn ends_the_run(norm: f64, previous: f64, tolerance: f64) -> bool {
    ends_the_run_within(norm, previous, tolerance, FINAL_PREDICTION)
}

/// [`ends_the_run`] with `prediction` in place of [`FINAL_PREDICTION`] (a
/// [`LineSearchSystem::final_prediction`]).
fn ends_the_run_within(norm: f64, previous: f64, tolerance: f64, prediction: f64) -> bool {
    norm * (norm / previous) <= prediction * tolerance
}

/// See [`ends_the_run`].
pub const FINAL_PREDICTION: f64 = 0.1;

/// Whether `rule` takes [chord steps from the start](StepRule::chord_from_start) at this
/// point of a run: only on the Jacobian at the start (a run that needed another goes on
/// as any other).
fn from_start<S, R: StepRule<S>>(rule: &R, report: &NewtonReport) -> bool {
    rule.chord_from_start() && report.jacobian_evaluations <= 1
}

/// [`solve_with_line_search`] takes chord steps only once ‖F‖ (test units) is at most this
/// multiple of the tolerance (unless its rule [starts with chord
/// steps](StepRule::starts_with_chord) or [takes them from the
/// start](StepRule::chord_from_start)). An underdetermined system has a manifold of
/// solutions, and a chord step lands on it elsewhere than a Newton step, by about
/// ‖δx_prev‖ · ‖δx‖ (the Jacobian's change times the step): chord steps from the first
/// iterate of a warm 1 mm IK step of the 9-DoF design moved q by 2.9e-9 m; in this tail,
/// by at most 1.4e-12 m (`tests/redundant_path.rs`, Gauss–Newton least-norm steps).
pub const CHORD_TAIL: f64 = 1e3;

/// Solves F(x) = 0 from the start in `x` (overwritten with the solution) by Gauss–Newton
/// steps of `rule`, each shortened by a backtracking line search: α = 1, ½, … until the
/// weighted residual ‖W F‖² falls below (1 − 1e-4 α) of its value at x (Armijo); the
/// run fails once α < 1e-6, unless the residual (in test units) is within [`FLOOR_FACTOR`]
/// of its round-off floor, as when [`solve`]'s trust region collapses
/// ([`NewtonReport::converged_at_floor`]). Stops as [`solve`] ([`NewtonSettings::outcome`]).
///
/// Jacobians: an accepted trial's residual is tested first, so a converged (or stopped)
/// run ends without a Jacobian at its last iterate. After a full step (α = 1) that
/// reduced ‖W F‖ by at least [`NewtonSettings::chord_contraction`] to at most
/// [`CHORD_TAIL`] × the tolerance (in test units), the next step is a chord step
/// ([`StepRule::chord_step`], the Jacobian reused) taken whole if it contracts as much
/// again or, where the system [speculates](LineSearchSystem::speculate_jacobians), lands
/// within the tolerance (which ends the run); otherwise (or when the rule
/// has no chord step) the Jacobian is evaluated at x and the step computed anew. Before
/// 2026-11-26 a chord trial within the tolerance was rejected unless it contracted: the
/// 9-DoF design's warm 1 mm steps land their second iterate at ‖F‖ ≈ 1.0–1.25e-10, just
/// above the tolerance, and a chord trial from there at 1–3e-11, often less than tenfold
/// below: a Jacobian and a Newton step more (BENCHMARKS.md). A rule
/// that [starts with chord steps](StepRule::starts_with_chord) has the run start so,
/// with the residual alone at the start, whatever its size.
/// A rule that takes [chord steps from the start](StepRule::chord_from_start) has them
/// after its first full step that contracts, whatever ‖F‖.
///
/// If the system [speculates](LineSearchSystem::speculate_jacobians), where the next
/// iterate will need a Jacobian anyway the full step's trial point is evaluated with its
/// Jacobian at once (the residual comes with it): after a full step (or at the first),
/// when ‖F‖² ≥ [`CHORD_TAIL`] × the tolerance (quadratic convergence then leaves ‖F‖
/// above the chord tail). A warm 1 mm IK step of the 9-DoF design then takes 2 Jacobians
/// and 2 residuals instead of 2 and 3 (BENCHMARKS.md); a rejected or final trial wastes
/// the Jacobian's tangents (the 9-DoF sweeps' path steps: 8 % more Jacobians, 11 % more
/// time, so they do not speculate). The iterates are those of a run without it, except
/// where a speculated trial lands in the chord tail: the next step is then a Newton step
/// with that trial's Jacobian instead of a chord step (a difference within the
/// tolerance).
///
/// A chord trial that [`ends_the_run`] predicts to converge (with the system's
/// [`LineSearchSystem::final_prediction`]) is evaluated by
/// [`LineSearchSystem::final_residual`] if the system [prepares
/// one](LineSearchSystem::prepares_final_residual) (the same iterates).
///
/// # Errors
/// [`SolveError::NotConverged`] with the stop reason of the settings, of the step rule,
/// or [`StopReason::LineSearchFailed`]; [`SolveError::NonFinite`] if F cannot be
/// evaluated at an accepted iterate.
pub fn solve_with_line_search<S: LineSearchSystem, R: StepRule<S>>(
    system: &mut S,
    rule: &mut R,
    x: &mut Vec<f64>,
    settings: &NewtonSettings,
) -> Result<NewtonReport, SolveError> {
    let m = system.dim();
    let mut weights = DVector::zeros(m);
    system.row_weights(&mut weights);
    let mut units = DVector::zeros(m);
    fill_test_units(&mut units, |c| system.row_scales(c));
    let mut r = DVector::zeros(m);
    let mut trial = DVector::zeros(m);
    // Buffers of the line search: the trial point and the weighted residual of the merit.
    let mut x_t = x.clone();
    let mut weighted = DVector::zeros(m);
    let mut report = NewtonReport::none();
    let mut merit = |r: &DVector<f64>| {
        weighted.copy_from(r);
        weighted.component_mul_assign(&weights);
        weighted.norm_squared()
    };
    // Whether the Jacobian the rule holds was evaluated at x.
    let mut fresh = !rule.starts_with_chord();
    if fresh {
        system.residual_and_jacobian(x, &mut r)?;
        report.jacobian_evaluations += 1;
    } else {
        system.residual(x, &mut r)?;
    }
    report.residual_evaluations += 1;
    report.residual_norm = test_norm(&r, &units);
    let first_norm = report.residual_norm;
    // ‖F‖ at the iterate before x (test units), for [`ends_the_run`].
    let mut previous_norm = f64::INFINITY;
    let contraction_sq = settings.chord_contraction.powi(2);
    // Whether the last step was taken whole (the first counts as one).
    let mut full_steps = true;
    loop {
        if let Some(end) = settings.outcome(&report, first_norm) {
            return end;
        }
        let m0 = merit(&r);
        if !fresh {
            // A chord step, taken whole or not at all.
            let chord = rule.chord_step(system, x, &r, &weights, report.iterations);
            if let Some(step) = chord {
                for ((t, x), d) in x_t.iter_mut().zip(x.iter()).zip(&step) {
                    *t = x + d;
                }
                report.residual_evaluations += 1;
                let finite = |r: &DVector<f64>| r.iter().all(|v| v.is_finite());
                let last = system.prepares_final_residual()
                    && ends_the_run_within(
                        report.residual_norm,
                        previous_norm,
                        settings.tolerance,
                        system.final_prediction(),
                    );
                let mut ok = if last {
                    system.final_residual(&x_t, &mut trial).is_ok() && finite(&trial)
                } else {
                    system.residual(&x_t, &mut trial).is_ok() && finite(&trial)
                };
                if last && ok && test_norm(&trial, &units) > settings.tolerance {
                    // Mispredicted: the run goes on from the residual at x_t itself.
                    report.residual_evaluations += 1;
                    ok = system.residual(&x_t, &mut trial).is_ok() && finite(&trial);
                }
                // A trial within the tolerance ends the run, contracted or not (where the
                // system speculates: see `LineSearchSystem::speculate_jacobians`).
                let converged = ok
                    && system.speculate_jacobians()
                    && test_norm(&trial, &units) <= settings.tolerance;
                if ok && (converged || merit(&trial) <= contraction_sq * m0) {
                    std::mem::swap(x, &mut x_t);
                    std::mem::swap(&mut r, &mut trial);
                    report.iterations += 1;
                    previous_norm = report.residual_norm;
                    report.residual_norm = test_norm(&r, &units);
                    continue;
                }
            }
            system.residual_and_jacobian(x, &mut r)?;
            report.residual_evaluations += 1;
            report.jacobian_evaluations += 1;
            previous_norm = report.residual_norm;
            report.residual_norm = test_norm(&r, &units);
            fresh = true;
            continue;
        }
        let step = rule
            .step(system, x, &r, &weights, report.iterations)
            .map_err(|reason| settings.not_converged(&report, reason))?;
        let speculate = system.speculate_jacobians()
            && !from_start(rule, &report)
            && full_steps
            && report.residual_norm.powi(2) >= CHORD_TAIL * settings.tolerance;
        // Whether the system's Jacobian is at the trial point of α = 1 (not at x).
        let mut speculated = false;
        let mut alpha = 1.0;
        let accepted = loop {
            if alpha < 1e-6 {
                break false;
            }
            for ((t, x), d) in x_t.iter_mut().zip(x.iter()).zip(&step) {
                *t = x + alpha * d;
            }
            report.residual_evaluations += 1;
            let evaluated = if speculate && alpha == 1.0 {
                report.jacobian_evaluations += 1;
                speculated = true;
                system.residual_and_jacobian(&x_t, &mut trial)
            } else {
                system.residual(&x_t, &mut trial)
            };
            let ok = evaluated.is_ok() && trial.iter().all(|v| v.is_finite());
            if ok && merit(&trial) < (1.0 - 1e-4 * alpha) * m0 {
                std::mem::swap(x, &mut x_t);
                break true;
            }
            alpha *= 0.5;
        };
        full_steps = accepted && alpha == 1.0;
        if !accepted {
            if speculated {
                // The row sums below read the Jacobian at x.
                system.residual_and_jacobian(x, &mut r)?;
                report.residual_evaluations += 1;
                report.jacobian_evaluations += 1;
            }
            let mut sums = trial;
            system.jacobian_row_sums(x, &mut sums);
            sums.component_div_assign(&units);
            let floor = floor_of_rows(sums.iter().copied());
            if floor_accepts(report.residual_norm, floor, settings.tolerance) {
                return Ok(NewtonReport {
                    converged_at_floor: true,
                    ..report
                });
            }
            return Err(settings.not_converged(&report, StopReason::LineSearchFailed));
        }
        report.iterations += 1;
        // The accepted trial's residual decides first: a run that ends here (converged or
        // stopped) needs no Jacobian at its last iterate.
        previous_norm = report.residual_norm;
        report.residual_norm = test_norm(&trial, &units);
        let tail =
            from_start(rule, &report) || report.residual_norm <= CHORD_TAIL * settings.tolerance;
        // At x already: the speculated Jacobian of an accepted full step.
        let at_x = speculated && alpha == 1.0;
        if tail && alpha == 1.0 && !at_x && merit(&trial) <= contraction_sq * m0 {
            std::mem::swap(&mut r, &mut trial);
            fresh = false;
            continue;
        }
        if let Some(end) = settings.outcome(&report, first_norm) {
            return end;
        }
        if at_x {
            std::mem::swap(&mut r, &mut trial);
            continue;
        }
        system.residual_and_jacobian(x, &mut r)?;
        report.residual_evaluations += 1;
        report.jacobian_evaluations += 1;
        previous_norm = report.residual_norm;
        report.residual_norm = test_norm(&r, &units);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_dispatched_dogleg_pieces_equal_their_portable_body_bit_for_bit() {
        let n = 36;
        let mut sc = NewtonScratch::new(n, 5);
        let wave = |k: usize, a: f64| (k as f64 * a).sin() * 10f64.powi(k as i32 % 5 - 2);
        for i in 0..n {
            sc.r[i] = wave(i, 0.7);
            sc.weights[i] = 1.0 + wave(i, 0.3).abs();
            sc.diag[i] = 0.5 + wave(i, 1.1).abs();
            sc.newton_step[i] = wave(i, 0.45);
            for j in 0..n {
                sc.jac[(i, j)] = wave(i * n + j, 0.013);
            }
        }
        let mut copy = sc.clone();
        let dispatched = dogleg_at(&mut sc, true);
        let portable = dogleg_at_inline(&mut copy, true);
        let same = |x: f64, y: f64| x.to_bits() == y.to_bits();
        assert!(same(dispatched.newton_len, portable.newton_len));
        assert!(same(dispatched.cauchy_t, portable.cauchy_t));
        assert!(same(dispatched.s_len, portable.s_len));
        assert!(
            sc.gradient
                .iter()
                .zip(&copy.gradient)
                .all(|(a, b)| same(*a, *b))
        );
        assert!(dispatched.cauchy_t > 0.0 && dispatched.s_len > 0.0);
    }

    /// Powell's badly scaled function: 1e4 x y = 1, e^{-x} + e^{-y} = 1.0001.
    struct Powell;

    impl NonlinearSystem for Powell {
        fn dim(&self) -> usize {
            2
        }
        fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
            r[0] = 1e4 * x[0] * x[1] - 1.0;
            r[1] = (-x[0]).exp() + (-x[1]).exp() - 1.0001;
            Ok(())
        }
        fn residual_and_jacobian(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
            j: &mut DMatrix<f64>,
        ) -> Result<(), SolveError> {
            self.residual(x, r)?;
            j[(0, 0)] = 1e4 * x[1];
            j[(0, 1)] = 1e4 * x[0];
            j[(1, 0)] = -(-x[0]).exp();
            j[(1, 1)] = -(-x[1]).exp();
            Ok(())
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
    }

    #[test]
    fn solves_powells_badly_scaled_function_from_the_standard_start() {
        let mut x = DVector::from_vec(vec![0.0, 1.0]);
        let mut sc = NewtonScratch::new(2, 200);
        let settings = NewtonSettings {
            tolerance: 1e-12,
            max_iterations: 200,
            ..Default::default()
        };
        let report = solve(&mut Powell, &mut x, &settings, &mut sc).unwrap();
        assert!(report.residual_norm <= 1e-12);
        assert!((x[0] - 1.098_159_3e-5).abs() < 1e-10, "x = {x}");
    }

    /// atan x₀ = 0, atan x₁ + 0.1 x₀ = 0: Newton overshoots far from 0 (rejected trials)
    /// and converges fast near it.
    struct Atan;

    impl NonlinearSystem for Atan {
        fn dim(&self) -> usize {
            2
        }
        fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
            r[0] = x[0].atan();
            r[1] = x[1].atan() + 0.1 * x[0];
            Ok(())
        }
        fn residual_and_jacobian(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
            j: &mut DMatrix<f64>,
        ) -> Result<(), SolveError> {
            self.residual(x, r)?;
            j[(0, 0)] = 1.0 / (1.0 + x[0] * x[0]);
            j[(0, 1)] = 0.0;
            j[(1, 0)] = 0.1;
            j[(1, 1)] = 1.0 / (1.0 + x[1] * x[1]);
            Ok(())
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
    }

    /// [`Powell`] (`true`) or [`Atan`] that records every point it is evaluated at and
    /// whether with its Jacobian.
    #[derive(Default)]
    struct Recorded {
        powell: bool,
        points: Vec<(f64, f64, bool)>,
    }

    impl NonlinearSystem for Recorded {
        fn dim(&self) -> usize {
            2
        }
        fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
            self.points.push((x[0], x[1], false));
            if self.powell {
                Powell.residual(x, r)
            } else {
                Atan.residual(x, r)
            }
        }
        fn residual_and_jacobian(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
            j: &mut DMatrix<f64>,
        ) -> Result<(), SolveError> {
            self.points.push((x[0], x[1], true));
            if self.powell {
                Powell.residual_and_jacobian(x, r, j)
            } else {
                Atan.residual_and_jacobian(x, r, j)
            }
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
    }

    /// Starts of [`Recorded`] runs: Powell's standard one, and two for [`Atan`] far out.
    const RECORDED_STARTS: [(bool, [f64; 2]); 3] = [
        (true, [0.0, 1.0]),
        (false, [3.0, -2.0]),
        (false, [10.0, 5.0]),
    ];

    /// A [`Recorded`] run from `start` under `rules`: its report, solution and points.
    fn recorded_run(
        powell: bool,
        start: [f64; 2],
        settings: &NewtonSettings,
        rules: Rules,
    ) -> (NewtonReport, DVector<f64>, Vec<(f64, f64, bool)>) {
        let mut system = Recorded {
            powell,
            points: Vec::new(),
        };
        let mut x = DVector::from_vec(start.to_vec());
        let mut sc = NewtonScratch::new(2, 200);
        let report = solve_with_rule(&mut system, &mut x, settings, &mut sc, rules).unwrap();
        (report, x, system.points)
    }

    /// Runs from every one of [`RECORDED_STARTS`] under the rules `before` and `after`
    /// (a deferral of some trials' Jacobians) and checks that `after` keeps every
    /// iterate and the solution bit for bit and evaluates each of its Jacobians at a
    /// point that had one under `before`, in the same order, and no more of them.
    /// Returns, per start, whether it is Powell's and the Jacobians saved.
    fn deferral_keeps_every_iterate(before: Rules, after: Rules) -> Vec<(bool, usize)> {
        let settings = NewtonSettings {
            tolerance: 1e-12,
            max_iterations: 200,
            ..Default::default()
        };
        let bits = |x: &DVector<f64>| (x[0].to_bits(), x[1].to_bits());
        let with_jacobian = |points: &[(f64, f64, bool)]| -> Vec<(u64, u64)> {
            points
                .iter()
                .filter(|p| p.2)
                .map(|p| (p.0.to_bits(), p.1.to_bits()))
                .collect()
        };
        RECORDED_STARTS
            .into_iter()
            .map(|(powell, start)| {
                let (b, x_b, points_b) = recorded_run(powell, start, &settings, before);
                let (a, x_a, points_a) = recorded_run(powell, start, &settings, after);
                assert_eq!(a.iterations, b.iterations, "from {start:?}");
                assert_eq!(bits(&x_a), bits(&x_b), "from {start:?}");
                let (jb, ja) = (with_jacobian(&points_b), with_jacobian(&points_a));
                assert_eq!(ja.len(), a.jacobian_evaluations);
                assert_eq!(points_a.len(), a.residual_evaluations);
                let mut rest = jb.iter();
                assert!(ja.iter().all(|p| rest.any(|q| q == p)), "from {start:?}");
                assert!(
                    a.jacobian_evaluations <= b.jacobian_evaluations,
                    "from {start:?}: {a:?} vs {b:?}"
                );
                (powell, b.jacobian_evaluations - a.jacobian_evaluations)
            })
            .collect()
    }

    #[test]
    fn deferring_the_jacobian_after_a_rejection_keeps_every_iterate() {
        let rules = |skip_after_rejection| Rules {
            skip_after_rejection,
            fresh_step_prediction: 0.0,
            stall_ratio: f64::INFINITY,
        };
        for (powell, saved) in deferral_keeps_every_iterate(rules(false), rules(true)) {
            // Long streaks of rejections: Jacobians saved.
            assert!(!powell || saved > 0, "Powell's run saved no Jacobian");
        }
    }

    /// A stalling run's trials go without their Jacobians ([`STALL_RATIO`]): the same
    /// iterates and solution bit for bit, each Jacobian at a point that had one before,
    /// and fewer Jacobians over these runs (one residual more per deferred trial that is
    /// accepted).
    #[test]
    fn deferring_a_stalling_runs_jacobians_keeps_every_iterate() {
        let rules = |stall_ratio| Rules {
            skip_after_rejection: SKIP_AFTER_REJECTION,
            fresh_step_prediction: FRESH_STEP_PREDICTION,
            stall_ratio,
        };
        let saved: usize = deferral_keeps_every_iterate(rules(f64::INFINITY), rules(STALL_RATIO))
            .iter()
            .map(|(_, saved)| saved)
            .sum();
        assert!(saved > 0, "no Jacobian saved");
    }

    /// A full Newton step from a fresh Jacobian expected to converge
    /// ([`FRESH_STEP_PREDICTION`]) goes without its trial's Jacobian: the same iterates and
    /// solution bit for bit, fewer Jacobians over these runs, and none more in any.
    #[test]
    fn a_fresh_step_expected_to_converge_goes_without_its_jacobian() {
        let mut saved = 0;
        for tolerance in [1e-4, 1e-6, 1e-8, 1e-10, 1e-12] {
            let settings = NewtonSettings {
                tolerance,
                max_iterations: 200,
                ..Default::default()
            };
            let nearer = [(false, [0.5, 0.5]), (false, [1.5, -1.0])];
            for (powell, start) in RECORDED_STARTS.into_iter().chain(nearer) {
                let run = |prediction: f64| {
                    let rules = Rules {
                        skip_after_rejection: SKIP_AFTER_REJECTION,
                        fresh_step_prediction: prediction,
                        stall_ratio: f64::INFINITY,
                    };
                    recorded_run(powell, start, &settings, rules)
                };
                let (before, x_before, points_before) = run(0.0);
                let (after, x_after, points_after) = run(FRESH_STEP_PREDICTION);
                let case = format!("tolerance {tolerance:e}, from {start:?}");
                let bits = |x: &DVector<f64>| (x[0].to_bits(), x[1].to_bits());
                assert_eq!(after.iterations, before.iterations, "{case}");
                assert_eq!(bits(&x_after), bits(&x_before), "{case}");
                // Every point evaluated before is evaluated now, in the same order.
                let points = |p: &[(f64, f64, bool)]| -> Vec<(u64, u64)> {
                    let mut v: Vec<_> = p.iter().map(|q| (q.0.to_bits(), q.1.to_bits())).collect();
                    v.dedup();
                    v
                };
                assert_eq!(points(&points_before), points(&points_after), "{case}");
                assert!(
                    after.jacobian_evaluations <= before.jacobian_evaluations,
                    "{case}: {after:?} vs {before:?}"
                );
                saved += before.jacobian_evaluations - after.jacobian_evaluations;
            }
        }
        assert!(saved > 0, "no Jacobian saved");
    }

    /// The points a run evaluated (bits of x₀, x₁, with the Jacobian) and its report.
    type Run = (Vec<(u64, u64, bool)>, NewtonReport);

    /// Every point a run of `system` evaluates from `start`, with the window of
    /// [`NewtonScratch::nonmonotone_once`] (None: no request), then of a second run on the
    /// same scratch without a request: both runs' points and reports.
    fn with_window(powell: bool, start: [f64; 2], window: Option<usize>) -> [Run; 2] {
        let settings = NewtonSettings {
            tolerance: 1e-12,
            max_iterations: 200,
            ..Default::default()
        };
        let mut sc = NewtonScratch::new(2, 200);
        if let Some(window) = window {
            sc.nonmonotone_once(window);
        }
        [0, 1].map(|_| {
            let mut system = Recorded {
                powell,
                points: Vec::new(),
            };
            let mut x = DVector::from_vec(start.to_vec());
            let report = solve(&mut system, &mut x, &settings, &mut sc).unwrap();
            let points = system.points.iter();
            let points = points
                .map(|p| (p.0.to_bits(), p.1.to_bits(), p.2))
                .collect();
            (points, report)
        })
    }

    #[test]
    fn a_nonmonotone_window_of_one_is_the_monotone_test_and_lasts_one_run() {
        for (powell, start) in [(true, [0.0, 1.0]), (false, [10.0, 5.0])] {
            let [monotone, _] = with_window(powell, start, None);
            for window in [0, 1] {
                let [run, _] = with_window(powell, start, Some(window));
                assert_eq!(run.0, monotone.0, "window {window} from {start:?}");
            }
            let [nonmonotone, next] = with_window(powell, start, Some(5));
            assert_ne!(nonmonotone.0, monotone.0, "from {start:?}");
            assert_eq!(next.0, monotone.0, "the run after, from {start:?}");
        }
    }

    #[test]
    fn a_nonmonotone_window_takes_the_steps_that_cross_powells_valley() {
        // The monotone test shrinks the region over and over in the curved valley of
        // Powell's function (21 iterations); steps that raise the merit for a while cross
        // it (14).
        let [(_, monotone), _] = with_window(true, [0.0, 1.0], None);
        let [(_, nonmonotone), _] = with_window(true, [0.0, 1.0], Some(5));
        assert!(nonmonotone.residual_norm <= 1e-12);
        assert!(
            nonmonotone.iterations < monotone.iterations,
            "{nonmonotone:?} vs {monotone:?}"
        );
    }

    /// x₀ + 0.1 x₁² = t, x₁ + 0.1 sin x₀ = 2t: a mildly nonlinear system with a target t.
    struct Shifted(f64);

    impl NonlinearSystem for Shifted {
        fn dim(&self) -> usize {
            2
        }
        fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
            r[0] = x[0] + 0.1 * x[1] * x[1] - self.0;
            r[1] = x[1] + 0.1 * x[0].sin() - 2.0 * self.0;
            Ok(())
        }
        fn residual_and_jacobian(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
            j: &mut DMatrix<f64>,
        ) -> Result<(), SolveError> {
            self.residual(x, r)?;
            j[(0, 0)] = 1.0;
            j[(0, 1)] = 0.2 * x[1];
            j[(1, 0)] = 0.1 * x[0].cos();
            j[(1, 1)] = 1.0;
            Ok(())
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
    }

    /// [`Shifted`] whose unknown 0 offers a one-sided column for every step that lowers
    /// it: a column of zeros (a singular system), or `e₀` (a valid one).
    struct OneSided(Shifted, f64);

    impl NonlinearSystem for OneSided {
        fn dim(&self) -> usize {
            2
        }
        fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
            self.0.residual(x, r)
        }
        fn residual_and_jacobian(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
            j: &mut DMatrix<f64>,
        ) -> Result<(), SolveError> {
            self.0.residual_and_jacobian(x, r, j)
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
        fn one_sided_column(
            &self,
            _x: &DVector<f64>,
            step: &DVector<f64>,
            j: usize,
            column: &mut DVector<f64>,
        ) -> Option<f64> {
            if j != 0 || step[0] >= 0.0 {
                return None;
            }
            column.fill(0.0);
            column[0] = self.1;
            Some(0.0)
        }
    }

    /// F(x) = x − t for x ≥ 0 and 2x − t below: a kink at 0, the Jacobian at 0 holding
    /// the right side's slope; one-sided columns on (`Some`) or off.
    struct Kinked(f64, bool);

    impl NonlinearSystem for Kinked {
        fn dim(&self) -> usize {
            1
        }
        fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
            r[0] = if x[0] >= 0.0 { x[0] } else { 2.0 * x[0] } - self.0;
            Ok(())
        }
        fn residual_and_jacobian(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
            j: &mut DMatrix<f64>,
        ) -> Result<(), SolveError> {
            self.residual(x, r)?;
            j[(0, 0)] = if x[0] >= 0.0 { 1.0 } else { 2.0 };
            Ok(())
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            // Not 1: the anchor must be weighted like the Jacobian.
            w.fill(3.0);
        }
        fn one_sided_column(
            &self,
            x: &DVector<f64>,
            step: &DVector<f64>,
            _j: usize,
            column: &mut DVector<f64>,
        ) -> Option<f64> {
            if !(self.1 && x[0] >= 0.0 && x[0] + step[0] < 0.0) {
                return None;
            }
            column[0] = 2.0;
            Some(x[0])
        }
    }

    #[test]
    fn a_one_sided_step_is_anchored_at_the_kink() {
        // From x = 0.01 to the root −0.5 beyond the kink: the right side's slope alone
        // lands at −1.01, the left side's from x at −0.495; the left side's from the
        // kink at the root.
        let settings = NewtonSettings::default();
        let mut sc = NewtonScratch::new(1, 60);
        let mut run = |one_sided| {
            let mut x = DVector::from_element(1, 0.01);
            let report = solve(&mut Kinked(-1.0, one_sided), &mut x, &settings, &mut sc).unwrap();
            (x[0], report.iterations)
        };
        let (x, iterations) = run(true);
        assert_eq!((x, iterations), (-0.5, 1));
        let (x, iterations) = run(false);
        assert!(
            (x + 0.5).abs() < 1e-12 && iterations > 1,
            "{x} in {iterations}"
        );
    }

    #[test]
    fn a_warm_start_after_a_one_sided_step_has_no_anchor() {
        // The first run converges right after its anchored one-sided step; the second
        // starts from its (one-sided, left side's) Jacobian with the target moved on the
        // left side: the chord step is exact there, with no Jacobian of its own.
        let settings = NewtonSettings::default();
        let mut sc = NewtonScratch::new(1, 60);
        let mut x = DVector::from_element(1, 0.01);
        solve(&mut Kinked(-1.0, true), &mut x, &settings, &mut sc).unwrap();
        assert_eq!(x[0], -0.5);
        sc.reuse_jacobian_once();
        let report = solve(&mut Kinked(-1.02, true), &mut x, &settings, &mut sc).unwrap();
        assert_eq!(x[0], -0.51);
        assert_eq!(report.jacobian_evaluations, 0);
    }

    #[test]
    fn a_mispredicting_one_sided_column_gives_way_to_the_two_sided_jacobian() {
        let settings = NewtonSettings::default();
        let start = || DVector::from_vec(vec![3.0, 0.0]);
        let mut x = start();
        let mut sc = NewtonScratch::new(2, 60);
        let plain = solve(&mut Shifted(1.0), &mut x, &settings, &mut sc).unwrap();
        // A column of the wrong sign: its step raises x₀ where the root needs it lower,
        // and every fresh iteration would offer it again (the trust region then
        // collapses). After its first rejected step the run goes on two-sided.
        let mut y = start();
        let report = solve(
            &mut OneSided(Shifted(1.0), -1.0),
            &mut y,
            &settings,
            &mut sc,
        )
        .expect("the two-sided Jacobian takes over");
        assert!((&y - &x).amax() < 1e-9, "{y} against {x}");
        assert!(
            report.iterations <= plain.iterations + 2,
            "{} against {}",
            report.iterations,
            plain.iterations
        );
    }

    #[test]
    fn a_singular_one_sided_system_keeps_the_two_sided_step() {
        let settings = NewtonSettings::default();
        let run =
            |system: &mut dyn FnMut(&mut DVector<f64>, &mut NewtonScratch) -> NewtonReport| {
                let mut x = DVector::from_vec(vec![3.0, 0.0]);
                let mut sc = NewtonScratch::new(2, 60);
                let report = system(&mut x, &mut sc);
                (x, report)
            };
        let (plain, plain_report) =
            run(&mut |x, sc| solve(&mut Shifted(1.0), x, &settings, sc).unwrap());
        // From x₀ = 3 the first step lowers x₀: a zero column is singular, so the run
        // is the plain one, bit for bit (a Cauchy step on the singular model would not).
        let (singular, singular_report) =
            run(&mut |x, sc| solve(&mut OneSided(Shifted(1.0), 0.0), x, &settings, sc).unwrap());
        assert_eq!(plain, singular);
        assert_eq!(plain_report, singular_report);
        // A valid one-sided column changes the run (the hook is used).
        let (other, _) =
            run(&mut |x, sc| solve(&mut OneSided(Shifted(1.0), 2.0), x, &settings, sc).unwrap());
        assert_ne!(plain, other);
    }

    #[test]
    fn a_run_from_the_last_jacobian_takes_chord_steps_or_starts_as_a_fresh_run() {
        let settings = NewtonSettings {
            tolerance: 1e-13,
            ..Default::default()
        };
        let mut sc = NewtonScratch::new(2, 60);
        let mut x = DVector::from_vec(vec![0.0, 0.0]);
        solve(&mut Shifted(1.0), &mut x, &settings, &mut sc).unwrap();
        let start = x.clone();
        // A nearby target: chord steps with the last Jacobian only.
        let mut fresh = start.clone();
        let fresh_report = solve(
            &mut Shifted(1.01),
            &mut fresh,
            &settings,
            &mut NewtonScratch::new(2, 60),
        )
        .unwrap();
        sc.reuse_jacobian_once();
        let mut reused = start.clone();
        let report = solve(&mut Shifted(1.01), &mut reused, &settings, &mut sc).unwrap();
        assert_eq!(report.jacobian_evaluations, 0, "{report:?}");
        assert!((&reused - &fresh).norm() < 1e-12, "{reused} vs {fresh}");
        // A Jacobian that does not contract (its sign flipped): the run is the fresh one,
        // bit for bit, after two more residual evaluations.
        sc.set_last_jacobian(|j| {
            j.fill_with_identity();
            j.neg_mut();
            true
        });
        sc.reuse_jacobian_once();
        let mut declined = start.clone();
        let report = solve(&mut Shifted(1.01), &mut declined, &settings, &mut sc).unwrap();
        assert_eq!(declined, fresh);
        assert_eq!(report.iterations, fresh_report.iterations);
        assert_eq!(
            report.jacobian_evaluations,
            fresh_report.jacobian_evaluations
        );
        assert_eq!(
            report.residual_evaluations,
            fresh_report.residual_evaluations + 2
        );
        // Without a request (or after forgetting) a run evaluates its own Jacobian.
        sc.forget_jacobian();
        sc.reuse_jacobian_once();
        let mut again = start.clone();
        let report = solve(&mut Shifted(1.01), &mut again, &settings, &mut sc).unwrap();
        assert_eq!((again, report), (fresh, fresh_report));
    }

    /// A path of warm runs, each from the last one's Jacobian and solution, targets `t`
    /// apart: (solution, report, final residuals evaluated) of each, with the first chord
    /// step's expected ratio replaced by `ratio` before each run if given.
    fn warm_path(
        t: &[f64],
        prepares: bool,
        ratio: Option<f64>,
    ) -> Vec<(DVector<f64>, NewtonReport, usize)> {
        let settings = NewtonSettings {
            tolerance: 1e-10,
            ..Default::default()
        };
        let mut sc = NewtonScratch::new(2, 60);
        let mut x = DVector::from_vec(vec![0.0, 0.0]);
        let mut out = Vec::new();
        for (k, &target) in t.iter().enumerate() {
            if k > 0 {
                sc.reuse_jacobian_once();
                if ratio.is_some() {
                    sc.first_chord_ratio = ratio;
                }
            }
            let (report, prepared) = if prepares {
                // The prepared residual at x itself ([`Prepared`] with no shift).
                let mut system = Prepared {
                    inner: Shifted(target),
                    shift: 0.0,
                    prepared: 0,
                };
                let report = solve(&mut system, &mut x, &settings, &mut sc).unwrap();
                (report, system.prepared)
            } else {
                (
                    solve(&mut Shifted(target), &mut x, &settings, &mut sc).unwrap(),
                    0,
                )
            };
            out.push((x.clone(), report, prepared));
        }
        out
    }

    /// A warm run whose first chord step the last run's ratio predicts to converge
    /// evaluates it as the expected last residual; a misprediction evaluates the plain
    /// residual again. The iterates are those of a run that prepares nothing.
    #[test]
    fn a_first_chord_step_expected_to_converge_is_the_final_residual() {
        // Small equal steps: the first chord step from the last Jacobian converges.
        let t = [1.0, 1.0 + 1e-9, 1.0 + 2e-9, 1.0 + 3e-9];
        let plain = warm_path(&t, false, None);
        let prepared = warm_path(&t, true, None);
        for (k, ((x, report, _), (y, prepared_report, _))) in
            plain.iter().zip(&prepared).enumerate()
        {
            assert_eq!(x, y);
            assert_eq!(report.iterations, prepared_report.iterations);
            assert_eq!(
                report.residual_evaluations,
                prepared_report.residual_evaluations
            );
            // Each warm run converges at its first chord step.
            if k > 0 {
                assert_eq!(report.iterations, 1, "{report:?}");
            }
        }
        // The second run has no ratio to go by; the third and fourth have (the first ends
        // as any run, by `ends_the_run`).
        let finals: Vec<usize> = prepared.iter().map(|p| p.2).collect();
        assert_eq!(finals[1], 0, "{finals:?}");
        assert_eq!(&finals[2..], &[1, 1], "{finals:?}");
        // Mispredicted (a ratio far too small, a step the chord cannot close at once):
        // one residual more, the same iterates.
        let t = [1.0, 1.1, 1.2];
        let plain = warm_path(&t, false, None);
        let misled = warm_path(&t, true, Some(1e-30));
        assert_eq!(plain[2].0, misled[2].0);
        assert!(misled[2].2 >= 1, "{misled:?}");
        assert_eq!(
            misled[2].1.residual_evaluations,
            plain[2].1.residual_evaluations + misled[2].2
        );
    }

    /// x² + 1 = 0: Newton creeps towards the minimum of |F| at x = 0 and never converges.
    struct NoRoot;

    impl NonlinearSystem for NoRoot {
        fn dim(&self) -> usize {
            1
        }
        fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
            r[0] = x[0] * x[0] + 1.0;
            Ok(())
        }
        fn residual_and_jacobian(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
            j: &mut DMatrix<f64>,
        ) -> Result<(), SolveError> {
            self.residual(x, r)?;
            j[(0, 0)] = 2.0 * x[0];
            Ok(())
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
    }

    #[test]
    fn a_progress_check_ends_a_crawling_run_at_its_iteration() {
        let settings = NewtonSettings {
            progress_check: Some(ProgressCheck {
                iterations: 4,
                factor: 100.0,
            }),
            ..Default::default()
        };
        let mut sc = NewtonScratch::new(1, 60);
        let err = solve(
            &mut NoRoot,
            &mut DVector::from_vec(vec![3.0]),
            &settings,
            &mut sc,
        )
        .unwrap_err();
        match err {
            SolveError::NotConverged {
                iterations, reason, ..
            } => {
                assert_eq!(iterations, 4);
                assert_eq!(reason, StopReason::TooLittleProgress);
            }
            e => panic!("unexpected {e}"),
        }
        assert_eq!(sc.residual_history().len(), 5);
    }

    #[test]
    fn a_passed_progress_check_changes_nothing() {
        let plain = NewtonSettings {
            tolerance: 1e-12,
            max_iterations: 200,
            ..Default::default()
        };
        let checked = NewtonSettings {
            progress_check: Some(ProgressCheck {
                iterations: 3,
                factor: 1.5,
            }),
            ..plain
        };
        let mut sc = NewtonScratch::new(2, 200);
        let mut a = DVector::from_vec(vec![0.0, 1.0]);
        let ra = solve(&mut Powell, &mut a, &plain, &mut sc).unwrap();
        let mut b = DVector::from_vec(vec![0.0, 1.0]);
        let rb = solve(&mut Powell, &mut b, &checked, &mut sc).unwrap();
        assert!(ra.iterations > 3);
        assert_eq!(a, b);
        assert_eq!(ra, rb);
    }

    /// a (x₀ + x₁) = b with a = 1e6 and x ~ 1 and an error of 1e-9 that acts as
    /// round-off: its round-off floor ε a (|x₀| + |x₁|) is 7e-10, above a tolerance of
    /// 1e-13.
    struct Stiff {
        jac: [f64; 2],
    }

    impl LineSearchSystem for Stiff {
        fn dim(&self) -> usize {
            1
        }
        fn residual_and_jacobian(
            &mut self,
            x: &[f64],
            r: &mut DVector<f64>,
        ) -> Result<(), SolveError> {
            self.jac = [1e6, 1e6];
            self.residual(x, r)
        }
        fn residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
            // Plus a round-off-like error of ±1e-9 that no step removes.
            let noise = if x[0].to_bits() % 2 == 0 { 1e-9 } else { -1e-9 };
            r[0] = 1e6 * (x[0] + x[1]) - 1e6 * std::f64::consts::PI + noise;
            Ok(())
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
        fn jacobian_row_sums(&self, x: &[f64], sums: &mut DVector<f64>) {
            sums[0] = self.jac[0] * x[0].abs() + self.jac[1] * x[1].abs();
        }
    }

    /// The least-norm step −Jᵀ r / (J Jᵀ) of a 1×2 Jacobian J and residual r.
    fn least_norm_step([a, b]: [f64; 2], r: f64) -> Vec<f64> {
        let s = -r / (a * a + b * b);
        vec![a * s, b * s]
    }

    /// The least-norm step of [`Stiff`].
    struct LeastNorm;

    impl StepRule<Stiff> for LeastNorm {
        fn step(
            &mut self,
            system: &Stiff,
            _: &[f64],
            r: &DVector<f64>,
            _: &DVector<f64>,
            _: usize,
        ) -> Result<Vec<f64>, StopReason> {
            Ok(least_norm_step(system.jac, r[0]))
        }
    }

    #[test]
    fn a_line_search_stalled_at_the_round_off_floor_is_converged_there_only() {
        let settings = NewtonSettings {
            tolerance: 1e-13,
            ..Default::default()
        };
        let mut x = vec![0.3, 0.7];
        let report = solve_with_line_search(
            &mut Stiff { jac: [0.0; 2] },
            &mut LeastNorm,
            &mut x,
            &settings,
        )
        .unwrap();
        assert!(report.converged_at_floor, "{report:?}");
        assert!(report.residual_norm > settings.tolerance);
        assert!((x[0] + x[1] - std::f64::consts::PI).abs() < 1e-14, "{x:?}");
        // A tolerance the floor exceeds by more than MAX_FLOOR_RELAXATION still fails.
        let strict = NewtonSettings {
            tolerance: 1e-16,
            ..settings
        };
        let err = solve_with_line_search(
            &mut Stiff { jac: [0.0; 2] },
            &mut LeastNorm,
            &mut vec![0.3, 0.7],
            &strict,
        )
        .unwrap_err();
        assert!(err.to_string().contains("line search"), "{err}");
    }

    /// x₀² + x₁² = 1: one equation in two unknowns.
    struct Circle {
        jac: [f64; 2],
        jacobians: usize,
    }

    impl LineSearchSystem for Circle {
        fn dim(&self) -> usize {
            1
        }
        fn residual_and_jacobian(
            &mut self,
            x: &[f64],
            r: &mut DVector<f64>,
        ) -> Result<(), SolveError> {
            self.jac = [2.0 * x[0], 2.0 * x[1]];
            self.jacobians += 1;
            self.residual(x, r)
        }
        fn residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
            r[0] = x[0] * x[0] + x[1] * x[1] - 1.0;
            Ok(())
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
        fn jacobian_row_sums(&self, x: &[f64], sums: &mut DVector<f64>) {
            sums[0] = self.jac[0].abs() * x[0].abs() + self.jac[1].abs() * x[1].abs();
        }
    }

    /// The least-norm step of [`Circle`], with chord steps when `chord`.
    struct CircleStep {
        chord: bool,
        chords: usize,
        /// [`StepRule::chord_from_start`].
        from_start: bool,
    }

    impl StepRule<Circle> for CircleStep {
        fn step(
            &mut self,
            system: &Circle,
            _: &[f64],
            r: &DVector<f64>,
            _: &DVector<f64>,
            _: usize,
        ) -> Result<Vec<f64>, StopReason> {
            Ok(least_norm_step(system.jac, r[0]))
        }
        fn chord_step(
            &mut self,
            system: &Circle,
            x: &[f64],
            r: &DVector<f64>,
            w: &DVector<f64>,
            i: usize,
        ) -> Option<Vec<f64>> {
            self.chords += 1;
            self.chord.then(|| self.step(system, x, r, w, i).unwrap())
        }
        fn chord_from_start(&self) -> bool {
            self.from_start
        }
    }

    #[test]
    fn chord_steps_in_the_tail_save_jacobians_and_no_jacobian_follows_convergence() {
        let settings = NewtonSettings::default();
        let run = |chord: bool| {
            let mut system = Circle {
                jac: [0.0; 2],
                jacobians: 0,
            };
            let mut rule = CircleStep {
                chord,
                chords: 0,
                from_start: false,
            };
            let mut x = vec![1.0, 0.5];
            let report = solve_with_line_search(&mut system, &mut rule, &mut x, &settings).unwrap();
            assert!((x[0].hypot(x[1]) - 1.0).abs() < 1e-10, "{x:?}");
            assert_eq!(report.jacobian_evaluations, system.jacobians);
            (report, rule.chords)
        };
        let (newton, asked) = run(false);
        // Without chord steps: one Jacobian per step, none at the solution.
        assert_eq!(newton.jacobian_evaluations, newton.iterations);
        assert!(asked >= 1, "the driver asked for a chord step in the tail");
        let (chord, _) = run(true);
        assert!(chord.jacobian_evaluations < chord.iterations, "{chord:?}");
        assert!(chord.jacobian_evaluations < newton.jacobian_evaluations);
    }

    #[test]
    fn chord_steps_from_the_start_keep_to_its_direction_or_hand_over_to_newton() {
        let settings = NewtonSettings::default();
        let run = |start: [f64; 2]| {
            let mut system = Circle {
                jac: [0.0; 2],
                jacobians: 0,
            };
            let mut rule = CircleStep {
                chord: true,
                chords: 0,
                from_start: true,
            };
            let mut x = start.to_vec();
            let report = solve_with_line_search(&mut system, &mut rule, &mut x, &settings).unwrap();
            assert!((x[0].hypot(x[1]) - 1.0).abs() <= 1e-10, "{x:?}");
            (x, report)
        };
        // Near the circle: one Jacobian (Newton steps would take one each, the test
        // above), and x − x₀ along the start's gradient (2, 1).
        let (x, report) = run([0.9, 0.45]);
        assert_eq!(report.jacobian_evaluations, 1, "{report:?}");
        assert!(report.iterations > 2, "{report:?}");
        let off = (x[1] - 0.45) * 2.0 - (x[0] - 0.9);
        assert!(off.abs() < 1e-13, "{off:e} off the start's direction");
        // Far from it the first chord step contracts less than tenfold: Newton takes over.
        let (_, report) = run([3.0, 0.1]);
        assert!(report.jacobian_evaluations > 1, "{report:?}");
    }

    /// F(x) = x + 0.1 x² in one unknown, with Newton steps and chord steps of half the
    /// length (a poorly contracting chord).
    struct Quadratic {
        jac: f64,
        speculate: bool,
    }

    impl LineSearchSystem for Quadratic {
        fn dim(&self) -> usize {
            1
        }
        fn residual_and_jacobian(
            &mut self,
            x: &[f64],
            r: &mut DVector<f64>,
        ) -> Result<(), SolveError> {
            self.jac = 1.0 + 0.2 * x[0];
            self.residual(x, r)
        }
        fn residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
            r[0] = x[0] + 0.1 * x[0] * x[0];
            Ok(())
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            w.fill(1.0);
        }
        fn jacobian_row_sums(&self, x: &[f64], sums: &mut DVector<f64>) {
            sums[0] = self.jac.abs() * x[0].abs();
        }
        fn speculate_jacobians(&self) -> bool {
            self.speculate
        }
    }

    struct HalfChord;

    impl StepRule<Quadratic> for HalfChord {
        fn step(
            &mut self,
            system: &Quadratic,
            _: &[f64],
            r: &DVector<f64>,
            _: &DVector<f64>,
            _: usize,
        ) -> Result<Vec<f64>, StopReason> {
            Ok(vec![-r[0] / system.jac])
        }
        fn chord_step(
            &mut self,
            system: &Quadratic,
            _: &[f64],
            r: &DVector<f64>,
            _: &DVector<f64>,
            _: usize,
        ) -> Option<Vec<f64>> {
            Some(vec![-0.5 * r[0] / system.jac])
        }
    }

    /// A chord trial within the tolerance ends the run even where it contracts the
    /// residual less than a chord step must to be kept otherwise (where the system
    /// speculates).
    #[test]
    fn a_chord_trial_within_the_tolerance_ends_the_run() {
        let settings = NewtonSettings::default();
        // One Newton step leaves |F| ≈ 0.1 x₀² ≈ 1.5e-10, the half chord step about half
        // of that: within the tolerance 1e-10, but contracted only twofold.
        let run = |speculate: bool| {
            let mut x = vec![(1.5e-9f64).sqrt()];
            let mut system = Quadratic {
                jac: 0.0,
                speculate,
            };
            solve_with_line_search(&mut system, &mut HalfChord, &mut x, &settings).unwrap()
        };
        let report = run(true);
        assert_eq!(
            (report.iterations, report.jacobian_evaluations),
            (2, 1),
            "{report:?}"
        );
        assert!(report.residual_norm <= settings.tolerance);
        assert!(report.residual_norm > 0.1 * 1.5e-10);
        // A system that does not speculate takes a Jacobian and a Newton step more.
        let report = run(false);
        assert_eq!(report.jacobian_evaluations, 2, "{report:?}");
    }

    /// A system whose prepared last residual is evaluated at x + `shift` (as the solver's
    /// systems evaluate theirs at the point the solution's state restates), counting the
    /// prepared evaluations.
    struct Prepared<S> {
        inner: S,
        shift: f64,
        prepared: usize,
    }

    impl NonlinearSystem for Prepared<Shifted> {
        fn dim(&self) -> usize {
            self.inner.dim()
        }
        fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
            self.inner.residual(x, r)
        }
        fn residual_and_jacobian(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
            j: &mut DMatrix<f64>,
        ) -> Result<(), SolveError> {
            self.inner.residual_and_jacobian(x, r, j)
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            self.inner.row_weights(w);
        }
        fn prepares_final_residual(&self) -> bool {
            true
        }
        fn final_residual(
            &mut self,
            x: &DVector<f64>,
            r: &mut DVector<f64>,
        ) -> Result<(), SolveError> {
            self.prepared += 1;
            self.inner.residual(&x.add_scalar(self.shift), r)
        }
    }

    impl LineSearchSystem for Prepared<Circle> {
        fn dim(&self) -> usize {
            self.inner.dim()
        }
        fn residual_and_jacobian(
            &mut self,
            x: &[f64],
            r: &mut DVector<f64>,
        ) -> Result<(), SolveError> {
            self.inner.residual_and_jacobian(x, r)
        }
        fn residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
            self.inner.residual(x, r)
        }
        fn row_weights(&self, w: &mut DVector<f64>) {
            self.inner.row_weights(w);
        }
        fn jacobian_row_sums(&self, x: &[f64], sums: &mut DVector<f64>) {
            self.inner.jacobian_row_sums(x, sums);
        }
        fn prepares_final_residual(&self) -> bool {
            true
        }
        fn final_residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
            self.prepared += 1;
            let shifted: Vec<f64> = x.iter().map(|v| v + self.shift).collect();
            self.inner.residual(&shifted, r)
        }
    }

    impl StepRule<Prepared<Circle>> for CircleStep {
        fn step(
            &mut self,
            system: &Prepared<Circle>,
            x: &[f64],
            r: &DVector<f64>,
            w: &DVector<f64>,
            i: usize,
        ) -> Result<Vec<f64>, StopReason> {
            StepRule::<Circle>::step(self, &system.inner, x, r, w, i)
        }
        fn chord_step(
            &mut self,
            system: &Prepared<Circle>,
            x: &[f64],
            r: &DVector<f64>,
            w: &DVector<f64>,
            i: usize,
        ) -> Option<Vec<f64>> {
            StepRule::<Circle>::chord_step(self, &system.inner, x, r, w, i)
        }
    }

    /// A prepared last residual changes no iterate: a run ends where it would have, and
    /// where the prediction fails (here: a shift that leaves the residual above the
    /// tolerance) the driver evaluates the residual at the trial itself and goes on as
    /// without, one residual evaluation later.
    #[test]
    fn a_prepared_last_residual_changes_no_iterate() {
        let settings = NewtonSettings {
            tolerance: 1e-13,
            ..Default::default()
        };
        let square = |shift: Option<f64>| {
            let mut system = Prepared {
                inner: Shifted(1.0),
                shift: shift.unwrap_or(0.0),
                prepared: 0,
            };
            let mut x = DVector::from_vec(vec![0.0, 0.0]);
            let mut sc = NewtonScratch::new(2, 60);
            let report = match shift {
                Some(_) => solve(&mut system, &mut x, &settings, &mut sc),
                None => solve(&mut system.inner, &mut x, &settings, &mut sc),
            };
            (x, report.unwrap(), system.prepared)
        };
        same_iterates_with_prepared_residuals(square);
        let line_search = |shift: Option<f64>| {
            let mut system = Prepared {
                inner: Circle {
                    jac: [0.0; 2],
                    jacobians: 0,
                },
                shift: shift.unwrap_or(0.0),
                prepared: 0,
            };
            let mut rule = CircleStep {
                chord: true,
                chords: 0,
                from_start: false,
            };
            let mut x = vec![1.0, 0.5];
            let settings = NewtonSettings::default();
            let report = match shift {
                Some(_) => solve_with_line_search(&mut system, &mut rule, &mut x, &settings),
                None => solve_with_line_search(&mut system.inner, &mut rule, &mut x, &settings),
            };
            (x, report.unwrap(), system.prepared)
        };
        same_iterates_with_prepared_residuals(line_search);
    }

    /// `run(shift)` (`None`: without preparing) gives the same solution with a prepared
    /// last residual within round-off (1e-17) of the trial, and with one that misses
    /// (1e-3: one more residual evaluation per prepared trial).
    fn same_iterates_with_prepared_residuals<X: PartialEq + std::fmt::Debug>(
        run: impl Fn(Option<f64>) -> (X, NewtonReport, usize),
    ) {
        let (plain, plain_report, _) = run(None);
        for (shift, extra) in [(1e-17, 0), (1e-3, 1)] {
            let (x, report, prepared) = run(Some(shift));
            assert!(prepared >= 1, "no trial was predicted to end the run");
            assert_eq!(x, plain, "shift {shift}");
            assert_eq!(
                report.residual_evaluations,
                plain_report.residual_evaluations + extra * prepared,
                "shift {shift}"
            );
        }
    }

    #[test]
    fn test_units_are_the_scales_below_one_and_never_looser_than_si() {
        let s = RowScales::of_rod(1e-3, 4.0e-10, 16.0);
        assert!((s.moment - 8e-5).abs() < 1e-18 && (s.force - 0.08).abs() < 1e-15);
        assert_eq!(test_unit(s.length), 1e-3);
        assert_eq!(test_unit(73.0), 1.0);
        assert_eq!(test_unit(0.0), 1.0);
        assert_eq!(test_unit(f64::NAN), 1.0);
    }

    #[test]
    fn reports_failure_with_residual_and_iterations() {
        let mut x = DVector::from_vec(vec![3.0]);
        let mut sc = NewtonScratch::new(1, 20);
        let err = solve(&mut NoRoot, &mut x, &NewtonSettings::default(), &mut sc).unwrap_err();
        match err {
            SolveError::NotConverged { residual_norm, .. } => assert!(residual_norm >= 1.0),
            e => panic!("unexpected {e}"),
        }
        assert!(err.to_string().contains("did not converge: residual norm"));
    }
}
