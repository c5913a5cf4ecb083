//! # tdpcr
//!
//! Kinetostatics of tendon-driven continuum robots (TDCR) and tendon-driven parallel
//! continuum robots (TDPCR) by shooting, with exact Jacobians from forward sensitivity
//! propagation along the rod ODEs. The mathematics and every sign convention are in
//! `MODEL.md` (shipped in the repository's docs); equation numbers refer to Lilge &
//! Burgner-Kahrs, "Kinetostatic Modeling of Tendon-Driven Parallel Continuum Robots".
//!
//! ## Data flow
//!
//! ```text
//!  design file (RON)                                         value types: spatial
//!      │  design::Tdpcr::from_ron_file (validated)           (Frame, Pose, Wrench)
//!      ▼
//!  model::Model ── geometry of the three legs, bases, platform, actuation
//!      │
//!      ▼
//!  rod ── one leg: integrate_leg(_with_sensitivities), cold_guess
//!      │
//!      ▼
//!  boundary ── residual b (30/36 rows) and exact blocks B_x, B_q, B_w, B_u
//!      │
//!      ▼
//!  newton ── dogleg trust region (square) / line search with a StepRule (redundant)
//!      │
//!      ▼
//!  kinetostatics::Solver ── solve_fk, solve_ik (warm starts, continuation) → Solution
//!      │
//!      ├──▶ analysis ── analyze_blocks: J_FK, J_IK, C, rcond, flags, stability
//!      │
//!      └──▶ workspace ── sweep_workspace: rays of warm IK in parallel → WorkspaceMap
//!               │
//!               ▼
//!           tdpcr-optim (the optim/ crate): CMA-ES over design parameters
//! ```
//!
//! Entry points:
//! - [`spatial`]: the value types every layer shares ([`Frame`], [`Pose`], [`Wrench`]);
//! - [`design`]: the RON design files ([`Tdcr`], [`Tdpcr`], [`Leg`]) and their validation;
//! - [`rod`]: one leg, integrated with or without exact sensitivities, and its cold guess;
//! - [`tdcr`]: the single-TDCR solver ([`TdcrSolver`]), tension or displacement control;
//! - [`newton`]: the dogleg Newton of square systems ([`newton::solve`]) and the
//!   Gauss–Newton driver of the redundant IK ([`newton::solve_with_line_search`], one loop
//!   for every [`newton::StepRule`]), both stopping by [`NewtonSettings::outcome`];
//! - [`kinetostatics`]: FK and IK of the parallel robot ([`Solver`]:
//!   [`Solver::new`] validates the design; `solve_fk`, `solve_ik`, `solve_ik_newton` with
//!   the solver's settings, `*_with` with settings per call), redundancy resolution of the
//!   9-DoF design ([`redundancy`]);
//! - [`analysis`]: Jacobians, compliance, singularity measures and ellipsoids, a function
//!   of the boundary blocks ([`analysis::analyze_blocks`]); a solved configuration is
//!   analysed by [`Solver::analyze_solution`];
//! - [`workspace`]: the translational workspace for a fixed orientation (paper Sec. V-B),
//!   rays of warm-started IK in parallel ([`workspace::sweep_workspace`]).
//!
//! The main types are at the crate root. The parallel robot: load the paper's design,
//! solve FK for an actuation, read the Jacobian and the compliance at the solution, and
//! check its stability (`examples/solve_fk.rs` and `examples/controller_loop.rs` go
//! further):
//!
//! ```
//! use tdpcr::{AnalysisSettings, Solver, Tdpcr, Wrench};
//!
//! let design = Tdpcr::from_ron_file(concat!(env!("CARGO_MANIFEST_DIR"), "/designs/lilge2022.ron"))?;
//! let mut solver = Solver::new(&design)?;
//! // q per leg: [bending q_b, base translation q_t] [m].
//! let q = [0.002, 0.01, -0.001, 0.0, 0.0, 0.005];
//! let sol = solver.solve_fk(&q, &Wrench::default(), None)?;
//! let a = solver.analyze_solution(&sol, &AnalysisSettings::default())?;
//! let (j_p, c_p) = (a.j_p(), a.compliance.view((0, 0), (3, 3)));
//! assert_eq!((j_p.nrows(), j_p.ncols()), (3, 6)); // ∂p/∂q [m/m]
//! assert!(c_p[(2, 2)] > 0.0); // ∂p_z/∂f_z [m/N]
//! assert!(a.stability.stable);
//! # Ok::<(), tdpcr::Error>(())
//! ```
//!
//! One tendon-driven continuum robot alone:
//!
//! ```
//! use tdpcr::{Tdcr, TdcrSolver, tdcr::{TendonControl, TipWrench}};
//! let robot = Tdcr::from_ron_file(concat!(env!("CARGO_MANIFEST_DIR"), "/designs/tdcr_one_segment.ron")).unwrap();
//! let mut solver = TdcrSolver::new(&robot);
//! let sol = solver
//!     .solve(&TendonControl::Displacement(vec![-0.005, 0.005]), &TipWrench::default(), None)
//!     .unwrap();
//! assert!(sol.tensions[0] > 3.0 && sol.tensions[1] == 0.0);
//! ```
//!
//! ## Crate features
//!
//! All on by default; the numerical library alone builds with `default-features = false`
//! (nalgebra, serde, ron, serde_json, thiserror, rayon):
//! - `qp`: the QP steps of
//!   [`Redundancy::WithinLimits`](redundancy::Redundancy::WithinLimits) (clarabel); without
//!   it a solve that asks for them is an [`Error::Input`] naming the feature;
//! - `plots`: SVG figures (plotters): `analysis::plot` and `workspace::figures`;
//! - `progress`: the progress bar of the `tdpcr workspace` sweep (indicatif);
//! - `cli`: the `tdpcr` binary (clap) and `cli_support` (libc); turns on `plots`,
//!   `progress` and `qp`.
#![warn(missing_docs, rustdoc::broken_intra_doc_links)]
// Tendon quantities live in parallel arrays indexed by k, as in the equations.
#![allow(clippy::needless_range_loop)]

/// `$vis fn $name(args) -> ret` that runs `$inline` (an `#[inline(always)]` function of
/// the same arguments) compiled for AVX2 where the CPU has it (detected at run time; the
/// same operations in the same order, so the results are bitwise identical either way),
/// with one AVX2 copy per function. (In the analysis, one AVX2 function with all of the
/// factorization inlined into it was about 60 k instructions long and only 7 % faster
/// than the baseline, 63.5 against 68.5 µs per 9-DoF analysis; one copy per kernel: 56.4
/// µs.)
/// The baseline build targets generic x86-64, whose SSE2 does two lanes.
macro_rules! avx2_dispatch {
    ($(#[$m:meta])* $vis:vis fn $name:ident = $avx2:ident / $inline:path;
        ($($arg:ident: $ty:ty),*) $(-> $ret:ty)?) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2, checked just above.
                return unsafe { $avx2($($arg),*) };
            }
            $inline($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        fn $avx2($($arg: $ty),*) $(-> $ret)? {
            $inline($($arg),*)
        }
    };
}

pub mod analysis;
pub mod boundary;
#[cfg(feature = "cli")]
pub mod cli_support;
mod decimal;
pub mod design;
pub mod error;
pub mod input_range;
pub mod jacobian_check;
pub mod kinetostatics;
pub mod linalg;
pub mod model;
pub mod newton;
pub mod output;
pub mod random;
pub mod redundancy;
pub mod rod;
pub mod sampling;
pub mod spatial;
pub mod tdcr;
pub mod trajectory;
#[cfg(feature = "views")]
pub mod view;
pub mod workspace;

pub use analysis::{Analysis, AnalysisSettings};
pub use design::{Leg, Tdcr, Tdpcr};
pub use error::{DesignError, Error, SolveError, StopReason};
pub use kinetostatics::{RobotState, Solution, Solver};
pub use newton::NewtonSettings;
pub use spatial::{Frame, Pose, Wrench};
pub use tdcr::TdcrSolver;
