//! The native module `tdpcr._tdpcr` of the Python package `tdpcr`: the library's
//! [`tdpcr::Solver`] behind numpy arrays in SI units, with the names of the CLI's JSON.
//! It converts and checks inputs and maps errors; every number comes from the library.
//!
//! - `errors.rs`: the exceptions (`DesignError`, `ConvergenceError`, `AnalysisError`)
//!   and the mapping of [`tdpcr::Error`] onto them;
//! - `arrays.rs`: float64 arrays in (shape and finiteness checked, named) and out;
//! - `design.rs`: `Design` (a validated design file);
//! - `solution.rs`: `State` (a configuration, a warm start) and `Solution`;
//! - `robot.rs`: `Robot` (fk, ik, analyze, the batches, workspace);
//! - `batch.rs`: batches as stacked arrays (parallel `*_many`, warm `trajectory_*`);
//! - `interrupt.rs`: long calls that Ctrl-C stops (the work on a thread of its own);
//! - `tdcr.rs`: `Tdcr` (one continuum robot alone, tension or displacement control);
//! - `workspace.rs`: the workspace sweep as columns of arrays, with a progress callback;
//! - `analysis.rs`: the analysis of a solution as a dict of arrays and dicts;
//! - `optim.rs`: the design search's steps (`DesignSearch`) and evaluation
//!   (`SearchProblem`) for the distributed driver `tdpcr.optim`.

mod analysis;
mod arrays;
mod batch;
mod design;
mod errors;
mod interrupt;
mod optim;
mod robot;
mod solution;
mod tdcr;
mod workspace;

use pyo3::prelude::*;

/// The native module; `tdpcr/__init__.py` re-exports it.
#[pymodule]
fn _tdpcr(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<design::Design>()?;
    m.add_class::<robot::Robot>()?;
    m.add_class::<solution::Solution>()?;
    m.add_class::<solution::State>()?;
    m.add_class::<tdcr::Tdcr>()?;
    m.add_class::<optim::DesignSearch>()?;
    m.add_class::<optim::SearchProblem>()?;
    m.add("DesignError", py.get_type::<errors::DesignError>())?;
    m.add(
        "ConvergenceError",
        py.get_type::<errors::ConvergenceError>(),
    )?;
    m.add("AnalysisError", py.get_type::<errors::AnalysisError>())?;
    Ok(())
}
