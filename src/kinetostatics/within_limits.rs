//! The step rule of [`Redundancy::WithinLimits`](super::Redundancy::WithinLimits) (cargo feature `qp`): every Gauss–Newton
//! step of the IK of the redundant design is a quadratic program:
//!
//! minimize    ½‖δq̃‖² + ½ε‖δỹ‖²          (least change; towards a reference r:
//!                                          ½‖q̃ + δq̃ − r̃‖² + ½ε‖δỹ‖²)
//! subject to  W (B_q δq + B_u δy) = −W b     (linearized boundary conditions)
//!             −1 ≤ q̃ + δq̃ ≤ 1                (actuation limits)
//!
//! with q̃ = q / q_lim (each actuator in units of its limit: `tendon_displacement` for
//! bending, `base_translation` for translation), W the solver's residual row weights,
//! ỹ the leg unknowns scaled to unit weighted Jacobian columns and ε = 1e-2 (the
//! least-norm step's 1e-6 for q in metres, here for q in units of 10 mm): the least
//! change of q in units of its range, within the range.
//!
//! The QP has 9 bounded variables and one simple box, so it is solved first by a
//! primal–dual active-set search on the limits, started from the last step's active
//! limits (the first step of a run: the limits q is at): each trial solves the KKT system
//! with its active limits as equalities, drops a limit whose multiplier is negative and
//! adds one the step violates; a trial with neither is the QP's one minimizer (strictly
//! convex). Along a 30-step path of 1 mm steps it finds every step with one or two KKT
//! solves (24–45 µs on the loaded 2-core machine), bitwise the step clarabel and its
//! polish gave, where clarabel took 6–8 interior-point iterations and then the same KKT
//! solve (265–525 µs, 10–17× as long; BENCHMARKS.md, issue 19).
//! clarabel stays where it is the right tool: when the search repeats an active set,
//! meets a singular KKT system or spends [`StepQp::MAX_ACTIVE_SETS`] trials (degenerate
//! limits, and a QP with no feasible step, which the interior point method proves
//! infeasible); its solution identifies the active limits, and the step is then
//! recomputed exactly from the KKT system with those limits as equalities (if that step
//! respects the other limits). Either way the linearized boundary conditions hold to
//! round-off and Newton keeps its quadratic convergence. A backtracking line search on
//! the weighted residual only shortens steps, so every iterate stays within the limits
//! (a box is convex) once one is. Converged as every solve ([`NewtonSettings::tolerance`]).
//!
//! The limit rows G (±δq̃_j) are formed as a matrix only for clarabel, and a chord step
//! reuses the step matrix of the last Jacobian: with the least-change step's S by tiles
//! (`linalg::scaled_gram_lower`), the warm 1 mm step of the 9-DoF design took
//! 140–144 µs against 151–153 µs before (2026-11-26, sixth session).
//!
//! A run whose line search fails is run again with one-sided steps across tendon kinks
//! (`redundant::across_kinks` with this rule's QP; `Solver::across_kinks`; not from the
//! start, which would move the solutions pinned to earlier ones): warm 1 mm steps around
//! circles of 10–50 mm radius failed 60 times in 2 646 steps where a tendon pair passes
//! through both-slack, and none with the retry (a step shortened to its first kink
//! crossing is still within the limits: the box is convex and holds 0).

use std::cell::RefCell;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, ZeroConeT,
};
use nalgebra::{DMatrix, DVector};

use super::least_change::{FactorCache, scaled_step_matrix};
use super::redundant::{
    IkSystem, KinkSteps, LEAST_NORM_Y_WEIGHT, Objective, across_kinks, crosses_at_a_kink,
    solve_across_kinks,
};
use super::shooting::crosses_a_kink;
use super::state::RobotState;
use crate::error::{SolveError, StopReason};
use crate::model::Model;
use crate::newton::{NewtonReport, NewtonSettings, StepRule};

/// Weight ε of the scaled leg unknowns against q in units of its limits: the least-norm
/// step's weight (1e-6 against q in metres) for q of 10 mm.
const Y_WEIGHT: f64 = LEAST_NORM_Y_WEIGHT / (0.01 * 0.01);

/// The same weight in steps towards a reference: small, so that the boundary
/// conditions are met by the leg unknowns before q leaves the reference.
const REFERENCE_Y_WEIGHT: f64 = 1e-8;

/// IK of the system's pose within the limits, from `guess` (q and γ leg unknowns):
/// with [`Objective::ClosestTo`] first a run from the reference (clamped to the limits)
/// towards it, retried with one-sided steps where its line search fails across a
/// tendon's kink ([`solve_across_kinks`], as the least-change run; before 2026-11-28 such
/// a reference was given up); where it fails, a least-change run from `guess`, and then
/// the run towards the reference once more from that solution's leg unknowns (a cold
/// guess's are far from every solution; before 2026-11-28 the least-change solution was
/// returned, the reference ignored without a word). Where that fails too, the
/// least-change solution.
///
/// # Errors
/// [`SolveError::NotConverged`] when a QP step is infeasible (the pose needs q outside
/// its limits, to first order), the line search fails, or the iteration limit is reached;
/// [`SolveError::NonFinite`] if a leg integration blows up.
pub(super) fn within_limits_ik(
    system: &mut IkSystem<'_>,
    settings: &NewtonSettings,
    guess: RobotState,
    objective: &Objective,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let limits = actuation_limits(system.model);
    // A run from the reference (clamped to the limits) towards it, from leg unknowns
    // `y_u`: the solution, or the work of the failed run (its evaluations counted from
    // the system's tally since `before`).
    let toward_reference = |system: &mut IkSystem<'_>, reference: &[f64], y_u: &[f64]| {
        let q: Vec<f64> = reference
            .iter()
            .zip(&limits)
            .map(|(r, l)| r.clamp(-l, *l))
            .collect();
        let before = system.evaluated;
        let mut rule = QpStep::new(&limits, Some(reference), settings, &q);
        solve_across_kinks(system, &mut rule, settings, &q, y_u).map_err(|e| {
            let mut failed = NewtonReport::of_failed_run(&e, &system.evaluated);
            failed.residual_evaluations -= before.residual_evaluations;
            failed.jacobian_evaluations -= before.jacobian_evaluations;
            failed
        })
    };
    let reference = match objective {
        Objective::ClosestTo(r) if r.len() == limits.len() => Some(r.as_slice()),
        _ => None,
    };
    // The work of a first run towards the reference that failed.
    let mut spent = NewtonReport::none();
    if let Some(reference) = reference {
        match toward_reference(system, reference, &guess.y_u) {
            Ok(done) => return Ok(done),
            Err(failed) => spent = failed,
        }
    }
    let mut rule = QpStep::new(&limits, None, settings, &guess.q);
    match solve_across_kinks(system, &mut rule, settings, &guess.q, &guess.y_u) {
        Ok((state, mut report)) => {
            report.add_work(&spent);
            let Some(reference) = reference else {
                return Ok((state, report));
            };
            // The run from the reference failed from the guess's leg unknowns (a cold
            // guess is far from every solution: its first QP step can be infeasible);
            // once more from the least-change solution's, which the pull then leaves
            // only as far as the reference asks.
            match toward_reference(system, reference, &state.y_u) {
                Ok((pulled, mut pulled_report)) => {
                    pulled_report.add_work(&report);
                    Ok((pulled, pulled_report))
                }
                Err(failed) => {
                    report.add_work(&failed);
                    Ok((state, report))
                }
            }
        }
        Err(SolveError::NotConverged {
            iterations,
            residual_norm,
            tolerance,
            reason,
        }) => Err(SolveError::NotConverged {
            iterations: iterations + spent.iterations,
            residual_norm,
            tolerance,
            reason,
        }),
        Err(e) => Err(e),
    }
}

/// Symmetric limit of each actuator \[m\].
fn actuation_limits(model: &Model) -> Vec<f64> {
    (0..model.n_actuators())
        .map(|j| {
            if j % (model.pairs + 1) < model.pairs {
                model.limits.tendon_displacement
            } else {
                model.limits.base_translation
            }
        })
        .collect()
}

/// A scaled step matrix and its column scales ([`scaled_step_matrix`]).
type StepMatrix = (DMatrix<f64>, Vec<f64>);

/// The QP step within the limits: towards `reference` (least change without) for at most
/// half the iteration budget, then least-change steps.
struct QpStep<'a> {
    /// Symmetric limit of each actuator \[m\].
    limits: &'a [f64],
    /// The reference actuation \[m\] of [`Objective::ClosestTo`].
    reference: Option<&'a [f64]>,
    /// The run's iteration limit (the pull stops after half of it).
    max_iterations: usize,
    /// The limits active at the last step (rows of [`StepQp::g`]), where the next step's
    /// active-set search starts.
    active: Vec<usize>,
    /// The last KKT factorization (a chord step repeats the last step's QP).
    cache: FactorCache,
    /// The scaled step matrix and column scales of the last [`QpStep::step`]'s Jacobian,
    /// which the chord steps reuse (the driver takes them on that Jacobian only).
    matrix: Option<StepMatrix>,
    /// Whether steps across tendon kinks are one-sided and stop at the first crossing
    /// ([`across_kinks`]).
    one_sided: bool,
    /// Whether the last two-sided step took a tendon across its kink
    /// ([`KinkSteps::last_step_crossed_a_kink`]).
    crossed: bool,
}

impl<'a> QpStep<'a> {
    /// The rule of a run from `q` \[m\]: its first active-set search starts with the
    /// limits q is at.
    fn new(
        limits: &'a [f64],
        reference: Option<&'a [f64]>,
        settings: &NewtonSettings,
        q: &[f64],
    ) -> Self {
        Self {
            limits,
            reference,
            max_iterations: settings.max_iterations,
            active: Self::limits_at(limits, q),
            cache: FactorCache::default(),
            matrix: None,
            one_sided: false,
            crossed: false,
        }
    }

    /// The limits (rows of [`StepQp::g`]) that `q` \[m\] is at or beyond.
    fn limits_at(limits: &[f64], q: &[f64]) -> Vec<usize> {
        (0..limits.len())
            .flat_map(|j| {
                let q_tilde = q[j] / limits[j];
                (q_tilde >= 1.0)
                    .then_some(2 * j)
                    .into_iter()
                    .chain((q_tilde <= -1.0).then_some(2 * j + 1))
            })
            .collect()
    }

    /// The step from `x` with `matrix` (the scaled step matrix and its column scales).
    fn step_with(
        &mut self,
        matrix: &StepMatrix,
        x: &[f64],
        r: &DVector<f64>,
        weights: &DVector<f64>,
        iteration: usize,
    ) -> Result<Vec<f64>, StopReason> {
        let q = &x[..self.limits.len()];
        let towards = self
            .reference
            .filter(|_| 2 * iteration < self.max_iterations);
        let (a_eq, y_scale) = matrix;
        let mut qp = StepQp::new(a_eq, y_scale, weights, r, q, self.limits, towards);
        qp.cache = RefCell::new(std::mem::take(&mut self.cache));
        let z = match qp.solve_active_set(&mut self.active) {
            Some(z) => Ok(z),
            None => qp.solve().map(|(z, active)| {
                self.active = active;
                z
            }),
        };
        self.cache = qp.cache.take();
        let z = z?;
        let (mut dq, dy) = qp.unscale(&z);
        dq.extend(dy);
        Ok(dq)
    }
}

impl StepRule<IkSystem<'_>> for QpStep<'_> {
    fn step(
        &mut self,
        system: &IkSystem<'_>,
        x: &[f64],
        r: &DVector<f64>,
        weights: &DVector<f64>,
        iteration: usize,
    ) -> Result<Vec<f64>, StopReason> {
        let matrix = scaled_step_matrix(system.blocks, weights, self.limits);
        let step = self.step_with(&matrix, x, r, weights, iteration);
        self.matrix = Some(matrix);
        self.crossed = step
            .as_ref()
            .is_ok_and(|step| crosses_a_kink(system.model, system.model.n_actuators(), x, step));
        if !self.one_sided {
            return step;
        }
        let mut step = step?;
        let two_sided =
            crosses_at_a_kink(system, x, &step).then(|| (self.matrix.clone(), self.active.clone()));
        let one_sided = across_kinks(system, x, r, &mut step, |blocks, r| {
            let matrix = scaled_step_matrix(blocks, weights, self.limits);
            let step = self.step_with(&matrix, x, r, weights, iteration).ok();
            self.matrix = Some(matrix);
            step
        });
        if let (false, Some(two_sided)) = (one_sided, two_sided) {
            (self.matrix, self.active) = two_sided;
        }
        Ok(step)
    }

    /// The QP step from `x` with the step matrix of the last [`QpStep::step`] (the
    /// Jacobian the driver's chord steps are taken on; the same matrix as built from the
    /// blocks the system still holds, without building it again).
    fn chord_step(
        &mut self,
        system: &IkSystem<'_>,
        x: &[f64],
        r: &DVector<f64>,
        weights: &DVector<f64>,
        iteration: usize,
    ) -> Option<Vec<f64>> {
        let matrix = match self.matrix.take() {
            Some(matrix) => matrix,
            None => scaled_step_matrix(system.blocks, weights, self.limits),
        };
        let step = self.step_with(&matrix, x, r, weights, iteration).ok();
        self.matrix = Some(matrix);
        step
    }
}

impl KinkSteps for QpStep<'_> {
    /// Only in the retry of a failed run: the within-limits solutions are pinned to
    /// earlier ones where both converge (issue 19: q within 1e-9 m), and one-sided steps
    /// from the first run moved the path of `tests/redundant_path.rs` by 8.4e-7 m.
    fn one_sided_first(&self) -> bool {
        false
    }

    fn set_one_sided(&mut self, on: bool) {
        self.one_sided = on;
    }

    /// A run from `q` as [`QpStep::new`] starts it.
    fn restart(&mut self, q: &[f64]) {
        self.active = Self::limits_at(self.limits, q);
        self.cache = FactorCache::default();
        self.matrix = None;
    }

    fn last_step_crossed_a_kink(&self) -> bool {
        self.crossed
    }
}

/// One Newton step's QP in the scaled variables z = \[δq̃ (n_q), δỹ (n_y)\]:
/// minimize ½ zᵀ P z + cᵀ z subject to A z = b_eq and G z ≤ h, G's rows ±δq̃_j
/// ([`StepQp::limit_row`]; as a matrix only for clarabel).
struct StepQp<'a> {
    /// Diagonal of P.
    p: Vec<f64>,
    /// c: q̃ − r̃ towards a reference, else 0.
    c: Vec<f64>,
    /// Equality rows (m × n): W \[B_q L, B_u S\].
    a_eq: &'a DMatrix<f64>,
    /// −W b.
    b_eq: Vec<f64>,
    /// 1 ∓ q̃_j (row 2j: δq̃_j ≤ h, row 2j + 1: −δq̃_j ≤ h).
    h: Vec<f64>,
    /// Actuator limits L \[m\].
    limits: &'a [f64],
    /// Column scales S of δy.
    y_scale: &'a [f64],
    /// The KKT factorizations of the trials, reused where they repeat.
    cache: RefCell<FactorCache>,
}

impl<'a> StepQp<'a> {
    /// The QP of the step matrix `a_eq` and its column scales `y_scale`
    /// ([`scaled_step_matrix`] with q in units of `limits`) at residual `r` and actuation
    /// `q`.
    fn new(
        a_eq: &'a DMatrix<f64>,
        y_scale: &'a [f64],
        weights: &DVector<f64>,
        r: &DVector<f64>,
        q: &[f64],
        limits: &'a [f64],
        reference: Option<&[f64]>,
    ) -> Self {
        let (nq, m) = (q.len(), r.len());
        let n = a_eq.ncols();
        let b_eq = (0..m).map(|i| -weights[i] * r[i]).collect();
        let y_weight = if reference.is_some() {
            REFERENCE_Y_WEIGHT
        } else {
            Y_WEIGHT
        };
        let mut p = vec![y_weight; n];
        p[..nq].fill(1.0);
        let mut c = vec![0.0; n];
        if let Some(r) = reference {
            for j in 0..nq {
                c[j] = (q[j] - r[j]) / limits[j];
            }
        }
        let mut h = vec![0.0; 2 * nq];
        for j in 0..nq {
            let q_tilde = q[j] / limits[j];
            h[2 * j] = 1.0 - q_tilde;
            h[2 * j + 1] = 1.0 + q_tilde;
        }
        Self {
            p,
            c,
            a_eq,
            b_eq,
            h,
            limits,
            y_scale,
            cache: RefCell::default(),
        }
    }

    /// (G z)_i = ±z_j for limit row i (j = i / 2, + for even i): the value G's row gives
    /// (its other entries are zeros), without the matrix.
    fn limit_row(i: usize, z: &DVector<f64>) -> f64 {
        if i % 2 == 0 { z[i / 2] } else { -z[i / 2] }
    }

    /// G (2 n_q × n) as a matrix.
    fn limit_rows(&self) -> DMatrix<f64> {
        let mut g = DMatrix::zeros(self.h.len(), self.a_eq.ncols());
        for i in 0..self.h.len() {
            g[(i, i / 2)] = if i % 2 == 0 { 1.0 } else { -1.0 };
        }
        g
    }

    /// Most active sets one search tries before it gives up (to clarabel).
    const MAX_ACTIVE_SETS: usize = 8;

    /// The step z by a primal–dual active-set search from `active` (rows of `g`; on
    /// success the solution's active limits): each trial solves the KKT system with its
    /// limits as equalities ([`StepQp::kkt`]), then drops the limits whose multiplier is
    /// negative and adds those the step violates. A trial with neither satisfies the KKT
    /// conditions of this strictly convex QP, so its z is the one minimizer. `None` when
    /// a KKT system is singular or its solution misses A z = b
    /// ([`StepQp::meets_the_equalities`]), a set repeats or [`Self::MAX_ACTIVE_SETS`] are spent
    /// (the caller then asks clarabel, which also tells an infeasible QP).
    fn solve_active_set(&self, active: &mut Vec<usize>) -> Option<DVector<f64>> {
        let mut tried: Vec<Vec<usize>> = Vec::new();
        for _ in 0..Self::MAX_ACTIVE_SETS {
            let (z, mu) = self.kkt(active)?;
            if !self.meets_the_equalities(&z) {
                return None;
            }
            let mut next: Vec<usize> = active
                .iter()
                .zip(&mu)
                .filter(|(_, mu)| **mu >= 0.0)
                .map(|(&i, _)| i)
                .collect();
            let kept = next.len();
            for i in 0..self.h.len() {
                if !active.contains(&i) && self.h[i] - Self::limit_row(i, &z) < 0.0 {
                    next.push(i);
                }
            }
            if kept == active.len() && next.len() == kept {
                return Some(z);
            }
            next.sort_unstable();
            tried.push(std::mem::replace(active, next));
            if tried.contains(active) {
                return None;
            }
        }
        None
    }

    /// Whether A z = b holds to 1e-9 (relative to 1 + ‖b‖∞): a trial whose free
    /// variables cannot meet the linearized boundary conditions (A without the fixed
    /// columns loses rank, which its Cholesky may not reveal) is no step.
    fn meets_the_equalities(&self, z: &DVector<f64>) -> bool {
        let b_max = self.b_eq.iter().fold(0.0f64, |max, b| max.max(b.abs()));
        // A z column by column (each row's sum in the order of j, as nalgebra's gemv),
        // into a buffer on the stack where it fits.
        let mut stack = [0.0; 64];
        let mut heap = Vec::new();
        let az = if self.b_eq.len() <= stack.len() {
            &mut stack[..self.b_eq.len()]
        } else {
            heap.resize(self.b_eq.len(), 0.0);
            &mut heap[..]
        };
        for (column, z) in self.a_eq.as_slice().chunks_exact(az.len()).zip(z.iter()) {
            for (acc, a) in az.iter_mut().zip(column) {
                *acc += a * z;
            }
        }
        let worst = az
            .iter()
            .zip(&self.b_eq)
            .fold(0.0f64, |max, (az, b)| max.max((az - b).abs()));
        worst <= 1e-9 * (1.0 + b_max)
    }

    /// The step z and its active limits: clarabel's solution, polished on its active set.
    fn solve(&self) -> Result<(DVector<f64>, Vec<usize>), StopReason> {
        let (m, n) = self.a_eq.shape();
        let k = self.h.len();
        let mut a = DMatrix::zeros(m + k, n);
        a.rows_mut(0, m).copy_from(self.a_eq);
        a.rows_mut(m, k).copy_from(&self.limit_rows());
        let b: Vec<f64> = self.b_eq.iter().chain(&self.h).copied().collect();
        let p = CscMatrix::new(n, n, (0..=n).collect(), (0..n).collect(), self.p.clone());
        let settings = DefaultSettings {
            verbose: false,
            ..DefaultSettings::default()
        };
        let mut solver = DefaultSolver::new(
            &p,
            &self.c,
            &dense_to_csc(&a),
            &b,
            &[ZeroConeT(m), NonnegativeConeT(k)],
            settings,
        )
        .map_err(|_| StopReason::QpStepFailed)?;
        solver.solve();
        let sol = &solver.solution;
        match sol.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {}
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                return Err(StopReason::NoStepWithinLimits);
            }
            _ => return Err(StopReason::QpStepFailed),
        }
        // Active limits: slack below its multiplier (complementarity).
        let active: Vec<usize> = (0..k).filter(|&i| sol.s[m + i] < sol.z[m + i]).collect();
        let z = self
            .polish(&active)
            .unwrap_or_else(|| DVector::from_column_slice(&sol.x));
        Ok((z, active))
    }

    /// The exact minimizer with the `active` limits as equalities, if it respects the
    /// others.
    fn polish(&self, active: &[usize]) -> Option<DVector<f64>> {
        let z = self.kkt(active)?.0;
        let feasible = (0..self.h.len()).all(|i| self.h[i] - Self::limit_row(i, &z) >= -1e-9)
            && z.iter().all(|x| x.is_finite());
        feasible.then_some(z)
    }

    /// The step z (n) and the multiplier μ of each `active` limit, of the QP with the
    /// `active` limits as equalities ([`LeastChange`]), or `None` if A without the fixed
    /// columns loses rank (or both limits of one actuator are given). Stationarity
    /// P z + c + Aᵀλ + Gᵀμ = 0: a limit holds the step back where its μ ≥ 0.
    fn kkt(&self, active: &[usize]) -> Option<(DVector<f64>, Vec<f64>)> {
        let n = self.a_eq.ncols();
        let mut fixed = vec![false; n];
        let mut values = vec![0.0; n];
        for &i in active {
            // Row 2j is δq̃_j ≤ h, row 2j + 1 is −δq̃_j ≤ h.
            let (j, sign) = (i / 2, if i % 2 == 0 { 1.0 } else { -1.0 });
            if fixed[j] {
                return None;
            }
            fixed[j] = true;
            values[j] = sign * self.h[i];
        }
        let (z, lambda) = self
            .cache
            .borrow_mut()
            .factor(self.a_eq, &self.p, &fixed)?
            .solve(self.a_eq, &self.p, &self.c, &self.b_eq, &values)?;
        let mu = active
            .iter()
            .map(|&i| {
                let (j, sign) = (i / 2, if i % 2 == 0 { 1.0 } else { -1.0 });
                -sign * (self.p[j] * z[j] + self.c[j] + self.a_eq.column(j).dot(&lambda))
            })
            .collect();
        Some((z, mu))
    }

    /// δq \[m\] and δy (solver variables) of a scaled step.
    fn unscale(&self, z: &DVector<f64>) -> (Vec<f64>, Vec<f64>) {
        let nq = self.limits.len();
        let dq = (0..nq).map(|j| z[j] * self.limits[j]).collect();
        let dy = self
            .y_scale
            .iter()
            .enumerate()
            .map(|(j, s)| z[nq + j] * s)
            .collect();
        (dq, dy)
    }
}

/// A dense matrix in clarabel's compressed-column form (zeros dropped).
fn dense_to_csc(a: &DMatrix<f64>) -> CscMatrix<f64> {
    let (m, n) = a.shape();
    let mut colptr = Vec::with_capacity(n + 1);
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    colptr.push(0);
    for j in 0..n {
        for i in 0..m {
            let v = a[(i, j)];
            if v != 0.0 {
                rowval.push(i);
                nzval.push(v);
            }
        }
        colptr.push(nzval.len());
    }
    CscMatrix::new(m, n, colptr, rowval, nzval)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boundary::BoundaryJacobians;

    /// Deterministic numbers in [−1, 1) (a linear congruential generator).
    fn numbers(seed: u64, count: usize) -> Vec<f64> {
        let mut state = seed;
        (0..count)
            .map(|_| {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
            })
            .collect()
    }

    /// The inputs of a QP of 6 rows, 4 actuators (limit 10 mm, q near the limits) and 4
    /// leg unknowns: the step matrix and its column scales, the residual and q.
    fn qp_inputs(seed: u64) -> (StepMatrix, DVector<f64>, Vec<f64>) {
        let (m, nq, ny) = (6, 4, 4);
        let v = numbers(seed, m * (nq + ny) + m + nq);
        let blocks = BoundaryJacobians {
            b_x: DMatrix::zeros(m, 6),
            b_q: DMatrix::from_column_slice(m, nq, &v[..m * nq]),
            b_w: DMatrix::zeros(m, 6),
            b_u: DMatrix::from_column_slice(m, ny, &v[m * nq..m * (nq + ny)]),
        };
        let r = DVector::from_column_slice(&v[m * (nq + ny)..m * (nq + ny) + m]) * 0.02;
        let q: Vec<f64> = v[m * (nq + ny) + m..]
            .iter()
            .map(|x| 0.0095 * x.signum() + 0.0005 * x)
            .collect();
        let matrix = scaled_step_matrix(&blocks, &DVector::from_element(m, 1.0), &LIMITS);
        (matrix, r, q)
    }

    const LIMITS: [f64; 4] = [0.01; 4];

    #[test]
    fn the_active_set_step_is_clarabels_and_respects_the_limits() {
        let mut with_active_limits = 0;
        for seed in 0..40 {
            let ((a, y_scale), r, q) = qp_inputs(seed);
            let weights = DVector::from_element(r.len(), 1.0);
            let qp = StepQp::new(&a, &y_scale, &weights, &r, &q, &LIMITS, None);
            let mut active = Vec::new();
            let Some(z) = qp.solve_active_set(&mut active) else {
                continue;
            };
            let (reference, _) = qp.solve().unwrap();
            let difference = (&z - &reference).amax();
            assert!(difference < 1e-7, "seed {seed}: |Δz| = {difference:e}");
            let slack = DVector::from_column_slice(&qp.h) - qp.limit_rows() * &z;
            assert!(slack.min() >= -1e-12, "seed {seed}: slack {}", slack.min());
            if !active.is_empty() {
                with_active_limits += 1;
            }
        }
        assert!(
            with_active_limits >= 5,
            "{with_active_limits} QPs with active limits"
        );
    }
}
