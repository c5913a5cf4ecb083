//! # tdpcr-optim
//!
//! Design optimization of tendon-driven parallel continuum robots (MODEL.md §7): CMA-ES
//! searches the design parameters of a base design (α, β, L, D, L_a, L_c, τ_pre, and
//! optionally ψ and the disk radius, each within bounds) for a large non-singular
//! workspace, an isotropic positional Jacobian and a wide singularity margin, evaluating
//! each candidate on a coarse workspace sweep of the `tdpcr` library.
//!
//! - [`config`]: the RON config ([`config::OptimConfig`]) and its validation;
//! - [`space`]: the parameters, their bounds and the unit box ↔ design map;
//! - [`objectives`]: what an evaluation measures, the Pareto objectives, the weighted
//!   composite and the ranking of infeasible designs;
//! - [`evaluate`]: the [`evaluate::Evaluator`] trait (the design problem);
//! - [`workspace_eval`]: the evaluator on `tdpcr`'s workspace sweep;
//! - [`cmaes`]: the optimizer (ask/tell CMA-ES on \[0, 1\]ⁿ), [`rng`] its random numbers;
//! - [`pareto`]: dominance and non-dominated sorting;
//! - [`search`]: the run loop (parallel evaluation, log, resume, termination);
//! - [`runlog`]: the evaluation log and the run identity;
//! - [`report`]: the output files (designs, `pareto.csv`, `report.md`, figures).
//!
//! The binary `tdpcr-optim CONFIG.ron [--budget-evals N] [--seed S] [--resume] --out DIR`
//! runs a search; see the repository README, section "Design optimization".
#![warn(missing_docs, rustdoc::broken_intra_doc_links)]

pub mod cmaes;
pub mod config;
pub mod design_view;
pub mod error;
pub mod evaluate;
pub mod figures;
pub mod objectives;
pub mod pareto;
pub mod report;
pub mod rng;
pub mod runlog;
pub mod search;
pub mod space;
pub mod workspace_eval;

pub use config::OptimConfig;
pub use error::OptimError;
pub use search::{Overrides, SearchResult, Setup, run_search, run_search_holding_directory};
