//! The sweep's numbers: cell counts and volumes per category \[m³\], rcond statistics
//! ([`Stats`], [`RcondStats`], paper Tab. III in [`TableIii`]), singularity fractions, and
//! the work done ([`WorkspaceSummary`]).

use std::sync::atomic::Ordering;

use serde::Serialize;

use super::cells::{Categories, WorkspacePoint};
use super::ends::{PathEnd, RayEnds};
use super::metrics::{PointMetrics, Rconds, Singularity};
use super::plane::Planes;
use super::settings::WorkspaceSettings;
use super::walk::Work;

/// Mean, minimum and maximum of one measure over the reachable cells (0 when empty).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Stats {
    /// Mean.
    pub mean: f64,
    /// Minimum.
    pub min: f64,
    /// Maximum.
    pub max: f64,
}

impl Stats {
    fn of(values: impl Iterator<Item = f64>) -> Self {
        let mut acc = StatsAcc::default();
        values.for_each(|x| acc.add(x));
        acc.stats()
    }
}

/// The running count, sum (in order), minimum and maximum behind a [`Stats`].
#[derive(Debug, Clone, Copy)]
struct StatsAcc {
    n: usize,
    sum: f64,
    min: f64,
    max: f64,
}

impl Default for StatsAcc {
    fn default() -> Self {
        Self {
            n: 0,
            sum: 0.0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
        }
    }
}

impl StatsAcc {
    fn add(&mut self, x: f64) {
        self.n += 1;
        self.sum += x;
        self.min = self.min.min(x);
        self.max = self.max.max(x);
    }

    fn stats(&self) -> Stats {
        if self.n == 0 {
            Stats::default()
        } else {
            Stats {
                mean: self.sum / self.n as f64,
                min: self.min,
                max: self.max,
            }
        }
    }
}

/// [`Stats`] of each rcond.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct RcondStats {
    /// rcond(\[B_x B_u\]).
    pub b_xu: Stats,
    /// rcond(\[B_q B_u\]).
    pub b_qu: Stats,
    /// rcond(B_u).
    pub b_u: Stats,
    /// rcond(J_p) (paper Tab. III).
    pub j_p: Stats,
    /// rcond(J_o) (paper Tab. III).
    pub j_o: Stats,
    /// rcond(C_p) (paper Tab. III).
    pub c_p: Stats,
    /// rcond(C_o) (paper Tab. III).
    pub c_o: Stats,
}

impl RcondStats {
    fn of<'a>(r: impl Iterator<Item = &'a Rconds>) -> Self {
        let mut acc = RcondAcc::default();
        r.for_each(|r| acc.add(r));
        acc.stats()
    }
}

/// The [`StatsAcc`] of each rcond: one pass over a population instead of one per rcond
/// (the same sums in the same order; the reference design's Δ = 3 mm summary took
/// 0.12 s over its 378 316 samples in about sixty passes).
#[derive(Debug, Clone, Copy, Default)]
struct RcondAcc([StatsAcc; 7]);

impl RcondAcc {
    fn add(&mut self, r: &Rconds) {
        let values = [r.b_xu, r.b_qu, r.b_u, r.j_p, r.j_o, r.c_p, r.c_o];
        for (acc, x) in self.0.iter_mut().zip(values) {
            acc.add(x);
        }
    }

    fn stats(&self) -> RcondStats {
        let [b_xu, b_qu, b_u, j_p, j_o, c_p, c_o] = self.0.map(|a| a.stats());
        RcondStats {
            b_xu,
            b_qu,
            b_u,
            j_p,
            j_o,
            c_p,
            c_o,
        }
    }
}

/// Raw SI rcond statistics over one population of points, in three variants.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct RcondVariants {
    /// Every point of the population, stable or not, near a singularity or not.
    pub all: RcondStats,
    /// Points of `all`.
    pub all_count: usize,
    /// Stable points not near a Type II singularity.
    pub without_type_ii: RcondStats,
    /// Points of `without_type_ii`.
    pub without_type_ii_count: usize,
    /// Stable points near no singularity (Type I, Type II or leg).
    pub regular: RcondStats,
    /// Points of `regular`.
    pub regular_count: usize,
}

impl RcondVariants {
    fn of<'a>(points: impl Iterator<Item = &'a PointMetrics>) -> Self {
        let (mut all, mut no_type_ii, mut regular) = (
            RcondAcc::default(),
            RcondAcc::default(),
            RcondAcc::default(),
        );
        for m in points {
            let s = &m.singularity;
            all.add(&m.rcond);
            if m.stable && !s.type_ii {
                no_type_ii.add(&m.rcond);
            }
            if m.stable && !(s.type_i || s.type_ii || s.leg) {
                regular.add(&m.rcond);
            }
        }
        Self {
            all: all.stats(),
            all_count: all.0[0].n,
            without_type_ii: no_type_ii.stats(),
            without_type_ii_count: no_type_ii.0[0].n,
            regular: regular.stats(),
            regular_count: regular.0[0].n,
        }
    }
}

/// Tab. III's statistics two ways. The paper averages over its ray samples (denser near
/// each plane's origin, so the centre weighs more); per cell every Δ³ of volume weighs
/// the same.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct TableIii {
    /// Over the cells of the map that are reachable or unstable (collision cells
    /// excluded), each once (volume-weighted).
    pub per_cell: RcondVariants,
    /// Over every solved, collision-free point: the plane origins and every ray sample,
    /// including the unstable points that ended rays.
    pub per_sample: RcondVariants,
}

/// Fractions of the reachable cells near each kind of singularity (0 when empty).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Fractions {
    /// Near Type I.
    pub near_type_i: f64,
    /// Near Type II.
    pub near_type_ii: f64,
    /// Near a leg singularity.
    pub near_leg_singularity: f64,
}

/// The sweep's numbers: sizes, Table-III statistics, singularity fractions, work.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorkspaceSummary {
    /// Grid step Δ \[m\].
    pub step: f64,
    /// Angle between rays φ \[rad\].
    pub angle_step: f64,
    /// R_ee as a rotation vector \[rad\].
    pub rotvec: [f64; 3],
    /// Requested z-range \[m\].
    pub z_range: [f64; 2],
    /// Planes in the z-range.
    pub planes: usize,
    /// Planes whose origin the path reached.
    pub planes_reached: usize,
    /// Lowest and highest z of a reached plane \[m\] (0, 0 when none).
    pub z_reached: [f64; 2],
    /// Why the path down and the path up along z stopped.
    pub path_ends: [PathEnd; 2],
    /// Rays per plane.
    pub rays_per_plane: usize,
    /// Cells per category.
    pub counts: Categories<usize>,
    /// Volume per category, count × Δ³ \[m³\].
    pub volume: Categories<f64>,
    /// rcond statistics of the raw SI matrices over the reachable cells.
    pub rcond: RcondStats,
    /// rcond statistics of the unit-scaled matrices over the reachable cells.
    pub rcond_scaled: RcondStats,
    /// Minimum tendon tension over the reachable cells \[N\].
    pub min_tension: Stats,
    /// The rcond statistics of paper Tab. III in the variants needed to hold them against
    /// the paper: per cell and per ray sample, with and without near-singular and
    /// unstable points.
    pub table_iii: TableIii,
    /// Fractions of reachable cells near singularities.
    pub fractions: Fractions,
    /// Why rays ended.
    pub ray_ends: RayEnds,
    /// The first error (the path first, then planes from the lowest and rays in order)
    /// that ended a ray or the path other than a solve that did not converge, or why the
    /// home configuration is invalid (`path_ends` both `invalid_home`); `None` when there
    /// was none.
    pub first_error: Option<String>,
    /// IK solves (Newton runs, including failed ones and retries).
    pub solves: usize,
    /// Newton iterations of the converged solves.
    pub newton_iterations: usize,
    /// Of the converged solves: residual evaluations (each a primal integration of the
    /// three legs) and, among them, Jacobian evaluations (with sensitivities).
    pub residual_evaluations: usize,
    /// See `residual_evaluations`.
    pub jacobian_evaluations: usize,
    /// Of the solves that found no solution (a step past a fold or beyond reach, which
    /// ends its ray or falls back to substeps): Newton iterations, residual and Jacobian
    /// evaluations, every run of each solve counted.
    pub failed_newton_iterations: usize,
    /// See `failed_newton_iterations`.
    pub failed_residual_evaluations: usize,
    /// See `failed_newton_iterations`.
    pub failed_jacobian_evaluations: usize,
    /// Solutions within the limits whose legs were integrated once more to check
    /// collisions at their disks: the rest were cleared by their knots, recorded by the
    /// analysis ([`CollisionChecker::clear_by_knots`](super::collision::CollisionChecker::clear_by_knots)).
    pub collision_integrations: usize,
    /// Worker threads.
    pub threads: usize,
    /// Wall time of the sweep (solves and measures, not file output) \[s\].
    pub wall_time_s: f64,
    /// solves / wall time \[1/s\].
    pub solves_per_second: f64,
}

/// The summary of a sweep from its cells (`points`), the measures of every collision-free
/// sample, the ray ends and the work counters; `first_error` is left `None` for the caller.
#[allow(clippy::too_many_arguments)]
pub(super) fn summarize(
    settings: &WorkspaceSettings,
    planes: &Planes,
    n_rays: usize,
    points: &[WorkspacePoint],
    samples: &[PointMetrics],
    ray_ends: RayEnds,
    work: &Work,
    wall: f64,
) -> WorkspaceSummary {
    let reachable: Vec<&WorkspacePoint> = points.iter().filter(|p| p.reachable()).collect();
    let count = |f: &dyn Fn(&Singularity) -> bool| {
        reachable
            .iter()
            .filter(|p| f(&p.metrics.singularity))
            .count()
    };
    let counts = Categories {
        reachable: reachable.len(),
        non_singular: count(&|s| !(s.type_i || s.type_ii || s.leg)),
        near_type_i: count(&|s| s.type_i),
        near_type_ii: count(&|s| s.type_ii),
        near_leg_singularity: count(&|s| s.leg),
        collision: points
            .iter()
            .filter(|p| p.collision && p.metrics.stable)
            .count(),
        unstable: points.iter().filter(|p| !p.metrics.stable).count(),
    };
    let cell = settings.step.powi(3);
    let volume = Categories {
        reachable: counts.reachable as f64 * cell,
        non_singular: counts.non_singular as f64 * cell,
        near_type_i: counts.near_type_i as f64 * cell,
        near_type_ii: counts.near_type_ii as f64 * cell,
        near_leg_singularity: counts.near_leg_singularity as f64 * cell,
        collision: counts.collision as f64 * cell,
        unstable: counts.unstable as f64 * cell,
    };
    let fraction = |n: usize| {
        if reachable.is_empty() {
            0.0
        } else {
            n as f64 / reachable.len() as f64
        }
    };
    let solves = work.solves.load(Ordering::Relaxed);
    let z = |k: i64| k as f64 * settings.step;
    WorkspaceSummary {
        step: settings.step,
        angle_step: settings.angle_step,
        rotvec: settings.rotvec,
        z_range: settings.z_range,
        planes: settings.plane_indices().count(),
        planes_reached: planes.origins.len(),
        z_reached: match (planes.origins.first(), planes.origins.last()) {
            (Some(a), Some(b)) => [z(a.0), z(b.0)],
            _ => [0.0, 0.0],
        },
        path_ends: planes.ends,
        rays_per_plane: n_rays,
        counts,
        volume,
        rcond: RcondStats::of(reachable.iter().map(|p| &p.metrics.rcond)),
        rcond_scaled: RcondStats::of(reachable.iter().map(|p| &p.metrics.rcond_scaled)),
        min_tension: Stats::of(reachable.iter().map(|p| p.metrics.min_tension)),
        table_iii: TableIii {
            per_cell: RcondVariants::of(
                points
                    .iter()
                    .filter(|p| !p.collision || !p.metrics.stable)
                    .map(|p| &p.metrics),
            ),
            per_sample: RcondVariants::of(samples.iter()),
        },
        fractions: Fractions {
            near_type_i: fraction(counts.near_type_i),
            near_type_ii: fraction(counts.near_type_ii),
            near_leg_singularity: fraction(counts.near_leg_singularity),
        },
        ray_ends,
        first_error: None,
        solves,
        newton_iterations: work.iterations.load(Ordering::Relaxed),
        residual_evaluations: work.residuals.load(Ordering::Relaxed),
        jacobian_evaluations: work.jacobians.load(Ordering::Relaxed),
        failed_newton_iterations: work.failed.iterations.load(Ordering::Relaxed),
        failed_residual_evaluations: work.failed.residuals.load(Ordering::Relaxed),
        failed_jacobian_evaluations: work.failed.jacobians.load(Ordering::Relaxed),
        collision_integrations: work.collision_integrations.load(Ordering::Relaxed),
        threads: rayon::current_num_threads(),
        wall_time_s: wall,
        solves_per_second: if wall > 0.0 {
            solves as f64 / wall
        } else {
            0.0
        },
    }
}
