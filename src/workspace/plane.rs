//! The planes z = k Δ \[m\]: reaching their origins by the path along z from the home
//! configuration ([`reach_planes`]), then sweeping each one ([`PlaneJob::sweep`]): its rays
//! in parallel and one representative per cell.

use std::sync::atomic::{AtomicBool, Ordering};

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::error::Error;
use crate::kinetostatics::RobotState;
use crate::model::{Model, Pose};
use crate::newton::NewtonSettings;
use crate::rod::Wrench;

use super::cells::{WorkspacePoint, representatives};
use super::ends::{End, PathEnd, RayEnds};
use super::metrics::{PointMetrics, tensions};
use super::predict::PREDICTOR_POINTS;
use super::settings::{DEFAULT_PROBE_ITERATIONS, WorkspaceSettings};
use super::walk::{Ray, Sample, Work, Worker};

/// The plane origins reached by the path along z, and why the path stopped.
pub(super) struct Planes {
    /// (k, origin) for every reached plane z = k Δ in the z-range, lowest first.
    pub(super) origins: Vec<(i64, Sample)>,
    /// Why the path down and the path up stopped.
    pub(super) ends: [PathEnd; 2],
    /// The message of a [`PathEnd::Failed`] (down first).
    pub(super) error: Option<String>,
}

/// Solves the home configuration, then follows z up and down to the plane origins in the
/// z-range.
pub(super) fn reach_planes(
    worker: &Worker,
    model: &Model,
    settings: &WorkspaceSettings,
    work: &Work,
) -> Result<Planes, Error> {
    let rotation = settings.rotation();
    let mut home_worker = worker.clone();
    // The cold home solve may need continuation: the solver's default iteration limit.
    let home_settings = NewtonSettings {
        max_iterations: NewtonSettings::default().max_iterations,
        ..worker.solver.settings
    };
    let home_pose = Pose {
        position: Vector3::zeros(),
        rotation,
    };
    // A cold solve: two-sided, as the solver's cold solves (one-sided kink columns can
    // land a cold run on another equilibrium: the ψ = 0 twin at R_ee = Rz(−30°) then
    // had no valid home).
    home_worker.solver.one_sided_kinks = false;
    // Solved to the end even beyond the actuation limits: such a home is reported as
    // invalid below (stopped there, the sweep failed with "beyond the actuation limits").
    home_worker.solver.stop_beyond_limits = false;
    let home =
        home_worker
            .solver
            .solve_ik_with(&home_pose, &Wrench::default(), None, &home_settings)?;
    home_worker.solver.one_sided_kinks = settings.one_sided_kinks;
    home_worker.solver.stop_beyond_limits = true;
    work.solves.fetch_add(1, Ordering::Relaxed);
    work.add(&home.report);
    let home = match home_worker.classify(model, home.state, work) {
        Ok(s) if s.end(settings.collisions).is_none() => s,
        invalid => {
            let end = match invalid {
                Ok(s) => s.end(settings.collisions),
                Err(end) => Some(end),
            };
            let why = match end {
                Some(End::Limits) => "outside the actuation limits",
                Some(End::Collision) => "in collision",
                Some(End::Unstable) => "an unstable equilibrium",
                _ => "not analysable",
            };
            return Ok(Planes {
                origins: Vec::new(),
                ends: [PathEnd::InvalidHome; 2],
                error: Some(format!(
                    "the home configuration (the platform at the origin) is {why}: nothing was swept"
                )),
            });
        }
    };
    let range = settings.plane_indices();
    let (lo, hi) = (*range.start(), *range.end());
    // One chain of path steps in direction `dir` (+1 up, −1 down) from home to `last_k`.
    let chain = |dir: i64, last_k: i64| -> (Vec<(i64, Sample)>, PathEnd, Option<String>) {
        let mut w = worker.clone();
        let mut out = Vec::new();
        let mut path: Vec<RobotState> = vec![home.state.clone()];
        let mut k = 0;
        while k != last_k {
            k += dir;
            let position = Vector3::new(0.0, 0.0, k as f64 * settings.step);
            let from = path.len().saturating_sub(PREDICTOR_POINTS);
            let history: Vec<&RobotState> = path[from..].iter().collect();
            match w.step(
                model,
                &rotation,
                position,
                &history,
                None,
                // The path to the planes ends at its first failed step (no substeps): it
                // keeps at least the default's iterations (a slow step there cost a
                // drawn candidate of the design search 17 % of its cells with 8).
                w.probe_iterations.max(DEFAULT_PROBE_ITERATIONS),
                work,
            ) {
                Ok(s) => {
                    if let Some(end) = s.end(settings.collisions) {
                        return (out, end.into(), None);
                    }
                    path.push(s.state.clone());
                    if range.contains(&k) {
                        out.push((k, s));
                    }
                }
                Err(end) => return (out, end.into(), w.error.take()),
            }
        }
        (out, PathEnd::EndOfRange, None)
    };
    let none = || (Vec::new(), PathEnd::EndOfRange, None);
    let ((down, down_end, down_error), (up, up_end, up_error)) = rayon::join(
        || if lo < 0 { chain(-1, lo) } else { none() },
        || if hi > 0 { chain(1, hi) } else { none() },
    );
    let mut planes: Vec<(i64, Sample)> = down.into_iter().rev().collect();
    if range.contains(&0) {
        planes.push((0, home));
    }
    planes.extend(up);
    Ok(Planes {
        origins: planes,
        ends: [down_end, up_end],
        error: down_error.or(up_error),
    })
}

/// The cells of one plane, the measures of every solved point (origin and ray samples,
/// colliding ones excluded) and why its rays ended.
pub(super) struct PlaneSweep {
    /// The cells of the plane, in (j, i) order.
    pub(super) points: Vec<WorkspacePoint>,
    /// The measures of the origin and every collision-free ray sample.
    pub(super) samples: Vec<PointMetrics>,
    /// Why the rays ended.
    pub(super) ray_ends: RayEnds,
    /// The message of the first ray (in ray order) that ended with
    /// [`End::Failed`](super::ends::End::Failed).
    pub(super) first_error: Option<String>,
}

/// What sweeping a plane needs.
pub(super) struct PlaneJob<'a> {
    /// Cloned once per rayon job split.
    pub(super) worker: &'a Worker,
    /// The robot model.
    pub(super) model: &'a Model,
    /// How to sweep.
    pub(super) settings: &'a WorkspaceSettings,
    /// Shared work counters.
    pub(super) work: &'a Work,
    /// Called after every ray.
    pub(super) on_ray_done: &'a (dyn Fn() + Sync),
    /// Set when the sweep is to stop: rays not yet started are skipped.
    pub(super) stop: &'a AtomicBool,
}

impl PlaneJob<'_> {
    /// The rays of plane k from its origin (in parallel), the cell representatives, and
    /// their measures (in parallel).
    pub(super) fn sweep(&self, k: i64, origin: &Sample, n_rays: usize) -> PlaneSweep {
        let (model, settings) = (self.model, self.settings);
        let start = self.worker.clone().ray_start(model, &origin.state);
        let rays: Vec<Ray> = (0..n_rays)
            .into_par_iter()
            .map_init(
                || self.worker.clone(),
                |w, j| {
                    if self.stop.load(Ordering::Relaxed) {
                        return Ray::skipped();
                    }
                    let ray = w.follow_ray(model, settings, origin, start.as_ref(), j, self.work);
                    (self.on_ray_done)();
                    ray
                },
            )
            .collect();
        if self.stop.load(Ordering::Relaxed) {
            // Not returned: no measures for its cells.
            return PlaneSweep {
                points: Vec::new(),
                samples: Vec::new(),
                ray_ends: RayEnds::default(),
                first_error: None,
            };
        }
        let mut ray_ends = RayEnds::default();
        for r in &rays {
            ray_ends.count(r.end);
        }
        let first_error = rays.iter().find_map(|r| r.error.clone());
        let samples = std::iter::once(origin)
            .chain(rays.iter().flat_map(|r| r.samples.iter()))
            .filter(|s| !s.collision)
            .map(|s| s.metrics)
            .collect();
        // Only the cells' points get the unit-scaled rconds (a second factorization each).
        let points = representatives(settings.step, origin, &rays)
            .into_par_iter()
            .map(|rep| WorkspacePoint {
                cell: [rep.cell.1, rep.cell.0, k],
                position: rep.sample.state.position,
                tensions: tensions(model, &rep.sample.state),
                state: rep.sample.state.clone(),
                collision: rep.sample.collision,
                metrics: rep.sample.complete_metrics(model),
            })
            .collect();
        PlaneSweep {
            points,
            samples,
            ray_ends,
            first_error,
        }
    }
}
