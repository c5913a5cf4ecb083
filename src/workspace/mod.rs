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
//!    its Newton run from the exact Jacobians at those solutions extrapolated likewise,
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
//!    need every point. Only the unit-scaled rconds of \[B_x B_u\], \[B_q B_u\] and B_u
//!    (a second factorization) wait until the plane's cells are chosen and are computed
//!    for the points that represent them, from the blocks kept with each sample (the
//!    same values, bit for bit; at Δ = 3 mm, φ = 0.035 about half the samples represent
//!    no cell). A leg is also flagged singular at two neighbouring points of a ray
//!    between which one of its tendon pairs changes its taut side (paper Fig. 9: the
//!    leg-singularity lines lie between grid points, where the τ threshold rarely sees
//!    them).
//!
//! Rays run in parallel (rayon, the current thread pool; one solver per worker). Each ray
//! depends only on its plane's origin state, and the cell representatives are chosen in a
//! fixed order, so the map is identical whatever the number of threads.
//!
//! Layout: `settings` ([`WorkspaceSettings`]: how to sweep), `plane` (the path along z to
//! the plane origins; one plane's rays and cells), `walk` (one ray: IK steps, substeps,
//! validity of a point), `predict` (the warm start of a step), `cells` (the cell map,
//! [`WorkspacePoint`]), `ends` ([`RayEnds`], [`PathEnd`]), `summary` ([`WorkspaceSummary`]),
//! [`metrics`] (the measures of a point), [`collision`], and the output in [`files`] and
//! `figures` (feature `plots`).

pub mod collision;
#[cfg(feature = "plots")]
pub mod figures;
pub mod files;
pub mod metrics;

mod cells;
mod chord_jacobian;
mod ends;
mod kink_start;
mod plane;
mod predict;
mod settings;
mod summary;
mod walk;

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::design::Tdpcr;
use crate::error::Error;

pub use cells::{Categories, WorkspacePoint};
pub use ends::{PathEnd, RayEnds};
pub use metrics::{AnalysisSettings, PointMetrics, Rconds, Singularity, point_metrics};
pub use settings::{
    CollisionPolicy, DEFAULT_ANGLE_STEP, DEFAULT_PROBE_ITERATIONS, DEFAULT_STEP, DEFAULT_Z_RANGE,
    WorkspaceSettings,
};
pub use summary::{Fractions, RcondStats, RcondVariants, Stats, TableIii, WorkspaceSummary};

use plane::{PlaneJob, PlaneSweep, reach_planes};
use summary::summarize;
use walk::{Work, Worker};

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
    sweep_workspace_until(design, settings, progress, &AtomicBool::new(false))
}

/// As [`sweep_workspace_with_progress`], stopping early once `stop` is set (by another
/// thread: a user's interrupt): the rays not yet started are skipped, those under way
/// finish (a ray takes milliseconds), and the sweep returns [`Error::Stopped`].
///
/// # Errors
/// As [`sweep_workspace`]; [`Error::Stopped`] when `stop` was set during the sweep.
pub fn sweep_workspace_until(
    design: &Tdpcr,
    settings: &WorkspaceSettings,
    progress: &(dyn Fn(Progress) + Sync),
    stop: &AtomicBool,
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
                stop,
            };
            job.sweep(*k, origin, n_rays)
        })
        .collect();
    if stop.load(Ordering::Relaxed) {
        return Err(Error::Stopped {
            what: "rays",
            done: rays_done.load(Ordering::Relaxed),
            total: rays_total,
        });
    }
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
