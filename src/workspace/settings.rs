//! How to sweep: [`WorkspaceSettings`] (orientation R_ee, grid step Δ \[m\], ray angle φ
//! \[rad\], z-range \[m\], Newton budget), the [`CollisionPolicy`], their defaults (the
//! paper's Δ = 3 mm, φ = 0.035 rad) and their validation.

use std::f64::consts::PI;

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::Serialize;

use crate::error::{Error, Violations};
use crate::kinetostatics::{Objective, Redundancy};
use crate::newton::NewtonSettings;

use super::metrics::AnalysisSettings;

/// Default grid step Δ \[m\] (paper: 3 mm).
pub const DEFAULT_STEP: f64 = 0.003;
/// Default angular step φ between rays \[rad\] (paper: 0.035).
pub const DEFAULT_ANGLE_STEP: f64 = 0.035;
/// Default z-range \[m\]: covers the reachable workspace of the reference design at
/// R_ee = I (−0.111 … 0.129 m at Δ = 3 mm) with a margin (see README).
pub const DEFAULT_Z_RANGE: [f64; 2] = [-0.15, 0.15];

/// Largest |z| of the z-range accepted \[m\] (10 × the longest leg a design takes).
pub const MAX_Z: f64 = 100.0;

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
    /// Newton tolerance ε_b on ‖b‖₂ of every IK step, in test units
    /// ([`crate::newton::NewtonSettings::tolerance`]).
    pub tolerance: f64,
    /// Newton iterations allowed per step. A warm step of Δ = 3 mm needs 2–4, but steps
    /// across a leg-singularity line (a leg's tendon pair switching, paper Fig. 9) can need
    /// 20–50, and a smaller budget ends rays there (measured on the plane z = 0 of the
    /// reference design: 1277 reachable cells with 15 iterations, 1582 with 60). A step
    /// first gets [`WorkspaceSettings::probe_iterations`] iterations and the rest only if
    /// those reduced ‖b‖ tenfold (a step past a fold, where no solution exists, makes no
    /// such progress).
    pub max_iterations: usize,
    /// Iterations a ray step's Newton run gets before it must have reduced ‖b‖ tenfold to
    /// go on (≥ 1; default [`DEFAULT_PROBE_ITERATIONS`] = 15). A step past a fold of the
    /// IK crawls at its first residual until this check ends it, and its ray then tries
    /// substeps that crawl as well. Fewer iterations end such steps sooner but could also
    /// end slow steps that make progress later. The path along z to the planes, which
    /// ends at its first failed step, keeps at least the default. At the design search's
    /// Δ = 12 mm (20 iterations) 8 kept the cells of all 26 feasible candidates of 30
    /// drawn (`tdpcr-optim`'s default config); the Δ = 3 mm sweeps keep 15
    /// (BENCHMARKS.md "An earlier progress check for the design search's sweeps").
    pub probe_iterations: usize,
    /// How the IK of the 9-DoF design chooses among its solutions (ignored by the 6-DoF
    /// design): least-norm steps (the default; a q beyond its limits ends the ray) or
    /// steps within the actuation limits ([`Redundancy::WithinLimits`], cargo feature
    /// `qp`).
    pub redundancy: Redundancy,
    /// Whether the IK steps take one-sided kink columns ([`Solver::one_sided_kinks`]),
    /// checked against the two-sided run where a step lands far from its prediction or
    /// its trust region collapses (the default: the reference design's
    /// Δ = 3 mm sweep with 30 more cells and a quarter of the Newton Jacobians, with the
    /// tangent ray starts); `false` takes the Jacobian's taut slopes only, as before.
    /// For the 9-DoF design it is [`Solver::across_kinks`]: a step whose run fails on a
    /// step across a tendon's kink is retried with one-sided steps (the default since
    /// 2026-11-28: 41 % more reachable cells free, 35 % within the limits, no ray ending
    /// unconverged at a kink); `false` ends such rays, as before.
    ///
    /// [`Solver::one_sided_kinks`]: crate::kinetostatics::Solver::one_sided_kinks
    /// [`Solver::across_kinks`]: crate::kinetostatics::Solver::across_kinks
    pub one_sided_kinks: bool,
    /// Each IK step's Newton run keeps its Jacobian (the one extrapolated from the ray's
    /// last solutions, or a fresh one) while every chord step contracts ‖W b‖ by at least
    /// this factor, in \[0, 1) ([`NewtonSettings::chord_contraction`]; default 0.1, the
    /// solver's). A larger factor trades Jacobians for cheaper chord steps: at coarse
    /// steps, where the extrapolated Jacobian is further off, 0.5 saves about 6 % of the
    /// work (the design search's evaluation, `tdpcr-optim`'s default config), but the
    /// other iterates can end rays differently at folds and Type II singularities (a
    /// few cells of the map; MODEL.md "Newton with chord steps").
    ///
    /// [`NewtonSettings::chord_contraction`]: crate::newton::NewtonSettings::chord_contraction
    pub chord_contraction: f64,
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
            redundancy: Redundancy::LeastNorm,
            one_sided_kinks: true,
            chord_contraction: NewtonSettings::default().chord_contraction,
            probe_iterations: DEFAULT_PROBE_ITERATIONS,
        }
    }
}

/// Default of [`WorkspaceSettings::probe_iterations`]: measured on the plane z = 0 at
/// Δ = 3 mm, the same 1581 cells and 14 % fewer instructions (φ = 0.1: 8.8 G against
/// 10.2 G) than a 60-iteration budget for every step. (The check runs inside one Newton
/// run; a separate probe re-run from the start when it passed repeated its iterations:
/// −7 % time on the plane z = 0 at φ = 0.035.)
pub const DEFAULT_PROBE_ITERATIONS: usize = 15;

/// Most planes or rays per plane a sweep accepts (memory and time guard).
const MAX_COUNT: f64 = 100_000.0;

impl WorkspaceSettings {
    /// Checks every value; all problems are listed.
    ///
    /// # Errors
    /// [`Error::Input`] naming each bad field, its value and the rule.
    pub fn validate(&self) -> Result<(), Error> {
        let mut v = Violations::default();
        if !crate::spatial::is_rotation_vector(&Vector3::from(self.rotvec)) {
            v.push(
                "rotvec",
                format!("{:?}", self.rotvec),
                crate::spatial::ROTVEC_RULE,
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
        } else if lo.abs().max(hi.abs()) > MAX_Z {
            // The plane index k = z/Δ saturated (z = 1e30 m swept k = i64::MAX).
            v.push(
                "z_range",
                format!("{lo:?},{hi:?}"),
                "within ±100 m (beyond any design's reach: legs are at most 10 m)",
            );
        } else if self.step > 0.0 && (hi - lo) / self.step > MAX_COUNT {
            v.push(
                "z_range",
                format!("{lo},{hi}"),
                &format!("at most {MAX_COUNT} planes of step {} m", self.step),
            );
        } else if self.step.is_finite() && self.step > 0.0 && self.plane_indices().is_empty() {
            v.push(
                "z_range",
                format!("{lo},{hi}"),
                &format!(
                    "a range that holds a plane z = k · step (step {} m), or none is swept",
                    self.step
                ),
            );
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            v.push("tolerance", self.tolerance, "> 0");
        }
        if self.max_iterations == 0 {
            v.push("max_iterations", 0, ">= 1");
        }
        if !(0.0..1.0).contains(&self.chord_contraction) {
            v.push("chord_contraction", self.chord_contraction, "in [0, 1)");
        }
        if self.probe_iterations == 0 {
            v.push("probe_iterations", 0, ">= 1");
        }
        #[cfg(not(feature = "qp"))]
        if matches!(self.redundancy, Redundancy::WithinLimits(_)) {
            v.push(
                "redundancy",
                "WithinLimits",
                "LeastNorm: steps within the limits need the cargo feature `qp` of tdpcr",
            );
        }
        if let Redundancy::WithinLimits(Objective::ClosestTo(r)) = &self.redundancy {
            if !r.iter().all(|x| x.is_finite()) {
                v.push(
                    "redundancy.reference",
                    format!("{r:?}"),
                    "finite numbers [m]",
                );
            }
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
