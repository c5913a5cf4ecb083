//! The translational workspace for a fixed platform orientation R_ee (paper Sec. V-B,
//! MODEL.md §6), by path following with warm-started IK:
//!
//! 1. From the home configuration (platform at the origin with orientation R_ee, solved
//!    cold), a path along z in steps Δ reaches the origin (0, 0, z_k) of every xy-plane
//!    z_k = k Δ in the z-range; the path up and the path down stop at the first invalid
//!    step (a plane beyond is not reachable along the path).
//! 2. From each plane's origin, rays at angles θ_j = j φ (j = 0 .. ⌈2π/φ⌉ − 1) are
//!    followed outwards in steps Δ (point i at radius i Δ), each IK solve warm-started
//!    from an extrapolation of the last solutions on the ray (the path along z likewise),
//!    until a step is invalid: Newton does not converge (one run from the prediction, at
//!    most [`WorkspaceSettings::max_iterations`] iterations, to
//!    [`WorkspaceSettings::tolerance`]; no continuation fallback), any q is outside its
//!    actuation limits, the equilibrium is unstable with the actuators held (sym(C) has a
//!    negative eigenvalue, [`crate::analysis::stability`]: the robot would snap away from
//!    it; the point is recorded as an unstable cell), or a disk collides ([`collision`];
//!    with [`CollisionPolicy::Continue`] a colliding point is recorded as such and the ray
//!    goes on). For the 9-DoF design the IK is the solver's least-norm IK.
//! 3. **Gridding.** Space is divided into cubic cells of side Δ centred on the grid
//!    (i Δ, j Δ, k Δ); the planes are the cell layers. Each solved point falls into the
//!    cell of its nearest grid node; a cell is *reachable* if a valid (collision-free)
//!    point fell into it, *collision* if only colliding points did, *unstable* if only
//!    unstable points did (each ended its ray). Each cell is represented by one solved
//!    point: a valid one before a colliding one before an unstable one, then the one
//!    nearest to the cell centre, then the first in (ray, step) order. So a count of
//!    cells times Δ³ is a volume. Rays are denser than the grid near the plane origin and
//!    sparser beyond the radius Δ/φ (86 mm at the paper's settings), where cells between
//!    two rays can be missed: the volume is then an underestimate. Keep φ ≤ Δ/R for a
//!    workspace of radius R (about 0.1 m for the reference design): measured on it,
//!    Δ = 10 mm gives 2.39 L with φ = 0.1 but 1.98 L with φ = 0.2 and 1.43 L with
//!    φ = 0.35 (Δ = 3 mm, φ = 0.035: 2.47 L).
//! 4. Every solved point gets the measures of [`metrics::point_metrics`] (rcond,
//!    singularity flags, stability, minimum tension) when it is solved: stability decides
//!    whether its ray goes on, and the statistics per ray sample (the paper's Tab. III)
//!    need every point. A leg is also flagged singular at two neighbouring points of a ray
//!    between which one of its tendon pairs changes its taut side (paper Fig. 9: the
//!    leg-singularity lines lie between grid points, where the τ threshold rarely sees
//!    them).
//!
//! Rays run in parallel (rayon, the current thread pool; one solver per worker). Each ray
//! depends only on its plane's origin state, and the cell representatives are chosen in a
//! fixed order, so the map is identical whatever the number of threads.

pub mod collision;
pub mod figures;
pub mod files;
pub mod metrics;

use std::f64::consts::PI;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use nalgebra::{Matrix3, Rotation3, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use crate::boundary::convert_tendon_unknowns;
use crate::design::Tdpcr;
use crate::error::{Error, SolveError, Violations};
use crate::kinetostatics::{RobotState, Solver};
use crate::model::{Model, Pose};
use crate::newton::{NewtonReport, NewtonSettings, ProgressCheck};
use crate::rod::Wrench;
use crate::rod::tendon::{TendonUnknown, tension};

use collision::CollisionChecker;
pub use metrics::{AnalysisSettings, PointMetrics, Rconds, Singularity, point_metrics};

/// Default grid step Δ \[m\] (paper: 3 mm).
pub const DEFAULT_STEP: f64 = 0.003;
/// Default angular step φ between rays \[rad\] (paper: 0.035).
pub const DEFAULT_ANGLE_STEP: f64 = 0.035;
/// Default z-range \[m\]: covers the reachable workspace of the reference design at
/// R_ee = I (−0.111 … 0.129 m at Δ = 3 mm) with a margin (see README).
pub const DEFAULT_Z_RANGE: [f64; 2] = [-0.15, 0.15];

/// What a colliding point does to its ray (and to the path to the planes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum CollisionPolicy {
    /// A collision is invalid: the point is recorded as a collision cell and its ray ends
    /// (MODEL.md §6).
    #[default]
    Stop,
    /// Colliding points are recorded and the ray goes on; only non-convergence or the
    /// actuation limits end it (shows the whole colliding region, as the paper's Fig. 7).
    Continue,
}

/// How to sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorkspaceSettings {
    /// Platform orientation R_ee as a rotation vector (axis × angle) \[rad\], world frame.
    pub rotvec: [f64; 3],
    /// Grid step Δ along rays and between planes \[m\].
    pub step: f64,
    /// Angle φ between rays \[rad\]; keep φ ≤ Δ / (workspace radius), see the module
    /// documentation.
    pub angle_step: f64,
    /// Lowest and highest plane z \[m\] (planes at multiples of Δ within the range).
    pub z_range: [f64; 2],
    /// What a collision does.
    pub collisions: CollisionPolicy,
    /// Singularity thresholds of the per-point measures.
    pub analysis: AnalysisSettings,
    /// Newton tolerance ε_b on ‖b‖₂ (SI) of every IK step.
    pub tolerance: f64,
    /// Newton iterations allowed per step. A warm step of Δ = 3 mm needs 2–4, but steps
    /// across a leg-singularity line (a leg's tendon pair switching, paper Fig. 9) can need
    /// 20–50, and a smaller budget ends rays there (measured on the plane z = 0 of the
    /// reference design: 1277 reachable cells with 15 iterations, 1582 with 60). A step
    /// first gets 15 iterations and the rest only if those reduced ‖b‖ tenfold (a step past
    /// a fold, where no solution exists, makes no such progress).
    pub max_iterations: usize,
}

impl Default for WorkspaceSettings {
    fn default() -> Self {
        Self {
            rotvec: [0.0; 3],
            step: DEFAULT_STEP,
            angle_step: DEFAULT_ANGLE_STEP,
            z_range: DEFAULT_Z_RANGE,
            collisions: CollisionPolicy::Stop,
            analysis: AnalysisSettings::default(),
            tolerance: 1e-10,
            max_iterations: 60,
        }
    }
}

/// Most planes or rays per plane a sweep accepts (memory and time guard).
const MAX_COUNT: f64 = 100_000.0;

impl WorkspaceSettings {
    /// Checks every value; all problems are listed.
    ///
    /// # Errors
    /// [`Error::Input`] naming each bad field, its value and the rule.
    pub fn validate(&self) -> Result<(), Error> {
        let mut v = Violations::default();
        if !self.rotvec.iter().all(|x| x.is_finite()) {
            v.push(
                "rotvec",
                format!("{:?}", self.rotvec),
                "finite numbers [rad]",
            );
        }
        if !(self.step.is_finite() && (1e-5..=1.0).contains(&self.step)) {
            v.push("step", self.step, "in [1e-5, 1] m");
        }
        if !(self.angle_step.is_finite() && self.angle_step >= 1e-4 && self.angle_step <= PI) {
            v.push("angle_step", self.angle_step, "in [1e-4, pi] rad");
        }
        let [lo, hi] = self.z_range;
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            v.push(
                "z_range",
                format!("{lo},{hi}"),
                "two finite numbers ZMIN <= ZMAX [m]",
            );
        } else if self.step > 0.0 && (hi - lo) / self.step > MAX_COUNT {
            v.push(
                "z_range",
                format!("{lo},{hi}"),
                &format!("at most {MAX_COUNT} planes of step {} m", self.step),
            );
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            v.push("tolerance", self.tolerance, "> 0");
        }
        if self.max_iterations == 0 {
            v.push("max_iterations", 0, ">= 1");
        }
        if v.0.is_empty() {
            Ok(())
        } else {
            Err(Error::Input(v))
        }
    }

    /// R_ee.
    pub fn rotation(&self) -> Matrix3<f64> {
        *Rotation3::new(Vector3::from(self.rotvec)).matrix()
    }

    /// Plane indices k (z = k Δ) in the z-range, lowest first.
    pub fn plane_indices(&self) -> std::ops::RangeInclusive<i64> {
        let tol = 1e-9;
        let lo = (self.z_range[0] / self.step - tol).ceil() as i64;
        let hi = (self.z_range[1] / self.step + tol).floor() as i64;
        lo..=hi
    }

    /// Rays per plane ⌈2π/φ⌉ (the last gap is at most φ).
    pub fn rays_per_plane(&self) -> usize {
        (2.0 * PI / self.angle_step - 1e-9).ceil() as usize
    }
}

/// One cell of the map, represented by one solved configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspacePoint {
    /// Grid cell (i, j, k): centre (i Δ, j Δ, k Δ).
    pub cell: [i64; 3],
    /// Solved platform position \[m\] (in the cell, within Δ/2 of its centre in x and y).
    pub position: [f64; 3],
    /// The solved configuration (q, leg unknowns); a warm start for nearby poses.
    pub state: RobotState,
    /// Tendon tensions \[N\], legs concatenated (n_t per leg).
    pub tensions: Vec<f64>,
    /// The disks collide (not part of the reachable workspace).
    pub collision: bool,
    /// rcond, singularity flags, stability and minimum tension. An unstable point
    /// (`!metrics.stable`) ended its ray and is not part of the reachable workspace.
    pub metrics: PointMetrics,
}

impl WorkspacePoint {
    /// Reachable: valid, stable and collision-free.
    pub fn reachable(&self) -> bool {
        !self.collision && self.metrics.stable
    }
}

/// A count or volume per category of cell.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Categories<T> {
    /// Reachable (valid, collision-free) cells.
    pub reachable: T,
    /// Reachable cells not near any singularity (Type I, Type II or leg).
    pub non_singular: T,
    /// Reachable cells near a Type I singularity.
    pub near_type_i: T,
    /// Reachable cells near a Type II singularity.
    pub near_type_ii: T,
    /// Reachable cells near a leg singularity.
    pub near_leg_singularity: T,
    /// Cells with only colliding solutions.
    pub collision: T,
    /// Cells with only unstable solutions (where rays ended because the equilibrium is
    /// unstable with the actuators held).
    pub unstable: T,
}

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
        let (mut n, mut sum, mut min, mut max) = (0usize, 0.0, f64::INFINITY, f64::NEG_INFINITY);
        for x in values {
            n += 1;
            sum += x;
            min = min.min(x);
            max = max.max(x);
        }
        if n == 0 {
            Self::default()
        } else {
            Self {
                mean: sum / n as f64,
                min,
                max,
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
    fn of<'a>(r: impl Iterator<Item = &'a Rconds> + Clone) -> Self {
        Self {
            b_xu: Stats::of(r.clone().map(|r| r.b_xu)),
            b_qu: Stats::of(r.clone().map(|r| r.b_qu)),
            b_u: Stats::of(r.clone().map(|r| r.b_u)),
            j_p: Stats::of(r.clone().map(|r| r.j_p)),
            j_o: Stats::of(r.clone().map(|r| r.j_o)),
            c_p: Stats::of(r.clone().map(|r| r.c_p)),
            c_o: Stats::of(r.map(|r| r.c_o)),
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
    fn of<'a>(points: impl Iterator<Item = &'a PointMetrics> + Clone) -> Self {
        let no_type_ii = points
            .clone()
            .filter(|m| m.stable && !m.singularity.type_ii);
        let regular = points.clone().filter(|m| {
            let s = &m.singularity;
            m.stable && !(s.type_i || s.type_ii || s.leg)
        });
        Self {
            all: RcondStats::of(points.clone().map(|m| &m.rcond)),
            all_count: points.count(),
            without_type_ii: RcondStats::of(no_type_ii.clone().map(|m| &m.rcond)),
            without_type_ii_count: no_type_ii.count(),
            regular: RcondStats::of(regular.clone().map(|m| &m.rcond)),
            regular_count: regular.count(),
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

/// Why rays ended (counts over all rays).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub struct RayEnds {
    /// Newton did not converge.
    pub not_converged: usize,
    /// Some q left its actuation limits.
    pub actuation_limits: usize,
    /// A collision ([`CollisionPolicy::Stop`]).
    pub collision: usize,
    /// The equilibrium became unstable with the actuators held.
    pub unstable: usize,
    /// The ray reached the geometric bound of the design (should not happen).
    pub max_radius: usize,
    /// An error other than a solve that did not converge (e.g. a leg integration that
    /// turned non-finite): the first one is in [`WorkspaceSummary::first_error`].
    pub failed: usize,
}

impl RayEnds {
    fn count(&mut self, end: End) {
        match end {
            End::NotConverged => self.not_converged += 1,
            End::Limits => self.actuation_limits += 1,
            End::Collision => self.collision += 1,
            End::Unstable => self.unstable += 1,
            End::MaxRadius => self.max_radius += 1,
            End::Failed => self.failed += 1,
        }
    }

    fn add(&mut self, other: &Self) {
        self.not_converged += other.not_converged;
        self.actuation_limits += other.actuation_limits;
        self.collision += other.collision;
        self.unstable += other.unstable;
        self.max_radius += other.max_radius;
        self.failed += other.failed;
    }
}

/// Why the path along z from the home configuration stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PathEnd {
    /// It reached the end of the z-range (or the range does not extend this way).
    EndOfRange,
    /// A step did not converge.
    NotConverged,
    /// A step left the actuation limits.
    ActuationLimits,
    /// A step collided ([`CollisionPolicy::Stop`]).
    Collision,
    /// A step reached an unstable equilibrium.
    Unstable,
    /// A step failed with an error other than non-convergence
    /// ([`WorkspaceSummary::first_error`]).
    Failed,
    /// The home configuration itself is invalid (out of limits or colliding).
    InvalidHome,
}

impl From<End> for PathEnd {
    fn from(e: End) -> Self {
        match e {
            End::NotConverged | End::MaxRadius => Self::NotConverged,
            End::Limits => Self::ActuationLimits,
            End::Collision => Self::Collision,
            End::Unstable => Self::Unstable,
            End::Failed => Self::Failed,
        }
    }
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
    /// that ended a ray or the path other than a solve that did not converge; `None` when
    /// there was none.
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
    /// Worker threads.
    pub threads: usize,
    /// Wall time of the sweep (solves and measures, not file output) \[s\].
    pub wall_time_s: f64,
    /// solves / wall time \[1/s\].
    pub solves_per_second: f64,
}

/// The result of a sweep: every cell (reachable or collision) and the summary.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspaceMap {
    /// The settings used.
    pub settings: WorkspaceSettings,
    /// Actuators n_q (6 or 9).
    pub n_actuators: usize,
    /// Tendons per leg n_t.
    pub tendons_per_leg: usize,
    /// Cells, sorted by (k, j, i) (z, then y, then x).
    pub points: Vec<WorkspacePoint>,
    /// Counts, volumes and statistics.
    pub summary: WorkspaceSummary,
}

impl WorkspaceMap {
    /// The cells of plane k (z = k Δ), in (j, i) order.
    pub fn plane(&self, k: i64) -> impl Iterator<Item = &WorkspacePoint> {
        let start = self.points.partition_point(|p| p.cell[2] < k);
        self.points[start..]
            .iter()
            .take_while(move |p| p.cell[2] == k)
    }
}

/// Progress of a sweep: rays done out of the total (known once the planes are reached).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// Rays finished.
    pub rays_done: usize,
    /// Rays in all reached planes.
    pub rays_total: usize,
}

/// Sweeps the workspace of `design` (see the module documentation).
///
/// # Errors
/// [`Error::Design`] for a design that breaks its rules; [`Error::Input`] for bad
/// settings; [`Error::Solve`] if the home configuration (the platform at the origin with
/// R_ee) cannot be solved.
///
/// # Example
/// ```no_run
/// use tdpcr::Tdpcr;
/// use tdpcr::workspace::{WorkspaceSettings, sweep_workspace};
/// let design = Tdpcr::from_ron_file("designs/lilge2022.ron")?;
/// let settings = WorkspaceSettings { step: 0.01, angle_step: 0.2, ..Default::default() };
/// let map = sweep_workspace(&design, &settings)?;
/// println!("{} m³", map.summary.volume.reachable);
/// # Ok::<(), tdpcr::error::Error>(())
/// ```
pub fn sweep_workspace(
    design: &Tdpcr,
    settings: &WorkspaceSettings,
) -> Result<WorkspaceMap, Error> {
    sweep_workspace_with_progress(design, settings, &|_| {})
}

/// As [`sweep_workspace`], calling `progress` after every ray (from worker threads).
///
/// # Errors
/// As [`sweep_workspace`].
pub fn sweep_workspace_with_progress(
    design: &Tdpcr,
    settings: &WorkspaceSettings,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<WorkspaceMap, Error> {
    design.validate("design")?;
    settings.validate()?;
    let start = Instant::now();
    let worker = Worker::new(design, settings)?;
    let model = worker.solver.model().clone();
    let work = Work::default();
    let planes = reach_planes(&worker, &model, settings, &work)?;
    let n_rays = settings.rays_per_plane();
    let rays_total = planes.origins.len() * n_rays;
    let rays_done = AtomicUsize::new(0);
    progress(Progress {
        rays_done: 0,
        rays_total,
    });
    let on_ray_done = || {
        let done = rays_done.fetch_add(1, Ordering::Relaxed) + 1;
        progress(Progress {
            rays_done: done,
            rays_total,
        });
    };
    // Planes in parallel and, inside each, rays and cells in parallel: a thread that waits
    // for the last ray of a plane takes work from another plane.
    let sweeps: Vec<PlaneSweep> = planes
        .origins
        .par_iter()
        .map(|(k, origin)| {
            let job = PlaneJob {
                worker: &worker,
                model: &model,
                settings,
                work: &work,
                on_ray_done: &on_ray_done,
            };
            job.sweep(*k, origin, n_rays)
        })
        .collect();
    let mut points = Vec::new();
    let mut samples = Vec::new();
    let mut ray_ends = RayEnds::default();
    let mut first_error = planes.error.clone();
    for sweep in sweeps {
        points.extend(sweep.points);
        ray_ends.add(&sweep.ray_ends);
        samples.extend(sweep.samples);
        first_error = first_error.or(sweep.first_error);
    }
    let wall = start.elapsed().as_secs_f64();
    let mut summary = summarize(
        settings, &planes, n_rays, &points, &samples, ray_ends, &work, wall,
    );
    summary.first_error = first_error;
    Ok(WorkspaceMap {
        settings: settings.clone(),
        n_actuators: model.n_actuators(),
        tendons_per_leg: model.n_tendons(),
        points,
        summary,
    })
}

/// The cells of one plane, the measures of every solved point (origin and ray samples,
/// colliding ones excluded) and why its rays ended.
struct PlaneSweep {
    points: Vec<WorkspacePoint>,
    samples: Vec<PointMetrics>,
    ray_ends: RayEnds,
    /// The message of the first ray (in ray order) that ended with [`End::Failed`].
    first_error: Option<String>,
}

/// What sweeping a plane needs.
struct PlaneJob<'a> {
    worker: &'a Worker,
    model: &'a Model,
    settings: &'a WorkspaceSettings,
    work: &'a Work,
    on_ray_done: &'a (dyn Fn() + Sync),
}

impl PlaneJob<'_> {
    /// The rays of plane k from its origin (in parallel), the cell representatives, and
    /// their measures (in parallel).
    fn sweep(&self, k: i64, origin: &Sample, n_rays: usize) -> PlaneSweep {
        let (model, settings) = (self.model, self.settings);
        let rays: Vec<Ray> = (0..n_rays)
            .into_par_iter()
            .map_init(
                || self.worker.clone(),
                |w, j| {
                    let ray = w.follow_ray(model, settings, origin, j, self.work);
                    (self.on_ray_done)();
                    ray
                },
            )
            .collect();
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
        let points = representatives(settings.step, origin, &rays)
            .into_iter()
            .map(|rep| WorkspacePoint {
                cell: [rep.cell.1, rep.cell.0, k],
                position: rep.sample.state.position,
                tensions: tensions(model, &rep.sample.state),
                state: rep.sample.state.clone(),
                collision: rep.sample.collision,
                metrics: rep.sample.metrics,
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

/// Tendon tensions \[N\] of a state, legs concatenated.
fn tensions(model: &Model, state: &RobotState) -> Vec<f64> {
    model
        .tendon_unknown_indices()
        .map(|i| tension(state.y_u[i]))
        .collect()
}

/// Counters shared by the workers (summed; their totals do not depend on the schedule).
#[derive(Debug, Default)]
struct Work {
    solves: AtomicUsize,
    iterations: AtomicUsize,
    jacobians: AtomicUsize,
    residuals: AtomicUsize,
}

impl Work {
    /// Counts a converged solve's work.
    fn add(&self, r: &NewtonReport) {
        self.iterations.fetch_add(r.iterations, Ordering::Relaxed);
        self.jacobians
            .fetch_add(r.jacobian_evaluations, Ordering::Relaxed);
        self.residuals
            .fetch_add(r.residual_evaluations, Ordering::Relaxed);
    }
}

/// One solved point of a ray (or a plane origin) and its measures.
#[derive(Debug, Clone)]
struct Sample {
    state: RobotState,
    collision: bool,
    metrics: PointMetrics,
}

impl Sample {
    /// Why this point ends its ray (or the path to the planes), if it does.
    fn end(&self, collisions: CollisionPolicy) -> Option<End> {
        if !self.metrics.stable {
            Some(End::Unstable)
        } else if self.collision && collisions == CollisionPolicy::Stop {
            Some(End::Collision)
        } else {
            None
        }
    }
}

/// Why a ray or path ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum End {
    /// Newton stopped without a solution here (iteration limit, no progress, trust region
    /// collapsed): the end of the reachable set in this direction.
    NotConverged,
    Limits,
    Collision,
    Unstable,
    MaxRadius,
    /// Any other error; its message is in [`Worker::error`].
    Failed,
}

/// A ray's solved points in order (steps 1, 2, ...) and why it ended.
#[derive(Debug, Clone)]
struct Ray {
    samples: Vec<Sample>,
    end: End,
    /// The message of an [`End::Failed`].
    error: Option<String>,
}

/// A solver and collision buffers; cloned once per rayon job split.
#[derive(Debug, Clone)]
struct Worker {
    solver: Solver,
    collisions: CollisionChecker,
    analysis: AnalysisSettings,
    /// The message of the last [`End::Failed`].
    error: Option<String>,
}

impl Worker {
    fn new(design: &Tdpcr, settings: &WorkspaceSettings) -> Result<Self, Error> {
        let mut solver = Solver::new(design)?;
        solver.settings.tolerance = settings.tolerance;
        solver.settings.max_iterations = settings.max_iterations;
        let collisions = CollisionChecker::new(solver.model());
        Ok(Self {
            solver,
            collisions,
            analysis: settings.analysis,
            error: None,
        })
    }

    /// [`End::NotConverged`] for a solve that stopped without a solution, [`End::Failed`]
    /// (keeping the message) for any other error.
    fn end_of(&mut self, e: Error) -> End {
        match e {
            Error::Solve(SolveError::NotConverged { .. }) => End::NotConverged,
            other => {
                self.error = Some(other.to_string());
                End::Failed
            }
        }
    }

    /// Validity of a solved state (actuation limits, then collisions) and its measures.
    fn classify(&mut self, model: &Model, state: RobotState) -> Result<Sample, End> {
        if !model.within_limits(&state.q) {
            return Err(End::Limits);
        }
        let collision = match self.collisions.check(model, &state) {
            Ok(c) => c.is_some(),
            Err(e) => return Err(self.end_of(e.into())),
        };
        let metrics = match point_metrics(&mut self.solver, &state, &self.analysis) {
            Ok(m) => m,
            Err(e) => return Err(self.end_of(e)),
        };
        Ok(Sample {
            state,
            collision,
            metrics,
        })
    }

    /// One path step to `position`: IK from a prediction extrapolated from the last
    /// solutions on the path (`history`, oldest first, at equal steps), with the
    /// [`PROBE_ITERATIONS`] progress check.
    fn step(
        &mut self,
        model: &Model,
        rotation: &Matrix3<f64>,
        position: Vector3<f64>,
        history: &[&RobotState],
        work: &Work,
    ) -> Result<Sample, End> {
        let pose = Pose {
            position,
            rotation: *rotation,
        };
        let zero = Wrench::default();
        let last = history[history.len() - 1];
        let predicted = predict(model, history);
        let guess = predicted.as_ref().unwrap_or(last);
        // The full budget only if the first iterations made progress.
        let newton = NewtonSettings {
            progress_check: (history.len() > 1).then_some(ProgressCheck {
                iterations: PROBE_ITERATIONS,
                factor: PROBE_PROGRESS,
            }),
            ..self.solver.settings
        };
        let result = self
            .solver
            .solve_ik_newton_with(&pose, &zero, guess, &newton);
        work.solves.fetch_add(1, Ordering::Relaxed);
        let sol = result.map_err(|e| self.end_of(e))?;
        work.add(&sol.report);
        self.classify(model, sol.state)
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
                work,
            )?;
            if m == SUBSTEPS {
                return Ok(sample);
            }
            path.push(sample.state);
        }
        unreachable!("the loop returns at its last substep")
    }

    /// Ray j from the plane origin `origin`.
    fn follow_ray(
        &mut self,
        model: &Model,
        settings: &WorkspaceSettings,
        origin: &Sample,
        j: usize,
        work: &Work,
    ) -> Ray {
        let theta = j as f64 * settings.angle_step;
        let (c, s) = (theta.cos(), theta.sin());
        let z = origin.state.position[2];
        let rotation = settings.rotation();
        let max_steps = (max_radius(model) / settings.step).ceil() as usize;
        let mut samples: Vec<Sample> = Vec::new();
        for i in 1..=max_steps {
            let r = i as f64 * settings.step;
            let position = Vector3::new(r * c, r * s, z);
            let n = samples.len();
            let history: Vec<&RobotState> = std::iter::once(&origin.state)
                .chain(samples.iter().map(|s| &s.state))
                .skip((n + 1).saturating_sub(PREDICTOR_POINTS))
                .collect();
            let result = match self.step(model, &rotation, position, &history, work) {
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
/// first `PROBE_ITERATIONS` iterations reduced ‖b‖ by [`PROBE_PROGRESS`]
/// ([`ProgressCheck`]): steps beyond a fold of the IK (no solution) crawl at their first
/// residual, while the slow steps across a leg-singularity line make progress first.
/// Measured on the plane z = 0 at Δ = 3 mm: the same 1581 cells, 14 % fewer instructions
/// (φ = 0.1: 8.8 G against 10.2 G) than a 60-iteration budget for every step. (The check
/// runs inside one Newton run; a separate probe re-run from the start when it passed
/// repeated its iterations: −7 % time on the plane z = 0 at φ = 0.035.)
const PROBE_ITERATIONS: usize = 15;
/// See [`PROBE_ITERATIONS`].
const PROBE_PROGRESS: f64 = 10.0;

/// Substeps of a ray step where the whole step fails ([`Worker::step_in_substeps`]).
const SUBSTEPS: usize = 4;

/// Solutions used by the predictor of a path step: the last three give a quadratic
/// extrapolation.
const PREDICTOR_POINTS: usize = 3;

/// The start of the next path step extrapolated from the last solutions at equal steps
/// (oldest first): quadratic from three, linear from two, none from one. Tendon unknowns
/// are extrapolated in ζ = γ|γ| (tension when positive, slack when negative: linear in
/// the pose away from the taut/slack switch, where γ = ±√ζ is not), and a tendon whose
/// prediction would switch between taut and slack is predicted at the switch (ζ = 0):
/// the two sides have different units (N, m), so extrapolating across is meaningless.
///
/// The solution is smooth in the pose only between switches, so once the last two
/// solutions share their taut/slack pattern only the trailing solutions with that pattern
/// are extrapolated ([`same_regime`]). Measured on the reference design at Δ = 3 mm,
/// φ = 0.035: 14 % fewer Jacobian evaluations on the plane z = 0 and 20 % fewer on
/// z = −0.06 m, the same cells. Right after a switch (one solution with the new pattern)
/// the whole history is still used: both alternatives measured worse there (starting from
/// the last solution lost 7 of 1581 cells on z = 0, a linear extrapolation from the last
/// two lost 24).
fn predict(model: &Model, history: &[&RobotState]) -> Option<RobotState> {
    let extrapolate = |xs: &[&[f64]]| -> Vec<f64> {
        let last = xs[xs.len() - 1];
        (0..last.len())
            .map(|i| match xs {
                [a, b, c] => 3.0 * c[i] - 3.0 * b[i] + a[i],
                [a, b] => 2.0 * b[i] - a[i],
                _ => last[i],
            })
            .collect()
    };
    let history = same_regime(model, history);
    if history.len() < 2 {
        return None;
    }
    let zeta: Vec<Vec<f64>> = history
        .iter()
        .map(|s| {
            let mut y = s.y_u.clone();
            convert_tendon_unknowns(model, &mut y, TendonUnknown::Gamma, TendonUnknown::Linear);
            y
        })
        .collect();
    let last = history[history.len() - 1];
    let last_zeta = &zeta[zeta.len() - 1];
    let mut y_u = extrapolate(&zeta.iter().map(Vec::as_slice).collect::<Vec<_>>());
    for i in model.tendon_unknown_indices() {
        if y_u[i] * last_zeta[i] < 0.0 {
            y_u[i] = 0.0;
        }
    }
    convert_tendon_unknowns(model, &mut y_u, TendonUnknown::Linear, TendonUnknown::Gamma);
    Some(RobotState {
        position: last.position,
        rotvec: last.rotvec,
        q: extrapolate(&history.iter().map(|s| s.q.as_slice()).collect::<Vec<_>>()),
        y_u,
    })
}

/// The trailing solutions of `history` whose tendons are taut or slack as in the last
/// one, if there are at least two of them; otherwise the whole history (see [`predict`]).
///
/// Always the whole history for a redundant design (more actuators than a square IK):
/// there the least-norm IK picks the solution nearest its start, so the predictor also
/// chooses the path through the solution set, and the shorter history measured worse
/// (Δ = 6 mm, φ = 0.05 rad: 11 044 instead of 12 057 reachable cells).
fn same_regime<'h, 's>(model: &Model, history: &'h [&'s RobotState]) -> &'h [&'s RobotState] {
    if model.pairs > 1 {
        return history;
    }
    let same_pattern = |a: &RobotState, b: &RobotState| {
        model
            .tendon_unknown_indices()
            .all(|i| (a.y_u[i] > 0.0) == (b.y_u[i] > 0.0))
    };
    let Some(last) = history.last() else {
        return history;
    };
    let run = history
        .iter()
        .rev()
        .take_while(|s| same_pattern(s, last))
        .count();
    if run >= 2 {
        &history[history.len() - run..]
    } else {
        history
    }
}

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

/// The plane origins reached by the path along z, and why the path stopped.
struct Planes {
    /// (k, origin) for every reached plane z = k Δ in the z-range, lowest first.
    origins: Vec<(i64, Sample)>,
    /// Why the path down and the path up stopped.
    ends: [PathEnd; 2],
    /// The message of a [`PathEnd::Failed`] (down first).
    error: Option<String>,
}

/// Solves the home configuration, then follows z up and down to the plane origins in the
/// z-range.
fn reach_planes(
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
    let home =
        home_worker
            .solver
            .solve_ik_with(&home_pose, &Wrench::default(), None, &home_settings)?;
    work.solves.fetch_add(1, Ordering::Relaxed);
    work.add(&home.report);
    let home = match home_worker.classify(model, home.state) {
        Ok(s) if s.end(settings.collisions).is_none() => s,
        _ => {
            return Ok(Planes {
                origins: Vec::new(),
                ends: [PathEnd::InvalidHome; 2],
                error: None,
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
            match w.step(model, &rotation, position, &history, work) {
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

/// The chosen sample of a cell.
struct Representative<'a> {
    /// (j, i): y index, then x index.
    cell: (i64, i64),
    sample: &'a Sample,
}

/// A sample competing to represent a cell.
struct Candidate<'a> {
    /// 0 valid, 1 colliding, 2 unstable (lower is better).
    rank: u8,
    /// Squared distance to the cell centre in units of Δ².
    distance2: f64,
    sample: &'a Sample,
}

impl Candidate<'_> {
    /// Valid before colliding before unstable, then nearer the centre; on a tie the earlier sample (in
    /// (ray, step) order) stays.
    fn better_than(&self, other: &Self) -> bool {
        self.rank < other.rank || (self.rank == other.rank && self.distance2 < other.distance2)
    }
}

/// One representative per cell of a plane (see the module documentation), in (j, i) order.
fn representatives<'a>(step: f64, origin: &'a Sample, rays: &'a [Ray]) -> Vec<Representative<'a>> {
    use std::collections::BTreeMap;
    let mut best: BTreeMap<(i64, i64), Candidate> = BTreeMap::new();
    let all = std::iter::once(origin).chain(rays.iter().flat_map(|r| r.samples.iter()));
    for sample in all {
        let (x, y) = (
            sample.state.position[0] / step,
            sample.state.position[1] / step,
        );
        let (i, j) = (x.round(), y.round());
        let rank = if !sample.metrics.stable {
            2
        } else {
            u8::from(sample.collision)
        };
        let candidate = Candidate {
            rank,
            distance2: (x - i).powi(2) + (y - j).powi(2),
            sample,
        };
        let cell = (j as i64, i as i64);
        if best.get(&cell).is_none_or(|b| candidate.better_than(b)) {
            best.insert(cell, candidate);
        }
    }
    best.into_iter()
        .map(|(cell, c)| Representative {
            cell,
            sample: c.sample,
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn summarize(
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
        threads: rayon::current_num_threads(),
        wall_time_s: wall,
        solves_per_second: if wall > 0.0 {
            solves as f64 / wall
        } else {
            0.0
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A state with every q = s², every tendon unknown γ = `gamma` (positive = taut) and
    /// the other leg unknowns s.
    fn state(model: &Model, s: f64, gamma: f64) -> RobotState {
        let nu = model.n_leg_unknowns();
        let y_u = (0..3 * nu)
            .map(|i| if i % nu < model.n_tendons() { gamma } else { s })
            .collect();
        RobotState {
            position: [0.0; 3],
            rotvec: [0.0; 3],
            q: vec![s * s; model.n_actuators()],
            y_u,
        }
    }

    fn model(design: &str) -> Model {
        let path = format!("{}/designs/{design}", env!("CARGO_MANIFEST_DIR"));
        Model::new(&Tdpcr::from_ron_file(path).unwrap())
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

    #[test]
    fn the_predictor_is_quadratic_within_one_taut_slack_pattern() {
        let m = model("lilge2022.ron");
        let h = [
            state(&m, 1.0, 1.0),
            state(&m, 2.0, 1.1),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        // q = s² is extrapolated exactly by a quadratic.
        assert!(p.q.iter().all(|q| (q - 16.0).abs() < 1e-12), "{:?}", p.q);
    }

    #[test]
    fn the_predictor_extrapolates_only_the_solutions_after_a_switch() {
        let m = model("lilge2022.ron");
        // The tendons switched from slack to taut between the first and second solution.
        let h = [
            state(&m, 1.0, -0.5),
            state(&m, 2.0, 1.1),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        // Linear from the last two: 2 · 9 − 4 = 14 (the quadratic through all three: 16).
        assert!(p.q.iter().all(|q| (q - 14.0).abs() < 1e-12), "{:?}", p.q);
        // Right after the switch the whole history is extrapolated (see `predict`).
        let h = [
            state(&m, 1.0, -0.5),
            state(&m, 2.0, -0.4),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(p.q.iter().all(|q| (q - 16.0).abs() < 1e-12), "{:?}", p.q);
    }

    #[test]
    fn the_predictor_of_a_redundant_design_always_extrapolates_the_whole_history() {
        let m = model("lilge2022_redundant.ron");
        let h = [
            state(&m, 1.0, -0.5),
            state(&m, 2.0, 1.1),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(p.q.iter().all(|q| (q - 16.0).abs() < 1e-12), "{:?}", p.q);
    }
}
