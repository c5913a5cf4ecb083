//! Walking a ray (or the path along z): one IK step to the next grid point, warm-started
//! from the predictor ([`super::predict`]), its Newton run from the Jacobians at the last
//! solutions extrapolated likewise ([`super::chord_jacobian`]), with a probe of its first
//! iterations ([`WorkspaceSettings::probe_iterations`]), the fallback in [`SUBSTEPS`]
//! substeps, the validity of each solved point (actuation limits, collisions, stability)
//! and the [`Worker`] that does it with its own solver and buffers.

use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::boundary::BoundaryJacobians;
use crate::design::Tdpcr;
use crate::error::{Error, SolveError, StopReason};
use crate::kinetostatics::{RobotState, Solution, Solver};
use crate::model::{Model, Pose};
use crate::newton::{NewtonReport, NewtonSettings, ProgressCheck};
use crate::rod::tendon::tension;
use crate::rod::{ShapeDetail, Wrench};

use super::chord_jacobian::JacobianHistory;
use super::collision::CollisionChecker;
use super::ends::End;
use super::kink_start::KinkStart;
use super::metrics::{AnalysisSettings, PointMetrics, complete_scaled, point_metrics_deferred};
use super::predict::{PREDICTOR_POINTS, in_zeta, max_difference, predict, predicted_state};
use super::settings::{CollisionPolicy, WorkspaceSettings};

/// Counters shared by the workers (summed; their totals do not depend on the schedule).
#[derive(Debug, Default)]
pub(super) struct Work {
    /// IK solves (Newton runs, including failed ones and retries).
    pub(super) solves: AtomicUsize,
    /// Newton iterations of the converged solves.
    pub(super) iterations: AtomicUsize,
    /// Jacobian evaluations of the converged solves.
    pub(super) jacobians: AtomicUsize,
    /// Residual evaluations of the converged solves.
    pub(super) residuals: AtomicUsize,
    /// The work of the solves that found no solution.
    pub(super) failed: FailedWork,
    /// Solutions whose legs were integrated once more to check collisions at the disks
    /// (their knots could not rule one out).
    pub(super) collision_integrations: AtomicUsize,
}

/// Newton iterations, residual and Jacobian evaluations of the solves without a solution.
#[derive(Debug, Default)]
pub(super) struct FailedWork {
    pub(super) iterations: AtomicUsize,
    pub(super) residuals: AtomicUsize,
    pub(super) jacobians: AtomicUsize,
}

impl Work {
    /// Counts a converged solve's work.
    pub(super) fn add(&self, r: &NewtonReport) {
        self.iterations.fetch_add(r.iterations, Ordering::Relaxed);
        self.jacobians
            .fetch_add(r.jacobian_evaluations, Ordering::Relaxed);
        self.residuals
            .fetch_add(r.residual_evaluations, Ordering::Relaxed);
    }

    /// Counts the work of a solve that found no solution (all its runs).
    pub(super) fn add_failed(&self, r: &NewtonReport) {
        let f = &self.failed;
        f.iterations.fetch_add(r.iterations, Ordering::Relaxed);
        f.jacobians
            .fetch_add(r.jacobian_evaluations, Ordering::Relaxed);
        f.residuals
            .fetch_add(r.residual_evaluations, Ordering::Relaxed);
    }
}

/// One solved point of a ray (or a plane origin) and its measures.
#[derive(Debug, Clone)]
pub(super) struct Sample {
    /// The solved configuration.
    pub(super) state: RobotState,
    /// The disks collide.
    pub(super) collision: bool,
    /// rcond, singularity flags, stability and minimum tension; the unit-scaled rconds of
    /// the block matrices are NaN while `scaled_pending` holds the blocks they need.
    pub(super) metrics: PointMetrics,
    /// The exact blocks at `state`, until the unit-scaled rconds are computed from them
    /// ([`Sample::complete_metrics`]; only for the points that represent cells).
    pub(super) scaled_pending: Option<Box<BoundaryJacobians>>,
}

impl Sample {
    /// The point's measures with the unit-scaled rconds filled in.
    pub(super) fn complete_metrics(&self, model: &Model) -> PointMetrics {
        let mut metrics = self.metrics;
        if let Some(blocks) = &self.scaled_pending {
            complete_scaled(model, &mut metrics, blocks);
        }
        metrics
    }

    /// Why this point ends its ray (or the path to the planes), if it does.
    pub(super) fn end(&self, collisions: CollisionPolicy) -> Option<End> {
        if !self.metrics.stable {
            Some(End::Unstable)
        } else if self.collision && collisions == CollisionPolicy::Stop {
            Some(End::Collision)
        } else {
            None
        }
    }
}

/// A ray's solved points in order (steps 1, 2, ...) and why it ended.
#[derive(Debug, Clone)]
pub(super) struct Ray {
    /// The solved points, step 1 first.
    pub(super) samples: Vec<Sample>,
    /// Why the ray ended.
    pub(super) end: End,
    /// The message of an [`End::Failed`].
    pub(super) error: Option<String>,
}

impl Ray {
    /// A ray not followed (a sweep asked to stop; its result is not returned).
    pub(super) fn skipped() -> Self {
        Self {
            samples: Vec::new(),
            end: End::Failed,
            error: None,
        }
    }
}

/// A solver and collision buffers; cloned once per rayon job split.
#[derive(Debug, Clone)]
pub(super) struct Worker {
    /// The IK solver, with the sweep's tolerance and iteration budget.
    pub(super) solver: Solver,
    /// Collision buffers.
    collisions: CollisionChecker,
    /// The exact Jacobians at the last solutions on the path being walked.
    jacobians: JacobianHistory,
    /// The start of a step across tendons' kinks from the last solution.
    kinks: KinkStart,
    /// Singularity thresholds of the per-point measures.
    analysis: AnalysisSettings,
    /// [`WorkspaceSettings::probe_iterations`].
    pub(super) probe_iterations: usize,
    /// The message of the last [`End::Failed`].
    pub(super) error: Option<String>,
}

impl Worker {
    /// A worker with the solver set up for `settings`.
    pub(super) fn new(design: &Tdpcr, settings: &WorkspaceSettings) -> Result<Self, Error> {
        let mut solver = Solver::new(design)?;
        solver.settings.tolerance = settings.tolerance;
        solver.settings.max_iterations = settings.max_iterations;
        solver.settings.chord_contraction = settings.chord_contraction;
        solver.redundancy = settings.redundancy.clone();
        // The least-norm rays keep their Gauss–Newton steps: steps from the start's
        // Jacobian saved 1 % of the 9-DoF sweep's time (35.5 against 36.0 s) and put 4.5 %
        // of its cells on other solutions along the rays (4 909 lost, 4 740 gained;
        // BENCHMARKS.md "Least-norm steps from the start's Jacobian").
        solver.least_norm_gauss_newton = true;
        // A 9-DoF step whose Gauss–Newton run fails on a step across a tendon's kink is
        // retried with one-sided steps (`Solver::across_kinks`; the runs that converge
        // keep their solutions): before, its ray ended there as not converged, at 3 263 of
        // the free sweep's rays (BENCHMARKS.md "The 9-DoF sweeps across tendon kinks").
        solver.across_kinks = settings.one_sided_kinks;
        solver.one_sided_kinks = settings.one_sided_kinks;
        // A step whose solution is certainly beyond the limits ends its ray as the
        // solution itself would (`classify`), a few iterations sooner.
        solver.stop_beyond_limits = true;
        // Every solution within the limits is analysed (`classify`): its Newton run's
        // expected last residual integrates what that analysis needs.
        solver.prepare_for_analysis(true);
        let collisions = CollisionChecker::new(solver.model());
        let jacobians = JacobianHistory::new(solver.model());
        let kinks = KinkStart::new(solver.model());
        Ok(Self {
            solver,
            collisions,
            jacobians,
            kinks,
            analysis: settings.analysis,
            probe_iterations: settings.probe_iterations,
            error: None,
        })
    }

    /// [`End::Limits`] for a solve stopped because its solution is beyond the actuation
    /// limits ([`Solver::stop_beyond_limits`]), [`End::NotConverged`] for one that stopped
    /// without a solution, [`End::Failed`] (keeping the message) for any other error.
    fn end_of(&mut self, e: Error) -> End {
        match e {
            Error::Solve(SolveError::NotConverged {
                reason: StopReason::BeyondActuationLimits,
                ..
            }) => End::Limits,
            Error::Solve(SolveError::NotConverged { .. }) => End::NotConverged,
            other => {
                self.error = Some(other.to_string());
                End::Failed
            }
        }
    }

    /// Validity of a solved state (actuation limits, then collisions) and its measures.
    pub(super) fn classify(
        &mut self,
        model: &Model,
        state: RobotState,
        work: &Work,
    ) -> Result<Sample, End> {
        if !model.within_limits(&state.q) {
            return Err(End::Limits);
        }
        // The analysis records the legs' knots (free: the states at the integration's
        // step ends); where they cannot rule out a collision, the legs are integrated
        // once more to their disks.
        self.solver.record_shape_detail(Some(ShapeDetail::Knots));
        let metrics = point_metrics_deferred(&mut self.solver, &state, &self.analysis);
        let clear = self
            .solver
            .shapes()
            .is_some_and(|shapes| self.collisions.clear_by_knots(model, &state, shapes));
        self.solver.record_shape_detail(None);
        let (metrics, scaled_pending) = match metrics {
            Ok(m) => m,
            Err(e) => return Err(self.end_of(e)),
        };
        // The next step's Newton run starts from the exact Jacobians at the last
        // solutions, extrapolated to the next point.
        self.jacobians.push(model, &self.solver, &state);
        self.jacobians.seed(&mut self.solver);
        self.kinks.record(model, &self.solver, &state);
        let collision = !clear && {
            work.collision_integrations.fetch_add(1, Ordering::Relaxed);
            match self.collisions.check(model, &state) {
                Ok(c) => c.is_some(),
                Err(e) => return Err(self.end_of(e.into())),
            }
        };
        Ok(Sample {
            state,
            collision,
            metrics,
            scaled_pending,
        })
    }

    /// One path step to `position`: IK from `start` if given, else from a prediction
    /// extrapolated from the last solutions on the path (`history`, oldest first, at
    /// equal steps), with a progress check after `probe` iterations
    /// ([`WorkspaceSettings::probe_iterations`] for rays, at least the default for the path
    /// along z).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn step(
        &mut self,
        model: &Model,
        rotation: &Matrix3<f64>,
        position: Vector3<f64>,
        history: &[&RobotState],
        start: Option<&RobotState>,
        probe: usize,
        work: &Work,
    ) -> Result<Sample, End> {
        let pose = Pose {
            position,
            rotation: *rotation,
        };
        let last = history[history.len() - 1];
        let predicted = match start {
            Some(_) => None,
            None => {
                predict(model, history).map(|p| self.across_kinks(model, history, p, &position))
            }
        };
        let guess = start.or(predicted.as_ref()).unwrap_or(last);
        // The full budget only if the first iterations made progress.
        let newton = NewtonSettings {
            progress_check: (history.len() > 1).then_some(ProgressCheck {
                iterations: probe,
                factor: PROBE_PROGRESS,
            }),
            ..self.solver.settings
        };
        let sol = self
            .solve_on_branch(&pose, guess, &newton, history, work)
            .map_err(|e| self.end_of(e))?;
        self.classify(model, sol.state, work)
    }

    /// `predicted` (from `history`) taken across one or two tendons' kinks where
    /// [`KinkStart::across`] does, the solver's seeded Jacobian given those tendons'
    /// other columns; else `predicted` as it is.
    fn across_kinks(
        &mut self,
        model: &Model,
        history: &[&RobotState],
        predicted: RobotState,
        position: &Vector3<f64>,
    ) -> RobotState {
        let last = history[history.len() - 1];
        match self.kinks.across(model, last, &predicted, position) {
            Some(start) => {
                self.jacobians
                    .seed_with_columns(&mut self.solver, self.kinks.columns());
                start
            }
            None => predicted,
        }
    }

    /// The IK of a path step from `guess` (the prediction from `history`), first with
    /// one-sided kink columns ([`Solver::one_sided_kinks`]), then, where that run took
    /// such a column and either its trust region collapsed or it landed farther from the
    /// prediction than [`BRANCH_JUMP`] × the last step's change of q (a ray's first step:
    /// × the predicted change), again without them: the solution nearer to the
    /// prediction is kept (each run's work is counted).
    /// Measured on the ψ = 0 twin's full Δ = 3 mm sweep: of 1 972 one-sided runs whose
    /// trust region collapsed, the two-sided run converged at 1 144; of the 2 695 that
    /// failed otherwise (too little progress, the iteration limit), at 287 only, and
    /// retrying those too made the sweep 7 % slower than two-sided runs alone.
    fn solve_on_branch(
        &mut self,
        pose: &Pose,
        guess: &RobotState,
        newton: &NewtonSettings,
        history: &[&RobotState],
        work: &Work,
    ) -> Result<Solution, Error> {
        let zero = Wrench::default();
        let first = self.solver.solve_ik_newton_with(pose, &zero, guess, newton);
        work.solves.fetch_add(1, Ordering::Relaxed);
        if first.is_err() {
            work.add_failed(self.solver.last_call_work());
        }
        let jump = |s: &Solution| max_difference(&s.state.q, &guess.q);
        let suspect = match &first {
            Ok(s) => match history {
                [.., before, last] => jump(s) > BRANCH_JUMP * max_difference(&last.q, &before.q),
                // A ray's first step from its plane's start: the predicted change (0
                // without a start, the path along z's first step and a first substep:
                // every one-sided run there is checked).
                [last] => jump(s) > BRANCH_JUMP * max_difference(&guess.q, &last.q),
                [] => false,
            },
            Err(Error::Solve(SolveError::NotConverged { reason, .. })) => {
                *reason == StopReason::TrustRegionCollapsed
            }
            Err(_) => false,
        };
        if !(suspect && self.solver.one_sided_columns_used() > 0) {
            if let Ok(s) = &first {
                work.add(&s.report);
            }
            return first;
        }
        // The same run as the first, two-sided: from the same extrapolated Jacobian, and
        // to its end (its solution is compared with the first's even beyond the limits).
        self.jacobians.seed(&mut self.solver);
        let one_sided = std::mem::replace(&mut self.solver.one_sided_kinks, false);
        let stop = std::mem::replace(&mut self.solver.stop_beyond_limits, false);
        let second = self.solver.solve_ik_newton_with(pose, &zero, guess, newton);
        self.solver.one_sided_kinks = one_sided;
        self.solver.stop_beyond_limits = stop;
        work.solves.fetch_add(1, Ordering::Relaxed);
        if second.is_err() {
            work.add_failed(self.solver.last_call_work());
        }
        for s in [&first, &second].into_iter().flatten() {
            work.add(&s.report);
        }
        match (first, second) {
            (Ok(a), Ok(b)) => Ok(if jump(&b) < jump(&a) { b } else { a }),
            (Ok(a), Err(_)) => Ok(a),
            (Err(_), second) => second,
        }
    }

    /// A ray step from the solution `last` to `position` in [`SUBSTEPS`] equal substeps,
    /// each predicted from the substeps before: the fallback where the whole step does
    /// not converge. Steps that switch a tendon pair's taut side near where the
    /// leg-singularity lines of several legs meet need it: a plane origin can lie there
    /// (the reference design at z ≈ −54 mm: every leg's slack tendon within 8 µm of
    /// taut), and the first step then failed in 109 of 180 directions (1142 cells against
    /// 2441 and 2582 on the neighbouring planes; 2535 with the fallback); on z = −42 mm
    /// the rays crossing three such meeting points failed at their fourth step (2489
    /// cells against 2747 and 2820).
    fn step_in_substeps(
        &mut self,
        model: &Model,
        rotation: &Matrix3<f64>,
        last: &RobotState,
        position: Vector3<f64>,
        work: &Work,
    ) -> Result<Sample, End> {
        // The substeps are shorter: their Jacobians are extrapolated among themselves.
        self.jacobians.clear();
        let probe = self.probe_iterations;
        let start = Vector3::from(last.position);
        let mut path = vec![last.clone()];
        for m in 1..=SUBSTEPS {
            let t = m as f64 / SUBSTEPS as f64;
            let from = path.len().saturating_sub(PREDICTOR_POINTS);
            let history: Vec<&RobotState> = path[from..].iter().collect();
            let sample = self.step(
                model,
                rotation,
                start + (position - start) * t,
                &history,
                None,
                probe,
                work,
            )?;
            if m == SUBSTEPS {
                // The next full step starts from this point's Jacobian alone (the solver's
                // blocks are still its analysis').
                self.jacobians.clear();
                self.jacobians.push(model, &self.solver, &sample.state);
                self.jacobians.seed(&mut self.solver);
                return Ok(sample);
            }
            path.push(sample.state);
        }
        unreachable!("the loop returns at its last substep")
    }

    /// The [`RayStart`] of the plane whose origin is `origin` (`None` where the IK
    /// Jacobian there is not available or singular: the rays then start as without).
    pub(super) fn ray_start(&mut self, model: &Model, origin: &RobotState) -> Option<RayStart> {
        let (_, blocks) = self.solver.blocks_at(origin, &Wrench::default()).ok()?;
        let b_x = blocks.b_x.clone();
        let n = model.n_residuals();
        let mut jacobian = DMatrix::zeros(n, n);
        if !self.solver.ik_jacobian_from_blocks(origin, &mut jacobian) {
            return None;
        }
        let lu = jacobian.clone().lu();
        let tangent = |axis: usize| {
            let t = lu.solve(&(-b_x.column(axis)))?;
            t.iter().all(|v| v.is_finite()).then_some(t)
        };
        Some(RayStart {
            tangents: [tangent(0)?, tangent(1)?],
            jacobian,
        })
    }

    /// Ray j from the plane origin `origin`, its first step started from the plane's
    /// `start` if there is one.
    pub(super) fn follow_ray(
        &mut self,
        model: &Model,
        settings: &WorkspaceSettings,
        origin: &Sample,
        start: Option<&RayStart>,
        j: usize,
        work: &Work,
    ) -> Ray {
        let theta = j as f64 * settings.angle_step;
        let (c, s) = (theta.cos(), theta.sin());
        let z = origin.state.position[2];
        let rotation = settings.rotation();
        let max_steps = (max_radius(model) / settings.step).ceil() as usize;
        // Within the ray each step may start from the Jacobian of the step before; the
        // first from the origin's (the same for every ray of the plane), so the ray does
        // not depend on what this worker solved before (the map is the same for any
        // thread count and schedule).
        self.solver.forget_jacobian();
        self.jacobians.clear();
        let first = start.map(|st| {
            self.jacobians
                .push_jacobian(model, &origin.state, &st.jacobian);
            self.jacobians.seed(&mut self.solver);
            st.guess(model, &origin.state, settings.step * c, settings.step * s)
        });
        let mut samples: Vec<Sample> = Vec::new();
        for i in 1..=max_steps {
            let r = i as f64 * settings.step;
            let position = Vector3::new(r * c, r * s, z);
            let n = samples.len();
            let history: Vec<&RobotState> = std::iter::once(&origin.state)
                .chain(samples.iter().map(|s| &s.state))
                .skip((n + 1).saturating_sub(PREDICTOR_POINTS))
                .collect();
            let start = if i == 1 { first.as_ref() } else { None };
            let probe = self.probe_iterations;
            let result = match self.step(model, &rotation, position, &history, start, probe, work) {
                Err(End::NotConverged) => {
                    let last = samples.last().unwrap_or(origin);
                    self.step_in_substeps(model, &rotation, &last.state, position, work)
                }
                result => result,
            };
            match result {
                Ok(mut sample) => {
                    let previous = samples.last_mut();
                    let before = previous.as_ref().map_or(&origin.state, |p| &p.state);
                    if taut_side_changed(model, before, &sample.state) {
                        flag_leg_switch(&mut sample.metrics);
                        if let Some(p) = previous {
                            flag_leg_switch(&mut p.metrics);
                        }
                    }
                    let end = sample.end(settings.collisions);
                    samples.push(sample);
                    if let Some(end) = end {
                        return Ray {
                            samples,
                            end,
                            error: None,
                        };
                    }
                }
                Err(end) => {
                    let error = (end == End::Failed).then(|| self.error.take()).flatten();
                    return Ray {
                        samples,
                        end,
                        error,
                    };
                }
            }
        }
        Ray {
            samples,
            end: End::MaxRadius,
            error: None,
        }
    }
}

/// A step's Newton run gets the full [`WorkspaceSettings::max_iterations`] only if its
/// first [`WorkspaceSettings::probe_iterations`] iterations reduced ‖b‖ by
/// [`PROBE_PROGRESS`] ([`ProgressCheck`]): steps beyond a fold of the IK (no solution)
/// crawl at their first residual, while the slow steps across a leg-singularity line make
/// progress first.
const PROBE_PROGRESS: f64 = 10.0;

/// The start of every ray of a plane: the exact IK Jacobian at the plane's origin (in the
/// solver's unknowns) and the tangents of the solution there along x and y, from which
/// each ray's first step starts (a first-order prediction with that Jacobian instead of
/// the origin itself and a Jacobian of its own). Computed once per plane from the origin
/// alone, so every ray still depends only on its plane.
pub(super) struct RayStart {
    /// J = ∂b/∂[q, ζ] at the origin.
    jacobian: DMatrix<f64>,
    /// ∂[q, ζ]/∂x and ∂[q, ζ]/∂y at the origin: J t = −∂b/∂x.
    tangents: [DVector<f64>; 2],
}

impl RayStart {
    /// The first-order prediction of the solution at `origin` moved by (dx, dy) \[m\]:
    /// as [`predict`], a tendon predicted across its kink starts at the kink (ζ = 0).
    fn guess(&self, model: &Model, origin: &RobotState, dx: f64, dy: f64) -> RobotState {
        let nq = model.n_actuators();
        let [tx, ty] = &self.tangents;
        let step = |i: usize| dx * tx[i] + dy * ty[i];
        let zeta = in_zeta(model, origin);
        let y_u = zeta
            .iter()
            .enumerate()
            .map(|(i, y)| y + step(nq + i))
            .collect();
        let q = origin
            .q
            .iter()
            .enumerate()
            .map(|(i, q)| q + step(i))
            .collect();
        predicted_state(model, origin, &zeta, q, y_u)
    }
}

/// A path step's one-sided run ([`Worker::solve_on_branch`]) is checked against the
/// two-sided one where its q lands farther from the prediction than this multiple of the
/// change of q over the step before. Measured on the ψ = 0 twin's full Δ = 3 mm sweep
/// (both runs at every step): where both converge on different solutions (317 of 180 674
/// steps) the two-sided one is the nearer to the prediction (and to the neighbours' q) in
/// 303; 302 of those exceed 0.3 × the last change of q, as do 1 041 of the steps where
/// both agree (the price: one run more at 0.7 % of the steps).
const BRANCH_JUMP: f64 = 0.3;

/// Substeps of a ray step where the whole step fails ([`Worker::step_in_substeps`]).
const SUBSTEPS: usize = 4;

/// Whether some tendon pair has one taut tendon in `a` and the other one in `b` (its taut
/// side changed: a leg-singularity line lies between the two solutions, paper Fig. 9).
/// A pair with both tendons taut (pretension) or both slack has no side.
fn taut_side_changed(model: &Model, a: &RobotState, b: &RobotState) -> bool {
    let nu = model.n_leg_unknowns();
    let side = |s: &RobotState, leg: usize, pair: usize| {
        let g = &s.y_u[leg * nu + 2 * pair..];
        match (tension(g[0]) > 0.0, tension(g[1]) > 0.0) {
            (true, false) => Some(0),
            (false, true) => Some(1),
            _ => None,
        }
    };
    (0..3).any(|leg| {
        (0..model.pairs).any(|pair| match (side(a, leg, pair), side(b, leg, pair)) {
            (Some(x), Some(y)) => x != y,
            _ => false,
        })
    })
}

/// Marks a point beside a taut-side change as near a leg singularity.
fn flag_leg_switch(m: &mut PointMetrics) {
    m.leg_switch = true;
    m.singularity.leg = true;
}

/// A bound on how far the platform centre can be from the origin: the farthest base
/// (at its largest translation) plus the leg, the coupling link and the platform radius.
fn max_radius(model: &Model) -> f64 {
    let base = model
        .bases
        .iter()
        .map(|b| b.position.norm())
        .fold(0.0, f64::max);
    let platform = model
        .coupling_points
        .iter()
        .map(|c| c.norm())
        .fold(0.0, f64::max);
    base + model.limits.base_translation + model.leg.length + model.coupling_offset + platform
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workspace::RayEnds;

    /// The ray start's prediction is the solution's first-order Taylor step: against IK
    /// solutions at (h cos θ, h sin θ) from the origin at z = −30 mm its error shrinks
    /// like h² (a wrong tangent leaves an error of order h).
    #[test]
    fn the_ray_start_predicts_to_first_order() {
        let path = format!("{}/designs/lilge2022.ron", env!("CARGO_MANIFEST_DIR"));
        let design = Tdpcr::from_ron_file(path).unwrap();
        let mut w = Worker::new(&design, &WorkspaceSettings::default()).unwrap();
        let model = w.solver.model().clone();
        let zero = Wrench::default();
        let at = |x: f64, y: f64| Pose {
            position: Vector3::new(x, y, -0.03),
            rotation: Matrix3::identity(),
        };
        let origin = w.solver.solve_ik(&at(0.0, 0.0), &zero, None).unwrap().state;
        let start = w.ray_start(&model, &origin).unwrap();
        let unknowns = |s: &RobotState| {
            let y = in_zeta(&model, s);
            s.q.iter().chain(&y).copied().collect::<Vec<f64>>()
        };
        for theta in [0.3_f64, 2.0] {
            let mut error = |h: f64| {
                let (dx, dy) = (h * theta.cos(), h * theta.sin());
                let guess = start.guess(&model, &origin, dx, dy);
                let solved = w
                    .solver
                    .solve_ik(&at(dx, dy), &zero, Some(&origin))
                    .unwrap();
                let (a, b) = (unknowns(&guess), unknowns(&solved.state));
                let moved = unknowns(&origin)
                    .iter()
                    .zip(&b)
                    .map(|(o, s)| (o - s).abs())
                    .fold(0.0, f64::max);
                let off = a
                    .iter()
                    .zip(&b)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                (off, moved)
            };
            let (e1, moved) = error(2e-4);
            let (e2, _) = error(1e-4);
            assert!(
                e1 < 0.01 * moved,
                "θ = {theta}: error {e1:e} for a move of {moved:e}"
            );
            assert!(
                e2 < 0.35 * e1,
                "θ = {theta}: {e2:e} at h/2 against {e1:e} at h"
            );
        }
    }

    #[test]
    fn only_a_solve_without_a_solution_ends_a_ray_as_not_converged() {
        let path = format!("{}/designs/lilge2022.ron", env!("CARGO_MANIFEST_DIR"));
        let design = Tdpcr::from_ron_file(path).unwrap();
        let mut w = Worker::new(&design, &WorkspaceSettings::default()).unwrap();
        let stopped = Error::Solve(SolveError::NotConverged {
            iterations: 15,
            residual_norm: 1e-3,
            tolerance: 1e-10,
            reason: crate::StopReason::TooLittleProgress,
        });
        assert_eq!(w.end_of(stopped), End::NotConverged);
        assert!(w.error.is_none());
        let blown_up = Error::Solve(SolveError::NonFinite {
            stage: "rod strain derivatives (eq. 5)",
        });
        assert_eq!(w.end_of(blown_up), End::Failed);
        assert!(
            w.error.as_deref().unwrap().contains("non-finite"),
            "{:?}",
            w.error
        );
        let mut ends = RayEnds::default();
        ends.count(End::Failed);
        assert_eq!((ends.failed, ends.not_converged), (1, 0));
    }
}
